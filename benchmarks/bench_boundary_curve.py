"""A boundary as a curve against the pixel grid: time and accuracy in one run (issue 40).

The problem: the limit point (det K = 0) of the McNamara diamond at the lateral
preload F2* = 0.75 (programme of ``studies/stability_diagram.toml``: F2* from
rest with F1 = 0, then Delta_1* driven to 0.6 with F2* held), along gamma in
[0.4, 0.5], before the curve's fold at gamma ~ 0.518.

* the curve: :func:`ncstab.boundary` (one located path, then continuation);
* the pixel grid: :func:`ncstab.follow` over ``--cells`` values of gamma, the
  limit point located on each path, the boundary between cells known by linear
  interpolation;
* the reference: the located events of a sweep at the curve's own gamma values.

Run:  python benchmarks/bench_boundary_curve.py [--cells 64] [--plane 64]

Prints the times, the error of each representation against the reference
(max over the curve's points of |F1* - F1*_ref|), and the ratios.  With
``--plane N`` it also times the N x N diagram over (gamma, F2*) of
``studies/stability_diagram.toml``, whose one row the curve replaces.  This is
a benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import ncstab

PROGRAMME = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.6}},
]
START, STOP, LATERAL = 0.4, 0.5, 0.75


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=64, help="gamma values of the pixel grid over [0.4, 0.5]")
    parser.add_argument("--plane", type=int, default=0, help="also time an N x N diagram over (gamma, F2*)")
    args = parser.parse_args(argv)
    common = {"secondary_contacts": "ignore"}
    # the grid's paths as machine code, the warm-up included (a one-case run would otherwise
    # run as plain Python on a new machine and leave the loop to compile in a timed run)
    compiled = {**common, "options": ncstab.PathOptions(backend="compiled")}
    ncstab.follow("diamond", ["mcnamara"], PROGRAMME, {"gamma": 0.4, "F2_lateral": LATERAL}, **compiled)  # compile, warm

    begin = time.perf_counter()
    curve = ncstab.boundary("diamond", ["mcnamara"], PROGRAMME, {"gamma": START, "F2_lateral": LATERAL},
                            event="limit_point", parameter="gamma", start=START, stop=STOP, **common)
    curve_time = time.perf_counter() - begin
    count = int(curve.n_points.values.ravel()[0])
    gamma = curve.boundary_gamma.values.ravel()[:count]
    F1 = curve.boundary_F.values.reshape(-1, 2)[:count, 0]

    begin = time.perf_counter()
    cells = np.linspace(START, STOP, args.cells)
    grid = ncstab.follow("diamond", ["mcnamara"], PROGRAMME, {"gamma": list(cells), "F2_lateral": LATERAL}, **compiled).to_dataset()
    grid_time = time.perf_counter() - begin
    grid_F1 = grid.limit_point_F.values.reshape(args.cells, 2)[:, 0]

    reference = ncstab.follow("diamond", ["mcnamara"], PROGRAMME, {"gamma": list(gamma), "F2_lateral": LATERAL}, **compiled).to_dataset()
    reference_F1 = reference.limit_point_F.values.reshape(count, 2)[:, 0]
    curve_error = float(np.max(np.abs(F1 - reference_F1)))
    grid_error = float(np.max(np.abs(np.interp(gamma, cells, grid_F1) - reference_F1)))

    print(f"curve: {count} points in {curve_time:.2f} s, max |F1* error| = {curve_error:.1e} ({curve.message.values.ravel()[0]})")
    print(f"pixel grid: {args.cells} cells in {grid_time:.2f} s, max |F1* error| between cells (linear) = {grid_error:.1e}")
    print(f"ratios: time grid/curve = {grid_time / curve_time:.2f}, error grid/curve = {grid_error / max(curve_error, 1e-16):.1e}")
    needed = args.cells * np.sqrt(grid_error / max(curve_error, 1e-16))  # linear interpolation: error ~ h^2
    print(f"cells a grid would need for the curve's accuracy (error ~ h^2): about {needed:,.0f}")
    if args.plane:
        begin = time.perf_counter()
        ncstab.follow("diamond", ["mcnamara"], PROGRAMME,
                      {"gamma": list(np.linspace(0.1, 2.0, args.plane)), "F2_lateral": list(np.linspace(0.0, 0.8, args.plane))},
                      **compiled)
        plane_time = time.perf_counter() - begin
        print(f"plane: {args.plane} x {args.plane} cells in {plane_time:.2f} s; time plane/curve = {plane_time / curve_time:.2f}")


if __name__ == "__main__":
    main()
