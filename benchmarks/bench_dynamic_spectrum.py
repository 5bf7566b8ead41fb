"""Dynamic spectra per second: the batched function against a loop of scipy.linalg.eig.

Issue 16 target: >= 10x.  For each size n, ``ncstab.operators.dynamic_spectrum``
(one batched solve with M and one batched ``numpy.linalg.eigvals`` of the 2n x 2n
companion matrices, then sorting) is timed against a Python loop that does, per
case, what one would write without it: ``scipy.linalg.solve`` with M, the
companion matrix [[0, I], [-M^-1 K, -M^-1 C]] and ``scipy.linalg.eig(...,
right=False)``.  A second baseline loops over ``scipy.linalg.eigvals`` of
companion matrices built beforehand (eigenvalues only: the most favourable loop).
Both results are checked to agree (roots matched after sorting) to 1e-10
relative to the spectral radius.  This is a benchmark, not a test.

Sizes n = 2 (100,000 cases), 3, 4 and 6 (20,000 each); the rounds alternate
the batched call and the loops, so that a load on the machine hits both.

Run:  python benchmarks/bench_dynamic_spectrum.py [--scale 1.0] [--rounds 2]
(--scale 0.1 for a quick run)
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import numpy as np
import scipy.linalg

from ncstab.operators import dynamic_spectrum


def random_systems(rng: np.random.Generator, cases: int, n: int) -> tuple[np.ndarray, ...]:
    """SPD M (eigenvalues in [1, ~4]), random C and K with O(1) entries."""
    a = rng.normal(size=(cases, n, n))
    mass = a @ np.swapaxes(a, -1, -2) / n + np.eye(n)
    return mass, rng.normal(size=(cases, n, n)), rng.normal(size=(cases, n, n)) + 2 * np.eye(n)


def scipy_loop(mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    n = mass.shape[-1]
    out = np.empty((len(mass), 2 * n), dtype=complex)
    top = np.hstack([np.zeros((n, n)), np.eye(n)])
    for case in range(len(mass)):
        bottom = -scipy.linalg.solve(mass[case], np.hstack([stiffness[case], damping[case]]))
        out[case] = scipy.linalg.eig(np.vstack([top, bottom]), right=False)
    return out


def scipy_eigvals_loop(companions: np.ndarray) -> np.ndarray:
    return np.stack([scipy.linalg.eigvals(matrix) for matrix in companions])


def timed(
    function: Callable[..., np.ndarray], *args: np.ndarray, repeat: int
) -> tuple[float, np.ndarray]:
    best, out = np.inf, np.empty(0)
    for _ in range(repeat):
        start = time.perf_counter()
        out = function(*args)
        best = min(best, time.perf_counter() - start)
    return best, out


def sort_roots(roots: np.ndarray) -> np.ndarray:
    """Sort by real part then imaginary part, rounded, so the two results line up."""
    scale = np.abs(roots).max(axis=-1, keepdims=True)
    key = np.round(roots / scale, 8)
    order = np.lexsort((key.imag, key.real), axis=-1)
    return np.take_along_axis(roots, order, axis=-1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scale", type=float, default=1.0, help="fraction of the default case counts"
    )
    parser.add_argument(
        "--rounds", type=int, default=2, help="alternated rounds (batched, loops) per size"
    )
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    threads = os.environ.get("OMP_NUM_THREADS", "unset")
    print(
        f"threads: OMP_NUM_THREADS={threads}; each row one round: batched (best of 3), then the loops"
    )
    print(
        f"{'n':>3} {'cases':>8} {'ncstab s':>9} {'spectra/s':>10} {'eig loop s':>10} {'spectra/s':>10} "
        f"{'ratio':>6} {'eigvals loop s':>14} {'ratio':>6} {'max diff':>8}"
    )
    for n, cases in ((2, 100_000), (3, 20_000), (4, 20_000), (6, 20_000)):
        cases = max(1, int(cases * args.scale))
        mass, damping, stiffness = random_systems(rng, cases, n)
        companions = np.zeros((cases, 2 * n, 2 * n))
        companions[:, :n, n:] = np.eye(n)
        companions[:, n:, :] = -np.linalg.solve(mass, np.concatenate([stiffness, damping], -1))
        for _ in range(args.rounds):
            batched_time, batched = timed(dynamic_spectrum, mass, damping, stiffness, repeat=3)
            loop_time, looped = timed(scipy_loop, mass, damping, stiffness, repeat=1)
            eigvals_time, _ = timed(scipy_eigvals_loop, companions, repeat=1)
            difference = np.abs(sort_roots(batched) - sort_roots(looped)).max(axis=-1)
            error = float((difference / np.abs(looped).max(axis=-1)).max())
            assert error < 1e-10, f"n={n}: the batched and looped spectra differ by {error:.1e}"
            print(
                f"{n:>3} {cases:>8,} {batched_time:>9.3f} {cases / batched_time:>10.3e} {loop_time:>10.2f} "
                f"{cases / loop_time:>10.3e} {loop_time / batched_time:>5.1f}x {eigvals_time:>14.2f} "
                f"{eigvals_time / batched_time:>5.1f}x {error:>8.1e}"
            )


if __name__ == "__main__":
    main()
