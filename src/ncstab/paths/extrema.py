"""The first extremum of a state variable along a path, located by root finding.

``[output] extrema = ["alpha"]`` asks, for every case, for the first state where
the rate of a stored state variable along the path passes through zero: the
event ``extremum_<name>``.  Seed Fig. 3: the hyperelastic diamond (McNamara et
al. 2008, gamma = 2, F2* = 0) reaches a maximum rotation alpha where the two
branches of Eq. (48) meet (the root of the square root: tan alpha = 4 gamma
(alpha - alpha0), l* = 1/2), while F1* goes on increasing.

The event is located after the path is followed, from its stored states and
the model, like the engine's events (:mod:`ncstab.paths.events`): a sign change
of an indicator, here the rate dv/ds of the variable v, located by root
finding, not at the resolution of the stored states.

* At every stored state of a linear stage the path's tangent is the null
  vector of the constrained rate system ``M du = g'_eff dlambda`` (M = P + Q K,
  :mod:`ncstab.paths.tangent_field`, seed Eq. 35), taken by the bordered solve
  ``[[M, -g'_eff], [t^T]] z = e`` with t the stored tangent (so z runs the way
  the path does); the rate of v follows: du for a displacement, K du + dF/dP dP
  for a force, the load parameter's rate, or a central difference of the
  model's interaction variables along z (step
  :data:`~ncstab.paths.extrema_root.RATE_STEP`).
* Between the two stored states a, b of the same stage where the rate
  changes sign (a rate within :data:`RATE_NOISE` of zero carries no sign), the
  path is parametrised by sigma = t_a . (x - x_a), x = (u, lambda): a law with
  a total form re-solves the equilibrium on the hyperplane sigma by Newton's
  method to :data:`~ncstab.paths.extrema_root.NEWTON_TOL` (the pseudo-arclength corrector of the engine);
  a rate-form law integrates dx/dsigma (its internal variables with it) from a
  by RK4 on :data:`~ncstab.paths.extrema_root.RK4_STEPS` pieces.  The rate's root in sigma is found by the
  Illinois variant of regula falsi to
  :data:`~ncstab.paths.extrema_root.SIGMA_TOL`, on every bracketed case
  at once.
* The arclength at the extremum is s_a plus the integral of |dx/dsigma| in
  (u, F, lambda) (the engine's norm) by Gauss-Legendre quadrature.

Not located: extrema in a cycle stage (its control is a circle), at the end of
a stage (where the next stage turns back the rate jumps, it does not pass
through zero), and for the pure-shear limit and assembled systems (refused
when the study is read).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.extrema_root import (
    Rows,
    SecantPath,
    StateVariable,
    path_motion,
    rate_along,
    rate_root,
)
from ncstab.paths.programme import Stage
from ncstab.paths.variables import family_fields

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.result import PathResult
    from ncstab.systems import SystemDefinition

__all__ = [
    "RATE_NOISE", "Extremum", "extremum", "extremum_choices", "extremum_names", "extremum_variables", "locate_extremum",
]

#: A rate dv/ds (per unit arclength) within this of zero carries no sign: a variable
#: that does not move (D2 on a symmetric path) has rates of rounding size, and a
#: central difference of an interaction variable is good to ~1e-10.
RATE_NOISE = 1e-9
_GAUSS = np.polynomial.legendre.leggauss(8)


@dataclass(frozen=True)
class Extremum:
    """A state variable whose first extremum is wanted.

    Attributes
    ----------
    label
        As the study names it: ``"alpha"``, ``"u:D2"``, ``"F:F1"``, ``"load"``,
        ``"N:top_left"`` (a member of a family with several).
    variable
        The stored variable: ``u``, ``F``, ``load`` or an interaction field.
    index
        The dof (``u``, ``F``) or member of the family, or None.
    """

    label: str
    variable: str
    index: int | None = None

    @property
    def event(self) -> str:
        """``extremum_<label>`` with ``:`` as ``_``: ``extremum_alpha``, ``extremum_u_D2``."""
        return "extremum_" + self.label.replace(":", "_")


def extremum_choices(definition: SystemDefinition) -> list[str]:
    """The names ``[output] extrema`` accepts for a system."""
    choices = [f"u:{d}" for d in definition.dofs] + [f"F:{f}" for f in definition.forces]
    for family, names, _ in family_fields(definition):
        for name in names:
            choices += [name] if family.size == 1 else [f"{name}:{m}" for m in family.members]
    if definition.load is not None:
        choices.append("load")
    return choices


def extremum(label: str, definition: SystemDefinition) -> Extremum:
    """The :class:`Extremum` a study names (see :func:`extremum_choices`).

    Raises
    ------
    ValueError
        A name the system has no such variable for (the message lists them).
    """
    if label not in extremum_choices(definition):
        raise ValueError(
            f"unknown state variable {label!r}; for system {definition.name!r} the choices are "
            f"{', '.join(extremum_choices(definition))}"
        )
    name, _, member = label.partition(":")
    if name == "u":
        return Extremum(label, "u", definition.dofs.index(member))
    if name == "F":
        return Extremum(label, "F", definition.forces.index(member))
    if name == "load" or not member:
        return Extremum(label, name, None)
    family = next(f for f, names, _ in family_fields(definition) if name in names)
    return Extremum(label, name, family.members.index(member))


def locate_extremum(result: PathResult, spec: Extremum) -> list[dict[str, np.ndarray]]:
    """The first extremum of ``spec`` in every case, as an event table per law.

    Parameters
    ----------
    result
        Followed paths (:func:`ncstab.follow`) of a system followed by the compiled
        engine with deformable contacts.
    spec
        The variable (:func:`extremum`).

    Returns
    -------
    list of dict
        Per law, the fields of an event table (:func:`ncstab.paths.case_result.empty_events`):
        ``found (B,)``, ``s``, ``s_lower``, ``s_upper`` (the stored states
        bracketing it), ``stage``, ``lam``, ``u (B, n)``, ``F``, ``K (B, n, n)``,
        the interaction variables and ``load``; NaN and stage -1 where a case has none.
    """
    from ncstab.paths.api import case_batch

    variable = StateVariable(spec, result.model.definition)
    values = result.grid.case_values()
    return [
        _locate(result, case, case_batch(law, result.model, values, result.grid.size), variable)
        for law, case in zip(result.model.laws, result.results)
    ]


def _stage_controls(result: PathResult, steps: dict, valid: np.ndarray) -> tuple:
    """Per (case, stage): force-controlled dofs ``(K, n)``, d(prescribed)/dlambda ``(B, K, n)``,
    dP/dlambda ``(B, K)`` and whether the stage is linear ``(K,)``."""
    definition = result.model.definition
    stages = result.programme.stages
    size, n = steps["u"].shape[0], len(definition.dofs)
    forced = np.zeros((len(stages), n), dtype=bool)
    slope = np.zeros((size, len(stages), n))
    load_slope = np.zeros((size, len(stages)))
    linear = np.array([isinstance(stage, Stage) for stage in stages])
    load_name = definition.load_parameter
    for j, stage in enumerate(stages):
        if not linear[j]:
            continue
        controls, drives = stage.controls(), dict(stage.drives)
        forced[j] = [dof not in controls for dof in definition.dofs]
        names = [f if forced[j, i] else d for i, (d, f) in enumerate(zip(definition.dofs, definition.forces))]
        if len(drives) == 1:
            slope[:, j] = [1.0 if name in drives else 0.0 for name in names]
            load_slope[:, j] = 1.0 if load_name in drives else 0.0
            continue
        # several driven quantities: lambda runs 0 to 1, each moves by (target - start)
        mask = valid & (steps["stage"] == j)
        first = np.argmax(mask, 1)
        last = mask.shape[1] - 1 - np.argmax(mask[:, ::-1], 1)
        cases = np.arange(size)
        span = steps["lam"][cases, last] - steps["lam"][cases, first]
        prescribed = np.where(forced[j], steps["F"], steps["u"])
        for i, name in enumerate(names):
            if name in drives:
                slope[:, j, i] = (prescribed[cases, last, i] - prescribed[cases, first, i]) / span
        if load_name in drives:
            load_slope[:, j] = (steps["load"][cases, last] - steps["load"][cases, first]) / span
    return forced, slope, load_slope, linear


def _rows(batch: Any, steps: dict, controls: tuple, cases: np.ndarray, positions: np.ndarray) -> Rows:
    """The stored states ``(cases, positions)`` as rows (prescribed values and lambda there)."""
    forced, slope, load_slope, _ = controls
    stage = steps["stage"][cases, positions]
    force_controlled = forced[stage]
    u, F = steps["u"][cases, positions], steps["F"][cases, positions]
    load = steps["load"][cases, positions] if "load" in steps else np.zeros(len(cases))
    return Rows(batch.take(cases), force_controlled, slope[cases, stage], load_slope[cases, stage],
                 np.where(force_controlled, F, u), load, steps["lam"][cases, positions])


def _internal(steps: dict, cases: np.ndarray, positions: np.ndarray) -> np.ndarray:
    internal = steps.get("internal")
    if internal is None or internal.ndim < 3 or internal.shape[-1] == 0:
        return np.zeros((len(cases), 0))
    return internal[cases, positions]


def _tangent(steps: dict, cases: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """The stored tangent (du, dlambda) ``(R, n + 1)``: it orients the bordered solves."""
    return np.concatenate([steps["du"][cases, positions], steps["dlam"][cases, positions][:, None]], 1)


#: Stored states whose rates are computed together (bounds the memory of a large sweep).
_BLOCK = 16384


def _stored_rates(batch: Any, steps: dict, controls: tuple, valid: np.ndarray, variable: StateVariable) -> np.ndarray:
    """dv/ds at every stored state ``(B, S)``; NaN outside linear stages and past a path's end."""
    rates = np.full(valid.shape, np.nan)
    linear = controls[3]
    usable = valid & linear[np.where(valid, steps["stage"], 0)]
    cases, positions = np.nonzero(usable)
    for start in range(0, len(cases), _BLOCK):
        c, p = cases[start:start + _BLOCK], positions[start:start + _BLOCK]
        rows = _rows(batch, steps, controls, c, p)
        state = (steps["u"][c, p], steps["lam"][c, p], _internal(steps, c, p))
        evaluation = rows.evaluate(*state)
        motion = path_motion(rows, evaluation, _tangent(steps, c, p))
        with np.errstate(invalid="ignore", divide="ignore"):
            rates[c, p] = rate_along(rows, variable, state, evaluation, motion)
    return rates


def _brackets(rates: np.ndarray, stage: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per case, the stored states (a, b) of the first sign change of the rate within a
    stage (-1 where none); a rate within :data:`RATE_NOISE` of zero carries no sign."""
    size, length = rates.shape
    sign = np.where(np.abs(np.nan_to_num(rates)) > RATE_NOISE, np.sign(np.nan_to_num(rates)), 0.0)
    last_sign, last_k, last_stage = np.zeros(size), np.full(size, -1), np.full(size, -1)
    a, b = np.full(size, -1), np.full(size, -1)
    for k in range(length):
        here = valid[:, k]
        moved_on = here & (stage[:, k] != last_stage)
        last_sign[moved_on], last_stage[moved_on] = 0.0, stage[moved_on, k]
        hit = here & (b < 0) & (sign[:, k] != 0) & (last_sign != 0) & (sign[:, k] != last_sign)
        a[hit], b[hit] = last_k[hit], k
        signed = here & (sign[:, k] != 0)
        last_sign[signed], last_k[signed] = sign[signed, k], k
    return a, b


def _locate(result: PathResult, case: Any, batch: Any, variable: StateVariable) -> dict[str, np.ndarray]:
    """The event table of one law's batch of cases (see :func:`locate_extremum`)."""
    steps = case.steps
    size, length = steps["s"].shape[:2]
    n = len(result.dof_names)
    valid = (np.arange(length)[None, :] < case.n_steps[:, None]) & (steps["stage"] >= 0)
    table = _empty_table(size, n, batch)
    if not valid.any():
        return table
    controls = _stage_controls(result, steps, valid)
    a, b = _brackets(_stored_rates(batch, steps, controls, valid, variable), steps["stage"], valid)
    cases = np.flatnonzero(b >= 0)
    if not cases.size:
        return table
    a, b = a[cases], b[cases]
    rows = _rows(batch, steps, controls, cases, a)
    t_a = _tangent(steps, cases, a)
    path = SecantPath(rows, steps["u"][cases, a], steps["lam"][cases, a], _internal(steps, cases, a), t_a,
                      batch.has_total_form)
    x_b = np.concatenate([steps["u"][cases, b], steps["lam"][cases, b][:, None]], 1)
    x_a = np.concatenate([path.u_a, path.lam_a[:, None]], 1)
    sigma = rate_root(path, variable, ((x_b - x_a) * t_a).sum(1))
    found = np.isfinite(sigma)
    cases, a, b, sigma = cases[found], a[found], b[found], sigma[found]
    if not cases.size:
        return table
    path = SecantPath(_rows(batch, steps, controls, cases, a), steps["u"][cases, a], steps["lam"][cases, a],
                      _internal(steps, cases, a), _tangent(steps, cases, a), batch.has_total_form)
    nodes, weights = _GAUSS
    speed = sum(w * path.rate(variable, sigma * (x + 1) / 2)[3].speed for x, w in zip(nodes, weights))
    _, state, evaluation, _ = path.rate(variable, sigma)
    table["found"][cases] = True
    table["s"][cases] = steps["s"][cases, a] + sigma / 2 * speed
    table["s_lower"][cases], table["s_upper"][cases] = steps["s"][cases, a], steps["s"][cases, b]
    table["stage"][cases] = steps["stage"][cases, a]
    table["lam"][cases] = state[1]
    table["u"][cases], table["F"][cases], table["K"][cases] = state[0], evaluation.forces, evaluation.stiffness
    for name, values in variable.named(evaluation).items():
        table[name][cases] = values
    if "load" in table:
        table["load"][cases] = path.rows.load(state[1])
    return table


def _empty_table(size: int, n: int, batch: Any) -> dict[str, np.ndarray]:
    table = {
        "found": np.zeros(size, dtype=bool), "s": np.full(size, np.nan), "s_lower": np.full(size, np.nan),
        "s_upper": np.full(size, np.nan), "stage": np.full(size, -1), "lam": np.full(size, np.nan),
        "u": np.full((size, n), np.nan), "F": np.full((size, n), np.nan), "K": np.full((size, n, n), np.nan),
    }
    for name, shape in dict(batch.interaction_shapes).items():
        table[name] = np.full((size, *shape), np.nan)
    if batch.has_load:
        table["load"] = np.full(size, np.nan)
    return table


def extremum_variables(result: PathResult, labels: Sequence[str]) -> dict[str, tuple[list[str], np.ndarray, dict]]:
    """The Dataset variables ``extremum_<name>_<field>`` of the extrema ``labels``.

    Per extremum the fields of every event table
    (:func:`ncstab.paths.dataset.event_field_dims`: ``s``, ``s_lower``,
    ``s_upper``, ``stage``, ``u``, ``F``, ``K``, the interaction variables, ``load``),
    over the sweep's dimensions: ``name -> (dims, values, attrs)``.
    """
    from ncstab.paths.dataset import event_field_dims, event_variable_attributes

    definition = result.model.definition
    sweep_dims = ["law", *result.grid.sweep]
    shape = result.shape
    out = {}
    for label in labels:
        spec = extremum(label, definition)
        tables = locate_extremum(result, spec)
        for suffix, dims in event_field_dims(definition).items():
            values = np.stack([table[suffix] for table in tables])
            values = values.reshape(shape + values.shape[2:])
            attrs = event_variable_attributes(spec.event, suffix)
            attrs["description"] += (
                f" (the first extremum of {label} along the path: its rate through zero, located by root finding)"
            )
            out[f"{spec.event}_{suffix}"] = (sweep_dims + dims, values.astype(np.int32) if suffix == "stage" else values, attrs)
    return out


def extremum_names(definition: SystemDefinition, labels: Sequence[str]) -> list[str]:
    """The names of the variables :func:`extremum_variables` makes (without computing them)."""
    from ncstab.paths.dataset import event_field_dims

    return [f"{extremum(label, definition).event}_{suffix}" for label in labels for suffix in event_field_dims(definition)]
