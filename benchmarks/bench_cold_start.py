"""First results on a new machine: whole-process ``ncstab run`` with empty caches.

Issue 39 asks for the first result of four shipped studies in at most 20 s on
2 cores, right after ``pip install .`` with nothing cached.  Each study runs
twice, each time in a new process with a new, empty cache folder
(``XDG_CACHE_HOME`` and ``NCSTAB_CACHE_DIR`` in a temporary directory):

* ``auto`` (the default): no machine code is cached, the study is small, so the
  loop runs as plain Python (``ncstab.plain_python``);
* ``compiled`` (the baseline, ``[options] backend = "compiled"``): numba compiles
  the loop first, as every first run did before.

Both archives must be identical (checked here, bit for bit, the ``created``
time stamp aside); the table gives both wall times and their ratio.

Run:  python benchmarks/bench_cold_start.py [--studies ziegler_follower ...]

A benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import xarray as xr

ROOT = Path(__file__).resolve().parent.parent
STUDIES = (
    "studies/seed/fig03_05_mcnamara_gamma2.toml",
    "studies/ring_hexagonal.toml",
    "studies/column_buckling.toml",
    "studies/ziegler_follower.toml",
)


def cold_run(study: Path, backend: str, scratch: Path) -> tuple[float, Path]:
    """Wall seconds of ``ncstab run`` of ``study`` in a new process with empty caches,
    and the archive it wrote."""
    cache = scratch / f"cache-{backend}"
    text = study.read_text(encoding="utf-8")
    if backend != "auto":
        text = text.replace("[[loading]]", f'[options]\nbackend = "{backend}"\n\n[[loading]]', 1)
    copy = scratch / f"{backend}-{study.name}"
    copy.write_text(text, encoding="utf-8")
    output = scratch / f"{backend}-{study.stem}.nc"
    environment = dict(os.environ, XDG_CACHE_HOME=str(cache), NCSTAB_CACHE_DIR=str(cache / "ncstab"))
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "ncstab", "run", "-q", str(copy), "-o", str(output)], check=True,
                   env=environment, cwd=scratch, capture_output=True)
    return time.perf_counter() - start, output


def identical(first: Path, second: Path) -> bool:
    """Whether two archives hold the same Dataset, the time stamp and the study text aside."""
    with xr.open_dataset(first) as a, xr.open_dataset(second) as b:
        a, b = a.load(), b.load()
    for dataset in (a, b):
        for name in ("created", "study"):
            dataset.attrs.pop(name, None)
    try:
        xr.testing.assert_identical(a, b)
    except AssertionError:
        return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--studies", nargs="*", default=list(STUDIES))
    arguments = parser.parse_args()
    print(f"{'study':<36} {'auto (s)':>9} {'compiled (s)':>13} {'ratio':>6} {'archives':>9}")
    for name in arguments.studies:
        study = ROOT / name
        with tempfile.TemporaryDirectory(prefix="ncstab-cold-") as scratch:
            plain, plain_archive = cold_run(study, "auto", Path(scratch))
            machine, machine_archive = cold_run(study, "compiled", Path(scratch))
            same = "identical" if identical(plain_archive, machine_archive) else "DIFFER"
        print(f"{study.stem:<36} {plain:>9.1f} {machine:>13.1f} {machine / plain:>6.1f} {same:>9}", flush=True)


if __name__ == "__main__":
    main()
