"""``[laws.<name>]`` tables of a study file: user laws by formula (docs/user-laws.md).

```toml
[laws]
names = ["mcnamara", "my_law"]

[laws.my_law]
normal = "-(l - 1)"
tangential = "mu*gamma*sin(alpha - alpha0)"
parameters = { mu = { min = 0, max = 2 } }
```

Each table becomes a :class:`~ncstab.laws.LawDefinition` through
:func:`ncstab.laws.user_law` (formulas parsed by a whitelist, never evaluated),
then is classified (:func:`ncstab.symbolic.classify`), so that a law that
cannot be derived is reported with the study file's other errors, before
anything runs.  Errors are reported by field: ``laws.my_law.tangential``,
``laws.my_law.parameters.mu.min``.

The symbolic work is bounded: formulas are limited before sympy sees them
(:mod:`ncstab.laws.formula`: length, terms once expanded, exponents,
numbers), and building and classifying one law gets at most
:data:`SYMBOLIC_SECONDS` (:func:`symbolic_time_limit`, in the main thread).
Reading an archive's study text (``ncstab info``, ``ncstab plot``) does not
classify its user laws (:func:`without_classification`): the archive stores
their classes.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import signal
import threading
from collections.abc import Callable, Iterator, Mapping
from typing import Any

from ncstab.laws.definition import LawDefinition, ParameterSpec
from ncstab.laws.formula import UserLawError
from ncstab.laws.registry import LAWS, MODIFIERS
from ncstab.laws.user import FORCE_KEYS, LAW_KEYS, PARAMETER_KEYS, user_law
from ncstab.paths.variables import RESERVED_NAMES
from ncstab.studies.expressions import ExpressionError, evaluate_expression

__all__ = ["SYMBOLIC_SECONDS", "SymbolicTimeout", "symbolic_time_limit", "user_laws_from_tables",
           "without_classification"]

AddError = Callable[[str, str], None]

#: Seconds of symbolic work (building a law from its formulas and classifying it) one
#: user law may take: within the formulas' limits the slowest measured took 2 s.
SYMBOLIC_SECONDS = 30.0
#: Seconds after which an expired time limit raises again while its block goes on (the
#: first :class:`SymbolicTimeout` can be dropped: see :func:`symbolic_time_limit`).
RETRY_SECONDS = 0.05
#: Whether user laws are classified as they are read (not when an archive's study text is checked).
_CLASSIFY: contextvars.ContextVar[bool] = contextvars.ContextVar("ncstab_classify_user_laws", default=True)


class SymbolicTimeout(BaseException):
    """The symbolic work on a law took longer than its time limit (a ``BaseException``, so that
    no ``except Exception`` inside sympy swallows it)."""


@contextlib.contextmanager
def symbolic_time_limit(seconds: float | None = None) -> Iterator[None]:
    """Raise :class:`SymbolicTimeout` in the block after ``seconds`` of wall-clock time
    (default :data:`SYMBOLIC_SECONDS`).

    A ``SIGALRM`` timer, so in the main thread only (elsewhere, and where
    ``setitimer`` is missing, the block runs unbounded); an outer timer is
    not supported (none is set by ncstab).  Once expired, it raises again every
    :data:`RETRY_SECONDS` until the block ends: Python drops an exception raised in
    a garbage-collector callback, and the signal may arrive during one.
    """
    seconds = SYMBOLIC_SECONDS if seconds is None else seconds
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"):
        yield
        return

    def expired(number: int, frame: object) -> None:
        # Again in 50 ms, until the block ends: an exception raised while Python runs a
        # garbage-collector callback (hypothesis installs one) is printed and dropped.
        signal.setitimer(signal.ITIMER_REAL, RETRY_SECONDS)
        raise SymbolicTimeout(f"more than {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@contextlib.contextmanager
def without_classification() -> Iterator[None]:
    """User laws read inside the block are built from their formulas but not classified."""
    token = _CLASSIFY.set(False)
    try:
        yield
    finally:
        _CLASSIFY.reset(token)


def _field(name: str, key: str) -> str:
    return f"laws.{name}.{key}" if key else f"laws.{name}"


def _parameter_declarations(
    name: str, raw: Any, add: AddError, reserved: set[str]
) -> dict[str, dict[str, Any]] | None:
    """The ``parameters`` table with its numbers evaluated (expressions allowed), or ``None``."""
    if not isinstance(raw, dict):
        add(_field(name, "parameters"), "expected a table of parameters, e.g. parameters = { mu = { min = 0 } }")
        return None
    declarations: dict[str, dict[str, Any]] = {}
    ok = True
    for pname, declaration in raw.items():
        field = _field(name, f"parameters.{pname}")
        if pname in reserved:
            add(field, f"parameter name {pname!r} is a system, engine or archive name; choose another name")
            ok = False
            continue
        if not isinstance(declaration, dict):
            add(field, f"expected a table such as {{ min = 0, max = 1, default = 0.5 }} (keys: {', '.join(PARAMETER_KEYS)})")
            ok = False
            continue
        values = dict(declaration)
        for key in ("min", "max", "default"):
            if isinstance(values.get(key), str):
                try:
                    values[key] = evaluate_expression(values[key])
                except ExpressionError as error:
                    add(f"{field}.{key}", str(error))
                    ok = False
            elif isinstance(values.get(key), float) and not math.isfinite(values[key]):
                add(f"{field}.{key}", f"{values[key]} is not finite; give a finite number")
                ok = False
        declarations[pname] = values
    return declarations if ok else None


def _one_law(name: str, table: Mapping[str, Any], add: AddError, reserved: set[str]) -> LawDefinition | None:
    from ncstab.symbolic.classification import classify

    unknown = [key for key in table if key not in LAW_KEYS]
    for key in unknown:
        add(_field(name, key), f"unknown key {key!r}; a user law takes: {', '.join(LAW_KEYS)}")
    if unknown:
        return None
    for key in FORCE_KEYS + ("description",):
        if key in table and not isinstance(table[key], str):
            add(_field(name, key), f"expected a formula string such as \"-(l - 1)\", got {table[key]!r}")
            return None
    parameters = None
    if "parameters" in table:
        parameters = _parameter_declarations(name, table["parameters"], add, reserved)
        if parameters is None:
            return None
    try:
        with symbolic_time_limit():
            try:
                definition = user_law(
                    name,
                    **{key: table[key] for key in FORCE_KEYS if key in table},
                    parameters=parameters,
                    description=table.get("description", ""),
                )
            except UserLawError as error:
                add(_field(name, error.key), error.detail)
                return None
            if not _CLASSIFY.get():
                return definition
            try:
                classify(definition)
            except Exception as error:  # noqa: BLE001 - sympy may fail on any formula; the user is told which
                add(_field(name, ""), f"cannot be classified ({type(error).__name__}: {error}); simplify the formulas")
                return None
    except SymbolicTimeout:
        given = [key for key in FORCE_KEYS if key in table]
        add(_field(name, given[0] if len(given) == 1 else ""),
            f"the symbolic work on the law ({', '.join(given)}) took more than {SYMBOLIC_SECONDS:g} s and was "
            "stopped; simplify the formulas")
        return None
    return definition


def _check_shared_parameters(definitions: Mapping[str, LawDefinition], add: AddError) -> None:
    """A parameter declared by two user laws is one sweep dimension: its declarations must agree."""
    seen: dict[str, tuple[str, ParameterSpec]] = {}
    for law, definition in definitions.items():
        for spec in definition.parameters:
            if spec.name in ("gamma", "alpha0"):
                continue
            if spec.name in seen and seen[spec.name][1] != spec:
                add(
                    _field(law, f"parameters.{spec.name}"),
                    f"parameter {spec.name!r} is also declared by law {seen[spec.name][0]!r} with another "
                    "range, default or description; declare it the same way in both (it is one parameter)",
                )
            seen.setdefault(spec.name, (law, spec))


def user_laws_from_tables(
    tables: Mapping[str, Any], add: AddError, system_parameters: set[str]
) -> tuple[dict[str, LawDefinition], set[str]]:
    """The user laws of a study's ``[laws.<name>]`` tables.

    Parameters
    ----------
    tables
        ``name -> table`` (the ``[laws]`` keys whose values are tables).
    add
        ``add(field, message)``: records an error.
    system_parameters
        Names a user-law parameter may not take (system and engine parameters).

    Returns
    -------
    (dict, set)
        The valid laws by name, and the names of the tables that were invalid.
    """
    reserved = set(RESERVED_NAMES) | set(system_parameters)
    laws: dict[str, LawDefinition] = {}
    invalid: set[str] = set()
    for name, table in tables.items():
        if name in LAWS or name in MODIFIERS:
            add(_field(name, ""), f"{name!r} is a catalogue law or modifier: a user law needs another name")
            invalid.add(name)
            continue
        if name in reserved:
            add(_field(name, ""), f"law name {name!r} is reserved (a parameter, dimension or variable name)")
            invalid.add(name)
            continue
        definition = _one_law(name, table, add, reserved)
        if definition is None:
            invalid.add(name)
        else:
            laws[name] = definition
    _check_shared_parameters(laws, add)
    return laws, invalid
