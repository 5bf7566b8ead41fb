"""Running a validated study: ``Study -> xarray.Dataset``."""

from __future__ import annotations

from pathlib import Path as FilePath
from typing import TYPE_CHECKING

from ncstab.paths.api import follow
from ncstab.studies.archive import normalise_dataset, with_load_level
from ncstab.studies.archive_selection import archive_selection, leave_out_unseen_events, select_variables
from ncstab.studies.maps import add_state_maps
from ncstab.studies.study import Study
from ncstab.terminal_text import printable

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from ncstab.paths.result import PathResult

__all__ = ["default_output_path", "run_study", "study_dataset"]

#: Directory of archives when a study names no ``[output] file``.
RESULTS_DIRECTORY = FilePath("results")


def run_study(study: Study, progress: bool = False) -> xr.Dataset:
    """Follow every case of a study and return its labelled Dataset.

    The Dataset is :meth:`ncstab.paths.PathResult.to_dataset` (docs/archive.md) in its on-disk representation
    (:func:`ncstab.studies.archive.normalise_dataset`), so that writing it with
    :func:`~ncstab.studies.write_dataset` and reading it back with
    :func:`~ncstab.studies.open_study` gives an identical Dataset.  Attributes
    added: ``study`` (the whole file text), ``study_name``,
    ``study_description`` (its control characters escaped, ``\\x1b``, ``\\x00``:
    netCDF text ends at a NUL) and ``figures`` (comma-separated figure kinds).

    Parameters
    ----------
    study
        A validated study (:func:`~ncstab.studies.load_study`).
    progress
        Show a progress bar (cases ended / cases).

    Returns
    -------
    xarray.Dataset
        Every case, failed ones included (their ``status`` and ``message`` say
        what happened); the variables the study keeps (``[output] variables``,
        or the default: every one up to 1,000 cases per law, the lean
        selection above, docs/archive.md).
    """
    if study.boundary is not None:  # a curve traced by continuation, not a sweep of paths
        from ncstab.boundaries.study import boundary_study_dataset

        return boundary_study_dataset(study)
    path = follow(
        study.system,
        list(study.law_definitions),
        study.programme,
        study.parameters,
        study.options,
        progress=progress,
        study_text=study.text,
    )
    dataset = study_dataset(study, path)
    return leave_out_unseen_events(dataset, archive_selection(study))


def study_dataset(study: Study, path: "PathResult") -> xr.Dataset:
    """The archive Dataset of a study from its followed paths (one place for every run mode).

    ``path.to_dataset`` with the study's ``[map]``, the study's attributes,
    the variables the study keeps (:func:`~ncstab.studies.archive_selection.select_variables`;
    the tables of events no case meets are left out of the whole sweep only,
    by the caller), in the on-disk representation.
    """
    study_map = study.map
    dataset = path.to_dataset(directions=study_map.directions if study_map else None, spectrum=study.spectrum)
    if study_map is not None and study_map.grid is not None:
        dataset = add_state_maps(dataset, path, study_map.grid)
    if study.extrema:
        from ncstab.paths.extrema import extremum_variables

        dataset = dataset.assign(extremum_variables(path, study.extrema))
    dataset.attrs.update(
        {
            "study": study.text,
            "study_name": study.name,
            "study_description": printable(study.description),  # netCDF text ends at a NUL: kept as \x00
            "figures": ",".join(study.figures),
        }
    )
    dataset = select_variables(dataset, archive_selection(study))
    if path.programme.dynamic is not None:  # the motion of the dynamic stage: always kept
        from ncstab.dynamics import motion_dataset
        from ncstab.studies.motions_on_cores import study_motions

        dataset = dataset.merge(motion_dataset(path, path.programme.dynamic, study_motions(study, path)))
    return with_load_level(normalise_dataset(dataset))  # ds.load is xarray's method: ds.load_level too


def default_output_path(study: Study) -> FilePath:
    """``[output] file`` of the study, else ``results/<study name>.nc`` (relative to the working directory)."""
    if study.output:
        return FilePath(study.output)
    return RESULTS_DIRECTORY / f"{study.name}.nc"
