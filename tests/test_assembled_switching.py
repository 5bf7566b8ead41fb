"""Branch switching in the sparse engine: the algebraic bifurcation equation that the compiled
route solves too (ncstab.paths.branch_switching.branch_direction), on a transcritical bifurcation
known in closed form.

Hencky's column of 2 links (one dof, the joint's deflection w) with a spring stiffening in one
direction, M = theta + theta^2, under an axial dead load P (units: the spring's stiffness and
the link's length).  The joint's rotation is theta = asin(-w) - asin(w) = -2 asin w, the
shortening 2 (1 - sqrt(1 - w^2)); equilibrium, M dtheta/dw = P dshortening/dw, gives the
trivial path w = 0 and the branch

    P(w) = -(theta + theta^2) / w = (2 asin w - 4 asin^2 w) / w,

through P1 = 2 at w = 0 with slope dP/dw = -4: a transcritical bifurcation (seed's companion,
Lerbet et al. 2020; Seydel 5.5).  The branch is left where the equation's second root says,
not along the null vector alone (which would leave with dP/dw = 0).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ncstab.laws.spring import THETA, SpringLaw
from ncstab.paths.api import follow
from ncstab.systems.assembled_builders import assembled_column

QUADRATIC = SpringLaw("quadratic_spring", "a spring stiffening in one direction", "M = theta + theta^2",
                      moment=THETA + THETA**2)


def branch_load(w: np.ndarray) -> np.ndarray:
    """P on the bifurcating branch at deflection w (module docstring)."""
    return (2 * np.arcsin(w) - 4 * np.arcsin(w) ** 2) / w


@pytest.mark.parametrize("direction", [-1, 1])
def test_a_transcritical_bifurcation_is_left_along_its_branch(direction):
    """P driven to 2.5 with the switch at the bifurcation: located at P1 = 2 (1e-10: event_tol,
    then the pencil's Rayleigh quotient); the path leaves with the branch's slope dP/dw = -4
    (1e-6: the equation's coefficients are central differences of step 1e-5, whose error is
    O(h^2) against O(1) coefficients; measured 1.5e-10) along w < 0 for direction = -1 and
    w > 0 for 1.  Every state after the switch is on the closed-form branch to 1e-9 (Newton's
    tolerance, 1e-12, on O(1) forces).  Along w < 0 the branch rises to the target; along w > 0
    it falls, and the chain lies flat (w = 1, P = pi - pi^2) before any target: those states are
    compared up to w = 0.9."""
    result = follow(dataclasses.replace(assembled_column(2), spring_law=QUADRATIC), None,
                    [{"drive": {"P": 2.5}, "at_bifurcation": {"switch": True, "direction": direction}}])
    outcome = result.results[0].outcomes[0]
    event = outcome.events["bifurcation"]["point"]
    assert abs(event.load - 2.0) < 1e-10
    dw, dlam = event.tangent  # the direction the path left along, in y = (w, P / scale), scale 2.5
    assert dlam * 2.5 / dw == pytest.approx(-4.0, rel=1e-6)
    assert np.sign(dw) == direction
    w = np.array([p.u[0] for p in outcome.points])
    P = np.array([p.load for p in outcome.points])
    after = (np.abs(w) > 1e-6) & (np.abs(w) < 0.9)
    assert after.sum() >= 5 and np.all(np.sign(w[after]) == direction)
    np.testing.assert_allclose(P[after], branch_load(w[after]), rtol=0, atol=1e-9)
    if direction == -1:
        assert outcome.status == "finished" and P[-1] == pytest.approx(2.5, rel=1e-12)


@pytest.mark.parametrize("direction", [1, -1])
def test_branch_index_says_which_states_left_the_bifurcation_point_on_both_routes(direction):
    """Hencky's column of 4 links (compiled route) and of 12 (sparse engine), P swept to 0.5 P1
    and to 1.2 P1 with the switch at P1: the Dataset's ``branch_index`` is 0 on the straight
    path, ``direction`` from the bifurcation point on (the point itself, at P1 to 1e-12,
    included), padded with -1 past each case's ``n_steps`` (the compiled route's layout).
    The sparse engine had no ``branch_index`` before."""
    from ncstab.paths.options import SystemSpec

    for links in (4, 12):
        P1 = 4 * np.sin(np.pi / (2 * links)) ** 2
        programme = [{"drive": {"P": "Pmax"}, "at_bifurcation": {"switch": True, "direction": direction}}]
        ds = follow(SystemSpec("column", links=links), None, programme, {"Pmax": [0.5 * P1, 1.2 * P1]}).to_dataset()
        assert ds.branch_index.dtype == np.int32 and ds.branch_index.dims == ("law", "Pmax", "step")
        index, load = ds.branch_index.values.reshape(2, -1), ds["load"].values.reshape(2, -1)
        short, long_ = (int(n) for n in ds.n_steps.values.ravel())
        assert (index[0, :short] == 0).all() and (index[0, short:] == -1).all()
        switched = index[1, :long_] != 0
        assert (index[1, :long_][switched] == direction).all() and switched[-1]
        assert not switched[0] and (np.diff(switched.astype(int)) >= 0).all()  # once left, never back
        assert load[1, :long_][switched].min() == pytest.approx(P1, rel=1e-12)
