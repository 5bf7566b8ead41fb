"""State maps of laws with a total form (issue 6): indicators over the displacement plane."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from ncstab import DiamondChain, make_law
from ncstab.operators import det_K, hill_eigenvalue, tangent_operator
from ncstab.operators.state_map import STATE_MAP_FIELDS, state_map
from ncstab.paths import SystemSpec, follow

ALPHA0 = np.pi / 4


@pytest.mark.parametrize("law_name", ["mcnamara", "turco", "weakly_hypoelastic"])
def test_state_map_at_path_states_equals_the_paths_own_indicators(law_name):
    """For a law with a total form K = K(u): the map evaluated at the stored states
    of a path gives the path's own hill and det K to 1e-10 (both are the same
    function of u; the difference is rounding of O(1) quantities)."""
    path = follow(SystemSpec(secondary_contacts="ignore"), law_name,
                  [{"hold": {"F1": 0.0}, "drive": {"F2": 0.5}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.4}}],
                  {"gamma": 0.5, "alpha0": ALPHA0})
    ds = path.to_dataset().isel(law=0)
    n = int(ds.n_steps)
    u = ds.u.values[:n]
    law = make_law(law_name, gamma=0.5, alpha0=ALPHA0)
    # Evaluate the map exactly at the path's states: one-point grids per state.
    at_states = [state_map(DiamondChain(alpha0=ALPHA0), law, [d1], [d2]) for d1, d2 in u]
    hill = np.array([m["map_hill"][0, 0] for m in at_states])
    det = np.array([m["map_det_K"][0, 0] for m in at_states])
    np.testing.assert_allclose(hill, ds.hill.values[:n], rtol=0, atol=1e-10)
    np.testing.assert_allclose(det, ds.det_K.values[:n], rtol=0, atol=1e-10)
    forces = np.array([[m["map_F1"][0, 0], m["map_F2"][0, 0]] for m in at_states])
    np.testing.assert_allclose(forces, ds.F.values[:n], rtol=0, atol=1e-10)


def test_state_map_grid_matches_pointwise_operators_and_broadcasts_over_cases():
    d1, d2 = np.linspace(-0.1, 0.3, 9), np.linspace(-0.2, 0.2, 7)
    gamma = np.array([0.5, 2.0])
    maps = state_map(DiamondChain(alpha0=ALPHA0), make_law("mcnamara", gamma=gamma, alpha0=ALPHA0), d1, d2)
    assert set(maps) == set(STATE_MAP_FIELDS)
    assert maps["map_hill"].shape == (2, 9, 7)
    for c, g in enumerate(gamma):
        law = make_law("mcnamara", gamma=g, alpha0=ALPHA0)
        for i in (0, 4, 8):
            for j in (0, 3, 6):
                K = tangent_operator(DiamondChain(alpha0=ALPHA0), law, np.array([d1[i], d2[j]]))
                assert maps["map_hill"][c, i, j] == pytest.approx(hill_eigenvalue(K), abs=1e-14)
                assert maps["map_det_K"][c, i, j] == pytest.approx(det_K(K), abs=1e-14)
                assert maps["map_mixed_control_F2"][c, i, j] == pytest.approx(K[1, 1], abs=1e-14)
    # Where Hill's condition holds there is no unstable cone, and conversely.
    hill, width = maps["map_hill"], maps["map_cone_width"]
    assert np.all(width[hill > 1e-12] == 0) and np.all(width[hill < -1e-12] > 0)


def test_limit_point_lies_on_the_zero_contour_of_det_k():
    """The located limit point of the seed's Fig. 10 case sits where the map's
    det K vanishes (interpolated on a fine grid: error O(h^2) ~ 1e-5)."""
    path = follow(SystemSpec(secondary_contacts="ignore"), "mcnamara",
                  [{"hold": {"F1": 0.0}, "drive": {"F2": 0.75}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}],
                  {"gamma": 0.5, "alpha0": ALPHA0})
    ds = path.to_dataset().isel(law=0)
    u_limit = ds.limit_point_u.values
    d1 = np.linspace(u_limit[0] - 0.02, u_limit[0] + 0.02, 201)
    d2 = np.linspace(u_limit[1] - 0.02, u_limit[1] + 0.02, 201)
    maps = state_map(DiamondChain(alpha0=ALPHA0), make_law("mcnamara", gamma=0.5, alpha0=ALPHA0), d1, d2)
    det = RegularGridInterpolator((d1, d2), maps["map_det_K"], method="cubic")(u_limit[None])[0]
    assert abs(det) < 1e-5


def test_state_map_refuses_a_rate_law():
    with pytest.raises(ValueError, match="no total form"):
        state_map(DiamondChain(), make_law("cundall_strack", gamma=1.0), [0.0], [0.0])
