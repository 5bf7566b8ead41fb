"""A law's class and its derivation, derived once and kept in the cache directory.

Classifying a law (:func:`~ncstab.symbolic.classify`) simplifies its
integrability conditions with sympy: a fraction of a second for most laws,
seconds for some (``turco+no_tension``).  ``ncstab laws`` prints the class of
every catalogue law, so the printed texts of each law -- its class, energy and
deciding condition (:func:`class_summary`), and the text of
``ncstab laws --explain`` (:func:`law_explanation`) -- are kept in one small
JSON file per law and per text in the cache directory
(:func:`ncstab.cache.cache_directory`, folder :data:`CACHE_KIND`).

A file is named by the SHA-256 of the law's whole symbolic definition (every
field, sympy expressions in ``srepr`` form, :func:`definition_fingerprint`),
the ncstab version and the sympy version, so a changed law, a new release or a
new sympy derives again.  Entries are written atomically; a corrupt or
foreign entry is ignored and rewritten (:mod:`ncstab.cache`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sympy as sp

import ncstab
from ncstab.cache import cache_directory, read_entry, write_entry
from ncstab.symbolic.classification import classify
from ncstab.symbolic.explain import explain_law

__all__ = ["CACHE_KIND", "ClassSummary", "class_cache_directory", "class_summary", "definition_fingerprint",
           "law_explanation"]

#: The cache's folder in the cache directory.
CACHE_KIND = "law_classes"


@dataclass(frozen=True)
class ClassSummary:
    """The printed class of a law (one row of ``ncstab laws``).

    Attributes
    ----------
    law
        Law name.
    kind
        ``"hyperelastic"``, ``"weakly hypoelastic"`` or ``"strongly hypoelastic"``.
    energy
        The potential W(l, alpha) as text (``sympy.sstr``) for a hyperelastic
        law, else ``None``.
    reason
        One line: the condition that decided the class
        (:attr:`ncstab.symbolic.Classification.reason`).
    """

    law: str
    kind: str
    energy: str | None
    reason: str


def class_cache_directory() -> Path:
    """Where the entries go: ``$NCSTAB_CACHE_DIR/law_classes``, else
    ``$XDG_CACHE_HOME/ncstab/law_classes`` (``~/.cache/ncstab/law_classes``)."""
    return cache_directory(CACHE_KIND)


def _canonical(value: Any) -> Any:
    """A JSON-able, exact description of a definition's field (sympy via ``srepr``)."""
    if isinstance(value, sp.Basic):
        return ["sympy", sp.srepr(value)]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: _canonical(getattr(value, f.name)) for f in dataclasses.fields(value)}
        return [f"{type(value).__module__}.{type(value).__qualname__}", fields]
    if isinstance(value, (tuple, list)):
        return [_canonical(item) for item in value]
    if isinstance(value, dict):
        return {str(key): _canonical(item) for key, item in sorted(value.items())}
    if isinstance(value, float):
        return repr(value)  # inf and nan too
    if value is None or isinstance(value, (bool, int, str)):
        return value
    return repr(value)


def definition_fingerprint(definition: Any) -> str:
    """The SHA-256 (hex) of a law definition, the ncstab and sympy versions.

    Parameters
    ----------
    definition
        A law definition (a dataclass of the interaction-law protocol: contact
        law, spring law, user law).

    Returns
    -------
    str
        64 hexadecimal digits; equal for equal definitions in the same versions.
    """
    description = {
        "ncstab": ncstab.__version__,
        "sympy": sp.__version__,
        "definition": _canonical(definition),
    }
    text = json.dumps(description, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _cached(
    definition: Any,
    what: str,
    derive: Callable[[], dict[str, Any]],
    is_valid: Callable[[dict[str, Any]], bool],
    use_cache: bool,
) -> dict[str, Any]:
    """The fields ``derive()`` gives for ``definition``: from its cache entry when one holds
    fields that pass ``is_valid``, else derived and (re)written."""
    if not use_cache:
        return derive()
    key = hashlib.sha256(f"{what}:{definition_fingerprint(definition)}".encode()).hexdigest()
    value = read_entry(CACHE_KIND, key)
    if value is not None and is_valid(value):
        return value
    value = derive()
    write_entry(CACHE_KIND, key, value)
    return value


def _is_text(value: Any) -> bool:
    return isinstance(value, str)


def class_summary(definition: Any, *, use_cache: bool = True) -> ClassSummary:
    """A law's class, energy and deciding condition, derived once (:func:`~ncstab.symbolic.classify`).

    Parameters
    ----------
    definition
        Any law definition (catalogue, modified, spring or user law).
    use_cache
        Read and write the cache directory; ``False`` derives afresh and writes nothing.

    Returns
    -------
    ClassSummary

    Raises
    ------
    ValueError
        As :func:`~ncstab.symbolic.classify`: a law that declares an energy but is not
        hyperelastic (never cached).
    """
    def derive() -> dict[str, Any]:
        result = classify(definition)
        energy = sp.sstr(result.energy) if result.energy is not None else None
        return {"kind": result.kind, "energy": energy, "reason": result.reason}

    def is_valid(value: dict[str, Any]) -> bool:
        return _is_text(value.get("kind")) and _is_text(value.get("reason")) and (
            value.get("energy") is None or _is_text(value.get("energy")))

    value = _cached(definition, "class", derive, is_valid, use_cache)
    return ClassSummary(str(definition.name), value["kind"], value.get("energy"), value["reason"])


def law_explanation(definition: Any, *, use_cache: bool = True) -> str:
    """The text of ``ncstab laws --explain`` (:func:`~ncstab.symbolic.explain.explain_law`), derived once.

    Parameters
    ----------
    definition
        Any law definition.
    use_cache
        Read and write the cache directory; ``False`` derives afresh and writes nothing.

    Returns
    -------
    str
    """
    value = _cached(definition, "explanation", lambda: {"text": explain_law(definition)},
                    lambda value: _is_text(value.get("text")), use_cache)
    return value["text"]
