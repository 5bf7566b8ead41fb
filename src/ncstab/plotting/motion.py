"""Figures of a dynamic stage's motion, from the Dataset's ``time`` variables alone.

* ``motion``: every dof's displacement u(t) (top) and log10 |u(t) - u(0)| (bottom:
  a growing linear mode is a straight line of slope max Re s / ln 10);
* ``phase_portrait``: velocity against displacement, one panel per dof;
* ``energies``: kinetic energy and the works of the controls and loads, of the
  interactions and of the dashpots against time, with the largest residual of
  kinetic_energy = external_work - internal_work - dissipated_work in the title.

One line per case (at most :data:`MAX_CASES`), coloured by case.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib import rc_context
from matplotlib.figure import Figure

from ncstab.plotting.style import FIGURE_SIZE, RC_PARAMS

__all__ = ["energies_figure", "motion_figure", "phase_portrait_figure"]

#: Cases drawn (the first ones of the sweep).
MAX_CASES = 6
#: Line colours of the energies figure.
ENERGY_COLOURS = {"kinetic_energy": "C0", "external_work": "C1", "internal_work": "C2", "dissipated_work": "C3"}


def _require(dataset: xr.Dataset, kind: str) -> None:
    if "u_t" not in dataset or "time" not in dataset.coords:
        raise ValueError(f"figure {kind!r} needs the motion of a dynamic stage (u_t over time) in the Dataset")


def _cases(dataset: xr.Dataset) -> list[tuple[dict, str]]:
    """(index, label) of the cases drawn."""
    dims = list(dataset["motion_status"].dims)
    sizes = [dataset.sizes[d] for d in dims]
    out = []
    for position in list(np.ndindex(*sizes))[:MAX_CASES]:
        index = dict(zip(dims, position))
        parts = [f"{d} = {dataset[d].values[i]:.4g}" if d != "law" else str(dataset[d].values[i]) for d, i in index.items()]
        out.append((index, ", ".join(parts)))
    return out


def _dof_label(dataset: xr.Dataset, dof: str, prefix: str = "") -> str:
    units = dataset["u_t"].attrs.get("units", "1")
    return f"{prefix}{dof}" + (f" ({units})" if units not in ("1", "") else "")


def motion_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """u(t) of every dof and case, and log10 |u(t) - u(0)|."""
    _require(dataset, "motion")
    with rc_context(RC_PARAMS):
        figure = figure or Figure(figsize=FIGURE_SIZE)
        top, bottom = figure.subplots(2, 1, sharex=True)
        time = dataset["time"].values
        styles = ["-", "--", ":", "-."]
        for k, (index, label) in enumerate(_cases(dataset)):
            u = dataset["u_t"].isel(index).values
            for d, dof in enumerate(dataset["dof"].values):
                name = f"{dof}, {label}" if label else str(dof)
                top.plot(time, u[:, d], styles[d % 4], color=f"C{k}", label=name)
                with np.errstate(divide="ignore"):
                    bottom.plot(time, np.log10(np.abs(u[:, d] - u[0, d])), styles[d % 4], color=f"C{k}")
        top.set_ylabel("u")
        bottom.set_ylabel("log10 |u - u(0)|")
        bottom.set_xlabel("time")
        top.legend(loc="best")
        top.set_title("motion of the dynamic stage")
        figure.tight_layout()
    return figure


def phase_portrait_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Velocity against displacement, one panel per dof (at most four)."""
    _require(dataset, "phase_portrait")
    with rc_context(RC_PARAMS):
        figure = figure or Figure(figsize=FIGURE_SIZE)
        dofs = list(dataset["dof"].values)[:4]
        axes = np.atleast_1d(figure.subplots(1, len(dofs), squeeze=False)[0])
        for k, (index, label) in enumerate(_cases(dataset)):
            u = dataset["u_t"].isel(index).values
            v = dataset["velocity"].isel(index).values
            for d, axis in enumerate(axes):
                axis.plot(u[:, d], v[:, d], "-", lw=0.8, color=f"C{k}", label=label or None)
                axis.plot(u[:1, d], v[:1, d], "o", color=f"C{k}")
        for d, axis in enumerate(axes):
            axis.set_xlabel(_dof_label(dataset, dofs[d]))
            axis.set_ylabel(f"d{dofs[d]}/dt")
        if any(label for _, label in _cases(dataset)):
            axes[0].legend(loc="best")
        figure.suptitle("phase portrait (o: start)")
        figure.tight_layout()
    return figure


def energies_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Kinetic energy and the three works against time, with the balance's largest residual."""
    _require(dataset, "energies")
    with rc_context(RC_PARAMS):
        figure = figure or Figure(figsize=FIGURE_SIZE)
        axis = figure.subplots()
        time = dataset["time"].values
        residual = 0.0
        for k, (index, label) in enumerate(_cases(dataset)):
            values = {name: dataset[name].isel(index).values for name in ENERGY_COLOURS}
            for name, colour in ENERGY_COLOURS.items():
                style = ["-", "--", ":", "-."][k % 4]
                text = name.replace("_", " ") + (f" ({label})" if label and k else "")
                axis.plot(time, values[name], style, color=colour, label=text if k == 0 or label else None)
            balance = values["kinetic_energy"] - (values["external_work"] - values["internal_work"] - values["dissipated_work"])
            if np.isfinite(balance).any():
                residual = max(residual, float(np.nanmax(np.abs(balance))))
        axis.set_xlabel("time")
        axis.set_ylabel("energy")
        axis.legend(loc="best")
        axis.set_title(f"energy balance: max |kinetic - (external - internal - dissipated)| = {residual:.2g}")
        figure.tight_layout()
    return figure
