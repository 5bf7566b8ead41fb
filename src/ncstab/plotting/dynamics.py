"""Figures of dynamic stability: the root locus, the frequencies, the damping map.

Drawn from a Dataset alone: the spectrum stored along the paths
(``spectrum_re``, ``spectrum_im``: ``[output] spectrum = true``) and the located
``flutter_onset_load`` over a sweep of the dashpots (b1, b2).

* ``root_locus``: the roots s of det(M s^2 + C s + K) in the complex plane,
  coloured by the load: a pair meets and leaves the imaginary axis at the
  flutter onset (the onset marked).
* ``frequencies``: Im s >= 0 against the load: two frequencies coalesce at
  an undamped flutter onset; states with Re s > 0 drawn thick.
* ``damping_map``: the critical load over the plane of the dashpots (b1, b2),
  and along the diagonal b1 = b2 against the damping b, with the undamped
  flutter load and the vanishing-damping limit (Ziegler's destabilization
  paradox: the limit lies below the undamped load).
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr
from matplotlib import rc_context
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ncstab.plotting.style import FIGURE_SIZE, RC_PARAMS
from ncstab.plotting.sweep_shape import sweep_shape

__all__ = ["damping_map_figure", "frequencies_figure", "root_locus_figure"]

#: Cases drawn by the spectrum figures (one panel each).
MAX_PANELS = 4
#: Size of one root-locus panel, inches (width, height).
PANEL_WIDTH, PANEL_HEIGHT = 2.6, 2.6
#: Most ticks on the Re s axis (its labels are long: "-0.025").
RE_TICKS = 4


def _require(dataset: xr.Dataset, names: tuple[str, ...], kind: str) -> None:
    missing = [name for name in names if name not in dataset]
    if missing:
        raise ValueError(
            f"figure {kind!r} needs {', '.join(missing)} in the Dataset: a system with inertia and a load "
            "parameter, with [output] spectrum = true"
        )


def _cases(dataset: xr.Dataset) -> list[dict]:
    shape = sweep_shape(dataset)
    return [dict(zip(shape.dims, p)) for p in np.ndindex(*[shape.sizes[d] for d in shape.dims])][:MAX_PANELS]


def _panel_title(dataset: xr.Dataset, index: dict) -> str:
    parts = [f"{name} = {dataset[name].values[value]:.4g}" for name, value in index.items() if name != "law"]
    return ", ".join(parts) or str(dataset.attrs.get("study_description", ""))


def _spectrum(dataset: xr.Dataset, index: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = int(dataset["n_steps"].isel(index))
    load = dataset["load"].isel(index).values[:n]
    return load, dataset["spectrum_re"].isel(index).values[:n], dataset["spectrum_im"].isel(index).values[:n]


def _panel_grid(n: int) -> tuple[int, int]:
    """(rows, columns) of the spectrum panels: side by side up to three, else two columns."""
    return (1, n) if n <= 3 else (math.ceil(n / 2), 2)


def _cases_note(dataset: xr.Dataset, cases: list[dict]) -> str:
    """``" (the first 4 of 13 cases)"`` when the panels do not show every case, else ``""``."""
    total = sweep_shape(dataset).n_cases
    return f" (the first {len(cases)} of {total} cases)" if total > len(cases) else ""


def root_locus_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Re s against Im s of every root along the path, coloured by the load, per case.

    One panel per case (at most :data:`MAX_PANELS`: a row of up to three,
    two columns for four), each at least :data:`PANEL_WIDTH` inches wide with at most
    :data:`RE_TICKS` ticks on Re s (the real parts are small beside the
    imaginary ones: more ticks collide).  The flutter onset is starred on the
    root that crosses, its load written in the panel's title; one legend and
    one colour bar (the load) serve every panel, below and beside them.
    """
    _require(dataset, ("spectrum_re", "spectrum_im", "load"), "root_locus")
    cases = _cases(dataset)
    rows, columns = _panel_grid(len(cases))
    parameter = dataset.attrs.get("load_parameter", "P")
    with rc_context(RC_PARAMS):
        size = (max(FIGURE_SIZE[0], columns * PANEL_WIDTH + 1.6), max(FIGURE_SIZE[1], rows * PANEL_HEIGHT + 1.4))
        figure = figure if figure is not None else Figure(figsize=size, layout="constrained")
        grid = figure.subplots(rows, columns, squeeze=False, sharex=True, sharey=True)
        panels = list(grid.ravel())
        for spare in panels[len(cases):]:
            spare.set_visible(False)
        loads = dataset["load"].values
        norm = Normalize(np.nanmin(loads), np.nanmax(loads))
        onset_handle = None
        for axes, index in zip(panels, cases):
            load, real, imag = _spectrum(dataset, index)
            points = axes.scatter(
                real.ravel(), imag.ravel(), c=np.repeat(load, real.shape[-1]), norm=norm, cmap="viridis", s=6,
                gid="roots",
            )
            onset = float(dataset["flutter_onset_load"].isel(index)) if "flutter_onset_load" in dataset else np.nan
            title = _panel_title(dataset, index)
            if np.isfinite(onset):
                k = int(np.nanargmin(np.abs(load - onset)))
                (onset_handle,) = axes.plot(real[k], imag[k], "*", color="k", markersize=10, linestyle="none",
                                            gid="event:flutter_onset", label="flutter onset")
                title = f"{title}\nflutter at {parameter} = {onset:.4g}" if title else f"flutter at {parameter} = {onset:.4g}"
            axes.axvline(0.0, color="0.3", linewidth=0.8)
            axes.xaxis.set_major_locator(MaxNLocator(RE_TICKS, symmetric=True, prune="both"))  # apart from the next panel's
            axes.set_title(title, fontsize=9)
        for axes in grid[-1]:
            axes.set_xlabel("Re s")
        for axes in grid[:, 0]:
            axes.set_ylabel("Im s")
        figure.colorbar(points, ax=panels, label=f"load {parameter}", shrink=0.8)
        if onset_handle is not None:
            figure.legend([onset_handle], ["flutter onset: a pair of roots crosses into Re s > 0"],
                          loc="outside lower center").set_gid("legend")
        figure.suptitle("Root locus of det(M s² + C s + K) along the path" + _cases_note(dataset, cases))
    return figure


def frequencies_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """The frequencies Im s >= 0 against the load; thick where Re s > 0 (unstable)."""
    _require(dataset, ("spectrum_re", "spectrum_im", "load"), "frequencies")
    cases = _cases(dataset)
    parameter = dataset.attrs.get("load_parameter", "P")
    with rc_context(RC_PARAMS):
        rows, columns = _panel_grid(len(cases))
        size = (max(FIGURE_SIZE[0], columns * PANEL_WIDTH + 1.0), max(FIGURE_SIZE[1], rows * PANEL_HEIGHT + 1.2))
        figure = figure if figure is not None else Figure(figsize=size, layout="constrained")
        grid = figure.subplots(rows, columns, squeeze=False, sharey=True)
        panels = list(grid.ravel())
        for axes, index in zip(panels, cases):
            load, real, imag = _spectrum(dataset, index)
            upper = imag >= 0
            frequency = np.where(upper, imag, np.nan)
            growing = np.where(upper & (real > 1e-9), imag, np.nan)
            for root in range(frequency.shape[-1]):
                axes.plot(load, frequency[:, root], ".", color="C0", markersize=2.5, gid="frequency")
                axes.plot(load, growing[:, root], ".", color="C3", markersize=4.0, gid="unstable")
            onset = float(dataset["flutter_onset_load"].isel(index)) if "flutter_onset_load" in dataset else np.nan
            title = _panel_title(dataset, index)
            if np.isfinite(onset):  # said in the title: a note beside the line may leave a narrow panel
                axes.axvline(onset, color="k", linewidth=0.8, linestyle=(0, (4, 2.5)), gid="event:flutter_onset")
                title = "\n".join(filter(None, [title, f"flutter onset (dashed) at {parameter} = {onset:.4g}"]))
            axes.set_xlabel(f"load {parameter}")
            axes.set_title(title, fontsize=9)
        for axes in grid[:, 0]:
            axes.set_ylabel("frequency Im s ≥ 0 (red: Re s > 0)")
        figure.suptitle("Frequencies of M s² + C s + K along the path" + _cases_note(dataset, cases))
    return figure


def damping_map_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """The flutter load over the dashpots (b1, b2), and along b1 = b2 against b.

    The undamped flutter load (a case with b1 = b2 = 0 where the sweep has
    one, else the closed form for the study's masses,
    :func:`ncstab.systems.closed_forms.ziegler_flutter_load`) is drawn as a
    line: a vanishing damping does not tend to it.  With masses 2m and m the
    equal-damping limit 41/28 is drawn too.
    """
    from ncstab.systems.closed_forms import ziegler_equal_damping_flutter_load, ziegler_flutter_load

    _require(dataset, ("flutter_onset_load",), "damping_map")
    for name in ("b1", "b2"):
        if name not in dataset.dims:
            raise ValueError("figure 'damping_map' needs a sweep over both dashpots b1 and b2")
    values = np.asarray(dataset["flutter_onset_load"].isel(law=0).transpose("b2", "b1").values)
    b1, b2 = np.asarray(dataset["b1"].values), np.asarray(dataset["b2"].values)
    positive = bool((b1 > 0).all() and (b2 > 0).all())
    m1, m2 = (float(dataset.attrs.get(f"parameter_{m}", default)) for m, default in (("m1", 2.0), ("m2", 1.0)))
    undamped = float(ziegler_flutter_load(m1, m2)) if dataset.attrs.get("system") == "ziegler" else np.nan
    if 0.0 in b1 and 0.0 in b2:
        undamped = float(values[np.flatnonzero(b2 == 0.0)[0], np.flatnonzero(b1 == 0.0)[0]])
    with rc_context(RC_PARAMS):
        figure = figure if figure is not None else Figure(figsize=(FIGURE_SIZE[0] * 1.6, FIGURE_SIZE[1]), layout="constrained")
        plane, diagonal = figure.subplots(1, 2)
        mesh = plane.pcolormesh(b1, b2, values, shading="nearest", cmap="magma", gid="critical_load")
        if positive:
            plane.set_xscale("log")
            plane.set_yscale("log")
        figure.colorbar(mesh, ax=plane, label="flutter onset load P")
        plane.set_xlabel(r"$b_1$ (base dashpot)")
        plane.set_ylabel(r"$b_2$ (middle dashpot)")
        plane.set_title("critical load over the damping plane")
        common = np.intersect1d(b1, b2)
        common = common[common > 0]
        if common.size:
            along = np.array([values[np.flatnonzero(b2 == b)[0], np.flatnonzero(b1 == b)[0]] for b in common])
            diagonal.plot(common, along, "o-", markersize=3, gid="diagonal", label="damped, b₁ = b₂ = b")
            diagonal.set_xscale("log")
        if np.isfinite(undamped):
            diagonal.axhline(undamped, color="C3", linestyle=(0, (4, 2.5)), gid="undamped",
                             label=f"undamped: P = {undamped:.4g}")
        if dataset.attrs.get("system") == "ziegler" and (m1, m2) == (2.0, 1.0):
            limit = float(ziegler_equal_damping_flutter_load(0.0))
            diagonal.axhline(limit, color="0.4", linestyle=":", gid="limit",
                             label=f"b → 0 (Routh–Hurwitz): 41/28 = {limit:.4g}")
        diagonal.set_xlabel("damping b")
        diagonal.set_ylabel("flutter onset load P")
        diagonal.set_title("the destabilization paradox (b → 0)")
        diagonal.legend(loc="center right")
        figure.suptitle(str(dataset.attrs.get("study_description", "Flutter load over the damping")))
    return figure
