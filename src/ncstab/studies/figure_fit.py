"""Which figure kinds a study can draw: each kind needs part of what a study gives.

A kind that a study cannot draw would fail only after the whole run (the
archive written, then an error): :func:`ncstab.studies.parse_study` refuses it
instead, with :func:`figure_misfit`'s reason.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ncstab.laws.definition import LawDefinition
from ncstab.paths.options import SystemSpec
from ncstab.paths.programme import LoadingProgramme

__all__ = ["FigureFit", "SEED_DIAMOND_KINDS", "figure_fit", "figure_misfit"]

#: Figure kinds of the seed's reduced diamond only (its two dofs, its one contact).
SEED_DIAMOND_KINDS = ("load_displacement_rotation", "second_order_work_map", "second_order_work_polar", "state_map")


@dataclass(frozen=True)
class FigureFit:
    """What a study gives its figures: each kind needs part of it (:func:`figure_misfit`).

    Attributes
    ----------
    cycles
        The programme has a cycle stage.
    swept
        Number of swept parameters (besides ``law``).
    directions, grid
        ``[map] directions`` / ``[map] grid`` are given.
    state_maps
        Some law has a state map: a total form, with deformable contacts.
    seed_diamond
        The system is the seed's reduced diamond (the seed's own figures).
    spectrum
        The system has inertia and a load parameter (a spectrum along the load).
    dashpots
        Both dashpots b1 and b2 are swept (a damping map).
    motion
        The programme ends with a dynamic stage (a motion in time).
    """

    cycles: bool
    swept: int
    directions: bool
    grid: bool
    state_maps: bool
    seed_diamond: bool = True
    spectrum: bool = False
    dashpots: bool = False
    motion: bool = False


def figure_fit(
    programme: LoadingProgramme | None,
    parameters: Mapping[str, Any],
    study_map: Any,
    definitions: Sequence[LawDefinition],
    system: SystemSpec,
) -> FigureFit | None:
    """The :class:`FigureFit` of a study, or None while its programme is invalid.

    ``study_map`` is the study's :class:`~ncstab.studies.study.StudyMap` (or None).
    """
    if programme is None:
        return None
    seed = isinstance(system, SystemSpec) and system.is_reduced_diamond
    definition = system.definition if isinstance(system, SystemSpec) else system
    swept = {name for name, value in parameters.items() if isinstance(value, (list, tuple))}
    return FigureFit(
        cycles=any(getattr(stage, "center", None) is not None for stage in programme.stages),
        swept=len(swept),
        directions=getattr(study_map, "directions", None) is not None,
        grid=getattr(study_map, "grid", None) is not None,
        state_maps=seed and system.normal == "deformable" and any(getattr(d, "has_total_form", False) for d in definitions),
        seed_diamond=seed,
        spectrum=definition.mass is not None and definition.load is not None,
        dashpots={"b1", "b2"} <= swept,
        motion=getattr(programme, "dynamic", None) is not None,
    )


def figure_misfit(kind: str, fit: FigureFit) -> str | None:
    """Why a study cannot draw a figure kind (the figure would fail after the run), or None."""
    if kind.startswith("cycle_") and not fit.cycles:
        return (f"figure kind {kind!r} draws cycles, and the loading programme has no cycle stage; add one "
                "(cycle = { center = [0.05, 0.0], turns = 3 }) or remove the kind")
    if kind == "stability_diagram" and fit.swept != 2:
        return (f"figure kind 'stability_diagram' needs exactly two swept parameters besides the laws; "
                f"the study sweeps {fit.swept}")
    if kind == "second_order_work_map" and not fit.directions:
        return "figure kind 'second_order_work_map' needs [map] directions = M; add it or remove the kind"
    if kind == "state_map" and not fit.grid:
        return "figure kind 'state_map' needs [map] grid = { D1 = [min, max, n], D2 = [min, max, n] }"
    if kind in ("root_locus", "frequencies") and not fit.spectrum:
        return (f"figure kind {kind!r} draws the dynamic spectrum along the load: it needs a system with "
                "inertia and a load parameter (ziegler)")
    if kind in ("motion", "phase_portrait", "energies") and not fit.motion:
        return (f"figure kind {kind!r} draws the motion of a dynamic stage, and the loading programme has none; "
                "add one ([[loading]] dynamic = { duration = 40.0, perturbation = { ... } }) or remove the kind")
    if kind == "damping_map" and not fit.dashpots:
        return "figure kind 'damping_map' needs a sweep over both dashpots b1 and b2 (ziegler)"
    if kind in SEED_DIAMOND_KINDS and not fit.seed_diamond:
        return (f"figure kind {kind!r} is drawn for the seed's reduced diamond (two dofs, one contact); "
                "this system's path figures are load_displacement, load_rotation and stability")
    if kind == "state_map" and not fit.state_maps:
        return ("figure kind 'state_map' needs a law with a total form and deformable contacts: no law of "
                "this study has a state map")
    return None
