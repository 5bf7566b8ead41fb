"""The motions of a dynamic stage on several processes give the serial run's numbers exactly
(:mod:`ncstab.studies.motions_on_cores`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from ncstab.studies import load_study
from ncstab.studies import motions_on_cores
from ncstab.studies.run import run_study

STUDY = Path(__file__).resolve().parents[1] / "studies" / "ziegler_flutter_motion.toml"


def _swept_study(tmp_path):
    """Ziegler's pendulum released at 8 follower loads, below and past flutter (2.0858)."""
    text = STUDY.read_text().replace('drive = { P = 2.2 }', 'drive = { P = "P_end" }')
    text = text.replace("[output]", "[parameters]\nP_end = [1.8, 1.9, 2.0, 2.05, 2.15, 2.2, 2.3, 2.4]\n\n[output]")
    text = text.replace("duration = 60.0", "duration = 20.0").replace("samples = 1201", "samples = 201")
    path = tmp_path / "ziegler_motions.toml"
    path.write_text(text)
    return load_study(path)


def test_worker_count_gives_each_worker_enough_cases():
    per = motions_on_cores.CASES_PER_WORKER
    assert motions_on_cores.worker_count(per - 1, 2) == 1  # too few cases: here
    assert motions_on_cores.worker_count(2 * per, 2) == 2
    assert motions_on_cores.worker_count(2 * per, 16) == 2  # CASES_PER_WORKER each at least
    assert motions_on_cores.worker_count(100 * per, 1) == 1


@pytest.fixture(autouse=True)
def four_cases_a_worker(monkeypatch):
    """8 cases on 2 processes (a test's sweep is small: the threshold is lowered)."""
    monkeypatch.setattr(motions_on_cores, "CASES_PER_WORKER", 4)


def test_motions_on_two_processes_equal_the_serial_ones(tmp_path, monkeypatch):
    study = _swept_study(tmp_path)
    serial_calls = []
    original = motions_on_cores.study_motions

    def serial(study, path, workers=None):
        serial_calls.append(True)
        return original(study, path, workers=1)

    monkeypatch.setattr(motions_on_cores, "study_motions", serial)
    alone = run_study(study)
    assert serial_calls
    monkeypatch.setattr(motions_on_cores, "study_motions", lambda study, path, workers=None: original(study, path, 2))
    spread = run_study(study)
    spread.attrs["created"] = alone.attrs["created"]
    xr.testing.assert_identical(spread, alone)
    # past flutter the oscillation grows, below it stays bounded: the motions are real
    amplitude = np.abs(alone["u_t"].isel(law=0)).max(("time", "dof")).values
    assert amplitude[-1] > 10 * amplitude[0]  # (measured 68 times over 20 time units)


def test_processes_are_used(tmp_path, monkeypatch):
    """With 8 cases and 2 workers the pool is started (not the in-order fallback)."""
    import concurrent.futures

    started = []
    pool = concurrent.futures.ProcessPoolExecutor

    class Counting(pool):
        def __init__(self, *args, **kwargs):
            started.append(args[0] if args else kwargs.get("max_workers"))
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", Counting)
    study = _swept_study(tmp_path)
    from ncstab.studies.chunked import chunk_path

    path = chunk_path(study, None, 0, 8)  # Ziegler's own springs: no law named
    motions = motions_on_cores.study_motions(study, path, workers=2)
    assert started == [2]
    assert len(motions[0]) == 8 and all(m is not None for m in motions[0])
