"""DEM codes' tangential (shear) updates, replayed step by step on one planar contact.

Each function here is one code's update of its stored tangential spring,
transcribed from its source (docs/dem-codes.md gives the file, function and
version read) and written for the diamond's contact: planar, no grain spin,
equal radii, dimensionless (seed Eq. 37: lengths in units of 2R, forces in
units of 2R k_n, k_t = gamma).  Friction (the Coulomb cap) and viscous damping
are left out: the chain is elastic.

The contact is the top grain seen from the left grain: its branch vector is
b = l n with n = (cos alpha, sin alpha) and t = (-sin alpha, cos alpha) = dn/dalpha.
The force of the left grain on the top grain is N n - T t (seed Eq. 4), so the
stored shear force on the top grain is G = -T t (plus, for a code that lets
it leave the tangent plane, a normal part N_s n).  A DEM step moves the top
grain by Delta = b_new - b_old relative to the left grain (a velocity times
the time step); the codes read the normal at the new position.

:func:`replay` runs a rule along a sampled kinematic path and returns T and
N_s after every step: the evidence of docs/dem-codes.md (which seed law each
rule reduces to as the step shrinks, and how fast) comes from it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["RULES", "replay"]

Update = Callable[[np.ndarray, np.ndarray, np.ndarray, float], np.ndarray]


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def _tangential(vector: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """The part of ``vector`` in the tangent plane of ``normal`` (a unit vector)."""
    return vector - (vector @ normal) * normal


def _cross_z(a: np.ndarray, b: np.ndarray) -> float:
    """z component of a x b for planar vectors."""
    return float(a[0] * b[1] - a[1] * b[0])


def project(shear: np.ndarray, old: np.ndarray, new: np.ndarray, gamma: float) -> np.ndarray:
    """LIGGGHTS ``tangential_model_history.h``, LAMMPS ``pair_gran_hooke_history.cpp``
    (and ``linear_history_classic``), Chrono::Multicore: the spring grows by the
    tangential relative displacement, then its normal part is removed."""
    n = _unit(new)
    grown = shear - gamma * _tangential(new - old, n)
    return _tangential(grown, n)


def rotate_rescale(shear: np.ndarray, old: np.ndarray, new: np.ndarray, gamma: float) -> np.ndarray:
    """LAMMPS ``gran_sub_mod_tangential.cpp`` (``linear_history``): the spring is projected
    on the new tangent plane and rescaled to its former length, then grows.
    (LAMMPS skips the frame update when |S.n| k <= 1e-10 mu F_n; not modelled.)"""
    n = _unit(new)
    projected = _tangential(shear, n)
    length = np.linalg.norm(projected)
    rotated = projected * (np.linalg.norm(shear) / length) if length > 0 else projected
    return rotated - gamma * _tangential(new - old, n)


def _yade(scaled: bool) -> Update:
    def update(shear: np.ndarray, old: np.ndarray, new: np.ndarray, gamma: float) -> np.ndarray:
        n_old, n = _unit(old), _unit(new)
        axis = _cross_z(n_old, n)  # ScGeom::precompute: orthonormal_axis = normal x currentNormal
        # ScGeom::rotate: shearForce -= shearForce x orthonormal_axis (axis along z, planar force)
        rotated = shear - np.array([shear[1] * axis, -shear[0] * axis])
        # ScGeom::getIncidentVel: the relative velocity times (R1 + R2)/(R1 + R2 - overlap) = 1/l*
        scale = 1.0 / np.linalg.norm(new) if scaled else 1.0
        return rotated - gamma * _tangential(scale * (new - old), n)

    update.__doc__ = (
        "YADE ``ScGeom::rotate`` + ``Law2_ScGeom_FrictPhys_CundallStrack``, "
        + ("with" if scaled else "without") + " ``avoidGranularRatcheting``."
    )
    return update


def euler_rotation(shear: np.ndarray, old: np.ndarray, new: np.ndarray, gamma: float) -> np.ndarray:
    """MercuryDPM ``SlidingFrictionInteraction::computeFrictionForce``: the spring xi moves
    with v_s = v_t - (xi . v_rel / distance) n, integrated by one explicit Euler step."""
    n = _unit(new)
    delta = new - old
    spring = -shear / gamma if gamma else np.zeros(2)  # tangentialForce = -k xi
    spring = spring + _tangential(delta, n) - (spring @ delta) / np.linalg.norm(new) * n
    return -gamma * spring


def exact_rotation(shear: np.ndarray, old: np.ndarray, new: np.ndarray, gamma: float) -> np.ndarray:
    """Kratos DEM ``SphericParticle::RotateOldContactForces``: the old force is turned by the
    angle between the normals (Rodrigues), then grows by -k_t times the relative
    displacement's tangential part in the new local frame."""
    n_old, n = _unit(old), _unit(new)
    sine = _cross_z(n_old, n)
    angle = np.arcsin(np.clip(abs(sine), 0.0, 1.0)) * np.sign(sine)
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    return rotation @ shear - gamma * _tangential(new - old, n)


def no_rotation(shear: np.ndarray, old: np.ndarray, new: np.ndarray, gamma: float) -> np.ndarray:
    """ESyS-Particle ``CFrictionInteraction::calcForces`` (and ``CRotFrictionInteraction``
    unless ``rigid``): the friction force is kept in the global frame; only the increment
    is made tangential.  The force keeps the direction it was built in."""
    return shear - gamma * _tangential(new - old, _unit(new))


def one_step(shear: np.ndarray, old: np.ndarray, new: np.ndarray, gamma: float) -> np.ndarray:
    """Chrono ``ChContactSMC`` / ``ChDefaultContactForceTorqueSMC``, tangential displacement
    model ``OneStep`` (``MultiStep`` falls back to it): delta_t = |v_t| dt, no history."""
    return -gamma * _tangential(new - old, _unit(new))


#: Every rule, by the name docs/dem-codes.md gives it.
RULES: dict[str, Update] = {
    "liggghts_history": project,
    "lammps_hooke_history": project,
    "lammps_granular_linear_history": rotate_rescale,
    "yade_avoid_ratcheting": _yade(scaled=True),
    "yade_plain": _yade(scaled=False),
    "mercurydpm_sliding_friction": euler_rotation,
    "kratos_rotate_old_contact_forces": exact_rotation,
    "esys_friction": no_rotation,
    "chrono_one_step": one_step,
}


def replay(rule: str, branch: np.ndarray, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """T and N_s after every step of a rule along sampled positions of the contact.

    Parameters
    ----------
    rule
        A key of :data:`RULES`.
    branch
        Branch vectors b_k = l_k (cos alpha_k, sin alpha_k) of the top grain
        relative to the left grain, shape ``(n_steps + 1, 2)`` (units of 2R);
        b_0 is where the contact forms with no shear force.
    gamma
        k_t / k_n.

    Returns
    -------
    (T, N_s)
        Shape ``(n_steps + 1,)`` each: the shear force on the top grain as
        G = N_s n - T t at each position (seed Eq. 4 sign conventions); N_s is
        the part of the stored force that left the tangent plane (it adds to
        the normal force the code applies).
    """
    update = RULES[rule]
    branch = np.asarray(branch, dtype=float)
    shear = np.zeros(2)
    tangential = np.zeros(len(branch))
    normal = np.zeros(len(branch))
    for k in range(1, len(branch)):
        shear = update(shear, branch[k - 1], branch[k], gamma)
        n = _unit(branch[k])
        t = np.array([-n[1], n[0]])
        tangential[k], normal[k] = -(shear @ t), shear @ n
    return tangential, normal
