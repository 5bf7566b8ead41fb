"""Hencky's column with a geometric imperfection (issue 41): springs stress-free in the shape
w0_i = imperfection sin(pi i / n), released from the straight clamp, then loaded.

Checked against an independent solution of the equilibrium (scipy's ``root`` on the gradient
of the column's energy written here in numpy, to a gradient of 1e-14), on both routes: derived whole (4
links) and assembled from elements (12 links), and against the linear theory w = w0 / (1 -
P/P1) for a small imperfection.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import root

from ncstab.cli import main
from ncstab.paths.api import follow
from ncstab.paths.options import SystemSpec
from ncstab.studies import open_study
from ncstab.systems.bars import imperfect_rises


def energy_equilibrium(links: int, eps: float, P: float) -> np.ndarray:
    """w at equilibrium: the gradient of E(w) = 1/2 sum_j (theta_{j+1} - theta_j - q0_j)^2
    - P sum_i (1 - cos theta_i), theta_i = asin(w_i - w_{i-1}), q0 the imperfect shape's."""
    n = links
    i = np.arange(1, n + 1)
    r0 = eps * (np.sin(np.pi * i / n) - np.sin(np.pi * (i - 1) / n))
    q0 = np.diff(np.arcsin(r0))
    D = np.diff(np.eye(n), axis=0)  # springs x bars
    B = np.eye(n, n - 1) - np.eye(n, n - 1, -1)  # bars x dofs: rise_i = w_i - w_{i-1}

    def gradient(w: np.ndarray) -> np.ndarray:
        r = B @ w
        theta = np.arcsin(r)
        A = B / np.sqrt(1 - r * r)[:, None]
        return A.T @ (D.T @ (D @ theta - q0)) - P * A.T @ np.sin(theta)

    P1 = 4 * np.sin(np.pi / (2 * n)) ** 2
    w0 = eps * np.sin(np.pi * np.arange(1, n) / n)
    solution = root(gradient, w0 / (1 - P / P1), tol=1e-15)
    assert np.abs(gradient(solution.x)).max() < 1e-14  # (success may say 1e-15 was not reached)
    return solution.x


def released_then_loaded(links: int, fraction: float) -> list[dict]:
    forces = {f"F{i}": 0.0 for i in range(1, links)}
    P1 = 4 * np.sin(np.pi / (2 * links)) ** 2
    return [{"hold": {"P": 0.0}, "drive": forces}, {"hold": dict(forces), "drive": {"P": fraction * P1}}]


def end_state(links: int, eps: float, fraction: float):
    ds = follow(SystemSpec("column", links=links), None, released_then_loaded(links, fraction),
                {"imperfection": eps}).to_dataset().isel(law=0)
    assert str(ds.status.values) == "finished"
    end = ds.isel(step=int(ds.n_steps) - 1)
    return end.u.values, float(end["load"]), ds


def test_unit_rises_are_the_first_modes_differences():
    for n in (2, 3, 4, 5, 12):
        shape = np.sin(np.pi * np.arange(n + 1) / n)
        np.testing.assert_allclose(imperfect_rises(n), np.diff(shape), atol=1e-15)
        assert abs(imperfect_rises(n).sum()) < 1e-15  # the ends are pinned: the rises close


@pytest.mark.parametrize("links", [5, 12])  # derived whole (4 dofs) and assembled (11 dofs)
def test_nonlinear_imperfect_column_against_its_energy(links):
    """eps = 0.05 loaded to 0.8 P1 (deflections 5 times the imperfection): the path's end equals
    the energy's stationary point to 1e-9 of max |w| (Newton's tolerance; measured 2.6e-11
    derived, 4.6e-15 assembled)."""
    w, P, _ = end_state(links, 0.05, 0.8)
    reference = energy_equilibrium(links, 0.05, P)
    assert np.abs(w - reference).max() < 1e-9 * np.abs(reference).max()


@pytest.mark.parametrize("links", [5, 12])
def test_a_small_imperfection_grows_as_one_over_one_minus_p_over_p1(links):
    """Linear theory: the first-mode imperfection is amplified by 1 / (1 - P/P1); with eps =
    1e-4 the nonlinear terms are O(eps^2) = 1e-8 relative (tolerance 1e-6)."""
    eps = 1e-4
    w, P, _ = end_state(links, eps, 0.5)
    P1 = 4 * np.sin(np.pi / (2 * links)) ** 2
    w0 = eps * np.sin(np.pi * np.arange(1, links) / links)
    np.testing.assert_allclose(w / w0, 1 / (1 - P / P1), rtol=1e-6)


def test_at_rest_the_imperfect_column_is_held_straight_by_r00():
    """u = 0 at the start: the forces there are R(0, 0), the springs' moments of the
    imperfect shape (docs/models.md, "A system not at rest at u = 0"), not 0."""
    _, _, ds = end_state(5, 0.05, 0.5)
    assert np.abs(ds.F.isel(step=0).values).max() > 1e-3
    assert np.abs(ds.F.isel(step=int(ds.n_steps) - 1).values).max() < 1e-9  # released


def test_the_shipped_study_sweeps_the_imperfection(tmp_path):
    from pathlib import Path

    study = Path(__file__).resolve().parents[1] / "studies" / "column_imperfection.toml"
    output = tmp_path / "imperfect.nc"
    assert main(["run", str(study), "-o", str(output), "--quiet"]) == 0
    ds = open_study(output)
    assert list(ds.imperfection.values) == [0.0, 0.01, 0.05]
    assert "stress-free shape" in ds.imperfection.attrs["description"]
    end = ds.isel(law=0).n_steps.values - 1
    middle = [float(ds.u.isel(law=0, imperfection=k, step=int(end[k]), dof=2)) for k in range(3)]
    assert middle[0] == 0.0 and 0 < middle[1] < middle[2]  # the perfect column stays straight


def test_an_imperfection_out_of_range_is_refused_naming_it(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text('[study]\nname = "bad"\n[system]\nname = "column"\nlinks = 3\n[parameters]\n'
                    'imperfection = 0.7\n[[loading]]\ndrive = { P = 0.5 }\n')
    assert main(["run", str(path), "-o", str(tmp_path / "bad.nc"), "--quiet"]) == 2
    assert "imperfection" in capsys.readouterr().err
