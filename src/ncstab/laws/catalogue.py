"""The four contact laws of the seed, in the dimensionless variables of Eq. (37).

Every law shares the normal law N = delta with delta the normal overlap; they
differ in the tangential part.  Classes (hyperelastic, weakly or strongly
hypoelastic) are *not* declared here: :func:`ncstab.symbolic.classify` computes
them from these expressions.
"""

from __future__ import annotations

import dataclasses
import functools

import sympy as sp

from ncstab.laws.definition import (
    ALPHA,
    ALPHA0,
    DELTA,
    GAMMA,
    L,
    LawDefinition,
)

__all__ = [
    "no_tension_branches",
    "CUNDALL_STRACK",
    "WEAKLY_HYPOELASTIC",
    "MCNAMARA",
    "TURCO",
    "DEM_YADE_AVOID_RATCHETING",
    "DEM_CHRONO_ONE_STEP",
    "no_tension",
]

#: Cundall & Strack (1979), seed Eq. (13)-(15): N = -(l - 1), dT = gamma l dalpha.
#: T is an internal variable: it travels with the state along a path.
CUNDALL_STRACK = LawDefinition(
    name="cundall_strack",
    title="Cundall & Strack (1979), DEM rate law",
    equations="Eq. (13)-(15)",
    normal_overlap=1 - L,
    normal_force=DELTA,
    tangential_rate=(sp.Integer(0), GAMMA * L),
    internal_variables=("T",),
)

#: Rate law with l replaced by l0 = 2R in the tangential rate, seed Eq. (26)-(27):
#: N = -(l - 1), T = gamma (alpha - alpha0).
WEAKLY_HYPOELASTIC = LawDefinition(
    name="weakly_hypoelastic",
    title="Cauchy-elastic law with constant lever arm, seed Eq. (26)-(27)",
    equations="Eq. (26)-(27)",
    normal_overlap=1 - L,
    normal_force=DELTA,
    tangential_force=GAMMA * (ALPHA - ALPHA0),
)

#: McNamara, Garcia-Rojo & Herrmann (2008), seed Eq. (18)-(20):
#: N = -(l - 1), l T = gamma (alpha - alpha0); energy Eq. (19).
MCNAMARA = LawDefinition(
    name="mcnamara",
    title="McNamara et al. (2008), shear rotational springs",
    equations="Eq. (18)-(22)",
    normal_overlap=1 - L,
    normal_force=DELTA,
    tangential_force=GAMMA * (ALPHA - ALPHA0) / L,
    energy=DELTA**2 / 2 + GAMMA * (ALPHA - ALPHA0) ** 2 / 2,
)

#: Turco et al. (2019), seed Eq. (28)-(29): shear translational springs,
#: N = -(l - cos(alpha - alpha0)),
#: l T = sin(alpha - alpha0) (l - cos(alpha - alpha0)) + gamma sin cos(alpha - alpha0).
TURCO = LawDefinition(
    name="turco",
    title="Turco et al. (2019), shear translational springs",
    equations="Eq. (28)-(29), (54)-(55)",
    normal_overlap=sp.cos(ALPHA - ALPHA0) - L,
    normal_force=DELTA,
    tangential_force=(
        -sp.sin(ALPHA - ALPHA0) * DELTA
        + GAMMA * sp.sin(ALPHA - ALPHA0) * sp.cos(ALPHA - ALPHA0)
    )
    / L,
    energy=DELTA**2 / 2 + GAMMA * sp.sin(ALPHA - ALPHA0) ** 2 / 2,
)


# --- DEM codes' shear updates on the diamond (docs/dem-codes.md) -----------------------------
# Most codes' updates (LIGGGHTS, LAMMPS, MercuryDPM, Kratos, YADE without its ratcheting
# fix) reduce to CUNDALL_STRACK for a small time step; they differ only by their discrete
# update.  The two rules below reduce to something else.

#: YADE's default (``Ig2_Sphere_Sphere_ScGeom.avoidGranularRatcheting = True``,
#: ``ScGeom::getIncidentVel``): the relative velocity is scaled by (R1 + R2)/(R1 + R2 - overlap)
#: = 2R/l before its tangential part increments the shear force
#: (``Law2_ScGeom_FrictPhys_CundallStrack``), so dT = k_t 2R dalpha: in dimensionless form
#: dT = gamma dalpha, the weakly hypoelastic law of seed Eq. (26), as a rate law.
DEM_YADE_AVOID_RATCHETING = LawDefinition(
    name="dem_yade_avoid_ratcheting",
    title="YADE's shear update with avoidGranularRatcheting (its default)",
    equations="Eq. (26) as a rate law; docs/dem-codes.md",
    normal_overlap=1 - L,
    normal_force=DELTA,
    tangential_rate=(sp.Integer(0), GAMMA),
    internal_variables=("T",),
)

#: Chrono's smooth contact (``ChContactSMC``, tangential displacement model ``OneStep``,
#: the default; ``MultiStep`` falls back to it): the tangential "spring" is k_t |v_t| dt,
#: one step of relative motion and no history, which vanishes with the time step.  For a
#: small time step the elastic tangential force is T = 0 (the rotational seed laws at
#: gamma = 0); gamma is accepted and has no effect.
DEM_CHRONO_ONE_STEP = LawDefinition(
    name="dem_chrono_one_step",
    title="Chrono's SMC contact, one-step tangential displacement (its default)",
    equations="T = 0 (the seed laws at gamma = 0); docs/dem-codes.md",
    normal_overlap=1 - L,
    normal_force=DELTA,
    tangential_force=sp.Integer(0),
)

def no_tension(law: LawDefinition) -> LawDefinition:
    """Apply the no-tension modifier of seed Eq. (59) to any law.

    The normal overlap delta is replaced by its Macaulay bracket
    <delta> = (delta + |delta|)/2 wherever it appears -- in N, in T (Turco's T
    carries the normal spring) and in the energy -- so a contact that opens
    carries no normal force.

    Parameters
    ----------
    law
        The law to modify; a law already modified is returned unchanged.

    Returns
    -------
    LawDefinition
        A new definition named ``"<name>+no_tension"``.
    """
    if law.no_tension:
        return law
    return dataclasses.replace(
        law,
        name=f"{law.name}+no_tension",
        title=f"{law.title}, no tension (Eq. 59)",
        equations=f"{law.equations}, (59)",
        no_tension=True,
    )


@functools.lru_cache(maxsize=None)
def no_tension_branches(law: LawDefinition) -> tuple[LawDefinition, LawDefinition]:
    """The two smooth branches of a ``no_tension`` law: (closed, open).

    Closed: the base law (delta acts); open: delta replaced by 0 (no normal
    spring).  An event-driven integrator follows one branch per step and
    switches where delta crosses 0.
    """
    if not law.no_tension:
        raise ValueError(f"law {law.name!r} has no no_tension modifier")
    closed = dataclasses.replace(law, name=f"{law.name}[closed]", no_tension=False)
    opened = dataclasses.replace(
        law, name=f"{law.name}[open]", no_tension=False, normal_overlap=sp.Integer(0)
    )
    return closed, opened
