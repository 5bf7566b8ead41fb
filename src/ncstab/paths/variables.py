"""Names, units and descriptions of every variable in a path Dataset.

One table, used by :meth:`ncstab.paths.PathResult.to_dataset` and by the docs page
on archive variables.  All quantities are dimensionless (seed Eq. 37).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.systems.definition import InteractionFamily, SystemDefinition

__all__ = ["CASE_DIMENSION", "EVENT_FIELDS", "MEMBER_DIMENSIONS", "RESERVED_NAMES", "VARIABLES", "family_fields",
           "member_field_dims"]

#: Dimension of the flat cases of one chunk of a sweep (ncstab.paths.api.CaseRange).
CASE_DIMENSION = "case"

#: name -> (units, long_name, description)
VARIABLES: dict[str, tuple[str, str, str]] = {
    "u": ("1", "generalized displacements Delta*", "Delta_i / 2R for each dof (Delta_1 vertical, Delta_2 horizontal), seed Eq. (1), (37)"),
    "F": ("1", "generalized forces F*", "F_i / (2R k_n) conjugate to each dof, seed Eq. (4), (37)"),
    "alpha": ("rad", "contact branch orientation alpha", "orientation of the branch joining two neighbour grain centres, from the vertical axis, seed Eq. (1)"),
    "l": ("1", "contact branch length l*", "distance between neighbour grain centres / 2R, seed Eq. (1), (37)"),
    "N": ("1", "normal contact force N*", "N / (2R k_n), positive in compression, seed Eq. (4)"),
    "T": ("1", "tangential contact force T*", "T / (2R k_n), seed Eq. (4); an internal variable for strongly hypoelastic laws"),
    "s": ("1", "arclength of the path", "pseudo-arclength in (Delta*, F*, lambda) from the start of the programme"),
    "stage": ("1", "loading stage index", "0-based index of the loading stage a stored state belongs to; -1 past the end of a path"),
    "lam": ("1", "driven quantity lambda", "value of the driven displacement or force of the stage (turned angle, rad, for a cycle stage)"),
    "work": ("1", "work per contact", "int F* . dDelta* / 2 along the path (seed Eq. 5), in units of k_n (2R)^2"),
    "K": ("1", "tangent operator K", "dF* = K dDelta*, seed Eq. (33)-(34), (38), (51); units of 2R k_n per 2R"),
    "K_sym": ("1", "symmetric part of K", "(K + K^T)/2"),
    "K_skew": ("1", "skew part of K", "(K - K^T)/2; zero for hyperelastic laws at equilibrium, seed Eq. (41)"),
    "det_K": ("1", "determinant of K", "det K; vanishes at a limit point under force control (divergence), seed Eq. (36)"),
    "hill": ("1", "smallest eigenvalue of K_sym", "Hill's condition (second-order work dF . dDelta > 0 in every direction) holds while positive"),
    "d2W": ("1", "normalised second-order work along the path", "dF . dDelta / (|dF| |dDelta|) along the path tangent"),
    "flutter": ("1", "growth rate max Re s", "max Re s over the roots of det(M s^2 + C s + K) = 0, the linearised dynamics about the state (> 0 unstable; 0 on an undamped stable state), time in the system's units"),
    "mixed_control": ("1", "mixed-control determinant", "det K_SS over the stage's force-controlled dofs S (1 under kinematic control); controllability is lost where it vanishes, seed Eq. (35)"),
    "n_steps": ("1", "number of stored states", "stored states of each case; later steps are NaN padding"),
    "status": ("", "case status", "finished, stopped:<event>, or failed:<reason>"),
    "message": ("", "case status message", "what happened to the case, in words"),
    "cycle_work": ("1", "work per contact over each closed cycle", "int F* . dDelta* / 2 over one turn of a cycle stage (seed Eq. 5), in units of k_n (2R)^2, integrated with the path to the integrator's accuracy; zero for hyperelastic laws (no Green's paradox)"),
    "cumulative_work": ("1", "cumulative cycle work", "sum of cycle_work over the cycles completed so far"),
    "cycle_force_gap": ("1", "force gap over each cycle", "F* at the end minus F* at the start of each turn of a cycle stage"),
    "cycle_T_drift": ("1", "tangential force drift over each cycle", "T* at the end minus T* at the start of each turn; gamma times the loop integral of l* dalpha for Cundall-Strack"),
    "cycle_stage": ("1", "stage of each cycle", "0-based loading stage each cycle belongs to"),
    "d2W_dir": ("1", "directional second-order work", "du . K du for unit displacement directions du = (cos theta, sin theta) in the (Delta_1*, Delta_2*) plane; its minimum over theta is hill"),
    "cone_width": ("rad", "width of the unstable cone", "total angle of displacement directions (over the full circle) where the second-order work is negative; 0 while Hill's condition holds"),
    "cone_lower": ("rad", "lower bound of the unstable cone", "exact root of du . K du = 0 bounding one of the two opposite unstable cones (the other is shifted by pi); NaN if no cone"),
    "cone_upper": ("rad", "upper bound of the unstable cone", "exact root of du . K du = 0 bounding one of the two opposite unstable cones; NaN if no cone"),
    "load": ("1", "load parameter", "the system's load parameter (P) at each stored state, in the system's units"),
    "load_level": ("1", "load parameter", "the same values as load, under a name that also works as an attribute (ds.load is xarray's Dataset.load method); read from an older archive, made from load"),
    "theta": ("rad", "spring rotation theta", "relative rotation across each rotational spring"),
    "moment": ("1", "spring moment", "moment of each rotational spring, in units of its stiffness (k or C)"),
    "branch_index": ("1", "branch of each state", "0 on the path followed from the start; +1 or -1 once the case has left a simple bifurcation point along the bifurcating branch, that way (at_bifurcation = \"switch\" or \"branches\")"),
    "spectrum_re": ("1", "real part of the dynamic spectrum", "Re s of the 2n roots of det(M s^2 + C s + K) = 0 at each state, sorted by imaginary part then real part ([output] spectrum = true)"),
    "spectrum_im": ("1", "imaginary part of the dynamic spectrum", "Im s of the 2n roots of det(M s^2 + C s + K) = 0 at each state, in the order of spectrum_re"),
    "accepted_steps": ("1", "accepted integrator steps", "accepted arclength steps of the case"),
    "rejected_steps": ("1", "rejected integrator steps", "steps rejected by error control or Newton projection"),
}

#: Per-event fields: suffix -> (units, long_name, description), each with ``{event}`` to fill in
EVENT_FIELDS: dict[str, tuple[str, str, str]] = {
    "s": ("1", "arclength at {event}", "located arclength of the first {event} (NaN if none)"),
    "s_lower": ("1", "lower bracket of {event}", "arclength bracket of the located {event}: lower end"),
    "s_upper": ("1", "upper bracket of {event}", "arclength bracket of the located {event}: upper end"),
    "stage": ("1", "stage of {event}", "0-based loading stage in which {event} was first located (-1 if none)"),
    "u": ("1", "Delta* at {event}", "generalized displacements at the first {event}"),
    "F": ("1", "F* at {event}", "generalized forces at the first {event}"),
    "alpha": ("rad", "alpha at {event}", "branch orientation at the first {event}"),
    "l": ("1", "l* at {event}", "branch length at the first {event}"),
    "N": ("1", "N* at {event}", "normal contact force at the first {event}"),
    "T": ("1", "T* at {event}", "tangential contact force at the first {event}"),
    "K": ("1", "K at {event}", "tangent operator at the first {event}"),
    "theta": ("rad", "theta at {event}", "spring rotations at the first {event}"),
    "moment": ("1", "moment at {event}", "spring moments at the first {event}"),
    "load": ("1", "load parameter at {event}", "the load parameter (P) at the first {event}"),
}

#: The flutter variable of a system without inertia.
FLUTTER_WITHOUT_INERTIA = ("1", "flutter discriminant of K", "(tr K)^2 - 4 det K; negative when K has complex eigenvalues (a system without inertia)")
#: The critical frequency of a flutter onset (systems with inertia).
FLUTTER_FREQUENCY = ("1", "frequency at flutter_onset", "omega of the critical pair s = +-i omega of det(M s^2 + C s + K) at the first flutter_onset, in units of the system's time")

#: Member dimensions of interaction families and the names a study may not use.
MEMBER_DIMENSIONS = ("contact", "spring")


#: Names a study parameter may not take: dimensions, coordinates and variables
#: of the Dataset, and words of the study syntax.
RESERVED_NAMES = frozenset(
    {"law", "law_class", "step", "dof", "force", "i", "j", "root", "cycle", "cycle_stage", "cycle_direction", "theta",
     "current", "pi", "e", CASE_DIMENSION, "map_D1", "map_D2", *MEMBER_DIMENSIONS,
     # the motion of a dynamic stage (ncstab.dynamics.runs)
     "time", "u_t", "velocity", "kinetic_energy", "external_work", "internal_work", "dissipated_work",
     "motion_status", "motion_message", "motion_steps", "motion_contact_closing_gap",
     *(f"motion_{event}_{field}" for event in ("contact_closing", "kinetic_energy")
       for field in ("time", "u", "velocity", "kinetic_energy"))}
    | set(VARIABLES)
    | {f"{event}_{suffix}" for event in (
        "limit_point", "bifurcation", "hill_loss", "controllability_loss", "flutter_onset", "divergence",
        "secondary_contact", "turning_point",
    ) for suffix in EVENT_FIELDS}
)


def family_fields(definition: SystemDefinition) -> list[tuple[InteractionFamily, tuple[str, ...], str]]:
    """Per family: (family, the names of its stored fields, the name of its members'
    dimension).  The first family of a kind has the bare names (``l``, ``alpha``,
    ``N``, ``T``; ``theta``, ``moment``); a further family of the same kind has
    them prefixed with its name."""
    seen: set[str] = set()
    out = []
    for family in definition.families:
        names = family.variable_names + family.force_names
        if family.kind in seen:
            out.append((family, tuple(f"{family.name}_{n}" for n in names), family.name))
        else:
            out.append((family, names, family.dimension))
        seen.add(family.kind)
    return out


def member_field_dims(definition: SystemDefinition) -> dict[str, list[str]]:
    """The interaction variables an event's table stores, with their dimensions (along the
    family's member dimension where it has several members), then ``load`` for a system
    under a load: the fields every route's event tables share."""
    fields: dict[str, list[str]] = {}
    for family, names, dimension in family_fields(definition):
        for name in names:
            fields[name] = [dimension] if family.size > 1 else []
    if definition.load is not None:
        fields["load"] = []
    return fields
