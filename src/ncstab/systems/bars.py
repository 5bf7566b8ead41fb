"""Chains of rigid bars with rotational springs: Hencky's column and Ziegler's pendulum.

Both have their own interactions (linear rotational springs of unit
stiffness, :data:`ncstab.laws.spring.LINEAR_SPRING`) and a load parameter P.

* :func:`column` -- Hencky's bar chain (docs/models.md): n rigid
  links of length a, bar i at the angle theta_i = asin(w_i - w_{i-1}) from the
  axis (w_0 = w_n = 0), ends pinned, the top end free to move along the
  axis; springs C at the n - 1 internal joints with moment
  C (theta_{j+1} - theta_j); an axial dead load P doing the work
  P a sum(1 - cos theta_i).  Dofs: the lateral displacements w_1..w_{n-1} of
  the internal joints (units of a); P in units of C/a; forces (lateral, at
  the joints) in units of C/a.  Straight-path buckling loads:
  P_k = (4 C/a) sin^2(k pi / 2n) (Hencky).  Its parameter ``imperfection`` (default 0)
  makes the springs stress-free at w0_i = imperfection sin(pi i / n) (the first mode):
  a joint's rotation is measured from its angle in that shape.
* :func:`ziegler` -- two rigid bars of length l (Ziegler 1952): absolute bar
  angles phi1, phi2 from the vertical; springs k at the base (moment
  k phi1) and at the middle joint (moment k (phi2 - phi1)); point masses
  m1 at the middle joint and m2 at the tip; joint dashpots b1 phi1' and
  b2 (phi2' - phi1'); a tip load P, either a follower (along the second
  bar: not conservative) or dead (vertical).  Units: angles in rad, moments
  in units of k, P in units of k/l, masses in units of m, time in units of
  sqrt(m l^2 / k), damping b* = b / sqrt(k m l^2).  On the straight state
  K_follower = [[2 - P, P - 1], [-1, 1]] (det K = 1: no divergence, flutter
  at (7/2 - sqrt 2) k/l for m1 = 2 m2) and K_dead = [[2 - P, -1], [-1, 1 - P]]
  (det K = P^2 - 3P + 1: divergence at (3 - sqrt 5)/2).
  With ``links = n`` it is the chain of n such bars (the discretised Beck column as n
  grows): springs k at the base (k phi1) and at every joint (k (phi_{i+1} - phi_i)),
  a point mass m1 at every joint between two bars and m2 at the tip, a dashpot b1 at
  the base and b2 at every other joint (n = 2: Ziegler's pendulum).  With l = 1, the
  kinetic energy (1/2) sum_k m_k |v_k|^2 of the joints gives
  M_ij = cos(phi_i - phi_j) sum_{k >= max(i, j)} m_k, the dissipation
  (1/2) [b1 phi1'^2 + b2 sum_{i>1} (phi_i' - phi_{i-1}')^2] gives C, and the tip load's
  virtual work gives Q_i = -sin(phi_n - phi_i) (follower) or sin(phi_i) (dead,
  from the potential P sum cos phi_i).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from ncstab.laws.definition import ParameterSpec
from ncstab.laws.spring import LINEAR_SPRING
from ncstab.systems.definition import (
    DomainCondition,
    InteractionFamily,
    LoadDefinition,
    SystemDefinition,
    SystemUnits,
    dof_symbols,
)

__all__ = ["CHAIN_PARAMETERS", "COLUMN_REFERENCE", "COLUMN_UNITS", "IMPERFECTION_SPEC", "ZIEGLER_LOADS",
           "ZIEGLER_REFERENCE", "ZIEGLER_UNITS", "chain_parameters", "column", "imperfect_rises", "ziegler",
           "ziegler_member_names", "ziegler_title"]

#: The two loads of Ziegler's pendulum.
ZIEGLER_LOADS = ("follower", "dead")

#: Units of Hencky's column (lengths in units of the link length a, forces of C/a).
COLUMN_UNITS = SystemUnits(
    displacement="1",
    displacement_description="lateral displacement of each internal joint / a (link length)",
    force="1",
    force_description="lateral force at each internal joint / (C/a)",
    work_description="work of the external forces and of P, in units of C",
    force_unit="C/a",
)
#: A column's geometric imperfection: the amplitude of its stress-free shape.
IMPERFECTION_SPEC = ParameterSpec(
    "imperfection", sp.Symbol("imperfection"),
    "amplitude / a of the stress-free shape w0_i = imperfection sin(pi i / n) (the first buckling mode)",
    lower=-0.5, upper=0.5, default=0.0,
)


def imperfect_rises(links: int) -> np.ndarray:
    """The rises of the bars of the stress-free shape per unit of imperfection,
    sin(pi i / n) - sin(pi (i - 1) / n), i = 1 .. n (``(n,)``; exactly 0 at both ends' joints)."""
    i = np.arange(1, links + 1)
    rises = 2.0 * np.cos(np.pi * (2 * i - 1) / (2 * links)) * np.sin(np.pi / (2 * links))
    rises[np.abs(rises) < 1e-15] = 0.0  # the middle bar of an odd column is level: exactly
    return rises


COLUMN_REFERENCE = "Hencky (1921), Eisenbau 11, 437-452; Challamel & Kocsis (2021), Int. J. Non-Linear Mech. 136, 103772"


def column(links: int) -> SystemDefinition:
    """Hencky's column of ``links`` rigid links (n >= 2) under an axial dead load P."""
    if isinstance(links, bool) or not isinstance(links, int) or links < 2:
        raise ValueError(f"a column needs links >= 2 (a whole number), got {links!r}")
    n = links
    dofs = tuple(f"w{i}" for i in range(1, n))
    w = (sp.Integer(0), *dof_symbols(dofs), sp.Integer(0))
    rise = [w[i] - w[i - 1] for i in range(1, n + 1)]  # sin(theta_i) of each bar
    theta = [sp.asin(x) for x in rise]
    # the stress-free shape: w0_i = imperfection * sin(pi i / n), the first buckling mode
    rest = [sp.asin(IMPERFECTION_SPEC.symbol * float(r)) for r in imperfect_rises(n)]
    springs = InteractionFamily(
        name="springs",
        kind="spring",
        members=tuple(f"joint{j}" for j in range(1, n)),
        variables=tuple((theta[j] - theta[j - 1] - (rest[j] - rest[j - 1]),) for j in range(1, n)),
        law=LINEAR_SPRING,
    )
    shortening = sum(1 - sp.sqrt(1 - x**2) for x in rise)  # sum (1 - cos theta_i)
    load = LoadDefinition(
        parameter="P",
        kind="dead",
        vector=tuple(sp.diff(shortening, u) for u in w[1:-1]),
        units="C/a",
        description="axial dead load P (units C/a)",
    )
    return SystemDefinition(
        name="column",
        title=f"Hencky column of {n} rigid links with rotational springs, axial dead load",
        dofs=dofs,
        forces=tuple(f"F{i}" for i in range(1, n)),
        families=(springs,),
        load=load,
        domain=tuple(DomainCondition(1 - x**2, f"bar {i + 1} at right angles to the axis") for i, x in enumerate(rise)),
        units=COLUMN_UNITS,
        settings=(("links", n),),
        reference=COLUMN_REFERENCE,
        parameters=(IMPERFECTION_SPEC,),
    )


def _positive(name: str, description: str, default: float) -> ParameterSpec:
    return ParameterSpec(name, sp.Symbol(name, positive=True), description, lower=0.0, lower_inclusive=False, default=default)


def _nonnegative(name: str, description: str) -> ParameterSpec:
    return ParameterSpec(name, sp.Symbol(name, nonnegative=True), description, lower=0.0, default=0.0)


#: Ziegler's parameters: masses (units m) and joint dashpots (units sqrt(k m l^2)).
ZIEGLER_PARAMETERS = (
    _positive("m1", "point mass at the middle joint / m", 2.0),
    _positive("m2", "point mass at the tip / m", 1.0),
    _nonnegative("b1", "dashpot at the base joint / sqrt(k m l^2)"),
    _nonnegative("b2", "dashpot at the middle joint / sqrt(k m l^2)"),
)
#: The same parameters of a chain of more than two bars (the defaults lump a uniform column's
#: mass: 2 at every joint between two bars, half of it at the tip).
CHAIN_PARAMETERS = (
    _positive("m1", "point mass at every joint between two bars / m", 2.0),
    _positive("m2", "point mass at the tip / m", 1.0),
    _nonnegative("b1", "dashpot at the base joint / sqrt(k m l^2)"),
    _nonnegative("b2", "dashpot at every joint between two bars / sqrt(k m l^2)"),
)
ZIEGLER_UNITS = SystemUnits(
    displacement="rad",
    displacement_description="absolute angle of each bar from the vertical",
    force="1",
    force_description="external moment conjugate to each bar angle / k",
    work_description="work of the external moments and of P, in units of k",
    force_unit="k",
)
ZIEGLER_REFERENCE = ("Ziegler (1952), Z. Angew. Math. Phys. 3, 96-119; Kirillov (2013), Nonconservative "
                     "Stability Problems of Modern Physics")


def chain_parameters(links: int) -> tuple[ParameterSpec, ...]:
    """Ziegler's parameters (two bars) or the chain's (more): the same names and defaults."""
    return ZIEGLER_PARAMETERS if links == 2 else CHAIN_PARAMETERS


def ziegler_member_names(links: int) -> tuple[str, ...]:
    """The springs' names: ``base``, ``middle`` (two bars) or ``base``, ``joint1`` .. ``joint{n-1}``."""
    return ("base", "middle") if links == 2 else ("base", *(f"joint{j}" for j in range(1, links)))


def ziegler_title(links: int, load: str) -> str:
    return (f"Ziegler's two-bar pendulum, {load} tip load" if links == 2
            else f"Ziegler's chain of {links} rigid bars, {load} tip load")


def ziegler(load: str = "follower", links: int = 2) -> SystemDefinition:
    """Ziegler's pendulum of ``links`` rigid bars (default 2) with a follower or a dead tip load P."""
    if load not in ZIEGLER_LOADS:
        raise ValueError(f"load = {load!r} is not allowed; allowed: {', '.join(ZIEGLER_LOADS)}")
    if isinstance(links, bool) or not isinstance(links, int) or links < 2:
        raise ValueError(f"Ziegler's chain needs links >= 2 (a whole number), got {links!r}")
    n = links
    dofs = tuple(f"phi{i}" for i in range(1, n + 1))
    phi = dof_symbols(dofs)
    parameters = chain_parameters(n)
    m1, m2, b1, b2 = (p.symbol for p in parameters)
    springs = InteractionFamily(
        name="springs",
        kind="spring",
        members=ziegler_member_names(n),
        variables=((phi[0],), *((phi[j] - phi[j - 1],) for j in range(1, n))),
        law=LINEAR_SPRING,
    )
    if load == "follower":  # along the last bar: dW = -P l sum_i sin(phi_n - phi_i) dphi_i
        vector = (*(-sp.sin(phi[-1] - phi[i]) for i in range(n - 1)), sp.Integer(0))
    else:  # vertical: dW = P l sum_i sin(phi_i) dphi_i
        vector = tuple(sp.sin(p) for p in phi)
    tail = [(n - 1 - k) * m1 + m2 for k in range(n)]  # the masses at or beyond joint k + 1 (0-based bar k)
    mass = tuple(tuple(tail[i] if i == j else tail[max(i, j)] * sp.cos(phi[max(i, j)] - phi[min(i, j)])
                       for j in range(n)) for i in range(n))
    dashpots = [b1, *([b2] * (n - 1))]  # at the base, then between bars k - 1 and k
    damping = [[sp.Integer(0)] * n for _ in range(n)]
    for k, b in enumerate(dashpots):
        damping[k][k] += b
        if k:
            damping[k - 1][k - 1] += b
            damping[k - 1][k] -= b
            damping[k][k - 1] -= b
    return SystemDefinition(
        name="ziegler",
        title=ziegler_title(n, load),
        dofs=dofs,
        forces=tuple(f"M{i}" for i in range(1, n + 1)),
        families=(springs,),
        parameters=parameters,
        load=LoadDefinition("P", load, vector, units="k/l", description=f"{load} tip load P (units k/l)"),
        mass=mass,
        damping=tuple(tuple(row) for row in damping),
        units=ZIEGLER_UNITS,
        settings=(("load", load),) if n == 2 else (("links", n), ("load", load)),
        reference=ZIEGLER_REFERENCE,
    )
