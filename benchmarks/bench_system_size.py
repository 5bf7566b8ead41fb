"""Cost of one path against the number of dofs n, for rings and columns assembled from elements.

Two problems, each followed by the sparse engine (:mod:`ncstab.paths.assembled_path`) for
n = 4 ... 10,000 dofs:

* ``ring`` -- a ring of n grains (McNamara, gamma = 0.5, secondary contacts ignored), grains 1
  and n/2 + 1 pushed in to D = 0.15, every other grain force-free;
* ``column`` -- Hencky's column of n + 1 links, P driven to 1.2 P1 with ``at_bifurcation =
  "switch"``: the straight path, P1 located (printed: its relative error against
  4 sin^2(pi / 2(n + 1))), then the buckled branch (printed: the largest deflection's relative
  error against Euler's elastica at the same P / P_cr, O((pi / n)^2)).

For each n: wall time of ``follow`` (in process, the law already derived), stored states, time
per state.  The baseline, in the same run, is the same engine with dense linear algebra
(``CaseRun.dense``: numpy's LU and eigensolvers on n x n arrays) up to ``--dense-limit`` dofs;
the table prints the ratio.  The exponent p of time ~ n^p is fitted by least squares on
log-log over n >= 100.  ``--plot FILE`` draws time per state against n (docs/models.md).

Run:  python benchmarks/bench_system_size.py [--only ring,column] [--max-n 10000] [--plot docs/figures/system_size_cost.png]

This is a benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ncstab.paths import assembled_engine
from ncstab.paths.api import follow
from ncstab.systems.assembled_builders import assembled_column, assembled_ring
from ncstab.systems.closed_forms import elastica_deflection

SIZES = (4, 8, 16, 32, 64, 128, 256, 512, 1000, 2000, 5000, 10000)


def ring_run(n: int) -> tuple[float, int, str]:
    """One ring path of n grains: (seconds, stored states, note)."""
    bottom = n // 2 + 1
    hold = {f"F{k}": 0.0 for k in range(2, n + 1) if k != bottom}
    programme = [{"hold": hold, "drive": {"D1": 0.15, f"D{bottom}": 0.15}}]
    start = time.perf_counter()
    result = follow(assembled_ring(n), ["mcnamara"], programme, {"gamma": 0.5}, secondary_contacts="ignore")
    seconds = time.perf_counter() - start
    outcome = result.results[0].outcomes[0]
    return seconds, len(outcome.points), outcome.status


def column_run(n: int) -> tuple[float, int, str]:
    """One column path with n dofs (n + 1 links): (seconds, stored states, P1's relative error)."""
    links = n + 1
    critical = 4 * np.sin(np.pi / (2 * links)) ** 2
    programme = [{"drive": {"P": 1.2 * critical}, "at_bifurcation": "switch"}]
    start = time.perf_counter()
    result = follow(assembled_column(links), None, programme)
    seconds = time.perf_counter() - start
    outcome = result.results[0].outcomes[0]
    found = outcome.events.get("bifurcation")
    error = abs(found["point"].load / critical - 1) if found else float("nan")
    note = f"{outcome.status}, P1 to {error:.1e}"
    last = outcome.points[-1]
    if outcome.status == "finished":  # the buckled shape against Euler's elastica (O((pi / n)^2) apart)
        deflection = np.abs(last.u).max() / links
        note += f", elastica to {abs(deflection / elastica_deflection(last.load / (np.pi / links) ** 2) - 1):.1e}"
    return seconds, len(outcome.points), note


def timed(problem, n: int, dense: bool) -> tuple[float, int, str]:
    """``problem(n)`` with the engine's linear algebra forced dense or left to its size rule."""
    original = assembled_engine.CaseRun.__init__

    def init(self, *args, **kwargs):
        original(self, *args, **kwargs)
        self.dense = dense

    assembled_engine.CaseRun.__init__ = init if dense else original
    try:
        return problem(n)
    finally:
        assembled_engine.CaseRun.__init__ = original


def exponent(sizes: list[int], seconds: list[float]) -> float:
    """p of seconds ~ n^p, least squares on log-log over n >= 100."""
    keep = [(n, t) for n, t in zip(sizes, seconds) if n >= 100]
    if len(keep) < 2:
        return float("nan")
    x, y = np.log([n for n, _ in keep]), np.log([t for _, t in keep])
    return float(np.polyfit(x, y, 1)[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="ring,column")
    parser.add_argument("--max-n", type=int, default=10000)
    parser.add_argument("--dense-limit", type=int, default=1000)
    parser.add_argument("--plot", default=None)
    args = parser.parse_args()
    problems = {"ring": ring_run, "column": column_run}
    curves = {}
    ring_run(6), column_run(5)  # the laws' responses derived once, outside the timings
    for name in args.only.split(","):
        problem = problems[name]
        print(f"\n{name}: n dofs, stored states, sparse s, per state ms, dense s, dense / sparse, note")
        sizes, times, per_state = [], [], []
        for n in (s for s in SIZES if s <= args.max_n):
            seconds, states, note = timed(problem, n, dense=False)
            dense_text = ""
            if n <= args.dense_limit:
                dense_seconds, _, _ = timed(problem, n, dense=True)
                dense_text = f"{dense_seconds:9.3f} {dense_seconds / seconds:8.2f}x"
            else:
                dense_text = f"{'-':>9} {'-':>9}"
            print(f"{n:6d} {states:6d} {seconds:9.3f} {1e3 * seconds / states:9.3f} {dense_text}  {note}")
            sizes.append(n), times.append(seconds), per_state.append(seconds / states)
        print(f"{name}: time ~ n^{exponent(sizes, times):.2f}, time per state ~ n^{exponent(sizes, per_state):.2f} "
              "(n >= 100)")
        curves[name] = (sizes, per_state)
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure, axes = plt.subplots(figsize=(6.4, 4.4), layout="constrained")
        for name, (sizes, per_state) in curves.items():
            axes.loglog(sizes, 1e3 * np.array(per_state), "o-", label=f"{name} (p = {exponent(sizes, per_state):.2f})")
        reference = np.array([100, 10000])
        axes.loglog(reference, 1e3 * curves[next(iter(curves))][1][-1] * reference / reference[-1], "k--",
                    lw=0.8, label="slope 1")
        axes.set_xlabel("number of dofs n")
        axes.set_ylabel("wall time per stored state (ms)")
        axes.set_title("Sparse engine: cost of a path against n (2 cores)")
        axes.legend()
        figure.savefig(args.plot, dpi=150)
        print(f"figure {args.plot}")


if __name__ == "__main__":
    main()
