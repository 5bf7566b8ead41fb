"""The first step of a path (``PathOptions.initial_step = "auto"``, the default).

- The compiled loop's starting-step estimate (``initial_step_size``, one case, a
  plain compiled function the loops import: :mod:`ncstab.paths.loop_numerics`) is Hairer's
  starting-step algorithm: it equals scipy's own implementation
  (``select_initial_step``, used by ``solve_ivp``) wherever scipy's probe step is
  the one given, in the reduced diamond's loop and in the general models' loop.
- In the engine: a number still fixes the first step, and the estimate saves
  steps on the uniaxial Cundall--Strack sweep without changing where the paths end.
- Study files take ``initial_step = "auto"`` or a number, and name the field
  otherwise.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate._ivp.common import select_initial_step

import ncstab
from ncstab.paths import PathOptions, SystemSpec
from ncstab.paths.loop_diamond import state_size
from ncstab.paths.loop_numerics import initial_step_size
from ncstab.paths.loop_records import DiamondModel
from ncstab.studies import StudyFileError
from ncstab.studies.study import parse_study

#: DOP853's error estimator order in scipy (the exponent 1/8 of the estimate).
ORDER = 7
#: scipy raises to the power 1/8 where we take three square roots, and takes
#: the RMS norm as ||x|| / sqrt(n) where we take sqrt(mean(x^2)): a few ulps each.
ROOT_RTOL = 1e-14

UNIAXIAL = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.2}}]
SWEEP = {"gamma": list(np.linspace(0.1, 2.0, 6)), "alpha0": list(np.linspace(0.3, 1.2, 6))}


@pytest.fixture(scope="module", params=["diamond", "general"])
def estimate(request):
    """(``initial_step_size`` of one case as a loop calls it, the state size it passes or None).

    The reduced diamond's loop passes its own state size (``state_size``, 4 for a total
    form: v0, v1, lambda, W) whatever the arrays' length; the general models' loop passes
    the arrays' length."""
    size = state_size.py_func(DiamondModel(rate_form=False), None) if request.param == "diamond" else None

    def one_case(y0, f0, f1, probe, rtol, atol):
        return initial_step_size(y0, f0, f1, probe, rtol, atol, size or y0.size)

    return one_case, size


def _rhs(matrix: np.ndarray):
    """A smooth nonlinear right-hand side: f(y) = sin(A y) + 0.3 (1, ..., 1)."""

    def f(t: float, y: np.ndarray) -> np.ndarray:
        return np.sin(matrix @ y) + 0.3

    return f


@pytest.mark.parametrize("seed", range(8))
def test_the_estimate_is_scipys_at_an_undeformed_start(seed, estimate):
    # y0 = 0: scipy probes with h0 = 1e-6 (its guess 0.01 |y0| / |f0| is 0 there).
    initial_step_size, size = estimate
    rng = np.random.default_rng(seed)
    m = size or 5
    f = _rhs(rng.normal(scale=rng.uniform(0.1, 50), size=(m, m)))
    y0 = np.zeros(m)
    f0 = f(0.0, y0)
    rtol, atol = 10.0 ** rng.uniform(-12, -4), 10.0 ** rng.uniform(-14, -6)
    expected = select_initial_step(f, 0.0, y0, np.inf, np.inf, f0, 1.0, ORDER, rtol, atol)
    probe = 1e-6
    ours = initial_step_size(y0, f0, f(0.0, y0 + probe * f0), probe, rtol, atol)
    np.testing.assert_allclose(ours, expected, rtol=ROOT_RTOL, atol=0)


def test_the_estimate_is_scipys_away_from_zero_case_by_case(estimate):
    # y0 != 0: scipy probes with 0.01 |y0| / |f0|; given that probe, every case gets
    # scipy's estimate, including the cap at 100 probes.
    initial_step_size, size = estimate
    rng = np.random.default_rng(42)
    m, cases = size or 4, 200
    capped = 0
    for _ in range(cases):
        f = _rhs(rng.normal(scale=rng.uniform(0.01, 100), size=(m, m)))
        y0 = rng.normal(size=m) * 10.0 ** rng.uniform(-3, 1)
        f0 = f(0.0, y0)
        rtol, atol = 1e-8, 1e-10
        scale = atol + np.abs(y0) * rtol
        probe = 0.01 * np.linalg.norm(y0 / scale) / np.linalg.norm(f0 / scale)
        expected = select_initial_step(f, 0.0, y0, np.inf, np.inf, f0, 1.0, ORDER, rtol, atol)
        ours = initial_step_size(y0, f0, f(0.0, y0 + probe * f0), probe, rtol, atol)
        np.testing.assert_allclose(ours, expected, rtol=ROOT_RTOL, atol=0)
        capped += bool(np.isclose(expected, 100 * probe, rtol=1e-15))
    assert 0 < capped < cases  # both branches of the min were exercised


def test_the_estimate_of_a_still_or_broken_start(estimate):
    initial_step_size, size = estimate
    m = size or 3
    zero = np.zeros(m)
    # f = 0 everywhere: scipy's fallback max(1e-6, 1e-3 probe), at most 100 probes
    expected = select_initial_step(lambda t, y: np.zeros(m), 0.0, zero, np.inf, np.inf, zero, 1.0, ORDER, 1e-6, 1e-9)
    assert initial_step_size(zero, zero, zero, 1e-6, 1e-6, 1e-9) == expected == 1e-6
    assert initial_step_size(zero, zero, zero, 1e-3, 1e-6, 1e-9) == 1e-6
    # a right-hand side that is not finite at the probe: the probe itself
    assert initial_step_size(zero, np.ones(m), np.full(m, np.nan), 1e-3, 1e-6, 1e-9) == 1e-3


def _first_steps(path) -> np.ndarray:
    s = path.results[0].steps["s"]
    return s[:, 1] - s[:, 0]


def _follow(options: PathOptions, law: str = "cundall_strack", parameters=None):
    return ncstab.follow(SystemSpec(secondary_contacts="ignore"), law, UNIAXIAL, parameters or SWEEP, options)


def test_a_number_still_fixes_the_first_step():
    path = _follow(PathOptions(initial_step=0.005, max_step=1.0))
    assert np.all(path.results[0].counters["rejected"] >= 0)
    np.testing.assert_array_equal(_first_steps(path), 0.005)  # 0.005 is accepted in every case


def test_auto_saves_steps_and_ends_where_a_small_fixed_start_does():
    options = PathOptions(max_step=1.0)
    auto = _follow(options)
    fixed = _follow(PathOptions(initial_step=1e-3, max_step=1.0))
    tiny = _follow(PathOptions(initial_step=1e-5, max_step=1.0))
    first = _first_steps(auto)
    # the estimate is an actual estimate: within Hairer's bounds, not the probe
    assert np.all((first > 1e-3) & (first <= 0.1))
    attempts = {
        name: int((p.results[0].counters["accepted"] + p.results[0].counters["rejected"]).sum())
        for name, p in (("auto", auto), ("fixed", fixed))
    }
    assert attempts["auto"] < attempts["fixed"]
    # Where the paths end: the same to the local error tolerance (rtol 1e-10) times
    # the few steps taken; 1e-9 on O(1) values.
    for other in (fixed, tiny):
        for name in ("u", "F"):
            end = np.take_along_axis(
                auto.results[0].steps[name], (auto.results[0].n_steps - 1)[:, None, None], axis=1
            )
            reference = np.take_along_axis(
                other.results[0].steps[name], (other.results[0].n_steps - 1)[:, None, None], axis=1
            )
            np.testing.assert_allclose(end, reference, rtol=0, atol=1e-9)


@pytest.mark.parametrize(("value", "expected"), [('"auto"', "auto"), ("0.01", 0.01), ("1e-4", 1e-4)])
def test_a_study_file_takes_auto_or_a_number(value, expected):
    study = parse_study(_study(value))
    assert study.options.initial_step == expected


@pytest.mark.parametrize("value", ['"small"', "-1.0", "true"])
def test_a_study_file_names_a_bad_initial_step(value):
    with pytest.raises(StudyFileError, match=r"options\.initial_step"):
        parse_study(_study(value))


def _study(value: str) -> str:
    return f"""
[study]
name = "first_step"

[system]
name = "diamond"
alpha0 = 0.8

[laws]
names = ["cundall_strack"]

[parameters]
gamma = 1.0

[[loading]]
hold = {{ F2 = 0.0 }}
drive = {{ D1 = 0.1 }}

[options]
initial_step = {value}
"""
