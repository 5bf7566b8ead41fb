"""Events during the motion of a dynamic stage (issue 43): a secondary contact closing and a
kinetic-energy threshold, located on the dense output.

Every located time is checked against an independent integration: scipy's ``solve_ivp``
(DOP853, rtol = 1e-12, atol = 1e-14, steps of at most 0.01 so that its step-end event
check resolves the excursions these motions have) with ``events=``, on equations of motion
written out here by hand -- Lagrange's equations of Ziegler's pendulum from its kinetic and
potential energies, and the seed's diamond with McNamara's law from its energy (seed
Eq. 19) -- and with the event functions written by hand (the kinetic energy
T = (3 phi1'^2 + 2 cos(phi2 - phi1) phi1' phi2' + phi2'^2) / 2, the gaps 2 (cos alpha0 -
Delta_1) - 1 and 2 (sin alpha0 - Delta_2) - 1 of seed Figs. 14-15).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fault_helpers import assert_one_line, run_cli
from ncstab.dynamics import DynamicStage, follow_motions
from ncstab.paths.api import follow
from ncstab.paths.options import SystemSpec
from ncstab.studies import open_study, parse_study, run_study, write_dataset

#: The reference integration: tolerances far below the motions' (1e-11 relative), steps short
#: enough for its step-end check of events.
REFERENCE = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-14, "max_step": 0.01}


def first_event(rhs, y0, duration, indicator, direction):
    """The first time ``indicator(y)`` crosses zero in ``direction`` (solve_ivp's own event location)."""

    def event(t, y):
        return indicator(y)

    event.terminal, event.direction = True, direction
    solution = solve_ivp(rhs, (0.0, duration), y0, events=event, **REFERENCE)
    assert solution.status == 1, "the reference never meets the event"
    return float(solution.t_events[0][0])


# --- Ziegler's pendulum under a dead load: the kinetic-energy threshold ----------------------------------

P_DEAD = 0.2


def ziegler_rhs(t, y):
    """Lagrange's equations of Ziegler's pendulum (m1 = 2, m2 = 1, l = k = 1) under a dead tip load P:
    T = (3 p1'^2 + 2 c p1' p2' + p2'^2) / 2, V = p1^2 / 2 + (p2 - p1)^2 / 2 + P (cos p1 + cos p2),
    c = cos(p2 - p1), s = sin(p2 - p1):
    3 p1'' + c p2'' = s p2'^2 - (2 p1 - p2 - P sin p1),  c p1'' + p2'' = -s p1'^2 - (p2 - p1 - P sin p2)."""
    p1, p2, v1, v2 = y
    c, s = math.cos(p2 - p1), math.sin(p2 - p1)
    rhs = [s * v2**2 - (2 * p1 - p2 - P_DEAD * math.sin(p1)), -s * v1**2 - (p2 - p1 - P_DEAD * math.sin(p2))]
    a1, a2 = np.linalg.solve([[3.0, c], [c, 1.0]], rhs)
    return [v1, v2, a1, a2]


def ziegler_kinetic_energy(u, velocity):
    c = math.cos(u[1] - u[0])
    return 0.5 * (3 * velocity[0] ** 2 + 2 * c * velocity[0] * velocity[1] + velocity[1] ** 2)


@pytest.mark.parametrize(
    "threshold",
    [0.05, 0.0806],
    ids=["on-the-first-swing", "an-excursion-inside-one-step"],
)
def test_kinetic_energy_threshold_is_located_where_an_independent_integration_finds_it(threshold):
    """Released from phi1 = 0.3 under a dead load P = 0.2 (no damping).  0.05 is first reached
    at t = 0.570; 0.0806 at t = 6.43, over an excursion [6.4302, 6.4898] inside one step of
    the motion's integrator, both of whose ends are below the threshold (so is it inside one
    step of solve_ivp without max_step, which reports 17.50; with one part per step instead of
    SUBDIVISIONS this case fails).  Located time against the reference to 1e-8
    (both integrations' errors, ~1e-11 of the state, divided by the energy's rate; measured
    9e-11), the kinetic energy written by hand at the located state equal to the threshold to
    1e-10 relative (the root finder's bracket; measured 1e-16)."""
    path = follow(SystemSpec("ziegler", load="dead"), None, [{"drive": {"P": P_DEAD}}])
    stage = DynamicStage(20.0, {"phi1": 0.3}, samples=201, kinetic_energy_threshold=threshold)
    motion = follow_motions(path, stage)[0][0]
    assert motion.status == "finished"  # located, not stopped: stop_at is empty
    event = motion.events["kinetic_energy"]
    expected = first_event(ziegler_rhs, [0.3, 0.0, 0.0, 0.0], 20.0,
                           lambda y: ziegler_kinetic_energy(y[:2], y[2:]) - threshold, 1)
    assert event.time == pytest.approx(expected, abs=1e-8)
    assert ziegler_kinetic_energy(event.u, event.velocity) == pytest.approx(threshold, rel=1e-10)
    assert event.kinetic_energy == pytest.approx(threshold, rel=1e-10)
    # the stored kinetic energy stays below the threshold before the located time
    before = motion.time < event.time
    assert np.all(motion.kinetic_energy[before] < threshold)


def test_a_motion_stops_at_the_kinetic_energy_threshold_when_the_stage_says_so():
    """stop_at = ["kinetic_energy"]: status stopped:kinetic_energy, the stored times after the
    located one NaN, the ones before it finite."""
    path = follow(SystemSpec("ziegler", load="dead"), None, [{"drive": {"P": P_DEAD}}])
    stage = DynamicStage(20.0, {"phi1": 0.3}, samples=201, kinetic_energy_threshold=0.05, stop_at=("kinetic_energy",))
    motion = follow_motions(path, stage)[0][0]
    assert motion.status == "stopped:kinetic_energy"
    time = motion.events["kinetic_energy"].time
    assert 0.5 < time < 0.6
    assert np.all(np.isfinite(motion.u[motion.time <= time]))
    assert np.all(np.isnan(motion.u[motion.time > time]))
    assert np.all(np.isnan(motion.kinetic_energy[motion.time > time]))


# --- the seed's diamond: a secondary contact closing -----------------------------------------------------

GAMMA = 0.5
ALPHA0 = math.pi / 4


def diamond_forces(u):
    """McNamara's diamond, R = 2 grad W with W = (l - 1)^2 / 2 + gamma (alpha - alpha0)^2 / 2 (seed Eq. 19),
    l cos alpha = cos alpha0 - Delta_1, l sin alpha = sin alpha0 - Delta_2."""
    x, y = math.cos(ALPHA0) - u[0], math.sin(ALPHA0) - u[1]
    length, alpha = math.hypot(x, y), math.atan2(y, x)
    grad_length = np.array([-x, -y]) / length
    grad_alpha = np.array([y, -x]) / length**2
    return 2 * ((length - 1) * grad_length + GAMMA * (alpha - ALPHA0) * grad_alpha)


def top_bottom_gap(u):
    return 2 * (math.cos(ALPHA0) - u[0]) - 1


def diamond_path(mode):
    """McNamara, gamma = 0.5: F2 = 0 held, Delta_1 driven to 0.19 (the top-bottom gap closes at
    cos(alpha0) - 1/2 = 0.2071)."""
    return follow(SystemSpec("diamond", secondary_contacts=mode), ["mcnamara"],
                  [{"hold": {"F2": 0.0}, "drive": {"D1": 0.19}}], {"gamma": GAMMA})


def test_a_closing_contact_is_located_where_an_independent_integration_finds_it():
    """Released with both forces held from (0.19 - 0.03, Delta_2 + 0.01): Delta_1 swings through
    0.2071 and the top-bottom gap closes at t = 1.98 (secondary contacts ignored: the motion is
    smooth).  The gap written by hand at the located state is 0 to 1e-10 (measured 0); the
    time agrees with solve_ivp on the equations written by hand, from the path's end state with
    F = R(u_end) held, to 1e-8 (measured 1.6e-12)."""
    path = diamond_path("ignore")
    result = path.results[0]
    start = np.array(result.steps["u"][0, result.n_steps[0] - 1])
    perturbation = np.array([-0.03, 0.01])
    stage = DynamicStage(10.0, dict(zip(("D1", "D2"), perturbation)), samples=101)
    motion = follow_motions(path, stage)[0][0]
    assert motion.status == "finished"
    event = motion.events["contact_closing"]
    assert event.gap == "top_bottom"
    assert abs(top_bottom_gap(event.u)) < 1e-10
    held = diamond_forces(start)

    def rhs(t, y):
        return [y[2], y[3], *(held - diamond_forces(y[:2]))]

    expected = first_event(rhs, [*(start + perturbation), 0.0, 0.0], 10.0, lambda y: top_bottom_gap(y[:2]), -1)
    assert event.time == pytest.approx(expected, abs=1e-8)
    assert 1.9 < event.time < 2.1
    # the kinetic energy there: w |u'|^2 / 2 with w = 1/2 and M = I
    assert event.kinetic_energy == pytest.approx(0.25 * float(event.velocity @ event.velocity), rel=1e-12)


def test_with_contacts_activated_the_closing_is_the_same_and_can_stop_the_motion():
    """With secondary_contacts = "activate" the gap's spring acts once it is closed: before, the
    motion is the same, so the closing is at the same time (to 1e-8; measured 1e-13); with
    stop_at = ["contact_closing"] the motion ends there."""
    stage = DynamicStage(10.0, {"D1": -0.03, "D2": 0.01}, samples=101)
    ignored = follow_motions(diamond_path("ignore"), stage)[0][0].events["contact_closing"]
    path = diamond_path("activate")
    motion = follow_motions(path, stage)[0][0]
    assert motion.events["contact_closing"].time == pytest.approx(ignored.time, abs=1e-8)
    stopped = follow_motions(path, DynamicStage(10.0, {"D1": -0.03, "D2": 0.01}, samples=101,
                                                stop_at=("contact_closing",)))[0][0]
    assert stopped.status == "stopped:contact_closing"
    assert "top_bottom" in stopped.message
    assert stopped.events["contact_closing"].time == pytest.approx(ignored.time, abs=1e-8)
    assert np.all(np.isnan(stopped.u[stopped.time > ignored.time]))


# --- through a study file: the Dataset, NaN where no event ---------------------------------------------------

DIAMOND = """\
[study]
name = "diamond_motion_events"
description = "motion events test"
[system]
name = "diamond"
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["mcnamara"]
[parameters]
gamma = 0.5
target = [0.19, 0.15]
[[loading]]
hold = {{ F2 = 0.0 }}
drive = {{ D1 = "target" }}
[[loading]]
dynamic = {{ duration = 10.0, perturbation = {{ D1 = -0.03, D2 = 0.01 }}, samples = 101, kinetic_energy_threshold = {threshold} }}
stop_at = {stop_at}
[output]
figures = []
"""


def diamond_study(threshold="1e-4", stop_at='["kinetic_energy"]'):
    return DIAMOND.format(threshold=threshold, stop_at=stop_at)


def test_a_study_stops_its_motions_at_the_threshold_and_stores_the_events(tmp_path):
    """Released 0.03 below D1 = 0.19 and 0.15: the kinetic energy reaches 1e-4 in both (its
    largest is 2.9e-4) and stops them there, before the first one's contact would close (its
    kinetic energy is 1.7e-4 at the closing): no closing located, NaN and an empty gap name.
    Every event variable has units, long_name and description, and the Dataset round-trips
    through netCDF."""
    import xarray as xr

    dataset = run_study(parse_study(diamond_study()))
    assert list(dataset["motion_status"].values.reshape(-1)) == ["stopped:kinetic_energy"] * 2
    time = dataset["motion_kinetic_energy_time"].values.reshape(-1)
    assert np.all((0.0 < time) & (time < 1.98))
    energy = dataset["motion_kinetic_energy_kinetic_energy"].values.reshape(-1)
    np.testing.assert_allclose(energy, 1e-4, rtol=1e-10)
    velocity = dataset["motion_kinetic_energy_velocity"].values.reshape(2, -1)
    np.testing.assert_allclose(0.25 * np.sum(velocity**2, axis=-1), 1e-4, rtol=1e-10)  # w = 1/2, M = I
    assert np.isnan(dataset["motion_contact_closing_time"].values).all()
    assert np.isnan(dataset["motion_contact_closing_u"].values).all()
    assert list(dataset["motion_contact_closing_gap"].values.reshape(-1)) == ["", ""]
    assert dataset["motion_kinetic_energy_u"].dims == ("law", "target", "dof")
    u_t = dataset["u_t"].values.reshape(2, -1, 2)
    later = dataset["time"].values > time[0]
    assert np.isnan(u_t[0, later]).all() and np.isfinite(u_t[0, ~later]).all()
    for name in ("motion_kinetic_energy_time", "motion_kinetic_energy_u", "motion_kinetic_energy_velocity",
                 "motion_kinetic_energy_kinetic_energy", "motion_contact_closing_time", "motion_contact_closing_u",
                 "motion_contact_closing_velocity", "motion_contact_closing_kinetic_energy", "motion_contact_closing_gap"):
        assert {"units", "long_name", "description"} <= set(dataset[name].attrs), name
    assert "0.0001" in dataset["motion_kinetic_energy_time"].attrs["description"]
    write_dataset(dataset, tmp_path / "events.nc")
    xr.testing.assert_identical(open_study(tmp_path / "events.nc"), dataset)


def test_events_a_motion_does_not_meet_are_nan():
    """A threshold of 1.0 (above the largest kinetic energy, 2.9e-4) and no stop_at: both motions
    finish, the threshold's variables are NaN; the contact closes in the first (Delta_1 reaches
    0.215 > cos(alpha0) - 1/2), at the time a motion followed directly finds (to 1e-8: the
    study's path reaches D1 = 0.19 by other steps), the gap written by hand 0 to 1e-10 there,
    and not in the second (Delta_1 stays below 0.176): NaN and an empty gap name."""
    dataset = run_study(parse_study(diamond_study(threshold="1.0", stop_at="[]")))
    assert list(dataset["motion_status"].values.reshape(-1)) == ["finished"] * 2
    for name in ("time", "u", "velocity", "kinetic_energy"):
        assert np.isnan(dataset[f"motion_kinetic_energy_{name}"].values).all(), name
    time = dataset["motion_contact_closing_time"].values.reshape(-1)
    direct = follow_motions(diamond_path("ignore"), DynamicStage(10.0, {"D1": -0.03, "D2": 0.01}, samples=101))[0][0]
    assert time[0] == pytest.approx(direct.events["contact_closing"].time, abs=1e-8)
    assert np.isnan(time[1])
    assert list(dataset["motion_contact_closing_gap"].values.reshape(-1)) == ["top_bottom", ""]
    u = dataset["motion_contact_closing_u"].values.reshape(2, -1)
    assert abs(top_bottom_gap(u[0])) < 1e-10
    assert np.isnan(u[1]).all()


def test_a_system_without_gaps_has_no_contact_variables():
    """Ziegler's pendulum has no secondary contacts: no motion_contact_closing_* variables, and
    without a threshold no motion_kinetic_energy_* either."""
    dataset = run_study(parse_study(ZIEGLER))
    assert not [name for name in dataset.data_vars if name.startswith(("motion_contact", "motion_kinetic"))]


# --- bad study files: exit 2 naming the field ------------------------------------------------------------

ZIEGLER = """\
[study]
name = "ziegler_motion_events"
[system]
name = "ziegler"
load = "dead"
[[loading]]
drive = { P = 0.2 }
[[loading]]
dynamic = { duration = 4.0, perturbation = { phi1 = 0.3 }, samples = 11 }
"""


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (diamond_study(threshold="-1e-3"), r"loading\[2\]\.dynamic\.kinetic_energy_threshold: expected a kinetic energy > 0"),
        (diamond_study(threshold="0.0"), r"loading\[2\]\.dynamic\.kinetic_energy_threshold: expected a kinetic energy > 0"),
        (diamond_study(threshold='"a lot"'), r"loading\[2\]\.dynamic\.kinetic_energy_threshold: "),
        (diamond_study(threshold="true"), r"loading\[2\]\.dynamic\.kinetic_energy_threshold: expected a number"),
        (diamond_study(stop_at="[]").replace("kinetic_energy_threshold = 1e-4", "kinetic_energy_treshold = 1e-4"),
         r"loading\[2\]\.dynamic\.kinetic_energy_treshold: unknown key"),
        (diamond_study(stop_at='["limit_point"]'), r"loading\[2\]\.stop_at: unknown event 'limit_point'; a dynamic stage stops at: contact_closing, kinetic_energy"),
        (diamond_study(stop_at="3"), r"loading\[2\]\.stop_at: expected a list of event names"),
        (ZIEGLER + 'stop_at = ["contact_closing"]\n', r"loading\[2\]\.stop_at: system 'ziegler' has no secondary contacts"),
        (ZIEGLER + 'stop_at = ["kinetic_energy"]\n', r"loading\[2\]\.stop_at: kinetic_energy needs the threshold"),
    ],
    ids=["negative", "zero", "not-a-number", "boolean", "misspelt-key", "path-event", "not-a-list", "no-gaps", "no-threshold"],
)
def test_bad_motion_events_exit_2_naming_the_field(tmp_path, capfd, text, needle):
    study = tmp_path / "study.toml"
    study.write_text(text)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2, err
    assert_one_line(err, needle)
    assert not (tmp_path / "out.nc").exists()
