"""The Dataset of a study with a ``[boundary]`` section (``ncstab run``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ncstab.boundaries.trace import boundary
from ncstab.terminal_text import printable

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from ncstab.studies.study import Study

__all__ = ["boundary_study_dataset"]


def boundary_study_dataset(study: Study) -> xr.Dataset:
    """The boundary of ``study.boundary`` for every law and sweep case, with the study's attributes.

    Every other swept parameter is a dimension before ``point``; the boundary
    parameter's own values in ``[parameters]`` (if any) are not a dimension:
    the curve runs along it from ``start`` to ``stop``.
    """
    from ncstab.studies.archive import normalise_dataset

    spec = study.boundary
    parameters = dict(study.parameters)
    if isinstance(parameters.get(spec.parameter), list):
        parameters[spec.parameter] = spec.start
    dataset = boundary(
        study.system,
        list(study.law_definitions) or None,
        study.programme,
        parameters,
        event=spec.event,
        parameter=spec.parameter,
        start=spec.start,
        stop=spec.stop,
    )
    dataset.attrs.update(
        {
            "study": study.text,
            "study_name": study.name,
            "study_description": printable(study.description),
            "figures": ",".join(study.figures),
        }
    )
    return normalise_dataset(dataset)
