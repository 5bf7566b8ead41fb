"""The result of :func:`ncstab.follow`: states, statuses and events of every case."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ncstab.paths.case_result import CaseResult
from ncstab.paths.options import PathOptions, SystemSpec
from ncstab.paths.programme import CycleStage, LoadingProgramme, Stage

if TYPE_CHECKING:  # pragma: no cover
    import xarray

    from ncstab.paths.api import Model
    from ncstab.paths.grid import CaseRange, ParameterGrid

__all__ = ["PathResult"]


@dataclass(frozen=True)
class PathResult:
    """Paths of every law and every case of a sweep.

    Attributes
    ----------
    model
        The system and laws followed (:class:`ncstab.paths.api.Model`).
    grid
        The parameter grid (further sweep dimensions, in order).
    programme, options
        What was followed and how.
    results
        One :class:`~ncstab.paths.case_result.CaseResult` per law, cases flat in C
        order over the grid.
    study_text
        The study file text (provenance).
    """

    model: "Model"
    grid: "ParameterGrid | CaseRange"
    programme: LoadingProgramme
    options: PathOptions
    results: tuple[CaseResult, ...]
    study_text: str = ""

    @property
    def laws(self) -> tuple[str, ...]:
        """Law names (the first sweep dimension)."""
        return self.model.law_names

    @property
    def system(self) -> SystemSpec | None:
        """The shipped system followed, or ``None`` for a system given as a definition."""
        return self.model.spec

    @property
    def dof_names(self) -> tuple[str, ...]:
        return self.model.definition.dofs

    @property
    def force_names(self) -> tuple[str, ...]:
        return self.model.definition.forces

    @property
    def force_unit(self) -> str:
        """Unit of forces: 2R k_n, or 2R k_t in the pure-shear limit (seed Eq. 62); a
        system's own unit otherwise."""
        if self.model.normal == "rigid":
            return "2R k_t"
        if self.model.definition.family("contact") is not None:
            return "2R k_n"
        return self.model.definition.units.force_unit

    @property
    def shape(self) -> tuple[int, ...]:
        """Sweep shape: (law, *swept parameters)."""
        return (len(self.laws),) + self.grid.shape

    @property
    def status(self) -> np.ndarray:
        """Per-case status, shape :attr:`shape`."""
        return np.stack([r.status for r in self.results]).reshape(self.shape)

    @property
    def message(self) -> np.ndarray:
        return np.stack([r.message for r in self.results]).reshape(self.shape)

    @property
    def succeeded(self) -> np.ndarray:
        """True where a case finished or stopped at an event (did not fail)."""
        return ~np.char.startswith(self.status.astype(str), "failed")

    def case(self, law: str, **parameters: float) -> tuple[CaseResult, int]:
        """(result of the law, flat case index) of one case, by parameter values."""
        result = self.results[self.laws.index(law)]
        index = []
        for name, values in self.grid.sweep.items():
            if name not in parameters:
                raise KeyError(f"give a value for the swept parameter {name!r}")
            matches = np.flatnonzero(np.isclose(values, parameters[name], rtol=0, atol=1e-12))
            if matches.size == 0:
                raise KeyError(f"{name} = {parameters[name]} is not in the sweep {values}")
            index.append(int(matches[0]))
        flat = int(np.ravel_multi_index(index, self.grid.shape)) if index else 0
        return result, flat

    def to_dataset(self, directions: int | None = None, spectrum: bool = False) -> "xarray.Dataset":
        """The labelled Dataset of docs/archive.md.

        Dimensions: ``law``, the swept parameters in order, then ``step``,
        ``dof`` (named by the system: ``D1``, ``D2``...), ``i``, ``j``, and the
        members of interaction families with several (``contact``,
        ``spring``).  Paths of different lengths are NaN-padded along
        ``step``; ``n_steps`` gives each case's length.

        Parameters
        ----------
        directions
            If given (M >= 4), add the directional second-order work map
            ``d2W_dir`` (dims ..., step, theta) on M directions theta in
            [0, pi) (d2W is pi-periodic), and per step the unstable cone
            ``cone_width``, ``cone_lower``, ``cone_upper`` (exact roots).
            Two-dof systems only.
        spectrum
            Add the dynamic spectrum at every state, ``spectrum_re`` and
            ``spectrum_im`` (dims ..., step, root), for a system with inertia.
        """
        from ncstab.paths.dataset import path_dataset

        return path_dataset(self, directions, spectrum)

    def law_definition(self, name: str):
        """The definition of one of :attr:`laws` (a catalogue law or a user law)."""
        return self.model.laws[self.laws.index(name)]

    def law_classes(self) -> dict[str, str]:
        """The computed class of every law (:func:`ncstab.symbolic.classify`, kept in the
        cache directory by :func:`ncstab.symbolic.class_cache.class_summary`)."""
        from ncstab.symbolic.class_cache import class_summary

        return {law.name: class_summary(law).kind for law in self.model.laws}

    def force_controlled(self, stage: int) -> list[int]:
        """The dofs whose force a stage prescribes (held, driven, or free)."""
        st = self.programme.stages[stage]
        if isinstance(st, CycleStage):
            return [i for i, d in enumerate(self.dof_names) if d not in st.dofs]
        assert isinstance(st, Stage)
        controls = st.controls()
        return [i for i, d in enumerate(self.dof_names) if d not in controls]

    def mixed_control(self, K: np.ndarray, stage: np.ndarray) -> np.ndarray:
        """det K_SS per stored state, with S the force-controlled dofs of its stage."""
        from ncstab.operators.indicators import mixed_control_determinant

        out = np.full(stage.shape, np.nan)
        for k in range(len(self.programme.stages)):
            where = stage == k
            if where.any():
                out[where] = mixed_control_determinant(K[where], self.force_controlled(k))
        return out
