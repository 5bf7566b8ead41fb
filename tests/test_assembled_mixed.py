"""The sparse engine's bordered solves in mixed form (ncstab.paths.assembled_mixed).

The mixed form solves the same bordered system as the assembled K, without summing the members'
stiffnesses into K: on small systems, whose K is well resolved, it must give numpy's solution of
[[K_SS, column], [last]] x = right; in a path, the route taken once a step fails at the rounding
floor, it must follow the same path.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from ncstab.laws import law_definition
from ncstab.paths import PathOptions, follow
from ncstab.paths import assembled_path
from ncstab.paths.assembled_engine import CaseRun, Point
from ncstab.paths.assembled_mixed import mixed_solver
from ncstab.systems.assembled_builders import assembled_column, assembled_ring
from ncstab.systems.assembled_chain import assembled_ziegler


def _case(system, law, values, u, load, closed=None):
    run = CaseRun(system, law, values, PathOptions(), "ignore")
    if closed is not None:
        run.closed = np.asarray(closed)
    internal = run.initial_internal()
    point = Point(np.zeros(0), u, load, run.evaluate(u, load, internal), internal)
    control = SimpleNamespace(force_dofs=np.arange(run.n), displacement_dofs=np.zeros(0, dtype=np.intp))
    return run, control, point


SYSTEMS = {
    # springs and bars (an axial dead load), a buckled-like shape
    "column": lambda: (assembled_column(12), None, {}, 0.05 * np.sin(np.pi * np.arange(1, 12) / 12), 0.07),
    # springs and a follower tip load (K not symmetric)
    "ziegler": lambda: (assembled_ziegler(3), None, {}, np.array([0.02, -0.05, 0.04]), 1.3),
    # granular contacts of a law with a tangential stiffness gamma
    "ring": lambda: (assembled_ring(6).for_values({"gamma": 0.5}, law_definition("mcnamara")),
                     law_definition("mcnamara"), {"gamma": 0.5},
                     0.01 * np.cos(np.arange(12) * 0.7), 0.0),
}


@pytest.mark.parametrize("name", SYSTEMS)
def test_the_mixed_solve_is_numpys_solve_of_the_bordered_system(name):
    # K of these systems is well resolved (condition below 1e5): the two solves agree to 1e-10
    # of the solution (rounding times the condition of the bordered matrix, at most about 1e-11)
    system, law, values, u, load = SYSTEMS[name]()
    run, control, point = _case(system, law, values, u, load)
    rng = np.random.default_rng(7)
    n = run.n
    column, last, right = rng.normal(size=n), rng.normal(size=n + 1), rng.normal(size=n + 1)
    K = point.state.K.toarray() if hasattr(point.state.K, "toarray") else point.state.K
    expected = np.linalg.solve(np.block([[K, column[:, None]], [last[None, :]]]), right)
    got = mixed_solver(run, control, point, column, last)(right)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10 * np.abs(expected).max())


def test_a_stage_with_driven_displacements_and_closed_contacts_is_numpys_solve_too():
    # grain 1's x driven (its part of the column, K_SD u_slope, comes from the members' rows),
    # a closed secondary contact between grains 1 and 4 (its spring in G): the same agreement
    system, law, values, u, load = SYSTEMS["ring"]()
    run, _, point = _case(system, law, values, u, load, closed=[[0, 3]])
    n = run.n
    control = SimpleNamespace(force_dofs=np.arange(1, n), displacement_dofs=np.array([0]), u_slope=np.array([1.0]),
                              f_slope=np.zeros(n - 1), scale=0.7, load_stage=False)
    K_SS, column = run.blocks(control, point.state, 0.0)
    K_SS = K_SS.toarray() if hasattr(K_SS, "toarray") else K_SS
    assert np.abs(column).max() > 0.1  # the driven dof pulls on its neighbours
    rng = np.random.default_rng(11)
    last, right = rng.normal(size=n), rng.normal(size=n)
    expected = np.linalg.solve(np.block([[K_SS, column[:, None]], [last[None, :]]]), right)
    got = mixed_solver(run, control, point, column, last)(right)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10 * np.abs(expected).max())


def _column_to_buckled(monkeypatch=None, mixed=False):
    links = 12
    critical = 4 * np.sin(np.pi / (2 * links)) ** 2
    if mixed:
        start = assembled_path.Stepper.__init__

        def mixed_from_the_start(self, *args):
            start(self, *args)
            self.mixed = True
        monkeypatch.setattr(assembled_path.Stepper, "__init__", mixed_from_the_start)
    result = follow(assembled_column(links), None, [{"drive": {"P": 1.2 * critical}, "at_bifurcation": "switch"}])
    return result.results[0].outcomes[0], critical


def test_a_path_in_mixed_form_is_the_path_of_the_assembled_k(monkeypatch):
    # Hencky's column of 12 links to 1.2 P1 through the bifurcation, every solve in mixed form:
    # the same steps, P1 to 1e-12 (the Rayleigh quotient refines it on either route) and every
    # stored state within 1e-9 of the assembled route's (Newton's tolerance, 1e-12, times the
    # states' sensitivity to the tangents' rounding)
    reference, critical = _column_to_buckled()
    outcome, _ = _column_to_buckled(monkeypatch, mixed=True)
    assert outcome.status == reference.status == "finished"
    assert len(outcome.points) == len(reference.points)
    assert outcome.events["bifurcation"]["point"].load == pytest.approx(critical, rel=1e-12)
    u, u_ref = (np.array([p.u for p in o.points]) for o in (outcome, reference))
    np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-9 * np.abs(u_ref).max())
    loads = np.array([p.load for p in outcome.points])
    np.testing.assert_allclose(loads, [p.load for p in reference.points], rtol=1e-9)


def test_a_step_failing_at_the_rounding_floor_turns_the_stage_to_the_mixed_form(monkeypatch):
    # a corrector made to fail once, at the floor, past the bifurcation: from there the stage
    # solves in mixed form, and the case still finishes at 1.2 P1
    correct, used = assembled_path.Stepper.correct, []

    def failing_once(self, predictor, normal, start, fixed_lambda=None):
        if fixed_lambda is None and not self.mixed and start is not None and start.indicators.get("switched_here"):
            self.at_floor = True
            return None
        return correct(self, predictor, normal, start, fixed_lambda)

    def counted(*args):
        used.append(1)
        return mixed_solver(*args)
    monkeypatch.setattr(assembled_path.Stepper, "correct", failing_once)
    monkeypatch.setattr(assembled_path, "mixed_solver", counted)
    outcome, critical = _column_to_buckled()
    assert outcome.status == "finished" and used
    assert outcome.points[-1].load == pytest.approx(1.2 * critical, rel=1e-12)
    assert np.abs(outcome.points[-1].u).max() > 0.5  # buckled


@pytest.mark.parametrize("name", SYSTEMS)
def test_the_element_forms_are_the_assembled_ks_quadratic_form(name):
    """``energy_forms`` (the Rayleigh quotient's parts, from the same members' responses and gap
    springs as the mixed form) against the assembled K: psi^T K phi = inner - P outer, K = K_int -
    P K_load, for random psi and phi; the ring with a closed secondary contact.  The two are sums
    of the same terms in another order: 1e-12 of |psi| |K| |phi|."""
    from ncstab.operators.assembly import energy_forms

    system, law, values, u, load = SYSTEMS[name]()
    closed = [[0, 3]] if name == "ring" else None
    run, _, point = _case(system, law, values, u, load, closed=closed)
    rng = np.random.default_rng(3)
    left, right = rng.normal(size=run.n), rng.normal(size=run.n)
    K = point.state.K.toarray() if hasattr(point.state.K, "toarray") else point.state.K
    inner, outer = energy_forms(system, law, values, u, point.internal, left, right,
                                run.closed if closed is not None else None, run.kappa)
    scale = np.linalg.norm(left) * np.abs(K).max() * np.linalg.norm(right) * run.n
    assert abs(left @ K @ right - (inner - load * outer)) <= 1e-12 * scale
