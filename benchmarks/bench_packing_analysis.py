"""Packing analysis: sparse indicators against a dense LAPACK baseline, and ``ncstab analyse`` at 10,000 grains.

Issue 38: ``ncstab analyse`` whole process <= 20 s at 10,000 grains (goal 2 s for
the analysis itself), and a comparison with what one would write without
ncstab: K dense, ``numpy.linalg.eigvalsh`` of K_sym (every eigenvalue: Hill's
is the first, the inertia counts follow) and ``numpy.linalg.slogdet(K)``.

* 1,000 grains (a 40 x 25 triangular lattice, bottom row fixed, 2,925 dofs,
  compressive normal forces and alternating tangential ones, Cundall-Strack,
  gamma = 0.5): ``analyse_packing`` (assembly, inertia by LDL^T, Hill, 6 modes,
  sign det K) against the dense baseline on the same K (its assembly not
  counted); both Hill eigenvalues must agree to 1e-8; the ratio is printed.
* 10,000 grains (100 x 100, bottom row fixed, 29,700 dofs): the analysis in
  this process, and ``ncstab analyse`` as a subprocess (start-up, reading,
  analysis, writing the 13 MB archive).  The dense baseline is not run there
  (29,700^2 doubles: 7 GB, and hours of eigvalsh).

Rounds alternate the two sides, so that a load on the machine hits both.

Run:  python benchmarks/bench_packing_analysis.py [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ncstab.laws.registry import law_definition
from ncstab.operators.packing_analysis import analyse_packing, packing_tangent
from ncstab.systems.packing import Packing, triangular_lattice, write_packing

LAW, GAMMA = "cundall_strack", 0.5


def loaded_lattice(rows: int, columns: int) -> Packing:
    packing = triangular_lattice(rows, columns, fix_bottom=True)
    rng = np.random.default_rng(1)
    return packing.with_forces(np.full(packing.n_contacts, 0.01), rng.choice([-0.002, 0.002], packing.n_contacts))


def dense_baseline(K) -> tuple[float, int, float]:
    """Hill's eigenvalue, the count of negative eigenvalues and sign det K, densely."""
    A = K.toarray()
    values = np.linalg.eigvalsh(0.5 * (A + A.T))
    return float(values[0]), int(np.sum(values < 0)), float(np.linalg.slogdet(A)[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    law = law_definition(LAW)
    small = loaded_lattice(40, 25)
    K = packing_tangent(small, law, GAMMA).K  # also derives the law once
    sparse_times, dense_times = [], []
    for _ in range(args.rounds):
        start = time.perf_counter()
        result = analyse_packing(small, law, GAMMA, modes=6)
        sparse_times.append(time.perf_counter() - start)
        start = time.perf_counter()
        hill, _, sign = dense_baseline(K)
        dense_times.append(time.perf_counter() - start)
    assert abs(result.hill - hill) <= 1e-8, (result.hill, hill)
    assert result.det_sign == sign
    best_sparse, best_dense = min(sparse_times), min(dense_times)
    print(f"1,000 grains ({K.shape[0]} dofs): analyse_packing {best_sparse:.3f} s (best of {args.rounds}: "
          f"{', '.join(f'{t:.3f}' for t in sparse_times)}), dense eigvalsh + slogdet {best_dense:.3f} s "
          f"({', '.join(f'{t:.3f}' for t in dense_times)}): ratio {best_dense / best_sparse:.1f}x; "
          f"hill {result.hill:.10g} = {hill:.10g}")

    big = loaded_lattice(100, 100)
    in_process, whole = [], []
    with tempfile.TemporaryDirectory() as directory:
        path = write_packing(big, Path(directory) / "big.nc")
        for _ in range(args.rounds):
            start = time.perf_counter()
            analyse_packing(big, law, GAMMA, modes=6)
            in_process.append(time.perf_counter() - start)
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "ncstab", "analyse", str(path), "--law", LAW, "--gamma", str(GAMMA),
                            "-o", str(Path(directory) / "out.nc")], check=True, stdout=subprocess.DEVNULL,
                           env={**os.environ})
            whole.append(time.perf_counter() - start)
    print(f"10,000 grains ({3 * 9900} dofs): analyse_packing {min(in_process):.2f} s "
          f"({', '.join(f'{t:.2f}' for t in in_process)}); ncstab analyse whole process {min(whole):.2f} s "
          f"({', '.join(f'{t:.2f}' for t in whole)}; bar 20 s)")


if __name__ == "__main__":
    main()
