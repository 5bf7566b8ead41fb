"""Loading programmes and the batched path engine (layer ``paths/``)."""

from ncstab.paths.api import CaseRange, ParameterGrid, case_batch, follow
from ncstab.paths.engine import CaseResult, follow_cases
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
from ncstab.paths.result import Path

__all__ = [
    "EVENTS",
    "CaseBatch",
    "CaseRange",
    "CaseResult",
    "CycleStage",
    "LoadingProgramme",
    "ParameterGrid",
    "Path",
    "PathOptions",
    "ProgrammeError",
    "Stage",
    "SystemSpec",
    "case_batch",
    "follow",
    "follow_cases",
    "parse_programme",
]
