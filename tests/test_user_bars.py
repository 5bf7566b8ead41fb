"""A chain of bars given by its joints in a study file, ``[system] name = "bars"``
(:mod:`ncstab.systems.user_bars`): Hencky's column again, closed forms, an independent
eigenproblem, and bad input named before anything runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import linalg

from ncstab.cli import main
from ncstab.paths.api import follow
from ncstab.studies import open_study
from ncstab.systems.assembled_builders import assembled_column
from ncstab.systems.user_bars import assembled_bars


def _buckling(system, target: float):
    outcome = follow(system, None, [{"drive": {"P": target}, "at_bifurcation": "switch"}]).results[0].outcomes[0]
    assert outcome.status == "finished"
    return outcome


def test_equal_bars_between_two_supports_are_hencky_s_column():
    """joints 0, 1, ..., n with the defaults is the shipped column of n links: the same path
    point by point (1e-12: the same element arrays up to the order of terms) and Hencky's
    P1 = 4 sin^2(pi / 2n) (1e-10, as the column's own tests)."""
    links = 12
    P1 = 4 * np.sin(np.pi / (2 * links)) ** 2
    bars = _buckling(assembled_bars(tuple(float(z) for z in range(links + 1))), 1.2 * P1)
    column = _buckling(assembled_column(links), 1.2 * P1)
    assert len(bars.points) == len(column.points)
    for a, b in zip(bars.points, column.points):
        np.testing.assert_allclose(a.u, b.u, atol=1e-12, rtol=0)
        assert a.load == pytest.approx(b.load, rel=1e-12)
    assert bars.events["bifurcation"]["point"].load == pytest.approx(P1, rel=1e-10)


@pytest.mark.parametrize("lengths, stiffness", [((1.0, 2.0), 1.0), ((0.5, 1.5), 3.0), ((2.0, 2.0), 0.25)])
def test_two_bars_buckle_at_the_closed_form(lengths, stiffness):
    """One joint between bars of lengths L1, L2 and a spring C: the energy
    C w^2 (1/L1 + 1/L2)^2 / 2 - P w^2 (1/L1 + 1/L2) / 2 gives P_cr = C (1/L1 + 1/L2), to 1e-10
    (the located load is refined by the pencil's Rayleigh quotient, exact here)."""
    joints = (0.0, lengths[0], lengths[0] + lengths[1])
    expected = stiffness * (1 / lengths[0] + 1 / lengths[1])
    outcome = _buckling(assembled_bars(joints, "ends", stiffness), 1.3 * expected)
    assert outcome.events["bifurcation"]["point"].load == pytest.approx(expected, rel=1e-10)


def _critical_loads(joints, supports, springs):
    """Small-angle pencil built by hand, independently of the element arrays: theta_i =
    (w_i - w_{i-1}) / L_i, springs C_j (theta_{j+1} - theta_j)^2 / 2, load P sum L_i theta_i^2 / 2
    over the joints that are not supported; the critical loads are the eigenvalues of (K_C, G)."""
    z = np.asarray(joints, float)
    n = len(z) - 1
    free = [j for j in range(n + 1) if j not in supports]
    dtheta = np.zeros((n + 1, len(free)))  # dtheta_i / dw, bars 1..n
    for i in range(1, n + 1):
        for k, j in enumerate(free):
            dtheta[i, k] = ((j == i) - (j == i - 1)) / (z[i] - z[i - 1])
    KC = sum(springs[j - 1] * np.outer(dtheta[j + 1] - dtheta[j], dtheta[j + 1] - dtheta[j]) for j in range(1, n))
    G = sum((z[i] - z[i - 1]) * np.outer(dtheta[i], dtheta[i]) for i in range(1, n + 1))
    return linalg.eigh(KC, G, eigvals_only=True)


def test_a_chain_on_three_supports_buckles_at_its_pencil_s_first_load():
    """Five bars of unequal lengths, supported at joints 0, 2 and 5, springs of unequal
    stiffness: the first critical load of the hand-built pencil, to 1e-10."""
    joints = (0.0, 1.0, 2.5, 3.0, 4.2, 5.0)
    supports = (0, 2, 5)
    springs = (1.0, 2.0, 0.5, 1.5)
    expected = _critical_loads(joints, supports, springs)[0]
    outcome = _buckling(assembled_bars(joints, supports, springs), 1.3 * expected)
    assert outcome.events["bifurcation"]["point"].load == pytest.approx(expected, rel=1e-10)
    assert assembled_bars(joints, supports, springs).dofs == ("w1", "w3", "w4")


def _study(tmp_path: Path, system: str, loading: str = "drive = { P = 2.0 }") -> Path:
    path = tmp_path / "bars.toml"
    path.write_text(f"""
[study]
name = "bars"
[system]
name = "bars"
{system}
[[loading]]
{loading}
at_bifurcation = "switch"
""")
    return path


def test_a_study_of_bars_runs_to_the_closed_form(tmp_path):
    out = tmp_path / "bars.nc"
    study = _study(tmp_path, "joints = [0.0, 1.0, 3.0]\nsprings = 2.0", "drive = { P = 4.0 }")
    assert main(["run", str(study), "-o", str(out), "--quiet"]) == 0
    data = open_study(out)
    assert list(data.dof.values) == ["w1"]
    assert float(data.bifurcation_load.values.ravel()[0]) == pytest.approx(2.0 * 1.5, rel=1e-10)


@pytest.mark.parametrize(
    "system, loading, field",
    [
        ("joints = [0.0, 2.0, 1.0]", "drive = { P = 2.0 }", "system.joints[2]"),
        ("joints = [0.0, 1.0, 2.0]\nsupports = [0, 4]", "drive = { P = 2.0 }", "system.supports[1]"),
        ("joints = [0.0, 1.0, 2.0, 3.0]\nsprings = [1.0]", "drive = { P = 2.0 }", "system.springs"),
        ("joints = [0.0, 1.0, 2.0]\nsprings = -1.0", "drive = { P = 2.0 }", "system.springs"),
        ("joints = [0.0, 1.0, 2.0]", "hold = { P = 0.5 }\ndrive = { w2 = 0.1 }", "loading[1].drive.w2"),
        ("joints = [0.0, 1.0, 2.0, 3.0]\nsupports = [0, 1, 3]", "hold = { P = 0.5 }\ndrive = { F1 = 0.1 }",
         "loading[1].drive.F1"),
    ],
    ids=["joints-not-rising", "missing-joint", "springs-count", "negative-spring", "support-driven",
         "support-force-driven"],
)
def test_bad_bars_exit_2_naming_the_field(tmp_path, capsys, system, loading, field):
    out = tmp_path / "bad.nc"
    assert main(["run", str(_study(tmp_path, system, loading)), "-o", str(out)]) == 2
    assert f": {field}:" in capsys.readouterr().err
    assert not out.exists()
