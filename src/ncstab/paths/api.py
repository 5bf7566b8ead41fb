"""``ncstab.follow``: one call from (system, laws, programme, parameters) to a Path."""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ncstab.laws.definition import LawDefinition
from ncstab.laws.registry import Law, law_definition, make_law
from ncstab.paths.engine import follow_cases
from ncstab.paths.model import CaseBatch
from ncstab.paths.options import PathOptions, SystemSpec
from ncstab.paths.programme import LoadingProgramme, parse_programme
from ncstab.paths.result import Path
from ncstab.paths.variables import CASE_DIMENSION, RESERVED_NAMES
from ncstab.paths.rigid_model import RigidCaseBatch
from ncstab.systems.diamond import DiamondChain
from ncstab.systems import SYSTEMS

__all__ = ["CaseRange", "ParameterGrid", "case_batch", "follow"]

#: Parameters every system understands besides its own and its law's.
ENGINE_PARAMETERS = {"kappa": 1.0}


@dataclass(frozen=True)
class ParameterGrid:
    """Sweep dimensions (lists) and fixed values (scalars) of a study.

    Attributes
    ----------
    sweep
        Ordered ``name -> 1-D values`` of the swept parameters.
    fixed
        ``name -> value`` of the fixed ones.
    """

    sweep: dict[str, np.ndarray]
    fixed: dict[str, float]

    @classmethod
    def from_mapping(cls, parameters: Mapping[str, Any]) -> "ParameterGrid":
        sweep: dict[str, np.ndarray] = {}
        fixed: dict[str, float] = {}
        for name, value in parameters.items():
            if name in RESERVED_NAMES:
                raise ValueError(
                    f"parameter name {name!r} is reserved (a dimension, variable or keyword of the "
                    "Dataset); choose another name"
                )
            if isinstance(value, (list, tuple, np.ndarray)):
                array = np.asarray(value, dtype=float).ravel()
                if array.size == 0:
                    raise ValueError(f"parameter {name!r}: an empty sweep has no cases")
                if not np.all(np.isfinite(array)):
                    raise ValueError(f"parameter {name!r}: every swept value must be finite")
                sweep[name] = array
            else:
                if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
                    raise ValueError(f"parameter {name!r}: expected a number or a list, got {value!r}")
                if not np.isfinite(value):
                    raise ValueError(f"parameter {name!r} = {value!r} is not finite")
                fixed[name] = float(value)
        return cls(sweep, fixed)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(v.size for v in self.sweep.values())

    @property
    def size(self) -> int:
        return int(np.prod(self.shape)) if self.sweep else 1

    def case_values(self) -> dict[str, np.ndarray]:
        """Every parameter as a flat array over the cases (C order over the sweep)."""
        out: dict[str, np.ndarray] = {}
        if self.sweep:
            mesh = np.meshgrid(*self.sweep.values(), indexing="ij")
            out.update({name: m.ravel() for name, m in zip(self.sweep, mesh)})
        out.update({name: np.full(self.size, value) for name, value in self.fixed.items()})
        return out

    @property
    def names(self) -> list[str]:
        return list(self.sweep) + list(self.fixed)


@dataclass(frozen=True)
class CaseRange:
    """The flat cases ``start:stop`` of a :class:`ParameterGrid`, as a one-dimensional grid.

    A chunk of a large sweep (:mod:`ncstab.studies.chunked`) is followed and
    turned into a Dataset on its own; its swept parameters become one ``case``
    dimension (flat index into the whole grid, C order) so that the chunk's
    Dataset can be cut into the whole archive's blocks (:mod:`ncstab.studies.streaming`).  It offers what
    :class:`ncstab.paths.Path` uses of a grid: ``sweep``, ``fixed``, ``shape``,
    ``size`` and ``case_values()``.
    """

    grid: ParameterGrid
    start: int
    stop: int

    def __post_init__(self) -> None:
        if not 0 <= self.start < self.stop <= self.grid.size:
            raise ValueError(f"cases {self.start}:{self.stop} are not a run of the grid's {self.grid.size} cases")

    @property
    def sweep(self) -> dict[str, np.ndarray]:
        return {CASE_DIMENSION: np.arange(self.start, self.stop, dtype=np.int64)}

    @property
    def fixed(self) -> dict[str, float]:
        return self.grid.fixed

    @property
    def shape(self) -> tuple[int, ...]:
        return (self.stop - self.start,)

    @property
    def size(self) -> int:
        return self.stop - self.start

    @property
    def names(self) -> list[str]:
        return self.grid.names

    def case_values(self) -> dict[str, np.ndarray]:
        """``grid.case_values()[name][start:stop]``, without building the whole grid."""
        values: dict[str, np.ndarray] = {}
        if self.grid.sweep:
            positions = np.unravel_index(np.arange(self.start, self.stop), self.grid.shape)
            values.update({name: sweep[k] for (name, sweep), k in zip(self.grid.sweep.items(), positions)})
        values.update({name: np.full(self.size, value) for name, value in self.grid.fixed.items()})
        return values


def case_batch(
    law_name: str | LawDefinition,
    spec: SystemSpec,
    values: dict[str, np.ndarray],
    size: int,
) -> CaseBatch | RigidCaseBatch:
    """The batch of ``size`` cases of one law that the engine follows.

    ``values`` holds every parameter as a flat array over the cases (see
    :meth:`ParameterGrid.case_values`); missing law or system parameters take
    their defaults.  Used by :func:`follow` and by chunked study runs
    (:mod:`ncstab.studies.chunked`), which follow a slice of the cases.
    ``law_name`` is a catalogue name or a definition (a user law).
    """
    definition = law_name if isinstance(law_name, LawDefinition) else law_definition(law_name)
    if spec.normal == "rigid":
        alpha0 = values.get("alpha0", np.full(size, np.pi / 4))
        law = make_law(definition, gamma=np.zeros(size), alpha0=alpha0)
        return RigidCaseBatch(DiamondChain(alpha0=alpha0), law, spec.secondary_contacts == "activate")
    law_parameters = {
        p.name: values.get(p.name, np.full(size, p.default) if p.default is not None else None)
        for p in definition.parameters
    }
    law_parameters = {k: v for k, v in law_parameters.items() if v is not None}
    law: Law = make_law(definition, **law_parameters)
    system_class = SYSTEMS[spec.name]
    system = system_class(
        **{name: values.get(name, np.full(size, spec_.default)) for name, spec_ in
           ((p.name, p) for p in system_class.parameter_specs)}  # type: ignore[attr-defined]
    )
    kappa = values.get("kappa", np.full(size, ENGINE_PARAMETERS["kappa"]))
    if np.any(~np.isfinite(kappa) | (kappa < 0)):
        raise ValueError("parameter 'kappa' (secondary-contact stiffness ratio) must be finite and >= 0")
    return CaseBatch(system, law, np.asarray(kappa, dtype=float), spec.secondary_contacts == "activate")


def follow(
    system: SystemSpec | str,
    laws: Sequence[str | LawDefinition | Law] | str | LawDefinition | Law,
    programme: LoadingProgramme | Sequence[Mapping[str, Any]],
    parameters: Mapping[str, Any] | None = None,
    options: PathOptions | None = None,
    *,
    progress: bool = False,
    study_text: str = "",
) -> Path:
    """Follow a loading programme for every law and every case of a sweep.

    Parameters
    ----------
    system
        A :class:`SystemSpec` or a system name (``"diamond"``).
    laws
        Law names (with modifiers, ``"mcnamara+no_tension"``), law definitions
        (user laws: :func:`ncstab.laws.user_law`) or laws (:func:`ncstab.make_law`,
        whose parameter values serve where ``parameters`` gives none); a sweep
        dimension.
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

    Returns
    -------
    Path
        Per-case status, states, events; ``to_dataset()`` for the archive.

    Raises
    ------
    ValueError
        Bad parameters, unknown laws or systems, or parameters nobody uses.
    ProgrammeError
        A malformed loading programme (names the stage and the field).
    """
    spec = SystemSpec(system) if isinstance(system, str) else system
    options = options or PathOptions()
    entries = [laws] if isinstance(laws, (str, LawDefinition, Law)) else list(laws)
    definitions = [
        e.definition if isinstance(e, Law) else e if isinstance(e, LawDefinition) else law_definition(e) for e in entries
    ]
    law_names = [e if isinstance(e, str) else d.name for e, d in zip(entries, definitions)]
    if not law_names:
        raise ValueError("give at least one law")
    if len(set(law_names)) != len(law_names):
        raise ValueError(f"laws: each law once, got {law_names}")
    system_class = SYSTEMS[spec.name]
    if not isinstance(programme, LoadingProgramme):
        programme = parse_programme(programme, system_class.dof_names, system_class.force_names)  # type: ignore[attr-defined]
    grid = ParameterGrid.from_mapping(parameters or {})
    known = set(ENGINE_PARAMETERS) | {p.name for p in system_class.parameter_specs}  # type: ignore[attr-defined]
    known |= set(itertools.chain.from_iterable(d.parameter_names for d in definitions))
    if spec.normal == "rigid":
        meaningless = sorted({"gamma", "kappa"} & set(grid.names))
        if meaningless:
            raise ValueError(
                f"parameter(s) {', '.join(map(repr, meaningless))} have no meaning with normal = 'rigid' "
                "(the pure-shear limit, seed Eq. 60-68: forces in units of 2R k_t, rigid secondary contacts)"
            )
        known -= {"gamma", "kappa"}
    referenced = programme.parameter_references()
    missing = sorted(referenced - set(grid.names))
    if missing:
        raise ValueError(
            f"the loading programme refers to undefined parameter(s) {', '.join(map(repr, missing))}; "
            f"defined: {', '.join(grid.names) or 'none'}"
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

        bar = tqdm(total=grid.size * len(law_names), unit="case", desc="ncstab", leave=False)
    results = []
    try:
        for entry, definition in zip(entries, definitions):
            own = dict(entry.parameters) if isinstance(entry, Law) else {}  # a Law's values, where the grid gives none
            law_values = {**{k: np.broadcast_to(v, (grid.size,)) for k, v in own.items()}, **values}
            batch = case_batch(definition, spec, law_values, grid.size)
            results.append(
                follow_cases(
                    batch, programme, law_values, options, spec.secondary_contacts,
                    progress=bar.update if bar is not None else None,
                )
            )
    finally:
        if bar is not None:
            bar.close()
    return Path(
        laws=tuple(law_names),
        grid=grid,
        system=spec,
        programme=programme,
        options=options,
        results=tuple(results),
        dof_names=system_class.dof_names,  # type: ignore[attr-defined]
        force_names=system_class.force_names,  # type: ignore[attr-defined]
        study_text=study_text,
        definitions=tuple(definitions),
    )
