"""Wall time of the quick ``ncstab`` commands (issue 19: fast commands).

Each command runs in a fresh Python process (``python -m ncstab ...``, the way a
user types it, imports included) and is timed from start to exit:

- ``ncstab --version``, ``ncstab --help``: argument parsing only;
- ``ncstab laws``, ``ncstab laws --all``: the law catalogue with each law's class
  (classified once, then read from the cache directory: the first run of a
  session is the slow one, so one untimed warm-up run precedes the timed ones);
- ``ncstab info ARCHIVE``: the summary of an archive (e.g. the 16,384-case
  archive of ``ncstab run studies/stability_diagram.toml -o /tmp/diagram.nc``).

Printed per command: the median and the range of the wall time of ``--repeat``
runs (3 by default), the median CPU time (user + system, of the process and its
threads: on a loaded machine the wall time measures the load, the CPU time
much less), and the exit code.
The source tree measured is the one ``python -m ncstab`` imports: set
``PYTHONPATH=src`` to measure a working tree rather than the installed package.

Run:  python benchmarks/bench_commands.py ARCHIVE.nc [--repeat 3]

A benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import time


def timed(arguments: list[str]) -> tuple[float, float, int]:
    """Wall and CPU seconds of ``python -m ncstab ARGUMENTS`` from start to exit, and its exit code."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    completed = subprocess.run(
        [sys.executable, "-m", "ncstab", *arguments], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, check=False
    )
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if completed.returncode != 0:
        first = (completed.stderr.decode(errors="replace").strip().splitlines() or [""])[0]
        print(f"  ncstab {' '.join(arguments)}: exit code {completed.returncode}: {first}", file=sys.stderr)
    return elapsed, cpu, completed.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("archive", metavar="ARCHIVE.nc", help="an archive for ncstab info")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per command (default 3)")
    args = parser.parse_args()
    commands = [["--version"], ["--help"], ["laws"], ["laws", "--all"], ["info", args.archive]]
    for arguments in commands:
        timed(arguments)  # warm-up: file-system caches, the law cache
    print(f"{'command':<40} {'wall (s)':>8} {'min':>6} {'max':>6} {'CPU (s)':>8}  exit")
    for arguments in commands:
        runs = [timed(arguments) for _ in range(args.repeat)]
        walls = [wall for wall, _, _ in runs]
        cpu = statistics.median(cpu for _, cpu, _ in runs)
        label = "ncstab " + " ".join(arguments)
        label = label if len(label) <= 40 else label[:37] + "..."
        print(f"{label:<40} {statistics.median(walls):>8.2f} {min(walls):>6.2f} {max(walls):>6.2f} {cpu:>8.2f}  "
              f"{runs[-1][2]}")


if __name__ == "__main__":
    main()
