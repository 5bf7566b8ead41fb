"""Figures of closed kinematic cycles (Green's paradox), drawn from a path Dataset only.

A cycle stage drives (Delta_1*, Delta_2*) around a circle; the Dataset records
the work per contact over each turn (``cycle_work``, seed Eq. 5), and every
stored state (``u``, ``F``, ``T``, ``alpha``, ``l``, the turned angle ``lam``
and the ``stage`` it belongs to).  Three figures, each
``(dataset) -> matplotlib.figure.Figure``:

``cycle_work_figure``
    |work| per cycle against the cycle number on a log scale, sign shown by the
    marker (filled: work done on the contacts, open: energy extracted);
    hyperelastic laws sit at round-off (a shaded band).
``cycle_paths_figure``
    The cycle in the (Delta_1*, Delta_2*) plane and in the (alpha, l*) plane,
    where the enclosed area is |I| = |oint l* dalpha|.
``cycle_force_drift_figure``
    F_1*, F_2* and T* against the cumulative number of turns: the ratcheting
    drift of Cundall--Strack, the return of the other laws.

Figures are built with :class:`matplotlib.figure.Figure` (no pyplot, no global
figure registry) under the project style (:data:`ncstab.plotting.style.RC_PARAMS`);
the caller saves them.  See ``docs/green-paradox.md``.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr
from matplotlib import rc_context
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ncstab.plotting.cycle_cases import CycleCase, CycleLayout, cycle_cases
from ncstab.plotting.cycle_paths import cycle_paths_figure
from ncstab.plotting.cycle_style import (
    cycle_styles,
    legend_handles,
    new_figure,
    stage_boundaries,
    stage_labels,
    subtitle,
)
from ncstab.plotting.style import RC_PARAMS

__all__ = [
    "CycleCase",
    "CycleLayout",
    "cycle_cases",
    "cycle_force_drift_figure",
    "cycle_paths_figure",
    "cycle_work_figure",
]

#: States whose turned angle is within this many turns of a whole number are
#: the located ends of turns (located to ``event_tol``, far below this).
TURN_END_TOLERANCE = 1e-6


def cycle_work_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """|work| per contact over each closed cycle against the cycle number.

    One curve per case (law x swept parameters) on a log scale: a filled
    marker where the work is positive (done on the contacts), an open one where
    it is negative (extracted).  Hyperelastic laws do no work over a closed
    cycle (seed Eq. 17-19: the integrand is dW); their values are round-off and
    sit in the shaded band.

    Parameters
    ----------
    dataset
        A path Dataset with cycle stages (``cycle_work``, ``cycle_stage``).
    figure
        A Figure to draw into (a new one, constrained layout, by default).

    Returns
    -------
    matplotlib.figure.Figure
        One axes.  Lines carry ``gid`` ``"cycle_work_line:<key>"`` (the curve,
        |W| at cycles where W != 0), ``"cycle_work_positive:<key>"`` and
        ``"cycle_work_negative:<key>"`` (the markers), with ``<key>`` of
        :attr:`CycleCase.key`.
    """
    cases, layout = cycle_cases(dataset)
    styles = cycle_styles(cases)
    cycles = np.arange(1, layout.n_cycles + 1)
    with rc_context(RC_PARAMS):
        figure = new_figure(figure, (9.0, 5.0))
        ax = figure.add_subplot()
        magnitudes = []
        for case, style in zip(cases, styles):
            work = case.work
            shown = np.isfinite(work) & (work != 0)
            positive, negative = shown & (work > 0), shown & (work < 0)
            ax.plot(
                cycles[shown],
                np.abs(work[shown]),
                color=style.colour,
                ls=style.linestyle,
                lw=0.9,
                alpha=0.7,
                gid=f"cycle_work_line:{case.key}",
            )
            ax.plot(
                cycles[positive],
                work[positive],
                ls="none",
                marker=style.marker,
                ms=6,
                color=style.colour,
                mfc=style.colour,
                gid=f"cycle_work_positive:{case.key}",
            )
            ax.plot(
                cycles[negative],
                -work[negative],
                ls="none",
                marker=style.marker,
                ms=6,
                color=style.colour,
                mfc="white",
                mew=1.3,
                gid=f"cycle_work_negative:{case.key}",
            )
            magnitudes.append(np.abs(work[shown]))
        ax.set_yscale("log")
        every = np.concatenate(magnitudes) if magnitudes else np.array([])
        hyper = [
            np.abs(c.work[np.isfinite(c.work)]) for c in cases if c.law_class == "hyperelastic"
        ]
        hyper_values = np.concatenate(hyper) if hyper else np.array([])
        bottom = float(every.min()) / 4 if every.size else 1e-18
        if hyper_values.size:
            largest = float(hyper_values.max())
            exponent = math.ceil(math.log10(largest)) if largest > 0 else -16
            bound = 10.0**exponent
            bottom = min(bottom, bound / 30)
            ax.axhspan(bottom, bound, color="0.9", zorder=0, lw=0, gid="round_off_band")
            ax.text(
                0.99,
                bound,
                rf"hyperelastic: $|W^*| < 10^{{{exponent}}}$ (round-off and integrator tolerance)",
                transform=ax.get_yaxis_transform(),
                ha="right",
                va="bottom",
                fontsize=8.5,
                color="0.2",
                gid="round_off_label",
            )
        top = float(every.max()) * 4 if every.size else 1.0
        if hyper_values.size:  # room above the band for its label (not over the title)
            top = max(top, bound * 30)
        ax.set_ylim(bottom, top)
        ax.set_xlim(0.5, layout.n_cycles + 0.5)
        ax.set_xticks(cycles)
        stage_boundaries(ax, layout, [layout.offset[k] + 0.5 for k in layout.stages[1:]])
        stage_labels(
            ax, layout, {k: layout.offset[k] + (layout.turns[k] + 1) / 2 for k in layout.stages}
        )
        ax.set_xlabel("cycle number (turn of a cycle stage)")
        ax.set_ylabel(r"$|W^*|$ per cycle and contact,  $W^* = W / k_n(2R)^2$")
        ax.set_title(
            r"Work over each closed cycle, $W^* = \oint \frac{1}{2}\,F^*\cdot d\Delta^*"
            r" = \oint (-N^*\,dl^* + T^*\,l^*\,d\alpha)$" + "\n" + subtitle(dataset, layout),
            pad=16,
        )
        handles = legend_handles(cases, styles, markers=True)
        handles += [
            Line2D(
                [],
                [],
                ls="none",
                marker="o",
                color="0.3",
                mfc="0.3",
                label=r"$W^* > 0$ (work done on the contacts)",
            ),
            Line2D(
                [],
                [],
                ls="none",
                marker="o",
                color="0.3",
                mfc="white",
                mew=1.3,
                label=r"$W^* < 0$ (energy extracted)",
            ),
        ]
        figure.legend(handles=handles, loc="outside right upper")
    return figure


def cycle_force_drift_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """F_1*, F_2* and T* against the cumulative number of turns of the cycle stages.

    A law with a total form (hyperelastic or weakly hypoelastic) brings the
    forces back at the end of every turn (markers); Cundall--Strack ratchets,
    T* drifting by gamma I per turn (seed Eq. 13, 14).

    Parameters
    ----------
    dataset
        A path Dataset with cycle stages.
    figure
        A Figure to draw into (a new one, constrained layout, by default).

    Returns
    -------
    matplotlib.figure.Figure
        Three axes sharing the turns axis; one line per case in each, ``gid``
        ``"force_drift:<F1|F2|T>:<key>"``, and the states at the ends of turns
        joined (``"force_drift_ends:<F1|F2|T>:<key>"``).
    """
    cases, layout = cycle_cases(dataset)
    styles = cycle_styles(cases)
    unit = str(dataset.attrs.get("force_unit", "2R k_n")).replace("2R k_", r"2R\,k_")
    quantities = (
        ("F1", rf"$F_1^* = F_1/({unit})$"),
        ("F2", rf"$F_2^* = F_2/({unit})$"),
        ("T", rf"$T^* = T/({unit})$"),
    )
    with rc_context(RC_PARAMS):
        figure = new_figure(figure, (9.0, 8.0))
        axes = figure.subplots(3, 1, sharex=True)
        for case, style in zip(cases, styles):
            x = case.turns.copy()
            series = {"F1": case.F[:, 0].copy(), "F2": case.F[:, 1].copy(), "T": case.T.copy()}
            # Break the line between stages (a non-cycle stage may lie between).
            breaks = np.flatnonzero(np.diff(case.stage) != 0) + 1
            x = np.insert(x, breaks, np.nan)
            ends = np.flatnonzero(np.abs(x - np.round(x)) < TURN_END_TOLERANCE)
            for ax, (name, _) in zip(axes, quantities):
                y = np.insert(series[name], breaks, np.nan)
                ax.plot(
                    x,
                    y,
                    color=style.colour,
                    ls=style.linestyle,
                    lw=1.0,
                    alpha=0.55,
                    gid=f"force_drift:{name}:{case.key}",
                )
                # The state at the end of every turn, joined: the drift (ratcheting) line.
                ax.plot(
                    x[ends],
                    y[ends],
                    color=style.colour,
                    ls="-",
                    lw=1.6,
                    marker=style.marker,
                    ms=5,
                    zorder=3,
                    gid=f"force_drift_ends:{name}:{case.key}",
                )
        boundaries = [float(layout.offset[k]) for k in layout.stages[1:]]
        for ax, (_, label) in zip(axes, quantities):
            ax.set_ylabel(label)
            stage_boundaries(ax, layout, boundaries)
        stage_labels(
            axes[0], layout, {k: layout.offset[k] + layout.turns[k] / 2 for k in layout.stages}
        )
        axes[-1].set_xlabel(r"turns $\lambda / 2\pi$, cumulative over the cycle stages")
        axes[-1].set_xlim(0, layout.n_cycles)
        axes[-1].set_xticks(np.arange(0, layout.n_cycles + 1))
        axes[0].set_title(
            "Forces over the cycles: a total form returns, Cundall–Strack ratchets\n"
            + subtitle(dataset, layout),
            pad=16,
        )
        handles = legend_handles(cases, styles, markers=False)
        handles.append(
            Line2D([], [], ls="-", lw=1.6, marker="o", color="0.3", ms=5, label="ends of turns")
        )
        figure.legend(handles=handles, loc="outside right upper")
    return figure
