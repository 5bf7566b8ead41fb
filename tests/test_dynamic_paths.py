"""Dynamic stability along paths: Ziegler's pendulum, flutter, divergence, the paradox.

The numeric layer (the spectrum and its smooth indicators) is tested in
tests/test_dynamics.py; here the engine locates the events on load-parameter
stages of Ziegler's pendulum, against closed forms derived by hand.
"""

from __future__ import annotations

import numpy as np
import pytest

from ncstab.paths import SystemSpec, follow

FLUTTER_LOAD = 3.5 - np.sqrt(2)  # undamped follower load, masses 2m and m
DIVERGENCE_LOAD = (3 - np.sqrt(5)) / 2  # dead load


def _events(load: str, P: float, **parameters) -> dict:
    ds = follow(SystemSpec("ziegler", load=load), None, [{"drive": {"P": P}}], parameters).to_dataset()
    assert str(ds["status"].item()) == "finished"
    return ds


def test_the_undamped_follower_load_flutters_at_ziegler_s_load_and_never_diverges():
    """flutter_onset at (7/2 - sqrt 2) k/l to 1e-10 (event_tol), frequency 2^(-1/4)
    (the coalescing pair mu = -omega^2 of det(M mu + K), (7 - 2P)^2 = 8 at onset);
    det K = 1: no divergence, no limit point; Hill's condition lost first, at P = 2."""
    ds = _events("follower", 3.0)
    assert abs(float(ds["flutter_onset_load"].item()) - FLUTTER_LOAD) <= 1e-10
    assert abs(float(ds["flutter_onset_frequency"].item()) - 2 ** -0.25) <= 1e-8
    for event in ("divergence", "limit_point", "bifurcation"):
        assert np.isnan(float(ds[f"{event}_load"].item()))
    assert float(ds["hill_loss_load"].item()) < float(ds["flutter_onset_load"].item())
    n = int(ds["n_steps"].item())
    P, growth = ds["load"].values[0, :n], ds["flutter"].values[0, :n]
    assert np.all(np.abs(growth[P < FLUTTER_LOAD - 1e-6]) < 1e-12)  # undamped, stable: Re s = 0
    assert np.all(growth[P > FLUTTER_LOAD + 1e-6] > 0)


def test_the_dead_load_diverges_and_never_flutters():
    ds = _events("dead", 1.0)
    assert abs(float(ds["divergence_load"].item()) - DIVERGENCE_LOAD) <= 1e-10
    assert np.isnan(float(ds["flutter_onset_load"].item()))


def _routh_hurwitz_critical_load(b: float) -> float:
    """By hand: with M = [[3, 1], [1, 1]], C = b [[2, -1], [-1, 1]] and
    K = [[2 - P, P - 1], [-1, 1]], det(M s^2 + C s + K) = a0 s^4 + a1 s^3 + a2 s^2 + a3 s + a4,
    a0 = 2, a1 = 7b, a2 = 7 + b^2 - 2P, a3 = 2b, a4 = 1.  Flutter sets in where the
    Hurwitz determinant a1 a2 a3 - a0 a3^2 - a4 a1^2 vanishes:
    14 b^2 (7 + b^2 - 2P) - 8 b^2 - 49 b^2 = 0, so P = 41/28 + b^2/2."""
    a0, a1, a3, a4 = 2.0, 7 * b, 2 * b, 1.0
    # a1 (7 + b^2 - 2P) a3 = a0 a3^2 + a4 a1^2, solved for P
    return (7 + b * b - (a0 * a3 * a3 + a4 * a1 * a1) / (a1 * a3)) / 2


@pytest.mark.parametrize("b", [1.0, 0.1, 0.01, 0.001])
def test_equal_dashpots_flutter_at_the_routh_hurwitz_load(b):
    """The located flutter_onset_load against the hand Routh-Hurwitz load (1e-9)."""
    ds = _events("follower", 3.0, b1=b, b2=b)
    assert abs(float(ds["flutter_onset_load"].item()) - _routh_hurwitz_critical_load(b)) <= 1e-9


def test_the_destabilization_paradox_vanishing_damping_lowers_the_critical_load_to_41_over_28():
    """Ziegler's paradox: at b = 1e-5 the damped critical load is 41/28 (to 1e-4), far
    below the undamped 7/2 - sqrt 2 = 2.086."""
    ds = _events("follower", 2.5, b1=1e-5, b2=1e-5)
    assert abs(float(ds["flutter_onset_load"].item()) - 41 / 28) <= 1e-4
    assert FLUTTER_LOAD - float(ds["flutter_onset_load"].item()) > 0.6


def test_hill_s_condition_is_lost_at_p_2_whatever_the_masses():
    """K_sym of the follower load does not involve M: Hill's loss at P = 2 (1e-10)
    for any masses; the flutter load depends on them."""
    ds = follow(
        SystemSpec("ziegler", load="follower"), None, [{"drive": {"P": 3.0}}], {"m1": [0.5, 1.0, 2.0, 4.0]}
    ).to_dataset()
    np.testing.assert_allclose(ds["hill_loss_load"].values, 2.0, rtol=0, atol=1e-10)
    assert np.ptp(ds["flutter_onset_load"].values) > 0.1


def test_hill_s_loss_is_found_where_a_stored_state_lands_on_it():
    """Steps of 0.01 in P from 0 land on P = 2 (s = P on the straight trivial path),
    where the smallest eigenvalue of K_sym is 0 within rounding (-1.3e-15): the signs
    along the path are +, 0, -.  The event is found there all the same, to event_tol
    (1e-10; the path is s = P), with the stored sampling or without."""
    from ncstab.paths import PathOptions

    for sample_step in (None, 0.02):
        options = PathOptions(max_step=0.01, sample_step=sample_step)
        ds = follow(SystemSpec("ziegler", load="follower"), None, [{"drive": {"P": 3.0}}], {}, options).to_dataset()
        landed = np.abs(ds["load"].values.ravel() - 2.0) < 1e-12
        assert landed.any() and np.abs(ds["hill"].values.ravel()[landed]).max() < 1e-13  # the premise
        assert abs(float(ds["hill_loss_load"].item()) - 2.0) <= 1e-10


def test_the_stored_spectrum_is_imaginary_below_ziegler_s_load_and_has_a_growing_pair_above():
    """to_dataset(spectrum=True): the 2n roots at every stored state of the undamped
    follower path.  They come in pairs +-s (sum 0), are imaginary below the flutter
    load 7/2 - sqrt 2 and have Re s > 0 above it; their largest real part is the
    ``flutter`` variable.  Tolerances: 1e-9 on the roots (eigenvalues of a 4 x 4
    companion with O(1) entries, a double pair near the onset loses half the digits),
    states within 1e-3 of the onset left out."""
    ds = follow(SystemSpec("ziegler", load="follower"), None, [{"drive": {"P": 3.0}}], {}).to_dataset(spectrum=True)
    n = int(ds["n_steps"].item())
    P = ds["load"].values[0, :n]
    roots = ds["spectrum_re"].values[0, :n] + 1j * ds["spectrum_im"].values[0, :n]
    assert roots.shape == (n, 4) and (P < FLUTTER_LOAD - 1e-3).any() and (P > FLUTTER_LOAD + 1e-3).any()
    np.testing.assert_allclose(roots.sum(axis=-1), 0.0, atol=1e-9)
    below, above = P < FLUTTER_LOAD - 1e-3, P > FLUTTER_LOAD + 1e-3
    assert np.abs(roots[below].real).max() < 1e-9
    assert (roots[above].real.max(axis=-1) > 1e-3).all()
    np.testing.assert_allclose(roots.real.max(axis=-1), ds["flutter"].values[0, :n], rtol=0, atol=1e-9)


def test_a_system_without_inertia_has_no_stored_spectrum():
    """Hencky's column declares no M: asking for its spectrum is an error that says so."""
    path = follow(SystemSpec("column", links=2), None, [{"drive": {"P": 0.5}}], {})
    assert path.model.definition.mass is None
    with pytest.raises(ValueError, match="'column' declares no inertia"):
        path.to_dataset(spectrum=True)
