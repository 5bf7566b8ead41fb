"""Drawing cost of the figures of large sweeps (issue 19): 4,096 and 65,536 cases.

The archives: the programme of ``studies/stability_diagram.toml`` (lateral
preload F2*, then Delta1* driven to 0.6 with F2 held), Cundall--Strack, on
cheap options (``max_step = sample_step = 0.3``: a handful of stored states per case, events
still located to ``event_tol``), swept

* in 2-D: gamma x F2_lateral on 64 x 64 (4,096 cases) and 256 x 256 (65,536):
  the path kinds draw parameter planes (and the stability diagram);
* in 1-D: F2_lateral over 4,096 and 65,536 values (gamma = 1): fans.

Each archive is written with ``write_dataset`` to a temporary directory, then
``draw_figures`` is timed on it opened lazily (``open_study_lazily``, the
arrays read when a figure needs them, as ``ncstab run`` does), for the
default kinds of a study (``load_displacement``, ``load_rotation``) and for
each path kind alone, at the default 200 dpi; and the whole command
``ncstab plot`` (a new process: imports, reading the archive, both default
figures) is timed once per archive.  The baseline, in the same run, is the
figure drawn the old way: one ``ax.plot`` per case and a legend placed with
``loc="best"`` (the curves figure forced on the sweep), for
``load_displacement`` on the 4,096-case archives only (minutes on 65,536).
Times are wall-clock; the machine's load average is printed with them.

Run:  python benchmarks/bench_plot_large_sweeps.py [--sides 64,256] [--repeat 3] [--no-baseline]

Prints the median of ``--repeat`` timings of each drawing and the ratio to
the baseline.  A benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from ncstab.plotting import draw_figures
from ncstab.plotting.curves import planar_curves_figure
from ncstab.studies import open_study_lazily, parse_study, run_study, write_dataset

STUDY = """\
[study]
name = "{name}"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["cundall_strack"]
[parameters]
gamma = {gamma}
F2_lateral = {{ start = 0.0, stop = 0.8, num = {lateral} }}
[[loading]]
hold = {{ F1 = 0.0 }}
drive = {{ F2 = "F2_lateral" }}
[[loading]]
hold = {{ F2 = "current" }}
drive = {{ D1 = 0.6 }}
[options]
max_step = 0.3
sample_step = 0.3
"""
KINDS = ("load_displacement", "load_rotation", "load_displacement_rotation", "stability")


def build(directory: Path, name: str, gamma: str, lateral: int) -> tuple[Path, float]:
    """Run the study and write its archive; (path, seconds of run_study)."""
    study = parse_study(STUDY.format(name=name, gamma=gamma, lateral=lateral))
    start = time.perf_counter()
    dataset = run_study(study)
    seconds = time.perf_counter() - start
    path = directory / f"{name}.nc"
    write_dataset(dataset, path)
    return path, seconds


def timed(function, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def old_figure(dataset, kind: str, target: Path) -> None:
    """The baseline: one ``ax.plot`` per case (the curves figure on the whole sweep), its
    legend placed with ``loc="best"`` among every curve, as before issue 19."""
    figure = planar_curves_figure(dataset, None, kind)
    legend = figure.legends[0] if figure.legends else figure.axes[0].get_legend()
    if legend is not None:
        texts = [text.get_text() for text in legend.texts]
        handles = legend.legend_handles
        legend.remove()
        figure.axes[0].legend(handles, texts, loc="best")
    figure.savefig(target, dpi=200)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sides", default="64,256", help="2-D sweeps of side x side cases (comma-separated)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--no-baseline", action="store_true",
                        help="skip the old one-curve-per-case figure (minutes on a loaded machine)")
    args = parser.parse_args(argv)
    sides = [int(s) for s in args.sides.split(",")]
    with tempfile.TemporaryDirectory(prefix="ncstab-bench-plot-") as scratch:
        directory = Path(scratch)
        archives = []
        for side in sides:
            n = side * side
            plane = build(directory, f"plane_{n}", f"{{ start = 0.1, stop = 2.0, num = {side} }}", side)
            fan = build(directory, f"fan_{n}", "1.0", n)
            archives += [("2-D", n, *plane), ("1-D", n, *fan)]
        out = directory / "figures"
        print(f"{'sweep':>5} {'cases':>7} {'figure':>28} {'seconds':>8} {'baseline':>9} {'ratio':>6}")
        for shape, n, path, run_seconds in archives:
            print(f"{shape:>5} {n:>7} {'(run_study)':>28} {run_seconds:8.2f}")
            with open_study_lazily(path) as dataset:
                default = timed(partial(draw_figures, dataset, out, kinds=KINDS[:2]), args.repeat)
                print(f"{shape:>5} {n:>7} {'default kinds (2 figures)':>28} {default:8.2f}")
                for kind in KINDS:
                    seconds = timed(partial(draw_figures, dataset, out, kinds=[kind]), args.repeat)
                    baseline = ratio = ""
                    if n <= 4096 and kind == "load_displacement" and not args.no_baseline:
                        base = timed(partial(old_figure, dataset, kind, out / "baseline.png"), 1)
                        baseline, ratio = f"{base:9.2f}", f"{base / seconds:6.1f}"
                    print(f"{shape:>5} {n:>7} {kind:>28} {seconds:8.2f} {baseline:>9} {ratio:>6}")
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "ncstab", "plot", str(path), "--directory", str(out)],
                           check=True, capture_output=True)
            command = time.perf_counter() - start
            print(f"{shape:>5} {n:>7} {'ncstab plot (whole command)':>28} {command:8.2f}")
        print(f"load average: {' '.join(f'{v:.1f}' for v in os.getloadavg())} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
