"""State maps of a study: indicators over the displacement plane, per law and case."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ncstab.laws.registry import make_law
from ncstab.operators.state_map import STATE_MAP_FIELDS, state_map
from ncstab.systems import DiamondChain

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from ncstab.paths.result import PathResult

__all__ = ["add_state_maps"]


def add_state_maps(
    dataset: "xr.Dataset", path: "PathResult", grid: tuple[tuple[float, float, int], tuple[float, float, int]]
) -> "xr.Dataset":
    """Add ``map_*`` fields (dims law, sweep..., map_D1, map_D2) to a path Dataset.

    Laws without a total form (strongly hypoelastic) get NaN maps: their
    tangent operator depends on the loading history, not on the state alone.
    The pure-shear limit has no state map either (u moves on a curve).
    """
    (d1_min, d1_max, n1), (d2_min, d2_max, n2) = grid
    d1 = np.linspace(d1_min, d1_max, n1)
    d2 = np.linspace(d2_min, d2_max, n2)
    values = path.grid.case_values()
    size = path.grid.size
    if not path.model.is_reduced_diamond:
        raise ValueError("state maps over (D1, D2) are drawn for the seed's reduced diamond only")
    fields = {name: np.full((len(path.laws), size, n1, n2), np.nan) for name in STATE_MAP_FIELDS}
    for k, name in enumerate(path.laws):
        definition = path.law_definition(name)
        if not definition.has_total_form or path.model.normal != "deformable":
            continue
        parameters = {
            p.name: values.get(p.name, np.full(size, p.default if p.default is not None else np.nan))
            for p in definition.parameters
        }
        law = make_law(definition, **parameters)
        system = DiamondChain(alpha0=values.get("alpha0", np.full(size, np.pi / 4)))
        for field, array in state_map(system, law, d1, d2).items():
            fields[field][k] = array
    dims = list(dataset["status"].dims) + ["map_D1", "map_D2"]
    shape = dataset["status"].shape + (n1, n2)
    out = dataset.assign_coords(
        map_D1=("map_D1", d1, {"units": "1", "long_name": "Delta1* of the state map grid",
                                "description": "Delta_1 / 2R at the grid points of the state maps"}),
        map_D2=("map_D2", d2, {"units": "1", "long_name": "Delta2* of the state map grid",
                                "description": "Delta_2 / 2R at the grid points of the state maps"}),
    )
    for field, array in fields.items():
        units, long_name, description = STATE_MAP_FIELDS[field]
        out[field] = (dims, array.reshape(shape), {"units": units, "long_name": long_name, "description": description})
    return out
