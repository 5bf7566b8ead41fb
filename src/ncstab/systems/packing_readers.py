"""Readers of DEM outputs into a packing (:mod:`ncstab.systems.packing`): LAMMPS, LIGGGHTS, YADE, CSV.

Every reader returns a validated :class:`~ncstab.systems.packing.Packing` in
the packing file's units (docs/packings.md): lengths divided by the mean grain
diameter d, forces by ``kn * d`` (``kn`` the DEM's normal stiffness, in the
DEM's units: force per length).  From a contact force F that grain a exerts on
grain b, with n the unit vector from a to b and t = n turned by +90 degrees:
N = F . n and T = -F . t (:mod:`ncstab.elements.grain_contact`).

*Dimension.*  A reader never drops a coordinate: data whose z varies (by more
than 1e-9 of the largest radius) give a three-dimensional packing (spheres:
x, y, z, radius, and the contact forces' three components, N = F . n and the
tangential part F - N n); data without z, or with a constant z (a 2-D LAMMPS
dump), give a two-dimensional one exactly as before.  ``dimension=2`` on
three-dimensional data is refused (:class:`PackingError`, naming z) unless
``plane_section=True`` asks explicitly for the plane section: the grains kept
as disks at their x-y positions, with the x-y components of the forces.
``dimension=3`` on data without z is refused.  Grains are held
by ``fixed_types`` (a LAMMPS atom type, e.g. wall grains) and/or ``fixed_ids``.

* :func:`read_lammps` -- a LAMMPS or LIGGGHTS ``dump`` of atoms
  (``ITEM: ATOMS id type x y ... radius``) and, optionally, a ``dump local``
  of the contacts.  LIGGGHTS: ``compute pair/gran/local id force`` (columns
  id1 id2 periodic-flag fx fy fz: :data:`LIGGGHTS_ID_FORCE`); LAMMPS:
  ``compute property/local patom1 patom2`` with ``compute pair/local fx fy fz``
  dumped together (:data:`LAMMPS_PAIR_LOCAL`).  In both, (fx, fy, fz) is the
  force on the first atom of the pair (pair styles' ``f[i] += fx``).  Any other
  layout: ``columns`` names the columns by index or header name.  Without a
  ``dump local``, contacts are the overlapping pairs and forces are 0.
* :func:`read_yade` -- the text export written by the YADE script of
  docs/packings.md (``B id x y radius fixed`` and ``I id1 id2 fx fy`` lines,
  F the force of id1 on id2).
* :func:`read_csv` -- a grains table (``x,y,radius[,fixed][,id]``) and an
  optional contacts table (``a,b[,normal_force,tangential_force]`` with grain
  ids, or ``a,b,fx,fy``: the force of a on b).

The readers were tested on small files written from the formats' documentation
(tests/test_packing_readers.py), and the LAMMPS reader on a packing poured and settled
by LAMMPS itself (tests/test_lammps_packing.py, tests/data/lammps_pour/); LIGGGHTS
and YADE were not run.
"""

from __future__ import annotations

import io
import stat
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ncstab.systems.packing import Packing, PackingError, contacts_from_geometry, validate

__all__ = ["LAMMPS_PAIR_LOCAL", "LIGGGHTS_ID_FORCE", "choose_z", "packing_from_arrays", "read_csv", "read_dump",
           "read_lammps", "read_yade"]

#: ``compute pair/gran/local id force`` (LIGGGHTS): id1 id2 periodic-flag fx fy fz, force on id1.
LIGGGHTS_ID_FORCE = {"id1": 0, "id2": 1, "fx": 3, "fy": 4, "fz": 5}
#: ``dump local c_ids[1] c_ids[2] c_pair[1] ... c_pair[6]`` (LAMMPS property/local patom1 patom2 and
#: pair/local fx fy fz p1 p2 p3): the force on id1 is (fx + p1, fy + p2).  For the granular pair
#: styles LAMMPS's fx, fy, fz are the normal force only; p1, p2, p3 the tangential force
#: (measured on a packing poured by LAMMPS itself: tests/test_lammps_packing.py).
LAMMPS_PAIR_LOCAL = {"id1": 0, "id2": 1, "fx": 2, "fy": 3, "fz": 4, "tx": 5, "ty": 6, "tz": 7}


def read_dump(path: str | Path, item: str = "ATOMS", timestep: int | None = None) -> tuple[list[str], np.ndarray]:
    """The column names and the table of one snapshot of a LAMMPS/LIGGGHTS text dump (the last, or ``timestep``).

    ``item`` is ``"ATOMS"`` (``dump atom/custom``) or ``"ENTRIES"`` (``dump local``).
    """
    path = Path(path)
    lines = read_text(path).splitlines()
    starts = [i for i, line in enumerate(lines) if line.startswith("ITEM: TIMESTEP")]
    if not starts:
        raise PackingError(f"{path}: not a LAMMPS dump (no 'ITEM: TIMESTEP' line)")
    chosen = starts[-1]
    if timestep is not None:
        found = [i for i in starts if _timestep(lines, i, path) == timestep]
        if not found:
            raise PackingError(f"{path}: no snapshot at timestep {timestep}")
        chosen = found[0]
    end = next((i for i in starts if i > chosen), len(lines))
    header = next((i for i in range(chosen, end) if lines[i].startswith(f"ITEM: {item}")), None)
    if header is None:
        raise PackingError(f"{path}: the snapshot has no 'ITEM: {item}' section")
    names = lines[header].split()[2:]
    table = numbers(path, [(k + 1, lines[k]) for k in range(header + 1, end) if lines[k].strip()], len(names), None)
    return names, table


def read_text(path: Path) -> str:
    """The text of a regular file, UTF-8; anything else (a fifo, a device, a folder, bytes that are
    not UTF-8) raises :class:`PackingError` naming the file (a fifo would block the read forever)."""
    try:
        if not stat.S_ISREG(path.stat().st_mode):
            raise PackingError(f"{path}: not a regular file (a fifo, device or folder cannot be read as a packing)")
        return path.read_bytes().decode("utf-8")
    except OSError as error:
        raise PackingError(f"cannot read {path}: {error}") from None
    except UnicodeDecodeError as error:
        line = path.read_bytes()[:error.start].count(b"\n") + 1
        raise PackingError(f"{path}: line {line} is not UTF-8 text (a binary file?)") from None


def numbers(path: Path, numbered: list[tuple[int, str]], width: int, delimiter: str | None) -> np.ndarray:
    """The (len(numbered), width) table of numbers in the lines ``numbered`` ((line number, text)
    pairs, blank lines left out); a line that is not ``width`` numbers raises
    :class:`PackingError` naming the file and the line."""
    if not numbered:
        return np.zeros((0, width))
    try:
        table = np.loadtxt(io.StringIO("\n".join(line for _, line in numbered)), delimiter=delimiter, ndmin=2)
        if table.shape[1] == width:
            return table
    except ValueError:
        pass
    for number, line in numbered:  # the error path only: find the line to name
        try:
            values = [float(field) for field in line.split(delimiter)]
        except ValueError:
            raise PackingError(f"{path}: line {number} is not {width} numbers: {line.strip()[:60]!r}") from None
        if len(values) != width:
            raise PackingError(f"{path}: line {number} has {len(values)} values for the {width} names of the header")
    raise PackingError(f"{path}: not a table of {width} numbers")


def _timestep(lines: list[str], start: int, path: Path) -> int:
    try:
        return int(lines[start + 1].split()[0])
    except (IndexError, ValueError):
        raise PackingError(f"{path}: line {start + 2} should hold the timestep of 'ITEM: TIMESTEP'") from None


def _column(names: list[str], table: np.ndarray, key: int | str, path: Path) -> np.ndarray:
    if isinstance(key, str):
        if key not in names:
            raise PackingError(f"{path}: no column {key!r} (columns: {' '.join(names)})")
        key = names.index(key)
    if not 0 <= key < table.shape[1]:
        raise PackingError(f"{path}: no column {key} ({table.shape[1]} columns)")
    return table[:, key]


def packing_from_arrays(ids: np.ndarray, x: np.ndarray, y: np.ndarray, radius: np.ndarray, fixed: np.ndarray,
                        pairs: np.ndarray | None = None, force: np.ndarray | None = None, kn: float = 1.0,
                        source: str = "<arrays>", z: np.ndarray | None = None) -> Packing:
    """A packing from DEM arrays in the DEM's units.

    Parameters
    ----------
    ids : (g,)
        The grains' ids (any integers); ``pairs`` refer to them.
    x, y, radius, fixed : (g,)
    pairs : (c, 2) or None
        Contacts by grain id (None: the overlapping pairs, with zero forces).
    force : (c, 2) or None
        Force (fx, fy) that the first grain of each pair exerts on the second ((c, 3) with ``z``).
    kn
        The DEM's normal stiffness (force per length): forces are divided by kn d.
    z : (g,) or None
        The centres' z: a three-dimensional packing (see :func:`choose_z`); None: 2-D.
    """
    dim = 2 if z is None else 3
    radius = np.asarray(radius, dtype=float)
    if len(radius) == 0:
        raise PackingError(f"{source}: no grains (a table with a header and no rows?)")
    ids = _integers(ids, source, "grain id")
    d = 2 * float(np.mean(radius))
    x, y = np.asarray(x, float) / d, np.asarray(y, float) / d
    z = None if z is None else np.asarray(z, float) / d
    radius = radius / d
    order = np.argsort(ids, kind="stable")
    if len(ids) > 1 and np.any(ids[order][1:] == ids[order][:-1]):
        raise PackingError(f"{source}: grain id {ids[order][1:][ids[order][1:] == ids[order][:-1]][0]} appears twice")
    if pairs is None:
        contacts = contacts_from_geometry(x, y, radius, z=z)
        force = np.zeros((len(contacts), dim))
    else:
        pairs = _integers(pairs, source, "contact's grain id")
        position = np.searchsorted(ids[order], pairs.ravel())
        position = np.minimum(position, len(ids) - 1)
        known = ids[order][position] == pairs.ravel()
        if not known.all():
            k = int(np.flatnonzero(~known)[0])
            raise PackingError(f"{source}: contact {k // 2} names grain id {pairs.ravel()[k]}, which is not a grain")
        contacts = order[position].reshape(-1, 2)
        force = np.zeros((len(contacts), dim)) if force is None else np.asarray(force, dtype=float)
    a, b = contacts[:, 0], contacts[:, 1]
    branch = np.column_stack([x[b] - x[a], y[b] - y[a]] + ([] if z is None else [z[b] - z[a]]))
    length = np.linalg.norm(branch, axis=1)
    far = length > 1.5 * (radius[a] + radius[b])
    if far.any():
        k = int(np.flatnonzero(far)[0])
        raise PackingError(f"{source}: contact {k} joins grains {ids[a[k]]} and {ids[b[k]]} whose centres are "
                           f"{length[k]:.3g} d apart (a periodic image? periodic packings are not supported)")
    n = branch / np.where(length > 0, length, 1.0)[:, None]
    scale = kn * d
    if z is not None:
        normal = np.sum(force * n, axis=1)
        tangential = (force - normal[:, None] * n) / scale
        return validate({"x": x, "y": y, "z": z, "radius": radius, "fixed": np.asarray(fixed, dtype=float),
                         "grain_a": a, "grain_b": b, "normal_force": normal / scale,
                         **{f"tangential_force_{k}": tangential[:, j] for j, k in enumerate("xyz")}}, source)
    t = np.column_stack([-n[:, 1], n[:, 0]])
    return validate({"x": x, "y": y, "radius": radius, "fixed": np.asarray(fixed, dtype=float),
                     "grain_a": a, "grain_b": b, "normal_force": np.sum(force * n, axis=1) / scale,
                     "tangential_force": -np.sum(force * t, axis=1) / scale}, source)


def _integers(values, source: str, what: str) -> np.ndarray:
    """``values`` as int64; a value that is not an integer (1.5, nan, 1e300) raises PackingError."""
    values = np.asarray(values)
    if values.dtype.kind == "f":
        bad = ~np.isfinite(values) | (values != np.round(values)) | (np.abs(values) > 2.0 ** 53)
        if bad.any():
            raise PackingError(f"{source}: {what} {float(values.ravel()[np.flatnonzero(bad.ravel())[0]]):g} is not an integer")
    return values.astype(np.int64)


def choose_z(z: np.ndarray | None, radius: np.ndarray, dimension: int | None, plane_section: bool,
             source: str) -> np.ndarray | None:
    """The z to keep: ``z`` for three-dimensional data, None for 2-D (see the module docstring).

    Raises
    ------
    PackingError
        ``dimension=2`` on data whose z varies, without ``plane_section``; ``dimension=3`` without z;
        a dimension other than 2, 3 or None.
    """
    if dimension not in (None, 2, 3):
        raise PackingError(f"{source}: dimension must be 2 or 3, is {dimension!r}")
    if plane_section:
        if dimension == 3:
            raise PackingError(f"{source}: plane_section=True gives a two-dimensional packing, not dimension=3")
        return None
    if z is None:
        if dimension == 3:
            raise PackingError(f"{source}: dimension=3, but the data have no z coordinate")
        return None
    z = np.asarray(z, dtype=float)
    spread = float(np.ptp(z)) if len(z) else 0.0
    varies = spread > 1e-9 * float(np.max(radius))
    if dimension == 2 and varies:
        raise PackingError(f"{source}: z varies by {spread:g} across the grains: they are spheres (a three-"
                           "dimensional packing); read it in 3-D (dimension=3 or None), or ask for the plane "
                           "section explicitly (plane_section=True: disks at their x-y positions)")
    return z if (dimension == 3 or varies) else None


def _fixed(ids: np.ndarray, types: np.ndarray | None, fixed_types: Sequence[int], fixed_ids: Sequence[int]):
    held = np.isin(ids, np.asarray(fixed_ids, dtype=np.int64))
    if types is not None and len(fixed_types):
        held |= np.isin(types, np.asarray(fixed_types))
    return held


def read_lammps(atoms: str | Path, pairs: str | Path | None = None, columns: Mapping[str, int | str] | None = None,
                kn: float = 1.0, fixed_types: Sequence[int] = (), fixed_ids: Sequence[int] = (),
                timestep: int | None = None, dimension: int | None = None, plane_section: bool = False) -> Packing:
    """A packing from a LAMMPS/LIGGGHTS ``dump`` of atoms and an optional ``dump local`` of contacts.

    Parameters
    ----------
    atoms
        ``dump ID all custom N file id type x y z radius`` (columns by name: ``id``, ``x``,
        ``y``, ``radius`` or ``diameter``; ``type`` if ``fixed_types``).
    pairs
        The ``dump local`` of the contacts, or None (contacts: overlapping pairs, forces 0).
    columns
        Where id1, id2, fx, fy (and optionally tx, ty, a tangential part added to them) are
        in ``pairs`` (index or header name); default :data:`LIGGGHTS_ID_FORCE`.  (fx, fy)
        (+ (tx, ty)) is the force on id1.
    kn
        The DEM's normal stiffness (units of force per length).
    fixed_types, fixed_ids
        Grains held.
    timestep
        The snapshot (default the last of each file).
    dimension, plane_section
        See :func:`choose_z`: a dump whose z varies is three-dimensional (then ``columns``
        also gives fz, and tz with tx, ty).
    """
    atoms = Path(atoms)
    names, table = read_dump(atoms, "ATOMS", timestep)
    ids = _column(names, table, "id", atoms).astype(np.int64)
    radius = (_column(names, table, "radius", atoms) if "radius" in names
              else 0.5 * _column(names, table, "diameter", atoms))
    types = _column(names, table, "type", atoms) if "type" in names else None
    held = _fixed(ids, types, fixed_types, fixed_ids)
    x, y = _column(names, table, "x", atoms), _column(names, table, "y", atoms)
    z = choose_z(_column(names, table, "z", atoms) if "z" in names else None, radius, dimension, plane_section,
                 str(atoms))
    if pairs is None:
        return packing_from_arrays(ids, x, y, radius, held, kn=kn, source=str(atoms), z=z)
    pairs = Path(pairs)
    local_names, local = read_dump(pairs, "ENTRIES", timestep)
    spec = dict(LIGGGHTS_ID_FORCE if columns is None else columns)
    i1, i2 = (_column(local_names, local, spec[k], pairs) for k in ("id1", "id2"))
    axes = ("x", "y") if z is None else ("x", "y", "z")
    missing = [f"f{a}" for a in axes if f"f{a}" not in spec] + \
        ([f"t{a}" for a in axes if f"t{a}" not in spec] if "tx" in spec else [])
    if missing:
        raise PackingError(f"{pairs}: the packing is three-dimensional (z varies), and columns does not say where "
                           f"{missing[0]!r} is")
    on_first = np.column_stack([_column(local_names, local, spec[f"f{a}"], pairs) for a in axes])
    if "tx" in spec:  # a tangential part given apart (LAMMPS's granular pair/local: p1, p2, p3)
        on_first = on_first + np.column_stack([_column(local_names, local, spec[f"t{a}"], pairs) for a in axes])
    return packing_from_arrays(ids, x, y, radius, held, np.column_stack([i1, i2]), -on_first, kn, str(pairs), z)


def read_yade(path: str | Path, kn: float = 1.0, dimension: int | None = None,
              plane_section: bool = False) -> Packing:
    """A packing from the YADE text export of docs/packings.md.

    Lines ``B id x y z radius fixed`` (bodies) and ``I id1 id2 fx fy fz`` (interactions: F the
    force of id1 on id2); ``#`` starts a comment.  The 2-D export of earlier versions
    (``B id x y radius fixed``, ``I id1 id2 fx fy``) is read too.  ``dimension``,
    ``plane_section``: see :func:`choose_z`.
    """
    path = Path(path)
    lines = [line.split("#", 1)[0].split() for line in read_text(path).splitlines()]
    bodies = [row[1:] for row in lines if row and row[0] == "B"]
    interactions = [row[1:] for row in lines if row and row[0] == "I"]
    unknown = next((k for k, row in enumerate(lines) if row and row[0] not in ("B", "I")), None)
    if unknown is not None:
        raise PackingError(f"{path}: line {unknown + 1} is neither a body (B) nor an interaction (I)")
    if not bodies:
        raise PackingError(f"{path}: no body line ('B id x y z radius fixed')")
    width = len(bodies[0])
    try:
        if width not in (5, 6):
            raise ValueError
        body = np.array(bodies, dtype=float).reshape(len(bodies), width)
        inter = np.array(interactions, dtype=float).reshape(len(interactions), width - 1)
    except ValueError:
        raise PackingError(f"{path}: body lines need 6 numbers (id x y z radius fixed) and interaction lines 5 "
                           "(id1 id2 fx fy fz), or 5 and 4 without z, all alike") from None
    spatial = width == 6
    radius = body[:, 3 + spatial]
    z = choose_z(body[:, 3] if spatial else None, radius, dimension, plane_section, str(path))
    force = inter[:, 2:5] if z is not None else inter[:, 2:4]
    return packing_from_arrays(body[:, 0], body[:, 1], body[:, 2], radius, body[:, 4 + spatial], inter[:, :2],
                               force, kn, str(path), z)


def read_csv(grains: str | Path, contacts: str | Path | None = None, kn: float = 1.0, dimension: int | None = None,
             plane_section: bool = False) -> Packing:
    """A packing from CSV tables with a header line (see the module docstring).

    A grains table with a ``z`` column that varies is three-dimensional; its contacts table
    then gives ``a,b,fx,fy,fz`` or ``a,b,normal_force,tangential_force_x,tangential_force_y,
    tangential_force_z``.  ``dimension``, ``plane_section``: see :func:`choose_z`.
    """
    grains = Path(grains)
    table = _read_table(grains)
    for name in ("x", "y", "radius"):
        if name not in table:
            raise PackingError(f"{grains}: no column {name!r} (a grains table needs x, y, radius)")
    count = len(table["x"])
    ids = table.get("id", np.arange(count))
    fixed = table.get("fixed", np.zeros(count))
    z = choose_z(table.get("z"), table["radius"], dimension, plane_section, str(grains))
    if contacts is None:
        return packing_from_arrays(ids, table["x"], table["y"], table["radius"], fixed, kn=kn, source=str(grains),
                                   z=z)
    contacts = Path(contacts)
    pairs = _read_table(contacts)
    for name in ("a", "b"):
        if name not in pairs:
            raise PackingError(f"{contacts}: no column {name!r} (a contacts table needs a, b)")
    ab = np.column_stack([pairs["a"], pairs["b"]])
    if z is not None:
        return _csv_spheres(table, pairs, ids, fixed, z, ab, kn, str(contacts))
    if "fx" in pairs:
        force = np.column_stack([pairs["fx"], pairs.get("fy", np.zeros(len(ab)))])
        return packing_from_arrays(ids, table["x"], table["y"], table["radius"], fixed, ab, force, kn, str(contacts))
    packing = packing_from_arrays(ids, table["x"], table["y"], table["radius"], fixed, ab, None, kn, str(contacts))
    d = 2 * float(np.mean(table["radius"]))
    return packing.with_forces(pairs.get("normal_force", np.zeros(len(ab))) / (kn * d),
                               pairs.get("tangential_force", np.zeros(len(ab))) / (kn * d))


def _csv_spheres(table, pairs, ids, fixed, z, ab, kn, source) -> Packing:
    """The 3-D packing of CSV tables (forces fx, fy, fz of a on b, or N and the tangential components)."""
    zeros = np.zeros(len(ab))
    if "fx" in pairs:
        force = np.column_stack([pairs["fx"], pairs.get("fy", zeros), pairs.get("fz", zeros)])
        return packing_from_arrays(ids, table["x"], table["y"], table["radius"], fixed, ab, force, kn, source, z)
    packing = packing_from_arrays(ids, table["x"], table["y"], table["radius"], fixed, ab, None, kn, source, z)
    d = 2 * float(np.mean(table["radius"]))
    vector = np.column_stack([pairs.get(f"tangential_force_{k}", zeros) for k in "xyz"]) / (kn * d)
    values = {"x": packing.x, "y": packing.y, "z": packing.z, "radius": packing.radius,
              "fixed": packing.fixed.astype(float), "grain_a": packing.contacts[:, 0],
              "grain_b": packing.contacts[:, 1], "normal_force": pairs.get("normal_force", zeros) / (kn * d),
              **{f"tangential_force_{k}": vector[:, j] for j, k in enumerate("xyz")}}
    return validate(values, source)


def _read_table(path: Path) -> dict[str, np.ndarray]:
    numbered = [(k + 1, line) for k, line in enumerate(read_text(path).splitlines())
                if line.strip() and not line.lstrip().startswith("#")]
    if not numbered:
        return {}
    names = [name.strip() for name in numbered[0][1].split(",")]
    data = numbers(path, numbered[1:], len(names), ",")
    return {name: data[:, k] for k, name in enumerate(names)}
