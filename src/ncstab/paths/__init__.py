"""Loading programmes and the batched path engine (layer ``paths/``).

The names are imported on first use (:mod:`ncstab.lazy_imports`): reading a study
file needs the options and the programme, not the engine (scipy, numba).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ncstab.lazy_imports import lazy_attributes

__all__ = [
    "EVENTS",
    "CaseBatch",
    "CaseRange",
    "CaseResult",
    "CycleStage",
    "LoadingProgramme",
    "ParameterGrid",
    "PathResult",
    "PathOptions",
    "ProgrammeError",
    "Stage",
    "SystemSpec",
    "case_batch",
    "follow",
    "follow_cases",
    "parse_programme",
]

__getattr__, __dir__ = lazy_attributes(
    __name__,
    {
        "CaseRange": "ncstab.paths.api",
        "ParameterGrid": "ncstab.paths.api",
        "case_batch": "ncstab.paths.api",
        "follow": "ncstab.paths.api",
        "CaseResult": "ncstab.paths.case_result",
        "follow_cases": "ncstab.paths.stepper",
        "CaseBatch": "ncstab.paths.model",
        "PathOptions": "ncstab.paths.options",
        "SystemSpec": "ncstab.paths.options",
        "EVENTS": "ncstab.paths.programme",
        "CycleStage": "ncstab.paths.programme",
        "LoadingProgramme": "ncstab.paths.programme",
        "ProgrammeError": "ncstab.paths.programme",
        "Stage": "ncstab.paths.programme",
        "parse_programme": "ncstab.paths.programme",
        "PathResult": "ncstab.paths.result",
    },
    globals(),
)

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.api import CaseRange, ParameterGrid, case_batch, follow
    from ncstab.paths.case_result import CaseResult
    from ncstab.paths.model import CaseBatch
    from ncstab.paths.options import PathOptions, SystemSpec
    from ncstab.paths.programme import (
        EVENTS,
        CycleStage,
        LoadingProgramme,
        ProgrammeError,
        Stage,
        parse_programme,
    )
    from ncstab.paths.result import PathResult
    from ncstab.paths.stepper import follow_cases
