"""A granular packing: the packing file (NetCDF), its validation, and the system it defines.

The packing file (docs/packings.md) has dimensions
``grain`` and ``contact``; lengths in units of the mean grain diameter d,
forces in units of k_n d (seed Eq. 37 with 2R -> d), compression positive as N:

========================  =========  ============================================
variable                  dims       meaning
========================  =========  ============================================
``x``, ``y``              grain      grain centre
``radius``                grain      grain radius (> 0)
``fixed``                 grain      1: the grain's three dofs are held, else 0
``grain_a``, ``grain_b``  contact    the two grains in contact, 0-based
``normal_force``          contact    optional (absent: 0), N
``tangential_force``      contact    optional (absent: 0), T: the force of a on b
                                     is ``N n - T t`` (n from a to b, t = n
                                     turned by +90 degrees)
``friction``              () or      optional, the Coulomb ratio mu >= 0 (absent:
                          contact    every contact sticks; docs/friction.md)
``z``                     grain      optional: a file with ``z`` is
                                     three-dimensional (spheres)
``tangential_force_x``,   contact    3-D only, optional (absent: 0): the global
``_y``, ``_z``                       components of the tangential part of the
                                     force of a on b (orthogonal to the branch)
========================  =========  ============================================

A three-dimensional packing (:attr:`Packing.dimension` 3) has six dofs per free
grain, analysed by :mod:`ncstab.operators.sphere_analysis`.

Each free grain i has three dofs, ``x<i>``, ``y<i>``, ``theta<i>``, in grain
order; the contacts' kinematics are :mod:`ncstab.elements.grain_contact`.
Every check is made before anything is computed or written; a failed one
raises :class:`PackingError` (exit code 2) naming the variable and its first
bad entry.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ncstab.studies.errors import InvalidInputError

__all__ = ["Packing", "PackingError", "contacts_from_geometry", "read_packing", "triangular_lattice",
           "write_packing"]

REQUIRED = ("x", "y", "radius", "fixed", "grain_a", "grain_b")
OPTIONAL = ("normal_force", "tangential_force")
#: The optional variables of a three-dimensional packing (spheres).
OPTIONAL_3D = ("z", "tangential_force_x", "tangential_force_y", "tangential_force_z")

#: Attributes of the packing file's variables (units, long_name, description).
ATTRIBUTES = {
    "x": ("mean grain diameter", "grain centre x", "x of the grain's centre"),
    "y": ("mean grain diameter", "grain centre y", "y of the grain's centre"),
    "radius": ("mean grain diameter", "grain radius", "radius of the disk"),
    "fixed": ("1", "grain held", "1: the grain's three dofs (x, y, theta) are held, else 0"),
    "grain_a": ("1", "first grain of the contact", "0-based index of grain a"),
    "grain_b": ("1", "second grain of the contact", "0-based index of grain b"),
    "normal_force": ("k_n mean grain diameter", "normal contact force N",
                     "compression positive; the force of a on b is N n - T t, n from a to b"),
    "tangential_force": ("k_n mean grain diameter", "tangential contact force T",
                         "the force of a on b is N n - T t, t = n turned by +90 degrees"),
    "friction": ("1", "Coulomb friction ratio mu", "a contact slides where |T| >= mu N (docs/friction.md)"),
    "z": ("mean grain diameter", "grain centre z", "z of the sphere's centre (a file with z is three-dimensional)"),
    **{f"tangential_force_{c}": ("k_n mean grain diameter", f"tangential contact force, {c} component",
                                 "global component of the tangential part of the force of a on b (orthogonal to "
                                 "the branch); the force of a on b is N n + (tangential_force_x, _y, _z)")
       for c in "xyz"},
}


class PackingError(InvalidInputError, ValueError):
    """A packing file that cannot be analysed (exit code 2); the message names the variable and entry."""


@dataclass(frozen=True, eq=False)
class Packing:
    """Grains and contacts of a packing (see the module docstring).

    Attributes
    ----------
    x, y, radius : (g,)
    fixed : (g,) bool
    contacts : (c, 2) int
        ``grain_a``, ``grain_b``.
    normal_force, tangential_force : (c,)
    held : (g, 3) bool or None
        Which of each grain's dofs (x, y, theta) are held; ``None``: those of the ``fixed``
        grains (a packing file holds whole grains; a study's grain list, single dofs).
    friction : float, (c,) or None
        The Coulomb ratio mu (one for all contacts, or per contact); ``None``: every contact sticks.
        In 3-D ``(g, 6)`` (x, y, z, theta_x, theta_y, theta_z).
    z : (g,) or None
        Sphere centres' z: a three-dimensional packing; ``None``: disks (2-D).
    tangential_force_vector : (c, 3) or None
        3-D: the tangential part of the force of a on b, global components
        (``tangential_force`` is then its norm, for display only).
    """

    x: np.ndarray
    y: np.ndarray
    radius: np.ndarray
    fixed: np.ndarray
    contacts: np.ndarray
    normal_force: np.ndarray
    tangential_force: np.ndarray
    source: str = field(default="<memory>")
    held: np.ndarray | None = None
    friction: np.ndarray | None = None
    z: np.ndarray | None = None
    tangential_force_vector: np.ndarray | None = None

    @property
    def dimension(self) -> int:
        """3 for spheres (the packing has ``z``), else 2."""
        return 2 if self.z is None else 3

    @property
    def n_grains(self) -> int:
        return len(self.x)

    @property
    def n_contacts(self) -> int:
        return len(self.contacts)

    @property
    def held_dofs(self) -> np.ndarray:
        """``(g, 3)`` bool: each grain's held dofs (x, y, theta)."""
        if self.held is not None:
            return np.asarray(self.held, dtype=bool)
        return np.repeat(np.asarray(self.fixed, dtype=bool)[:, None], 3, axis=1)

    @property
    def free(self) -> np.ndarray:
        """Indices of the grains with a dof that is not held, ``(f,)``."""
        return np.flatnonzero(~self.held_dofs.all(axis=1))

    @property
    def n_dof(self) -> int:
        return int(np.count_nonzero(~self.held_dofs))

    def dof_index(self) -> np.ndarray:
        """``(g, 3)``: each grain's dof indices (x, y, theta) among the free dofs, -1 where held."""
        index = np.full((self.n_grains, 3), -1, dtype=np.intp)
        free = ~self.held_dofs
        index[free] = np.arange(int(np.count_nonzero(free)))
        return index

    def dof_names(self, components: tuple[str, ...] = ("x", "y", "theta")) -> list[str]:
        """``x<i>``, ``y<i>``, ``theta<i>`` of every dof that is not held, in dof order
        (``components``: other names for the three, such as ``("Fx", "Fy", "M")`` for the forces)."""
        free = ~self.held_dofs
        return [f"{c}{i}" for i in range(self.n_grains) for j, c in enumerate(components) if free[i, j]]

    def with_forces(self, normal: np.ndarray, tangential: np.ndarray) -> Packing:
        """The same packing with other contact forces."""
        tangential = np.asarray(tangential, float)
        if self.z is not None:
            vector = np.zeros((len(tangential), 3)) if tangential.ndim == 1 else tangential
            return Packing(self.x, self.y, self.radius, self.fixed, self.contacts, np.asarray(normal, float),
                           np.linalg.norm(vector, axis=1), self.source, self.held, self.friction, self.z, vector)
        return Packing(self.x, self.y, self.radius, self.fixed, self.contacts, np.asarray(normal, float),
                       tangential, self.source, self.held, self.friction)


def _first(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def validate(values: dict[str, np.ndarray], source: str = "<memory>") -> Packing:
    """A :class:`Packing` from its variables, every check made (:class:`PackingError` names the first bad entry)."""
    def fail(message: str) -> PackingError:
        return PackingError(f"{source}: {message}")

    for name in REQUIRED:
        if name not in values:
            raise fail(f"variable {name!r} is missing (a packing needs {', '.join(REQUIRED)})")
    arrays = {name: np.asarray(values[name]) for name in (*REQUIRED, *OPTIONAL, *OPTIONAL_3D) if name in values}
    if "z" not in arrays:
        extra = [name for name in OPTIONAL_3D if name in arrays]
        if extra:
            raise fail(f"variable {extra[0]!r} is given without 'z' (only a three-dimensional packing has it)")
    for name, array in arrays.items():
        if array.ndim != 1:
            raise fail(f"variable {name!r} must be one-dimensional, has shape {array.shape}")
        if not np.issubdtype(array.dtype, np.number) and array.dtype != bool:
            raise fail(f"variable {name!r} must be numeric, is {array.dtype}")
        bad = ~np.isfinite(array.astype(float))
        if bad.any():
            i = _first(bad)
            raise fail(f"variable {name!r}: entry {i} is {array[i]} (not a finite number)")
    g = len(arrays["x"])
    for name in ("y", "radius", "fixed", *(("z",) if "z" in arrays else ())):
        if len(arrays[name]) != g:
            raise fail(f"variable {name!r} has {len(arrays[name])} entries for {g} grains (dimension 'grain')")
    c = len(arrays["grain_a"])
    for name in ("grain_b", *OPTIONAL, *OPTIONAL_3D[1:]):
        if name in arrays and len(arrays[name]) != c:
            raise fail(f"variable {name!r} has {len(arrays[name])} entries for {c} contacts (dimension 'contact')")
    if g == 0:
        raise fail("the packing has no grain")
    radius = arrays["radius"].astype(float)
    if (radius <= 0).any():
        i = _first(radius <= 0)
        raise fail(f"variable 'radius': entry {i} is {radius[i]:g} (radii must be positive)")
    fixed = arrays["fixed"].astype(float)
    if not np.isin(fixed, (0.0, 1.0)).all():
        i = _first(~np.isin(fixed, (0.0, 1.0)))
        raise fail(f"variable 'fixed': entry {i} is {fixed[i]:g} (0 or 1)")
    pair = []
    for name in ("grain_a", "grain_b"):
        index = arrays[name].astype(float)
        wrong = (index != np.round(index)) | (index < 0) | (index >= g)
        if wrong.any():
            i = _first(wrong)
            raise fail(f"variable {name!r}: entry {i} is {index[i]:g}, not a grain index in 0..{g - 1}")
        pair.append(index.astype(np.intp))
    contacts = np.stack(pair, axis=1) if c else np.zeros((0, 2), dtype=np.intp)
    same = contacts[:, 0] == contacts[:, 1]
    if same.any():
        i = _first(same)
        raise fail(f"variable 'grain_b': entry {i} is {contacts[i, 1]}, the same grain as grain_a "
                   "(a grain in contact with itself)")
    x, y = arrays["x"].astype(float), arrays["y"].astype(float)
    if c:
        key = np.sort(contacts, axis=1)
        key = key[:, 0] * g + key[:, 1]
        order = np.argsort(key, kind="stable")
        repeated = np.zeros(c, dtype=bool)
        repeated[order[1:]] = key[order[1:]] == key[order[:-1]]
        if repeated.any():
            i = _first(repeated)
            raise fail(f"variable 'grain_b': entry {i} repeats the contact between grains {contacts[i, 0]} and "
                       f"{contacts[i, 1]}")
        distance = np.hypot(x[contacts[:, 1]] - x[contacts[:, 0]], y[contacts[:, 1]] - y[contacts[:, 0]])
        if "z" in arrays:
            z = arrays["z"].astype(float)
            distance = np.hypot(distance, z[contacts[:, 1]] - z[contacts[:, 0]])
        if (distance == 0).any():
            i = _first(distance == 0)
            raise fail(f"variable 'x': contact {i} joins grains {contacts[i, 0]} and {contacts[i, 1]} at the same "
                       "centre (no branch direction)")
    zeros = np.zeros(c)
    if "z" in arrays:
        return _sphere_packing(arrays, x, y, radius, fixed.astype(bool), contacts, source)
    return Packing(x, y, radius, fixed.astype(bool), contacts,
                   arrays["normal_force"].astype(float) if "normal_force" in arrays else zeros,
                   arrays["tangential_force"].astype(float) if "tangential_force" in arrays else zeros.copy(),
                   source, friction=validate_friction(values.get("friction"), c, source))


def validate_friction(value, contacts: int, source: str = "<memory>", name: str = "variable 'friction'"):
    """mu as a float or a ``(c,)`` array (None: absent); :class:`PackingError` unless finite, >= 0, scalar or per contact."""
    if value is None:
        return None
    array = np.asarray(value)
    if array.ndim > 1 or (array.ndim == 1 and len(array) != contacts):
        raise PackingError(f"{source}: {name} must be a scalar or have one entry per contact ({contacts}), "
                           f"has shape {array.shape}")
    if not np.issubdtype(array.dtype, np.number):
        raise PackingError(f"{source}: {name} must be numeric, is {array.dtype}")
    flat = np.atleast_1d(array.astype(float))
    bad = ~np.isfinite(flat) | (flat < 0)
    if bad.any():
        i = _first(bad)
        raise PackingError(f"{source}: {name}: entry {i} is {flat[i]:g} (a Coulomb ratio is a finite number >= 0)")
    return float(array) if array.ndim == 0 else array.astype(float)


def _sphere_packing(arrays, x, y, radius, fixed, contacts, source) -> Packing:
    """The 3-D packing of validated arrays (its tangential force orthogonal to the branch: checked)."""
    c = len(contacts)
    z = arrays["z"].astype(float)
    vector = np.column_stack([arrays[f"tangential_force_{k}"].astype(float) if f"tangential_force_{k}" in arrays
                              else np.zeros(c) for k in "xyz"]) if c else np.zeros((0, 3))
    if "tangential_force" in arrays:
        raise PackingError(f"{source}: variable 'tangential_force' is two-dimensional; a packing with 'z' gives "
                           "tangential_force_x, _y, _z")
    branch = np.column_stack([x[contacts[:, 1]] - x[contacts[:, 0]], y[contacts[:, 1]] - y[contacts[:, 0]],
                              z[contacts[:, 1]] - z[contacts[:, 0]]]) if c else np.zeros((0, 3))
    normal = branch / np.linalg.norm(branch, axis=1, keepdims=True) if c else branch
    along = np.abs(np.sum(vector * normal, axis=1))
    bad = along > 1e-9 * (1 + np.linalg.norm(vector, axis=1))
    if bad.any():
        i = _first(bad)
        raise PackingError(f"{source}: variable 'tangential_force_x': entry {i} (with _y, _z) has a component "
                           f"{along[i]:g} along the branch (the tangential force is orthogonal to it)")
    normal_force = arrays["normal_force"].astype(float) if "normal_force" in arrays else np.zeros(c)
    return Packing(x, y, radius, fixed, contacts, normal_force, np.linalg.norm(vector, axis=1), source, None, None, z,
                   vector)


def read_packing(path: str | Path) -> Packing:
    """Read and validate a packing file (:class:`PackingError`: exit code 2)."""
    import netCDF4

    path = Path(path)
    if not path.is_file():
        raise PackingError(f"no such packing file: {path}")
    try:
        with netCDF4.Dataset(path) as handle:
            handle.set_auto_mask(True)  # a fill (never written) or out-of-valid-range value is masked
            read = {name: handle.variables[name][...] for name in (*REQUIRED, *OPTIONAL, *OPTIONAL_3D, "friction")
                    if name in handle.variables}
            values = {name: np.asarray(np.ma.getdata(array)) for name, array in read.items()}
            dims = {name: handle.variables[name].dimensions for name in values}
    except OSError as error:
        raise PackingError(f"{path}: not a readable NetCDF packing file ({error})") from None
    masked = next((name for name, array in read.items() if np.ma.is_masked(array)), None)
    if masked is not None:
        entry = _first(np.ma.getmaskarray(read[masked]).ravel())
        raise PackingError(f"{path}: variable {masked!r}, entry {entry}: a missing (fill) value, never written")
    for name, expected in {**{n: "grain" for n in ("x", "y", "z", "radius", "fixed")},
                           **{n: "contact" for n in ("grain_a", "grain_b", *OPTIONAL, *OPTIONAL_3D[1:])}}.items():
        if name in dims and dims[name] != (expected,):
            raise PackingError(f"{path}: variable {name!r} has dimensions {dims[name]}, expected ({expected!r},)")
    if "friction" in dims and dims["friction"] not in ((), ("contact",)):
        raise PackingError(f"{path}: variable 'friction' has dimensions {dims['friction']}, expected () or ('contact',)")
    return validate(values, str(path))


def write_packing(packing: Packing, path: str | Path) -> Path:
    """Write ``packing`` as a packing file (every variable with units, long_name, description)."""
    import xarray as xr

    values = {
        "x": ("grain", packing.x), "y": ("grain", packing.y), "radius": ("grain", packing.radius),
        "fixed": ("grain", packing.fixed.astype(np.int8)),
        "grain_a": ("contact", packing.contacts[:, 0].astype(np.int32)),
        "grain_b": ("contact", packing.contacts[:, 1].astype(np.int32)),
        "normal_force": ("contact", packing.normal_force), "tangential_force": ("contact", packing.tangential_force),
    }
    if packing.friction is not None:
        values["friction"] = ((), packing.friction) if np.ndim(packing.friction) == 0 else ("contact", packing.friction)
    if packing.z is not None:
        del values["tangential_force"]
        values["z"] = ("grain", packing.z)
        vector = packing.tangential_force_vector
        values.update({f"tangential_force_{k}": ("contact", vector[:, j]) for j, k in enumerate("xyz")})
    data = xr.Dataset({name: (dim, array, dict(zip(("units", "long_name", "description"), ATTRIBUTES[name])))
                       for name, (dim, array) in values.items()},
                      attrs={"title": "ncstab packing", "Conventions": "CF-1.8",
                             "comment": "lengths in mean grain diameters, forces in k_n times that diameter"})
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data.to_netcdf(path)
    return path


def contacts_from_geometry(x: np.ndarray, y: np.ndarray, radius: np.ndarray, tolerance: float = 1e-9,
                           z: np.ndarray | None = None) -> np.ndarray:
    """Pairs of grains whose disks (spheres, with ``z``) touch or overlap (distance <= r_a + r_b + tolerance),
    ``(c, 2)``, a < b.

    A k-d tree over the centres (not all pairs), searched to twice the largest radius.
    """
    from scipy.spatial import cKDTree

    points = np.column_stack([x, y] if z is None else [x, y, z])
    pairs = cKDTree(points).query_pairs(2 * float(np.max(radius)) + tolerance, output_type="ndarray")
    if pairs.size == 0:
        return np.zeros((0, 2), dtype=np.intp)
    distance = np.linalg.norm(points[pairs[:, 1]] - points[pairs[:, 0]], axis=1)
    pairs = np.sort(pairs[distance <= radius[pairs[:, 0]] + radius[pairs[:, 1]] + tolerance], axis=1)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def triangular_lattice(rows: int, columns: int, fix_bottom: bool = False, jitter: float = 0.0,
                       seed: int = 0) -> Packing:
    """Disks of diameter 1 (radius 0.5) on a triangular lattice, ``rows x columns``, touching, zero forces.

    Grains are numbered row by row from the bottom.  ``jitter`` > 0 draws the radii
    in [0.5 (1 - jitter), 0.5] (contacts stay those of the lattice, with overlaps
    set by the smaller radii: a polydisperse packing for tests).
    """
    i, j = np.divmod(np.arange(rows * columns), columns)
    x = j + 0.5 * (i % 2)
    y = i * np.sqrt(3.0) / 2
    radius = np.full(rows * columns, 0.5)
    contacts = contacts_from_geometry(x, y, radius, tolerance=1e-9)
    if jitter:
        radius = 0.5 * (1 - jitter * np.random.default_rng(seed).random(rows * columns))
    fixed = (i == 0) if fix_bottom else np.zeros(rows * columns, dtype=bool)
    zeros = np.zeros(len(contacts))
    return Packing(x, y, radius, fixed, contacts, zeros, zeros.copy(), f"triangular lattice {rows}x{columns}")
