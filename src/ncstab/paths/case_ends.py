"""How the cases of a batch end: finished, stopped at an event, or failed with a reason.

Each case ends once, with a status (``finished``, ``stopped:<event>``,
``failed:<reason>``, :mod:`ncstab.paths.status`) and a message saying what and
where; the others go on.  :class:`CaseEnds` is the part of
:class:`ncstab.paths.stepper.BatchStepper` that writes them, from the compiled loop's outcomes
(:meth:`ncstab.paths.compiled_stages.CompiledStages.run`) or at stage entry.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ncstab.paths.status import FINISHED, failed, finished_message, max_steps_message, stopped, stopped_message

__all__ = ["CaseEnds"]


class CaseEnds:
    """Ending cases of a stepper: its ``status``, ``message``, ``progress``,
    ``programme``, ``options``, ``stage_index``, ``columns`` and ``recorder`` (set by the stepper)."""

    status: np.ndarray
    message: np.ndarray
    progress: Callable[[int], None] | None
    programme: Any
    options: Any
    stage_index: np.ndarray
    columns: Any
    recorder: Any

    def end(self, index: np.ndarray, state: str, text: str | np.ndarray) -> None:
        """Cases ``index`` end with status ``state`` and message ``text``."""
        if index.size:
            self.status[index] = state
            self.message[index] = text
            if self.progress:
                self.progress(index.size)

    def fail(self, index: np.ndarray, reason: str, text: str | np.ndarray) -> None:
        """Cases ``index`` fail (status ``failed:<reason>``)."""
        self.end(index, failed(reason), text)

    def finish(self, index: np.ndarray) -> None:
        """Cases ``index`` have done every stage."""
        self.end(index, FINISHED, finished_message(len(self.programme)))

    def fail_step_size_underflow(self, cases: np.ndarray) -> None:
        """Cases ``cases`` fail: their step size fell below ``min_step``."""
        self.fail(
            cases,
            "step_size_underflow",
            "the step size fell below min_step: the path cannot be continued "
            "(non-convergent Newton projection, a kink or a singular point)",
        )

    def fail_outside_domain(self, cases: np.ndarray, why: np.ndarray) -> None:
        """Cases ``cases`` fail: they left the admissible domain (``why``, per case)."""
        for reason in np.unique(why):
            which = cases[why == reason]
            self.fail(
                which,
                "left_domain",
                f"the path left the admissible domain ({reason}) in stage "
                f"{self.stage_index[which[0]] + 1}",
            )

    def fail_singular_branch(self, cases: np.ndarray) -> None:
        """Cases ``cases`` fail: a contact switch led onto a branch where their control is
        singular (the control determinant 0 within rounding, so the driven quantity stays
        put while the state runs off along the branch's null direction)."""
        for number in np.unique(self.stage_index[cases]):
            self.fail(
                cases[self.stage_index[cases] == number],
                "singular_control",
                f"stage {number + 1}: a contact switch led onto a branch where the control is singular (det of "
                "the force-controlled block of K is 0): the driven quantity cannot go on (a no_tension contact "
                "opened under a force it cannot carry, say)",
            )

    def fail_memory(self, cases: np.ndarray) -> None:
        """Cases ``cases`` fail: their next step could store more states than the recorder's
        limit per case (:func:`ncstab.paths.recorder.state_limit`)."""
        from ncstab.paths.recorder import STORED_SHARE
        from ncstab.sizes import readable_size

        recorder = self.recorder
        available = "" if recorder.available is None else f" ({readable_size(recorder.available)} available)"
        for number in np.unique(self.stage_index[cases]):
            self.fail(
                cases[self.stage_index[cases] == number],
                "memory",
                f"stage {number + 1}: the path needs more than {recorder.limit} stored states, the most each of "
                f"{recorder.size:,} cases can keep in {STORED_SHARE:.0%} of the memory{available}; raise sample_step, or "
                "run fewer cases at once (ncstab run --chunk-cases)",
            )

    def stop(self, cases: np.ndarray, columns: np.ndarray) -> None:
        """Cases ``cases`` stop at the stop event of indicator column ``columns`` (per case)."""
        for column in np.unique(columns):
            which = cases[columns == column]
            name = self.columns.events[column]
            number = self.stage_index[which[0]] + 1
            self.end(which, stopped(name), stopped_message(name, number))

    def fail_max_steps(self, cases: np.ndarray) -> None:
        """Cases ``cases`` fail: ``max_steps`` accepted steps before the end of the programme."""
        self.fail(cases, "max_steps", max_steps_message(self.options.max_steps))
