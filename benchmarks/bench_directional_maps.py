"""Directional second-order work maps: (state, direction) evaluations per second.

Issue 6 target: >= 1e8 evaluations per second per core.
``ncstab.operators.directional_second_order_work`` (K11 c^2 + (K12 + K21) c s
+ K22 s^2 as one (states, 3) x (3, directions) product) is compared, in the
same run, with the quadratic form e(theta) . K e(theta) evaluated directly by
an optimised einsum over the same (state, direction) grid.  Both results are
checked to agree to 1e-12.  This is a benchmark, not a test.

Run:  python benchmarks/bench_directional_maps.py [--states 200000] [--directions 360]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from ncstab.operators.directional_work import directional_second_order_work


def direct(stiffness: np.ndarray, theta: np.ndarray) -> np.ndarray:
    e = np.stack([np.cos(theta), np.sin(theta)], -1)
    return np.einsum("ti,sij,tj->st", e, stiffness, e, optimize=True)


def timed(function, *args, repeat: int = 3) -> tuple[float, np.ndarray]:
    best, out = np.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        out = function(*args)
        best = min(best, time.perf_counter() - start)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=200_000)
    parser.add_argument("--directions", type=int, default=360)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    stiffness = rng.normal(size=(args.states, 2, 2))
    theta = np.linspace(0, np.pi, args.directions, endpoint=False)
    evaluations = args.states * args.directions
    closed_time, closed = timed(directional_second_order_work, stiffness, theta)
    direct_time, reference = timed(direct, stiffness, theta)
    error = float(np.abs(closed - reference).max())
    print(f"(state, direction) pairs        {evaluations:,}  (threads: OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')})")
    print(f"ncstab (basis product)          {closed_time:8.3f} s  {evaluations / closed_time:10.3e} evaluations/s")
    print(f"direct e.K e (einsum)            {direct_time:8.3f} s  {evaluations / direct_time:10.3e} evaluations/s")
    print(f"ratio einsum / ncstab            {direct_time / closed_time:8.1f} x    max difference {error:.1e}")


if __name__ == "__main__":
    main()
