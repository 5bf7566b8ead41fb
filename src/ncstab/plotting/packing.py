"""Figures of a packing analysis (the archive of ``ncstab analyse``), readable at 10,000 grains.

One collection per layer, never one artist per grain or contact (matplotlib's
``LineCollection``, ``EllipseCollection``, ``PolyCollection``; a quiver):

* :func:`plot_packing_forces` -- the grains, and the contacts as segments
  between centres, width and colour by the normal force N;
* :func:`plot_critical_mode` -- grains coloured by their participation in a
  mode, and the mode's translations as arrows (the largest grain's arrow one
  grain diameter long);
* :func:`plot_loops` -- the grain loops filled by their own Hill eigenvalue
  (:mod:`ncstab.systems.mesostructures`), diverging about 0;
* :func:`draw_packing_figures` -- the three, as PNG files.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["draw_packing_figures", "plot_critical_mode", "plot_loops", "plot_packing_forces"]


def _axes(figure, dataset):
    import matplotlib.pyplot as plt

    if figure is None:
        span = float(np.ptp(dataset.x.values) + 1), float(np.ptp(dataset.y.values) + 1)
        width = 8.0
        figure = plt.figure(figsize=(width, max(3.0, min(12.0, width * span[1] / max(span[0], 1e-9)))))
    ax = figure.add_subplot(1, 1, 1)
    ax.set_aspect("equal")
    ax.set_xlabel("x / d")
    ax.set_ylabel("y / d")
    x, y, r = dataset.x.values, dataset.y.values, dataset.radius.values
    ax.set_xlim(float((x - r).min()) - 0.5, float((x + r).max()) + 0.5)
    ax.set_ylim(float((y - r).min()) - 0.5, float((y + r).max()) + 0.5)
    return figure, ax


def _grains(ax, dataset, colours=None, cmap="viridis", **kwargs):
    from matplotlib.collections import EllipseCollection

    x, y, r = dataset.x.values, dataset.y.values, dataset.radius.values
    grains = EllipseCollection(2 * r, 2 * r, np.zeros_like(r), units="xy", offsets=np.column_stack([x, y]),
                               offset_transform=ax.transData, linewidths=0.2, **kwargs)
    if colours is not None:
        grains.set_array(colours)
        grains.set_cmap(cmap)
    ax.add_collection(grains)
    return grains


def plot_packing_forces(dataset, figure=None):
    """The packing, contacts drawn by their normal force (width and colour)."""
    from matplotlib.collections import LineCollection

    figure, ax = _axes(figure, dataset)
    fixed = dataset.fixed.values.astype(bool)
    _grains(ax, dataset, facecolors=np.where(fixed[:, None], [[0.6, 0.6, 0.6, 1]], [[0.93, 0.93, 0.93, 1]]),
            edgecolors="0.5")
    a, b = dataset.grain_a.values, dataset.grain_b.values
    x, y = dataset.x.values, dataset.y.values
    N = dataset.normal_force.values
    scale = float(np.max(np.abs(N))) if N.size and np.max(np.abs(N)) > 0 else 1.0
    lines = LineCollection(np.stack([np.column_stack([x[a], y[a]]), np.column_stack([x[b], y[b]])], axis=1),
                           linewidths=0.3 + 3.0 * np.abs(N) / scale, cmap="plasma")
    lines.set_array(N)
    ax.add_collection(lines)
    figure.colorbar(lines, ax=ax, label="normal force N / (k_n d)")
    ax.set_title(f"{dataset.attrs.get('packing', '')}: contacts by normal force")
    return figure


def plot_critical_mode(dataset, mode: int = 0, figure=None):
    """Mode ``mode`` of K_sym: participation per grain as colour, translations as arrows."""
    figure, ax = _axes(figure, dataset)
    participation = dataset.participation.values[mode]
    grains = _grains(ax, dataset, colours=participation, cmap="magma_r", edgecolors="none")
    figure.colorbar(grains, ax=ax, label="participation")
    vector = dataset["mode"].values[mode]
    length = np.hypot(vector[:, 0], vector[:, 1])
    big = length.max() if length.max() > 0 else 1.0
    keep = length > 0.05 * big  # arrows where the mode moves the grain (an arrow per grain is unreadable)
    ax.quiver(dataset.x.values[keep], dataset.y.values[keep], vector[keep, 0] / big, vector[keep, 1] / big,
              angles="xy", scale_units="xy", scale=1.0, width=0.002, color="tab:blue")
    value = float(dataset.mode_eigenvalue.values[mode])
    ax.set_title(f"mode {mode}: eigenvalue of K_sym {value:.4g} (law {dataset.attrs.get('law', '')})")
    return figure


def plot_loops(packing, loops, hill, figure=None):
    """The grain loops filled by their Hill eigenvalue as rings (diverging colours about 0)."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import TwoSlopeNorm

    if figure is None:
        figure = plt.figure(figsize=(8, 8 * max(np.ptp(packing.y) + 1, 1) / max(np.ptp(packing.x) + 1, 1)))
    ax = figure.add_subplot(1, 1, 1)
    ax.set_aspect("equal")
    padded = loops.padded()
    filled = np.where(padded >= 0, padded, padded[:, :1])  # a shorter loop repeats its first grain
    polygons = np.stack([packing.x[filled], packing.y[filled]], axis=2)
    low, high = float(np.nanmin(hill)), float(np.nanmax(hill))
    norm = TwoSlopeNorm(0.0, min(low, -1e-12), max(high, 1e-12))
    collection = PolyCollection(polygons, cmap="RdBu", norm=norm, edgecolors="0.3", linewidths=0.2)
    collection.set_array(hill)
    ax.add_collection(collection)
    ax.set_xlim(packing.x.min() - 1, packing.x.max() + 1)
    ax.set_ylim(packing.y.min() - 1, packing.y.max() + 1)
    figure.colorbar(collection, ax=ax, label="Hill eigenvalue of the loop as a ring")
    ax.set_title(f"{loops.count} grain loops; {int(np.sum(hill < 0))} have lost Hill's condition")
    ax.set_xlabel("x / d")
    ax.set_ylabel("y / d")
    return figure


def draw_packing_figures(archive, directory, stem: str | None = None, loops: bool = True) -> list[Path]:
    """Draw the figures of an analysis archive (a path or Dataset) as PNGs in ``directory``; their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import xarray as xr

    dataset = xr.load_dataset(archive) if not isinstance(archive, xr.Dataset) else archive
    stem = stem or (Path(archive).stem if not isinstance(archive, xr.Dataset) else "packing")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    figures = [("forces", plot_packing_forces(dataset))]
    if dataset.sizes.get("mode", 0):
        figures.append(("mode", plot_critical_mode(dataset)))
    if loops:
        from ncstab.laws.registry import law_definition
        from ncstab.operators.packing_analysis import packing_tangent
        from ncstab.systems.mesostructures import grain_loops, loop_stiffness
        from ncstab.systems.packing import validate

        packing = validate({name: dataset[name].values for name in
                            ("x", "y", "radius", "fixed", "grain_a", "grain_b", "normal_force", "tangential_force")},
                           dataset.attrs.get("packing", "<archive>"))
        found = grain_loops(packing)
        if found.count:
            tangent = packing_tangent(packing, law_definition(dataset.attrs["law"]), float(dataset.attrs["gamma"]))
            figures.append(("loops", plot_loops(packing, found, loop_stiffness(packing, found, tangent.blocks))))
    paths = []
    for kind, figure in figures:
        path = directory / f"{stem}_{kind}.png"
        figure.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(figure)
        paths.append(path)
    return paths
