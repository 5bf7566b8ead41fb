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

The names are imported on first use (:mod:`ncstab.lazy_imports`):
reading an archive (``ncstab info``) or naming an error does not import the
study machinery (sympy, the path engine).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ncstab.lazy_imports import lazy_attributes

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

__getattr__, __dir__ = lazy_attributes(
    __name__,
    {
        "normalise_dataset": "ncstab.studies.archive",
        "open_study": "ncstab.studies.archive",
        "open_study_lazily": "ncstab.studies.archive",
        "write_dataset": "ncstab.studies.archive",
        "run_study_chunked": "ncstab.studies.chunked",
        "ArchiveError": "ncstab.studies.errors",
        "InvalidInputError": "ncstab.studies.errors",
        "NcstabError": "ncstab.studies.errors",
        "ResumeError": "ncstab.studies.errors",
        "RunError": "ncstab.studies.errors",
        "RunInterrupted": "ncstab.studies.errors",
        "ExpressionError": "ncstab.studies.expressions",
        "evaluate_expression": "ncstab.studies.expressions",
        "tangent_operators": "ncstab.studies.recomputed",
        "default_output_path": "ncstab.studies.run",
        "run_study": "ncstab.studies.run",
        "DEFAULT_FIGURES": "ncstab.studies.study",
        "FIGURE_KINDS": "ncstab.studies.study",
        "Study": "ncstab.studies.study",
        "StudyFileError": "ncstab.studies.study",
        "load_study": "ncstab.studies.study",
        "parse_study": "ncstab.studies.study",
    },
    globals(),
)

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.studies.archive import (
        normalise_dataset,
        open_study,
        open_study_lazily,
        write_dataset,
    )
    from ncstab.studies.chunked import run_study_chunked
    from ncstab.studies.errors import (
        ArchiveError,
        InvalidInputError,
        NcstabError,
        ResumeError,
        RunError,
        RunInterrupted,
    )
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
