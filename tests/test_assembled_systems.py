"""Systems assembled from interaction elements (issue 37, first step).

Three independent checks of the element route:

* the element kinematics (hand-derived formulas in ``ncstab.elements``) against
  the symbolic definitions of the same systems (``ncstab.systems.granular`` and
  ``bars``, differentiated by sympy): q and J to 1e-12 (rounding of O(1) values);
* the assembled K against central finite differences of the assembled R
  (step 1e-6: truncation O(h^2) ~ 1e-12, rounding O(eps/h) ~ 1e-10; tolerance 1e-7);
* the sparse engine against Hencky's closed form P_1 = 4 sin^2(pi/2n) (the
  located bifurcation, 1e-9 relative for n <= 40: float64 limits the straight
  column's pencil to about 3e-8 at n = 1000, see docs/models.md) and against the
  equilibrium equations at every stored state.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sparse
import sympy as sp

from ncstab.elements import branch_kinematics
from ncstab.laws.registry import law_definition
from ncstab.operators.assembly import assemble
from ncstab.operators.sparse_indicators import (
    critical_eigenvalue,
    determinant,
    hill_eigenvalue,
    negative_pivots,
)
from ncstab.paths.assembled_engine import CaseRun
from ncstab.paths.assembled_path import follow_case
from ncstab.paths.options import PathOptions
from ncstab.paths.programme import parse_programme
from ncstab.systems.assembled_builders import assembled_column, assembled_diamond, assembled_ring
from ncstab.systems.bars import column
from ncstab.systems.granular import axes_diamond, ring


def _internal(system):
    out = {}
    if system.contacts is not None:
        out["contacts"] = np.zeros((system.contacts.size, 2))
    if system.springs is not None:
        out["springs"] = np.zeros((system.springs.size, 1))
    return out


def _symbolic_q_and_J(definition, u, substitutions):
    """q and dq/du of every member of a symbolic definition, at u (sympy, lambdified)."""
    dofs = definition.dof_symbols
    family = definition.families[0]
    q = sp.Matrix([e.subs(substitutions) for member in family.variables for e in member])
    J = q.jacobian(sp.Matrix(dofs))
    values = sp.lambdify(dofs, q, "numpy")(*u)
    jacobian = sp.lambdify(dofs, J, "numpy")(*u)
    k = len(family.variables[0])
    return np.asarray(values, float).reshape(-1, k), np.asarray(jacobian, float).reshape(-1, k, len(dofs))


@pytest.mark.parametrize(
    "assembled, symbolic",
    [(assembled_ring(6), ring(6)), (assembled_ring(7), ring(7)), (assembled_diamond("axes"), axes_diamond())],
    ids=["ring6", "ring7", "diamond_axes"],
)
def test_branch_kinematics_equal_the_symbolic_definition(assembled, symbolic):
    rng = np.random.default_rng(4)
    u = 0.05 * rng.standard_normal(assembled.n_dof)
    q_sym, J_sym = _symbolic_q_and_J(symbolic, u, {sp.Symbol("alpha0", real=True): sp.pi / 4})
    q, J, _ = branch_kinematics(assembled.contacts, u)
    np.testing.assert_allclose(q, q_sym, rtol=0, atol=1e-12)
    dense = np.zeros_like(J_sym)
    for m, dofs in enumerate(assembled.contacts.dofs):
        dense[m][:, dofs] = J[m]
    np.testing.assert_allclose(dense, J_sym, rtol=0, atol=1e-12)
    (name, values), = symbolic.families[0].member_parameters
    assert name == "alpha0"
    expected = [float(v.subs(sp.Symbol("alpha0", real=True), sp.pi / 4)) for v in values]
    np.testing.assert_allclose(assembled.contact_alpha0, expected, rtol=0, atol=1e-15)


@pytest.mark.parametrize("imperfection", [0.0, 0.07])
def test_column_springs_and_load_equal_the_symbolic_definition(imperfection):
    """Straight and imperfect (springs stress-free in imperfection sin(pi i / n)): the assembled
    springs' q and J equal the symbolic column's to 1e-12."""
    n = 6
    symbolic = column(n)
    assembled = assembled_column(n).for_values({"imperfection": imperfection})
    u = 0.1 * np.random.default_rng(5).standard_normal(n - 1)
    (spec,) = symbolic.parameters
    q_sym, J_sym = _symbolic_q_and_J(symbolic, u, {spec.symbol: imperfection})
    q, J, _ = assembled.springs.kinematics(u)
    np.testing.assert_allclose(q, q_sym, rtol=0, atol=1e-12)
    dense = np.zeros_like(J_sym)
    for m, dofs in enumerate(assembled.springs.dofs):
        np.add.at(dense[m], (slice(None), dofs), J[m])
    np.testing.assert_allclose(dense, J_sym, rtol=0, atol=1e-12)
    # the load: R(u, P) = internal - P Q_ext, Q_ext from the symbolic load vector
    load = np.array([float(e.subs(dict(zip(symbolic.dof_symbols, u)))) for e in symbolic.load.vector])
    state = assemble(assembled, None, {}, u, _internal(assembled), load=1.0)
    np.testing.assert_allclose(state.dR_dload, -load, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    "system, law",
    [
        (assembled_ring(6), "mcnamara"),
        (assembled_ring(9), "turco"),
        (assembled_diamond("axes"), "mcnamara+no_tension"),
        (assembled_diamond("symmetric"), "turco"),
        (assembled_column(7), None),
    ],
    ids=["ring6-mcnamara", "ring9-turco", "axes-no_tension", "symmetric-turco", "column7"],
)
@pytest.mark.parametrize("dense", [True, False])
def test_assembled_K_is_the_derivative_of_R(system, law, dense):
    rng = np.random.default_rng(6)
    n = system.n_dof
    u = 0.03 * rng.standard_normal(n)
    law_value = law_definition(law) if law else None
    internal = _internal(system)
    closed = np.array([[0, 3]]) if system.grains is not None and n >= 6 else None
    state = assemble(system, law_value, {"gamma": 0.7}, u, internal, load=0.2, closed=closed, kappa=2.0, dense=dense)
    K = state.K.toarray() if sparse.issparse(state.K) else state.K
    h = 1e-6
    fd = np.empty((n, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = h
        plus = assemble(system, law_value, {"gamma": 0.7}, u + e, internal, 0.2, closed, 2.0, dense).R
        minus = assemble(system, law_value, {"gamma": 0.7}, u - e, internal, 0.2, closed, 2.0, dense).R
        fd[:, i] = (plus - minus) / (2 * h)
    np.testing.assert_allclose(K, fd, rtol=0, atol=1e-7)


def test_sparse_indicators_equal_dense_linear_algebra():
    rng = np.random.default_rng(7)
    n = 400
    main = rng.uniform(-1, 3, n)
    K = sparse.diags([rng.uniform(-1, 1, n - 2), rng.uniform(-1, 1, n - 1), main, rng.uniform(-1, 1, n - 1),
                      rng.uniform(-1, 1, n - 2)], [-2, -1, 0, 1, 2], format="csr")
    A = K.toarray()
    sign, log = determinant(K)
    ref_sign, ref_log = np.linalg.slogdet(A)
    assert sign == ref_sign
    assert log == pytest.approx(ref_log, rel=1e-12)
    S = 0.5 * (A + A.T)
    eigenvalues = np.linalg.eigvalsh(S)
    assert hill_eigenvalue(K) == pytest.approx(eigenvalues[0], abs=1e-10)
    assert negative_pivots(sparse.csr_matrix(S)) == int(np.sum(eigenvalues < 0))
    value, vector = critical_eigenvalue(sparse.csr_matrix(S))
    assert value == pytest.approx(eigenvalues[np.argmin(np.abs(eigenvalues))], abs=1e-10)
    assert np.linalg.norm(S @ vector - value * vector) < 1e-9


@pytest.mark.parametrize("links", [5, 12, 40])
def test_hencky_column_bifurcation_load_and_buckled_branch(links):
    system = assembled_column(links)
    P1 = 4 * np.sin(np.pi / (2 * links)) ** 2  # Hencky (1921): P_1 = (4C/a) sin^2(pi/2n)
    programme = parse_programme([{"drive": {"P": 1.2 * P1}, "at_bifurcation": "switch"}],
                                system.dofs, system.forces, "P")
    run = CaseRun(system, None, {}, PathOptions(), "activate")
    out = follow_case(run, programme, {}, system.dofs, system.forces, "P")
    assert out.status == "finished", out.message
    event = out.events["bifurcation"]
    assert event["point"].load == pytest.approx(P1, rel=1e-9)
    assert event["s_lower"] <= event["s"] <= event["s_upper"]
    # the path left along the first buckling mode sin(pi i / n): the first state after the switch
    after = next(p for p in out.points if np.max(np.abs(p.u)) > 0)
    mode = np.sin(np.pi * np.arange(1, links) / links)
    assert abs(after.u @ mode) / (np.linalg.norm(after.u) * np.linalg.norm(mode)) > 0.999
    final = out.points[-1]
    assert final.load == pytest.approx(1.2 * P1, rel=1e-12)
    assert np.max(np.abs(final.u)) > 0.1  # buckled, not straight
    for point in out.points:  # every stored state is an equilibrium: R = 0 (every force held at 0)
        assert np.max(np.abs(point.state.R)) < 1e-9


def test_ring_pushed_in_is_in_equilibrium_and_reaches_its_target():
    n = 12
    system = assembled_ring(n)
    opposite = n // 2 + 1
    hold = {f"F{k}": 0.0 for k in range(1, n + 1) if k not in (1, opposite)}
    programme = parse_programme([{"hold": hold, "drive": {"D1": 0.1, f"D{opposite}": 0.1}}],
                                system.dofs, system.forces)
    run = CaseRun(system, law_definition("mcnamara"), {"gamma": 0.5}, PathOptions(), "ignore")
    out = follow_case(run, programme, {"gamma": 0.5}, system.dofs, system.forces, None)
    assert out.status == "finished", out.message
    final = out.points[-1]
    assert final.u[0] == pytest.approx(0.1, abs=1e-12)
    assert final.u[opposite - 1] == pytest.approx(0.1, abs=1e-12)
    free = [k for k in range(n) if k not in (0, opposite - 1)]
    for point in out.points:
        assert np.max(np.abs(point.state.R[free])) < 1e-9
    assert final.state.R[0] > 0  # the pushed grains carry a compressive force
    # the ring's mirror symmetry about the vertical axis: D_k = D_{n+2-k}
    np.testing.assert_allclose(final.u[1:], final.u[1:][::-1], atol=1e-9)


def test_an_element_naming_a_missing_dof_is_refused():
    from ncstab.elements import BranchElements
    from ncstab.systems.assembled import AssembledSystem

    contacts = BranchElements(("a_b",), np.array([[0, 5]]), np.zeros((1, 2, 2)), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="contact 'a_b' names a dof that does not exist"):
        AssembledSystem("mine", "test", ("x", "y"), ("Fx", "Fy"), contacts=contacts, contact_alpha0=np.zeros(1))


def test_a_case_tells_how_far_along_its_stages_it_is(monkeypatch):
    """Two stages of Hencky's column (P to 0.5 P1, then back to 0.2 P1): ``follow_case`` reports,
    after every accepted step, its stage and the fraction of the stage's driven quantity covered
    (P's own fraction, exactly: the path is straight); the fraction rises through each stage
    and ends above 0.9 (the stage's end itself is the located target).  ``follow`` shows it on
    its progress bar, at most every 0.5 s."""
    from ncstab.paths import assembled_result

    links = 12
    system = assembled_column(links)
    P1 = 4 * np.sin(np.pi / (2 * links)) ** 2
    programme = parse_programme([{"drive": {"P": 0.5 * P1}}, {"drive": {"P": 0.2 * P1}}], system.dofs, system.forces, "P")
    run = CaseRun(system, None, {}, PathOptions(), "activate")
    told: list[tuple[int, float]] = []
    out = follow_case(run, programme, {}, system.dofs, system.forces, "P", lambda *said: told.append(said))
    assert out.status == "finished"
    for stage in (1, 2):
        fractions = [f for k, f in told if k == stage]
        assert len(fractions) > 3 and np.all(np.diff(fractions) > 0) and 0.9 < fractions[-1] <= 1.0
    ends = (0.0, 0.5 * P1, 0.2 * P1)  # each stage's start and target: (P - start) / (target - start)
    expected = [(p.load - ends[k]) / (ends[k + 1] - ends[k]) for p, k in zip(out.points[1:], out.stages[1:])
                if p.load not in ends]  # (a stage's end is its located target, not a step)
    np.testing.assert_allclose([f for _, f in told], expected, rtol=1e-12)

    class Bar:  # the part of tqdm the engine uses
        postfix, updates = [], 0

        def set_postfix_str(self, text):
            self.postfix.append(text)

        def update(self, n):
            Bar.updates += n

    clock = iter(np.arange(0.0, 1000.0, 0.3))
    monkeypatch.setattr(assembled_result.time, "monotonic", lambda: float(next(clock)))
    bar = Bar()
    tell = assembled_result._case_progress(bar, 2, 5)
    tell(1, 0.25)  # 0.3 s after the start: not yet
    tell(1, 0.5)  # 0.6 s: shown
    assert bar.postfix == ["case 3/5: stage 1, 50%"]
