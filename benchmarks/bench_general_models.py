"""Sweeps of general models: time per case of one batched sweep against a loop of single cases.

Three problems (issues 13, 15 and 16), each run in this one process:

* ``ring`` -- a ring of six grains (Cundall--Strack, secondary contacts
  ignored), grains 1 and 4 pushed in to D = 0.15 with the four others free,
  1,024 values of gamma in [0.2, 2]; the ring has 6 dofs (each grain's
  displacement along its radius) and 6 contacts.
* ``column`` -- Hencky's columns of n = 3, 4, 5, 6 links (one sweep each): a
  lateral imperfection force ``eps`` at the first joint, then P driven to 1.1
  times the first buckling load, 256 values of eps in [-1e-3, 1e-3] (0 among
  them, where the straight column bifurcates) per n: 1,024 cases with
  bifurcations located.
* ``damping`` -- the destabilization-paradox map: Ziegler's follower-loaded
  pendulum, P driven to 2.5 with ``stop_at = flutter_onset`` over a 64 x 64 log
  grid of joint dashpots (b1, b2) in [1e-4, 1]: total time.

For ``ring`` and ``column`` the baseline is the same engine called once per
case (``follow`` with scalar parameters) on an evenly spaced subset of
``--loop-cases`` cases, timed and scaled to per-case time; the batched sweep
must agree with those single cases (final u and F to 1e-10: batch
independence).  For ``damping`` the flutter loads along b1 = b2 are printed
beside the limit 41/28 of vanishing equal damping.

Run:  python benchmarks/bench_general_models.py [--only ring,column,damping] [--loop-cases 32]

This is a benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import ncstab
from ncstab.paths import PathOptions, SystemSpec
from ncstab.systems.closed_forms import ziegler_equal_damping_flutter_load, ziegler_flutter_load

RING_PROGRAMME = [{"hold": {"F2": 0.0, "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D1": 0.15, "D4": 0.15}}]
COLUMN_LINKS = (3, 4, 5, 6)


def column_programme(links: int) -> list[dict]:
    """The imperfection force F1 = eps applied first, then P driven to 1.1 P_1 (Hencky)."""
    others = {f"F{i}": 0.0 for i in range(2, links)}
    first_buckling = 4 * np.sin(np.pi / (2 * links)) ** 2
    return [
        {"hold": others, "drive": {"F1": "eps"}},
        {"hold": {**others, "F1": "current"}, "drive": {"P": 1.1 * first_buckling}},
    ]


def final_states(dataset) -> tuple[np.ndarray, np.ndarray]:
    """u and F at each case's last step (cases flattened)."""
    last = (dataset["n_steps"] - 1).clip(min=0)
    u = dataset["u"].isel(step=last).transpose(..., "dof").values
    force = dataset["F"].isel(step=last).transpose(..., "dof").values
    return u.reshape(-1, u.shape[-1]), force.reshape(-1, force.shape[-1])


def timed(function):
    start = time.perf_counter()
    value = function()
    return value, time.perf_counter() - start


def compare_sweep(name: str, run_one, values: np.ndarray, run_sweep, loop_cases: int) -> None:
    """Time the batched sweep over ``values`` and a loop over a subset; check they agree."""
    run_one(values[0])  # warm: symbolic derivation and compilation are cached per process
    sweep, sweep_time = timed(lambda: run_sweep(values))
    picks = np.unique(np.linspace(0, values.size - 1, loop_cases).round().astype(int))
    singles, loop_time = timed(lambda: [run_one(values[k]) for k in picks])
    u_sweep, f_sweep = final_states(sweep)
    worst = 0.0
    for k, single in zip(picks, singles):
        u_one, f_one = final_states(single)
        worst = max(worst, float(np.max(np.abs(u_one[0] - u_sweep[k]))), float(np.max(np.abs(f_one[0] - f_sweep[k]))))
    per_case_sweep = sweep_time / values.size
    per_case_loop = loop_time / picks.size
    print(
        f"{name:>10}: {values.size} cases, sweep {sweep_time:7.2f} s ({1e3 * per_case_sweep:7.2f} ms/case); "
        f"loop of single cases {1e3 * per_case_loop:7.2f} ms/case ({picks.size} timed); "
        f"ratio {per_case_loop / per_case_sweep:5.1f}x; largest |single - swept| {worst:.1e}"
    )


def ring(loop_cases: int) -> None:
    spec = SystemSpec("ring", grains=6, secondary_contacts="ignore")
    options = PathOptions(backend="compiled")  # the machine code in the warm-up and the timed runs

    def run_sweep(values):
        return ncstab.follow(spec, ["cundall_strack"], RING_PROGRAMME, {"gamma": list(values)}, options).to_dataset()

    def run_one(value):
        return ncstab.follow(spec, ["cundall_strack"], RING_PROGRAMME, {"gamma": float(value)}, options).to_dataset()

    compare_sweep("ring n=6", run_one, np.linspace(0.2, 2.0, 1024), run_sweep, loop_cases)


def column(loop_cases: int) -> None:
    eps = np.linspace(-1e-3, 1e-3, 255)
    eps = np.sort(np.append(eps, 0.0))  # 256 values, the perfect column among them
    for links in COLUMN_LINKS:
        spec = SystemSpec("column", links=links)
        programme = column_programme(links)

        def run_sweep(values, spec=spec, programme=programme):
            return ncstab.follow(spec, None, programme, {"eps": list(values)}).to_dataset()

        def run_one(value, spec=spec, programme=programme):
            return ncstab.follow(spec, None, programme, {"eps": float(value)}).to_dataset()

        compare_sweep(f"column n={links}", run_one, eps, run_sweep, max(2, loop_cases // len(COLUMN_LINKS)))
        found = run_one(0.0)
        load = float(found["bifurcation_load"].squeeze()) if "bifurcation_load" in found else float("nan")
        print(f"{'':>10}  perfect column: bifurcation at P = {load:.12f}, Hencky 4 sin^2(pi/{2 * links}) = "
              f"{4 * np.sin(np.pi / (2 * links)) ** 2:.12f}")


def damping() -> None:
    spec = SystemSpec("ziegler", load="follower")
    values = list(np.logspace(-4, 0, 64))
    programme = [{"drive": {"P": 2.5}, "stop_at": ["flutter_onset"]}]
    options = PathOptions(max_step=0.1, backend="compiled")
    ncstab.follow(spec, None, programme, {"b1": 1e-2, "b2": 1e-2}, options)  # warm
    path, total = timed(lambda: ncstab.follow(spec, None, programme, {"b1": values, "b2": values}, options))
    loads = path.to_dataset()["flutter_onset_load"].squeeze()
    diagonal = np.array([float(loads.isel(b1=k, b2=k)) for k in range(len(values))])
    print(
        f"   damping: 64 x 64 = 4,096 cases in {total:.2f} s ({1e3 * total / 4096:.2f} ms/case); "
        f"flutter load from {float(loads.min()):.4f} to {float(loads.max()):.4f}; "
        f"along b1 = b2: {diagonal[0]:.9f} at b = 1e-4 (closed form 41/28 + b^2/2 = "
        f"{float(ziegler_equal_damping_flutter_load(1e-4)):.9f}), "
        f"undamped {ziegler_flutter_load():.6f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", default="ring,column,damping")
    parser.add_argument("--loop-cases", type=int, default=32)
    args = parser.parse_args()
    chosen = set(args.only.split(","))
    if "ring" in chosen:
        ring(args.loop_cases)
    if "column" in chosen:
        column(args.loop_cases)
    if "damping" in chosen:
        damping()


if __name__ == "__main__":
    main()
