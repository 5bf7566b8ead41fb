"""The recorder's limit of stored states per case (ncstab.paths.recorder): a case whose path
needs more fails with ``failed:memory`` and a message, while the others finish as without it.

Stored states are dense, ``(cases, states)``: without a limit one long case makes every case
of the batch take its room, and a sweep could ask for more memory than the machine has (the
system then kills the process, nothing written).
"""

from __future__ import annotations

import numpy as np
import pytest

from ncstab.paths import PathOptions, follow
from ncstab.paths.options import SystemSpec
from ncstab.paths.recorder import MIN_STATE_LIMIT, STORED_SHARE, Recorder, state_limit

PROGRAMME = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.2}}]
#: Nine cases storing 18 to 44 states each with the default options.
GRID = {"gamma": [0.3, 1.0, 2.0], "alpha0": [0.5, 0.8, 1.1]}
SPEC = SystemSpec(secondary_contacts="ignore")
LIMIT = 28


def _follow():
    return follow(SPEC, "cundall_strack", PROGRAMME, GRID, PathOptions())


@pytest.fixture(scope="module")
def limited():
    """(the run without a limit, the run with LIMIT states per case)."""
    import ncstab.paths.stepper as stepper_module

    free = _follow()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(stepper_module, "state_limit", lambda size, bytes_per_state, available: LIMIT)
        capped = _follow()
    return free, capped


def test_the_cases_within_the_limit_finish_as_without_it_and_the_others_fail_with_memory(limited):
    """Each case whose next step could store more than LIMIT states fails with
    failed:memory; the cases that never come near it are the same to the bit; a failed
    case's stored states are the first ones of its unlimited path, at most LIMIT of them."""
    free, capped = limited
    free_count, count = free.results[0].n_steps.ravel(), capped.results[0].n_steps.ravel()
    status = capped.status.ravel()
    assert (free.status.ravel() == "finished").all()
    assert free_count.min() < LIMIT < free_count.max()  # the premise: some cases fit, some do not
    assert set(status) == {"finished", "failed:memory"}
    assert (status[free_count > LIMIT] == "failed:memory").all()
    assert (count <= LIMIT).all()
    kept, full = capped.to_dataset(), free.to_dataset()
    for name in ("s", "u", "F", "K", "hill"):
        a = kept[name].values.reshape(free_count.size, kept.sizes["step"], -1)
        b = full[name].values.reshape(free_count.size, full.sizes["step"], -1)
        for case in range(free_count.size):
            n = count[case]
            np.testing.assert_array_equal(a[case, :n], b[case, :n])  # a prefix, bit for bit
            if status[case] == "finished":
                assert n == free_count[case]


def test_the_failure_says_which_stage_the_limit_and_what_to_change(limited):
    _, capped = limited
    messages = set(capped.message.ravel()[capped.status.ravel() == "failed:memory"])
    assert len(messages) == 1
    message = messages.pop()
    assert message.startswith(f"stage 1: the path needs more than {LIMIT} stored states")
    assert "9 cases" in message and "raise sample_step" in message and "--chunk-cases" in message


def test_state_limit_is_a_share_of_the_memory_for_every_case():
    assert state_limit(1000, 160, 64_000_000_000) == int(STORED_SHARE * 64e9) // (1000 * 160)
    assert state_limit(10**6, 160, 1_000_000) == MIN_STATE_LIMIT
    assert state_limit(1000, 160, None) is None


def test_the_recorder_grows_up_to_its_limit_and_beyond_only_where_asked():
    """Doubling stops at the limit; an explicit need beyond it (a stage's first state) is met."""
    recorder = Recorder(2, limit=12)
    recorder.add(np.array([0, 1]), s=np.array([1.0, 2.0]))
    recorder.reserve(9)
    assert recorder.capacity == 12  # 16 by doubling, cut at the limit
    recorder.reserve(13)
    assert recorder.capacity == 13
    recorder.reserve_within_limit(40)
    assert recorder.capacity == 13  # the limit (12) already exceeded where asked: no further
    assert recorder.fits(np.array([0, 1]), np.array([11, 12])).tolist() == [True, False]
    assert Recorder(2).fits(np.array([0]), np.array([10**9])).all()
