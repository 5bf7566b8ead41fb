"""The vocabulary of study files: sections, keys and figure kinds, the error that lists
every mistake (:class:`StudyFileError`), and readers of single fields (a number, a
table, known keys) that record what is wrong instead of raising."""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import sympy as sp

from ncstab.laws.definition import ParameterSpec
from ncstab.studies.expressions import ExpressionError, evaluate_expression
from ncstab.studies.figure_kinds import DEFAULT_FIGURES, FIGURE_KINDS

#: Sections of a study file, in the order they are documented.
SECTIONS = ("study", "system", "laws", "parameters", "loading", "options", "map", "output", "boundary")



#: Most cases a study may have unless ``[options] max_cases`` (or ``--max-cases``) allows more.
DEFAULT_MAX_CASES = 1_000_000


NAME_PATTERN = re.compile(r"[A-Za-z0-9_-]+")


SYSTEM_KEYS = ("name", "secondary_contacts", "normal")


#: Structural settings of every shipped system (when the system itself is unknown).
ALL_SETTINGS = ("reduction", "grains", "links", "load", "file", "grain", "contacts", "rotations",
                "joints", "supports", "springs")


STAGE_KEYS = ("hold", "drive", "stop_at", "cycle", "at_bifurcation", "dynamic")


CYCLE_KEYS = ("center", "turns", "direction", "dofs")


OUTPUT_KEYS = ("figures", "file", "spectrum", "variables", "extrema")


#: Figure kinds drawn from the dynamic spectrum (which they store).
SPECTRUM_FIGURES = ("root_locus", "frequencies")


MAP_KEYS = ("directions", "grid")


GRID_KEYS = ("D1", "D2")


STUDY_KEYS = ("name", "description")


#: Secondary-contact stiffness ratio kappa (understood by the path engine for every system).
KAPPA_SPEC = ParameterSpec(
    "kappa",
    sp.Symbol("kappa", nonnegative=True),
    "secondary-contact stiffness ratio k_secondary/k_n",
    lower=0.0,
    default=1.0,
)


#: Parameters that mean nothing with normal = "rigid" (pure-shear limit, seed Eq. 60-68).
RIGID_MEANINGLESS = ("gamma", "kappa")


class StudyFileError(ValueError):
    """A study file with errors; lists every error found, each naming its field.

    Attributes
    ----------
    path
        The study file (``"<string>"`` for text without a file).
    errors
        ``(field, message)`` pairs, e.g. ``("parameters.gamma", "... must be finite and >= 0")``.

    ``str(error)`` has one line per error: ``<file>: <field>: <message>``.
    """

    def __init__(self, path: str, errors: Sequence[tuple[str, str]]) -> None:
        self.path = str(path)
        self.errors = [(str(f), str(m)) for f, m in errors]
        super().__init__("\n".join(f"{self.path}: {f}: {m}" for f, m in self.errors))

    def __reduce__(self):  # picklable despite the custom signature
        return (type(self), (self.path, self.errors))

    @property
    def fields(self) -> list[str]:
        """The offending fields, in the order reported."""
        return [f for f, _ in self.errors]


class FieldErrors:
    """Collects ``(field, message)`` pairs in the order they are found."""

    def __init__(self) -> None:
        self.items: list[tuple[str, str]] = []

    def add(self, field: str, message: str) -> None:
        if (field, message) not in self.items:
            self.items.append((field, message))

    def __len__(self) -> int:
        return len(self.items)


def toml_type(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a float"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"  # dates and times


def did_you_mean(name: str, choices: Iterable[str]) -> str:
    close = difflib.get_close_matches(name, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def check_keys(table: Mapping[str, Any], allowed: Sequence[str], prefix: str, errors: FieldErrors, what: str) -> None:
    for key in table:
        if key not in allowed:
            errors.add(
                f"{prefix}.{key}",
                f"unknown key {key!r}{did_you_mean(key, allowed)}; {what} takes: {', '.join(allowed)}",
            )


def read_number(value: Any, field: str, errors: FieldErrors) -> float | None:
    """A finite number from a TOML number or an expression string (``None`` on error)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        errors.add(field, f"expected a number or an expression string such as \"pi/4\", got {toml_type(value)} ({value!r})")
        return None
    if isinstance(value, str):
        try:
            return evaluate_expression(value)
        except ExpressionError as error:
            errors.add(field, str(error))
            return None
    if not math.isfinite(value):
        errors.add(field, f"{value} is not finite; give a finite number")
        return None
    try:
        return float(value)
    except OverflowError:  # an integer too large for a float
        errors.add(field, f"{value} is too large for a floating-point number")
        return None


def read_table(data: Mapping[str, Any], name: str, errors: FieldErrors) -> dict[str, Any] | None:
    value = data.get(name)
    if value is None:
        return None
    if not isinstance(value, dict):
        errors.add(name, f"expected a [{name}] table, got {toml_type(value)}")
        return None
    return value


def unknown_sections(data: Mapping[str, Any], errors: FieldErrors) -> None:
    for key, value in data.items():
        if key in SECTIONS:
            continue
        if isinstance(value, dict):
            errors.add(key, f"unknown section [{key}]{did_you_mean(key, SECTIONS)}; sections are: {', '.join(SECTIONS)}")
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            errors.add(key, f"unknown section [[{key}]]{did_you_mean(key, SECTIONS)}; sections are: {', '.join(SECTIONS)}")
        else:
            errors.add(
                key,
                f"key {key!r} is outside any section{did_you_mean(key, SECTIONS)}; keys belong in one of the sections: "
                + ", ".join(f"[{s}]" for s in SECTIONS),
            )


def error_order(error: tuple[str, str]) -> tuple[int, int]:
    """Sort key: the section's place in :data:`SECTIONS` (unknown ones last), then the stage."""
    head = re.split(r"[.\[]", error[0], maxsplit=1)[0]
    stage = re.match(r"loading\[(\d+)\]", error[0])
    return (SECTIONS.index(head) if head in SECTIONS else len(SECTIONS), int(stage.group(1)) if stage else 0)


def decode_toml(text: str, source: str) -> dict[str, Any]:
    """The TOML text as a table; any text that is not valid TOML is one :class:`StudyFileError`.

    Besides syntax errors: an integer of more digits than Python converts
    (``sys.get_int_max_str_digits()``, 4300), and nesting deeper than the
    parser's recursion allows (``[[[[...`` 100,000 deep).
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        message = str(error)
        if message.endswith("(at end of document)"):
            message = message[: -1] + f", line {text.count(chr(10)) + 1})"
        raise StudyFileError(source, [("toml", f"invalid TOML: {message}")]) from None
    except RecursionError:
        raise StudyFileError(
            source, [("toml", "invalid TOML: arrays or tables nested too deeply for a study file")]
        ) from None
    except ValueError as error:  # an integer too long to convert ("Exceeds the limit (4300 digits)...")
        first = str(error).split(";")[0]
        raise StudyFileError(source, [("toml", f"invalid TOML: a number too long to read ({first})")]) from None
