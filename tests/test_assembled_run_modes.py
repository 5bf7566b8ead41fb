"""Every run mode on an assembled system gives the in-process archive.

A ring of 12 grains (above the derived-dofs limit of 8: an assembled system, the
sparse engine), McNamara, 4 values of gamma, grains 1 and 7 pushed in (D1 = D7 =
0.1), the others force-free.  Chunked (one case a chunk), killed and resumed,
streamed (more cases than a default chunk, no flag) and on two dask workers: each
archive is compared with the in-process archive by ``xarray.testing.assert_identical``
(bit-identical: the sparse engine follows each case alone, whatever its chunk),
the ``created`` time stamp aside.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest
import xarray as xr

from ncstab.cli import main
from ncstab.studies import open_study, parse_study, run_study, run_study_chunked, write_dataset
from ncstab.studies import chunked as chunked_module
from ncstab.studies.chunked import parts_directory

N = 12
_HOLDS = ", ".join(f"F{k} = 0.0" for k in range(2, N + 1) if k != 7)
STUDY_TEXT = (
    f'[study]\nname = "ring_modes"\n[system]\nname = "ring"\ngrains = {N}\n[laws]\nnames = ["mcnamara"]\n'
    f"[parameters]\ngamma = [0.5, 1.0, 2.0, 4.0]\n[[loading]]\nhold = {{ {_HOLDS} }}\n"
    "drive = { D1 = 0.1, D7 = 0.1 }\n"
)


@pytest.fixture(scope="module")
def study():
    return parse_study(STUDY_TEXT)


@pytest.fixture(scope="module")
def reference(study, tmp_path_factory):
    path = tmp_path_factory.mktemp("reference") / "ring_modes.nc"
    write_dataset(run_study(study), path)
    archive = open_study(path)
    assert "sparse engine" in archive.attrs["engine"]
    assert (archive.status.values.astype(str) == "finished").all()
    return archive


def assert_same_archive(path: Path, reference: xr.Dataset) -> None:
    archive = open_study(path)
    assert archive.attrs.pop("created")
    expected = reference.copy()
    expected.attrs.pop("created")
    xr.testing.assert_identical(archive, expected)
    assert not parts_directory(path).exists()


def test_chunks_of_one_case_give_the_in_process_archive(study, reference, tmp_path):
    output = tmp_path / "ring_modes.nc"
    run_study_chunked(study, output, chunk_cases=1)
    assert_same_archive(output, reference)


def test_a_killed_run_resumed_gives_the_in_process_archive(study, reference, tmp_path, monkeypatch):
    output = tmp_path / "ring_modes.nc"
    original, computed = chunked_module.run_chunk, []

    def killed_after_two(study, law, start, stop):
        if len(computed) == 2:
            raise KeyboardInterrupt("killed")
        computed.append(start)
        return original(study, law, start, stop)

    monkeypatch.setattr(chunked_module, "run_chunk", killed_after_two)
    with pytest.raises(KeyboardInterrupt):
        run_study_chunked(study, output, chunk_cases=1)
    monkeypatch.setattr(chunked_module, "run_chunk", lambda *a: computed.append(a[2]) or original(*a))
    computed.clear()
    run_study_chunked(study, output, resume=True)
    assert computed == [2, 3], "only the missing chunks are computed"
    assert_same_archive(output, reference)


def test_a_study_larger_than_a_chunk_streams_to_the_in_process_archive(study, reference, tmp_path, monkeypatch):
    """No flag: 4 cases > a default chunk of 2 (the 8,192 of a real run, made small), streamed."""
    import ncstab.studies as studies_package
    import ncstab.studies.chunk_plan as chunk_plan

    monkeypatch.setattr(chunk_plan, "DEFAULT_CHUNK_CASES", 2)
    chunks, original = [], chunked_module.run_chunk
    monkeypatch.setattr(chunked_module, "run_chunk", lambda *a: chunks.append(a[2:]) or original(*a))

    def in_memory(*args, **kwargs):
        raise AssertionError("a study larger than a chunk must not be run in memory")

    monkeypatch.setattr(studies_package, "run_study", in_memory)
    study_file = tmp_path / "ring_modes.toml"
    study_file.write_text(STUDY_TEXT)
    output = tmp_path / "out" / "ring_modes.nc"
    assert main(["run", str(study_file), "-q", "-o", str(output)]) == 0
    assert chunks == [(0, 2), (2, 4)]
    for figure in output.parent.glob("*.png"):
        figure.unlink()
    assert_same_archive(output, reference)


def test_two_dask_workers_give_the_in_process_archive(study, reference, tmp_path, monkeypatch):
    pytest.importorskip("dask.distributed")
    # A short TMPDIR (the forkserver's socket path may not exceed 107 bytes), as in test_chunked.py.
    scratch = Path(tempfile.mkdtemp(prefix="ncr-"))
    try:
        monkeypatch.setenv("TMPDIR", str(scratch))
        monkeypatch.setattr(tempfile, "tempdir", None)
        output = tmp_path / "out" / "ring_modes.nc"
        run_study_chunked(study, output, chunk_cases=1, workers=2)
        assert_same_archive(output, reference)
    finally:
        import multiprocessing.util

        for entry in scratch.iterdir():
            if entry.is_dir() and not entry.name.startswith("pymp-"):
                shutil.rmtree(entry, ignore_errors=True)
            elif not entry.is_dir():
                entry.unlink()
        multiprocessing.util.Finalize(None, shutil.rmtree, args=(str(scratch),), kwargs={"ignore_errors": True},
                                      exitpriority=-101)
