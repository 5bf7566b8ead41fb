"""Signs on a trivial path where K's rounding hides them (:mod:`ncstab.paths.trivial_path`), and a
stage that ends at its target when Newton at the target itself fails.

A long straight column's critical eigenvalue, (pi/n)^4 against entries of K of order 6, is
within the rounding of K at 5,000 links: a column that long is slow for a test, so the
rounding is *declared* larger instead (``assembled_events.SIGN_NOISE``), which puts a 40-link column's
critical eigenvalue (3.8e-5) deep within the "noise": without the exact signs the sign of
det K would be carried over the whole path and the buckling load never found.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import sparse

from ncstab.paths import assembled_events, assembled_path
from ncstab.paths.api import follow
from ncstab.paths.trivial_path import _rest_sign
from ncstab.systems.assembled_builders import assembled_column

LINKS = 40
P1 = 4 * np.sin(np.pi / (2 * LINKS)) ** 2  # Hencky, units C/a


def _column_events(links: int = LINKS, target: float = 1.2):
    result = follow(assembled_column(links), None, [{"drive": {"P": target * P1}, "at_bifurcation": "switch"}])
    return result.results[0].outcomes[0]


def test_buckling_found_where_every_eigenvalue_is_declared_within_rounding(monkeypatch):
    monkeypatch.setattr(assembled_events, "SIGN_NOISE", 1e-3)  # 6e-3 >> (pi/40)^4 = 3.8e-5
    outcome = _column_events()
    assert outcome.status == "finished"
    # located by the exact signs, then refined by the pencil's Rayleigh quotient: the closed form
    # to 1e-12 (measured 2e-15; the quotient is second-order accurate in the eigenvector)
    assert abs(outcome.events["bifurcation"]["point"].load / P1 - 1) < 1e-12
    assert np.abs(outcome.points[-1].u).max() > 1.0  # the buckled branch followed after the switch


def test_without_the_exact_signs_the_declared_rounding_hides_the_buckling(monkeypatch):
    """The same run with the trivial-path signs turned off: no bifurcation, which is what a
    column of 5,000 links gave before (so the test above can fail)."""
    monkeypatch.setattr(assembled_events, "SIGN_NOISE", 1e-3)
    monkeypatch.setattr(assembled_path, "is_trivial", lambda stepper, p: False)
    assert "bifurcation" not in _column_events().events


@pytest.mark.parametrize("dense", [True, False])
@pytest.mark.parametrize("tiny", [3e-17, -3e-17])
def test_rest_sign_is_exact_beside_an_eigenvalue_at_rounding(dense, tiny):
    """K = Q diag(values) Q^T with one eigenvalue of 3e-17 (below rounding of entries of order 1):
    the sign of the product of the others, from the determinant lemma, is the exact one, whatever
    sign the factorization gives the tiny one."""
    rng = np.random.default_rng(7)
    n = 30
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    values = np.concatenate([[tiny], rng.uniform(0.5, 2.0, n - 1) * np.where(np.arange(n - 1) < 3, -1, 1)])
    K = (Q * values) @ Q.T
    K = 0.5 * (K + K.T)
    phi = Q[:, 0]
    exact = float(np.prod(np.sign(values[1:])))  # three negative eigenvalues besides: -1
    assert exact == -1.0
    matrix = K if dense else sparse.csc_matrix(K)
    assert _rest_sign(matrix, phi, float(np.abs(K).max())) == exact


def test_a_stage_ends_at_its_target_when_newton_at_the_target_fails(monkeypatch):
    """If the corrector at lambda = target fails, the stage still ends there (the bisection's point,
    within event_tol of a step), not past its target."""
    original = assembled_path.Stepper.correct
    target = 0.9 * P1

    def failing_at_the_target(self, predictor, normal, start, fixed_lambda=None):
        if fixed_lambda is not None and abs(fixed_lambda - target) <= 1e-12 * target:
            return None
        return original(self, predictor, normal, start, fixed_lambda)

    monkeypatch.setattr(assembled_path.Stepper, "correct", failing_at_the_target)
    outcome = _column_events(target=0.9)
    assert outcome.status == "finished"
    last = outcome.points[-1].load
    assert last == pytest.approx(target, rel=1e-9)  # the bisection to event_tol of a step (measured 5e-13)


def _rounded_critical_load(offset: float):
    """``refine_critical_load`` whose lambda carries a rounding of ``offset`` (relative)."""
    original = assembled_path.refine_critical_load

    def rounded(stepper, e):
        refined = original(stepper, e)
        y = refined.y.copy()
        y[stepper.m] *= 1 + offset
        return dataclasses.replace(refined, y=y, load=refined.load * (1 + offset))

    return rounded


def test_the_rounding_of_a_switched_bifurcation_is_not_a_turning_point(monkeypatch):
    """A column of 5,001 links located P1 with a rounding of 1.4e-10 relative against the branch's
    Newton lambda, and its buckled branch rises by 1e-18: the first secant off the switch was
    negative by rounding, the branch's true rise later positive, and a turning point was reported
    at the bifurcation.  The same rounding is put on a 40-link column's located load here (1e-8 of
    P1, 100 times SECANT_NOISE, much more than the branch's first rise): no turning point, the
    bifurcation located to the offset put on it."""
    monkeypatch.setattr(assembled_path, "refine_critical_load", _rounded_critical_load(1e-8))
    outcome = _column_events()
    assert outcome.status == "finished"
    assert abs(outcome.events["bifurcation"]["point"].load / P1 - 1) < 2e-8
    assert "turning_point" not in outcome.events
    assert np.abs(outcome.points[-1].u).max() > 1.0


def test_without_the_switch_mark_the_rounding_reads_as_a_turning_point(monkeypatch):
    """The run above with the first secant off the switch read as any other: the turning point
    that the 5,001-link column reported (so the test above can fail)."""
    monkeypatch.setattr(assembled_path, "refine_critical_load", _rounded_critical_load(1e-8))
    monkeypatch.setattr(assembled_events, "SWITCHED", "never set")
    assert "turning_point" in _column_events().events
