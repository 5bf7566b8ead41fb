"""The Dataset's indicators: the stage loop's per-state functions over the stored states.

``ncstab.operators.one_state`` holds the indicators of one state (det K, the
least eigenvalue of K_sym, the normalised second-order work, the discriminant of
K, det K_SS of the stage's mixed control); the compiled stage loop calls them for
its events and the Dataset runs them over every stored state
(``ncstab.operators.stored_states.stored_state_indicators``).  Checked here:

* for two dofs (the diamond under two stages and two laws, paths of different
  lengths, NaN padding; Ziegler's pendulum with masses swept, whose ``flutter``
  variable comes from M(u), C and K, as the diamond's with M = I and C = 0): bit
  for bit what numpy's vectorized operators (``ncstab.operators.indicators``,
  ``ncstab.paths.dataset_dynamics``) give on the whole sweep at once;
* the same functions run as plain Python and as machine code: bit for bit;
* beyond two dofs, against LAPACK through numpy on random matrices, to 1e-12
  relative (LU and symmetric eigenvalues in another order of operations: a few
  roundings of the matrix's scale);
* the mixed control follows each state's own stage.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from ncstab.operators import one_state, stored_states
from ncstab.operators.indicators import (
    det_K, flutter_discriminant, hill_eigenvalue, mixed_control_determinant, skew_part, symmetric_part,
)
from ncstab.paths import SystemSpec, follow
from ncstab.paths.dataset_dynamics import case_parameters, state_dynamics
from ncstab.paths.dataset_indicators import state_indicators

DIAMOND = (
    SystemSpec(secondary_contacts="ignore"),
    ["cundall_strack", "mcnamara"],
    [{"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}},
     {"hold": {"F2": "current"}, "drive": {"D1": 0.6}, "stop_at": ["limit_point"]}],
    {"gamma": np.linspace(0.1, 2.0, 3), "alpha0": np.pi / 4, "F2_lateral": np.linspace(0.0, 0.6, 3)},
)
ZIEGLER = (SystemSpec("ziegler", load="follower"), None, [{"drive": {"P": 3.0}}], {"m1": [0.5, 1.0, 2.0], "b1": [0.0, 0.1]})


def _stored(path, key: str) -> np.ndarray:
    """A stored field, ``(law, *sweep, step, ...)``, padded to the longest path."""
    length = max(int(r.n_steps.max()) for r in path.results)
    arrays = []
    for r in path.results:
        a = r.steps[key]
        pad = np.full((a.shape[0], length - a.shape[1]) + a.shape[2:], -1 if a.dtype.kind == "i" else np.nan,
                      dtype=a.dtype)
        arrays.append(np.concatenate([a, pad], axis=1))
    array = np.stack(arrays)
    return array.reshape(path.shape + array.shape[2:])


def _normalised_work(K: np.ndarray, du: np.ndarray) -> np.ndarray:
    """du . K du / (|K du| |du|) by numpy: einsum and norms."""
    dF = np.einsum("...ij,...j->...i", K, du)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.einsum("...i,...i->...", dF, du) / (np.linalg.norm(dF, axis=-1) * np.linalg.norm(du, axis=-1))


def _on_route(monkeypatch, route: str) -> None:
    """Have the kernel run as plain Python or as machine code, whatever numba's cache holds."""
    from ncstab.paths import loop_route

    plain = route == "plain"
    monkeypatch.setattr(loop_route, "machine_code_cached", lambda *args: not plain)
    monkeypatch.setattr(loop_route, "PYTHON_ROWS", 1 << 30 if plain else -1)


@pytest.fixture(scope="module", params=["diamond", "ziegler"])
def path(request):
    return follow(*(DIAMOND if request.param == "diamond" else ZIEGLER))


@pytest.mark.parametrize("route", ["plain", "machine code"])
def test_two_dofs_give_numpy_s_operators_on_the_whole_sweep_bit_for_bit(path, route, monkeypatch):
    _on_route(monkeypatch, route)
    K, u, du, stage = (_stored(path, key) for key in ("K", "u", "du", "stage"))
    length = stage.shape[-1]
    assert len({int(n) for r in path.results for n in r.n_steps}) > 1 or path.shape[0] == 1  # padded paths
    got = state_indicators(path, K, u, du, stage)
    whole = {
        "K_sym": symmetric_part(K), "K_skew": skew_part(K), "det_K": det_K(K), "hill": hill_eigenvalue(K),
        "d2W": _normalised_work(K, du),
        "flutter": (flutter_discriminant(K) if path.model.definition.mass is None
                    else state_dynamics(path, u, K, case_parameters(path, (length,)))),  # (numpy's M, C and K)
        "mixed_control": path.mixed_control(K, stage),
    }
    assert set(got) == set(whole)
    for name, expected in whole.items():
        assert got[name].shape == expected.shape, name
        np.testing.assert_array_equal(got[name], expected, err_msg=name)
        if name == "d2W" and not np.any(np.nan_to_num(du)):
            continue  # the pendulum's straight path: du = 0, d2W is 0/0 at every state
        assert np.isfinite(got[name]).any(), name  # the comparison is not between NaN arrays only


def test_the_recorder_s_views_are_read_where_they_are(path):
    """A view with room between the cases (the recorder's padded rows) gives what its
    contiguous copy gives, read only or not, and the kernel leaves both untouched."""
    K, du, stage = (_stored(path, key) for key in ("K", "du", "stage"))
    cases, length, n = int(np.prod(stage.shape[:-1])), stage.shape[-1], K.shape[-1]
    roomy = np.full((cases, length + 3, n, n), 7.0)
    roomy[:, :length] = K.reshape(cases, length, n, n)
    view = roomy[:, :length]
    assert not view.flags.c_contiguous
    controlled = np.array([[True] * n, [False, True] + [False] * (n - 2)])
    args = (du.reshape(cases, length, n), np.maximum(stage.reshape(cases, length), -1) % 2, controlled)
    from_view = stored_states.stored_state_indicators(view, *args)
    from_copy = stored_states.stored_state_indicators(np.ascontiguousarray(view), *args)
    for a, b in zip(from_view, from_copy):
        np.testing.assert_array_equal(a, b)
    assert (roomy[:, length:] == 7.0).all()
    roomy.setflags(write=False)  # an archive's arrays: read only, the same machine code
    frozen = roomy[:, :length]
    assert not frozen.flags.writeable
    for a, b in zip(stored_states.stored_state_indicators(frozen, *args, plain=False), from_copy):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("n", [1, 3, 5])
def test_beyond_two_dofs_the_kernel_agrees_with_lapack(n, monkeypatch):
    """Random K (some states not finite, some padding): det K and det K_SS by LU, the least
    eigenvalue of K_sym, the discriminant and d2W against numpy's LAPACK, to 1e-12 of the
    matrix's scale (det: of its n-th power); machine code and plain Python bit for bit."""
    rng = np.random.default_rng(n)
    K = rng.normal(size=(6, 5, n, n))
    du = rng.normal(size=(6, 5, n))
    stage = rng.integers(0, 2, size=(6, 5))
    stage[0, 3:] = -1
    K[1, 2, 0, 0] = np.nan
    controlled = np.zeros((2, n), dtype=bool)
    controlled[0] = True
    controlled[1, ::2] = True
    _on_route(monkeypatch, "machine code")
    symmetric, skew, values = stored_states.stored_state_indicators(K, du, stage, controlled)
    _on_route(monkeypatch, "plain")
    plain = stored_states.stored_state_indicators(K, du, stage, controlled)
    np.testing.assert_array_equal(plain[2], values)
    got = dict(zip(one_state.INDICATOR_NAMES, values))
    np.testing.assert_array_equal(symmetric, symmetric_part(K))
    np.testing.assert_array_equal(skew, skew_part(K))
    mixed = np.full(stage.shape, np.nan)
    for k in range(2):
        mixed[stage == k] = mixed_control_determinant(K[stage == k], controlled[k])
    scale = np.nanmax(np.abs(K))
    expected = {"det_K": (det_K(K), scale**n), "hill": (hill_eigenvalue(K), scale),
                "flutter": (flutter_discriminant(K), scale ** max(n * (n - 1), 1)),
                "d2W": (_normalised_work(K, du), 1.0), "mixed_control": (mixed, scale**n)}
    for name, (value, size) in expected.items():
        assert np.array_equal(np.isnan(got[name]), np.isnan(value)), name
        np.testing.assert_allclose(got[name], value, rtol=0, atol=1e-12 * size, equal_nan=True, err_msg=name)


def test_mixed_control_follows_each_state_s_stage():
    """The diamond's first stage controls both forces (det K_SS = det K) and the second
    holds F2 and drives D1 (det K_SS = K_22): each stored state gets its own stage's."""
    path = follow(*DIAMOND)
    K, u, du, stage = (_stored(path, key) for key in ("K", "u", "du", "stage"))
    got = state_indicators(path, K, u, du, stage)
    first, second = stage == 0, stage == 1
    assert first.any() and second.any()
    np.testing.assert_array_equal(got["mixed_control"][first], det_K(K)[first])
    np.testing.assert_array_equal(got["mixed_control"][second], K[..., 1, 1][second])
    assert np.isnan(got["mixed_control"][stage < 0]).all()


@pytest.mark.parametrize("threads", [1, 2])
def test_the_dataset_is_the_same_whatever_the_blocks_and_threads(path, threads, monkeypatch):
    """The whole Dataset (indicators included) with blocks of one case, on one or two
    threads, and with the default blocks on one thread."""
    from ncstab.paths import dataset_indicators
    from ncstab.paths.threads import thread_limit, using_threads

    if threads > thread_limit():
        pytest.skip("numba runs one thread here (NUMBA_NUM_THREADS or one core)")
    with using_threads(1):
        default = path.to_dataset()
    monkeypatch.setattr(dataset_indicators, "BLOCK_STATES", 1)  # at least one case per block
    with using_threads(threads):
        small = path.to_dataset()
    for dataset in (default, small):
        dataset.attrs.pop("created", None)
    xr.testing.assert_identical(default, small)


def test_the_growth_rate_of_two_dofs_is_the_same_plain_and_compiled(monkeypatch):
    """max Re s of M s^2 + K from P = M^-1 K (tests/test_dynamics.py checks it against the
    companion matrix's eigenvalues in every regime): the same bits as plain Python and as
    machine code, NaN where P is not finite."""
    rng = np.random.default_rng(7)
    product = rng.normal(size=(200, 2, 2)) * rng.choice([1e-3, 1.0, 1e3], size=(200, 1, 1))
    product[3, 0, 1], product[4, 1, 1] = np.nan, np.inf
    _on_route(monkeypatch, "machine code")
    compiled = stored_states.undamped_growths(product)
    _on_route(monkeypatch, "plain")
    plain = stored_states.undamped_growths(product)
    np.testing.assert_array_equal(plain, compiled)
    assert np.isnan(compiled[[3, 4]]).all() and np.isfinite(np.delete(compiled, [3, 4])).all()
    assert (compiled[np.isfinite(compiled)] >= 0).all()


def test_two_dofs_from_the_entries_are_the_general_function_s_numbers():
    """The pass takes two dofs from K's entries (``state_values_2``, no views): the numbers of
    the general ``state_values`` for every control (none, either force, both), bit for bit."""
    from ncstab.plain_python import plain_import

    functions = plain_import("ncstab.operators.one_state")
    rng = np.random.default_rng(11)
    for _ in range(50):
        K, du = rng.normal(size=(2, 2)), rng.normal(size=2)
        for controlled in ([False, False], [True, False], [False, True], [True, True]):
            general = functions.state_values(K, du, np.array(controlled))
            entries = functions.state_values_2(K[0, 0], K[0, 1], K[1, 0], K[1, 1], du[0], du[1], *controlled, True)
            np.testing.assert_array_equal(np.array(general, dtype=float), np.array(entries, dtype=float))
    no_stage = functions.state_values(K, du, np.zeros(0, dtype=bool))
    assert np.isnan(no_stage[4]) and np.isnan(functions.state_values_2(*K.ravel(), *du, False, False, False)[4])
