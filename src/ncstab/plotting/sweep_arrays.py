"""Quantities of every case of a path Dataset as arrays, for figures of large sweeps.

No per-case objects: each quantity is one array with the case dimensions
first (``(*case_dims, step)`` along paths, ``(*case_dims,)`` at an event or
at the end of a path), read once from the Dataset.  Generalized forces and
displacements are those of the first dof present in the Dataset (``F1*``,
``Delta1*`` for the diamond).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr

from ncstab.plotting.style import AXIS_LABELS, force_label

__all__ = [
    "PATH_QUANTITIES",
    "end_values",
    "event_values",
    "events_present",
    "path_values",
    "quantity_label",
]

#: Quantity -> (per-step variable, its value at an event: ``<event>_<field>`` or ``"K"``
#: for a function of the event's tangent operator, None if the event does not store it).
PATH_QUANTITIES: dict[str, tuple[str, str | None]] = {
    "F1": ("F", "F"),
    "D1": ("u", "u"),
    "alpha": ("alpha", "alpha"),
    "det_K": ("det_K", "K"),
    "hill": ("hill", "K"),
    "d2W": ("d2W", None),
}


def quantity_label(quantity: str, normal: str = "deformable") -> str:
    """Axis or colour-bar label of a quantity (with units)."""
    if quantity == "F1":
        return force_label(normal)
    return AXIS_LABELS[quantity]


def _case_array(dataset: xr.Dataset, name: str, dims: Sequence[str], tail: tuple[str, ...]) -> np.ndarray:
    """``dataset[name]`` as floats, case dims first, then ``tail``; first dof if it has one."""
    array = dataset[name]
    if "dof" in array.dims:
        array = array.isel(dof=0)
    return np.asarray(array.transpose(*dims, *tail).values, dtype=float)


def path_values(dataset: xr.Dataset, quantity: str, dims: Sequence[str]) -> np.ndarray:
    """``(*case_dims, step)``: the quantity at every stored state, NaN past ``n_steps``.

    A Dataset without the variable gives NaN everywhere.
    """
    name, _ = PATH_QUANTITIES[quantity]
    if name not in dataset:
        return np.full(tuple(dataset.sizes[d] for d in dims) + (dataset.sizes["step"],), np.nan)
    values = _case_array(dataset, name, dims, ("step",))
    n_steps = np.asarray(dataset["n_steps"].transpose(*dims).values)
    values[np.arange(values.shape[-1]) >= n_steps[..., None]] = np.nan
    return values


def end_values(values: np.ndarray, n_steps: np.ndarray) -> np.ndarray:
    """``(*case_dims,)``: the last stored state of each case (NaN for a case without states).

    Parameters
    ----------
    values
        ``(*case_dims, step)`` from :func:`path_values`.
    n_steps
        ``(*case_dims,)`` stored states per case.
    """
    last = np.clip(np.asarray(n_steps, dtype=int) - 1, 0, max(values.shape[-1] - 1, 0))
    end = np.take_along_axis(values, last[..., None], axis=-1)[..., 0]
    return np.where(np.asarray(n_steps) > 0, end, np.nan)


def events_present(dataset: xr.Dataset, names: Sequence[str]) -> list[str]:
    """The events of ``names`` that the Dataset stores and locates in at least one case.

    An event whose table is absent (a lean archive drops the tables of events
    that never occur) or all NaN is left out.
    """
    present = []
    for name in names:
        variable = f"{name}_s"
        if variable in dataset and bool(np.isfinite(np.asarray(dataset[variable].values, dtype=float)).any()):
            present.append(name)
    return present


def event_values(dataset: xr.Dataset, event: str, quantity: str, dims: Sequence[str]) -> np.ndarray:
    """``(*case_dims,)``: the quantity at the first located ``event`` of each case (NaN where none).

    ``det_K`` and ``hill`` are computed from the event's tangent operator
    ``<event>_K`` (det K, smallest eigenvalue of its symmetric part); ``d2W``
    needs the path direction and is NaN.
    """
    shape = tuple(dataset.sizes[d] for d in dims)
    _, field = PATH_QUANTITIES[quantity]
    name = f"{event}_{field}"
    if field is None or name not in dataset:
        return np.full(shape, np.nan)
    if field != "K":
        return _case_array(dataset, name, dims, ())
    K = _case_array(dataset, name, dims, ("i", "j"))
    finite = np.isfinite(K).all(axis=(-2, -1))
    K = np.where(finite[..., None, None], K, 0.0)
    if quantity == "det_K":
        values = np.linalg.det(K)
    else:
        values = np.linalg.eigvalsh((K + np.swapaxes(K, -1, -2)) / 2)[..., 0]
    return np.where(finite, values, np.nan)
