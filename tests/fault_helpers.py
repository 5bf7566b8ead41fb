"""Helpers of the fault catalogue (``test_faults.py``): tiny studies, the command run
in process, the files left on disk, damaged archives."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import netCDF4
import numpy as np

from ncstab.cli import main

#: Two cases (one law, two gammas), a few stored states each: a run takes a fraction of a second.
TINY = """\
[study]
name = "tiny"
description = "fault catalogue"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["mcnamara"]
[parameters]
gamma = [0.5, 2.0]
[[loading]]
hold = { F2 = 0.0 }
drive = { D1 = 0.05 }
[options]
max_step = 0.05
[output]
figures = []
"""
#: Four cases, for runs in chunks of one case.
FOUR = TINY.replace("gamma = [0.5, 2.0]", "gamma = [0.5, 1.0, 1.5, 2.0]")

ROOT = Path(__file__).resolve().parents[1]


def run_cli(argv: list[str], capfd) -> tuple[int, str, str]:
    """``ncstab <argv>`` in this process: (exit code, stdout, stderr), stderr at the file-descriptor
    level (what HDF5's C library would print is seen too)."""
    capfd.readouterr()
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exit_:  # argparse's usage errors and --help
        code = exit_.code if isinstance(exit_.code, int) else 2
    out, err = capfd.readouterr()
    return code, out, err


def run_subprocess(argv: list[str], cwd: Path, timeout: float = 120, **kwargs) -> subprocess.CompletedProcess:
    """``python -m ncstab <argv>`` in a child process (for faults that need one)."""
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.run(
        [sys.executable, "-m", "ncstab", *map(str, argv)], cwd=cwd, capture_output=True, text=True,
        timeout=timeout, env=env, **kwargs,
    )


def assert_one_line(err: str, *needles: str) -> str:
    """stderr is exactly one line, without a traceback, containing every needle (a regex)."""
    lines = err.splitlines()
    assert "Traceback" not in err, err
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}:\n{err}"
    for needle in needles:
        assert re.search(needle, lines[0]), f"{needle!r} not in {lines[0]!r}"
    return lines[0]


def tree(root: Path) -> set[str]:
    """Every file and directory under ``root``, as paths relative to it."""
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def write_study(directory: Path, text: str, name: str = "study.toml") -> Path:
    path = directory / name
    path.write_text(text)
    return path


def flip_byte(path: Path, offset: int, mask: int = 0x10) -> None:
    """Flip bits of one byte of a file in place."""
    with open(path, "r+b") as handle:
        handle.seek(offset)
        byte = handle.read(1)
        handle.seek(offset)
        handle.write(bytes([byte[0] ^ mask]))


def copy_archive(source: Path, directory: Path, name: str = "archive.nc") -> Path:
    target = directory / name
    shutil.copy(source, target)
    return target


def chunk_offset(path: Path, variable: str) -> int:
    """Byte offset of the middle of the first HDF5 chunk of a compressed variable."""
    with h5py.File(path, "r") as handle:
        info = handle[variable].id.get_chunk_info(0)
        return info.byte_offset + info.size // 2


def contiguous_offset(path: Path, variable: str) -> int:
    """Byte offset of the data of an uncompressed (contiguous) variable."""
    with h5py.File(path, "r") as handle:
        return handle[variable].id.get_offset()


def edit_archive(path: Path, *, variable: str | None = None, values=None, attribute: str | None = None,
                 text: str | None = None, drop_digests: bool = True) -> None:
    """Change an archive with netCDF4 as another program would (no checksum recomputed)."""
    with netCDF4.Dataset(path, "a") as handle:
        if variable is not None:
            target = handle.variables[variable]
            target[...] = np.asarray(values, dtype=object if target.dtype is str else target.dtype)
        if attribute is not None:
            if text is None:
                handle.delncattr(attribute)
            else:
                handle.setncattr(attribute, text)
        if drop_digests and "ncstab_sha256" in handle.ncattrs():
            handle.delncattr("ncstab_sha256")
