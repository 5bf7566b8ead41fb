"""The compiled stage loop of general models (:mod:`ncstab.paths.loop_general`).

General models (any number of dofs, with inertia and damping, switching branches at
bifurcation points) run by default on the compiled loop
(the shared template parts with a general model part, on threads).  It must
follow the same paths as the numpy stepper, which the tests of
``test_models.py`` (Hencky's loads, K against sympy) and ``test_bifurcations.py``
hold to closed forms, and as independent integrations here:

* the two engines are the same algorithms, but not the same roundings: numpy
  sums of more than seven terms pairwise and multiplies matrices in BLAS, the
  loop sums in order.  The DOP853 error estimate is a difference of nearly
  equal stage sums, so a last-bit change moves the next step size by a
  relative 1e-10 to 1e-7, and the stored states sit at slightly different
  arclengths along the same path.  What is compared is what does not depend
  on where the states are stored: statuses and messages, which events were
  found, their places (each a root located to ``event_tol``), and the ends of
  the stages (at their targets: projected onto equilibrium to ``newton_tol``
  for a total form, integrated to ``rtol`` for a rate form);
* results that depend on neither engine's rounding are bit for bit: 1 and 2
  threads, a case swept or alone.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import xarray as xr
from scipy.integrate import solve_ivp

pytest.importorskip("numba")

from ncstab.laws.spring import LINEAR_SPRING
from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.paths.threads import thread_limit, using_threads
from ncstab.systems import InteractionFamily, LoadDefinition, SystemDefinition, dof_symbols

RING = SystemSpec("ring", grains=6, secondary_contacts="ignore")
#: Grains 1 and 4 pushed in, the others free: flutter onsets, gaps closing and, for the
#: largest gammas, contacts leaving the admissible domain (|alpha| >= pi/2) before the target.
RING_PROGRAMME = [{"hold": {"F2": 0.0, "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D1": 0.6, "D4": 0.6}}]
RING_GRID = {"gamma": list(np.linspace(0.2, 2.0, 16))}
OPTIONS = PathOptions()


def _column_programme(links: int) -> list[dict]:
    """An imperfection force eps on the first hinge, then P to 1.1 times Hencky's first load."""
    others = {f"F{i}": 0.0 for i in range(2, links)}
    first = 4 * np.sin(np.pi / (2 * links)) ** 2
    return [
        {"hold": others, "drive": {"F1": "eps"}},
        {"hold": {**others, "F1": "current"}, "drive": {"P": 1.1 * first}},
    ]


def _both(spec, laws, programme, grid):
    """The numpy stepper's and the default engine's archives."""
    numpy_run = follow(spec, laws, programme, grid, PathOptions(backend="numpy")).to_dataset()
    default_run = follow(spec, laws, programme, grid, OPTIONS).to_dataset()
    return numpy_run, default_run


def _ends(dataset: xr.Dataset, name: str) -> np.ndarray:
    """Each case's last stored value of a state variable."""
    values = dataset[name].values
    cases = int(np.prod(dataset["n_steps"].shape))
    values = values.reshape(cases, dataset.sizes["step"], -1)
    last = dataset["n_steps"].values.reshape(-1) - 1
    return values[np.arange(cases), last]


def _compare(numpy_run: xr.Dataset, default_run: xr.Dataset, end_tol: float,
             ends: tuple[str, ...] = ("u", "F", "lam", "work")) -> None:
    assert "compiled stepper" in default_run.attrs["engine"]
    assert "compiled stepper" not in numpy_run.attrs["engine"]
    np.testing.assert_array_equal(default_run["status"].values, numpy_run["status"].values)
    np.testing.assert_array_equal(default_run["message"].values, numpy_run["message"].values)
    for name in ("limit_point", "hill_loss", "controllability_loss", "flutter_onset", "secondary_contact",
                 "turning_point", "bifurcation", "divergence"):
        found, expected = default_run[f"{name}_s"].values, numpy_run[f"{name}_s"].values
        np.testing.assert_array_equal(np.isnan(found), np.isnan(expected), err_msg=name)
        # each is the root of its indicator to event_tol on paths that agree far closer
        np.testing.assert_allclose(found, expected, rtol=0, atol=OPTIONS.event_tol, err_msg=name)
    for name in ends:
        np.testing.assert_allclose(_ends(default_run, name), _ends(numpy_run, name), rtol=0, atol=end_tol,
                                   err_msg=name)


def test_a_rate_law_ring_follows_the_numpy_steppers_paths_events_and_failures():
    """Cundall-Strack on the 6-grain ring: flutter onsets (the frequencies' discriminant of
    M s^2 + K), gaps closing, and cases failing where a contact leaves the domain, with the
    same messages.  Ends to 1e-9 (10 rtol: two integrations of a rate form, measured 1.6e-11)."""
    numpy_run, default_run = _both(RING, ["cundall_strack"], RING_PROGRAMME, RING_GRID)
    _compare(numpy_run, default_run, end_tol=1e-9)
    statuses = set(default_run["status"].values.ravel())
    assert statuses == {"finished", "failed:left_domain"}  # both kinds among the 16 cases
    assert np.isfinite(default_run["flutter_onset_s"].values).sum() >= 3
    assert np.isfinite(default_run["secondary_contact_s"].values).sum() >= 3


def test_contacts_switch_on_the_compiled_loop_as_on_the_numpy_stepper():
    """The ring with its nine gaps activated (Cundall-Strack) and with no_tension contacts that
    open (Turco): located switches, the same statuses, events and ends (1e-9, a rate form)."""
    numpy_run, default_run = _both(SystemSpec("ring", grains=6), ["cundall_strack"], RING_PROGRAMME, RING_GRID)
    _compare(numpy_run, default_run, end_tol=1e-9)
    assert np.isfinite(default_run["secondary_contact_s"].values).sum() >= 3
    opening = [{"hold": {"F1": 0.0, "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D2": 0.3, "D4": -0.3}}]
    numpy_run, default_run = _both(RING, ["turco+no_tension"], opening, RING_GRID)
    _compare(numpy_run, default_run, end_tol=1e-9)
    normal = _ends(default_run, "N")
    assert (normal == 0).any() and (normal > 0).any()  # contacts opened (N = 0 exactly), others closed


def test_gaps_closing_at_once_on_a_symmetric_ring_all_switch():
    """Grains 1 and 4 of the regular hexagon pushed in (McNamara): four gaps close at the same
    point by symmetry.  Each must switch (a crossing already past zero, by rounding, at the cut
    of another is kept for the next piece, cut_points.move_to_cut_points): the free grains then
    move alike to the end, on both engines (the loop lost one of the four before, and its end
    state was 4.5e-2 off the symmetric one)."""
    grid = {"gamma": float(np.linspace(0.2, 2.0, 16)[8])}
    numpy_run, default_run = _both(SystemSpec("ring", grains=6), ["mcnamara"], RING_PROGRAMME, grid)
    _compare(numpy_run, default_run, end_tol=1e-9)
    for run in (numpy_run, default_run):
        u = _ends(run, "u")[0]
        assert str(run["status"].item()) == "finished"
        np.testing.assert_allclose(u[[2, 4, 5]], u[1], rtol=0, atol=1e-12)  # grains 2, 3, 5, 6 alike
        assert abs(u[0] - u[3]) <= 1e-12


def test_cycles_of_a_ring_close_their_turns_as_on_the_numpy_stepper_and_show_greens_paradox():
    """Two turns of a circle in the plane (D1, D4) after a push: the cycle tables (work over
    each turn, the force gap, the drift of T) against the numpy stepper's to 1e-12 (each turn
    closes where its crossing is located, to event_tol in lambda; measured 4e-16), and Green's
    paradox: Cundall-Strack does work over a closed cycle, McNamara's potential law none
    (to 1e-12 against 3e-10)."""
    push = {"hold": {"F2": 0.0, "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D1": 0.05, "D4": 0.05}}
    programme = [push, {"cycle": {"center": [0.04, 0.05], "turns": 2, "direction": 1, "dofs": ["D1", "D4"]}}]
    grid = {"gamma": list(np.linspace(0.2, 2.0, 8))}
    work = {}
    for law in ("cundall_strack", "mcnamara"):
        numpy_run, default_run = _both(RING, [law], programme, grid)
        _compare(numpy_run, default_run, end_tol=1e-9)
        for name in ("cycle_work", "cycle_force_gap", "cycle_T_drift"):
            np.testing.assert_allclose(default_run[name].values, numpy_run[name].values, rtol=0, atol=1e-12,
                                       err_msg=name)
        work[law] = np.abs(default_run["cycle_work"].values)
        assert np.isfinite(work[law]).all()
    assert work["cundall_strack"].min() > 1e-10
    assert work["mcnamara"].max() < 1e-12


@pytest.mark.parametrize("links", [3, 4, 6])
def test_an_imperfect_column_follows_the_numpy_steppers_paths_to_its_ends(links):
    """Hencky's column with an imperfection sweep through zero (the perfect column crosses its
    bifurcation point by an over step; 3 links: two dofs, the loop's QR tangent against the
    numpy stepper's 2 x 2 closed forms): ends to 1e-12 (newton_tol: both projected onto the
    equilibrium path at the stage's target; measured 1.3e-15)."""
    grid = {"eps": list(np.linspace(-1e-3, 1e-3, 9))}
    numpy_run, default_run = _both(SystemSpec("column", links=links), None, _column_programme(links), grid)
    _compare(numpy_run, default_run, end_tol=1e-12)
    perfect = default_run.sel(eps=0.0)
    hencky = 4 * np.sin(np.pi / (2 * links)) ** 2
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
    assert "compiled stepper" in dataset.attrs["engine"]
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
    assert "compiled stepper" in archives[0].attrs["engine"]
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


def test_branches_switch_at_a_bifurcation_on_the_compiled_loop_as_on_the_numpy_stepper():
    """Hencky's perfect column of 5 links (4 dofs), at_bifurcation = "branches": the loop
    returns each case at the located bifurcation point (its branch test changing sign) and
    the stepper leaves along the bifurcating branch either way
    (branch_switching.leave_along_branch, the numpy stepper's own), then the loop follows it.
    Same statuses, events and ends as the numpy stepper (1e-12: total forms, projected at the
    target); the three branches end apart (the buckled ones mirror images, to 1e-12).  The
    work along every branch is the springs' strain energy, sum (theta_{i+1} - theta_i)^2 / 2
    with theta_i = asin(w_i - w_{i-1}) (conservative: the internal forces' work is the
    energy stored), to 1e-9 (the DOP853 integration at rtol 1e-10 of W ~ 0.5; measured
    2e-11).  (The numpy stepper's work after the switch is 6e-7 off that energy at the
    default max_step, so the work is not compared between the engines.)"""
    first = 4 * np.sin(np.pi / 10) ** 2
    programme = [{"drive": {"P": first + 0.05}, "at_bifurcation": "branches"}]
    numpy_run, default_run = _both(SystemSpec("column", links=5), None, programme, {})
    _compare(numpy_run, default_run, end_tol=1e-12, ends=("u", "F", "lam"))
    n_steps = default_run["n_steps"].values.reshape(-1)
    u = default_run["u"].values.reshape(3, default_run.sizes["step"], 4)
    work = default_run["work"].values.reshape(3, -1)
    for branch in range(3):
        w = np.pad(u[branch, : n_steps[branch]], ((0, 0), (1, 1)))
        energy = 0.5 * np.sum(np.diff(np.arcsin(np.diff(w, axis=1)), axis=1) ** 2, axis=1)
        np.testing.assert_allclose(work[branch, : n_steps[branch]], energy, rtol=0, atol=1e-9)
    np.testing.assert_allclose(default_run["bifurcation_load"].values, first, rtol=0, atol=OPTIONS.event_tol)
    ends = _ends(default_run, "u")  # branch 0, +1, -1
    assert np.abs(ends[0]).max() < 1e-12 and np.abs(ends[1]).min() > 1e-3
    np.testing.assert_allclose(ends[1], -ends[2], rtol=0, atol=1e-12)
    last = default_run["n_steps"].values.reshape(-1) - 1
    np.testing.assert_array_equal(default_run["branch_index"].values.reshape(3, -1)[np.arange(3), last], [0, 1, -1])


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
    Delta_{2n-1} (onset_cases.damped_onset, the numpy stepper's own per-case function,
    pasted).  Ziegler's pendulum over a 3 x 3 plane of dashpots (b1, b2) (the closed-form
    coefficients of n = 2) and a three-bar pendulum with b = 0.05 (the coefficients by
    interpolation on a circle, n = 3), each stopped at its flutter onset: the same
    statuses, events and ends as the numpy stepper (1e-12, total forms), and at every
    located onset the largest Re s of the spectrum, from numpy's eigenvalues, is 0 to 1e-9
    (the onset located to event_tol = 1e-10 in s, along which Re s moves at a rate of
    order 1; measured <= 1e-15).  At the undamped straight state the bars' mass matrix is
    the constant one written here."""
    programme = [{"drive": {"P": 5.0}, "stop_at": ["flutter_onset"]}]
    b = [1e-3, 0.05, 0.5]
    numpy_run, default_run = _both(SystemSpec("ziegler", load="follower"), None, programme, {"b1": b, "b2": b})
    _compare(numpy_run, default_run, end_tol=1e-12)
    assert (default_run["status"].values == "stopped:flutter_onset").all()
    mass = np.array([[3.0, 1.0], [1.0, 1.0]])  # masses 2 and 1, straight (phi = 0)
    for i, b1 in enumerate(b):
        for j, b2 in enumerate(b):
            stiffness = default_run["flutter_onset_K"].values.reshape(3, 3, 2, 2)[i, j]
            damping = np.array([[b1 + b2, -b2], [-b2, b2]])
            assert abs(_largest_growth(mass, damping, stiffness)) <= 1e-9
    numpy_run, default_run = _both(_three_bars(0.05), None, programme, {})
    _compare(numpy_run, default_run, end_tol=1e-12)
    stiffness = default_run["flutter_onset_K"].values.reshape(3, 3)
    mass = np.array([[5.0, 3.0, 1.0], [3.0, 3.0, 1.0], [1.0, 1.0, 1.0]])
    damping = 0.05 * np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    assert abs(_largest_growth(mass, damping, stiffness)) <= 1e-9
    # the destabilization paradox of three bars: the damped onset far below the undamped one
    undamped = follow(_three_bars(0.0), None, programme, {}, OPTIONS).to_dataset()
    assert float(default_run["flutter_onset_load"].item()) < 0.7 * float(undamped["flutter_onset_load"].item())


def test_one_dof_systems_run_on_the_compiled_loop_as_on_the_numpy_stepper():
    """Hencky's column of 2 links (1 dof; bifurcation at P = 2 exactly), perfect and with
    imperfection forces +-1e-3, and the transcritical one-dof system of test_bifurcations
    (u = 0 and u = P - 1 crossing at P = 1) followed along its branch and switched onto
    the other: the same statuses, events and ends (1e-12, total forms) as the numpy
    stepper, the ends u = 0 and u = P - 1 = 1 at P = 2 (1e-12: projected onto equilibrium
    to newton_tol, |dR/du| = 1 there)."""
    programme = [{"drive": {"F1": "eps"}}, {"hold": {"F1": "current"}, "drive": {"P": 3.0}}]
    numpy_run, default_run = _both(SystemSpec("column", links=2), None, programme, {"eps": [0.0, 1e-3, -1e-3]})
    _compare(numpy_run, default_run, end_tol=1e-12)
    assert abs(float(default_run["bifurcation_load"].values.ravel()[0]) - 2.0) <= OPTIONS.event_tol
    from test_bifurcations import _transcritical_system

    programme = [{"drive": {"P": 2.0}, "at_bifurcation": "branches"}]
    # (branch -1 leaves along u = P - 1 toward lower P and never reaches the target: the
    # numpy stepper takes minutes of steps to fail there, the loop a fraction of a second)
    numpy_run, default_run = _both(_transcritical_system(), None, programme, {"branch": [0, 1]})
    _compare(numpy_run, default_run, end_tol=1e-12)
    np.testing.assert_allclose(_ends(default_run, "u").ravel(), [0.0, 1.0], rtol=0, atol=1e-12)  # u = 0, u = P - 1
    np.testing.assert_allclose(default_run["bifurcation_load"].values, 1.0, rtol=0, atol=OPTIONS.event_tol)
