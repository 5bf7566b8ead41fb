"""Second-order work figures: directional maps, polar plots, state maps.

Drawn from a path Dataset only: ``d2W_dir``/``cone_*`` (``[map] directions``)
and ``map_*`` fields (``[map] grid``), see docs/archive.md.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib import rc_context
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure

from ncstab.operators.directional_work import directional_second_order_work
from ncstab.plotting.style import RC_PARAMS, law_display_name

__all__ = ["second_order_work_map_figure", "second_order_work_polar_figure", "state_map_figure"]

#: At most this many cases get a panel (the first ones, in sweep order).
MAX_PANELS = 4


def _cases(dataset: xr.Dataset) -> list[tuple[str, dict, xr.Dataset]]:
    """(label, selection, case Dataset) for every case, in sweep order."""
    sweep = [d for d in dataset["status"].dims]
    stacked = []
    for index in np.ndindex(*dataset["status"].shape):
        selection = {d: dataset[d].values[i] for d, i in zip(sweep, index)}
        case = dataset.isel({d: i for d, i in zip(sweep, index)})
        parts = [law_display_name(str(selection["law"]))]
        parts += [f"{d} = {selection[d]:g}" for d in sweep if d != "law"]
        stacked.append((", ".join(parts), selection, case))
    return stacked


def _require(dataset: xr.Dataset, name: str, section: str) -> None:
    if name not in dataset:
        raise ValueError(f"this figure needs the variable {name!r}: add {section} to the study's [map] section")


def _norm(values: np.ndarray) -> TwoSlopeNorm:
    finite = values[np.isfinite(values)]
    low = min(float(finite.min()) if finite.size else -1.0, -1e-12)
    high = max(float(finite.max()) if finite.size else 1.0, 1e-12)
    return TwoSlopeNorm(vcenter=0.0, vmin=low, vmax=high)


def second_order_work_map_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """d2W(theta) along each path (x: arclength s, y: direction theta), cone outlined.

    Blue where the second-order work du . K du is negative: the cone of
    unstable loading directions; its exact bounds (``cone_lower``,
    ``cone_upper``, roots of the quadratic form) are drawn as black lines.
    """
    _require(dataset, "d2W_dir", "directions = M")
    cases = _cases(dataset)[:MAX_PANELS]
    with rc_context(RC_PARAMS):
        fig = figure or Figure(figsize=(6.4, 2.4 + 1.9 * len(cases)), layout="constrained")
        axes = fig.subplots(len(cases), 1, sharex=False, squeeze=False)[:, 0]
        theta = dataset["theta"].values
        for ax, (label, _, case) in zip(axes, cases):
            n = int(case["n_steps"])
            # Arclength: monotonic through every stage (stage boundaries are stored twice).
            s_values, keep = np.unique(case["s"].values[:n], return_index=True)
            x = s_values
            values = case["d2W_dir"].values[:n][keep]
            mesh = ax.pcolormesh(x, theta, values.T, shading="nearest", cmap="RdBu", norm=_norm(values))
            fig.colorbar(mesh, ax=ax, label=r"$\mathrm{d}u\cdot K\,\mathrm{d}u$ ($|\mathrm{d}u| = 1$)")
            lower, upper = case["cone_lower"].values[:n][keep], case["cone_upper"].values[:n][keep]
            for event, marker in (("hill_loss", "s"), ("limit_point", "o")):
                at = float(case[f"{event}_s"])
                if np.isfinite(at):
                    ax.axvline(at, color="0.3", linestyle=":", linewidth=0.8)
                    ax.plot([at], [np.pi * 0.97], marker=marker, color="k", markerfacecolor="none", clip_on=False)
            for bound in (lower, upper, upper - np.pi):
                inside = np.where((bound >= 0) & (bound < np.pi), bound, np.nan)
                ax.plot(x, inside, color="k", linewidth=1.0, gid="cone_bound")
            ax.set_ylabel(r"direction $\theta$ (rad)")
            ax.set_ylim(0, np.pi)
            ax.set_title(label, fontsize=9)
        axes[-1].set_xlabel(r"arclength $s$ of the path (dotted: Hill loss, square; limit point, circle)")
        fig.suptitle("Second-order work by loading direction; black: bounds of the unstable cone", fontsize=10)
    return fig


def second_order_work_polar_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Polar plots of d2W(theta) = du . K du at five states of the first case.

    The states are the start, the end and three states between (the located
    Hill loss replaces the middle one when there is one).  Negative values
    (unstable directions) are drawn on the dashed inner side of the zero circle.
    """
    label, _, case = _cases(dataset)[0]
    n = int(case["n_steps"])
    if n == 0:
        raise ValueError("the first case has no stored state")
    K = case["K"].values[:n]
    picks = sorted(set(np.linspace(0, n - 1, 5).astype(int).tolist()))
    matrices = [K[i] for i in picks]
    names = [f"step {i}" for i in picks]
    if "hill_loss_K" in case and np.isfinite(case["hill_loss_K"].values).all():
        matrices[len(matrices) // 2] = case["hill_loss_K"].values
        names[len(names) // 2] = "Hill loss"
    theta = np.linspace(0, 2 * np.pi, 361)
    with rc_context(RC_PARAMS):
        fig = figure or Figure(figsize=(6.4, 5.2), layout="constrained")
        ax = fig.add_subplot(projection="polar")
        values = [directional_second_order_work(k, theta) for k in matrices]
        lowest = min(float(v.min()) for v in values)
        highest = max(float(v.max()) for v in values)
        # Offset the radius so that d2W = 0 is a visible circle inside every curve's range.
        shift = max(-lowest, 0.0) + 0.25 * max(highest - min(lowest, 0.0), 1e-12)
        for name, v in zip(names, values):
            ax.plot(theta, v + shift, label=name, gid=f"polar:{name}")
        ax.plot(theta, np.full_like(theta, shift), color="k", linestyle="--", linewidth=0.8, label="d²W = 0")
        ax.set_rticks([])
        ax.set_title(f"{label}\nd²W(θ) = du·K du, radius shifted by {shift:.3g} so that 0 is the dashed circle",
                     fontsize=9)
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8)
    return fig


def state_map_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Hill's eigenvalue over the displacement plane, with the case's path over it.

    One panel per case with a state map (laws with a total form; at most
    :data:`MAX_PANELS`): colour = smallest eigenvalue of K_sym; thick line:
    Hill's condition lost (0); dashed: det K = 0; dotted: K22 = 0
    (controllability lost with F2 held).  The case's equilibrium path is drawn
    over its own map, with its located Hill loss (square) and limit point (circle).
    """
    _require(dataset, "map_hill", "a grid")
    cases = [c for c in _cases(dataset) if np.isfinite(c[2]["map_hill"].values).any()][:MAX_PANELS]
    if not cases:
        raise ValueError("no case of this Dataset has a state map (only laws with a total form do)")
    d1, d2 = dataset["map_D1"].values, dataset["map_D2"].values
    with rc_context(RC_PARAMS):
        fig = figure or Figure(figsize=(6.4, 3.6 * len(cases)), layout="constrained")
        axes = fig.subplots(len(cases), 1, squeeze=False)[:, 0]
        for ax, (label, _, case) in zip(axes, cases):
            hill = case["map_hill"].values
            mesh = ax.pcolormesh(d1, d2, hill.T, shading="nearest", cmap="RdBu", norm=_norm(hill))
            fig.colorbar(mesh, ax=ax, label=r"$\lambda_\min(K_\mathrm{sym})$")
            for field, style in (("map_hill", "-"), ("map_det_K", "--"), ("map_mixed_control_F2", ":")):
                values = case[field].values
                if np.nanmin(values) < 0 < np.nanmax(values):
                    ax.contour(d1, d2, values.T, levels=[0.0], colors="k", linestyles=style,
                               linewidths=1.6 if style == "-" else 1.0)
            n = int(case["n_steps"])
            u = case["u"].values[:n]
            ax.plot(u[:, 0], u[:, 1], color="tab:orange", linewidth=1.6, label="equilibrium path", gid=f"path:{label}")
            for event, marker in (("limit_point", "o"), ("hill_loss", "s")):
                point = case[f"{event}_u"].values
                if np.isfinite(point).all():
                    ax.plot(*point, marker=marker, color="k", markerfacecolor="none", linestyle="none",
                            label=event.replace("_", " "))
            ax.set_xlim(d1[0], d1[-1])
            ax.set_ylim(d2[0], d2[-1])
            ax.set_xlabel(r"$\Delta_1^* = \Delta_1/2R$")
            ax.set_ylabel(r"$\Delta_2^* = \Delta_2/2R$")
            ax.set_title(label, fontsize=9)
            ax.legend(fontsize=8, loc="lower left")
        fig.suptitle(r"$\lambda_\min(K_\mathrm{sym})$ over the displacement plane: solid = 0 (Hill), "
                     r"dashed det K = 0, dotted $K_{22}$ = 0", fontsize=9)
    return fig
