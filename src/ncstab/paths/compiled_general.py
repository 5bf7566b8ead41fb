"""Drive the compiled stage loop of a general model (:mod:`ncstab.paths.loop_general`).

:class:`GeneralStages` is :class:`ncstab.paths.compiled_stages.CompiledStages`
for a :class:`~ncstab.paths.model_batch.ModelBatch`: the same calls, threads
and outcomes, with the general model's rows.  The loop is one for every
general model and form of law (:func:`general_runner`); the model is its compiled
kernel's C callback, and its sizes and event columns are each case's ``geo``
row (:data:`ncstab.paths.loop_general.GEO`).  The loop stores what it knows of a
state (s, u, lambda, internal variables, W, F, K, du, dlambda) straight into the
recorder and the interactions' block of the kernel's row beside it; after each
call that block goes into the named interaction fields, with the load parameter
and the branch index (:meth:`GeneralStages.after_call`).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.compiled import StageLoop
from ncstab.paths.compiled_stages import CompiledStages
from ncstab.paths.events import STIFFNESS_COLUMNS
from ncstab.paths.loop_general import GEO
from ncstab.paths.variables import family_fields

if TYPE_CHECKING:
    from ncstab.paths.model_batch import ModelBatch
    from ncstab.paths.stepper import BatchStepper

__all__ = ["GeneralStages", "general_runner"]


@functools.cache
def general_runner(rate_form: bool, plain: bool = False) -> StageLoop:
    """The compiled stage loop of the general models of one form (compiled once per machine),
    or with ``plain`` its text as plain Python (:mod:`ncstab.plain_python`)."""
    from ncstab.paths.compiled import stage_loop
    from ncstab.paths.loop_records import GeneralModel

    return stage_loop(GeneralModel(rate_form), plain)


class GeneralStages(CompiledStages):
    """The compiled stage loop bound to a batch of one general model.

    Parameters
    ----------
    batch
        The stepper's cases.
    loop
        :func:`general_runner` of the model's form.
    plain
        Whether ``loop`` is plain Python: the model's kernel is then its plain ``case``,
        not its compiled C callback.
    """

    def __init__(self, batch: ModelBatch, loop: StageLoop, plain: bool = False) -> None:
        from ncstab.paths.cofactor import work_size

        size, n = batch.size, batch.n_dof
        kernel = batch._kernel
        layout, module = kernel.layout, kernel.module
        self.runner, self.starter, self.settler, self.kind = loop.run, loop.start, loop.settle, loop.kind
        self.law = kernel.plain_case if plain else kernel.callback
        self.batch = batch
        # p: the kernel's parameter row, the work factor, the contact-state bits (loop_general)
        self.parameters = np.column_stack([batch._rows, np.full(size, batch.work_factor), np.zeros(size)])
        columns = batch.columns
        self.first_interaction = layout.interactions[0][0] if layout.interactions else layout.size
        scratch = 4 * module.WORK
        values = {
            "n": n, "n_internal": layout.n_internal, "size": layout.size, "scratch": scratch,
            "forces": layout.forces, "stiffness": layout.stiffness, "load": layout.load, "gradient": layout.gradient,
            "gaps": layout.gaps, "n_gaps": layout.n_gaps, "overlaps": layout.overlaps, "n_open": layout.n_open,
            "domain": layout.domain, "interactions": self.first_interaction, "has_load": int(batch.has_load),
            "columns": columns.size, "target": columns.target, "cycle": columns.cycle, "turning": columns.turning,
            "bifurcation": columns.bifurcation, "limit": columns.events.index("limit_point"),
            "control": columns.events.index("controllability_loss"), "divergence": columns.divergence,
            "gap_column": STIFFNESS_COLUMNS, "normal_column": columns.normal_columns.start, "row": module.ROW,
            "ev_size": layout.size + 1 + scratch + n * n + 2 * n + 1 + work_size(n),
            "mass": layout.mass if layout.inertia[0] else -1,
            "damping": layout.damping if layout.inertia[0] and layout.inertia[1] else -1,
            "coordinates": -1, "blocking": 0,
            **self._tangential_slots(batch),
        }
        row = np.array([values[name] for name in GEO], dtype=np.int64)
        # (writable: a read-only row, as broadcast_to gives for one case, is another type to numba)
        self.geometry = np.tile(row, (size, 1))
        self.code = np.zeros(size, dtype=np.int64)
        self.detail = np.zeros(size, dtype=np.int64)
        self.width = layout.size - self.first_interaction
        self.event_width = 5 + 2 * n + n * n + self.width
        self.tangential_shape = batch.interaction_shapes.get("T", ())
        self.turn_width = 1 + n + max(1, int(np.prod(self.tangential_shape)))
        self._interactions = np.empty((size, 0, self.width))

    @staticmethod
    def _tangential_slots(batch: ModelBatch) -> dict[str, int]:
        """Where T (the first contact family's second force, per member) sits in the kernel's row."""
        layout = batch._kernel.layout
        for f, family in enumerate(batch.definition.families):
            if family.kind == "contact":
                m, _, kf = layout.family_shapes[f]
                return {"tangential": layout.interactions[f][1] + 1, "tangential_count": m, "tangential_stride": kf}
        return {"tangential": -1, "tangential_count": 1, "tangential_stride": 0}

    def control_rows(self, stages: Any) -> np.ndarray:
        """is_cycle, the load parameter's offset and slope, g's offset and slope, then a
        cycle's centre, radius, theta0, direction and the two dofs of its plane."""
        return np.ascontiguousarray(np.column_stack([
            stages.is_cycle.astype(float), stages.load_offset, stages.load_slope, stages.offset, stages.slope,
            stages.center, stages.radius, stages.theta0, stages.turn_direction.astype(float),
            stages.cycle_axes.astype(float),
        ]))

    def turn_end(self, row: np.ndarray) -> Any:
        """F and T where turns close, from the loop's rows (W, F, T: loop_general ``turn_record``)."""
        from ncstab.paths.compiled_stages import _TurnEnd

        n = self.batch.n_dof
        tangential = row[:, 1 + n :]
        if self.geometry[0, GEO["tangential"]] < 0:  # no contact family: no T
            tangential = None
        elif self.tangential_shape:
            tangential = tangential.reshape(-1, *self.tangential_shape)
        else:
            tangential = tangential[:, :1]
        return _TurnEnd(forces=row[:, 1 : 1 + n], tangential=tangential)

    def recorded(self, stepper: BatchStepper) -> tuple:
        """The recorder's (s, stage, u, lam, internal, work, F, K, du, dlam) and the
        interactions' block beside them (as long as the recorder)."""
        arrays = stepper.recorder.arrays
        if self._interactions.shape[1] != stepper.recorder.capacity:
            self._interactions = np.empty((self.batch.size, stepper.recorder.capacity, self.width))
        names = ("s", "stage", "u", "lam", "internal", "work", "F", "K", "du", "dlam")
        return (*(arrays[name] for name in names), self._interactions)

    def after_call(self, stepper: BatchStepper, cases: np.ndarray, count_before: np.ndarray) -> None:
        """The interactions, the load parameter and the branch index of the states a call stored."""
        counts = stepper.recorder.count[cases] - count_before
        rows = np.repeat(cases, counts)
        if rows.size == 0:
            return
        positions = np.arange(rows.size) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(count_before, counts)
        arrays = stepper.recorder.arrays
        for name, values in self._named(self._interactions[rows, positions]).items():
            arrays[name][rows, positions] = values
        if "load" in arrays:
            stages = stepper.stages
            arrays["load"][rows, positions] = stages.load_offset[rows] + stages.load_slope[rows] * arrays["lam"][rows, positions]
        if "branch_index" in arrays:
            arrays["branch_index"][rows, positions] = stepper.branch_index[rows]

    def _named(self, block: np.ndarray) -> dict[str, np.ndarray]:
        """ModelBatch.record_interactions from rows of the interactions' block."""
        layout = self.batch._kernel.layout
        out = {}
        for (family, names, _), (q_at, f_at), (m, k, kf) in zip(
            family_fields(self.batch.definition), layout.interactions, layout.family_shapes
        ):
            variables = block[:, q_at - self.first_interaction : q_at - self.first_interaction + m * k].reshape(-1, m, k)
            forces = block[:, f_at - self.first_interaction : f_at - self.first_interaction + m * kf].reshape(-1, m, kf)
            values = np.concatenate([variables, forces], axis=-1)
            for a, name in enumerate(names):
                out[name] = values[:, 0, a] if family.size == 1 else values[:, :, a]
        return out

    def event_fields(self, stepper: BatchStepper, table: dict, rows: np.ndarray, row_values: np.ndarray) -> None:
        """An event table's fields at ``rows`` from the loop's event rows (loop_general ``store_event``)."""
        n = self.batch.n_dof
        for column, key in enumerate(("s", "s_lower", "s_upper", "lam")):
            table[key][rows] = row_values[:, column]
        if "load" in table:
            table["load"][rows] = row_values[:, 4]
        table["u"][rows] = row_values[:, 5 : 5 + n]
        table["F"][rows] = row_values[:, 5 + n : 5 + 2 * n]
        table["K"][rows] = row_values[:, 5 + 2 * n : 5 + 2 * n + n * n].reshape(-1, n, n)
        for name, values in self._named(row_values[:, 5 + 2 * n + n * n :]).items():
            table[name][rows] = values
