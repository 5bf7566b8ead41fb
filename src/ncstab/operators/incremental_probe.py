"""The incremental response to prescribed dof increments, each contact on its consistent branch.

Prescribed increments du_p on the dofs p; every other free dof f keeps its force (dF_f = 0).  For a
branch pattern P (:mod:`ncstab.operators.friction_branches`) the response is linear::

    K_P[f, f] du_f = -K_P[f, p] du_p,      dF = K_P du,

and it is the response when du lies in P's cone (every contact on the branch du selects).  That is a
piecewise-linear complementarity problem over the contacts at the limit, solved exactly by an
active-set iteration (start: every contact sticking; P <- P(du) until P(du) = P) and, where that
cycles or does not converge, by enumeration of every pattern when there are at most
ENUMERATION_LIMIT patterns.  With at most COUNT_LIMIT patterns every pattern is also tried, so that
the number of consistent solutions is known (``solutions``; -1: not counted); with several, the
active set's is returned (the first from the sticking start), else the first in enumeration order.
No consistent solution: :class:`ProbeError` (exit code 3).  The response is positively homogeneous
of degree one: the branches depend on the direction of du only.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from ncstab.operators.friction_branches import FrictionBranches
from ncstab.studies.errors import RunError

__all__ = ["COUNT_LIMIT", "ENUMERATION_LIMIT", "ProbeError", "ProbeResponse", "incremental_probe"]

#: Every pattern is tried (solutions counted) up to this many patterns.
COUNT_LIMIT = 256
#: The fallback enumeration runs up to this many patterns.
ENUMERATION_LIMIT = 65536


class ProbeError(RunError):
    """No consistent incremental response (or a singular K_P[f, f]): exit code 3."""


@dataclass(frozen=True)
class ProbeResponse:
    """du ``(n,)``, dF ``(n,)``, the limit contacts' pattern ``(k,)``, how it was found and how many solutions."""

    du: np.ndarray
    dF: np.ndarray
    pattern: np.ndarray
    method: str
    solutions: int
    iterations: int


def _solve(branches: FrictionBranches, pattern: np.ndarray, prescribed: np.ndarray, values: np.ndarray):
    import scipy.sparse.linalg as splinalg

    K = branches.tangent(pattern)
    n = branches.n
    free = np.setdiff1d(np.arange(n), prescribed)
    du = np.zeros(n)
    du[prescribed] = values
    if len(free):
        Kff = K[free][:, free].tocsc()
        rhs = -(K[free][:, prescribed] @ values)
        try:
            if len(free) <= 600:
                du[free] = np.linalg.solve(Kff.toarray(), rhs)
            else:
                du[free] = splinalg.splu(Kff).solve(rhs)
        except (np.linalg.LinAlgError, RuntimeError):
            return None
        if not np.all(np.isfinite(du)):
            return None
    return du, K @ du


def incremental_probe(branches: FrictionBranches, prescribed: np.ndarray, values: np.ndarray,
                      max_iterations: int = 100) -> ProbeResponse:
    """Solve the incremental equilibrium (module docstring) for ``values`` of the dofs ``prescribed``."""
    prescribed = np.asarray(prescribed, dtype=np.intp)
    values = np.asarray(values, dtype=float)
    choices = branches.choices()
    count = int(np.prod([len(c) for c in choices])) if choices else 1
    found = None
    pattern = branches.sticking()
    seen: set[bytes] = set()
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        solved = _solve(branches, pattern, prescribed, values)
        if solved is None:
            break
        selected = branches.select(solved[0])
        if branches.consistent(solved[0], pattern):
            found = (solved, pattern)
            break
        seen.add(pattern.tobytes())
        if selected.tobytes() in seen:
            break
        pattern = selected
    solutions = -1
    if count <= COUNT_LIMIT or (found is None and count <= ENUMERATION_LIMIT):
        consistent = []
        for combination in itertools.product(*choices):
            candidate = np.array(combination, dtype=np.int8)
            solved = _solve(branches, candidate, prescribed, values)
            if solved is not None and branches.consistent(solved[0], candidate):
                consistent.append((solved, candidate))
        if count <= COUNT_LIMIT:
            solutions = _distinct(consistent)
        if found is None and consistent:
            found = consistent[0]
            return ProbeResponse(found[0][0], found[0][1], found[1], "enumeration", solutions, iterations)
    if found is None:
        raise ProbeError("--probe: no incremental response with every contact on a consistent branch "
                         f"({len(branches.limit)} contacts at the Coulomb limit or open, {count} patterns"
                         f"{' tried' if count <= ENUMERATION_LIMIT else ', too many to enumerate'})",
                         "nothing was written")
    return ProbeResponse(found[0][0], found[0][1], found[1], "active set", solutions, iterations)


def _distinct(consistent: list) -> int:
    """Distinct responses among the consistent patterns (patterns on a common boundary give the same du)."""
    responses: list[np.ndarray] = []
    for (du, _), _pattern in consistent:
        scale = max(float(np.max(np.abs(du))), 1e-300)
        if not any(np.max(np.abs(du - other)) <= 1e-9 * scale for other in responses):
            responses.append(du)
    return len(responses)
