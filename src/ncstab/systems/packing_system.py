"""A packing followed along a loading path: the assembled system of a :class:`~ncstab.systems.packing.Packing`.

A study names a packing file (``[system] name = "packing"``, ``file = ...``;
docs/packing-paths.md) and the sparse engine follows it
(:mod:`ncstab.paths.assembled_path`) as it follows a ring or a column: the
contacts are :class:`~ncstab.elements.grain_contact.GrainContacts` between
rotating disks, an element family of the assembly
(:mod:`ncstab.operators.assembly`) beside the branches of the shipped systems.
With the contract of :mod:`ncstab.systems.packing`:

* each free grain i has three dofs, ``x<i>``, ``y<i>``, ``theta<i>`` (i its
  0-based index), conjugate to the forces ``Fx<i>``, ``Fy<i>`` and the moment
  ``M<i>``; held grains have none, and a packing's ``held`` mask may hold single
  dofs (a contact's held slots are masked, ``GrainContacts.free``);
* lengths in units of the mean grain diameter d, forces in units of k_n d,
  moments in k_n d^2; every contact's tangential motion l dbeta includes both
  grains' rotations (seed Eq. 6, 11 with beta for alpha);
* R = sum_c rho_c^2 J_c^T Q*_c and K = sum_c rho_c^2 (J_c^T D*_c J_c + sum_k Q*_ck H_ck)
  (seed Eq. 5, 9, 16, 30-34), each contact's rest length rho and reference
  angle alpha0 chosen for the case's law and gamma so that the law's forces at
  u = 0 are the packing's
  (:func:`~ncstab.operators.packing_analysis.contact_references`): the path
  starts from the packing's stressed state.  A rate law's internal variables
  start at the packing's forces (N/rho, T/rho);
* the external forces at u = 0 are F = R(0), which balance the contact forces;
  a loading stage's uncontrolled dofs keep their force where it is when the
  stage starts (:attr:`~ncstab.systems.assembled.AssembledSystem.hold_other_forces`).

New contacts are not detected: the contacts are those of the file, each one
bilateral unless its law says otherwise (``+no_tension``).  A contact between
two held grains moves nothing and is left out.
"""

from __future__ import annotations

import dataclasses
import functools
import os
from pathlib import Path
from typing import Any

import numpy as np

from ncstab.elements.grain_contact import GrainContacts
from ncstab.systems.assembled import AssembledSystem
from ncstab.systems.definition import SystemUnits
from ncstab.systems.packing import Packing, PackingError, read_packing

__all__ = ["PACKING_UNITS", "assembled_packing", "packing_file_problem", "packing_system",
           "resolve_packing_file"]

#: Units of a packing's dofs and forces (docs/packings.md).
PACKING_UNITS = SystemUnits(
    displacement="d (x, y); rad (theta)",
    displacement_description="displacement of each free grain's centre / d (x<i>, y<i>) and its rotation, "
    "counter-clockwise (theta<i>); d the mean grain diameter",
    force="k_n d (Fx, Fy); k_n d^2 (M)",
    force_description="external force on each free grain / (k_n d) (Fx<i>, Fy<i>) and moment / (k_n d^2) "
    "(M<i>), conjugate to its dofs; at u = 0 they balance the packing's contact forces",
    work_description="work of the external forces, in units of k_n d^2",
    force_unit="k_n d",
)
#: The seed, and where the rotating contact is written out.
REFERENCE = ("Challamel, Nicot, Wautier, Darve & Lerbet (2022), J. Eng. Mech. 148(9) 04022053; "
             "contacts between rotating grains: docs/packings.md")


def resolve_packing_file(value: Any, base: str | os.PathLike[str] | None) -> Any:
    """``[system] file`` relative to the study file's folder ``base`` (absolute paths kept);
    anything but a string is returned as it is (its check says what is wrong)."""
    if not isinstance(value, str) or not value.strip():
        return value
    path = Path(value).expanduser()
    if not path.is_absolute():
        path = Path(base if base is not None else os.getcwd()) / path
    return str(path.resolve())


@functools.lru_cache(maxsize=16)
def _read(path: str, stamp: tuple[int, int]) -> Packing:
    """The packing of ``path``, read once per version of the file (``stamp``: its mtime and size)."""
    return read_packing(path)


def _packing_of(path: str) -> Packing:
    try:
        info = os.stat(path)
    except OSError:
        raise PackingError(f"no such packing file: {path}") from None
    return _read(path, (info.st_mtime_ns, info.st_size))


def packing_file_problem(value: Any) -> str | None:
    """``None`` where ``value`` names a readable, valid packing file with a free grain, else
    what to give instead (the check of the ``file`` setting, ``[system] file``)."""
    if not isinstance(value, str) or not value.strip():
        return "the path of a packing file (a string, relative to the study file; docs/packings.md)"
    try:
        packing = _packing_of(value)
    except PackingError as error:
        return f"a valid packing file ({error})"
    if packing.n_dof == 0:
        return f"a packing with a free grain ({value}: every grain is held, variable 'fixed')"
    return None


def packing_system(file: str) -> AssembledSystem:
    """The system of the packing file ``file`` (an absolute path), without its law: each case's
    contacts are set for its law and parameters (:func:`assembled_packing`)."""
    system = assembled_packing(_packing_of(file))
    return dataclasses.replace(system, settings=(("file", file),))


def _contacts(packing: Packing, keep: np.ndarray, scale: np.ndarray) -> GrainContacts:
    """The contacts ``keep`` on the dofs that are not held; a held dof's slot is masked (pointed
    at a dof of the same contact, whose value it never reads: K keeps its sparsity)."""
    index = packing.dof_index()
    a, b = packing.contacts[keep, 0], packing.contacts[keep, 1]
    dofs = np.concatenate([index[a], index[b]], axis=1)
    free = dofs >= 0
    first = dofs[np.arange(len(dofs)), np.argmax(free, axis=1)]
    dofs = np.where(free, dofs, first[:, None])
    branch = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
    total = packing.radius[a] + packing.radius[b]
    lever = np.column_stack([packing.radius[a] / total, packing.radius[b] / total])
    labels = tuple(f"{i}_{j}" for i, j in zip(a.tolist(), b.tolist()))
    return GrainContacts(dofs, branch, lever, np.asarray(scale, dtype=float), free, labels)


def _case(packing: Packing, keep: np.ndarray, system: AssembledSystem, law: Any,
          values: dict[str, float]) -> AssembledSystem:
    """The system of one case: rho and alpha0 per contact such that ``law`` with the case's
    ``gamma`` carries the packing's forces at u = 0 (seed laws: rho = |d| + N)."""
    from ncstab.elements.law_response import law_response
    from ncstab.operators.packing_analysis import contact_references

    rho, alpha0 = contact_references(packing, law_response(law), float(values.get("gamma", 1.0)))
    rho, alpha0 = rho[keep], alpha0[keep]
    given = np.column_stack([packing.normal_force[keep], packing.tangential_force[keep]])
    return dataclasses.replace(system, contacts=_contacts(packing, keep, rho), contact_alpha0=alpha0,
                               contact_forces=given / rho[:, None], case_system=None)


def assembled_packing(packing: Packing, law: Any = None, values: dict[str, float] | None = None) -> AssembledSystem:
    """The assembled system of ``packing`` (see the module docstring).

    Parameters
    ----------
    packing
        The packing (:func:`~ncstab.systems.packing.read_packing`).
    law
        A contact law (a definition or a name): the system of that law and ``values``
        (each contact's rho, alpha0 and starting forces set); ``None``: the system
        whose cases set them (what a study follows; rho = |d| + N and alpha0 = the
        branch angle until then).
    values
        The case's parameters (``gamma``; default 1).

    Raises
    ------
    PackingError
        Every grain held, or forces the law cannot carry (exit code 2).
    """
    if packing.n_dof == 0:
        raise PackingError(f"{packing.source}: every grain is held (variable 'fixed'): no dof to follow")
    held = packing.held_dofs.all(axis=1)  # grains whose three dofs are held
    keep = np.flatnonzero(~(held[packing.contacts[:, 0]] & held[packing.contacts[:, 1]]))
    given = np.column_stack([packing.normal_force[keep], packing.tangential_force[keep]])
    a, b = packing.contacts[keep, 0], packing.contacts[keep, 1]
    rho = np.hypot(packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]) + given[:, 0]
    if np.any(rho <= 0):
        i = int(keep[np.flatnonzero(rho <= 0)[0]])
        raise PackingError(f"{packing.source}: variable 'normal_force': entry {i} is a tension longer than "
                           "its contact (no rest length)")
    if len(keep) == 0:
        raise PackingError(f"{packing.source}: no contact touches a free grain (variables 'grain_a', 'grain_b')")
    free = packing.free
    system = AssembledSystem(
        name="packing",
        title=f"packing of {packing.n_grains} grains ({len(free)} free) and {len(keep)} contacts, "
        f"from {packing.source}",
        dofs=tuple(packing.dof_names()),
        forces=tuple(packing.dof_names(("Fx", "Fy", "M"))),
        contacts=_contacts(packing, keep, rho),
        contact_alpha0=np.arctan2(packing.y[b] - packing.y[a], packing.x[b] - packing.x[a]),
        contact_forces=given / rho[:, None],
        units=PACKING_UNITS,
        reference=REFERENCE,
        case_system=functools.partial(_case, packing, keep),
        hold_other_forces=True,
    )
    if law is None:
        return system
    if isinstance(law, str):
        from ncstab.laws.registry import law_definition

        law = law_definition(law)
    return system.for_values(dict(values or {}), law)
