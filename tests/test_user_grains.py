"""Grains given in a study file, ``[system] name = "grains"`` (:mod:`ncstab.systems.user_grains`).

The seed's diamond given grain by grain (each free along its own axis, no rotation) is the
shipped four-axes diamond: the same path to rounding.  With rotations, a grain resting on a
held one has exactly one mode of zero stiffness at zero force (rolling without sliding).  Bad
input is exit 2 naming the field and entry, before anything is written.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ncstab.cli import main
from ncstab.paths.api import follow
from ncstab.studies import load_study, open_study
from ncstab.systems.assembled_builders import assembled_diamond
from ncstab.systems.registry import SYSTEMS
from ncstab.systems.user_grains import freeze_contacts, freeze_grains

C = math.cos(math.pi / 4)
#: The seed's diamond at alpha0 = pi/4 (units 2R = the mean diameter): top, bottom, left, right,
#: each free along its own axis.
DIAMOND = [
    {"x": 0.0, "y": C, "radius": 0.5, "held": ["x"]},
    {"x": 0.0, "y": -C, "radius": 0.5, "held": ["x"]},
    {"x": -C, "y": 0.0, "radius": 0.5, "held": ["y"]},
    {"x": C, "y": 0.0, "radius": 0.5, "held": ["y"]},
]
CONTACTS = [[0, 2], [0, 3], [1, 2], [1, 3]]
#: The programme of tests/test_assembled_runs.py on the four axes, and the same in the grains'
#: own dofs: D_top = -y0, D_bottom = y1, D_left = x2, D_right = -x3 (each toward the centre),
#: and the forces alike (F_top = -Fy0, ...).
AXES_PROGRAMME = [
    {"hold": {"F_top": 0.0, "F_bottom": 0.0}, "drive": {"F_left": 0.75, "F_right": 0.75}},
    {"hold": {"F_left": "current", "F_right": "current"}, "drive": {"D_top": 0.6, "D_bottom": 0.6}},
]
GRAINS_PROGRAMME = [
    {"hold": {"Fy0": 0.0, "Fy1": 0.0}, "drive": {"Fx2": 0.75, "Fx3": -0.75}},
    {"hold": {"Fx2": "current", "Fx3": "current"}, "drive": {"y0": -0.6, "y1": 0.6}},
]
SIGNS = np.array([-1.0, 1.0, 1.0, -1.0])  # grains' dofs (y0, y1, x2, x3) -> the axes' (D_top, ...)


def _grains_system(grain=DIAMOND, contacts=CONTACTS, rotations=False):
    return SYSTEMS["grains"].build(freeze_grains(grain), freeze_contacts(contacts), rotations)


@pytest.mark.parametrize("law", ["cundall_strack", "weakly_hypoelastic", "mcnamara", "turco"])
def test_the_diamond_given_grain_by_grain_is_the_four_axes_diamond(law):
    """Two routes to the same path: the shipped diamond's branches (c, s) in each top/bottom
    grain's frame, and the grains' contacts between disks in the global frame with alpha0 the
    branch angle.  The same equations, so the same states to rounding: 1e-10 (measured 3e-16),
    with the same events at the same loads."""
    grains = follow(_grains_system(), [law], GRAINS_PROGRAMME, {"gamma": 0.5}).results[0].outcomes[0]
    axes = follow(assembled_diamond("axes"), [law], AXES_PROGRAMME, {"gamma": 0.5},
                  secondary_contacts="ignore").results[0].outcomes[0]
    assert grains.status == axes.status
    assert len(grains.points) == len(axes.points)
    for a, b in zip(grains.points, axes.points):
        np.testing.assert_allclose(SIGNS * a.u, b.u, atol=1e-10, rtol=0)
        np.testing.assert_allclose(SIGNS * a.state.R, b.state.R, atol=1e-10, rtol=0)
    assert set(grains.events) == set(axes.events) - {"secondary_contact"}
    for name in grains.events:
        np.testing.assert_allclose(SIGNS * grains.events[name]["point"].u, axes.events[name]["point"].u,
                                   atol=1e-9, rtol=0)


def test_a_grain_rolling_on_a_held_one_has_one_mode_of_zero_stiffness():
    """Grain 1 on top of held grain 0, free in x, y and theta, McNamara at zero force: the normal
    stiffness along the branch is 1 and rolling (moving across the branch by dt while turning by
    -2 dt, units d = 1, r = 1/2: the contact point does not slide) costs nothing, while sliding
    costs gamma.  So K has exactly one zero eigenvalue, whose mode turns by -2 per unit of x, and
    the eigenvalue 1 along the branch (y): exact properties, checked to 1e-12 (rounding of K's
    entries of order 1)."""
    grain = [{"x": 0.0, "y": 0.0, "radius": 0.5, "held": ["x", "y", "theta"]},
             {"x": 0.0, "y": 1.0, "radius": 0.5}]
    system = _grains_system(grain, [[0, 1]], rotations=True)
    assert system.dofs == ("x1", "y1", "theta1") and system.forces == ("Fx1", "Fy1", "M1")
    from ncstab.operators.assembly import assemble
    from ncstab.laws.registry import law_definition

    case = system.for_values({"gamma": 0.5}, law_definition("mcnamara"))
    state = assemble(case, law_definition("mcnamara"), {"gamma": 0.5}, np.zeros(3),
                     {"contacts": np.zeros((1, 2))}, dense=True)
    K = np.asarray(state.K)
    eigenvalues, vectors = np.linalg.eigh(0.5 * (K + K.T))
    assert np.sum(np.abs(eigenvalues) < 1e-12) == 1
    rolling = vectors[:, np.argmin(np.abs(eigenvalues))]
    # x1 moves by dt and theta1 by -2 dt (units d = 1, r = 0.5): the contact point does not slide
    np.testing.assert_allclose(rolling[2] / rolling[0], -2.0, rtol=1e-12)
    normal = vectors[:, np.argmin(np.abs(eigenvalues - 1.0))]
    np.testing.assert_allclose(abs(normal[1]), 1.0, rtol=1e-12)


def _study(tmp_path: Path, grain_lines: str, contacts: str, loading: str = "drive = { y0 = -0.05 }") -> Path:
    path = tmp_path / "grains.toml"
    path.write_text(f"""
[study]
name = "grains"
[system]
name = "grains"
grain = [
{grain_lines}
]
contacts = {contacts}
rotations = false
[laws]
names = ["mcnamara"]
[parameters]
gamma = 0.5
[[loading]]
{loading}
""")
    return path


DIAMOND_LINES = """
  { x = 0.0, y = 0.7071067811865476, radius = 0.5, held = ["x"] },
  { x = 0.0, y = -0.7071067811865476, radius = 0.5, held = ["x", "y"] },
  { x = -0.7071067811865476, y = 0.0, radius = 0.5, held = ["y"] },
  { x = 0.7071067811865476, y = 0.0, radius = 0.5, held = ["y"] },
"""


def test_a_study_of_grains_runs_and_archives_its_dofs(tmp_path):
    out = tmp_path / "grains.nc"
    assert main(["run", str(_study(tmp_path, DIAMOND_LINES, str(CONTACTS))), "-o", str(out), "--quiet"]) == 0
    data = open_study(out)
    assert list(data.dof.values) == ["y0", "x2", "x3"]
    assert str(data.status.values.ravel()[0]) == "finished"
    assert float(data.u.isel(step=int(data.n_steps.values.ravel()[0]) - 1).sel(dof="y0").values.ravel()[0]) \
        == pytest.approx(-0.05, abs=1e-12)
    assert load_study(_study(tmp_path, DIAMOND_LINES, str(CONTACTS))).system.name == "grains"


@pytest.mark.parametrize(
    "grain_lines, contacts, loading, field",
    [
        (DIAMOND_LINES, "[[0, 2], [0, 3], [1, 2], [1, 4]]", "drive = { y0 = -0.05 }", "system.contacts[3]"),
        (DIAMOND_LINES, "[[0, 2], [0, 3], [1, 2], [1, 1]]", "drive = { y0 = -0.05 }", "system.contacts[3]"),
        (DIAMOND_LINES.replace("radius = 0.5, held = [\"y\"] },\n  { x = 0.7", "radius = -0.5, held = [\"y\"] },\n  { x = 0.7"),
         str(CONTACTS), "drive = { y0 = -0.05 }", "system.grain[2].radius"),
        (DIAMOND_LINES.replace("y = -0.7071067811865476", "y = -0.6"), str(CONTACTS), "drive = { y0 = -0.05 }",
         "system.contacts[2]"),
        (DIAMOND_LINES + '  { x = 0.3, y = 0.0, radius = 0.5, held = ["y"] },', str(CONTACTS),
         "drive = { y0 = -0.05 }", "system.grain"),
        (DIAMOND_LINES, str(CONTACTS), "drive = { y1 = 0.05 }", "loading[1].drive.y1"),
        (DIAMOND_LINES, str(CONTACTS), "hold = { M2 = 0.0 }\ndrive = { y0 = -0.05 }", "loading[1].hold.M2"),
        (DIAMOND_LINES.replace('held = ["x"]', 'held = ["z"]', 1), str(CONTACTS), "drive = { y0 = -0.05 }",
         "system.grain[0].held"),
    ],
    ids=["missing-grain", "self-contact", "negative-radius", "not-touching", "overlap", "held-and-driven",
         "held-rotation-moment", "unknown-held-dof"],
)
def test_bad_grains_exit_2_naming_the_field_before_anything_is_written(tmp_path, capsys, grain_lines, contacts,
                                                                        loading, field):
    out = tmp_path / "bad.nc"
    assert main(["run", str(_study(tmp_path, grain_lines, contacts, loading)), "-o", str(out)]) == 2
    assert f": {field}:" in capsys.readouterr().err
    assert not out.exists()
