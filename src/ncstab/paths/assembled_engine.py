"""The sparse engine: one case of an assembled system followed along its programme.

For systems of any size (:class:`~ncstab.systems.assembled.AssembledSystem`):
pseudo-arclength continuation of G(y) = 0, y = (u_S, lambda / lambda_scale)
(:mod:`ncstab.paths.assembled_control`), each step an Euler predictor along
the unit tangent and a Newton corrector on the hyperplane orthogonal to it,
with the bordered Jacobian [[dG/dy], [t^T]] factorized sparse (SuperLU) or
dense (Keller 1977; the AUTO-07p and BifurcationKit.jl formulation).  A
rate-form law's internal variables are integrated over each step by the
explicit midpoint rule in the increments of its members' variables (a DEM
code's update, second order in the step).

After every accepted step the indicators of the archive's events (docs/archive.md) are
compared with the step's start (:mod:`ncstab.paths.assembled_events`); a sign
change is located on the step length by the Illinois iteration the compiled
loop uses too (:mod:`ncstab.paths.bracket`), each trial re-corrected onto the
path.  det K changes sign at a limit point; where the bordered
Jacobian's determinant changes sign too the point is a simple bifurcation
(its tangent space is two-dimensional: the sign of det [[G_y], [t^T]] flips
along a branch through a branch point and not at a fold).  With
``at_bifurcation = "switch"`` the path leaves along the bifurcating branch:
the root of the algebraic bifurcation equation in the plane of the incoming
tangent and (phi, 0), phi the null vector of K_SS, solved by the compiled
route's function (:func:`ncstab.paths.branch_switching.branch_direction`).
Cost per step: a few sparse factorizations, linear in n for banded K.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse.linalg as splinalg

from ncstab.elements import law_response
from ncstab.operators.assembly import AssembledState, assemble
from ncstab.paths.assembled_control import StageControl
from ncstab.paths.options import PathOptions
from ncstab.systems.assembled import AssembledSystem

__all__ = ["CaseRun", "DomainError", "Point"]

#: Largest change of lambda / lambda_scale in one step (figures resolve the stage).
MAX_LAMBDA_STEP = 0.02
#: Largest change of any dof in one step: this part of max(1, |u|_inf) (events and gaps resolved).
MAX_RELATIVE_MOVE = 0.05
#: Largest relative residual of a tangent from block elimination (else the bordered Jacobian whole).
TANGENT_RESIDUAL = 1e-12
#: Reach of the neighbour search for secondary contacts (units 2R); steps move a grain less.
GAP_REACH = 0.5


class DomainError(ArithmeticError):
    """A trial state outside the system's domain (a bar at right angles to the axis)."""


@dataclass
class Point:
    """A converged state on the path: y, u, load, the assembled state, internal forces, tangent."""

    y: np.ndarray
    u: np.ndarray
    load: float
    state: AssembledState
    internal: dict[str, np.ndarray]
    tangent: np.ndarray | None = None
    indicators: dict[str, float] = field(default_factory=dict)
    #: The indicators as computed, before a sign within rounding was replaced by the last
    #: certain one (:func:`ncstab.paths.assembled_events._steady`); None: the same as ``indicators``.
    raw: dict[str, float] | None = None
    #: 0 on the path followed from the start; +1 or -1 from the simple bifurcation point the
    #: case left along the bifurcating branch, that way (the Dataset's ``branch_index``).
    branch: int = 0


class CaseRun:
    """Everything one case needs: the system, law, parameter values, options, contacts."""

    def __init__(self, system: AssembledSystem, law: Any, values: dict[str, float], options: PathOptions,
                 secondary_contacts: str) -> None:
        self.system, self.law, self.values, self.options = system, law, values, options
        self.mode = secondary_contacts
        self.kappa = float(values.get("kappa", 1.0))
        self.parameters = {k: float(v) for k, v in values.items()}
        self.n = system.n_dof
        self.dense = self.n <= 64
        self.closed = np.zeros((0, 2), dtype=np.intp)
        self.responses = {}
        if system.contacts is not None:
            self.responses["contacts"] = law_response(law)
        if system.springs is not None:
            self.responses["springs"] = law_response(system.spring_law)

    # --- states -----------------------------------------------------------------------
    def initial_internal(self) -> dict[str, np.ndarray]:
        """The stored forces at the start, u = 0: the system's ``contact_forces`` where it
        gives them (a packing's contacts carry its forces), else zero."""
        out = {}
        if self.system.contacts is not None:
            given = self.system.contact_forces
            shape = (self.system.contacts.size, self.responses["contacts"].forces)
            out["contacts"] = np.zeros(shape) if given is None else np.array(given, dtype=float).reshape(shape)
        if self.system.springs is not None:
            out["springs"] = np.zeros((self.system.springs.size, self.responses["springs"].forces))
        return out

    def advance(self, start: Point | None, u: np.ndarray, velocity: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Internal forces at u from the step's start, or zeros before the first state.

        A rate-form law's internal variables obey df = C(q, f) dq (seed Eq. 13-15), whose
        integral depends on the path between the two states.  Over a step the path is taken as
        the quadratic u(sigma) = u_start + sigma v + sigma^2 (u - u_start - v), v = du/dsigma at
        the start (the step's length times the path tangent there), which follows the arc to
        O(h^3) over a step of length h; without ``velocity`` (a stage's first state) the chord
        (v = u - u_start).  q(sigma) are the members' exact kinematics on it and f is integrated
        in sigma by the classical fourth-order Runge-Kutta rule, dq/dsigma = J(u(sigma)) u'(sigma).
        The area between the arc and its quadratic is O(h^4) a step: the forces are third order in
        the step along a path (second order along chords; measured in the tests).
        """
        if start is None:
            return self.initial_internal()
        out = {}
        chord = u - start.u
        v = chord if velocity is None else velocity
        bend = chord - v
        for family, response in self.responses.items():
            f0 = start.state.members[family]["f"]
            if not response.internal:
                out[family] = f0
                continue
            values = {**self.parameters, **({"alpha0": self.system.contact_alpha0} if family == "contacts" else {})}
            dofs = start.state.members[family]["dofs"]

            def rate(sigma: float, f: np.ndarray) -> np.ndarray:
                q, J = self._kinematics(family, start.u + sigma * v + sigma * sigma * bend)
                _, _, C = response.response(q, response.stored_forces(q, f, values), values)
                return np.einsum("mfk,mk->mf", C, np.einsum("mkl,ml->mk", J, (v + 2 * sigma * bend)[dofs]))

            k1 = rate(0.0, f0)
            k2 = rate(0.5, f0 + 0.5 * k1)
            k3 = rate(0.5, f0 + 0.5 * k2)
            k4 = rate(1.0, f0 + k3)
            out[family] = f0 + (k1 + 2 * k2 + 2 * k3 + k4) / 6.0
        return out

    def _kinematics(self, family: str, u: np.ndarray):
        if family == "contacts":
            return self.system.contacts.kinematics(u, second=False)[:2]
        return self.system.springs.kinematics(u, second=False)[:2]

    def evaluate(self, u: np.ndarray, load: float, internal: dict[str, np.ndarray]) -> AssembledState:
        bars = self.system.axial_load
        if bars is not None:
            rise = np.einsum("bk,bk->b", bars.rise_signs, u[bars.rise_dofs])
            if np.any(np.abs(rise) >= 1.0):
                raise DomainError(f"bar {int(np.argmax(np.abs(rise))) + 1} at right angles to the axis")
        springs = self.system.springs
        if springs is not None and hasattr(springs, "rises"):  # bars whose rise is linear in the dofs
            rises = np.einsum("mkl,ml->mk", springs.rises, u[springs.dofs])
            if np.any(np.abs(rises) >= 1.0):
                raise DomainError("a bar at right angles to the axis")
        return assemble(self.system, self.law, self.parameters, u, internal, load, self.closed, self.kappa, self.dense)

    # --- the bordered system ------------------------------------------------------------
    def blocks(self, control: StageControl, state: AssembledState, lam: float):
        """K_SS and the column dG/d(lambda / scale)."""
        S, D = control.force_dofs, control.displacement_dofs
        K = state.K
        if self.dense:
            K_SS = K[np.ix_(S, S)]
            column = K[np.ix_(S, D)] @ control.u_slope
        else:
            rows = K[S]
            K_SS = rows[:, S]
            column = rows[:, D] @ control.u_slope
        if control.load_stage:  # dR/dlambda = dR/dP dP/dlambda
            column = column + state.dR_dload[S] * control.load_slope
        column = (column - control.f_slope) * control.scale
        return K_SS, column

    def bordered(self, K_SS, column: np.ndarray, last: np.ndarray):
        """The bordered Jacobian [[K_SS, column], [last]]: dense, or its parts for block elimination."""
        if self.dense:
            return np.block([[K_SS, column[:, None]], [last[None, :]]])
        return (splinalg.splu(K_SS.tocsc()), K_SS, column, last)

    def solve(self, A, right: np.ndarray) -> np.ndarray:
        """Solve with the bordered Jacobian.  Sparse: block elimination on K_SS's LU (Keller's
        bordering algorithm; K_SS keeps its band, the dense border row costs nothing), with one
        step of iterative refinement."""
        if self.dense:
            return np.linalg.solve(A, right)
        lu, K_SS, column, last = A
        m = len(column)

        def once(r: np.ndarray) -> np.ndarray:
            x1 = lu.solve(r[:m])
            x2 = lu.solve(column)
            z = (r[m] - last[:m] @ x1) / (last[m] - last[:m] @ x2)
            return np.append(x1 - z * x2, z)

        x = once(right)
        residual = right - np.append(K_SS @ x[:m] + column * x[m], last @ x)
        return x + once(residual)

    def solve_tangent(self, A, right: np.ndarray) -> np.ndarray:
        """Solve for the path tangent: block elimination on K_SS's LU where it is accurate (its
        residual within :data:`TANGENT_RESIDUAL` of the right-hand side: O(n) for banded K), else
        the bordered Jacobian factorized whole (next to a bifurcation, where K_SS is nearly
        singular and the two eliminated solves cancel)."""
        if self.dense:
            return np.linalg.solve(A, right)
        x = self.solve(A, right)
        _, K_SS, column, last = A
        m = len(column)
        residual = right - np.append(K_SS @ x[:m] + column * x[m], last @ x)
        if np.linalg.norm(residual) <= TANGENT_RESIDUAL * np.linalg.norm(right) and np.all(np.isfinite(x)):
            return x
        return self.solve_exactly(A, right)

    def solve_exactly(self, A, right: np.ndarray) -> np.ndarray:
        """Solve with the bordered Jacobian factorized whole (SuperLU with partial pivoting):
        accurate where K_SS is nearly singular (next to a bifurcation), at the price of the
        border's fill; used for the path tangent, whose lambda component decides turning points."""
        if self.dense:
            return np.linalg.solve(A, right)
        import scipy.sparse as sparse

        _, K_SS, column, last = A
        whole = sparse.bmat([[K_SS, sparse.csr_matrix(column[:, None])],
                             [sparse.csr_matrix(last[None, :-1]), sparse.csr_matrix(last[None, -1:])]], format="csc")
        return splinalg.splu(whole).solve(right)

    def bordered_sign(self, A) -> float:
        """sign det of the bordered Jacobian (det K_SS times its Schur complement)."""
        from ncstab.operators.sparse_indicators import lu_determinant

        if self.dense:
            return float(np.linalg.slogdet(A)[0])
        lu, _, column, last = A
        m = len(column)
        sign, _ = lu_determinant(lu)
        return float(sign * np.sign(last[m] - last[:m] @ lu.solve(column)))

