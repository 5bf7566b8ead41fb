"""The figure kinds, each a function ``(dataset, figure=None) -> Figure``.

The path kinds (load-rotation, load-displacement, 3-D, stability) choose what
to draw from the shape of the sweep (:func:`ncstab.plotting.sweep_shape.sweep_shape`):

* up to 12 cases: one curve per case, its events and the seed's closed form
  (:mod:`ncstab.plotting.curves`, :mod:`ncstab.plotting.curves_3d`,
  :mod:`ncstab.plotting.stability_curves`);
* more, over two swept parameters: a field over the parameter plane per law
  (:mod:`ncstab.plotting.parameter_plane`; the stability kind draws the
  stability diagram, :mod:`ncstab.plotting.diagrams`);
* more, over one swept parameter (or three and more): a fan of the paths with
  their envelope and a few labelled cases (:mod:`ncstab.plotting.fans`; the 3-D
  kind draws the load-displacement fan).

Figures are plain :class:`matplotlib.figure.Figure` objects, not pyplot
figures: nothing is registered globally, nothing needs closing, no window
ever opens.
"""

from __future__ import annotations

from collections.abc import Callable

import xarray as xr
from matplotlib.figure import Figure

from ncstab.plotting.boundaries import boundary_figure
from ncstab.plotting.curves import planar_curves_figure
from ncstab.plotting.curves_3d import curves_3d_figure
from ncstab.plotting.cycle_paths import cycle_paths_figure
from ncstab.plotting.cycles import cycle_force_drift_figure, cycle_work_figure
from ncstab.plotting.diagrams import stability_diagram_figure
from ncstab.plotting.fans import fan_figure
from ncstab.plotting.maps import (
    second_order_work_map_figure,
    second_order_work_polar_figure,
    state_map_figure,
)
from ncstab.plotting.parameter_plane import parameter_plane_figure
from ncstab.plotting.dynamics import damping_map_figure, frequencies_figure, root_locus_figure
from ncstab.plotting.motion import energies_figure, motion_figure, phase_portrait_figure
from ncstab.plotting.model_paths import is_seed_diamond, model_path_figure
from ncstab.plotting.stability_curves import stability_curves_figure
from ncstab.plotting.sweep_shape import sweep_shape

__all__ = [
    "FIGURE_KINDS",
    "plot_load_displacement",
    "plot_load_displacement_rotation",
    "plot_load_rotation",
    "plot_stability",
]


def _squeezed(dataset: xr.Dataset) -> xr.Dataset:
    """The Dataset without its swept dimensions of length 1 (kept as scalar coordinates)."""
    shape = sweep_shape(dataset)
    return dataset.squeeze([d for d in shape.dims if d != "law" and shape.sizes[d] == 1])


def plot_load_rotation(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Load-rotation response F1 against alpha (seed Figs. 3, 8, 9, 12, 14).

    Parameters
    ----------
    dataset
        A path Dataset (:meth:`ncstab.paths.PathResult.to_dataset`).
    figure
        A Figure to draw into (a new (6.4, 4.8) in Figure by default).

    Returns
    -------
    Figure
        Up to 12 cases: one axes, a curve per case, its events, closed-form
        overlays (dashed), alpha in rad below and in degrees above.  More: the
        parameter plane of alpha (2-D sweeps) or the fan of the curves.
        Another system than the seed's diamond: the load (or the driven
        force) against its first interaction angle
        (:func:`ncstab.plotting.model_paths.model_path_figure`).
    """
    if not is_seed_diamond(dataset):
        return model_path_figure(dataset, figure, "load_rotation")
    layout = sweep_shape(dataset).layout
    if layout == "parameter_plane":
        return parameter_plane_figure(dataset, "load_rotation", figure)
    if layout == "fan":
        return fan_figure(dataset, "load_rotation", figure)
    return planar_curves_figure(dataset, figure, "load_rotation")


def plot_load_displacement(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Load-displacement response F1 against Delta1* (seed Figs. 4, 6, 7, 10, 13, 15).

    Returns
    -------
    Figure
        As :func:`plot_load_rotation` with Delta1* on x; the parameter plane
        of a large 2-D sweep is that of F1*.  Another system than the seed's
        diamond: axes chosen from what the stages drive, branches and the
        stability of each state (:mod:`ncstab.plotting.model_paths`).
    """
    if not is_seed_diamond(dataset):
        return model_path_figure(dataset, figure, "load_displacement")
    layout = sweep_shape(dataset).layout
    if layout == "parameter_plane":
        return parameter_plane_figure(dataset, "load_displacement", figure)
    if layout == "fan":
        return fan_figure(dataset, "load_displacement", figure)
    return planar_curves_figure(dataset, figure, "load_displacement")


def plot_load_displacement_rotation(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """3-D curves (Delta1*, alpha, F1) (seed Figs. 5 and 11).

    The 3-D view shows that the two branches of the closed form, which seem
    to cross in the load-displacement plane, do not meet in a bifurcation.

    Returns
    -------
    Figure
        Up to 12 cases: one 3-D axes; closed forms are cut (NaN) outside the
        box of the computed data, since 3-D axes do not clip.  More: the
        parameter plane of Delta1* (2-D sweeps) or the load-displacement fan.
    """
    layout = sweep_shape(dataset).layout
    if layout == "parameter_plane":
        return parameter_plane_figure(dataset, "load_displacement_rotation", figure)
    if layout == "fan":
        return fan_figure(dataset, "load_displacement", figure)
    return curves_3d_figure(dataset, figure)


def plot_stability(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Stability indicators along the path against Delta1*.

    Three stacked panels: det K (a limit point under force control where it
    vanishes, seed Eq. 36), the smallest eigenvalue of K_sym (Hill's
    condition holds while positive) and the normalised second-order work
    along the path; each with its zero line and the located events.  In the
    pure-shear limit (rigid normal) K is not defined and the panels say so.

    Returns
    -------
    Figure
        Up to 12 cases: three axes sharing x, a curve per case.  More: the
        stability diagram (2-D sweeps) or the fans of the three indicators.
    """
    layout = sweep_shape(dataset).layout
    if layout == "parameter_plane":
        return stability_diagram_figure(_squeezed(dataset), figure)
    if layout == "fan":
        return fan_figure(dataset, "stability", figure)
    return stability_curves_figure(dataset, figure)


#: Figure kinds by name (the ``figures`` of a study file, ``ncstab plot --kinds``).
FIGURE_KINDS: dict[str, Callable[..., Figure]] = {
    "load_rotation": plot_load_rotation,
    "load_displacement": plot_load_displacement,
    "load_displacement_rotation": plot_load_displacement_rotation,
    "stability": plot_stability,
    "cycle_work": cycle_work_figure,
    "cycle_paths": cycle_paths_figure,
    "cycle_force_drift": cycle_force_drift_figure,
    "stability_diagram": stability_diagram_figure,
    "second_order_work_map": second_order_work_map_figure,
    "second_order_work_polar": second_order_work_polar_figure,
    "state_map": state_map_figure,
    "root_locus": root_locus_figure,
    "frequencies": frequencies_figure,
    "damping_map": damping_map_figure,
    "motion": motion_figure,
    "phase_portrait": phase_portrait_figure,
    "energies": energies_figure,
    "boundary": boundary_figure,
}
