"""A study with its own options against a tight reference run of the same study, same process.

For each study file: the study is run as written, then again with reference
options (``max_step`` 0.01, ``sample_step`` unset: every step stored and
checked, rtol 1e-12, atol 1e-14; see the flags), and the two are compared
case by case:

* statuses (each differing case printed with its parameters and messages);
* for each event, how many cases found it in each run, the cases where one
  run found it and the other did not, and the largest difference of its
  arclength ``s`` and displacements ``u`` where both found it;
* the end states' ``u`` and ``F``.

This comparison found the defects fixed on 2026-12-02 (CHANGELOG: a root a
stored state lands on, contacts chattering at a corner, a ``no_tension``
contact pulled by a force).  A measurement, not a test: it asserts
nothing and prints a report.  The reference runs every case with small
steps: for a large sweep it takes minutes, and memory in proportion to its
stored states.

Run:  python benchmarks/check_against_reference.py STUDY.toml [STUDY.toml ...] [--max-step 0.01]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from ncstab.paths.programme import EVENTS
from ncstab.studies import load_study, run_study


def _where(dataset, dims, index) -> str:
    """The swept values of one case, in words."""
    parts = []
    for dim, k in zip(dims, index):
        value = dataset[dim].values[k]
        parts.append(f"{dim}={value}" if dataset[dim].dtype.kind in "OUS" else f"{dim}={float(value):.6g}")
    return ", ".join(parts)


def _end(dataset, name: str) -> np.ndarray:
    """``name`` at each case's last stored state."""
    steps = dataset["n_steps"].values
    values = dataset[name].values
    last = np.maximum(steps - 1, 0).reshape(steps.shape + (1,) * (values.ndim - steps.ndim))
    return np.take_along_axis(values, last, axis=steps.ndim)


def compare(path: Path, reference: dict, shown: int) -> None:
    """Run ``path`` as written and with ``reference`` options; print how they differ."""
    study = load_study(path)
    start = time.perf_counter()
    run = run_study(study)
    seconds = time.perf_counter() - start
    start = time.perf_counter()
    tight = run_study(dataclasses.replace(study, options=dataclasses.replace(study.options, **reference)))
    print(f"== {path}: {run['status'].size} cases; as written {seconds:.2f} s, reference "
          f"{time.perf_counter() - start:.2f} s")
    status, tight_status = run["status"].values, tight["status"].values
    dims = run["status"].dims
    differ = np.argwhere(status != tight_status)
    print(f"  statuses: {len(differ)} differ")
    for index in differ[:shown]:
        index = tuple(index)
        print(f"    {_where(run, dims, index)}: {status[index]} ({run['message'].values[index][:80]}) | "
              f"reference {tight_status[index]} ({tight['message'].values[index][:80]})")
    for event in EVENTS:
        key = f"{event}_s"
        if key not in run or key not in tight:
            continue
        s, tight_s = run[key].values, tight[key].values
        found, tight_found = np.isfinite(s), np.isfinite(tight_s)
        line = f"  {event}: found {int(found.sum())}, reference {int(tight_found.sum())}"
        both = found & tight_found
        if both.any():
            u = np.abs(run[f"{event}_u"].values - tight[f"{event}_u"].values)[both]
            line += f"; where both: max |ds| {np.abs(s - tight_s)[both].max():.2e}, max |du| {np.nanmax(u):.2e}"
        mismatch = np.argwhere(found != tight_found)
        if len(mismatch):
            line += f"; found by one run only in {len(mismatch)} case(s)"
        print(line)
        for index in mismatch[:shown]:
            index = tuple(index)
            print(f"    {_where(run, dims, index)}: s {s[index]:.10g}, reference {tight_s[index]:.10g}")
    for name in ("u", "F"):
        gap = np.abs(_end(run, name) - _end(tight, name))
        print(f"  end {name}: max difference {np.nanmax(gap) if np.isfinite(gap).any() else float('nan'):.2e}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("studies", nargs="+", type=Path)
    parser.add_argument("--max-step", type=float, default=0.01, help="the reference's max_step")
    parser.add_argument("--rtol", type=float, default=1e-12)
    parser.add_argument("--atol", type=float, default=1e-14)
    parser.add_argument("--max-steps", type=int, default=None, help="the reference's max_steps (the study's if unset)")
    parser.add_argument("--shown", type=int, default=5, help="differing cases printed per item")
    args = parser.parse_args()
    reference = {"max_step": args.max_step, "sample_step": None, "rtol": args.rtol, "atol": args.atol}
    if args.max_steps is not None:
        reference["max_steps"] = args.max_steps
    for path in args.studies:
        compare(path, reference, args.shown)


if __name__ == "__main__":
    main()
