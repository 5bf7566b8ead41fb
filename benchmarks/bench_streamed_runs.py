"""Whole runs of a stability-diagram study: in memory, streamed in chunks, on dask workers.

The study is ``studies/stability_diagram.toml`` (4 laws x 64 gamma x 64 F2* =
16,384 cases) or, with ``--side N --laws a,b``, the same programme over an
N x N grid for the given laws (``--side 256 --laws mcnamara``: the 65,536-case
sweep of issue 6).  Each mode runs in a fresh Python process (same machine, same
run) and is timed from the parsed study to the archive on disk:

- ``memory``: :func:`ncstab.studies.run_study` then :func:`write_dataset` (the
  whole Dataset in memory; the baseline);
- ``streamed``: :func:`ncstab.studies.run_study_chunked` in process (chunks
  appended to the archive as they finish);
- ``workers``: the same on a local dask cluster of ``--workers`` processes
  (cluster start-up included).

Printed per mode: wall time, ratio to ``memory``, peak resident memory of the
main process (``ru_maxrss``; for ``workers`` the largest worker's too), and
whether the archive is identical to the ``memory`` one
(``xarray.testing.assert_identical`` but for the ``created`` stamp).

Run:  python benchmarks/bench_streamed_runs.py [--side 64] [--laws ...] [--workers 2] [--repeat 3]
      [--modes memory,streamed,workers]

With ``--repeat N`` the modes run N times, interleaved, and each mode's median
run is reported (wall times on a shared machine vary by 10-20 %).

A benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies" / "stability_diagram.toml"


def study_text(side: int | None, laws: list[str] | None) -> str:
    text = STUDY.read_text()
    if side is not None:
        text = re.sub(r"num = 64\b", f"num = {side}", text)  # the gamma and F2_lateral ranges
    if laws:
        text = re.sub(r"names = \[[^\]]*\]", f"names = {json.dumps(laws)}", text)
    return text


def run_mode(mode: str, text_file: str, output: str, workers: int) -> None:
    """One mode, in this process; prints a JSON line of measurements."""
    import resource

    from ncstab.studies import load_study, run_study, run_study_chunked, write_dataset

    study = load_study(text_file)
    start = time.perf_counter()
    worker_rss = None
    if mode == "memory":
        write_dataset(run_study(study), output)
    elif mode == "streamed":
        run_study_chunked(study, output)
    elif mode == "workers":
        import distributed

        peaks: list[float] = []
        original = distributed.Client.close

        def close(self, *args, **kwargs):  # read the workers' peak RSS before the cluster goes
            try:
                peaks.extend(self.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss).values())
            except Exception:  # noqa: BLE001 - a measurement, never a failure
                pass
            return original(self, *args, **kwargs)

        distributed.Client.close = close
        run_study_chunked(study, output, workers=workers)
        worker_rss = max(peaks) / 2**10 if peaks else None
    else:
        raise ValueError(f"unknown mode {mode!r}")
    elapsed = time.perf_counter() - start
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**10
    print(json.dumps({"mode": mode, "seconds": elapsed, "rss_mib": rss, "worker_rss_mib": worker_rss}))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, help="grid points per parameter (default: the study's 64)")
    parser.add_argument("--laws", help="comma-separated laws (default: the study's four)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--modes", default="memory,streamed,workers")
    parser.add_argument("--repeat", type=int, default=1,
                        help="run the modes N times, interleaved, and report each mode's median time")
    parser.add_argument("--run-mode", nargs=3, metavar=("MODE", "STUDY", "OUTPUT"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.run_mode:
        run_mode(*args.run_mode, workers=args.workers)
        return
    import xarray as xr

    from ncstab.studies import open_study

    laws = args.laws.split(",") if args.laws else None
    with tempfile.TemporaryDirectory(prefix="ncstab-bench-") as scratch:
        text_file = Path(scratch) / "stability_diagram.toml"
        text_file.write_text(study_text(args.side, laws))
        runs: dict[str, list[dict]] = {mode: [] for mode in args.modes.split(",")}
        for _ in range(args.repeat):
            for mode in runs:
                output = Path(scratch) / f"{mode}.nc"
                line = subprocess.run(
                    [sys.executable, __file__, "--workers", str(args.workers), "--run-mode", mode, str(text_file),
                     str(output)],
                    check=True, capture_output=True, text=True,
                ).stdout.strip().splitlines()[-1]
                runs[mode].append(json.loads(line) | {"output": output})
        results = {}
        for mode, measured in runs.items():
            ordered = sorted(measured, key=lambda r: r["seconds"])
            results[mode] = ordered[len(ordered) // 2] | {"all": [round(r["seconds"], 1) for r in measured]}
        cases = None
        reference = open_study(results["memory"]["output"]) if "memory" in results else None
        if reference is not None:
            cases = reference["status"].size
            reference.attrs.pop("created")
        print(f"stability diagram runs: {cases or '?'} cases; {args.workers} workers; "
              f"{len(__import__('os').sched_getaffinity(0))} cores available")
        base = results.get("memory", {}).get("seconds")
        for mode, r in results.items():
            same = ""
            if reference is not None and mode != "memory":
                archive = open_study(r["output"])
                archive.attrs.pop("created")
                try:
                    xr.testing.assert_identical(archive, reference)
                    same = "archive identical"
                except AssertionError:
                    same = "ARCHIVE DIFFERS"
            ratio = f"{base / r['seconds']:.2f}x" if base else "-"
            workers = f", largest worker {r['worker_rss_mib']:,.0f} MiB" if r["worker_rss_mib"] else ""
            every = f" (runs: {', '.join(map(str, r['all']))} s)" if args.repeat > 1 else ""
            print(f"  {mode:9s} {r['seconds']:7.1f} s  {ratio:>6s}  peak RSS {r['rss_mib']:,.0f} MiB{workers}  {same}{every}")


if __name__ == "__main__":
    main()
