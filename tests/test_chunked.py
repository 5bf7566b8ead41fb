"""Large sweeps in chunks: chunked, resumed, dask and CLI runs give the in-process archive.

The study (24 cases: 2 laws x 4 gamma x 3 lateral forces, D1 driven to 0.1) is
cut into chunks of 5 cases (3 per law, the last of 2 cases), so chunk borders
fall anywhere in the sweep.  Every archive is compared with the archive of
the plain in-process run (:func:`run_study` + :func:`write_dataset`) by
``xarray.testing.assert_identical``: not a tolerance but bit-identical
numbers, since each case gets the same floating-point operations whatever the
batch it is followed in (the compiled loop runs each case alone).  Only the
``created`` time stamp differs between two runs.
"""

from __future__ import annotations

import builtins
import multiprocessing.util
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from ncstab.cli import main
from ncstab.studies import (
    ResumeError,
    open_study,
    parse_study,
    run_study,
    run_study_chunked,
    write_dataset,
)
from ncstab.studies import chunked as chunked_module
from ncstab.studies.chunked import parts_directory, plan_chunks

STUDY_TEXT = """
[study]
name = "chunks"
description = "24 cases for the chunked runs"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["weakly_hypoelastic", "cundall_strack"]
[parameters]
gamma = [0.5, 1.0, 2.0, 4.0]
F2_lateral = [0.0, 0.1, 0.2]
[[loading]]
hold = { F1 = 0.0 }
drive = { F2 = "F2_lateral" }
[[loading]]
hold = { F2 = "current" }
drive = { D1 = 0.1 }
[options]
max_step = 0.05
"""
CHUNK_CASES = 5


@pytest.fixture(scope="module")
def study():
    return parse_study(STUDY_TEXT)


@pytest.fixture(scope="module")
def reference(study, tmp_path_factory):
    """The archive of the plain in-process run, as read back."""
    path = tmp_path_factory.mktemp("reference") / "chunks.nc"
    write_dataset(run_study(study), path)
    return open_study(path)


def assert_same_archive(path: Path, reference: xr.Dataset) -> None:
    """The archive at ``path`` is identical to the reference (but for its time stamp), parts gone."""
    archive = open_study(path)
    assert archive.attrs.pop("created")
    expected = reference.copy()
    expected.attrs.pop("created")
    xr.testing.assert_identical(archive, expected)
    assert not parts_directory(path).exists()
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name], "no temporary file is left"


def test_the_chunks_cover_every_case_once_in_uneven_runs(study):
    chunks = plan_chunks(study, CHUNK_CASES)
    # 4 gamma x 3 F2*: blocks (the archive's chunks) of one gamma row; two rows exceed 5 cases.
    assert [(c.law, c.start, c.stop) for c in chunks] == [
        (law, start, start + 3) for law in study.laws for start in (0, 3, 6, 9)
    ]
    assert len({c.file_name for c in chunks}) == len(chunks)


def test_the_reference_has_steps_of_different_lengths(reference):
    # Otherwise padding the step dimension across chunks would go untested.
    assert np.unique(reference["n_steps"].values).size > 1
    assert reference.sizes["law"] * reference.sizes["gamma"] * reference.sizes["F2_lateral"] == 24


def test_a_chunked_run_writes_the_in_process_archive(study, reference, tmp_path):
    output = tmp_path / "chunks.nc"
    assert run_study_chunked(study, output, chunk_cases=CHUNK_CASES) == output
    assert_same_archive(output, reference)


def test_a_chunked_run_of_the_compiled_backend_writes_its_in_process_archive(tmp_path):
    """The compiled stepper's cases do not depend on their batch either."""
    pytest.importorskip("numba")
    study = parse_study(STUDY_TEXT.replace("max_step = 0.05", 'max_step = 0.05\nbackend = "compiled"'))
    assert study.options.backend == "compiled"
    reference_path = tmp_path / "reference" / "chunks.nc"
    reference_path.parent.mkdir()
    write_dataset(run_study(study), reference_path)
    output = tmp_path / "out" / "chunks.nc"
    run_study_chunked(study, output, chunk_cases=CHUNK_CASES)
    assert_same_archive(output, open_study(reference_path))


def test_a_killed_run_keeps_its_chunks_and_resume_computes_only_the_rest(
    study, reference, tmp_path, monkeypatch
):
    output = tmp_path / "chunks.nc"
    original = chunked_module.run_chunk
    computed: list[tuple[str, int]] = []

    def killed_after_two(study, law, start, stop):
        if len(computed) == 2:
            raise KeyboardInterrupt("killed")
        computed.append((law, start))
        return original(study, law, start, stop)

    monkeypatch.setattr(chunked_module, "run_chunk", killed_after_two)
    with pytest.raises(KeyboardInterrupt):
        run_study_chunked(study, output, chunk_cases=CHUNK_CASES)
    assert not output.exists()
    parts = sorted(p.name for p in parts_directory(output).iterdir())
    assert parts == ["manifest.json", "weakly_hypoelastic_000000.npz", "weakly_hypoelastic_000001.npz"]

    def counted(study, law, start, stop):
        computed.append((law, start))
        return original(study, law, start, stop)

    computed.clear()
    monkeypatch.setattr(chunked_module, "run_chunk", counted)
    run_study_chunked(study, output, resume=True)  # the chunk size comes from the parts
    assert computed == [("weakly_hypoelastic", 6), ("weakly_hypoelastic", 9)] + [
        ("cundall_strack", start) for start in (0, 3, 6, 9)
    ]
    assert_same_archive(output, reference)

    computed.clear()
    run_study_chunked(study, output, resume=True)  # nothing left to do
    assert computed == []
    assert_same_archive(output, reference)


def test_resume_refuses_the_parts_of_another_study_or_chunk_size(study, tmp_path, monkeypatch):
    output = tmp_path / "chunks.nc"

    def killed(study, law, start, stop):
        raise KeyboardInterrupt("killed")

    monkeypatch.setattr(chunked_module, "run_chunk", killed)
    with pytest.raises(KeyboardInterrupt):
        run_study_chunked(study, output, chunk_cases=CHUNK_CASES)
    other = parse_study(STUDY_TEXT.replace("D1 = 0.1", "D1 = 0.2"))
    with pytest.raises(ResumeError, match="another version of study 'chunks'") as error:
        run_study_chunked(other, output, resume=True)
    assert error.value.field == "study"
    with pytest.raises(ResumeError, match="chunk_cases = 5, not 4") as error:
        run_study_chunked(study, output, chunk_cases=4, resume=True)
    assert error.value.field == "chunk_cases"


def test_the_cli_writes_the_in_process_archive_in_chunks(study, reference, tmp_path, capsys):
    study_file = tmp_path / "study" / "chunks.toml"
    study_file.parent.mkdir()
    study_file.write_text(STUDY_TEXT)
    output = tmp_path / "out" / "chunks.nc"
    assert main(["run", str(study_file), "--chunk-cases", "5", "-q", "-o", str(output)]) == 0
    assert f"wrote {output}" in capsys.readouterr().out
    for figure in output.parent.glob("*.png"):
        figure.unlink()
    assert_same_archive(output, reference)


def test_workers_without_dask_is_a_clear_error(tmp_path, monkeypatch, capsys):
    real_import = builtins.__import__

    def no_distributed(name, *args, **kwargs):
        if name == "distributed" or name.startswith("distributed."):
            raise ModuleNotFoundError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_distributed)
    study_file = tmp_path / "chunks.toml"
    study_file.write_text(STUDY_TEXT)
    output = tmp_path / "chunks.nc"
    assert main(["run", str(study_file), "--workers", "2", "-q", "-o", str(output)]) == 2
    assert "pip install ncstab[distributed]" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chunks.toml"], "nothing was run"


def test_workers_and_scheduler_are_exclusive(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["run", "x.toml", "--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"])
    assert "not allowed with argument" in capsys.readouterr().err


def test_a_dask_run_writes_the_in_process_archive(study, reference, tmp_path, monkeypatch):
    pytest.importorskip("dask.distributed")
    # A short TMPDIR of its own (not under tmp_path): the forkserver's socket lives in it,
    # and a Unix socket's path may not exceed 107 bytes (pytest-xdist's tmp_path is long).
    scratch = Path(tempfile.mkdtemp(prefix="ncd-"))
    try:
        monkeypatch.setenv("TMPDIR", str(scratch))
        monkeypatch.setattr(tempfile, "tempdir", None)  # TMPDIR is read again
        output = tmp_path / "out" / "chunks.nc"
        run_study_chunked(study, output, chunk_cases=CHUNK_CASES, workers=2)
        assert_same_archive(output, reference)
        # (pymp-*: the socket directory of multiprocessing's forkserver, which starts the
        # workers and serves later runs; multiprocessing removes it when the process exits.)
        left = [p for p in scratch.iterdir() if not p.name.startswith("pymp-")]
        assert left == [], "the workers' scratch space is removed"
    finally:
        # The forkserver's pymp-* folder is multiprocessing's to remove at exit (removing
        # it here made its finalizer print a FileNotFoundError traceback); the scratch
        # folder goes after it (finalizers run by decreasing priority; pymp's is -100).
        for entry in scratch.iterdir():
            if entry.is_dir() and not entry.name.startswith("pymp-"):
                shutil.rmtree(entry, ignore_errors=True)
            elif not entry.is_dir():
                entry.unlink()
        multiprocessing.util.Finalize(None, shutil.rmtree, args=(str(scratch),), kwargs={"ignore_errors": True},
                                      exitpriority=-101)


def test_a_run_on_an_existing_scheduler_writes_the_in_process_archive(study, reference, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    import dask

    # A worker in a process of its own, as on a remote cluster: the chunk's Dataset is
    # pickled back to this process, which writes the part (the workers of an existing
    # cluster may not see the output directory).
    with dask.config.set({"temporary-directory": str(tmp_path / "scratch")}), distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=True, dashboard_address=":0"
    ) as cluster:
        output = tmp_path / "out" / "chunks.nc"
        run_study_chunked(study, output, chunk_cases=CHUNK_CASES, scheduler=cluster.scheduler_address)
    assert_same_archive(output, reference)


def test_the_cli_streams_a_study_larger_than_a_chunk_without_flags(
    study, reference, tmp_path, monkeypatch, capsys
):
    """More cases per law than one chunk: streamed (never all in memory), same archive."""
    import ncstab.studies as studies_package
    import ncstab.studies.chunk_plan as chunk_plan

    monkeypatch.setattr(chunk_plan, "DEFAULT_CHUNK_CASES", CHUNK_CASES)  # 12 cases per law > 5
    chunks = []
    original = chunked_module.run_chunk
    monkeypatch.setattr(chunked_module, "run_chunk", lambda *a: chunks.append(a[2:]) or original(*a))

    def in_memory(*args, **kwargs):
        raise AssertionError("a study larger than a chunk must not be run in memory")

    monkeypatch.setattr(studies_package, "run_study", in_memory)
    study_file = tmp_path / "study" / "chunks.toml"
    study_file.parent.mkdir()
    study_file.write_text(STUDY_TEXT)
    output = tmp_path / "out" / "chunks.nc"
    assert main(["run", str(study_file), "-q", "-o", str(output)]) == 0
    assert "cases: 24" in capsys.readouterr().out
    assert len(chunks) > len(study.laws), "each law's cases in more than one chunk"
    for figure in output.parent.glob("*.png"):
        figure.unlink()
    assert_same_archive(output, reference)
