"""Which stepper runs a batch: the compiled stage loop where it applies, else the numpy stepper.

The choice follows ``options.backend`` (``"auto"``, ``"compiled"``, ``"numpy"``)
and what the compiled loop covers (:func:`ncstab.paths.compiled.unsupported_reason`);
the engine that ran, in words, is the archive's ``engine`` attribute.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ncstab.paths.case_result import NUMPY_ENGINE
from ncstab.paths.options import PathOptions
from ncstab.paths.programme import LoadingProgramme

if TYPE_CHECKING:
    from ncstab.paths.compiled_stages import CompiledStages

__all__ = ["choose_engine"]


def choose_engine(
    batch: Any, programme: LoadingProgramme, options: PathOptions
) -> tuple[CompiledStages | None, str]:
    """The compiled stage loop where ``options.backend`` asks for it and it applies,
    and the engine that runs the batch, in words (the archive's ``engine`` attribute).

    Raises RuntimeError (from :func:`ncstab.paths.compiled.stage_runner`) when
    the compiled backend is asked for and numba is missing.
    """
    if options.backend == "numpy":
        return None, NUMPY_ENGINE
    from ncstab.paths import compiled

    asked = options.backend == "compiled"
    if not compiled.NUMBA_AVAILABLE:
        if asked:
            compiled.stage_runner(batch)  # raises, naming what to install
        return None, f"{NUMPY_ENGINE} (numba is not installed)"
    from ncstab.paths.model_batch import ModelBatch
    from ncstab.paths.rigid_model import RigidCaseBatch

    if isinstance(batch, ModelBatch):
        return _general_engine(batch, programme, asked)
    if isinstance(batch, RigidCaseBatch):  # the pure-shear limit: on the general models' loop
        from ncstab.paths.compiled_general import general_runner
        from ncstab.paths.compiled_rigid import RigidStages

        stages = RigidStages(batch, general_runner(not batch.has_total_form))
        version = compiled.numba.__version__
        return stages, f"compiled stepper (numba {version}) with the pure-shear limit's kernel, numpy stepper for what it leaves"
    reason = compiled.unsupported_reason(batch, programme)
    if reason is not None:
        because = "backend = 'compiled' asked" if asked else "the compiled stepper does not cover this"
        return None, f"{NUMPY_ENGINE} ({because}: {reason})"
    from ncstab.paths.compiled_stages import CompiledStages

    engine = f"compiled stepper (numba {compiled.numba.__version__}), numpy stepper for what it leaves"
    return CompiledStages(batch, compiled.stage_runner(batch)), engine


def _general_engine(batch: Any, programme: LoadingProgramme, asked: bool) -> tuple[CompiledStages | None, str]:
    """The compiled loop of a general model where it applies, and the engine in words."""
    from ncstab.paths import compiled
    from ncstab.paths.compiled_general import (
        GeneralStages,
        general_runner,
        general_unsupported_reason,
    )

    kernel = f"compiled model kernels (numba {compiled.numba.__version__})"
    reason = general_unsupported_reason(batch, programme)
    if reason is not None:
        because = "backend = 'compiled' asked" if asked else "the compiled stepper does not cover this"
        return None, f"{NUMPY_ENGINE}, {kernel} ({because}: {reason})"
    stages = GeneralStages(batch, general_runner(not batch.has_total_form))
    return stages, f"compiled stepper (numba {compiled.numba.__version__}) with {kernel}, numpy stepper for what it leaves"
