"""Whole-process cost per case of ``ncstab run`` against a loop of solve_ivp, same run.

Issue 19 asks for the marginal cost per case of the command (engine, archive and
figures included) against the one-``solve_ivp``-per-case script of
``bench_sweep_cundall_strack.py`` on its 4,096-case sweep: the Cundall--Strack
diamond, F2* held at 0, Delta_1* driven to 0.2, 64 gamma in [0.1, 2] x 64
alpha0 in [0.3, 1.2].  The marginal cost is the difference of the wall times of
``ncstab run`` on 64 x 64 and on 8 x 8 cases, divided by the difference of
their case counts: start-up, imports and the drawing of the figures' axes are
paid once and cancel.  The fixed cost (about 10 s) is large against the
marginal one (a few tenths of a second for 4,096 cases), so on a busy machine
take a larger study (``--big 128``) and several repeats.  The loop runs 256 of the cases, in the same run.

Each command runs with the study's engine options (the compiled stepper,
the only one; ``sample_step = 1``: every step stored once), the figures of
the study (a parameter-plane field of the end state, and the
load--displacement field) and the default archive.

With ``--in-process`` each command is ``ncstab.cli.main`` called in this
process after a warm-up run: the same work (run, archive, figures), without
the start-up of a new interpreter, whose jitter (about 0.5 s on this machine)
is larger than the marginal cost of 4,000 cases.

Run:  python benchmarks/bench_whole_run.py [--repeat 3] [--big 64] [--in-process]

A benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).parent))
from bench_sweep_cundall_strack import TARGET, baseline_rhs  # noqa: E402

STUDY = """\
[study]
name = "whole_run_{side}"
description = "Cundall-Strack, F2* = 0 held, D1* driven to 0.2 ({side} x {side} cases)"

[system]
secondary_contacts = "ignore"

[laws]
names = ["cundall_strack"]

[parameters]
gamma = {{ start = 0.1, stop = 2.0, num = {side} }}
alpha0 = {{ start = 0.3, stop = 1.2, num = {side} }}

[[loading]]
hold = {{ F2 = 0.0 }}
drive = {{ D1 = {target} }}

[options]
rtol = 1e-10
atol = 1e-12
max_step = 1.0
sample_step = 1.0
backend = "compiled"

[output]
figures = ["load_displacement", "load_rotation"]
"""


def run_command(directory: Path, side: int, in_process: bool = False) -> float:
    """Wall time of ``ncstab run`` on a side x side study (archive and figures written);
    ``in_process``: ``ncstab.cli.main`` called in this process (imports and compiled
    loops loaded once, by the warm-up run), not a new process."""
    study = directory / f"whole_run_{side}.toml"
    study.write_text(STUDY.format(side=side, target=TARGET))
    output = directory / f"whole_run_{side}.nc"
    if in_process:
        from ncstab.cli import main as ncstab_main

        start = time.perf_counter()
        code = ncstab_main(["run", str(study), "-o", str(output), "--overwrite", "--quiet"])
        elapsed = time.perf_counter() - start
        if code != 0:
            raise SystemExit(f"ncstab run failed ({code})")
        return elapsed
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "ncstab", "run", str(study), "-o", str(output), "--overwrite"],
        capture_output=True, text=True,
    )
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"ncstab run failed ({done.returncode}): {done.stderr.strip()}")
    return elapsed


def loop_per_case(cases: int) -> float:
    """Wall time per case of one solve_ivp (DOP853, rtol 1e-10, atol 1e-12) per case."""
    rng = np.random.default_rng(0)
    gamma = rng.uniform(0.1, 2.0, cases)
    alpha0 = rng.uniform(0.3, 1.2, cases)
    start = time.perf_counter()
    for g, a in zip(gamma, alpha0):
        solve_ivp(baseline_rhs(g, a), (0.0, TARGET), [0.0, 0.0], method="DOP853", rtol=1e-10, atol=1e-12)
    return (time.perf_counter() - start) / cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--loop-cases", type=int, default=256)
    parser.add_argument("--big", type=int, default=64, help="cases per side of the large study")
    parser.add_argument("--small", type=int, default=8, help="cases per side of the small study")
    parser.add_argument("--in-process", action="store_true",
                        help="call ncstab.cli.main in this process: the command's work without a new "
                             "interpreter's start-up, whose jitter (about 0.5 s) hides the marginal cost")
    args = parser.parse_args()
    big, small = args.big, args.small
    with tempfile.TemporaryDirectory() as name:
        directory = Path(name)
        run_command(directory, small, args.in_process)  # warm: compilation caches, file system
        marginal, loop = [], []
        for _ in range(args.repeat):
            t_big = run_command(directory, big, args.in_process)
            t_small = run_command(directory, small, args.in_process)
            marginal.append((t_big - t_small) / (big * big - small * small))
            loop.append(loop_per_case(args.loop_cases))
            print(
                f"ncstab run: {big * big} cases {t_big:.2f} s, {small * small} cases {t_small:.2f} s; "
                f"marginal {1e3 * marginal[-1]:.3f} ms/case; loop {1e3 * loop[-1]:.3f} ms/case; "
                f"ratio {loop[-1] / marginal[-1]:.1f}x"
            )
    m, b = statistics.median(marginal), statistics.median(loop)
    where = "in this process" if args.in_process else "new processes"
    print(f"ncstab run ({where}): marginal cost of ncstab run {1e3 * m:.3f} ms/case (median of "
          f"{args.repeat}); solve_ivp loop {1e3 * b:.3f} ms/case; ratio {b / m:.1f}x")
    if args.repeat >= 4:
        # The marginal cost is a difference of two whole-process times of about 8 s each: where
        # the spread of the estimates is as large as their median, it is below what this
        # machine resolves, and the ratio is only a bound.
        q1, _, q3 = statistics.quantiles(marginal, n=4)
        print(f"spread of the marginal cost: quartiles {1e3 * q1:.3f} to {1e3 * q3:.3f} ms/case; ratio at the upper "
              f"quartile {b / q3:.1f}x" + (" (resolved)" if q3 - q1 < abs(m) else " (not resolved: the spread "
              "exceeds the median; take a larger --big, up to 90 for one in-memory chunk, or more repeats)"))


if __name__ == "__main__":
    main()
