"""The cycles of a path Dataset in the (Delta_1*, Delta_2*) plane and in the (alpha, l*) plane.

In the (alpha, l*) plane the area enclosed by one turn is |I| = |oint l* dalpha|
(seed Eq. 11).  Cases with the same path (kinematic control: every law follows
the same circle) are drawn once.  See ``docs/green-paradox.md``.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr
from matplotlib import colormaps, rc_context
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ncstab.plotting.cycle_cases import CycleCase, cycle_cases
from ncstab.plotting.cycle_style import CycleStyle, cycle_styles, new_figure, subtitle
from ncstab.plotting.style import RC_PARAMS, law_display_name

__all__ = ["SAME_PATH_TOLERANCE", "cycle_paths_figure"]

#: Two cases share a path if their start states and circles (centre, radius) agree to this.
SAME_PATH_TOLERANCE = 1e-8


def _circles(case: CycleCase) -> np.ndarray:
    """Per cycle stage of the case: centre (2) and radius of its circle, flattened."""
    rows = []
    for _, where in case.stage_slices():
        if where.size < 3:
            return np.full(1, np.nan)
        centre = _circle_centre(case.u[where])
        radius = float(np.mean(np.hypot(*(case.u[where] - centre).T)))
        rows.append([*centre, radius])
    return np.ravel(rows)


def _same_path(a: CycleCase, b: CycleCase) -> bool:
    """Same stages on the same circles from the same start state (to SAME_PATH_TOLERANCE)."""
    if a.u.shape[0] == 0 or b.u.shape[0] == 0:
        return False
    if not np.array_equal(np.unique(a.stage), np.unique(b.stage)):
        return False
    first = np.concatenate([a.u[0], _circles(a)])
    second = np.concatenate([b.u[0], _circles(b)])
    return first.shape == second.shape and bool(
        np.allclose(first, second, rtol=0, atol=SAME_PATH_TOLERANCE)
    )


def _circle_centre(points: np.ndarray) -> np.ndarray:
    """Centre of the circle through the points (algebraic least squares, exact on a circle)."""
    x, y = points[:, 0], points[:, 1]
    matrix = np.column_stack([x, y, np.ones_like(x)])
    (a, b, _), *_ = np.linalg.lstsq(matrix, -(x**2 + y**2), rcond=None)
    return np.array([-a / 2, -b / 2])


def _direction_arrow(
    ax: Axes, x: np.ndarray, y: np.ndarray, fraction: float, colour: object, text: str
) -> None:
    """An arrow head along the polyline at the given fraction of its points, labelled."""
    if x.size < 3:
        return
    i = min(int(fraction * (x.size - 1)), x.size - 2)
    ax.annotate(
        "",
        xy=(x[i + 1], y[i + 1]),
        xytext=(x[i], y[i]),
        arrowprops={
            "arrowstyle": "-|>",
            "color": colour,
            "lw": 1.2,
            "mutation_scale": 15,
            "shrinkA": 0,
            "shrinkB": 0,
        },
    )
    ax.annotate(
        text,
        xy=(x[i + 1], y[i + 1]),
        xytext=(4, 4),
        textcoords="offset points",
        fontsize=8,
        color=colour,
        fontweight="bold",
    )


def cycle_paths_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """The cycle stages in the (Delta_1*, Delta_2*) plane and in the (alpha, l*) plane.

    Only the states of the cycle stages are drawn.  Cases with the same path
    (kinematic control: every law follows the same circle) are drawn once.
    In the (alpha, l*) plane the area enclosed by one turn is
    |I| = |oint l* dalpha| (seed Eq. 11; I changes sign with the direction),
    shaded; the dotted line is alpha = alpha0.

    Parameters
    ----------
    dataset
        A path Dataset with cycle stages.
    figure
        A Figure to draw into (a new one, constrained layout, by default).

    Returns
    -------
    matplotlib.figure.Figure
        Two axes (Delta plane, (alpha, l*) plane); one line per distinct path
        in each, ``gid`` ``"cycle_path_u:<k>"`` and ``"cycle_path_alpha_l:<k>"``.
    """
    cases, layout = cycle_cases(dataset)
    styles = cycle_styles(cases)
    groups: list[list[int]] = []
    for i, case in enumerate(cases):
        for group in groups:
            if _same_path(cases[group[0]], case):
                group.append(i)
                break
        else:
            groups.append([i])
    all_laws = {c.law for c in cases}
    law_independent = (
        all({cases[i].law for i in g} == all_laws for g in groups) and len(all_laws) > 1
    )
    if law_independent and len(groups) > 1:
        viridis = colormaps["viridis"]
        colours: list[object] = [viridis(0.85 * k / (len(groups) - 1)) for k in range(len(groups))]
    else:
        colours = [styles[g[0]].colour for g in groups]
    with rc_context(RC_PARAMS):
        figure = new_figure(figure, (11.0, 5.0))
        ax_u, ax_q = figure.subplots(1, 2)
        handles = []
        for k, (group, colour) in enumerate(zip(groups, colours)):
            case = cases[group[0]]
            if case.u.shape[0] == 0:
                continue
            style = styles[group[0]] if not law_independent else CycleStyle(colour, "o", "-")
            if law_independent:
                label = case.parameter_label or "all laws"
            else:
                laws = ", ".join(law_display_name(cases[i].law) for i in group)
                label = ", ".join(t for t in (laws, case.parameter_label) if t)
            ax_u.plot(
                case.u[:, 0],
                case.u[:, 1],
                color=colour,
                ls=style.linestyle,
                lw=1.5,
                gid=f"cycle_path_u:{k}",
            )
            ax_q.plot(
                case.alpha,
                case.l,
                color=colour,
                ls=style.linestyle,
                lw=1.5,
                gid=f"cycle_path_alpha_l:{k}",
            )
            ax_u.plot(
                case.u[0, 0],
                case.u[0, 1],
                ls="none",
                marker="o",
                color="k",
                ms=5,
                zorder=5,
                gid="cycle_start",
            )
            for n, (stage, where) in enumerate(case.stage_slices()):
                first_turn = where[case.lam[where] <= 2 * math.pi * (1 + 1e-9)]
                fraction = 0.15 + 0.35 * (n % 2)
                number = str(stage + 1)
                _direction_arrow(
                    ax_u, case.u[first_turn, 0], case.u[first_turn, 1], fraction, colour, number
                )
                _direction_arrow(
                    ax_q, case.alpha[first_turn], case.l[first_turn], fraction, colour, number
                )
                if n == 0 and first_turn.size >= 3:
                    ax_q.fill(
                        case.alpha[first_turn],
                        case.l[first_turn],
                        color=colour,
                        alpha=max(0.04, 0.36 / len(groups)),
                        lw=0,
                        gid="enclosed_area",
                    )
                    centre = _circle_centre(case.u[first_turn])
                    ax_u.plot(
                        *centre,
                        ls="none",
                        marker="+",
                        color=colour,
                        ms=9,
                        mew=1.5,
                        gid="cycle_centre",
                    )
            handles.append(Line2D([], [], color=colour, ls=style.linestyle, lw=1.5, label=label))
        alpha0 = {c.alpha0 for c in cases if np.isfinite(c.alpha0)}
        for value in sorted(alpha0):
            ax_q.axvline(value, color="0.35", ls=":", lw=1.0, gid="alpha0")
        if alpha0:
            ax_q.text(
                min(alpha0),
                0.02,
                r" $\alpha = \alpha_0$",
                transform=ax_q.get_xaxis_transform(),
                ha="left",
                va="bottom",
                fontsize=8.5,
                color="0.25",
            )
        ax_u.set_aspect("equal", adjustable="datalim")
        ax_u.set_xlabel(r"$\Delta_1^* = \Delta_1/2R$")
        ax_u.set_ylabel(r"$\Delta_2^* = \Delta_2/2R$")
        ax_u.set_title(r"displacements: start $\bullet$, centre +, arrow per stage", fontsize=9)
        ax_q.set_xlabel(r"$\alpha$ (rad)")
        ax_q.set_ylabel(r"$l^* = l/2R$")
        ax_q.set_title(r"contact: shaded area $= |I|$, $I = \oint l^*\,d\alpha$", fontsize=9)
        handles += [
            Line2D(
                [], [], ls="none", marker="o", color="k", ms=5, label="start of the cycle stages"
            ),
        ]
        if len(handles) <= 5:
            figure.legend(handles=handles, loc="outside lower center", ncols=len(handles))
        else:
            figure.legend(handles=handles, loc="outside right upper")
        figure.suptitle(
            "Closed kinematic cycles: " + subtitle(dataset, layout, stages=True), fontsize=10
        )
    return figure
