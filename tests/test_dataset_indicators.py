"""The Dataset's indicators in blocks of cases (ncstab.paths.dataset_indicators).

Every indicator is a function of one stored state, so computing them in
blocks of cases on one or two threads must give, bit for bit, what the
operators give on the whole sweep at once: the test calls
:mod:`ncstab.operators` on the whole contiguous arrays and compares with
``assert_array_equal`` (NaN in the same places, every other value equal).
Blocks of one or two cases (``BLOCK_STATES`` shrunk) cut the sweep
everywhere; the systems: the diamond under two stages with two laws (the
mixed control changes with the stage, the paths have different lengths,
NaN padding after the shorter ones) and Ziegler's pendulum with masses
swept (the flutter variable from M(u), C and K with per-case parameters).
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from ncstab.operators.indicators import det_K, hill_eigenvalue, skew_part, symmetric_part
from ncstab.paths import SystemSpec, dataset_indicators, follow
from ncstab.paths.dataset_dynamics import case_parameters, flutter_variable
from ncstab.paths.dataset_indicators import normalised_work, state_indicators
from ncstab.paths.threads import thread_limit, using_threads

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


@pytest.fixture(scope="module", params=["diamond", "ziegler"])
def path(request):
    return follow(*(DIAMOND if request.param == "diamond" else ZIEGLER))


@pytest.mark.parametrize("threads", [1, 2])
def test_blocks_of_cases_give_the_operators_on_the_whole_sweep_bit_for_bit(path, threads, monkeypatch):
    if threads > thread_limit():
        pytest.skip("numba runs one thread here (NUMBA_NUM_THREADS or one core)")
    K, u, du, stage = (_stored(path, key) for key in ("K", "u", "du", "stage"))
    length = stage.shape[-1]
    assert len({int(n) for r in path.results for n in r.n_steps}) > 1 or path.shape[0] == 1  # padded paths
    monkeypatch.setattr(dataset_indicators, "BLOCK_STATES", length + 1)  # one case per block
    with using_threads(threads):
        K_out, u_out, got = state_indicators(path, K, u, du, stage)
    np.testing.assert_array_equal(K_out, K)
    np.testing.assert_array_equal(u_out, u)
    assert K_out.flags.c_contiguous and u_out.flags.c_contiguous
    whole = {
        "K_sym": symmetric_part(K), "K_skew": skew_part(K), "det_K": det_K(K), "hill": hill_eigenvalue(K),
        "d2W": normalised_work(K, du),
        "flutter": flutter_variable(path, u, K, case_parameters(path, (length,))),
        "mixed_control": path.mixed_control(K, stage),
    }
    assert set(got) == set(whole)
    for name, expected in whole.items():
        assert got[name].shape == expected.shape, name
        np.testing.assert_array_equal(got[name], expected, err_msg=name)
        if name == "d2W" and not np.any(np.nan_to_num(du)):
            continue  # the pendulum's straight path: du = 0, d2W is 0/0 at every state
        assert np.isfinite(got[name]).any(), name  # the comparison is not between NaN arrays only


def test_the_dataset_is_the_same_whatever_the_block_size(path, monkeypatch):
    """The whole Dataset (indicators included) with blocks of one case and with the default."""
    default = path.to_dataset()
    monkeypatch.setattr(dataset_indicators, "BLOCK_STATES", 1)  # at least one case per block
    small = path.to_dataset()
    for dataset in (default, small):
        dataset.attrs.pop("created", None)
    xr.testing.assert_identical(default, small)


def test_mixed_control_follows_each_state_s_stage():
    """The diamond's first stage controls both forces (det K_SS = det K) and the second
    holds F2 and drives D1 (det K_SS = K_22): the blocks give each stored state its
    own stage's determinant."""
    path = follow(*DIAMOND)
    K, u, du, stage = (_stored(path, key) for key in ("K", "u", "du", "stage"))
    _, _, got = state_indicators(path, K, u, du, stage)
    first, second = stage == 0, stage == 1
    assert first.any() and second.any()
    np.testing.assert_array_equal(got["mixed_control"][first], det_K(K)[first])
    np.testing.assert_array_equal(got["mixed_control"][second], K[..., 1, 1][second])
