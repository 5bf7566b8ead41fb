"""The signs of det K, det K_SS, the bordered determinant and Hill's eigenvalue on a trivial
path, exact where the rounding of K's assembled entries hides them.

On a trivial path of a load-parameter stage (u = 0 while P grows: Hencky's straight column)
K = K_int - P K_load, and the critical eigenvalue of a long column is tiny: (pi/n)^4 ~ 1.6e-13
at 5,000 links against entries of K of order 6 (the transverse displacements make K a fourth
difference, of condition number about n^4).  K's entries are rounded at 1e-15, so a
factorization of K gives that eigenvalue, and det K's sign with it, no certain sign: the
buckling load would not be found.  Two things are computed without that cancellation:

* the critical eigenvalue itself, as the Rayleigh quotient of its eigenvector phi (unit) in
  element form, lambda = phi^T K_int phi - P phi^T K_load phi
  (:func:`ncstab.operators.assembly.energy_forms`: sums of (J_e phi)^T D (J_e phi) and
  (a_i . phi)^2, no cancellation; second-order accurate in phi's error);
* the sign of the product of the *other* eigenvalues, from the matrix determinant lemma:
  K + c phi phi^T moves lambda to lambda + c (c = max |K_ij| > 0, a certain sign), and
  det(K + c phi phi^T) = det K (1 + c phi^T K^-1 phi), where det K and K^-1 come from the same
  LU so that its rounding of lambda cancels: sign(rest) = sign(det K) sign(1 + c phi^T K^-1 phi).

Then sign det K = sign(rest) sign(lambda).  On such a path dR/dP = 0 and the tangent is
(0, t_P), so the bordered determinant is det K_SS t_P.  Used only where Hill's eigenvalue is
within rounding of zero (:data:`ncstab.paths.events.SIGN_NOISE`) and K_SS is
symmetric; the indicators say so with ``exact = 1.0``.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as splinalg

from ncstab.operators.assembly import energy_forms
from ncstab.operators.sparse_indicators import critical_eigenvalue, is_symmetric, lu_determinant

__all__ = ["is_trivial", "trivial_path_signs"]


def is_trivial(stepper, p) -> bool:
    """p lies on a trivial path of a load-parameter stage: u = 0 exactly and R does not move with P."""
    if not stepper.control.load_stage or np.any(p.u):
        return False
    return not np.any(p.state.dR_dload)


def _rest_sign(K_SS, phi: np.ndarray, c: float) -> float:
    """sign of the product of K_SS's eigenvalues other than phi's (the determinant lemma)."""
    if sparse.issparse(K_SS):
        try:
            lu = splinalg.splu(K_SS.tocsc())
        except RuntimeError:  # exactly singular: the lemma's LU does not exist
            return 0.0
        sign, _ = lu_determinant(lu)
        return float(sign * np.sign(1.0 + c * phi @ lu.solve(phi)))
    A = np.asarray(K_SS)
    sign = np.linalg.slogdet(A)[0]
    if sign == 0:
        return 0.0
    return float(sign * np.sign(1.0 + c * phi @ np.linalg.solve(A, phi)))


def trivial_path_signs(stepper, p, out: dict, noise: float) -> None:
    """Replace ``out``'s det, det_SS, bordered and hill by their exact values on a trivial path
    where Hill's eigenvalue is within ``noise`` (a part of max |K_ij|) of zero; mark ``exact``."""
    run, control, m = stepper.run, stepper.control, stepper.m
    K_SS, _ = run.blocks(control, p.state, stepper.lam(p.y))
    scale = float(abs(K_SS).max()) if K_SS.shape[0] else 0.0
    if scale == 0.0 or abs(out["hill"]) > noise * scale or not is_symmetric(K_SS):
        return
    _, phi = critical_eigenvalue(K_SS)
    vector = np.zeros(run.n)
    vector[control.force_dofs] = phi
    inner, outer = energy_forms(run.system, run.law, run.parameters, p.u, p.internal, vector, vector,
                                run.closed, run.kappa)
    value = inner - stepper.lam(p.y) * outer  # phi^T K phi, phi unit: the critical eigenvalue
    rest = _rest_sign(K_SS, phi, scale)
    if not np.isfinite(value) or rest == 0.0:
        return
    sign_SS = rest * float(np.sign(value))
    out["det_SS"] = sign_SS
    if m == run.n:
        out["det"] = sign_SS
        out["hill"] = float(value)  # K_sym = K = K_SS: Hill's eigenvalue is the critical one
    out["bordered"] = sign_SS * float(np.sign(p.tangent[m])) if p.tangent is not None else out["bordered"]
    out["exact"] = 1.0
