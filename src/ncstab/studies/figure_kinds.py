"""The figure kinds a study file may name (no import of sympy: archives are checked against them)."""

from __future__ import annotations

__all__ = ["DEFAULT_FIGURES", "FIGURE_KINDS"]

#: Figure kinds a study may ask for in ``[output] figures``: those
#: ``ncstab.plotting.FIGURE_KINDS`` draws (the cycle kinds for programmes with cycle stages).
FIGURE_KINDS = (
    "load_rotation",
    "load_displacement",
    "load_displacement_rotation",
    "stability",
    "cycle_work",
    "cycle_paths",
    "cycle_force_drift",
    "stability_diagram",
    "second_order_work_map",
    "second_order_work_polar",
    "state_map",
    "root_locus",
    "frequencies",
    "damping_map",
    "motion",
    "phase_portrait",
    "energies",
    "boundary",
)


#: Figures drawn when ``[output] figures`` is not given.
DEFAULT_FIGURES = ("load_displacement", "load_rotation")
