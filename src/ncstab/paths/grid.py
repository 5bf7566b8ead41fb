"""The cases of a sweep: swept parameters (dimensions) and fixed ones, flat in C order."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ncstab.paths.variables import CASE_DIMENSION, RESERVED_NAMES

__all__ = ["CaseRange", "ParameterGrid"]


@dataclass(frozen=True)
class ParameterGrid:
    """Sweep dimensions (lists) and fixed values (scalars) of a study.

    Attributes
    ----------
    sweep
        Ordered ``name -> 1-D values`` of the swept parameters.
    fixed
        ``name -> value`` of the fixed ones.
    """

    sweep: dict[str, np.ndarray]
    fixed: dict[str, float]

    @classmethod
    def from_mapping(cls, parameters: Mapping[str, Any]) -> "ParameterGrid":
        sweep: dict[str, np.ndarray] = {}
        fixed: dict[str, float] = {}
        for name, value in parameters.items():
            if name in RESERVED_NAMES:
                raise ValueError(
                    f"parameter name {name!r} is reserved (a dimension, variable or keyword of the "
                    "Dataset); choose another name"
                )
            if isinstance(value, (list, tuple, np.ndarray)):
                array = np.asarray(value, dtype=float).ravel()
                if array.size == 0:
                    raise ValueError(f"parameter {name!r}: an empty sweep has no cases")
                if not np.all(np.isfinite(array)):
                    raise ValueError(f"parameter {name!r}: every swept value must be finite")
                sweep[name] = array
            else:
                if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
                    raise ValueError(f"parameter {name!r}: expected a number or a list, got {value!r}")
                if not np.isfinite(value):
                    raise ValueError(f"parameter {name!r} = {value!r} is not finite")
                fixed[name] = float(value)
        return cls(sweep, fixed)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(v.size for v in self.sweep.values())

    @property
    def size(self) -> int:
        return int(np.prod(self.shape)) if self.sweep else 1

    def case_values(self) -> dict[str, np.ndarray]:
        """Every parameter as a flat array over the cases (C order over the sweep)."""
        out: dict[str, np.ndarray] = {}
        if self.sweep:
            mesh = np.meshgrid(*self.sweep.values(), indexing="ij")
            out.update({name: m.ravel() for name, m in zip(self.sweep, mesh)})
        out.update({name: np.full(self.size, value) for name, value in self.fixed.items()})
        return out

    @property
    def names(self) -> list[str]:
        return list(self.sweep) + list(self.fixed)


@dataclass(frozen=True)
class CaseRange:
    """The flat cases ``start:stop`` of a :class:`ParameterGrid`, as a one-dimensional grid.

    A chunk of a large sweep (:mod:`ncstab.studies.chunked`) is followed and
    turned into a Dataset on its own; its swept parameters become one ``case``
    dimension (flat index into the whole grid, C order) so that the chunk's
    Dataset can be cut into the whole archive's blocks (:mod:`ncstab.studies.streaming`).  It offers what
    :class:`ncstab.paths.PathResult` uses of a grid: ``sweep``, ``fixed``, ``shape``,
    ``size`` and ``case_values()``.
    """

    grid: ParameterGrid
    start: int
    stop: int

    def __post_init__(self) -> None:
        if not 0 <= self.start < self.stop <= self.grid.size:
            raise ValueError(f"cases {self.start}:{self.stop} are not a run of the grid's {self.grid.size} cases")

    @property
    def sweep(self) -> dict[str, np.ndarray]:
        return {CASE_DIMENSION: np.arange(self.start, self.stop, dtype=np.int64)}

    @property
    def fixed(self) -> dict[str, float]:
        return self.grid.fixed

    @property
    def shape(self) -> tuple[int, ...]:
        return (self.stop - self.start,)

    @property
    def size(self) -> int:
        return self.stop - self.start

    @property
    def names(self) -> list[str]:
        return self.grid.names

    def case_values(self) -> dict[str, np.ndarray]:
        """``grid.case_values()[name][start:stop]``, without building the whole grid."""
        values: dict[str, np.ndarray] = {}
        if self.grid.sweep:
            positions = np.unravel_index(np.arange(self.start, self.stop), self.grid.shape)
            values.update({name: sweep[k] for (name, sweep), k in zip(self.grid.sweep.items(), positions)})
        values.update({name: np.full(self.size, value) for name, value in self.grid.fixed.items()})
        return values
