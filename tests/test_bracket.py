"""The Illinois iteration both engines locate events with (ncstab.paths.bracket).

Checked, compiled and as plain Python (the same text, :mod:`ncstab.plain_python`),
against roots known in closed form: the iteration ends inside a bracket of the
requested width around the root (the root is the only exact reference, so the
tolerance is the bracket's width, 1e-12), and it gets there in far fewer trials
than bisection (41 halvings of (0, 2) to 1e-12): superlinear convergence, which
plain regula falsi loses on a convex function (one end never moves) and Illinois
restores.  The two routes give the same trials bit for bit (the same IEEE
operations in the same order).  The sparse engine's use of it is checked on
Hencky's column: the buckling load where the theory puts it, found with a few
corrections per event where bisection took 35.
"""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from ncstab.paths import bracket
from ncstab.plain_python import plain_file

WIDTH = 1e-12


@pytest.fixture(params=["compiled", "plain"])
def iteration(request):
    if request.param == "compiled":
        return bracket
    return plain_file("ncstab.paths.bracket", importlib.util.find_spec("ncstab.paths.bracket").origin)


def _solve(module, f, lower, upper, width=WIDTH):
    """The iteration as both engines run it: trial, evaluate, update, until the bracket is narrow."""
    f_lower, f_upper, side, last_width = f(lower), f(upper), 0, upper - lower
    trials = []
    for number in range(200):
        if upper - lower <= width:
            break
        trial, last_width = module.illinois_trial(lower, upper, f_lower, f_upper, number, last_width)
        trials.append(trial)
        lower, upper, f_lower, f_upper, side, exact = module.illinois_update(
            lower, upper, f_lower, f_upper, side, trial, f(trial))
        if exact:
            break
    return lower, upper, trials


@pytest.mark.parametrize(("f", "lower", "upper", "root"), [
    (lambda x: x ** 3 - 2.0, 0.0, 2.0, 2.0 ** (1 / 3)),
    (lambda x: math.exp(10.0 * x) - 2.0, 0.0, 1.0, math.log(2.0) / 10.0),  # convex: regula falsi stalls
    (lambda x: math.cos(x), 0.0, 3.0, math.pi / 2),
    (lambda x: 1.0 - x, 0.0, 1.0 + 2 ** -20, 1.0),  # decreasing
])
def test_the_bracket_closes_on_the_root_in_few_trials(iteration, f, lower, upper, root):
    a, b, trials = _solve(iteration, f, lower, upper)
    assert a <= root + 4e-16 and root - 4e-16 <= b  # the root inside the bracket (its rounding)
    assert b - a <= WIDTH
    # at most half of bisection's ceil(log2((upper - lower) / WIDTH)), 40 to 42 here
    # (measured 10, 18, 9 and 1 trials)
    assert len(trials) <= 20


def test_a_trial_on_the_root_ends_the_iteration_there(iteration):
    a, b, trials = _solve(iteration, lambda x: x - 0.5, 0.0, 1.0)  # the secant's zero is 0.5 exactly
    assert a == b == 0.5 and trials == [0.5]


def test_a_value_that_is_not_finite_is_taken_as_the_crossing(iteration):
    # -1 below 0.4, NaN on [0.4, 0.6], +1 above: the first trial, 0.5, is NaN
    a, b, trials = _solve(iteration, lambda x: -1.0 if x < 0.4 else 1.0 if x > 0.6 else math.nan, 0.0, 1.0)
    assert a == b == 0.5 and trials == [0.5]


def test_signs_alone_still_converge_as_bisection_does(iteration):
    """Values that are only signs (+-1): the secant's zero is the middle, and Illinois's
    halving then skews it; the check every fifth trial keeps the bracket halving."""
    a, b, trials = _solve(iteration, lambda x: 1.0 if x > 1 / 3 else -1.0, 0.0, 1.0, width=1e-10)
    assert a <= 1 / 3 <= b and b - a <= 1e-10
    assert len(trials) <= 40  # bisection: 34 (measured 34)


def test_compiled_and_plain_take_the_same_trials():
    plain = plain_file("ncstab.paths.bracket", importlib.util.find_spec("ncstab.paths.bracket").origin)
    for f, lower, upper in [(lambda x: x ** 3 - 2.0, 0.0, 2.0), (lambda x: math.exp(10.0 * x) - 2.0, 0.0, 1.0)]:
        assert _solve(bracket, f, lower, upper) == _solve(plain, f, lower, upper)


def test_the_compiled_loop_locates_events_with_these_functions():
    """One implementation: the loop's ``locate`` and the sparse engine's call this module."""
    from ncstab.paths import assembled_events, loop_steps

    assert loop_steps.illinois_trial is bracket.illinois_trial
    assert loop_steps.illinois_update is bracket.illinois_update
    assert assembled_events._BRACKET.illinois_update.__code__.co_filename == bracket.__file__


def test_the_sparse_engine_locates_events_in_a_few_corrections(monkeypatch):
    """Hencky's column of 40 links driven to 1.2 P1, switching at P1: each sign change (the
    bifurcation, Hill's loss, the loss of controllability, the stage's end) is located within
    event_tol of its step by at most 10 corrected trials (measured 3 to 6; bisection took 35
    and more: 2^-34 of a step is 1e-10), and the buckling load is Hencky's to 1e-12."""
    from ncstab.paths import assembled_events, assembled_path
    from ncstab.paths.api import follow
    from ncstab.systems.assembled_builders import assembled_column

    links = 40
    P1 = 4 * np.sin(np.pi / (2 * links)) ** 2  # Hencky, units C/a
    corrections: list[int] = []
    corrected, locate = assembled_events._corrected, assembled_path.locate

    def counted(*args):
        corrections[-1] += 1
        return corrected(*args)

    def located(*args):
        corrections.append(0)
        return locate(*args)

    monkeypatch.setattr(assembled_events, "_corrected", counted)
    monkeypatch.setattr(assembled_path, "locate", located)
    result = follow(assembled_column(links), None, [{"drive": {"P": 1.2 * P1}, "at_bifurcation": "switch"}])
    outcome = result.results[0].outcomes[0]
    assert outcome.status == "finished"
    assert abs(outcome.events["bifurcation"]["point"].load / P1 - 1) < 1e-12
    assert len(corrections) >= 2 and max(corrections) <= 10, corrections
    for name, event in outcome.events.items():
        assert event["s_upper"] - event["s_lower"] <= 1e-10, name
