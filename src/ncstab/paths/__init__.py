"""Loading programmes and the batched path engine (layer ``paths/``)."""

from ncstab.paths.api import CaseRange, ParameterGrid, case_batch, follow
from ncstab.paths.case_result import CaseResult
from ncstab.paths.stepper import follow_cases
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
