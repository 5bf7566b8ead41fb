"""The text summary of an archive (``ncstab info``) and of a run's statuses (``ncstab run``).

Read from an archive's small variables
(:func:`~ncstab.studies.archive_contents.open_archive_contents`, or a Dataset
opened lazily): only the statuses, the messages, the coordinates and the
located events are read, never the paths.  The text keeps to :data:`LINE_WIDTH` characters: a
long list of swept values is summarised (``64 values from 0.1 to 2``), a long
description wrapped, a long message cut; numbers are printed to 6
significant digits.
"""

from __future__ import annotations

import os
import textwrap
from typing import Any

import numpy as np

__all__ = ["LINE_WIDTH", "MAX_LISTED_VALUES", "archive_summary", "event_lines", "status_lines", "swept_values"]

#: No line of a summary is longer.
LINE_WIDTH = 100
#: A sweep of more values is summarised as ``N values from first to last``.
MAX_LISTED_VALUES = 8


#: Systems whose grains can meet in new (secondary) contacts: ``info`` says how they were treated.
GAP_SYSTEMS = ("diamond", "ring")


def _number(value: Any) -> str:
    """A number to 6 significant digits (``0.785398``, ``2``, ``-7.58352e-14``)."""
    return f"{float(value):.6g}"


def _fit(line: str, width: int = LINE_WIDTH) -> str:
    """``line`` cut to ``width`` characters, ending in ``...`` if it was cut."""
    return line if len(line) <= width else line[: width - 3] + "..."


def swept_values(values: np.ndarray) -> str:
    """The values of a swept parameter as a summary prints them.

    ``[0.5, 2]`` for a few values (at most :data:`MAX_LISTED_VALUES`),
    ``64 values from 0.1 to 2`` for more; numbers to 6 significant digits,
    text values (a swept name) as they are.

    Parameters
    ----------
    values
        The coordinate's values, shape ``(n,)``.
    """
    values = np.asarray(values).ravel()
    text = [_number(v) if values.dtype.kind in "biuf" else str(v) for v in values]
    if len(text) <= MAX_LISTED_VALUES:
        return "[" + ", ".join(text) + "]"
    return f"{len(text)} values from {text[0]} to {text[-1]}"


def _values(dataset: Any, name: str, law: int | None) -> np.ndarray:
    """A variable's values, of one law (index along its first dimension ``law``) or of all."""
    values = np.asarray(dataset[name].values)
    if law is not None and dataset[name].dims[:1] == ("law",):
        values = values[law]
    return values


def status_lines(dataset: Any, indent: str = "  ", law: int | None = None) -> list[str]:
    """Lines summarising case statuses: cases, finished, stopped at events, failed with reasons.

    Parameters
    ----------
    dataset
        An ``xarray.Dataset`` with ``status`` and ``message``, or the
        :class:`~ncstab.studies.archive_contents.ArchiveContents` of an archive.
    indent
        Put before every line.
    law
        Only the cases of this law (its index), or all.
    """
    status = _values(dataset, "status", law).astype(str).ravel()
    message = _values(dataset, "message", law).astype(str).ravel()
    lines = [f"{indent}cases: {status.size}", f"{indent}finished: {int(np.sum(status == 'finished'))}"]
    states, counts = np.unique(status, return_counts=True)
    for state, count in zip(states.tolist(), counts.tolist()):
        if state.startswith("stopped:"):
            lines.append(f"{indent}stopped at {state.split(':', 1)[1]}: {count}")
    for state, count in zip(states.tolist(), counts.tolist()):
        if state.startswith("failed:"):
            example = " ".join(message[status == state][0].split())
            lines.append(_fit(f"{indent}FAILED ({state.split(':', 1)[1]}): {count} -- e.g. {example}"))
    return lines


def event_lines(dataset: Any, indent: str = "  ", law: int | None = None) -> list[str]:
    """One line per event located in some case: in how many cases, and at which load.

    The load is the system's load parameter at the event where the system has
    one (``<event>_load``), else the force on the first dof (``<event>_F``):
    its range over the cases (``F1 from 0.127978 to 0.670426``), or its value
    where all give the same to 6 digits (``F1 = 0.660869``).

    Parameters
    ----------
    dataset
        As :func:`status_lines`.
    indent
        Put before every line.
    law
        Only the cases of this law (its index), or all.
    """
    from ncstab.paths.programme import EVENTS

    lines = []
    extrema = sorted(str(name)[:-2] for name in dataset.variables  # [output] extrema: extremum_<name>
                     if str(name).startswith("extremum_") and str(name).endswith("_s"))
    for event in (*EVENTS, *extrema):
        if f"{event}_s" not in dataset or f"{event}_F" not in dataset:
            continue
        found = np.isfinite(_values(dataset, f"{event}_s", law))
        if not found.any():
            continue
        if f"{event}_load" in dataset:  # a system with a load parameter: the load at the event
            label = str(dataset.attrs.get("load_parameter", "P"))
            values = _values(dataset, f"{event}_load", law)[found]
        else:  # the first dof's force
            label = str(dataset["force"].values[0]) if "force" in dataset.coords else "F1"
            forces = _values(dataset, f"{event}_F", law)
            values = np.take(forces, 0, axis=-1)[found]  # dof is the last dimension
        low, high = _number(np.nanmin(values)), _number(np.nanmax(values))
        where = f"{label} = {low}" if low == high else f"{label} from {low} to {high}"
        lines.append(_fit(f"{indent}{event}: found in {int(found.sum())} of {found.size} cases ({where})"))
    return lines or [f"{indent}no events located"]


def _law_classes(dataset: Any) -> list[str]:
    if "law_class" in dataset.variables:
        return [str(c) for c in np.asarray(dataset["law_class"].values).ravel()]
    return ["?"] * int(dataset.sizes["law"])


def archive_summary(dataset: Any, path: str | os.PathLike[str]) -> list[str]:
    """The lines ``ncstab info`` prints: study, system, sweep, statuses, then each law's cases and events.

    Parameters
    ----------
    dataset
        An archive's :class:`~ncstab.studies.archive_contents.ArchiveContents`, or
        its ``xarray.Dataset`` (opened lazily: only the statuses, messages,
        coordinates and event variables are read).
    path
        The archive's path, the first line.

    Returns
    -------
    list of str
        No line longer than :data:`LINE_WIDTH` characters.
    """
    attrs = dataset.attrs
    lines = [_fit(str(path))]
    study = f"study: {attrs.get('study_name', '?')} -- {attrs.get('study_description', '')}".rstrip(" -")
    lines += textwrap.wrap(" ".join(study.split()), LINE_WIDTH, initial_indent="  ", subsequent_indent="    ")
    lines.append(_fit(f"  created {attrs.get('created', '?')} with ncstab {attrs.get('ncstab_version', '?')}"))
    contacts = (f" (normal {attrs.get('normal', '?')}, secondary contacts {attrs.get('secondary_contacts', '?')})"
                if attrs.get("system") in GAP_SYSTEMS else "")  # the others have no new contacts to meet
    lines.append(_fit(f"  system: {attrs.get('system', '?')}{contacts}, forces in units of {attrs.get('force_unit', '?')}"))
    for name in [d for d in dataset["status"].dims if d != "law"]:
        lines.append(_fit(f"  sweep {name}: {swept_values(dataset[name].values)}"))
    fixed = {k[len("parameter_"):]: v for k, v in attrs.items() if k.startswith("parameter_")}
    if fixed:
        text = ", ".join(f"{k} = {_number(v)}" for k, v in fixed.items())
        lines += textwrap.wrap(f"fixed: {text}", LINE_WIDTH, initial_indent="  ", subsequent_indent="    ")
    lines.append(f"  stored states: up to {dataset.sizes.get('step', 0)} per case")
    lines += status_lines(dataset)
    for index, (law, law_class) in enumerate(zip(np.asarray(dataset["law"].values).ravel(), _law_classes(dataset))):
        lines.append(_fit(f"  law {law} ({law_class}):"))
        lines += status_lines(dataset, indent="    ", law=index)
        lines += event_lines(dataset, indent="    ", law=index)
    return lines
