"""Granular packings (issue 38): rotating-grain contact kinematics, K of a packing, its indicators, the CLI.

Tolerances, and why:

* central differences with step h = 1e-6 of functions whose entries are O(1):
  truncation h^2 |f'''| ~ 1e-12, rounding eps |f| / h ~ 1e-10, so 1e-7 (J, K)
  and 1e-6 (H, from differences of J);
* symmetry and null vectors: sums of O(1) terms, each rounded at 1e-16: 1e-10
  (the issue's bar);
* eigenvalues from ARPACK (tol 1e-12) against LAPACK: 1e-8 absolute on O(1)
  spectra.
"""

from __future__ import annotations

import numpy as np
import pytest

from ncstab.elements import law_response
from ncstab.elements.grain_contact import GrainContacts, grain_contact_kinematics
from ncstab.laws.registry import law_definition
from ncstab.operators.packing_analysis import (
    analyse_packing,
    packing_contacts,
    packing_tangent,
    second_order_work,
)
from ncstab.systems.packing import Packing, triangular_lattice, validate

SEED_LAWS = ["cundall_strack", "weakly_hypoelastic", "mcnamara", "turco"]
H = 1e-6


def _random_contacts(m: int = 7, seed: int = 3) -> tuple[GrainContacts, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = 6 * m
    dofs = np.arange(n).reshape(m, 6)
    r = rng.uniform(0.3, 0.7, (m, 2))
    angle = rng.uniform(-np.pi, np.pi, m)
    distance = (r[:, 0] + r[:, 1]) * rng.uniform(0.97, 1.0, m)
    branch = distance[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    lever = r / r.sum(axis=1, keepdims=True)
    contacts = GrainContacts(dofs, branch, lever, r.sum(axis=1))
    return contacts, rng.normal(scale=0.02, size=n)


def test_contact_jacobian_and_hessian_equal_finite_differences() -> None:
    contacts, u = _random_contacts()
    _, J, Hs = grain_contact_kinematics(contacts, u)
    for j in range(len(u)):
        e = np.zeros(len(u))
        e[j] = H
        qp, Jp, _ = grain_contact_kinematics(contacts, u + e)
        qm, Jm, _ = grain_contact_kinematics(contacts, u - e)
        m, col = divmod(j, 6)
        assert np.allclose((qp[m] - qm[m]) / (2 * H), J[m, :, col], atol=1e-7)
        assert np.allclose((Jp[m] - Jm[m]) / (2 * H), Hs[m, :, :, col], atol=1e-6)


def test_rigid_motions_leave_q_unchanged_and_l_dbeta_is_the_contact_slip() -> None:
    contacts, u = _random_contacts()
    q0, J, _ = grain_contact_kinematics(contacts, u)
    # a rigid rotation phi of both grains about the origin (each grain's centre moves, and it turns by phi)
    phi, m = 0.37, contacts.size
    rotated = u.copy().reshape(m, 6)
    c, s = np.cos(phi), np.sin(phi)
    # branch X_b - X_a = branch + (u_b - u_a): rotate the displaced branch by phi; translations are arbitrary
    d = contacts.branch + rotated[:, 3:5] - rotated[:, 0:2]
    turned = np.column_stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]])
    rotated[:, 3:5] = rotated[:, 0:2] + 0.4 + turned - contacts.branch
    rotated[:, 0:2] += 0.4
    rotated[:, [2, 5]] += phi
    q1, _, _ = grain_contact_kinematics(contacts, rotated.ravel())
    assert np.allclose(q1[:, 0], q0[:, 0], atol=1e-12)
    assert np.allclose(np.angle(np.exp(1j * (q1[:, 1] - q0[:, 1]))), 0.0, atol=1e-12)
    # at u = 0 the grains touch at |d| = rho: rho l dbeta is the slip of the two material points at the contact
    touching = GrainContacts(contacts.dofs, contacts.branch / np.linalg.norm(contacts.branch, axis=1)[:, None]
                             * contacts.scale[:, None], contacts.lever, contacts.scale)
    zero = np.zeros(6 * m)
    q, J, _ = grain_contact_kinematics(touching, zero)
    du = np.random.default_rng(5).normal(size=6 * m) * 1e-7
    ra, rb = touching.lever[:, 0] * touching.scale, touching.lever[:, 1] * touching.scale
    n = touching.branch / touching.scale[:, None]
    t = np.column_stack([-n[:, 1], n[:, 0]])
    e = du.reshape(m, 6)
    slip_a = e[:, 0:2] + ra[:, None] * e[:, 2:3] * t   # point of a at the contact: v_a + omega_a x (r_a n)
    slip_b = e[:, 3:5] - rb[:, None] * e[:, 5:6] * t   # point of b: v_b + omega_b x (-r_b n)
    slip = np.sum((slip_b - slip_a) * t, axis=1)
    dbeta = np.einsum("ml,ml->m", J[:, 1], e)
    assert np.allclose(touching.scale * q[:, 0] * dbeta, slip, rtol=1e-12, atol=1e-20)
    # grains that do not rotate: beta is the branch angle (the seed's diamond, Eq. 1-3)
    assert np.allclose(q[:, 1], np.arctan2(touching.branch[:, 1], touching.branch[:, 0]), atol=0)


def _loaded(rows: int = 4, columns: int = 5, fix: bool = True, seed: int = 2, jitter: float = 0.1) -> Packing:
    packing = triangular_lattice(rows, columns, fix_bottom=fix, jitter=jitter, seed=seed)
    rng = np.random.default_rng(seed)
    return packing.with_forces(rng.uniform(0.005, 0.05, packing.n_contacts),
                               rng.uniform(-0.01, 0.01, packing.n_contacts))


@pytest.mark.parametrize("name", SEED_LAWS)
def test_the_law_reproduces_the_packing_forces_and_R_is_their_resultant(name: str) -> None:
    """R at the state equals minus the resultant of the given forces on each grain (the force of a on b
    is N n - T t, its moment on b r_b T |d|/(r_a + r_b)): an independent sum over contacts."""
    packing = _loaded()
    tangent = packing_tangent(packing, law_definition(name), 0.7)
    assert np.allclose(tangent.forces[:, 0], packing.normal_force, atol=1e-12)
    assert np.allclose(tangent.forces[:, 1], packing.tangential_force, atol=1e-12)
    a, b = packing.contacts.T
    d = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
    dist = np.linalg.norm(d, axis=1)
    nvec = d / dist[:, None]
    t = np.column_stack([-nvec[:, 1], nvec[:, 0]])
    on_b = packing.normal_force[:, None] * nvec - packing.tangential_force[:, None] * t
    lever = dist / (packing.radius[a] + packing.radius[b])
    resultant = np.zeros((packing.n_grains, 3))
    np.add.at(resultant[:, :2], b, on_b)
    np.add.at(resultant[:, :2], a, -on_b)
    np.add.at(resultant[:, 2], b, packing.radius[b] * packing.tangential_force * lever)
    np.add.at(resultant[:, 2], a, packing.radius[a] * packing.tangential_force * lever)
    assert np.allclose(tangent.R, -resultant[packing.free].ravel(), atol=1e-12)


@pytest.mark.parametrize("name", SEED_LAWS)
def test_K_equals_a_finite_difference_of_R(name: str) -> None:
    """Total laws: central differences of R(u).  Rate laws: the stored T advanced by its rate rows
    (df* = C dq, seed Eq. 13) between the two states, so that R(u) is the law's along the difference."""
    packing = _loaded()
    law = law_definition(name)
    response = law_response(law)
    tangent = packing_tangent(packing, law, 0.7)
    rho = tangent.contacts.scale
    contacts, n = packing_contacts(packing, scale=rho)
    K = tangent.K.toarray()
    f0 = np.column_stack([packing.normal_force, packing.tangential_force])
    full = np.zeros(n + 1)
    q0 = grain_contact_kinematics(contacts, full, second=False)[0]
    C = response.response(q0, f0 / rho[:, None], tangent.parameters)[2]
    for j in range(n):
        columns = []
        for sign in (1, -1):
            u = np.zeros(n)
            u[j] = sign * H
            full[:n] = u
            q = grain_contact_kinematics(contacts, full, second=False)[0]
            internal = f0 + rho[:, None] * np.einsum("mfk,mk->mf", C, q - q0)
            columns.append(packing_tangent(packing, law, 0.7, u=u, internal=internal).R)
        assert np.allclose((columns[0] - columns[1]) / (2 * H), K[:, j], atol=1e-7), f"column {j}"


def test_mcnamara_K_is_the_hessian_of_its_energy() -> None:
    """W = sum rho^2 [(l - 1)^2/2 + gamma (beta - alpha0)^2/2] (seed Eq. 19), written here from the grains'
    positions and rotations alone; its second differences equal K."""
    packing = _loaded(3, 4)
    gamma = 0.8
    tangent = packing_tangent(packing, law_definition("mcnamara"), gamma)
    rho, alpha0 = tangent.contacts.scale, tangent.parameters["alpha0"]
    a, b = packing.contacts.T
    index = packing.dof_index()

    def energy(u):
        X = np.column_stack([packing.x, packing.y, np.zeros(packing.n_grains)])
        free = index >= 0
        X[free] += u[index[free]]
        d = X[b, :2] - X[a, :2]
        l = np.linalg.norm(d, axis=1) / rho
        ra, rb = packing.radius[a], packing.radius[b]
        beta = np.arctan2(d[:, 1], d[:, 0]) - (ra * X[a, 2] + rb * X[b, 2]) / (ra + rb)
        return np.sum(rho**2 * ((l - 1) ** 2 / 2 + gamma * (beta - alpha0) ** 2 / 2))

    n = packing.n_dof
    h = 1e-4  # second differences: truncation h^2 ~ 1e-8, rounding eps W / h^2 ~ 1e-8
    K = tangent.K.toarray()
    rng = np.random.default_rng(0)
    for i, j in rng.integers(0, n, size=(25, 2)):
        ei, ej = np.eye(n)[i] * h, np.eye(n)[j] * h
        second = (energy(ei + ej) - energy(ei - ej) - energy(ej - ei) + energy(-ei - ej)) / (4 * h * h)
        assert abs(second - K[i, j]) <= 1e-6, (i, j, second, K[i, j])


def test_free_lattice_mcnamara_zero_forces_has_exactly_three_zero_eigenvalues() -> None:
    packing = triangular_lattice(6, 7)
    result = analyse_packing(packing, law_definition("mcnamara"), 1.0, modes=5)
    K = result.tangent.K.toarray()
    assert np.abs(K - K.T).max() <= 1e-10
    assert result.zero_eigenvalues == 3 and result.negative_eigenvalues == 0
    assert result.mode_values[3] > 1e3 * result.tolerance  # the fourth is not a zero eigenvalue
    # the null vectors: two translations and the rigid rotation theta_i = 1, (x, y)_i = (-y_i, x_i)
    rotation = np.column_stack([-packing.y, packing.x, np.ones(packing.n_grains)]).ravel()
    for vector in (np.tile([1.0, 0, 0], packing.n_grains), np.tile([0, 1.0, 0], packing.n_grains), rotation):
        assert np.abs(K @ vector).max() <= 1e-10
    assert result.det_sign == 0


def test_alternating_tangential_forces_make_cundall_strack_asymmetric_but_not_mcnamara() -> None:
    packing = triangular_lattice(6, 7, fix_bottom=True)
    T = np.where(np.arange(packing.n_contacts) % 2, 0.01, -0.01)
    loaded = packing.with_forces(np.full(packing.n_contacts, 0.02), T)
    cundall = packing_tangent(loaded, law_definition("cundall_strack"), 0.5).K.toarray()
    mcnamara = packing_tangent(loaded, law_definition("mcnamara"), 0.5).K.toarray()
    assert np.abs(mcnamara - mcnamara.T).max() <= 1e-10
    # D = [[1, 0], [T*, gamma l^2]]: the skew part is of order T
    assert np.abs(cundall - cundall.T).max() >= 0.5 * np.abs(T).max()


def test_sparse_indicators_equal_dense_lapack() -> None:
    """Past DENSE_DOFS: inertia (LDL^T), Hill's eigenvalue and the modes against numpy's eigh of K_sym."""
    packing = _loaded(16, 16, jitter=0.05)
    packing = packing.with_forces(packing.normal_force * 6, packing.tangential_force)
    result = analyse_packing(packing, law_definition("cundall_strack"), 0.3, modes=4)
    K = result.tangent.K.toarray()
    assert K.shape[0] > 600
    values = np.linalg.eigvalsh((K + K.T) / 2)
    assert abs(result.hill - values[0]) <= 1e-8
    assert np.allclose(result.mode_values, values[:4], atol=1e-8)
    assert result.negative_eigenvalues == int(np.sum(values < -result.tolerance)) > 0
    assert result.zero_eigenvalues == int(np.sum(np.abs(values) <= result.tolerance))
    assert result.det_sign == int(np.linalg.slogdet(K)[0])
    S = (K + K.T) / 2
    for value, mode in zip(result.mode_values, result.modes):
        assert np.abs(S @ mode - value * mode).max() <= 1e-8
    assert np.allclose(result.participation.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(result.participation[:, packing.fixed] == 0)
    assert np.allclose(second_order_work(result.tangent.K, result.modes), result.mode_values, atol=1e-10)


def test_free_lattice_on_the_sparse_path_counts_three_zero_eigenvalues() -> None:
    result = analyse_packing(triangular_lattice(15, 15), law_definition("mcnamara"), 1.0, modes=4)
    assert result.tangent.K.shape[0] > 600
    assert (result.zero_eigenvalues, result.negative_eigenvalues) == (3, 0)
    assert np.allclose(result.mode_values[:3], 0, atol=1e-9) and result.mode_values[3] > 1e-6


@pytest.mark.parametrize("bad, message", [
    ({"x": [0, 1, np.nan]}, "variable 'x': entry 2 is nan"),
    ({"radius": [0.5, -0.5, 0.5]}, "variable 'radius': entry 1 is -0.5"),
    ({"grain_b": [1, 3]}, "variable 'grain_b': entry 1 is 3, not a grain index"),
    ({"grain_a": [0, 2], "grain_b": [1, 2]}, "variable 'grain_b': entry 1 is 2, the same grain"),
    ({"fixed": [0, 2, 0]}, "variable 'fixed': entry 1 is 2"),
    ({"normal_force": [0.1, np.inf]}, "variable 'normal_force': entry 1 is inf"),
    ({"grain_a": [0, 1], "grain_b": [1, 0]}, "entry 1 repeats the contact between grains 1 and 0"),
])
def test_malformed_packings_name_the_variable_and_entry(bad, message) -> None:
    from ncstab.systems.packing import PackingError

    values = {"x": [0.0, 1.0, 0.5], "y": [0.0, 0.0, 0.9], "radius": [0.5, 0.5, 0.5], "fixed": [1, 0, 0],
              "grain_a": [0, 1], "grain_b": [1, 2]}
    with pytest.raises(PackingError, match=message.replace("(", r"\(")):
        validate({**values, **bad}, "p.nc")
