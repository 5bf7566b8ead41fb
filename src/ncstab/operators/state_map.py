"""Stability indicators as maps over the displacement plane (laws with a total form).

For a law with a total form the forces and the tangent operator are functions
of the state alone, F = F(u), K = K(u) (seed Eq. 4, 34, 51), so every
indicator is a field over the (Delta_1*, Delta_2*) plane, and any equilibrium
path of a study can be drawn over it.  Strongly hypoelastic laws have no such
map: their K depends on the loading history through T.
"""

from __future__ import annotations

import numpy as np

from ncstab.laws.registry import Law
from ncstab.operators.directional_work import unstable_cone
from ncstab.operators.indicators import det_K, hill_eigenvalue
from ncstab.operators.tangent import generalized_forces, tangent_operator
from ncstab.systems.protocol import DiscreteSystem

__all__ = ["STATE_MAP_FIELDS", "state_map"]

#: Fields of a state map: name -> (units, long_name, description).
STATE_MAP_FIELDS: dict[str, tuple[str, str, str]] = {
    "map_hill": ("1", "smallest eigenvalue of K_sym over the displacement plane",
                 "Hill's condition holds where positive (laws with a total form: K = K(u))"),
    "map_det_K": ("1", "det K over the displacement plane", "vanishes where a force-controlled path has a limit point"),
    "map_cone_width": ("rad", "unstable cone width over the displacement plane",
                       "total angle of displacement directions with negative second-order work"),
    "map_mixed_control_F1": ("1", "K11 over the displacement plane",
                             "mixed-control determinant with F1 held (Delta_2 driven): controllability lost where 0"),
    "map_mixed_control_F2": ("1", "K22 over the displacement plane",
                             "mixed-control determinant with F2 held (Delta_1 driven): controllability lost where 0 (seed Eq. 35)"),
    "map_F1": ("1", "F1* over the displacement plane", "generalized force F1* = F1/(2R k_n) at each state"),
    "map_F2": ("1", "F2* over the displacement plane", "generalized force F2* = F2/(2R k_n) at each state"),
}


def state_map(system: DiscreteSystem, law: Law, d1: np.ndarray, d2: np.ndarray) -> dict[str, np.ndarray]:
    """Stability indicators on the grid d1 x d2 of displacements (2-dof systems).

    Parameters
    ----------
    system, law
        A two-dof system and a law with a total form; parameters may carry
        leading batch dimensions ``(...)`` (one map per case).
    d1, d2
        1-D grids of Delta_1* and Delta_2*.

    Returns
    -------
    dict
        Every field of :data:`STATE_MAP_FIELDS`, each of shape
        ``(..., len(d1), len(d2))``.

    Raises
    ------
    ValueError
        For a law without a total form (its K depends on the path).
    """
    if not law.has_total_form:
        raise ValueError(
            f"law {law.name!r} has no total form: its tangent operator depends on the loading "
            "history (T is an internal variable), so it has no state map"
        )
    d1, d2 = np.asarray(d1, dtype=float), np.asarray(d2, dtype=float)
    grid = np.stack(np.meshgrid(d1, d2, indexing="ij"), axis=-1)  # (n1, n2, 2)
    batch = np.broadcast_shapes(*(np.shape(v) for v in law.parameters.values()),
                                *(np.shape(v) for v in system.parameters.values()))
    u = np.broadcast_to(grid, batch + grid.shape)
    expand = (...,) + (None, None)
    law_on_grid = Law(law.definition, {k: np.asarray(v)[expand] for k, v in law.parameters.items()})
    system_on_grid = type(system)(**{k: np.asarray(v)[expand] for k, v in system.parameters.items()})
    stiffness = tangent_operator(system_on_grid, law_on_grid, u)
    forces = generalized_forces(system_on_grid, law_on_grid, u)
    width, _, _ = unstable_cone(stiffness)
    return {
        "map_hill": hill_eigenvalue(stiffness),
        "map_det_K": det_K(stiffness),
        "map_cone_width": width,
        "map_mixed_control_F1": stiffness[..., 0, 0],
        "map_mixed_control_F2": stiffness[..., 1, 1],
        "map_F1": forces[..., 0],
        "map_F2": forces[..., 1],
    }
