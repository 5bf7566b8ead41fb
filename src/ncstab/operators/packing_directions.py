"""Second-order work of given directions of a packing, and the exact unstable cone in a plane of its dofs.

**Directions.**  A direction d is a vector over the packing's free dofs, in the
order of :meth:`~ncstab.systems.packing.Packing.dof_names` (``x<i>``, ``y<i>``,
``theta<i>`` of each free grain i, in grain order).  Its normalised
second-order work is

    d2W(d) = d^T K d / d^T d  ( = d^T K_sym d / d^T d, K_sym = (K + K^T)/2),

negative where Hill's condition fails in that direction
(:func:`~ncstab.operators.packing_analysis.second_order_work`, on each
direction scaled by its largest entry, so that no product overflows).
:func:`read_directions` reads them from a CSV file whose header names dofs (a
dof not named is 0) or from a ``.npy`` array of rows over all free dofs;
:func:`directions_from` also takes an array or a ``{name: vector}`` mapping.  A
malformed direction (a length that is not the number of free dofs, a column
that is not a free dof, a value that is not a finite number, the zero
direction) is a :class:`DirectionsError` (exit code 2) naming the source and
its first bad entry.

**The unstable cone in a plane.**  Let e1, e2 be an orthonormal basis of a
plane of directions (:func:`plane_basis`: Gram-Schmidt of two given
directions; or the two softest modes of K_sym, which are orthonormal
already).  For the unit direction d(t) = cos t e1 + sin t e2,

    d2W(t) = d(t)^T K d(t) = B11 cos^2 t + (B12 + B21) cos t sin t + B22 sin^2 t,   B = E^T K E,

with E = [e1 e2]: exactly the seed's directional second-order work of the
2 x 2 operator B (:mod:`ncstab.operators.directional_work`).  Its cone of
directions with d2W < 0, bounded by the exact roots of d2W(t) = 0, is therefore
:func:`~ncstab.operators.directional_work.unstable_cone` of B
(:func:`plane_cone`): a width (total over the full circle, 0 where the
projected form is positive definite, 2 pi where it is negative definite) and,
where the form is indefinite, the bounds (lower in [0, pi), upper =
lower + width/2; the opposite cone is shifted by pi), angles t measured from
e1 towards e2.
"""

from __future__ import annotations

import csv
import os
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ncstab.studies.errors import InvalidInputError

__all__ = ["Directions", "DirectionsError", "PlaneCone", "cone_planes", "direction_work", "directions_from",
           "MAX_DIRECTIONS", "plane_basis", "plane_cone", "read_directions", "resolve_planes"]

#: A second direction whose part orthogonal to the first is below this share of its norm spans no plane with it.
PARALLEL_TOLERANCE = 1e-10
_DOF = re.compile(r"^(x|y|theta)(\d+)$")


class DirectionsError(InvalidInputError, ValueError):
    """Directions that cannot be used (exit code 2); the message names the source and the first bad entry."""


@dataclass(frozen=True)
class Directions:
    """Directions over a packing's free dofs.

    Attributes
    ----------
    names : list of str
        One label per direction (the CSV's ``name`` column, else the 0-based row).
    vectors : (p, n)
        The directions as given, over the free dofs.
    source : str
        Where they came from (a file's path, or ``directions``).
    """

    names: list[str]
    vectors: np.ndarray
    source: str


def _component(packing, name: str, where: str) -> int:
    """The free-dof index of a dof name ``x<i>``, ``y<i>``, ``theta<i>``."""
    match = _DOF.match(name.strip())
    if not match:
        raise DirectionsError(f"{where}: {name!r} is not a dof name (x<i>, y<i> or theta<i>, i a free grain)")
    grain = int(match[2])
    if grain >= packing.n_grains:
        raise DirectionsError(f"{where}: {name!r}: there is no grain {grain} (grains 0..{packing.n_grains - 1})")
    index = packing.dof_index()[grain, ("x", "y", "theta").index(match[1])]
    if index < 0:
        raise DirectionsError(f"{where}: {name!r}: grain {grain} is held (fixed = 1): its dofs are not free")
    return int(index)


#: The most directions one file may hold (a CSV's data lines, a ``.npy``'s rows): each is a
#: row over all free dofs, and reading a CSV costs about 0.1 ms a line.
MAX_DIRECTIONS = 10_000


def _too_many(path: Path, rows: int) -> DirectionsError:
    return DirectionsError(f"{path}: {rows} directions, more than the limit of {MAX_DIRECTIONS} a file "
                           "(docs/when-things-go-wrong.md, Limits)")


def _npy_directions(path: Path, packing) -> Directions:
    """A ``.npy`` array: its header is checked (real numbers, at most :data:`MAX_DIRECTIONS` rows)
    before any allocation."""
    try:
        with path.open("rb") as handle:
            version = np.lib.format.read_magic(handle)
            read_header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                           else np.lib.format.read_array_header_2_0)
            shape, _, dtype = read_header(handle)
    except (OSError, ValueError) as error:
        raise DirectionsError(f"{path}: not a readable .npy array ({error})") from None
    if dtype.kind not in "fiub":
        raise DirectionsError(f"{path}: an array of {dtype} (directions are real numbers: float or integer)")
    if len(shape) >= 1 and shape[0] > MAX_DIRECTIONS:
        raise _too_many(path, int(shape[0]))
    if int(np.prod(shape, dtype=float)) > MAX_DIRECTIONS * max(packing.n_dof, 1):
        raise DirectionsError(f"{path}: has shape {shape}; directions are rows over the free dofs, "
                              f"(p, {packing.n_dof})")
    try:
        array = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as error:
        raise DirectionsError(f"{path}: not a readable .npy array ({error})") from None
    return _checked_array(array, packing, str(path))


def _csv_directions(path: Path, packing) -> Directions:
    """A CSV file: a header of dof names (and optionally ``name``), one direction a line; ``#`` lines skipped."""
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            lines = [(number, row) for number, row in enumerate(csv.reader(handle), start=1)
                     if row and any(cell.strip() for cell in row) and not row[0].lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise DirectionsError(f"{path}: not a readable CSV file ({error})") from None
    if not lines:
        raise DirectionsError(f"{path}: no header (a line of dof names such as x3,y3,theta3) and no direction")
    header_line, header = lines[0]
    header = [cell.strip() for cell in header]
    columns: dict[int, int] = {}
    label = None
    for k, name in enumerate(header):
        where = f"{path}: line {header_line}, column {k + 1}"
        if name in header[:k]:
            raise DirectionsError(f"{where}: {name!r} appears twice in the header")
        if name == "name":
            label = k
        else:
            columns[k] = _component(packing, name, where)
    if not columns:
        raise DirectionsError(f"{path}: line {header_line}: the header names no dof (x<i>, y<i>, theta<i>)")
    if len(lines) == 1:
        raise DirectionsError(f"{path}: no direction after the header (line {header_line})")
    if len(lines) - 1 > MAX_DIRECTIONS:
        raise _too_many(path, len(lines) - 1)
    vectors = np.zeros((len(lines) - 1, packing.n_dof))
    names = []
    for row, (number, cells) in enumerate(lines[1:]):
        if len(cells) != len(header):
            raise DirectionsError(f"{path}: line {number} has {len(cells)} fields, the header {len(header)}")
        names.append(cells[label].strip() if label is not None else str(row))
        for k, index in columns.items():
            text = cells[k].strip()
            try:
                value = float(text) if text else 0.0
            except ValueError:
                raise DirectionsError(f"{path}: line {number}, column {header[k]!r}: {text!r} is not a "
                                      "number") from None
            if not np.isfinite(value):
                raise DirectionsError(f"{path}: line {number}, column {header[k]!r}: {text!r} is not a finite number")
            vectors[row, index] = value
        if not np.any(vectors[row]):
            raise DirectionsError(f"{path}: line {number} (direction {names[-1]!r}) is the zero direction")
    _check_names(names, path)
    return Directions(names, vectors, str(path))


def _check_names(names: list[str], source: Any) -> None:
    for k, name in enumerate(names):
        if not name:
            raise DirectionsError(f"{source}: direction {k} has an empty name")
        if name in names[:k]:
            raise DirectionsError(f"{source}: direction {k}: the name {name!r} is used twice")


def _checked_array(array: Any, packing, source: str, names: list[str] | None = None) -> Directions:
    """Rows over all free dofs: the right length, finite, not zero."""
    if np.iscomplexobj(array):
        raise DirectionsError(f"{source}: complex numbers (directions are real)")
    try:
        vectors = np.array(array, dtype=float, ndmin=2)
    except (TypeError, ValueError) as error:
        raise DirectionsError(f"{source}: not an array of numbers ({error})") from None
    n = packing.n_dof
    if vectors.ndim != 2:
        raise DirectionsError(f"{source}: has shape {vectors.shape}; directions are rows over the free dofs, (p, {n})")
    if vectors.shape[1] != n:
        raise DirectionsError(f"{source}: rows of length {vectors.shape[1]}, but the packing has {n} free dofs "
                              f"(x<i>, y<i>, theta<i> of its {n // 3} free grains)")
    if vectors.shape[0] == 0:
        raise DirectionsError(f"{source}: no direction")
    bad = ~np.isfinite(vectors)
    if bad.any():
        row, column = np.argwhere(bad)[0]
        raise DirectionsError(f"{source}: entry [{row}, {column}] (dof {packing.dof_names()[column]}) is "
                              f"{vectors[row, column]}, not a finite number")
    zero = ~np.any(vectors, axis=1)
    if zero.any():
        raise DirectionsError(f"{source}: row {int(np.flatnonzero(zero)[0])} is the zero direction")
    names = [str(k) for k in range(len(vectors))] if names is None else names
    _check_names(names, source)
    return Directions(names, vectors, source)


def read_directions(path: str | os.PathLike[str], packing) -> Directions:
    """Directions from a file: CSV (``.csv``, a header of dof names) or NumPy (``.npy``, rows over all free dofs).

    The CSV's header names dofs (``x3,y3,theta3``) and optionally a ``name``
    column; each following line is one direction, a dof it does not name and an
    empty field are 0.  Blank lines and lines starting with ``#`` are skipped.
    """
    path = Path(path)
    if not path.is_file():
        raise DirectionsError(f"--directions: no such file: {path}")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return _csv_directions(path, packing)
    if suffix == ".npy":
        return _npy_directions(path, packing)
    raise DirectionsError(f"--directions: {path}: not a .csv or .npy file")


def directions_from(value: Any, packing) -> Directions:
    """Directions from a file's path, an array ``(p, n)`` or ``(n,)``, or a mapping {name: vector over the dofs}."""
    if isinstance(value, Directions):
        return _checked_array(value.vectors, packing, value.source, list(value.names))
    if isinstance(value, (str, os.PathLike)):
        return read_directions(value, packing)
    if isinstance(value, Mapping):
        names = [str(name) for name in value]
        if not names:
            raise DirectionsError("directions: no direction")
        rows = [np.ravel(np.asarray(vector, dtype=float)) for vector in value.values()]
        for name, row in zip(names, rows):
            if row.shape != (packing.n_dof,):
                raise DirectionsError(f"directions: {name!r} has {row.size} entries, but the packing has "
                                      f"{packing.n_dof} free dofs")
        return _checked_array(np.stack(rows), packing, "directions", names)
    return _checked_array(value, packing, "directions")


def direction_work(K, directions: Directions) -> np.ndarray:
    """d^T K d / d^T d of each direction ``(p,)`` (rows scaled by their largest entry first: no overflow)."""
    from ncstab.operators.packing_analysis import second_order_work

    d = directions.vectors
    return second_order_work(K, d / np.max(np.abs(d), axis=1, keepdims=True))


def plane_basis(first: np.ndarray, second: np.ndarray, where: str = "plane") -> np.ndarray:
    """``(2, n)``: e1 = first/|first| and e2 the unit part of ``second`` orthogonal to it (Gram-Schmidt, twice)."""
    e1 = np.asarray(first, dtype=float)
    e1 = e1 / np.max(np.abs(e1))
    e1 = e1 / np.linalg.norm(e1)
    e2 = np.asarray(second, dtype=float)
    e2 = e2 / np.max(np.abs(e2))
    size = np.linalg.norm(e2)
    for _ in range(2):  # twice is enough (Kahan): e1 . e2 at rounding
        e2 = e2 - (e1 @ e2) * e1
    if np.linalg.norm(e2) <= PARALLEL_TOLERANCE * size:
        raise DirectionsError(f"{where}: the two directions are parallel: they span no plane")
    return np.stack([e1, e2 / np.linalg.norm(e2)])


@dataclass(frozen=True)
class PlaneCone:
    """The cone of directions of negative second-order work in one plane (see the module docstring).

    Attributes
    ----------
    label : str
        ``softest modes``, or the two directions' names (``a,b``).
    basis : (2, n)
        e1, e2, orthonormal over the free dofs.
    form : (2, 2)
        B = E^T K E.
    width, lower, upper : float
        :func:`~ncstab.operators.directional_work.unstable_cone` of B (rad).
    hill : float
        The smallest d2W(t) over the plane (the smallest eigenvalue of B's symmetric part).
    """

    label: str
    basis: np.ndarray
    form: np.ndarray
    width: float
    lower: float
    upper: float
    hill: float


def plane_cone(K, basis: np.ndarray, label: str) -> PlaneCone:
    """The exact unstable cone of K in the plane of the orthonormal ``basis`` ``(2, n)``."""
    from ncstab.operators.directional_work import second_order_work_form, unstable_cone

    basis = np.asarray(basis, dtype=float)
    form = basis @ np.asarray(K @ basis.T)
    width, lower, upper = unstable_cone(form)
    mean, radius, _ = second_order_work_form(form)
    return PlaneCone(label, basis, form, float(width), float(lower), float(upper), float(mean - radius))


def _direction_index(token: str, directions: Directions | None, spec: str) -> int:
    where = f"--cone-plane {spec!r}"
    if directions is None:
        raise DirectionsError(f"{where}: a plane of given directions needs --directions")
    if token in directions.names:
        return directions.names.index(token)
    if re.fullmatch(r"\d+", token) and int(token) < len(directions.names):
        return int(token)
    shown = ", ".join(directions.names[:8]) + (", ..." if len(directions.names) > 8 else "")
    raise DirectionsError(f"{where}: no direction {token!r} in {directions.source} (its directions: {shown})")


def resolve_planes(pairs: Iterable[Any], directions: Directions | None) -> list[tuple[str, np.ndarray]]:
    """The label and orthonormal basis ``(2, n)`` of each pair's plane (:func:`plane_basis`).

    Each pair names two directions, by name or 0-based row, as ``"a,b"`` or
    ``(a, b)``.  Checked before anything is computed: an unknown direction, a
    pair without ``directions``, a plane given twice or two parallel directions
    are a :class:`DirectionsError`.
    """
    planes = []
    for pair in pairs:
        tokens = [t.strip() for t in pair.split(",")] if isinstance(pair, str) else [str(p) for p in pair]
        spec = ",".join(tokens)
        if len(tokens) != 2:
            raise DirectionsError(f"--cone-plane {spec!r}: two directions, as NAME1,NAME2")
        i, j = (_direction_index(token, directions, spec) for token in tokens)
        assert directions is not None
        basis = plane_basis(directions.vectors[i], directions.vectors[j], f"--cone-plane {spec!r}")
        label = f"{directions.names[i]},{directions.names[j]}"
        if label in (known for known, _ in planes):
            raise DirectionsError(f"--cone-plane {spec!r}: the plane {label!r} is given twice")
        planes.append((label, basis))
    return planes


def cone_planes(K, softest: np.ndarray, planes: Iterable[tuple[str, np.ndarray]] = ()) -> list[PlaneCone]:
    """The unstable cones: in the plane of the two softest modes of K_sym, then in each given plane.

    Parameters
    ----------
    K
        The packing's K over its free dofs (sparse or dense).
    softest : (2, n)
        The two smallest eigenvectors of K_sym.
    planes
        (label, basis) of further planes (:func:`resolve_planes`).
    """
    cones = [plane_cone(K, plane_basis(softest[0], softest[1], "softest modes"), "softest modes")]
    return cones + [plane_cone(K, basis, label) for label, basis in planes]
