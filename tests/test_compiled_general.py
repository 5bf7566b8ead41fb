"""The compiled stage loop of general models (:mod:`ncstab.paths.loop_general`).

General models (any number of dofs, with inertia and damping, switching branches at
bifurcation points) run on the compiled loop (the shared template parts with a
general model part, on threads).  Its paths are held here to what the engine does not
compute itself (``test_models.py`` and ``test_bifurcations.py`` hold the models to
Hencky's loads, K against sympy and the bifurcation closed forms):

* the ring's kinematics, written out here (grain i on its axis at the polar angle
  2 pi (i - 1)/6, moved by D_i toward the centre): located secondary contacts have
  their gap at zero, the path leaves the domain where a contact's alpha reaches
  pi/2, a no_tension contact opens where its overlap (seed Eq. 28) is zero and
  carries N = <overlap> everywhere, the symmetric pushes keep the ring's mirror
  symmetry, and at a located flutter onset K has a double eigenvalue (numpy's);
* an independent integration (scipy's ``solve_ivp`` at rtol 1e-12) of the
  ring's rate system;
* closed cycles of the ring: each turn closed, Green's paradox;
* Hencky's column: its critical loads, the equilibrium of its end states
  (the potential written out here, differentiated by sympy), mirror images,
  and the strain energy equal to the work along each branch;
* damped pendulums: Re s = 0 at each located flutter onset (numpy's eigenvalues),
  Ziegler's equal-damping flutter load in closed form;
* results that depend on no rounding choice are bit for bit: 1 and 2 threads,
  a case swept or alone.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import xarray as xr
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

pytest.importorskip("numba")

from ncstab.laws.spring import LINEAR_SPRING
from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.paths.threads import thread_limit, using_threads
from ncstab.systems import InteractionFamily, LoadDefinition, SystemDefinition, dof_symbols
from ncstab.systems.closed_forms import ziegler_equal_damping_flutter_load

RING = SystemSpec("ring", grains=6, secondary_contacts="ignore")
#: Grains 1 and 4 pushed in, the others free: flutter onsets, gaps closing and, for the
#: largest gammas, contacts leaving the admissible domain (|alpha| >= pi/2) before the target.
RING_PROGRAMME = [{"hold": {"F2": 0.0, "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D1": 0.6, "D4": 0.6}}]
RING_GRID = {"gamma": list(np.linspace(0.2, 2.0, 16))}
OPTIONS = PathOptions()
#: A located root (a gap, an overlap, the domain's edge) is bracketed to event_tol = 1e-10
#: in arclength, along which these quantities move at rates of order 1 (up to ~10 for
#: alpha near the edge): 1e-9 (measured <= 3e-11).
LOCATED_TOL = 1e-9

#: The regular hexagon of unit grains (radius 1 / (2 sin(pi/6)) = 1): grain i's axis,
#: from the centre, at the polar angle 2 pi (i - 1)/6 clockwise from the top.
_AXES = np.stack([np.sin(2 * np.pi * np.arange(6) / 6), np.cos(2 * np.pi * np.arange(6) / 6)], axis=-1)
#: alpha0 of every contact of the hexagon, pi/2 - pi/6.
RING_ALPHA0 = np.pi / 3


def ring_positions(u: np.ndarray) -> np.ndarray:
    """Grain centres (..., 6, 2): each at distance 1 - D_i from the centre along its axis."""
    return (1.0 - u[..., :, None]) * _AXES


def ring_gaps(u: np.ndarray) -> dict[str, np.ndarray]:
    """Centre distance minus one grain diameter of every pair of non-neighbour grains."""
    positions = ring_positions(u)
    gaps = {}
    for i in range(6):
        for j in range(i + 2, 6):
            if (i, j) != (0, 5):
                gaps[f"{i + 1}_{j + 1}"] = np.linalg.norm(positions[..., i, :] - positions[..., j, :], axis=-1) - 1
    return gaps


def ring_contacts(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(l, alpha) (..., 6) of contacts (i, i+1): the branch from grain i+1 to grain i and its
    angle counterclockwise from grain i's axis (seed Eq. 1 for every contact)."""
    positions = ring_positions(u)
    lengths, angles = [], []
    for i in range(6):
        branch = positions[..., i, :] - positions[..., (i + 1) % 6, :]
        axis = _AXES[i]
        lengths.append(np.hypot(branch[..., 0], branch[..., 1]))
        angles.append(np.arctan2(axis[0] * branch[..., 1] - axis[1] * branch[..., 0],
                                 axis[0] * branch[..., 0] + axis[1] * branch[..., 1]))
    return np.stack(lengths, axis=-1), np.stack(angles, axis=-1)


def _ran_compiled(dataset: xr.Dataset) -> None:
    """Every law (or model) of the archive followed by the compiled stepper."""
    for part in dataset.attrs["engine"].split("; "):
        assert part.split(": ", 1)[1].startswith("compiled stepper (numba "), part


def _column_programme(links: int) -> list[dict]:
    """An imperfection force eps on the first hinge, then P to 1.1 times Hencky's first load."""
    others = {f"F{i}": 0.0 for i in range(2, links)}
    first = 4 * np.sin(np.pi / (2 * links)) ** 2
    return [
        {"hold": others, "drive": {"F1": "eps"}},
        {"hold": {**others, "F1": "current"}, "drive": {"P": 1.1 * first}},
    ]


def column_residual(links: int):
    """R(w, P) - F for Hencky's column, written out here: bar i at sin(theta_i) = w_i - w_{i-1}
    (w_0 = w_n = 0), unit springs on theta_{j+1} - theta_j, P doing the work
    P sum(1 - cos(theta_i)): the gradient of the potential sum (theta_{j+1} - theta_j)^2 / 2
    - P sum(1 - cos theta_i) (differentiated by sympy), minus the lateral forces F."""
    w = sp.symbols(f"w1:{links}")
    load = sp.Symbol("P")
    joints = (0, *w, 0)
    rise = [joints[i] - joints[i - 1] for i in range(1, links + 1)]
    theta = [sp.asin(x) for x in rise]
    potential = sum((theta[j] - theta[j - 1]) ** 2 / 2 for j in range(1, links)) - load * sum(
        1 - sp.sqrt(1 - x**2) for x in rise
    )
    gradient = sp.lambdify((w, load), [sp.diff(potential, wi) for wi in w], "numpy")
    return lambda u, p, forces: np.asarray(gradient(u, p), dtype=float) - forces


def _ends(dataset: xr.Dataset, name: str) -> np.ndarray:
    """Each case's last stored value of a state variable."""
    values = dataset[name].values
    cases = int(np.prod(dataset["n_steps"].shape))
    values = values.reshape(cases, dataset.sizes["step"], -1)
    last = dataset["n_steps"].values.reshape(-1) - 1
    return values[np.arange(cases), last]


def test_a_rate_law_ring_locates_flutter_onsets_and_gap_closings_and_fails_at_the_domains_edge():
    """Cundall-Strack on the 6-grain ring, grains 1 and 4 pushed in alike: every stored state
    keeps the ring's two mirror symmetries (D1 = D4, D2 = D3 = D5 = D6, to 1e-12: rounding,
    measured 9e-16); cases that finish end at D1 = D4 = 0.6 (to 1e-9, the stage end located);
    the others fail with left_domain where, by the ring's kinematics, a contact's alpha
    reaches pi/2 (to LOCATED_TOL: the last admissible state found by bisection to event_tol).
    Gaps closing (recorded, secondary contacts ignored): grains 1 and 4 meet at the centre,
    D1 = D4 = 1/2, the gap 1_4 zero to LOCATED_TOL and every other gap open.  Flutter onsets
    (M = I: the eigenvalue discriminant of K): K has a double eigenvalue there, numpy's two
    closest eigenvalues within 1e-4 of each other (the coalescing pair splits as
    sqrt(|d(lambda_i - lambda_j)^2/ds| event_tol) ~ 1e-5 within the onset's bracket;
    measured <= 4e-6, the next closest pair of these K 5e-4 apart or more)."""
    dataset = follow(RING, ["cundall_strack"], RING_PROGRAMME, RING_GRID, OPTIONS).to_dataset().isel(law=0)
    _ran_compiled(dataset)
    status = dataset["status"].values.astype(str)
    assert set(status) == {"finished", "failed:left_domain"}  # both kinds among the 16 cases
    n_steps = dataset["n_steps"].values
    for k in range(status.size):
        u = dataset["u"].values[k, : n_steps[k]]
        np.testing.assert_allclose(u[:, [1, 2, 4, 5]], u[:, [1, 1, 1, 1]], rtol=0, atol=1e-12, err_msg=f"case {k}")
        np.testing.assert_allclose(u[:, 3], u[:, 0], rtol=0, atol=1e-12, err_msg=f"case {k}")
        if status[k] == "finished":
            np.testing.assert_allclose(u[-1, [0, 3]], 0.6, rtol=0, atol=1e-9)
        else:
            assert "admissible domain" in str(dataset["message"].values[k])
            _, alpha = ring_contacts(u[-1])
            assert abs(np.abs(alpha).max() - np.pi / 2) <= LOCATED_TOL, (k, np.pi / 2 - np.abs(alpha).max())
    contact = np.isfinite(dataset["secondary_contact_s"].values)
    assert contact.sum() >= 3
    for k in np.flatnonzero(contact):
        u = dataset["secondary_contact_u"].values[k]
        gaps = ring_gaps(u)
        assert abs(gaps.pop("1_4")) <= LOCATED_TOL and abs(u[0] - 0.5) <= LOCATED_TOL, k
        assert min(gaps.values()) > 0.05, (k, gaps)
    flutter = np.isfinite(dataset["flutter_onset_s"].values)
    assert flutter.sum() >= 3
    for k in np.flatnonzero(flutter):
        eigenvalues = np.linalg.eigvals(dataset["flutter_onset_K"].values[k])
        closest = np.abs(eigenvalues[:, None] - eigenvalues[None, :])[np.triu_indices(6, 1)].min()
        assert closest <= 1e-4, (k, np.sort_complex(eigenvalues))


def test_contacts_switch_on_the_compiled_loop_where_their_gaps_and_overlaps_are_zero():
    """The ring with its nine gaps activated (Cundall-Strack): each located switch at D1 = 1/2,
    the gap 1_4 zero to LOCATED_TOL.  no_tension contacts (Turco) pushed in, then pulled apart
    (D2 in, D4 out): at every stored state N = <delta> with the overlap of seed Eq. (28),
    delta = cos(alpha - alpha0) - l*, from the ring's kinematics (to 1e-12: rounding; measured
    8e-16); the overlap of a contact never changes sign within a step: each switch is a
    stored state with delta = 0 to LOCATED_TOL, contacts opening inside the second stage."""
    activated = follow(SystemSpec("ring", grains=6), ["cundall_strack"], RING_PROGRAMME, RING_GRID, OPTIONS)
    dataset = activated.to_dataset().isel(law=0)
    _ran_compiled(dataset)
    assert set(dataset["status"].values.astype(str)) <= {"finished", "failed:left_domain"}
    contact = np.isfinite(dataset["secondary_contact_s"].values)
    assert contact.sum() >= 3
    for k in np.flatnonzero(contact):
        u = dataset["secondary_contact_u"].values[k]
        assert abs(ring_gaps(u)["1_4"]) <= LOCATED_TOL and abs(u[0] - 0.5) <= LOCATED_TOL, k
    opening = [
        {"hold": {"F2": 0.0, "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D1": 0.05, "D4": 0.05}},
        {"hold": {"F1": "current", "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D2": 0.3, "D4": -0.3}},
    ]
    dataset = follow(RING, ["turco+no_tension"], opening, RING_GRID, OPTIONS).to_dataset().isel(law=0)
    _ran_compiled(dataset)
    assert (dataset["status"].values == "finished").all()
    n_steps = dataset["n_steps"].values
    for k in range(n_steps.size):
        n = n_steps[k]
        length, alpha = ring_contacts(dataset["u"].values[k, :n])
        overlap = np.cos(alpha - RING_ALPHA0) - length
        np.testing.assert_allclose(dataset["N"].values[k, :n], np.maximum(overlap, 0.0), rtol=0, atol=1e-12)
        side = np.where(np.abs(overlap) <= LOCATED_TOL, 0.0, np.sign(overlap))
        assert not np.any(side[1:] * side[:-1] < 0), k  # from one side to the other only through a switch
        switches = (side[1:] == 0) & (side[:-1] > 0) & (dataset["stage"].values[k, 1:n, None] == 1)
        assert switches.any(), k  # a contact closed in the first stage opened inside the second
        assert (overlap[-1] < -1e-3).any(), k  # and is open at the end


def test_gaps_closing_at_once_on_a_symmetric_ring_all_switch():
    """Grains 1 and 4 of the regular hexagon pushed in (McNamara): four gaps close at the same
    point by symmetry.  Each must switch (a crossing already past zero, by rounding, at the cut
    of another is kept for the next piece, cut_points.move_to_cut_points): the free grains then
    move alike to the end, the ring's mirror symmetry kept to 1e-12 (rounding; the loop lost
    one of the four before, and its end state was 4.5e-2 off the symmetric one)."""
    grid = {"gamma": float(np.linspace(0.2, 2.0, 16)[8])}
    dataset = follow(SystemSpec("ring", grains=6), ["mcnamara"], RING_PROGRAMME, grid, OPTIONS).to_dataset()
    _ran_compiled(dataset)
    u = _ends(dataset, "u")[0]
    assert str(dataset["status"].item()) == "finished"
    np.testing.assert_allclose(u[[2, 4, 5]], u[1], rtol=0, atol=1e-12)  # grains 2, 3, 5, 6 alike
    assert abs(u[0] - u[3]) <= 1e-12


def test_cycles_of_a_ring_close_their_turns_and_show_greens_paradox():
    """Two turns of a circle in the plane (D1, D4) after a push: each turn ends with D1 and D4
    where it started (to LOCATED_TOL: the turn's end located to event_tol in arclength), and
    Green's paradox: McNamara's potential law comes back to the same state (every D and F to
    1e-9) having done no work (|W| < 1e-12, the work integrated at rtol 1e-10 over terms of
    order 1e-3; measured 3e-13); Cundall-Strack does work over each closed turn (|W| > 1e-10,
    measured >= 3e-10) and its free grains and forces do not come back (the ratchet, forces
    off by more than 1e-7; measured >= 1e-6)."""
    push = {"hold": {"F2": 0.0, "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D1": 0.05, "D4": 0.05}}
    programme = [push, {"cycle": {"center": [0.04, 0.05], "turns": 2, "direction": 1, "dofs": ["D1", "D4"]}}]
    grid = {"gamma": list(np.linspace(0.2, 2.0, 8))}
    for law in ("cundall_strack", "mcnamara"):
        dataset = follow(RING, [law], programme, grid, OPTIONS).to_dataset().isel(law=0)
        _ran_compiled(dataset)
        assert (dataset["status"].values == "finished").all()
        work = np.abs(dataset["cycle_work"].values)
        assert work.shape == (8, 2) and np.isfinite(work).all()
        for k in range(8):
            n = int(dataset["n_steps"].values[k])
            stage, lam = dataset["stage"].values[k, :n], dataset["lam"].values[k, :n]
            u, forces = dataset["u"].values[k, :n], dataset["F"].values[k, :n]
            start = np.flatnonzero(stage == 1)[0]
            for turn in (1, 2):
                end = np.flatnonzero((stage == 1) & (np.abs(lam - 2 * np.pi * turn) <= 1e-8))[0]
                np.testing.assert_allclose(u[end, [0, 3]], u[start, [0, 3]], rtol=0, atol=LOCATED_TOL)
                if law == "mcnamara":
                    np.testing.assert_allclose(u[end], u[start], rtol=0, atol=1e-9)
                    np.testing.assert_allclose(forces[end], forces[start], rtol=0, atol=1e-9)
                else:
                    assert np.abs(forces[end] - forces[start]).max() > 1e-7, (k, turn)
        if law == "mcnamara":
            assert work.max() < 1e-12
        else:
            assert work.min() > 1e-10


@pytest.mark.parametrize("links", [3, 4, 6])
def test_an_imperfect_column_ends_in_equilibrium_on_the_branch_its_imperfection_selects(links):
    """Hencky's column with an imperfection sweep through zero (the perfect column crosses its
    bifurcation point by an over step; 3 links: two dofs, the loop's QR tangent).  Each end
    state is in equilibrium by the potential written out here (column_residual: to 1e-10,
    newton_tol 1e-12 with margin; measured 4e-16), at P = 1.1 times Hencky's first load
    (to 1e-9, the stage end located) with F1 = eps (to 1e-12, held since the first stage);
    the perfect column stays straight (to 1e-12), the imperfect ones buckle with w1 of the
    sign of eps (|w1| > 0.5) and +-eps give mirror images (to 1e-12: the same equations,
    mirrored, projected to newton_tol); the perfect column's bifurcation is at Hencky's
    load 4 sin^2(pi / 2n) to event_tol."""
    eps = np.linspace(-1e-3, 1e-3, 9)
    dataset = follow(SystemSpec("column", links=links), None, _column_programme(links), {"eps": list(eps)}, OPTIONS)
    dataset = dataset.to_dataset()
    _ran_compiled(dataset)
    assert (dataset["status"].values == "finished").all()
    hencky = 4 * np.sin(np.pi / (2 * links)) ** 2
    u, forces, load = _ends(dataset, "u"), _ends(dataset, "F"), _ends(dataset, "lam")[:, 0]
    residual = column_residual(links)
    for k in range(eps.size):
        assert np.abs(residual(u[k], load[k], forces[k])).max() <= 1e-10, k
    np.testing.assert_allclose(load, 1.1 * hencky, rtol=0, atol=1e-9)
    np.testing.assert_allclose(forces[:, 0], eps, rtol=0, atol=1e-12)
    assert np.abs(u[4]).max() <= 1e-12  # eps = 0
    buckled = np.flatnonzero(eps != 0)
    assert np.all(np.sign(u[buckled, 0]) == np.sign(eps[buckled])) and np.all(np.abs(u[buckled, 0]) > 0.5)
    np.testing.assert_allclose(u, -u[::-1], rtol=0, atol=1e-12)
    perfect = dataset.sel(eps=0.0)
    assert abs(float(perfect["bifurcation_load"].item()) - hencky) <= OPTIONS.event_tol


def test_a_ring_case_ends_where_an_independent_integration_of_its_rate_system_ends():
    """Cundall-Strack on the ring, D1 = D4 = t driven to 0.2, the other forces held at 0:
    the default engine's end state against scipy's DOP853 at rtol 1e-12 of du/dt = M^-1 g'
    (M the rows of K of the force-controlled dofs and of I elsewhere, g' = e1 + e4) and
    dT/dt = (dT/du) du/dt, from the model's kernel alone.  To 1e-9: the engine integrates in
    arclength to rtol 1e-10 (measured 2e-12)."""
    from ncstab.paths.api import case_batch

    target = 0.2
    programme = [{"hold": {"F2": 0.0, "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D1": target, "D4": target}}]
    dataset = follow(RING, ["cundall_strack"], programme, {"gamma": 0.5}, OPTIONS).to_dataset()
    _ran_compiled(dataset)
    assert str(dataset["status"].item()) == "finished"
    batch = case_batch("cundall_strack", RING, {"gamma": np.array([0.5])}, 1)
    kernel, n, n_internal = batch._kernel, batch.n_dof, batch.n_internal
    layout = kernel.layout
    driven = np.zeros(n)
    driven[[0, 3]] = 1.0
    state = batch.initial_secondary_state(np.zeros((1, n)))

    def rhs(_, y):
        row = kernel.evaluate(y[None, :n], y[None, n:], 0.0, state, batch._rows)[0]
        stiffness = row[layout.stiffness : layout.stiffness + n * n].reshape(n, n)
        matrix = np.where(driven[:, None] > 0, np.eye(n), stiffness)
        du = np.linalg.solve(matrix, driven)
        gradient = row[layout.gradient : layout.gradient + n_internal * n].reshape(n_internal, n)
        return np.concatenate([du, gradient @ du])

    y0 = np.concatenate([batch.initial_state()[0], np.zeros(n_internal)])
    solution = solve_ivp(rhs, (0.0, target), y0, method="DOP853", rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(_ends(dataset, "u")[0], solution.y[:n, -1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(_ends(dataset, "T")[0], solution.y[n:, -1], rtol=0, atol=1e-9)


@pytest.mark.skipif(thread_limit() < 2, reason="numba runs one thread here (NUMBA_NUM_THREADS or one core)")
def test_one_and_two_threads_give_the_same_general_archive_bit_for_bit():
    """160 ring cases (three blocks of 64 dealt to two threads): a case's arithmetic does not
    depend on its thread."""
    grid = {"gamma": list(np.linspace(0.2, 2.0, 160))}
    archives = []
    for threads in (1, 2):
        with using_threads(threads):
            dataset = follow(RING, ["cundall_strack"], RING_PROGRAMME, grid, OPTIONS).to_dataset()
        dataset.attrs.pop("created", None)
        archives.append(dataset)
    _ran_compiled(archives[0])
    xr.testing.assert_identical(archives[0], archives[1])


def test_a_swept_ring_case_equals_the_case_followed_alone_bit_for_bit():
    grid = list(np.linspace(0.2, 2.0, 16))
    swept = follow(RING, ["cundall_strack"], RING_PROGRAMME, {"gamma": grid}, OPTIONS).to_dataset()
    alone = follow(RING, ["cundall_strack"], RING_PROGRAMME, {"gamma": grid[11]}, OPTIONS).to_dataset()
    for name in ("u", "F", "lam", "T", "s"):
        n = int(alone["n_steps"].item())
        np.testing.assert_array_equal(
            swept[name].isel(gamma=11).values.reshape(swept.sizes["step"], -1)[:n],
            alone[name].values.reshape(alone.sizes["step"], -1)[:n],
        )


def test_branches_switch_at_a_bifurcation_on_the_compiled_loop():
    """Hencky's perfect column of 5 links (4 dofs), at_bifurcation = "branches": the loop
    returns each case at the located bifurcation point (its branch test changing sign),
    the stepper leaves along the bifurcating branch either way
    (branch_switching.leave_along_branch), then the loop follows it.  The bifurcation is at
    Hencky's first load 4 sin^2(pi/10) to event_tol; each branch ends at its target load
    (to 1e-9, located) in equilibrium by the potential written out here (column_residual, to
    1e-10: newton_tol with margin); the three branches end apart, the straight one at
    w = 0 and the buckled ones mirror images (to 1e-12).  The work along every branch is
    the springs' strain energy, sum (theta_{i+1} - theta_i)^2 / 2 with
    theta_i = asin(w_i - w_{i-1}) (conservative: the internal forces' work is the energy
    stored), to 1e-9 (the DOP853 integration at rtol 1e-10 of W ~ 0.5; measured 2e-11)."""
    first = 4 * np.sin(np.pi / 10) ** 2
    programme = [{"drive": {"P": first + 0.05}, "at_bifurcation": "branches"}]
    dataset = follow(SystemSpec("column", links=5), None, programme, {}, OPTIONS).to_dataset()
    _ran_compiled(dataset)
    assert (dataset["status"].values == "finished").all()
    n_steps = dataset["n_steps"].values.reshape(-1)
    u = dataset["u"].values.reshape(3, dataset.sizes["step"], 4)
    work = dataset["work"].values.reshape(3, -1)
    for branch in range(3):
        w = np.pad(u[branch, : n_steps[branch]], ((0, 0), (1, 1)))
        energy = 0.5 * np.sum(np.diff(np.arcsin(np.diff(w, axis=1)), axis=1) ** 2, axis=1)
        np.testing.assert_allclose(work[branch, : n_steps[branch]], energy, rtol=0, atol=1e-9)
    np.testing.assert_allclose(dataset["bifurcation_load"].values, first, rtol=0, atol=OPTIONS.event_tol)
    ends, loads, forces = _ends(dataset, "u"), _ends(dataset, "lam")[:, 0], _ends(dataset, "F")  # branch 0, +1, -1
    np.testing.assert_allclose(loads, first + 0.05, rtol=0, atol=1e-9)
    residual = column_residual(5)
    for branch in range(3):
        assert np.abs(residual(ends[branch], loads[branch], forces[branch])).max() <= 1e-10, branch
    assert np.abs(ends[0]).max() < 1e-12 and np.abs(ends[1]).min() > 1e-3
    np.testing.assert_allclose(ends[1], -ends[2], rtol=0, atol=1e-12)
    last = dataset["n_steps"].values.reshape(-1) - 1
    np.testing.assert_array_equal(dataset["branch_index"].values.reshape(3, -1)[np.arange(3), last], [0, 1, -1])


def _three_bars(b: float) -> SystemDefinition:
    """Ziegler's pendulum with three bars (written out here): angles phi1..phi3 from the
    vertical, unit springs on the relative rotations phi1, phi2 - phi1, phi3 - phi2,
    point masses 2, 2, 1 at the joints and the tip (M_ik = sum_{j >= max(i,k)} m_j
    cos(phi_i - phi_k)), equal dashpots b on the relative rotations, and a follower
    tip load along the third bar (virtual work P sum_i sin(phi_i - phi3) dphi_i)."""
    phi = dof_symbols(("phi1", "phi2", "phi3"))
    masses = (2, 2, 1)
    relative = (phi[0], phi[1] - phi[0], phi[2] - phi[1])
    gradients = ((1, 0, 0), (-1, 1, 0), (0, -1, 1))  # of the relative rotations
    return SystemDefinition(
        name="three_bars", title="three bars under a follower tip load", dofs=("phi1", "phi2", "phi3"),
        forces=("M1", "M2", "M3"),
        families=(InteractionFamily("springs", "spring", ("base", "middle", "top"), tuple((r,) for r in relative),
                                    law=LINEAR_SPRING),),
        load=LoadDefinition("P", "follower", tuple(sp.sin(phi[i] - phi[2]) for i in range(3))),
        mass=tuple(tuple(sum(masses[max(i, k):]) * sp.cos(phi[i] - phi[k]) for k in range(3)) for i in range(3)),
        damping=tuple(tuple(sum(b * g[i] * g[k] for g in gradients) for k in range(3)) for i in range(3)),
    )


def _largest_growth(mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> float:
    """max Re s over the eigenvalues of the first-order form of M s^2 + C s + K (numpy's
    eigvals of [[0, I], [-M^-1 K, -M^-1 C]]: independent of the stepper's Hurwitz test)."""
    n = mass.shape[0]
    first_order = np.block([[np.zeros((n, n)), np.eye(n)],
                            [-np.linalg.solve(mass, stiffness), -np.linalg.solve(mass, damping)]])
    return float(np.linalg.eigvals(first_order).real.max())


def test_damped_pendulums_flutter_on_the_compiled_loop_where_a_root_crosses_the_imaginary_axis():
    """Damping runs on the compiled loop: its flutter column is the Hurwitz determinant
    Delta_{2n-1} (onset_cases.damped_onset, pasted).  Ziegler's pendulum over a 3 x 3 plane
    of dashpots (b1, b2) (the closed-form coefficients of n = 2) and a three-bar pendulum with
    b = 0.05 (the coefficients by interpolation on a circle, n = 3), each stopped at its
    flutter onset: at every located onset the largest Re s of the spectrum, from numpy's
    eigenvalues, is 0 to 1e-9 (the onset located to event_tol = 1e-10 in s, along which
    Re s moves at a rate of order 1; measured <= 1e-15).  At the undamped straight state
    the bars' mass matrix is the constant one written here.  With equal dashpots
    b1 = b2 = b, Ziegler's onset is at 41/28 + b^2/2 (Routh-Hurwitz in closed form,
    closed_forms.ziegler_equal_damping_flutter_load) to 1e-9 (P = lambda located to
    event_tol; measured 1e-15)."""
    programme = [{"drive": {"P": 5.0}, "stop_at": ["flutter_onset"]}]
    b = [1e-3, 0.05, 0.5]
    dataset = follow(SystemSpec("ziegler", load="follower"), None, programme, {"b1": b, "b2": b}, OPTIONS).to_dataset()
    _ran_compiled(dataset)
    assert (dataset["status"].values == "stopped:flutter_onset").all()
    mass = np.array([[3.0, 1.0], [1.0, 1.0]])  # masses 2 and 1, straight (phi = 0)
    for i, b1 in enumerate(b):
        for j, b2 in enumerate(b):
            stiffness = dataset["flutter_onset_K"].values.reshape(3, 3, 2, 2)[i, j]
            damping = np.array([[b1 + b2, -b2], [-b2, b2]])
            assert abs(_largest_growth(mass, damping, stiffness)) <= 1e-9
    loads = dataset["flutter_onset_load"].values.reshape(3, 3)
    np.testing.assert_allclose(np.diag(loads), ziegler_equal_damping_flutter_load(np.array(b)), rtol=0, atol=1e-9)
    damped = follow(_three_bars(0.05), None, programme, {}, OPTIONS).to_dataset()
    _ran_compiled(damped)
    assert str(damped["status"].item()) == "stopped:flutter_onset"
    stiffness = damped["flutter_onset_K"].values.reshape(3, 3)
    mass = np.array([[5.0, 3.0, 1.0], [3.0, 3.0, 1.0], [1.0, 1.0, 1.0]])
    damping = 0.05 * np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    assert abs(_largest_growth(mass, damping, stiffness)) <= 1e-9
    # the destabilization paradox of three bars: the damped onset far below the undamped one
    undamped = follow(_three_bars(0.0), None, programme, {}, OPTIONS).to_dataset()
    assert float(damped["flutter_onset_load"].item()) < 0.7 * float(undamped["flutter_onset_load"].item())


def test_one_dof_systems_run_on_the_compiled_loop():
    """Hencky's column of 2 links (1 dof w; bifurcation at P = 2 exactly), perfect and with
    imperfection forces eps = +-1e-3, to P = 3: the perfect column stays straight (w = 0),
    the imperfect ones end at the root of the closed-form equilibrium
    (4 asin(w) - 2 P w) / sqrt(1 - w^2) = eps (the potential 2 asin(w)^2 - 2 P (1 - sqrt(1 - w^2))
    differentiated) at P = 3, to 1e-10 (the end located on P = 3 to event_tol, dw/dP = 0.04
    there; measured 1.3e-12).  The transcritical one-dof system of test_bifurcations (u = 0
    and u = P - 1 crossing at P = 1), followed along its branch and switched onto the other,
    ends at u = 0 and u = P - 1 = 1 at P = 2 (1e-12: projected onto equilibrium to newton_tol,
    |dR/du| = 1 there), its bifurcation at P = 1 to event_tol."""
    programme = [{"drive": {"F1": "eps"}}, {"hold": {"F1": "current"}, "drive": {"P": 3.0}}]
    eps = [0.0, 1e-3, -1e-3]
    dataset = follow(SystemSpec("column", links=2), None, programme, {"eps": eps}, OPTIONS).to_dataset()
    _ran_compiled(dataset)
    assert (dataset["status"].values == "finished").all()
    assert abs(float(dataset["bifurcation_load"].values.ravel()[0]) - 2.0) <= OPTIONS.event_tol
    ends = _ends(dataset, "u")[:, 0]
    assert ends[0] == 0.0
    for k in (1, 2):
        sign = np.sign(eps[k])

        def equilibrium(w, imperfection=eps[k]):
            return 4 * np.arcsin(w) - 6.0 * w - imperfection * np.sqrt(1 - w * w)

        expected = brentq(equilibrium, sign * 0.5, sign * (1 - 1e-9), xtol=1e-15, rtol=4 * np.finfo(float).eps)
        assert abs(ends[k] - expected) <= 1e-10, (k, ends[k] - expected)
    from test_bifurcations import _transcritical_system

    programme = [{"drive": {"P": 2.0}, "at_bifurcation": "branches"}]
    # (branch -1 leaves along u = P - 1 toward lower P and never reaches the target)
    dataset = follow(_transcritical_system(), None, programme, {"branch": [0, 1]}, OPTIONS).to_dataset()
    _ran_compiled(dataset)
    np.testing.assert_array_equal(dataset["status"].values.ravel(), ["finished", "finished"])
    np.testing.assert_allclose(_ends(dataset, "u").ravel(), [0.0, 1.0], rtol=0, atol=1e-12)  # u = 0, u = P - 1
    np.testing.assert_allclose(dataset["bifurcation_load"].values, 1.0, rtol=0, atol=OPTIONS.event_tol)
