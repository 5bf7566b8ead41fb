"""The systems ncstab ships, by name (docs/models.md).

Each entry says which structural *settings* build the system (``reduction``
of the diamond, ``grains`` of a ring, ``links`` of a column, ``load`` and ``links`` of
Ziegler's pendulum: they fix its dofs and cannot be swept), which numeric
*parameters* it has (``alpha0``, Ziegler's masses and dashpots: sweepable),
and builds its :class:`~ncstab.systems.SystemDefinition`.  Add a system here,
nowhere else.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, Callable

from ncstab.laws.definition import ALPHA0_SPEC, ParameterSpec
from ncstab.lazy_imports import lazy_function
from ncstab.systems.bars import IMPERFECTION_SPEC, ZIEGLER_LOADS, ZIEGLER_PARAMETERS, column, ziegler
from ncstab.systems.definition import SystemDefinition
from ncstab.systems.granular import axes_diamond, ring, symmetric_diamond

__all__ = ["DERIVED_DOFS_LIMIT", "REDUCTIONS", "SYSTEMS", "Setting", "SystemKind", "system_definition"]

#: Reductions of the diamond.
REDUCTIONS = ("symmetric", "axes")


#: The most dofs a shipped system is built with: 10^7 dofs need about 150 GB of working
#: memory in the sparse engine (15 kB a dof, :mod:`ncstab.studies.system_size`), and a
#: larger count would exhaust memory while the study is checked, before any estimate.
MOST_DOFS = 10_000_000


def _whole_at_least(low: int, high: int = MOST_DOFS) -> Callable[[Any], str | None]:
    def check(value: Any) -> str | None:
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            return f"a whole number from {low} to {high:,} (a larger system needs more than 100 GB of memory)"
        return None

    return check


def _one_of(choices: tuple[str, ...]) -> Callable[[Any], str | None]:
    def check(value: Any) -> str | None:
        return None if value in choices else f"one of {', '.join(choices)}"

    return check


@dataclass(frozen=True)
class Setting:
    """A structural setting of a system (``grains = 6``): not sweepable.

    Attributes
    ----------
    name, description
        Its key in ``[system]`` and what it means.
    default
        The value when it is not given, or ``None``: it must be given.
    check
        ``value -> None`` if allowed, else a phrase saying what is allowed.
    """

    name: str
    description: str
    default: Any
    check: Callable[[Any], str | None]
    freeze: Callable[[Any], Any] | None = None

    def frozen(self, value: Any) -> Any:
        """``value`` as the hashable value a system is built and cached with (a list of
        tables as a tuple of tuples), once it passed :attr:`check`."""
        return value if self.freeze is None else self.freeze(value)


@dataclass(frozen=True)
class SystemKind:
    """One shipped system: its settings, parameters and definition.

    Attributes
    ----------
    name, title
        Its ``[system] name`` and a line on what it is.
    settings
        Structural settings.
    parameter_specs
        Numeric parameters (sweepable).
    shorthands
        ``[system]`` keys that set several parameters at once
        (``damping = [b1, b2]``).
    granular
        Whether it has grains, secondary contacts and the ``kappa`` parameter.
    own_laws
        Whether its interactions have laws of their own (no ``[laws]`` needed).
    build
        ``settings -> SystemDefinition``.
    dof_count
        ``settings -> n``, the number of dofs of what ``build`` gives, known before
        anything is built (the size estimated before a run, :mod:`ncstab.studies.system_size`).
    size_setting
        The setting that sets the size (``grains``, ``links``), or None.
    check_together
        ``settings -> [(field, problem), ...]``: the checks that need several settings at
        once (a contact naming a grain of the grain list), made once each passed its own.
    """

    name: str
    title: str
    settings: tuple[Setting, ...]
    parameter_specs: tuple[ParameterSpec, ...]
    shorthands: tuple[tuple[str, tuple[str, ...]], ...]
    granular: bool
    own_laws: bool
    build: Callable[..., SystemDefinition]
    dof_count: Callable[..., int] = lambda **_settings: 2
    size_setting: str | None = None
    check_together: Callable[..., list[tuple[str, str]]] | None = None

    def setting_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.settings)

    def check_settings(self, given: dict[str, Any]) -> dict[str, Any]:
        """Complete ``given`` with defaults; raise ValueError naming a bad setting."""
        known = {s.name: s for s in self.settings}
        for key in given:
            if key not in known:
                allowed = ", ".join(known) or "none"
                raise ValueError(f"{key!r} is not a setting of system {self.name!r} (its settings: {allowed})")
        out = {}
        for setting in self.settings:
            value = given.get(setting.name, setting.default)
            if value is None:
                raise ValueError(f"system {self.name!r} needs {setting.name} ({setting.description})")
            problem = setting.check(value)
            if problem is not None:
                raise ValueError(f"{setting.name} = {value!r} is not allowed for system {self.name!r}: give {problem}")
            out[setting.name] = value
        for field_name, problem in self.check_together(**out) if self.check_together is not None else ():
            raise ValueError(f"system {self.name!r}, {field_name}: {problem}")
        return {name: setting.frozen(out[name]) for name, setting in known.items()}


def _diamond(reduction: str = "symmetric") -> SystemDefinition:
    return symmetric_diamond() if reduction == "symmetric" else axes_diamond()


#: Up to this many dofs a ring or a column is derived whole and followed by the compiled,
#: batched loop (many cases at once, each a few microseconds a state); above it, it is
#: assembled from elements (:mod:`ncstab.systems.assembled_builders`) and followed by the
#: sparse engine (:mod:`ncstab.paths.assembled_path`), whose cost is linear in n.  The
#: derived route costs 1-60 s of sympy and compilation per new size and grows faster than
#: n^2; the assembled route a few milliseconds (docs/models.md, "Systems of any size").
DERIVED_DOFS_LIMIT = 8


def _ring(grains: int):
    if isinstance(grains, int) and grains > DERIVED_DOFS_LIMIT:
        from ncstab.systems.assembled_builders import assembled_ring

        return assembled_ring(grains)
    return ring(grains)


_packing = lazy_function("ncstab.systems.packing_system", "packing_system")
_packing_file = lazy_function("ncstab.systems.packing_system", "packing_file_problem")
_grains = lazy_function("ncstab.systems.user_grains", "grains_system")
_grains_together = lazy_function("ncstab.systems.user_grains", "grains_problems")
_frozen_grains = lazy_function("ncstab.systems.user_grains", "freeze_grains")
_frozen_contacts = lazy_function("ncstab.systems.user_grains", "freeze_contacts")
_bars = lazy_function("ncstab.systems.user_bars", "assembled_bars")
_bars_together = lazy_function("ncstab.systems.user_bars", "bars_problems")


def _grain_list(value: Any) -> str | None:
    return None if isinstance(value, (list, tuple)) and value else "a list of grain tables { x, y, radius, held }"


def _contact_list(value: Any) -> str | None:
    return None if isinstance(value, (list, tuple)) else "a list of grain index pairs such as [[0, 1], [1, 2]]"


def _frozen_list(value):
    return tuple(value) if isinstance(value, list) else value


def _ziegler(load: str = "follower", links: int = 2):
    if isinstance(links, int) and links > DERIVED_DOFS_LIMIT:
        from ncstab.systems.assembled_chain import assembled_ziegler

        return assembled_ziegler(links, load)
    return ziegler(load, links)


def _column(links: int):
    if isinstance(links, int) and links - 1 > DERIVED_DOFS_LIMIT:
        from ncstab.systems.assembled_builders import assembled_column

        return assembled_column(links)
    return column(links)


#: Every system ncstab knows, by name.
SYSTEMS: dict[str, SystemKind] = {
    "diamond": SystemKind(
        name="diamond",
        title="the seed's four-grain diamond (Figs. 1-2)",
        settings=(Setting("reduction", "symmetric (2 dofs, the seed's) or axes (4 dofs)", "symmetric", _one_of(REDUCTIONS)),),
        parameter_specs=(ALPHA0_SPEC,),
        shorthands=(),
        granular=True,
        own_laws=False,
        build=_diamond,
        dof_count=lambda reduction="symmetric", **_: 2 if reduction == "symmetric" else 4,
    ),
    "ring": SystemKind(
        name="ring",
        title="n grains on a regular n-gon, each free along its radius",
        settings=(Setting("grains", "the number of grains, n >= 3", None, _whole_at_least(3)),),
        parameter_specs=(),
        shorthands=(),
        granular=True,
        own_laws=False,
        build=_ring,
        dof_count=lambda grains, **_: int(grains),
        size_setting="grains",
    ),
    "column": SystemKind(
        name="column",
        title="Hencky's column: n rigid links, rotational springs, axial dead load P",
        settings=(Setting("links", "the number of rigid links, n >= 2", None, _whole_at_least(2, MOST_DOFS + 1)),),
        parameter_specs=(IMPERFECTION_SPEC,),
        shorthands=(),
        granular=False,
        own_laws=True,
        build=_column,
        dof_count=lambda links, **_: int(links) - 1,
        size_setting="links",
    ),
    "ziegler": SystemKind(
        name="ziegler",
        title="Ziegler's pendulum: a chain of n rigid bars (two by default), follower or dead tip load P",
        settings=(Setting("load", "the tip load: follower or dead", "follower", _one_of(ZIEGLER_LOADS)),
                  Setting("links", "the number of rigid bars, n >= 2 (2: Ziegler's pendulum)", 2, _whole_at_least(2))),
        parameter_specs=ZIEGLER_PARAMETERS,
        shorthands=(("masses", ("m1", "m2")), ("damping", ("b1", "b2"))),
        granular=False,
        own_laws=True,
        build=_ziegler,
        dof_count=lambda links=2, **_: int(links),
        size_setting="links",
    ),
    "packing": SystemKind(
        name="packing",
        title="a packing file's grains and contacts, rotations included (docs/packing-paths.md)",
        settings=(Setting("file", "a packing file, relative to the study file", None, _packing_file),),
        parameter_specs=(),
        shorthands=(),
        granular=False,  # no secondary contacts: new contacts are not detected
        own_laws=False,
        build=_packing,
        dof_count=lambda file, **_: _packing(file).n_dof,
        size_setting="file",
    ),
    "grains": SystemKind(
        name="grains",
        title="grains given by centre and radius, and their contacts (docs/study-files.md)",
        settings=(
            Setting("grain", "the grains: a list of tables { x, y, radius, held }", None, _grain_list, _frozen_grains),
            Setting("contacts", "the contacts: a list of grain index pairs [a, b], 0-based", None, _contact_list,
                    _frozen_contacts),
            Setting("rotations", "whether the grains rotate (false holds every theta)", True,
                    lambda v: None if isinstance(v, bool) else "true or false"),
        ),
        parameter_specs=(),
        shorthands=(),
        granular=False,  # no secondary contacts: new contacts are not detected
        own_laws=False,
        build=_grains,
        dof_count=lambda grain, contacts=(), rotations=True, **_: _grains(grain, contacts, rotations).n_dof,
        check_together=_grains_together,
    ),
    "bars": SystemKind(
        name="bars",
        title="a chain of rigid bars given by its joints, rotational springs, axial dead load P",
        settings=(
            Setting("joints", "the joints' heights along the axis, from the base up (units a)", None,
                    lambda v: None if isinstance(v, (list, tuple)) else "a list of heights", _frozen_list),
            Setting("supports", "the joints held on the axis (0-based), or \"ends\": the first and the last",
                    "ends", lambda v: None if isinstance(v, (list, tuple)) or v == "ends"
                    else "a list of joint indices, or \"ends\"", _frozen_list),
            Setting("springs", "each internal joint's spring stiffness (units C), or one for all", 1.0,
                    lambda v: None if isinstance(v, (list, tuple, int, float)) and not isinstance(v, bool)
                    else "a number or a list of numbers", _frozen_list),
        ),
        parameter_specs=(),
        shorthands=(),
        granular=False,
        own_laws=True,
        build=_bars,
        dof_count=lambda joints, supports="ends", **_: len(joints) - len(
            set((0, len(joints) - 1) if supports == "ends" else supports)),
        check_together=_bars_together,
    ),
}


@functools.lru_cache(maxsize=None)
def system_definition(name: str, settings: tuple[tuple[str, Any], ...] = ()) -> SystemDefinition:
    """The definition of the shipped system ``name`` with ``settings`` (cached: built once)."""
    kind = SYSTEMS[name]
    return kind.build(**kind.check_settings(dict(settings)))
