"""Threads of the compiled stepper: the cases of a stage share the cores.

A case's arithmetic does not depend on the thread that runs it, so every
archive must be bit for bit the same whatever the thread count (issue 14,
"Must hold"); ``--threads`` is validated like every other option (exit 2,
naming the option).
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

pytest.importorskip("numba")

from ncstab.cli import main
from ncstab.paths import PathOptions, SystemSpec, compiled_stages, follow
from ncstab.paths.threads import check_thread_count, side_by_side, thread_count, thread_limit, using_threads

IGNORE = SystemSpec(secondary_contacts="ignore")
PRELOAD = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.6}, "stop_at": ["limit_point"]},
]
#: 96 cases with limit points, Hill losses and stops, unevenly costly, so that
#: the shares of the cases (blocks of SHARE_BLOCK dealt in turn) give each thread a different mix.
GRID = {"gamma": np.linspace(0.1, 2.0, 8), "alpha0": np.pi / 4, "F2_lateral": np.linspace(0.0, 0.6, 12)}


def _dataset(threads: int) -> xr.Dataset:
    """The archive with ``threads`` threads, for the stepping and for the Dataset's
    indicators (a second thread computes some of them)."""
    with using_threads(threads):
        path = follow(IGNORE, ["cundall_strack", "mcnamara"], PRELOAD, GRID, PathOptions())
        dataset = path.to_dataset()
    dataset.attrs.pop("created", None)
    return dataset


@pytest.mark.skipif(thread_limit() < 2, reason="numba runs one thread here (NUMBA_NUM_THREADS or one core)")
def test_one_and_two_threads_give_the_same_archive_bit_for_bit():
    one, two = _dataset(1), _dataset(2)
    assert "compiled stepper" in one.attrs["engine"]
    assert int((one["status"] != "finished").sum()) > 0  # stops at limit points are among them
    xr.testing.assert_identical(one, two)


def test_using_threads_restores_the_count():
    before = thread_count()
    assert before == thread_limit()
    with using_threads(1):
        assert thread_count() == 1
    assert thread_count() == before
    with using_threads(None):
        assert thread_count() == before


@pytest.mark.skipif(thread_limit() < 2, reason="numba runs one thread here (NUMBA_NUM_THREADS or one core)")
def test_two_threads_run_the_loop_side_by_side_and_one_thread_runs_it_inline(monkeypatch):
    """The count reaches the threads: two threads run two shares side by side, blocks of
    SHARE_BLOCK consecutive cases dealt in turn; one thread none, nor fewer cases than one block."""
    calls = []

    def recording(tasks, name):
        calls.append([task.args[0].copy() for task in tasks])
        side_by_side(tasks, name)

    monkeypatch.setattr(compiled_stages, "side_by_side", recording)
    grid = {"gamma": np.linspace(0.5, 1.5, 5), "alpha0": np.pi / 4}
    programme = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.1}}]
    with using_threads(1):
        follow(IGNORE, ["cundall_strack"], programme, grid, PathOptions())
    with using_threads(2):  # 5 cases, fewer than a block of the default SHARE_BLOCK = 64: one share
        follow(IGNORE, ["cundall_strack"], programme, grid, PathOptions())
    assert compiled_stages.SHARE_BLOCK == 64 and calls == []
    monkeypatch.setattr(compiled_stages, "SHARE_BLOCK", 2)
    with using_threads(2):
        follow(IGNORE, ["cundall_strack"], programme, grid, PathOptions())
    shares = calls[0]
    assert len(shares) == 2
    np.testing.assert_array_equal(shares[0], [0, 1, 4])
    np.testing.assert_array_equal(shares[1], [2, 3])


def test_side_by_side_runs_the_first_task_here_and_the_others_on_ncstab_s_threads():
    """The first task in the calling thread, the others on ncstab's threads (named for what
    they do), started once: a second call runs on the same threads; an error reaches the
    caller after every task is done."""
    import threading

    seen = []

    def task():
        seen.append(threading.current_thread())

    side_by_side([task, task], "probe")
    first = list(seen)
    assert first[0] is threading.current_thread()
    assert first[1] is not threading.current_thread() and first[1].name == "ncstab-probe"
    seen.clear()
    side_by_side([task, task], "probe")
    assert seen[1] is first[1]
    done = []

    def fails():
        raise RuntimeError("share failed")

    with pytest.raises(RuntimeError, match="share failed"):
        side_by_side([fails, lambda: done.append(1)], "probe")
    assert done == [1]
    nested = []

    def shares_out():  # on ncstab's thread, sharing out again: run there, no wait on itself
        side_by_side([lambda: nested.append(threading.current_thread())] * 2, "inner")

    side_by_side([lambda: None, shares_out], "probe")
    assert len(nested) == 2 and nested[0] is nested[1] and nested[0] is not threading.current_thread()


@pytest.mark.parametrize("count", [0, -2, 1.5, True])
def test_a_thread_count_that_is_not_a_positive_whole_number_is_refused(count):
    with pytest.raises(ValueError, match="--threads must be a positive whole number"):
        check_thread_count(count)


def test_more_threads_than_numba_started_with_are_refused():
    with pytest.raises(ValueError, match=rf"more than the {thread_limit()} threads numba started with"):
        check_thread_count(thread_limit() + 1)


@pytest.mark.parametrize("count", ["0", "100000"])
def test_ncstab_run_with_a_bad_thread_count_exits_2_naming_the_option(tmp_path, capsys, count):
    study = tmp_path / "s.toml"
    study.write_text('[study]\nname = "s"\n[system]\nname = "diamond"\n[laws]\nnames = ["mcnamara"]\n'
                     '[parameters]\ngamma = 1.0\nalpha0 = 0.785\n'
                     '[[loading]]\nhold = { F2 = 0.0 }\ndrive = { D1 = 0.01 }\n')
    assert main(["run", str(study), "-o", str(tmp_path / "s.nc"), "--threads", count]) == 2
    err = capsys.readouterr().err
    assert "--threads" in err and "Traceback" not in err
    assert not (tmp_path / "s.nc").exists()


@pytest.mark.skipif(thread_limit() < 2, reason="numba runs one thread here (NUMBA_NUM_THREADS or one core)")
def test_in_shares_runs_every_share_once_inline_on_one_thread_and_beside_it_on_two():
    """in_shares (the recorder's growth, the Dataset's indicator blocks): every
    non-empty share once, in the calling thread under one thread; under two, in the
    calling thread and on one of ncstab's; empty shares are skipped."""
    import threading

    from ncstab.paths.threads import in_shares

    for threads in (1, 2):
        seen = []

        def work(rows, seen=seen):
            seen.append((rows.start, rows.stop, threading.get_ident()))

        with using_threads(threads):
            in_shares(work, [0, 3, 3, 7, 10], "test")
        assert sorted((a, b) for a, b, _ in seen) == [(0, 3), (3, 7), (7, 10)]
        idents = {ident for _, _, ident in seen}
        if threads == 1:
            assert idents == {threading.get_ident()}
        else:
            assert threading.get_ident() in idents and len(idents) == 2


def test_the_recorder_grows_the_same_bytes_on_one_thread_and_on_two():
    """Recorder.reserve copies the stored states and blanks the rest in shares of the case
    axis on the study's threads where an array is large (PARALLEL_GROWTH_BYTES): the
    grown arrays are the same, byte for byte, and the same as written by hand."""
    from ncstab.paths.recorder import PARALLEL_GROWTH_BYTES, Recorder

    rng = np.random.default_rng(3)
    size = PARALLEL_GROWTH_BYTES // (8 * 2 * 64) + 7  # float64 (size, 64, 2) grows past the threshold
    grown = []
    for threads in (1, 2):
        recorder = Recorder(size)
        recorder.create({"u": ((2,), np.dtype(float)), "stage": ((), np.dtype(int))})
        recorder.arrays["u"][:] = rng.normal(size=recorder.arrays["u"].shape) if threads == 1 else grown[0][0][:, :8]
        recorder.arrays["stage"][:] = 5
        with using_threads(threads):
            recorder.reserve(64)
        assert recorder.arrays["u"].nbytes > PARALLEL_GROWTH_BYTES
        grown.append((recorder.arrays["u"], recorder.arrays["stage"]))
    for one, two in zip(*grown):
        assert one.tobytes() == two.tobytes()
    u, stage = grown[1]
    assert np.isnan(u[:, 8:]).all() and (stage[:, 8:] == -1).all() and (stage[:, :8] == 5).all()
