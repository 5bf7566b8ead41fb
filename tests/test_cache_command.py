"""One cache root and ``ncstab cache`` (issue 14, "Compilation cost").

Every cache of ncstab is a folder of one root (``$NCSTAB_CACHE_DIR``, else
``$XDG_CACHE_HOME/ncstab``, else ``~/.cache/ncstab``), named in
``ncstab.cache.CACHE_KINDS``; ``ncstab cache`` reports those folders and
``ncstab cache clear`` removes them and nothing else.  Each test points the
root at its own temporary folder: the session's cache is not touched.
"""

from __future__ import annotations

import errno
import os
import re
import sys
from pathlib import Path

import pytest

from ncstab.cache import CACHE_KINDS, cache_directory, cache_root, cache_usage, clear_cache
from ncstab.cli import main

#: Fake entries: path under the root -> size in bytes.
ENTRIES = {
    "compiled/ncstab_stage_loop_0123.py": 1000,
    "compiled/__pycache__/ncstab_stage_loop_0123.run-1.py311.nbi": 120,
    "compiled/__pycache__/ncstab_stage_loop_0123.run-1.py311.1.nbc": 2000,
    "law_classes/ab.json": 10,
}
#: What is under the root and not ncstab's: left alone by ``ncstab cache clear``.
FOREIGN = {"other/keep.txt": 7, "notes.txt": 5}


def _fill(root: Path, entries: dict[str, int]) -> None:
    for name, size in entries.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_bytes(b"x" * size)


@pytest.fixture
def root(tmp_path, monkeypatch) -> Path:
    """A cache root holding :data:`ENTRIES` and :data:`FOREIGN`."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(folder))
    _fill(folder, ENTRIES | FOREIGN)
    return folder


def _ncstab(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(["cache", *argv])
    out, err = capsys.readouterr()
    return code, out, err


# --- one root ---------------------------------------------------------------------------------


def test_the_root_is_ncstab_cache_dir_else_xdg_cache_home_else_home(tmp_path, monkeypatch):
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path / "mine"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "mine"
    assert cache_directory("compiled") == tmp_path / "mine" / "compiled"
    monkeypatch.setenv("NCSTAB_CACHE_DIR", "")  # empty: not set
    assert cache_root() == tmp_path / "xdg" / "ncstab"
    assert cache_directory("compiled") == tmp_path / "xdg" / "ncstab" / "compiled"
    monkeypatch.delenv("NCSTAB_CACHE_DIR")
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert cache_root() == Path.home() / ".cache" / "ncstab"


def test_every_cache_of_ncstab_is_a_registered_kind_and_no_other_is_accepted():
    from ncstab.operators import kernel_cache
    from ncstab.paths import compiled_source
    from ncstab.studies.verification import VALID_STUDIES_KIND
    from ncstab.symbolic.class_cache import CACHE_KIND

    assert set(CACHE_KINDS) == {compiled_source.CACHE_KIND, CACHE_KIND, VALID_STUDIES_KIND, kernel_cache.CACHE_KIND}
    with pytest.raises(ValueError, match="unknown cache 'loops'"):
        cache_directory("loops")


def test_the_compiled_loops_are_written_under_the_root(tmp_path, monkeypatch):
    pytest.importorskip("numba")
    from ncstab.paths import compiled_source

    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path / "cache"))
    module = compiled_source.load_module(f'"""A generated module of {tmp_path}."""\nVALUE = 7\n', "ncstab_stage_loop")
    path = Path(module.__file__)
    try:
        assert module.VALUE == 7
        assert path.parent == tmp_path / "cache" / "compiled"
        assert re.fullmatch(r"ncstab_stage_loop_[0-9a-f]+\.py", path.name), path.name
        # the module, and its bytecode where Python writes it (PYTHONDONTWRITEBYTECODE unset)
        usage = [(u.kind, u.files) for u in cache_usage()]
        others = [("law_classes", 0), ("state_kernels", 0), ("valid_studies", 0)]
        assert usage in ([("compiled", 1), *others], [("compiled", 2), *others]), usage
    finally:
        sys.modules.pop(path.stem, None)


# --- ncstab cache (info) ------------------------------------------------------------------------


def test_info_counts_the_files_and_bytes_of_each_folder_exactly(root, capsys):
    code, out, err = _ncstab(capsys)
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0] == f"cache root: {root}"
    rows = {line.split()[0]: line.split()[1:5] for line in lines[1:6]}
    assert rows == {
        "compiled": ["3", "files", "3.12", "kB"],
        "law_classes": ["1", "file", "10", "bytes"],
        "state_kernels": ["0", "files", "0", "bytes"],
        "valid_studies": ["0", "files", "0", "bytes"],
        "total": ["4", "files", "3.13", "kB"],
    }
    for kind, description in CACHE_KINDS.items():
        assert lines[1 + list(CACHE_KINDS).index(kind)].endswith(f"  {description}")
    assert lines[6] == "  and 2 other entries under the root, not a cache of ncstab (ncstab cache clear leaves them)"
    assert len(lines) == 7
    assert max(len(line) for line in lines[1:]) <= 100
    assert [(u.kind, u.files, u.size) for u in cache_usage()] == [
        ("compiled", 3, 3120), ("law_classes", 1, 10), ("state_kernels", 0, 0), ("valid_studies", 0, 0)
    ]
    assert _ncstab(capsys, "info") == (0, out, "")


def test_info_of_a_root_that_does_not_exist_is_all_zeros(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path / "none"))
    code, out, _ = _ncstab(capsys)
    assert code == 0
    assert out.splitlines()[0] == f"cache root: {tmp_path / 'none'} (nothing cached yet)"
    assert out.splitlines()[5].split() == ["total", "0", "files", "0", "bytes"]
    assert not (tmp_path / "none").exists()


def test_info_and_clear_use_xdg_cache_home_when_ncstab_cache_dir_is_unset(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("NCSTAB_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    _fill(tmp_path / "xdg" / "ncstab", {"law_classes/ab.json": 10})
    code, out, _ = _ncstab(capsys)
    assert code == 0 and out.startswith(f"cache root: {tmp_path / 'xdg' / 'ncstab'}\n")
    assert out.splitlines()[2].split()[:5] == ["law_classes", "1", "file", "10", "bytes"]
    assert _ncstab(capsys, "clear")[0] == 0
    assert not (tmp_path / "xdg" / "ncstab" / "law_classes").exists()


# --- ncstab cache clear -----------------------------------------------------------------------


def test_clear_removes_ncstab_folders_says_what_it_freed_and_leaves_the_rest(root, capsys):
    code, out, err = _ncstab(capsys, "clear")
    assert (code, err) == (0, "")
    assert out.splitlines() == [
        f"cache root: {root}",
        "  removed compiled: 3 files, 3.12 kB",
        "  removed law_classes: 1 file, 10 bytes",
        "freed 3.13 kB (4 files)",
    ]
    left = sorted(p.relative_to(root).as_posix() for p in root.rglob("*"))
    assert left == ["notes.txt", "other", "other/keep.txt"]
    code, out, _ = _ncstab(capsys, "clear")
    assert (code, out) == (0, f"nothing to clear: no ncstab cache folder in {root}\n")


def test_clearing_a_root_that_does_not_exist_is_not_an_error(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path / "none"))
    code, out, err = _ncstab(capsys, "clear")
    assert (code, err) == (0, "")
    assert out == f"nothing to clear: the cache root {tmp_path / 'none'} does not exist\n"
    assert not (tmp_path / "none").exists()


def test_clear_removes_a_link_in_place_of_a_folder_not_what_it_points_to(root, tmp_path):
    outside = tmp_path / "elsewhere"
    _fill(outside, {"precious.txt": 3})
    (root / "valid_studies").symlink_to(outside, target_is_directory=True)
    (root / "compiled" / "link").symlink_to(outside, target_is_directory=True)
    clearance = clear_cache()
    assert clearance.failures == ()
    assert [(u.kind, u.files) for u in clearance.removed] == [("compiled", 4), ("law_classes", 1),
                                                              ("valid_studies", 1)]
    assert (outside / "precious.txt").read_bytes() == b"xxx"
    assert not os.path.lexists(root / "valid_studies") and not (root / "compiled").exists()


def test_a_file_removed_by_another_process_meanwhile_is_not_an_error(root, monkeypatch, capsys):
    gone = str(root / "law_classes" / "ab.json")
    unlink = os.unlink

    def removed_meanwhile(path, *args, **kwargs):
        if str(path) == gone:
            unlink(path)
            raise FileNotFoundError(errno.ENOENT, "No such file or directory", path)
        return unlink(path, *args, **kwargs)

    monkeypatch.setattr(os, "unlink", removed_meanwhile)
    code, out, _ = _ncstab(capsys, "clear")
    assert code == 0 and out.endswith("freed 3.12 kB (3 files)\n")
    assert not (root / "law_classes").exists()


@pytest.mark.parametrize(("code", "reason"), [(errno.EACCES, "Permission denied"),
                                              (errno.EBUSY, "Device or resource busy")])
def test_a_file_that_cannot_be_removed_is_named_in_one_line_with_exit_code_3(root, monkeypatch, capsys, code,
                                                                              reason):
    stuck = str(root / "compiled" / "ncstab_stage_loop_0123.py")
    unlink = os.unlink

    def refuse(path, *args, **kwargs):
        if str(path) == stuck:
            raise OSError(code, reason, path)
        return unlink(path, *args, **kwargs)

    monkeypatch.setattr(os, "unlink", refuse)
    exit_code, out, err = _ncstab(capsys, "clear")
    assert exit_code == 3
    assert err == f"ncstab cache: cannot remove {stuck}: {reason}; freed 2.13 kB (3 files); the rest is kept\n"
    assert "  removed compiled: 2 files, 2.12 kB" in out.splitlines()
    left = sorted(p.name for p in root.rglob("*") if p.is_file())
    assert left == ["keep.txt", "ncstab_stage_loop_0123.py", "notes.txt"]


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0,
                    reason="root may remove files from a read-only folder")
def test_a_read_only_folder_gives_exit_code_3_and_names_what_stayed(root, capsys):
    stuck = root / "compiled" / "__pycache__"
    stuck.chmod(0o555)
    try:
        code, out, err = _ncstab(capsys, "clear")
    finally:
        stuck.chmod(0o755)
    assert code == 3
    assert re.fullmatch(rf"ncstab cache: cannot remove {re.escape(str(stuck))}/\S+: Permission denied "
                        r"\(and 1 more\); freed 1.01 kB \(2 files\); the rest is kept\n", err), err
    assert "Traceback" not in err and "freed" not in out
    assert len(list(stuck.iterdir())) == 2


def test_compile_compiles_every_loop_in_processes_by_model_and_says_so(capsys):
    """On the session's cache (the warm-up compiled the loops, so it takes seconds): five
    items in two processes, the general models' loop apart from the diamond's laws, a
    ring's kernel and the Dataset's indicators, so that no two processes compile the same loop."""
    from ncstab.engine_warmup import ENGINE_ITEMS, groups_by_model

    assert groups_by_model(ENGINE_ITEMS, 2) == [
        ("mcnamara", "cundall_strack", "general-rate", "dataset"), ("general-total",)]
    (single,) = groups_by_model(ENGINE_ITEMS, 1)
    assert sorted(single) == sorted(ENGINE_ITEMS)
    code, out, err = _ncstab(capsys, "compile")
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0].startswith("compiling the compiled stepper's 2 loops (the reduced diamond's, the general models') into ")
    assert sorted(line.split(" in ")[0] for line in lines[1:3]) == [
        "  compiled for general-total", "  compiled for mcnamara, cundall_strack, general-rate, dataset"]
    assert re.fullmatch(r"done in \d+ s: studies of any size now start at once", lines[3])


def test_compile_that_fails_is_one_line_and_exit_code_3(capsys, monkeypatch):
    import ncstab.engine_warmup as warmup

    def failing(items, processes, done=None):
        raise RuntimeError("mcnamara, general-total: numba.core.errors.TypingError: ...")

    monkeypatch.setattr(warmup, "compile_loops", failing)
    code, out, err = _ncstab(capsys, "compile", "--processes", "1")
    assert code == 3
    assert err == ("ncstab cache: compiling failed: mcnamara, general-total: numba.core.errors.TypingError: ...; "
                   "the loops compiled before it stay cached\n")


def test_compile_refuses_a_process_count_below_one(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["cache", "compile", "--processes", "0"])
    assert exit_.value.code == 2
    assert "--processes: must be a whole number of at least 1, not '0'" in capsys.readouterr().err
