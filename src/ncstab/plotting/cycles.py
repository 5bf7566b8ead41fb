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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr
from matplotlib import colormaps, rc_context
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ncstab.plotting.style import (
    RC_PARAMS,
    fixed_parameters_text,
    format_parameter,
    law_display_name,
)

__all__ = [
    "CycleCase",
    "CycleLayout",
    "cycle_cases",
    "cycle_force_drift_figure",
    "cycle_paths_figure",
    "cycle_work_figure",
]

#: Marker and line style of the k-th combination of swept parameters.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">")
LINESTYLES = ("-", "--", ":", "-.")
#: States whose turned angle is within this many turns of a whole number are
#: the located ends of turns (located to ``event_tol``, far below this).
TURN_END_TOLERANCE = 1e-6
#: Two cases share a path if their start states and circles (centre, radius) agree to this.
SAME_PATH_TOLERANCE = 1e-8


@dataclass(frozen=True)
class CycleLayout:
    """The cycle stages of a Dataset's loading programme.

    Attributes
    ----------
    cycle_stage
        ``(C,)``: 0-based stage index of each cycle (turn), programme order.
    stages
        The cycle stages, in order.
    offset
        Stage index -> number of turns of the earlier cycle stages.
    turns
        Stage index -> number of turns of the stage.
    direction
        Stage index -> +1 (counterclockwise in the (Delta_1*, Delta_2*) plane)
        or -1, read from the signed area swept by the stored states.
    """

    cycle_stage: np.ndarray
    stages: tuple[int, ...]
    offset: dict[int, int]
    turns: dict[int, int]
    direction: dict[int, int]

    @property
    def n_cycles(self) -> int:
        return int(self.cycle_stage.size)

    def describe(self, stage: int) -> str:
        """``"stage 1: 3 turns counterclockwise"``."""
        sense = {1: "counterclockwise", -1: "clockwise"}.get(self.direction.get(stage, 0), "")
        turns = self.turns[stage]
        return f"stage {stage + 1}: {turns} turn{'s' if turns != 1 else ''} {sense}".rstrip()


@dataclass(frozen=True)
class CycleCase:
    """One case (a law and values of the swept parameters) restricted to its cycle stages.

    Attributes
    ----------
    law, law_class
        Law name and computed class (``hyperelastic``...).
    swept
        Swept parameter name -> value (law excluded).
    law_index, parameter_index
        Position along the ``law`` dimension; flat position over the other
        sweep dimensions (C order).
    status
        ``finished``, ``stopped:<event>`` or ``failed:<reason>``.
    work
        ``(C,)``: work per contact over each turn, ``cycle_work``.
    u, F
        ``(n, 2)``: Delta*, F* at the stored states of the cycle stages.
    T, alpha, l, lam, stage
        ``(n,)``: tangential force, orientation, length, turned angle (rad,
        from the start of its stage), stage index.
    turns
        ``(n,)``: cumulative number of turns over the cycle stages,
        ``offset[stage] + lam / 2 pi``.
    alpha0
        Initial orientation (alpha at the unloaded first state of the path).
    """

    law: str
    law_class: str
    swept: dict[str, float]
    law_index: int
    parameter_index: int
    status: str
    work: np.ndarray
    u: np.ndarray
    F: np.ndarray
    T: np.ndarray
    alpha: np.ndarray
    l: np.ndarray
    lam: np.ndarray
    stage: np.ndarray
    turns: np.ndarray
    alpha0: float

    @property
    def key(self) -> str:
        """A unique name of the case (artist ``gid`` suffix): ``"mcnamara|radius=0.05"``."""
        return "|".join([self.law] + [f"{k}={v:.12g}" for k, v in self.swept.items()])

    @property
    def parameter_label(self) -> str:
        """``"radius = 0.05"`` (empty without swept parameters)."""
        return ", ".join(format_parameter(k, v) for k, v in self.swept.items())

    def stage_slices(self) -> list[tuple[int, np.ndarray]]:
        """(stage, indices of its states) for every cycle stage the case reached."""
        return [(int(k), np.flatnonzero(self.stage == k)) for k in np.unique(self.stage)]


def _signed_area(points: np.ndarray) -> float:
    """Shoelace area of a closed polygon (positive counterclockwise)."""
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def cycle_cases(dataset: xr.Dataset) -> tuple[list[CycleCase], CycleLayout]:
    """Every case of a path Dataset with cycle stages, in C order over the sweep.

    Parameters
    ----------
    dataset
        A Dataset of :meth:`ncstab.paths.PathResult.to_dataset` (or read back from
        its archive) whose programme has at least one cycle stage.

    Returns
    -------
    (cases, layout)

    Raises
    ------
    ValueError
        If the Dataset has no ``cycle`` dimension (no cycle stage) or lacks a
        variable the figures need.
    """
    if "cycle" not in dataset.dims or "cycle_work" not in dataset:
        raise ValueError(
            "the Dataset has no cycle stages (no 'cycle' dimension): cycle figures need a "
            "loading programme with a stage such as cycle = { center = [0.05, 0.0], turns = 3 }"
        )
    needed = ("n_steps", "u", "F", "T", "alpha", "l", "lam", "stage", "cycle_stage")
    missing = [name for name in needed if name not in dataset.variables]
    if missing:
        raise ValueError(
            f"not a path Dataset with cycles: missing variable(s) {', '.join(missing)}"
        )
    dims = list(dataset["n_steps"].dims)

    def values(name: str, tail: tuple[str, ...] = ()) -> np.ndarray:
        array = dataset[name]
        if "dof" in tail:
            array = array.isel(dof=[0, 1])
        return np.asarray(array.transpose(*dims, *tail).values)

    n_steps = values("n_steps")
    u, F = values("u", ("step", "dof")), values("F", ("step", "dof"))
    T, alpha, l, lam = (
        values(name, ("step",)).astype(float) for name in ("T", "alpha", "l", "lam")
    )
    stage = values("stage", ("step",)).astype(int)
    work = values("cycle_work", ("cycle",)).astype(float)
    status = (
        values("status").astype(str) if "status" in dataset else np.full(n_steps.shape, "finished")
    )
    cycle_stage = np.asarray(dataset["cycle_stage"].values).astype(int)
    stages = tuple(int(k) for k in np.unique(cycle_stage))
    offset = {k: int(np.sum(cycle_stage < k)) for k in stages}
    turns_per_stage = {k: int(np.sum(cycle_stage == k)) for k in stages}
    laws = [str(v) for v in dataset["law"].values] if "law" in dims else ["law"]
    classes = (
        [str(v) for v in dataset["law_class"].values]
        if "law_class" in dataset.coords
        else [""] * len(laws)
    )
    coords = {d: np.asarray(dataset[d].values) for d in dims if d != "law" and d in dataset.coords}
    other_shape = tuple(n_steps.shape[i] for i, d in enumerate(dims) if d != "law")

    cases: list[CycleCase] = []
    direction: dict[int, int] = {}
    for index in np.ndindex(n_steps.shape):
        n = max(int(n_steps[index]), 0)
        law_index = index[dims.index("law")] if "law" in dims else 0
        other = tuple(k for d, k in zip(dims, index) if d != "law")
        swept = {
            d: float(coords[d][k]) if d in coords else float(k)
            for d, k in zip([d for d in dims if d != "law"], other)
        }
        in_cycle = np.isin(stage[index][:n], stages)
        steps = np.flatnonzero(in_cycle)
        case_stage = stage[index][steps]
        case_lam = lam[index][steps]
        turns = np.array([offset[k] for k in case_stage], dtype=float) + case_lam / (2 * math.pi)
        alpha0 = float(alpha[index][0]) if n else math.nan
        case = CycleCase(
            law=laws[law_index],
            law_class=classes[law_index],
            swept=swept,
            law_index=int(law_index),
            parameter_index=int(np.ravel_multi_index(other, other_shape)) if other_shape else 0,
            status=str(status[index]),
            work=work[index],
            u=np.asarray(u[index][steps], dtype=float),
            F=np.asarray(F[index][steps], dtype=float),
            T=T[index][steps],
            alpha=alpha[index][steps],
            l=l[index][steps],
            lam=case_lam,
            stage=case_stage,
            turns=turns,
            alpha0=alpha0,
        )
        cases.append(case)
        for k, where in case.stage_slices():
            if k not in direction and where.size >= 3:
                area = _signed_area(case.u[where])
                if area != 0:
                    direction[k] = 1 if area > 0 else -1
    layout = CycleLayout(cycle_stage, stages, offset, turns_per_stage, direction)
    return cases, layout


# --- look -----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Style:
    colour: object
    marker: str
    linestyle: str


def _styles(cases: Sequence[CycleCase]) -> list[_Style]:
    """Colour by law (several laws) or along viridis (one law); marker and line style by parameters."""
    n_laws = len({c.law_index for c in cases})
    n_parameters = len({c.parameter_index for c in cases})
    palette = colormaps["tab10"].colors
    viridis = colormaps["viridis"]
    out = []
    for case in cases:
        p = case.parameter_index
        if n_laws > 1:
            colour: object = palette[case.law_index % len(palette)]
        else:
            colour = viridis(0.0 if n_parameters == 1 else 0.85 * p / (n_parameters - 1))
        out.append(_Style(colour, MARKERS[p % len(MARKERS)], LINESTYLES[p % len(LINESTYLES)]))
    return out


def _legend_handles(
    cases: Sequence[CycleCase], styles: Sequence[_Style], markers: bool
) -> list[Line2D]:
    """Proxy artists: one per law (colour), one per parameter combination (marker/line)."""
    laws: dict[int, Line2D] = {}
    parameters: dict[int, Line2D] = {}
    several_laws = len({c.law_index for c in cases}) > 1
    for case, style in zip(cases, styles):
        if several_laws and case.law_index not in laws:
            laws[case.law_index] = Line2D(
                [], [], color=style.colour, lw=2.2, label=law_display_name(case.law)
            )
        if case.parameter_index not in parameters and case.parameter_label:
            colour = "0.35" if several_laws else style.colour
            parameters[case.parameter_index] = Line2D(
                [],
                [],
                color=colour,
                ls=style.linestyle,
                lw=1.2,
                marker=style.marker if markers else None,
                ms=5,
                label=case.parameter_label,
            )
    if not several_laws and cases:
        if len(parameters) <= 1:
            return [
                Line2D([], [], color=styles[0].colour, lw=2.2, label=law_display_name(cases[0].law))
            ]
        parameters = {
            -1: Line2D([], [], color="none", label=law_display_name(cases[0].law)),
            **parameters,
        }
    return list(laws.values()) + list(parameters.values())


def _new_figure(figure: Figure | None, size: tuple[float, float]) -> Figure:
    return figure if figure is not None else Figure(figsize=size, layout="constrained")


def _subtitle(dataset: xr.Dataset, layout: CycleLayout, stages: bool = False) -> str:
    """Fixed parameters (``"α₀ = π/4, γ = 0.5"``), optionally with each stage's turns and sense."""
    parts = [fixed_parameters_text(dataset.attrs)]
    if stages:
        parts.append("; ".join(layout.describe(k) for k in layout.stages))
    return " — ".join(p for p in parts if p)


def _stage_boundaries(ax: Axes, layout: CycleLayout, positions: Sequence[float]) -> None:
    for x in positions:
        ax.axvline(x, color="0.45", ls="--", lw=0.8, zorder=1, gid="stage_boundary")


def _stage_labels(ax: Axes, layout: CycleLayout, centre: dict[int, float]) -> None:
    """Direction of each cycle stage written above the axes, over its turns."""
    transform = ax.get_xaxis_transform()
    for k in layout.stages:
        ax.text(
            centre[k],
            1.015,
            layout.describe(k),
            transform=transform,
            ha="center",
            va="bottom",
            fontsize=8,
            color="0.25",
            gid="stage_label",
        )


# --- figures --------------------------------------------------------------------------------------


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
    styles = _styles(cases)
    cycles = np.arange(1, layout.n_cycles + 1)
    with rc_context(RC_PARAMS):
        figure = _new_figure(figure, (9.0, 5.0))
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
        ax.set_ylim(bottom, top)
        ax.set_xlim(0.5, layout.n_cycles + 0.5)
        ax.set_xticks(cycles)
        _stage_boundaries(ax, layout, [layout.offset[k] + 0.5 for k in layout.stages[1:]])
        _stage_labels(
            ax, layout, {k: layout.offset[k] + (layout.turns[k] + 1) / 2 for k in layout.stages}
        )
        ax.set_xlabel("cycle number (turn of a cycle stage)")
        ax.set_ylabel(r"$|W^*|$ per cycle and contact,  $W^* = W / k_n(2R)^2$")
        ax.set_title(
            r"Work over each closed cycle, $W^* = \oint \frac{1}{2}\,F^*\cdot d\Delta^*"
            r" = \oint (-N^*\,dl^* + T^*\,l^*\,d\alpha)$" + "\n" + _subtitle(dataset, layout),
            pad=16,
        )
        handles = _legend_handles(cases, styles, markers=True)
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
    styles = _styles(cases)
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
        figure = _new_figure(figure, (11.0, 5.0))
        ax_u, ax_q = figure.subplots(1, 2)
        handles = []
        for k, (group, colour) in enumerate(zip(groups, colours)):
            case = cases[group[0]]
            if case.u.shape[0] == 0:
                continue
            style = styles[group[0]] if not law_independent else _Style(colour, "o", "-")
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
            "Closed kinematic cycles: " + _subtitle(dataset, layout, stages=True), fontsize=10
        )
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
    styles = _styles(cases)
    unit = str(dataset.attrs.get("force_unit", "2R k_n")).replace("2R k_", r"2R\,k_")
    quantities = (
        ("F1", rf"$F_1^* = F_1/({unit})$"),
        ("F2", rf"$F_2^* = F_2/({unit})$"),
        ("T", rf"$T^* = T/({unit})$"),
    )
    with rc_context(RC_PARAMS):
        figure = _new_figure(figure, (9.0, 8.0))
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
            _stage_boundaries(ax, layout, boundaries)
        _stage_labels(
            axes[0], layout, {k: layout.offset[k] + layout.turns[k] / 2 for k in layout.stages}
        )
        axes[-1].set_xlabel(r"turns $\lambda / 2\pi$, cumulative over the cycle stages")
        axes[-1].set_xlim(0, layout.n_cycles)
        axes[-1].set_xticks(np.arange(0, layout.n_cycles + 1))
        axes[0].set_title(
            "Forces over the cycles: a total form returns, Cundall–Strack ratchets\n"
            + _subtitle(dataset, layout),
            pad=16,
        )
        handles = _legend_handles(cases, styles, markers=False)
        handles.append(
            Line2D([], [], ls="-", lw=1.6, marker="o", color="0.3", ms=5, label="ends of turns")
        )
        figure.legend(handles=handles, loc="outside right upper")
    return figure
