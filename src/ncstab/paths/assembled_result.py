"""Following every case of an assembled system, and its Dataset (docs/archive.md).

:func:`follow_assembled` runs the sparse engine (:mod:`ncstab.paths.assembled_path`)
case by case -- each case of a large system is large work, so the loop over
cases is Python's -- and gives an :class:`AssembledPathResult`, whose
``to_dataset`` writes the variables of the contract with the same names, units
and attributes as the compiled engine's Dataset, and these differences:

* K, K_sym and K_skew (step, i, j) are stored up to :data:`STORED_K_LIMIT` dofs
  only (64 dofs make 32 kB a state; 1,000 would make 8 MB); the indicators built
  on K are stored for every size;
* ``det_K`` overflows for large n (the column of 1,000 links has det K of order
  1e600): ``det_K_sign`` and ``log_abs_det_K`` give it whole, ``det_K`` is their
  value where it fits in float64 (+-inf where it does not);
* ``flutter`` is computed up to :data:`STORED_K_LIMIT` dofs (dense spectrum), NaN
  above: with a diagonal M, or with the M(u) and C of the system's ``inertia``
  (:mod:`ncstab.paths.assembled_dynamics`, which also gives the events ``flutter_onset``
  and ``divergence`` and ``flutter_onset_frequency``); ``d2W`` is du . K du / (|K du| |du|)
  along the path tangent.
"""

from __future__ import annotations

import time

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.assembled_control import refuse_cycles
from ncstab.paths.assembled_engine import CaseRun
from ncstab.paths.assembled_path import CaseOutcome, follow_case
from ncstab.paths.options import PathOptions
from ncstab.paths.programme import LoadingProgramme

if TYPE_CHECKING:  # pragma: no cover
    import xarray

    from ncstab.paths.api import Model

__all__ = ["STORED_K_LIMIT", "AssembledPathResult", "follow_assembled"]

#: Up to this many dofs the Dataset stores K, K_sym, K_skew and flutter.
STORED_K_LIMIT = 64
#: What the archive's ``engine`` attribute says.
ENGINE = "sparse engine (assembled elements; ncstab.paths.assembled_path)"


@dataclass(frozen=True)
class _LawCases:
    """One law's cases (what :class:`~ncstab.paths.result.PathResult` calls a result)."""

    outcomes: tuple[CaseOutcome, ...]
    engine: str = ENGINE


@dataclass(frozen=True)
class AssembledPathResult:
    """Paths of every law and case of an assembled system (the surface of a PathResult)."""

    model: "Model"
    grid: Any
    programme: LoadingProgramme
    options: PathOptions
    results: tuple[_LawCases, ...]
    study_text: str = ""

    laws = property(lambda self: self.model.law_names)
    dof_names = property(lambda self: self.model.definition.dofs)
    force_names = property(lambda self: self.model.definition.forces)
    system = property(lambda self: self.model.spec)

    @property
    def force_unit(self) -> str:
        definition = self.model.definition
        unit = definition.units.force_unit  # a packing's k_n d
        return "2R k_n" if definition.family("contact") is not None and unit == "1" else unit

    @property
    def shape(self) -> tuple[int, ...]:
        return (len(self.laws),) + self.grid.shape

    @property
    def status(self) -> np.ndarray:
        return np.array([[o.status for o in r.outcomes] for r in self.results], dtype=object).reshape(self.shape)

    @property
    def message(self) -> np.ndarray:
        return np.array([[o.message for o in r.outcomes] for r in self.results], dtype=object).reshape(self.shape)

    @property
    def succeeded(self) -> np.ndarray:
        return ~np.char.startswith(self.status.astype(str), "failed")

    def law_classes(self) -> dict[str, str]:
        from ncstab.symbolic.class_cache import class_summary

        return {law.name: class_summary(law).kind for law in self.model.laws}

    def to_dataset(self, directions: int | None = None, spectrum: bool = False) -> "xarray.Dataset":
        if directions is not None or spectrum:
            raise ValueError("directional maps and the stored spectrum are not available for assembled systems")
        from ncstab.paths.assembled_dataset import assembled_dataset

        return assembled_dataset(self)


#: Seconds between two refreshes of a case's progress on the bar (steps come faster at small n).
PROGRESS_INTERVAL = 0.5


def _case_progress(bar, case: int, cases: int):
    """What a case tells the progress bar after each accepted step: its stage and how far along
    it is, refreshed at most every :data:`PROGRESS_INTERVAL` s (a case of 10,000 dofs takes a minute)."""
    if bar is None:
        return None
    last = time.monotonic()

    def told(stage: int, fraction: float) -> None:
        nonlocal last
        if time.monotonic() - last >= PROGRESS_INTERVAL:
            last = time.monotonic()
            bar.set_postfix_str(f"case {case + 1}/{cases}: stage {stage}, {100 * min(max(fraction, 0.0), 1.0):.0f}%")
    return told


def follow_assembled(model: "Model", programme: LoadingProgramme, grid: Any, values: dict[str, np.ndarray],
                     options: PathOptions, study_text: str = "", progress=None) -> AssembledPathResult:
    """Follow every law and case of ``grid`` on the assembled system of ``model`` (a cycle stage
    is refused before any work: :func:`~ncstab.paths.assembled_control.refuse_cycles`).
    ``progress``: a tqdm bar counting the cases, told each case's stage and how far along it is."""
    refuse_cycles(programme)
    definition = model.definition
    results = []
    for law in model.laws:
        outcomes = []
        for case in range(grid.size):
            case_values = {name: float(np.asarray(v).reshape(-1)[case]) for name, v in values.items()}
            for parameter in getattr(law, "parameters", ()):
                if parameter.name not in case_values and parameter.default is not None:
                    case_values[parameter.name] = float(parameter.default)
            contact_law = law if definition.contacts is not None else None
            system = definition.for_values(case_values, contact_law)
            run = CaseRun(system, contact_law, case_values, options, model.secondary_contacts)
            outcomes.append(follow_case(run, programme, case_values, definition.dofs, definition.forces,
                                        definition.load_parameter, _case_progress(progress, case, grid.size)))
            if progress is not None:
                progress.update(1)
        results.append(_LawCases(tuple(outcomes)))
    return AssembledPathResult(model, grid, programme, options, tuple(results), study_text)
