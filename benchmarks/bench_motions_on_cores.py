"""Motions of a dynamic stage on one core against several processes, in one run.

Ziegler's pendulum (follower load, undamped) released from the straight state at N loads
from 1.8 to 2.4 (below and past flutter at 2.0858), 40 time units each: the motions alone
(:func:`ncstab.studies.motions_on_cores.study_motions`), first in order (workers = 1, the
baseline), then on ``--workers`` processes; the ratio and whether the motions are identical.

Run:  python benchmarks/bench_motions_on_cores.py [--cases 32] [--workers 2]

This is a benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from ncstab.studies import load_study
from ncstab.studies.chunked import chunk_path
from ncstab.studies.motions_on_cores import study_motions

STUDY = Path(__file__).resolve().parents[1] / "studies" / "ziegler_flutter_motion.toml"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--cases", type=int, default=32)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    loads = ", ".join(f"{p:.6g}" for p in np.linspace(1.8, 2.4, args.cases))
    text = STUDY.read_text().replace('drive = { P = 2.2 }', 'drive = { P = "P_end" }')
    text = text.replace("[output]", f"[parameters]\nP_end = [{loads}]\n\n[output]").replace("duration = 60.0", "duration = 40.0")
    path = Path("/tmp") / "bench_motions_on_cores.toml"
    path.write_text(text)
    study = load_study(path)
    followed = chunk_path(study, None, 0, args.cases)
    study_motions(study, followed, workers=1)  # compiled and warm
    start = time.perf_counter()
    alone = study_motions(study, followed, workers=1)
    serial = time.perf_counter() - start
    start = time.perf_counter()
    spread = study_motions(study, followed, workers=args.workers)
    parallel = time.perf_counter() - start
    same = all(np.array_equal(a.u, b.u, equal_nan=True) for a, b in zip(alone[0], spread[0]))
    print(f"{args.cases} motions: in order {serial:.2f} s, on {args.workers} processes {parallel:.2f} s "
          f"(ratio {serial / parallel:.2f}x, process start-up included); identical: {same}")


if __name__ == "__main__":
    main()
