"""The ``[map]`` section of a study file: second-order work maps to add to the archive."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ncstab.studies.study_fields import GRID_KEYS, MAP_KEYS, FieldErrors, check_keys, read_number, read_table

__all__ = ["StudyMap", "map_section"]


@dataclass(frozen=True)
class StudyMap:
    """The ``[map]`` section: second-order work maps to add to the archive.

    Attributes
    ----------
    directions
        Number of loading directions theta in [0, pi) for ``d2W_dir`` along the
        paths (and the unstable cone per step), or ``None``.
    grid
        ``((D1 min, D1 max, n1), (D2 min, D2 max, n2))``: a state map of the
        indicators over the displacement plane (laws with a total form), or
        ``None``.
    """

    directions: int | None = None
    grid: tuple[tuple[float, float, int], tuple[float, float, int]] | None = None


def map_section(data: Mapping[str, Any], errors: FieldErrors) -> StudyMap | None:
    table = read_table(data, "map", errors)
    if table is None:
        return None
    check_keys(table, MAP_KEYS, "map", errors, "[map]")
    directions = None
    if "directions" in table:
        raw = table["directions"]
        if isinstance(raw, bool) or not isinstance(raw, int) or not 4 <= raw <= 100_000:
            errors.add("map.directions", f"expected a whole number of directions from 4 to 100000, got {raw!r}")
        else:
            directions = raw
    grid = None
    if "grid" in table:
        raw = table["grid"]
        if not isinstance(raw, dict):
            errors.add("map.grid", "expected a table { D1 = [min, max, n], D2 = [min, max, n] }")
        else:
            check_keys(raw, GRID_KEYS, "map.grid", errors, "[map] grid")
            axes = []
            for key in GRID_KEYS:
                field = f"map.grid.{key}"
                spec = raw.get(key)
                if not isinstance(spec, list) or len(spec) != 3:
                    errors.add(field, f"expected [min, max, n] for {key}, got {spec!r}")
                    continue
                low, high = read_number(spec[0], field, errors), read_number(spec[1], field, errors)
                count = spec[2]
                if isinstance(count, bool) or not isinstance(count, int) or not 2 <= count <= 2000:
                    errors.add(field, f"the number of grid points must be a whole number from 2 to 2000, got {count!r}")
                    continue
                if low is None or high is None:
                    continue
                if not low < high:
                    errors.add(field, f"expected min < max, got [{low:g}, {high:g}]")
                    continue
                axes.append((low, high, count))
            if len(axes) == 2:
                grid = (axes[0], axes[1])
    if directions is None and grid is None and not errors.items:
        errors.add("map", "an empty [map] section: give directions, a grid, or both")
    return StudyMap(directions, grid)
