"""``ncstab.follow``: one call from (system, laws, programme, parameters) to a PathResult.

The model is a value: a shipped system by name or :class:`SystemSpec`, or any
:class:`~ncstab.systems.SystemDefinition`; laws by name or as definitions
(:class:`~ncstab.laws.LawDefinition`, :class:`~ncstab.laws.spring.SpringLaw`).
Everything that reaches the engine -- and every worker of a chunked or dask
run -- is a picklable value, never a name looked up in a mutated registry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ncstab.laws.definition import ALPHA0_SPEC
from ncstab.laws.registry import Law, law_definition, make_law
from ncstab.paths.grid import CaseRange, ParameterGrid
from ncstab.paths.model import CaseBatch
from ncstab.paths.model_batch import ModelBatch
from ncstab.paths.options import PathOptions, SystemSpec
from ncstab.paths.programme import BRANCH_DIMENSION, LoadingProgramme, parse_programme
from ncstab.paths.result import PathResult
from ncstab.paths.rigid_model import RigidCaseBatch
from ncstab.paths.stepper import follow_cases
from ncstab.systems.assembled import is_assembled
from ncstab.systems.definition import SystemDefinition
from ncstab.systems.diamond import DiamondChain

__all__ = ["BRANCHES", "CaseRange", "Model", "ParameterGrid", "case_batch", "follow", "resolve_model", "with_branches"]



#: Parameters of granular systems besides their own and their laws' (secondary contacts).
ENGINE_PARAMETERS = {"kappa": 1.0}


def _resolve_law(law: Any) -> Any:
    """A law definition from a name (with modifiers) or a definition."""
    if isinstance(law, str):
        return law_definition(law)
    if isinstance(law, Law):
        return law.definition
    if hasattr(law, "kind") and hasattr(law, "force_totals"):
        return law
    raise ValueError(f"a law is a name or a law definition, got {law!r}")


@dataclass(frozen=True)
class Model:
    """A system and its laws, resolved: what :func:`follow` runs, case by case.

    Attributes
    ----------
    definition
        The system.
    laws
        The laws of the ``law`` dimension (definitions), in order.
    spec
        The shipped system's :class:`SystemSpec`, or ``None`` for a system
        given as a definition.
    secondary_contacts
        ``"activate"``, ``"ignore"`` or ``"stop"``.
    """

    definition: SystemDefinition
    laws: tuple[Any, ...]
    spec: SystemSpec | None
    secondary_contacts: str = "activate"

    @property
    def law_names(self) -> tuple[str, ...]:
        return tuple(law.name for law in self.laws)

    @property
    def normal(self) -> str:
        return self.spec.normal if self.spec is not None else "deformable"

    @property
    def is_reduced_diamond(self) -> bool:
        """The seed's two-dof diamond: followed by its fused kernel (or the pure-shear limit)."""
        return self.spec is not None and self.spec.is_reduced_diamond

    @property
    def granular(self) -> bool:
        """Whether the system has secondary contacts (and the ``kappa`` parameter)."""
        return bool(self.definition.gaps)

    def family_laws(self, law: Any) -> tuple[Any, ...]:
        """The law of every family when ``law`` is the case's law (its kind's families)."""
        return tuple(law if law.kind == f.kind else f.law for f in self.definition.families)

    def fixed_parameters(self) -> set[str]:
        """Law parameters fixed by the system's geometry (each contact's alpha0 of a ring)."""
        fixed: set[str] = set()
        for family in self.definition.families:
            fixed |= set(family.fixed_parameters)
        return fixed - {p.name for p in self.definition.parameters}

    def known_parameters(self) -> set[str]:
        """Every parameter a study may set: the system's, kappa, the laws' own."""
        known = {p.name for p in self.definition.parameters}
        if self.granular:
            known |= set(ENGINE_PARAMETERS)
        for law in self.laws:
            for family_law in self.family_laws(law):
                known |= set(family_law.parameter_names)
        if self.normal == "rigid":
            known -= {"gamma", "kappa"}
        return known - self.fixed_parameters()


def resolve_model(
    system: SystemSpec | str | SystemDefinition | Model,
    laws: Sequence[Any] | Any | None = None,
    secondary_contacts: str | None = None,
) -> Model:
    """The :class:`Model` of a system and laws given by name or as values.

    A system whose interactions have laws of their own (a column, Ziegler's
    pendulum) needs no laws: its ``law`` dimension is then its own laws.

    Raises
    ------
    ValueError
        Unknown system or law, a law of a kind the system has no interaction
        of, no law for a system that needs one, a law given twice.
    """
    if isinstance(system, Model):
        return system
    spec = SystemSpec(system) if isinstance(system, str) else system
    if isinstance(spec, SystemSpec):
        definition = spec.definition
        mode = spec.secondary_contacts if secondary_contacts is None else secondary_contacts
    elif isinstance(spec, SystemDefinition) or is_assembled(spec):
        definition, mode, spec = spec, secondary_contacts or "activate", None
    else:
        raise ValueError(f"a system is a name, a SystemSpec or a SystemDefinition, got {system!r}")
    if laws is None or (isinstance(laws, (list, tuple)) and not laws):
        own = tuple(dict.fromkeys(f.law for f in definition.families if f.law is not None))
        if any(f.law is None for f in definition.families) or not own:
            kinds = sorted({f.kind for f in definition.families if f.law is None})
            raise ValueError(
                f"system {definition.name!r} needs a law for its {', '.join(kinds)} interactions: "
                "give at least one law"
            )
        resolved = own[:1]
    else:
        items = [laws] if isinstance(laws, (str, Law)) or hasattr(laws, "force_totals") else list(laws)
        resolved = tuple(_resolve_law(law) for law in items)
    names = [law.name for law in resolved]
    if len(set(names)) != len(names):
        raise ValueError(f"laws: each law once, got {names}")
    kinds = {f.kind for f in definition.families}
    for law in resolved:
        if law.kind not in kinds:
            raise ValueError(
                f"law {law.name!r} is a {law.kind} law; system {definition.name!r} has "
                f"{' and '.join(sorted(kinds))} interactions only"
            )
    needing = {f.kind for f in definition.families if f.law is None}
    for kind in needing:
        if not any(law.kind == kind for law in resolved):
            raise ValueError(f"system {definition.name!r} needs a {kind} law; give one")
    return Model(definition, resolved, spec if isinstance(spec, SystemSpec) else None, mode)


def _values_of(specs: Sequence[Any], values: Mapping[str, np.ndarray], size: int) -> dict[str, np.ndarray]:
    """Validated values of ``specs`` from ``values`` (defaults where not given)."""
    out = {}
    for spec in specs:
        if spec.name in values:
            out[spec.name] = spec.validate(values[spec.name])
        elif spec.default is not None:
            out[spec.name] = np.full(size, float(spec.default))
        else:
            raise ValueError(f"parameter {spec.name!r} ({spec.description}) is needed; allowed: {spec.allowed}")
    return out


#: The branches a stage with ``at_bifurcation = "branches"`` follows: the path it was
#: on (0) and the bifurcating branch either way (+1, -1).
BRANCHES = [0.0, 1.0, -1.0]


def with_branches(programme: LoadingProgramme, parameters: Mapping[str, Any]) -> dict[str, Any]:
    """``parameters`` with the ``branch`` sweep dimension first where a stage follows
    every branch of its bifurcation (and the parameters do not sweep it already)."""
    if not programme.follows_branches or BRANCH_DIMENSION in parameters:
        return dict(parameters)
    return {BRANCH_DIMENSION: list(BRANCHES), **parameters}


def case_batch(
    law: Any,
    system: SystemSpec | str | SystemDefinition | Model,
    values: Mapping[str, np.ndarray],
    size: int,
) -> CaseBatch | RigidCaseBatch | ModelBatch:
    """The batch of ``size`` cases of one law that the engine follows.

    ``values`` holds every parameter as a flat array over the cases (see
    :meth:`ParameterGrid.case_values`); missing law or system parameters take
    their defaults.  The seed's reduced diamond is followed by its fused
    kernel (:class:`~ncstab.paths.model.CaseBatch`) or, with a rigid normal,
    in the pure-shear limit; every other system as a
    :class:`~ncstab.paths.model_batch.ModelBatch`.  Used by :func:`follow` and
    by chunked study runs, which follow a slice of the cases.
    """
    model = resolve_model(system, [law] if not isinstance(system, Model) else None)
    definition = _resolve_law(law)
    activate = model.secondary_contacts == "activate"
    if model.is_reduced_diamond and model.normal == "rigid":
        alpha0 = values.get("alpha0", np.full(size, np.pi / 4))
        rigid_law = make_law(definition, gamma=np.zeros(size), alpha0=alpha0)
        return RigidCaseBatch(DiamondChain(alpha0=alpha0), rigid_law, activate)
    kappa = np.asarray(values.get("kappa", np.full(size, ENGINE_PARAMETERS["kappa"])), dtype=float)
    if np.any(~np.isfinite(kappa) | (kappa < 0)):
        raise ValueError("parameter 'kappa' (secondary-contact stiffness ratio) must be finite and >= 0")
    if model.is_reduced_diamond:
        law_parameters = {
            p.name: values.get(p.name, np.full(size, p.default) if p.default is not None else None)
            for p in definition.parameters
        }
        law_value: Law = make_law(definition, **{k: v for k, v in law_parameters.items() if v is not None})
        system_value = DiamondChain(alpha0=values.get("alpha0", np.full(size, ALPHA0_SPEC.default)))
        return CaseBatch(system_value, law_value, kappa, activate)
    laws = model.family_laws(definition)
    fixed = model.fixed_parameters()
    law_values = tuple(
        _values_of([p for p in family_law.parameters if p.name not in fixed and p.name not in family.fixed_parameters], values, size)
        for family, family_law in zip(model.definition.families, laws)
    )
    parameters = _values_of(model.definition.parameters, values, size)
    return ModelBatch(model.definition, laws, law_values, parameters, kappa, activate, size)


def follow(
    system: SystemSpec | str | SystemDefinition | Model,
    laws: Sequence[Any] | Any | None = None,
    programme: LoadingProgramme | Sequence[Mapping[str, Any]] = (),
    parameters: Mapping[str, Any] | None = None,
    options: PathOptions | None = None,
    *,
    progress: bool = False,
    study_text: str = "",
    secondary_contacts: str | None = None,
) -> PathResult:
    """Follow a loading programme for every law and every case of a sweep.

    Parameters
    ----------
    system
        A system name (``"diamond"``), a :class:`SystemSpec` (a shipped
        system with its settings: ``SystemSpec("ring", grains=6)``), or any
        :class:`~ncstab.systems.SystemDefinition` built in Python.
    laws
        Laws by name (with modifiers, ``"mcnamara+no_tension"``), as
        definitions (a user law) or as :class:`~ncstab.laws.Law` values (whose
        parameter values stand where ``parameters`` gives none); a sweep
        dimension.  ``None`` for a system whose
        interactions have laws of their own (``column``, ``ziegler``).
    programme
        A validated :class:`LoadingProgramme` or raw stage tables.
    parameters
        ``name -> scalar`` (fixed) or ``name -> list`` (sweep dimension, in the
        given order): law parameters (``gamma``, ``alpha0``), system parameters,
        ``kappa`` and any parameter the programme names.
    options
        Engine options (:class:`PathOptions`).
    progress
        Show a tqdm progress bar (cases ended / cases).
    study_text
        Study file text kept in the Dataset's provenance.
    secondary_contacts
        For a system given as a definition: ``"activate"`` (default),
        ``"ignore"`` or ``"stop"`` (a :class:`SystemSpec` carries its own).

    Returns
    -------
    PathResult
        Per-case status, states, events; ``to_dataset()`` for the archive.

    Raises
    ------
    ValueError
        Bad parameters, unknown laws or systems, or parameters nobody uses.
    ProgrammeError
        A malformed loading programme (names the stage and the field).
    """
    model = resolve_model(system, laws, secondary_contacts)
    entries = [laws] if isinstance(laws, Law) else list(laws) if isinstance(laws, (list, tuple)) else []
    # A Law's own parameter values stand where the grid gives none.
    own_values = {entry.name: dict(entry.parameters) for entry in entries if isinstance(entry, Law)}
    options = options or PathOptions()
    definition = model.definition
    if not isinstance(programme, LoadingProgramme):
        programme = parse_programme(programme, definition.dofs, definition.forces, definition.load_parameter,
                                    getattr(definition, "hold_other_forces", False))
    grid = ParameterGrid.from_mapping(with_branches(programme, parameters or {}))
    known = model.known_parameters() | ({BRANCH_DIMENSION} if programme.follows_branches else set())
    if model.normal == "rigid":
        meaningless = sorted({"gamma", "kappa"} & set(grid.names))
        if meaningless:
            raise ValueError(
                f"parameter(s) {', '.join(map(repr, meaningless))} have no meaning with normal = 'rigid' "
                "(the pure-shear limit, seed Eq. 60-68: forces in units of 2R k_t, rigid secondary contacts)"
            )
    referenced = programme.parameter_references()
    missing = sorted(referenced - set(grid.names))
    if missing:
        raise ValueError(
            f"the loading programme refers to undefined parameter(s) {', '.join(map(repr, missing))}; "
            f"defined: {', '.join(grid.names) or 'none'}"
        )
    fixed = sorted(model.fixed_parameters() & set(grid.names))
    if fixed:
        raise ValueError(
            f"parameter(s) {', '.join(map(repr, fixed))} are fixed by the geometry of system "
            f"{definition.name!r} (each contact's own value): remove them"
        )
    unused = sorted(set(grid.names) - known - referenced)
    if unused:
        raise ValueError(
            f"parameter(s) {', '.join(map(repr, unused))} are used by neither the system, the laws "
            "nor the loading programme"
        )
    values = grid.case_values()
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=grid.size * len(model.laws), unit="case", desc="ncstab", leave=False)
    results = []
    try:
        if is_assembled(definition):
            from ncstab.paths.assembled_result import follow_assembled

            return follow_assembled(model, programme, grid, values, options, study_text, progress=bar)
        for law in model.laws:
            own = {k: np.broadcast_to(np.asarray(v, dtype=float), (grid.size,)) for k, v in own_values.get(law.name, {}).items()}
            law_values = {**own, **values}
            batch = case_batch(law, model, law_values, grid.size)
            results.append(
                follow_cases(
                    batch, programme, law_values, options, model.secondary_contacts,
                    progress=bar.update if bar is not None else None,
                )
            )
    finally:
        if bar is not None:
            bar.close()
    return PathResult(
        model=model,
        grid=grid,
        programme=programme,
        options=options,
        results=tuple(results),
        study_text=study_text,
    )
