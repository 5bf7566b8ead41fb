"""The compiled stage loop that runs a batch, and the engine in words.

Every system runs on the compiled loop (:mod:`ncstab.paths.compiled`): the
reduced diamond on its fused kernel, every other system (and the diamond's
pure-shear limit) on the general models' loop with the model's compiled
kernels.  The engine that ran, in words, is the archive's ``engine`` attribute.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ncstab.paths.options import PathOptions
from ncstab.paths.programme import LoadingProgramme

if TYPE_CHECKING:
    from ncstab.paths.compiled_stages import CompiledStages

__all__ = ["choose_engine"]


def choose_engine(
    batch: Any, programme: LoadingProgramme, options: PathOptions, plain: bool | None = None,
    study_cases: int | None = None,
) -> tuple[CompiledStages, str]:
    """The compiled stage loop bound to ``batch``, and the engine in words (the archive's
    ``engine`` attribute: ``compiled stepper (numba X.Y.Z)`` and the model's kernel).

    ``plain``: whether the loop runs as plain Python (:mod:`ncstab.plain_python`); by
    default as :func:`ncstab.paths.loop_route.runs_plain` says for ``options.backend``, the
    work counted over ``study_cases`` cases where the batch is a chunk of a larger study
    (its other chunks will need the machine code too).  Either route gives the
    same numbers, so the engine in words does not say which ran.

    Raises
    ------
    RuntimeError
        When numba, a dependency of ncstab, is not installed
        (:func:`ncstab.paths.compiled.stage_runner` names what to install).
    """
    from ncstab.paths import compiled

    if not compiled.NUMBA_AVAILABLE:
        compiled.stage_runner(batch)  # raises, naming what to install
    from ncstab.paths.compiled_general import general_runner
    from ncstab.paths.loop_route import runs_plain
    from ncstab.paths.model_batch import ModelBatch
    from ncstab.paths.rhs import StateLayout
    from ncstab.paths.rigid_model import RigidCaseBatch

    rate_form = not batch.has_total_form
    general = isinstance(batch, (ModelBatch, RigidCaseBatch))
    if plain is None:
        from ncstab.paths.loop_records import DiamondModel, GeneralModel

        kind = GeneralModel(rate_form) if general else DiamondModel(rate_form)
        cases = max(batch.size, study_cases or 0)
        plain = runs_plain(
            options.backend, cases, StateLayout(batch.n_dof, batch.n_internal).size, compiled.stage_loop(kind).run, kind
        )
    engine = f"compiled stepper (numba {compiled.numba.__version__})"
    if isinstance(batch, ModelBatch):
        from ncstab.paths.compiled_general import GeneralStages

        stages, engine = GeneralStages(batch, general_runner(rate_form, plain), plain), f"{engine} with compiled model kernels"
    elif isinstance(batch, RigidCaseBatch):  # the pure-shear limit: on the general models' loop
        from ncstab.paths.compiled_rigid import RigidStages

        stages = RigidStages(batch, general_runner(rate_form, plain), plain)
        engine = f"{engine} with the pure-shear limit's kernel"
    else:
        from ncstab.paths.compiled_stages import CompiledStages

        stages = CompiledStages(batch, compiled.stage_runner(batch, plain))
    stages.plain = plain
    return stages, engine
