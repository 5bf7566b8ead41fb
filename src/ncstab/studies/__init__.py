"""Study files, runs and archives (layer ``studies/``).

A study file (TOML, ``docs/study-files.md``) is validated into a :class:`Study`
(:func:`load_study`, every error of the file reported at once in a
:class:`StudyFileError`), run into an ``xarray.Dataset`` (:func:`run_study`),
written atomically to NetCDF (:func:`write_dataset`) and read back identical
(:func:`open_study`, ``docs/archive.md``).  Large sweeps run in chunks, resumable
and optionally on a dask cluster (:func:`run_study_chunked`, ``docs/scale.md``).
What can go wrong is a named error with an exit code (:mod:`ncstab.studies.errors`,
``docs/when-things-go-wrong.md``): an archive that is not readable
(:class:`ArchiveError`), an output in use, a full disk, a lost cluster...
"""

from ncstab.studies.archive import normalise_dataset, open_study, open_study_lazily, write_dataset
from ncstab.studies.chunked import run_study_chunked
from ncstab.studies.errors import ArchiveError, InvalidInputError, NcstabError, ResumeError, RunError, RunInterrupted
from ncstab.studies.expressions import ExpressionError, evaluate_expression
from ncstab.studies.recomputed import tangent_operators
from ncstab.studies.run import default_output_path, run_study
from ncstab.studies.study import (
    DEFAULT_FIGURES,
    FIGURE_KINDS,
    Study,
    StudyFileError,
    load_study,
    parse_study,
)

__all__ = [
    "ArchiveError",
    "DEFAULT_FIGURES",
    "FIGURE_KINDS",
    "ExpressionError",
    "InvalidInputError",
    "NcstabError",
    "ResumeError",
    "RunError",
    "RunInterrupted",
    "Study",
    "StudyFileError",
    "default_output_path",
    "evaluate_expression",
    "load_study",
    "normalise_dataset",
    "open_study",
    "open_study_lazily",
    "parse_study",
    "run_study",
    "run_study_chunked",
    "tangent_operators",
    "write_dataset",
]
