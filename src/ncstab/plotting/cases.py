"""The cases of a path Dataset, one curve each, read from the Dataset alone."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from ncstab.plotting.style import EVENT_MARKERS, format_parameter, law_display_name

__all__ = ["Case", "CaseEvent", "path_cases"]

#: Per-step variables read for each case (missing ones are left NaN).
_STEP_VARIABLES = ("alpha", "l", "s", "stage", "N", "det_K", "hill", "d2W", "load")


@dataclass(frozen=True)
class CaseEvent:
    """The first located occurrence of an event on one case's path.

    Attributes
    ----------
    name
        Event name (``"limit_point"``, ...).
    s, alpha
        Arclength and branch orientation (rad) at the event.
    u, F
        Generalized displacements and forces at the event, shape (2,).
    K
        Tangent operator at the event, shape (2, 2) (NaN if not stored).
    load
        The load parameter at the event (NaN for a system without one).
    """

    name: str
    s: float
    alpha: float
    u: np.ndarray
    F: np.ndarray
    K: np.ndarray
    load: float = np.nan


@dataclass(frozen=True)
class Case:
    """One case of a sweep: a law and values of the swept parameters.

    Arrays hold the first ``n_steps`` stored states only (the valid part).

    Attributes
    ----------
    law
        Law name (``"mcnamara+no_tension"``).
    swept
        Swept parameter name -> value for this case (law excluded).
    fixed
        Fixed parameters of the study (``parameter_<name>`` attributes).
    status
        ``finished``, ``stopped:<event>`` or ``failed:<reason>``.
    u, F
        Shape (n, 2): Delta*, F* for dof 1 and 2.
    alpha, l, s, stage, N, det_K, hill, d2W
        Shape (n,).
    load
        Shape (n,): the load parameter (NaN for a system without one).
    events
        Located events of this case, by name (events not found are absent).
    """

    law: str
    swept: dict[str, object]
    fixed: dict[str, object]
    status: str
    u: np.ndarray
    F: np.ndarray
    alpha: np.ndarray
    l: np.ndarray
    s: np.ndarray
    stage: np.ndarray
    N: np.ndarray
    det_K: np.ndarray
    hill: np.ndarray
    d2W: np.ndarray
    load: np.ndarray
    events: dict[str, CaseEvent] = field(default_factory=dict)

    @property
    def failed(self) -> bool:
        return self.status.startswith("failed")

    @property
    def n_steps(self) -> int:
        return int(self.alpha.shape[0])

    @property
    def failure_note(self) -> str:
        """``" — failed (reason)"`` for a failed case, else ``""``."""
        if not self.failed:
            return ""
        reason = self.status.split(":", 1)[1] if ":" in self.status else self.status
        return f" — failed ({reason})"

    @property
    def label(self) -> str:
        """``"McNamara et al. 2008 (hyperelastic), γ = 0.5"`` (+ ``" — failed (reason)"``)."""
        parts = [law_display_name(self.law)]
        parts += [format_parameter(name, value) for name, value in self.swept.items()]
        return ", ".join(parts) + self.failure_note

    def parameter(self, name: str) -> float | None:
        """A swept or fixed numeric parameter of the case, or None if the study has none."""
        value = self.swept.get(name, self.fixed.get(name))
        try:
            number = float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return None
        return number if np.isfinite(number) else None


def _values(
    dataset: xr.Dataset, name: str, dims: list[str], tail: tuple[str, ...]
) -> np.ndarray | None:
    if name not in dataset:
        return None
    array = dataset[name]
    if "dof" in tail and "dof" in array.dims and "dof" in array.coords:
        array = array.isel(dof=[0, 1])
    members = [d for d in array.dims if d not in dims and d not in tail]
    if members:  # a variable per contact (or spring) of a general system: its first member
        array = array.isel({d: 0 for d in members})
    return np.asarray(array.transpose(*dims, *tail).values)


def _first_steps(array: np.ndarray | None, index: tuple[int, ...], n: int) -> np.ndarray:
    """The first n stored states of one case (NaN if the Dataset lacks the variable)."""
    return np.asarray(array[index][:n], dtype=float) if array is not None else np.full(n, np.nan)


def _case_event(
    name: str, fields: Mapping[str, np.ndarray | None], index: tuple[int, ...]
) -> CaseEvent:
    """The located event ``name`` of one case from the ``<event>_<field>`` arrays."""

    def scalar(key: str) -> float:
        array = fields[key]
        return float(array[index]) if array is not None else np.nan

    def matrix(key: str, shape: tuple[int, ...]) -> np.ndarray:
        array = fields[key]
        return (
            np.asarray(array[index], dtype=float) if array is not None else np.full(shape, np.nan)
        )

    return CaseEvent(
        name=name,
        s=scalar("s"),
        alpha=scalar("alpha"),
        u=matrix("u", (2,)),
        F=matrix("F", (2,)),
        K=matrix("K", (2, 2)),
        load=scalar("load"),
    )


def path_cases(dataset: xr.Dataset) -> list[Case]:
    """Every case of a path Dataset, in the order of its sweep dimensions (C order).

    Parameters
    ----------
    dataset
        A Dataset of :meth:`ncstab.paths.PathResult.to_dataset` (or read back from
        its NetCDF archive).

    Returns
    -------
    list of Case
        One per (law, swept parameter values), arrays cut to ``n_steps``.

    Raises
    ------
    ValueError
        If the Dataset is not a path Dataset (no ``n_steps``, ``u`` or ``F``).
    """
    missing = [name for name in ("n_steps", "u", "F") if name not in dataset]
    if missing:
        raise ValueError(f"not a path Dataset: missing variable(s) {', '.join(missing)}")
    dims = list(dataset["n_steps"].dims)
    n_steps = np.asarray(dataset["n_steps"].values)
    u = _values(dataset, "u", dims, ("step", "dof"))
    F = _values(dataset, "F", dims, ("step", "dof"))
    steps = {name: _values(dataset, name, dims, ("step",)) for name in _STEP_VARIABLES}
    status = _values(dataset, "status", dims, ())
    events = {}
    extrema = [str(name)[:-2] for name in dataset.data_vars if str(name).startswith("extremum_") and str(name).endswith("_F")]
    for event in (*EVENT_MARKERS, *extrema):
        if f"{event}_F" not in dataset:
            continue
        events[event] = {
            "s": _values(dataset, f"{event}_s", dims, ()),
            "alpha": _values(dataset, f"{event}_alpha", dims, ()),
            "u": _values(dataset, f"{event}_u", dims, ("dof",)),
            "F": _values(dataset, f"{event}_F", dims, ("dof",)),
            "K": _values(dataset, f"{event}_K", dims, ("i", "j")),
            "load": _values(dataset, f"{event}_load", dims, ()),
        }
    fixed = {
        key[len("parameter_") :]: value
        for key, value in dataset.attrs.items()
        if key.startswith("parameter_")
    }
    coords = {
        dim: np.asarray(dataset[dim].values) if dim in dataset.coords else None for dim in dims
    }

    cases = []
    for index in np.ndindex(n_steps.shape):
        n = max(int(n_steps[index]), 0)
        labels = {
            dim: (coords[dim][k] if coords[dim] is not None else k) for dim, k in zip(dims, index)
        }
        law = str(labels.pop("law", "law"))
        swept = {
            dim: value.item() if isinstance(value, np.generic) else value
            for dim, value in labels.items()
        }

        case_events = {}
        for event, fields in events.items():
            located = fields["F"][index]
            if np.all(np.isfinite(located)):
                case_events[event] = _case_event(event, fields, index)
        cases.append(
            Case(
                law=law,
                swept=swept,
                fixed=fixed,
                status=str(status[index]) if status is not None else "finished",
                u=np.asarray(u[index][:n], dtype=float),
                F=np.asarray(F[index][:n], dtype=float),
                **{name: _first_steps(steps[name], index, n) for name in _STEP_VARIABLES},
                events=case_events,
            )
        )
    return cases
