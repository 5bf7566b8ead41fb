"""The archive variables of friction and of ``--probe`` (``ncstab analyse``), and the parsing of ``--probe``."""

from __future__ import annotations

from typing import Any

import numpy as np

from ncstab.studies.errors import InvalidInputError

__all__ = ["friction_variables", "parse_probe"]

STIFFNESS = "k_n (per mean grain diameter for x, y; times it for theta)"
PER_DOF = "x, y: mean grain diameter; theta: rad"
FORCE = "k_n mean grain diameter (theta: times the diameter)"


def _attrs(units: str, long_name: str, description: str, **more: Any) -> dict[str, Any]:
    return {"units": units, "long_name": long_name, "description": description, **more}


def parse_probe(text: str | dict[str, float], names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """``"x3=1e-4,theta3=0"`` (or a mapping) as the prescribed free dofs' indices and values (exit 2 if malformed)."""
    if isinstance(text, dict):
        entries = [(str(k), v) for k, v in text.items()]
    else:
        entries = []
        for item in str(text).split(","):
            name, sep, value = item.partition("=")
            if not sep:
                raise InvalidInputError(f"--probe: {item.strip()!r} is not DOF=VALUE")
            entries.append((name.strip(), value.strip()))
    position = {name: i for i, name in enumerate(names)}
    indices, values = [], []
    for name, value in entries:
        if name not in position:
            raise InvalidInputError(f"--probe: {name!r} is not a free dof of the packing (x<i>, y<i>, theta<i>)")
        if position[name] in indices:
            raise InvalidInputError(f"--probe: {name!r} is given twice")
        try:
            number = float(value)
        except ValueError:
            raise InvalidInputError(f"--probe: {name}={value!r} is not a number") from None
        if not np.isfinite(number):
            raise InvalidInputError(f"--probe: {name}={value!r} is not a finite number")
        indices.append(position[name])
        values.append(number)
    if not indices:
        raise InvalidInputError("--probe: no dof given")
    return np.array(indices, dtype=np.intp), np.array(values)


def _state_attrs(description: str) -> dict[str, Any]:
    from ncstab.operators.friction_branches import OPEN_TOLERANCE, SLIDING_TOLERANCE

    return _attrs("1", "contact state", description, flag_values=np.array([0, 1, 2], dtype=np.int8),
                  flag_meanings="stick slide open", sliding_tolerance=SLIDING_TOLERANCE,
                  open_tolerance=OPEN_TOLERANCE,
                  tolerance_rule="slide: |T| >= mu N (1 - sliding_tolerance); open: N <= open_tolerance max |N|")


def friction_variables(packing, tangent, mu, probe: tuple[np.ndarray, np.ndarray] | None):
    """Friction's variables (mu given) and the probe's (``probe`` given) as an ``xarray.Dataset``."""
    import xarray as xr

    from ncstab.operators.consistent_hill import consistent_hill
    from ncstab.operators.friction_branches import friction_branches
    from ncstab.operators.incremental_probe import incremental_probe

    branches = friction_branches(tangent, mu)
    data: dict[str, Any] = {}
    attrs: dict[str, Any] = {}
    if mu is not None:
        found = consistent_hill(branches)
        data.update({
            "friction": (("contact",), branches.mu, _attrs("1", "Coulomb friction ratio mu",
                                                          "from the packing's 'friction' or --friction")),
            "contact_state": (("contact",), branches.state, _state_attrs(
                "each contact's state at the packing's forces: 0 stick (|T| < mu N), 1 slide (on the Coulomb "
                "cone), 2 open (N <= 0)")),
            "sliding_contacts": ((), np.int32(np.sum(branches.state == 1)), _attrs(
                "1", "sliding contacts", "count of contacts on the Coulomb cone (contact_state 1)")),
            "open_contacts": ((), np.int32(np.sum(branches.state == 2)), _attrs(
                "1", "open contacts", "count of contacts with N <= 0 (contact_state 2)")),
            "hill": ((), found.value, _attrs(
                STIFFNESS, "Hill's second-order work on the consistent branch",
                "smallest d^T K(d) d / d^T d found over unit d, each contact on the branch d selects (active-set "
                "search over branch patterns from the sticking and all-sliding eigenvectors; an upper bound of "
                "the true minimum, docs/friction.md)", patterns_visited=found.patterns,
                search_converged=np.int8(found.converged))),
            "hill_direction": (("dof",), found.direction, _attrs(
                PER_DOF, "direction of Hill's minimum", "unit direction over the free dofs where hill is reached; "
                "its branches are verified consistent")),
            "hill_sticking": ((), found.sticking, _attrs(
                STIFFNESS, "Hill's eigenvalue with every contact sticking",
                "smallest eigenvalue of K_sym = (K + K^T)/2 with every contact elastic")),
        })
    if probe is not None:
        response = incremental_probe(branches, *probe)
        data.update({
            "probe_du": (("dof",), response.du, _attrs(
                PER_DOF, "incremental displacement of the probe",
                "the prescribed increments on the probe's dofs, the response elsewhere (their dF = 0)")),
            "probe_dF": (("dof",), response.dF, _attrs(
                FORCE, "incremental force of the probe", "K(du) du: the force increments needed on the prescribed "
                "dofs, 0 on every other free dof", method=response.method, solutions=np.int32(response.solutions),
                solutions_rule="distinct consistent responses over every branch pattern; -1: not counted")),
            "probe_contact_state": (("contact",), branches.full_state(response.pattern), _state_attrs(
                "each contact's branch in the probe's increment: 0 stick (elastic), 1 slide, 2 open (separating)")),
        })
    return xr.Dataset({name: (dims, value, a) for name, (dims, value, a) in data.items()}, attrs=attrs)
