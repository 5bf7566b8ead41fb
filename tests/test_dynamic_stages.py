"""Dynamic stages (issue 43): the motion after the loss of stability and its energy balance.

Checked against independent results: the growth rate of Ziegler's flutter
oscillation against max Re s of the roots of the characteristic polynomial
det(M s^2 + K) written out by hand; the conservation of the total energy of
Ziegler's pendulum under a dead load, from its potential written out by hand;
the work of Cundall-Strack's contact over a closed loop of the motion against
the skew part of K times the loop's area (Green's paradox), McNamara's zero.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq, fsolve

from fault_helpers import assert_one_line, run_cli
from ncstab.dynamics import DynamicStage, follow_motions
from ncstab.paths.api import follow
from ncstab.paths.options import SystemSpec
from ncstab.studies import open_study, parse_study, run_study, write_dataset

ZIEGLER = """\
[study]
name = "ziegler_motion"
description = "dynamic stage test"
[system]
name = "ziegler"
load = "{load}"
damping = [{b}, {b}]
[[loading]]
drive = {{ P = {P} }}
[[loading]]
dynamic = {{ duration = {duration}, perturbation = {{ phi1 = {phi1} }}, samples = {samples} }}
[output]
figures = []
"""


def ziegler_study(load="follower", b=0.0, P=2.2, duration=40.0, phi1=1e-8, samples=401):
    return parse_study(ZIEGLER.format(load=load, b=b, P=P, duration=duration, phi1=phi1, samples=samples))


def growth_rate(P: float) -> float:
    """max Re s of det(M s^2 + K) on the straight state, by hand: M = [[3, 1], [1, 1]] (m1 = 2,
    m2 = 1), K = [[2 - P, P - 1], [-1, 1]], so det = 2 s^4 + (7 - 2P) s^2 + 1."""
    return float(np.roots([2.0, 0.0, 7.0 - 2.0 * P, 0.0, 1.0]).real.max())


# --- Ziegler's flutter ------------------------------------------------------------------------------


def test_flutter_oscillation_grows_at_the_rate_of_the_spectrum():
    """P = 2.2 > 7/2 - sqrt 2: log|phi1| at its peaks grows with slope max Re s, to 1e-4.

    The peaks are fitted where the amplitude is between 1e-5 and 1e-4: the decaying partner
    (-s) is then below 1e-6 relative to the growing mode, the nonlinear terms (~ amplitude^2)
    below 1e-8; the integrator's tolerance is 1e-11.  Measured: 3e-8."""
    path = follow("ziegler", None, [{"drive": {"P": 2.2}}])
    motion = follow_motions(path, DynamicStage(60.0, {"phi1": 1e-8}, samples=601), keep_solution=True)[0][0]
    assert motion.status == "finished"
    solution = motion.solution
    times = np.linspace(0.0, 60.0, 6001)
    rate = solution(times)[2]  # phi1' (state: phi1, phi2, phi1', phi2', works)
    peaks = []
    for a, b, ra, rb in zip(times[:-1], times[1:], rate[:-1], rate[1:]):
        if ra * rb < 0:
            t = brentq(lambda x: solution(x)[2], a, b, xtol=1e-14)
            peaks.append((t, abs(solution(t)[0])))
    peaks = np.array(peaks)
    window = (peaks[:, 1] > 1e-5) & (peaks[:, 1] < 1e-4)
    assert window.sum() >= 3
    slope = np.polyfit(peaks[window, 0], np.log(peaks[window, 1]), 1)[0]
    assert slope == pytest.approx(growth_rate(2.2), rel=1e-4)
    assert growth_rate(2.2) > 0.1


def test_below_the_flutter_load_the_amplitude_stays_bounded():
    """P = 1.9 < 7/2 - sqrt 2: every root imaginary; over 200 time units (about 30 periods) the
    amplitude stays within a few times the 1e-8 perturbation (through the study and its Dataset)."""
    assert growth_rate(1.9) == pytest.approx(0.0, abs=1e-7)
    dataset = run_study(ziegler_study(P=1.9, duration=200.0, samples=2001))
    assert str(dataset["motion_status"].item()) == "finished"
    amplitude = np.abs(dataset["u_t"].values).max()
    assert 1e-8 <= amplitude < 1e-7
    unstable = run_study(ziegler_study(P=2.2, duration=60.0, samples=601))
    assert np.abs(unstable["u_t"].values).max() > 1e-5


# --- the energy balance --------------------------------------------------------------------------------


def test_dead_load_conserves_energy_without_damping():
    """Dead load P = 0.2, phi1 = 0.5 (nonlinear), no damping: kinetic_energy + internal_work -
    external_work constant to 1e-8 relative over 40 time units; and the total energy written
    by hand -- T(u, u') + phi1^2/2 + (phi2 - phi1)^2/2 + P (cos phi1 + cos phi2) -- is constant
    too (it checks the Christoffel terms of the configuration-dependent mass)."""
    dataset = run_study(ziegler_study(load="dead", P=0.2, phi1=0.5, duration=40.0, samples=801))
    kinetic, external, internal = (dataset[k].values.ravel() for k in ("kinetic_energy", "external_work", "internal_work"))
    scale = kinetic.max()
    assert scale > 0.1
    assert np.abs(kinetic + internal - external).max() < 1e-8 * scale
    assert np.all(dataset["dissipated_work"].values == 0.0)
    phi1, phi2 = dataset["u_t"].values[0].T
    rate1, rate2 = dataset["velocity"].values[0].T
    by_hand = 0.5 * (3 * rate1**2 + 2 * np.cos(phi2 - phi1) * rate1 * rate2 + rate2**2)
    assert np.allclose(by_hand, kinetic, rtol=0, atol=1e-13)
    total = by_hand + 0.5 * phi1**2 + 0.5 * (phi2 - phi1) ** 2 + 0.2 * (np.cos(phi1) + np.cos(phi2))
    assert np.abs(total - total[0]).max() < 1e-8 * scale


def test_damped_dead_load_dissipates_and_balances():
    """b1 = b2 = 0.1: dissipated work positive and growing, the balance still to 1e-8."""
    dataset = run_study(ziegler_study(load="dead", b=0.1, P=0.2, phi1=0.5, duration=40.0, samples=801))
    kinetic, external, internal, dissipated = (
        dataset[k].values.ravel() for k in ("kinetic_energy", "external_work", "internal_work", "dissipated_work")
    )
    assert dissipated[-1] > 0.1
    assert np.all(np.diff(dissipated) >= -1e-15)
    assert np.abs(kinetic + internal + dissipated - external).max() < 1e-8 * kinetic.max()
    # the implicit integrator (stiff motions) keeps the balance too
    path = follow(SystemSpec("ziegler", load="dead"), None, [{"drive": {"P": 0.2}}], {"b1": 0.1, "b2": 0.1})
    motion = follow_motions(path, DynamicStage(40.0, {"phi1": 0.5}, samples=401, method="Radau", rtol=1e-10))[0][0]
    assert motion.status == "finished"
    assert np.abs(motion.energy_balance).max() < 1e-8 * motion.kinetic_energy.max()
    assert motion.dissipated_work[-1] == pytest.approx(dissipated[-1], rel=1e-6)


# --- Green's paradox in motion -----------------------------------------------------------------------------


def first_loop(motion):
    """(t1, t2): the first self-intersection u(t1) = u(t2) of the trajectory in the (D1, D2) plane,
    found on a fine polyline and refined on the dense output."""
    solution = motion.solution
    times = np.linspace(0.0, motion.time[-1], 8001)
    points = solution(times)[:2].T
    starts, ends = points[:-1], points[1:]
    for j in range(2, len(starts)):
        d, e, f = ends[j] - starts[j], ends[: j - 1] - starts[: j - 1], starts[: j - 1] - starts[j]
        with np.errstate(divide="ignore", invalid="ignore"):
            den = d[0] * e[:, 1] - d[1] * e[:, 0]
            along_j = (f[:, 0] * e[:, 1] - f[:, 1] * e[:, 0]) / den
            along_i = (f[:, 0] * d[1] - f[:, 1] * d[0]) / den
        hits = np.flatnonzero((along_j >= 0) & (along_j <= 1) & (along_i >= 0) & (along_i <= 1))
        if hits.size:
            i = hits[0]
            guess = [times[i] + along_i[i] * (times[1] - times[0]), times[j] + along_j[i] * (times[1] - times[0])]
            return fsolve(lambda x: solution(x[0])[:2] - solution(x[1])[:2], guess, xtol=1e-14)
    raise AssertionError("the trajectory never crosses itself")


def diamond_motion(law):
    path = follow(SystemSpec("diamond", secondary_contacts="ignore"), [law], [{"hold": {"F2": 0.0}, "drive": {"D1": 0.05}}],
                  {"gamma": 0.5})
    result = path.results[0]
    stiffness = result.steps["K"][0, result.n_steps[0] - 1]
    stage = DynamicStage(40.0, {"D1": 0.004, "D2": 0.003}, samples=801)
    return follow_motions(path, stage, keep_solution=True)[0][0], stiffness


def test_cundall_strack_interactions_do_work_over_a_closed_loop():
    """Cundall-Strack (gamma = 0.5, preloaded to D1 = 0.05 with F2 = 0, then released with both
    forces held): the balance holds to 1e-8, and over the first closed loop of the trajectory
    (u(t1) = u(t2)) the interactions' work is not zero: 1.16e-8 k_n (2R)^2 per contact, equal
    to -w (K12 - K21) A (w = 1/2 the work per contact, A the loop's signed area: the skew part
    of K, Green's paradox) to 1e-2 (the loop's size, ~1e-3, sets the linear estimate's error;
    measured 5e-4)."""
    motion, stiffness = diamond_motion("cundall_strack")
    assert motion.status == "finished"
    assert np.abs(motion.energy_balance).max() < 1e-8 * motion.kinetic_energy.max()
    t1, t2 = first_loop(motion)
    work = motion.solution(t2)[-2] - motion.solution(t1)[-2]
    loop = motion.solution(np.linspace(t1, t2, 20001))[:2]
    area = 0.5 * np.sum(loop[0, :-1] * loop[1, 1:] - loop[0, 1:] * loop[1, :-1])
    assert work == pytest.approx(1.16e-8, rel=1e-2)
    assert work == pytest.approx(-0.5 * (stiffness[0, 1] - stiffness[1, 0]) * area, rel=1e-2)
    assert abs(work) > 1e-5 * np.abs(motion.internal_work).max()


def test_mcnamara_interactions_work_returns_to_zero_over_a_closed_loop():
    """McNamara (hyperelastic): the interactions' work over the first closed loop is zero to 1e-8
    of its largest value (measured 1e-13)."""
    motion, _ = diamond_motion("mcnamara")
    assert np.abs(motion.energy_balance).max() < 1e-8 * motion.kinetic_energy.max()
    t1, t2 = first_loop(motion)
    work = motion.solution(t2)[-2] - motion.solution(t1)[-2]
    assert abs(work) < 1e-8 * np.abs(motion.internal_work).max()


# --- the Dataset ---------------------------------------------------------------------------------------


def test_dataset_variables_have_units_and_round_trip(tmp_path):
    import xarray as xr

    dataset = run_study(ziegler_study(P=2.2, duration=5.0, samples=51))
    for name in ("time", "u_t", "velocity", "kinetic_energy", "external_work", "internal_work", "dissipated_work",
                 "motion_status", "motion_message", "motion_steps"):
        assert {"units", "long_name", "description"} <= set(dataset[name].attrs), name
    assert dataset["u_t"].dims == ("law", "time", "dof")
    assert dataset["time"].values[-1] == 5.0
    write_dataset(dataset, tmp_path / "motion.nc")
    xr.testing.assert_identical(open_study(tmp_path / "motion.nc"), dataset)


def test_a_lone_dynamic_stage_starts_from_rest_and_holds_displacements():
    """A dynamic stage alone starts from rest (P = 0); a held displacement stays put."""
    text = ZIEGLER.format(load="follower", b=0.0, P=1.0, duration=10.0, phi1=0.1, samples=101)
    text = text.replace("[[loading]]\ndrive = { P = 1.0 }\n", "").replace("dynamic = {", 'hold = { phi2 = "current" }\ndynamic = {')
    dataset = run_study(parse_study(text))
    u = dataset["u_t"].values[0]
    assert np.all(u[:, 1] == 0.0)
    # one dof, spring stiffness 2 (both springs), inertia m1 + m2 = 3: phi1 = 0.1 cos(sqrt(2/3) t)
    assert np.allclose(u[:, 0], 0.1 * np.cos(np.sqrt(2 / 3) * dataset["time"].values), atol=1e-9)


# --- bad study files: exit 2 naming the field ------------------------------------------------------------

COLUMN = """\
[study]
name = "column_motion"
[system]
name = "column"
links = 3
[[loading]]
drive = { P = 0.5 }
[[loading]]
dynamic = { duration = 10.0, perturbation = { w1 = 1e-3 } }
"""


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (COLUMN, r"loading\[2\]\.dynamic: system 'column' declares no inertia"),
        (ZIEGLER.format(load="follower", b=0.0, P=2.2, duration=40.0, phi1=1e-8, samples=11).replace("duration = 40.0, ", ""),
         r"loading\[2\]\.dynamic\.duration: missing"),
        (ZIEGLER.format(load="follower", b=0.0, P=2.2, duration=40.0, phi1=1e-8, samples=11).replace("phi1 = 1e-08", "phi3 = 1e-8"),
         r"loading\[2\]\.dynamic\.perturbation\.phi3: unknown dof 'phi3'; dofs are: phi1, phi2"),
        (ZIEGLER.format(load="follower", b=0.0, P=2.2, duration=-1.0, phi1=1e-8, samples=11),
         r"loading\[2\]\.dynamic\.duration: expected a time > 0"),
        (ZIEGLER.format(load="follower", b=0.0, P=2.2, duration=4.0, phi1=1e-8, samples=11) + "[[loading]]\ndrive = { P = 3.0 }\n",
         r"loading\[2\]\.dynamic: a dynamic stage is the programme's last"),
        (ZIEGLER.format(load="follower", b=0.0, P=2.2, duration=4.0, phi1=1e-8, samples=11).replace("dynamic = {", "drive = { P = 3.0 }\ndynamic = {"),
         r"loading\[2\]\.drive: a dynamic stage drives nothing"),
    ],
    ids=["no-inertia", "no-duration", "unknown-dof", "negative-duration", "not-last", "drives"],
)
def test_bad_dynamic_stages_exit_2_naming_the_field(tmp_path, capfd, text, needle):
    study = tmp_path / "study.toml"
    study.write_text(text)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2
    assert_one_line(err, needle)
    assert not (tmp_path / "out.nc").exists()


# --- figures ---------------------------------------------------------------------------------------------


def test_motion_figures_draw_the_dataset(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from ncstab.plotting.figures import FIGURE_KINDS

    dataset = run_study(ziegler_study(P=2.2, duration=20.0, samples=201))
    motion = FIGURE_KINDS["motion"](dataset)
    top, bottom = motion.axes[:2]
    assert np.array_equal(top.lines[0].get_ydata(), dataset["u_t"].values[0, :, 0])
    assert bottom.get_ylabel() == "log10 |u - u(0)|"
    phase = FIGURE_KINDS["phase_portrait"](dataset)
    assert [axis.get_ylabel() for axis in phase.axes] == ["dphi1/dt", "dphi2/dt"]
    assert np.array_equal(phase.axes[0].lines[0].get_xdata(), dataset["u_t"].values[0, :, 0])
    assert np.array_equal(phase.axes[0].lines[0].get_ydata(), dataset["velocity"].values[0, :, 0])
    energies = FIGURE_KINDS["energies"](dataset)
    labels = [line.get_label() for line in energies.axes[0].lines]
    assert labels == ["kinetic energy", "external work", "internal work", "dissipated work"]
    assert "energy balance" in energies.axes[0].get_title()
    for name, figure in (("motion", motion), ("phase", phase), ("energies", energies)):
        figure.savefig(tmp_path / f"{name}.png")
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000


# --- the burst past Hill's loss ---------------------------------------------------------------------------


def test_burst_past_hill_loss_feeds_kinetic_energy_by_minus_the_second_order_work():
    """The seed's diamond (McNamara, gamma = 0.5) under its mixed control: F2 = 0.75 held, D1
    driven to 0.58, past Hill's loss (D1 = 0.561); then D1 released with F1 held too and the
    state displaced by 1e-4 along the eigenvector of K_sym with the negative eigenvalue (the
    direction of negative second-order work).  With the forces held, the energy balance gives
    kinetic_energy = -(d2W(Delta u) - d2W(delta)) / 2, d2W(x) = w x . K x the second-order work
    per contact of the displacement from the equilibrium: checked to 10 |Delta u| relative
    (the cubic terms) while |Delta u| < 0.01, over two decades of growth; the burst then
    leaves the admissible domain (stopped:left_domain)."""
    path = follow(SystemSpec("diamond", secondary_contacts="ignore"), ["mcnamara"],
                  [{"hold": {"F1": 0.0}, "drive": {"F2": 0.75}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.58}}],
                  {"gamma": 0.5})
    result = path.results[0]
    last = result.n_steps[0] - 1
    start, stiffness = result.steps["u"][0, last], result.steps["K"][0, last]
    eigenvalues, vectors = np.linalg.eigh(0.5 * (stiffness + stiffness.T))
    assert eigenvalues[0] < -0.2  # past Hill's loss
    direction = 1e-4 * vectors[:, 0]
    stage = DynamicStage(30.0, {"D1": direction[0], "D2": direction[1]}, samples=301)
    motion = follow_motions(path, stage)[0][0]
    assert motion.status == "stopped:left_domain"
    increment = motion.u - start
    size = np.linalg.norm(increment, axis=1)
    second_order_work = 0.5 * np.einsum("ti,ij,tj->t", increment, stiffness, increment)  # w = 1/2
    assert second_order_work[0] < 0
    predicted = -0.5 * (second_order_work - second_order_work[0])
    growing = (size < 0.01) & (motion.time > 0)
    assert size[growing].max() > 50 * size[0]
    error = np.abs(motion.kinetic_energy[growing] - predicted[growing])
    assert np.all(error <= 10 * size[growing] * predicted[growing])


def test_a_dynamic_study_is_not_run_in_chunks(tmp_path, capfd):
    """The motions are not streamed chunk by chunk (yet): --workers is refused before anything runs."""
    study = tmp_path / "study.toml"
    study.write_text(ZIEGLER.format(load="dead", b=0.0, P=0.2, duration=1.0, phi1=0.1, samples=11))
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc", "--workers", "2"], capfd)
    assert code == 2
    assert_one_line(err, r"a study with a dynamic stage runs in one process")
    assert not (tmp_path / "out.nc").exists()
