"""The status vocabulary of a case (a leaf module: every layer of the engine reads it).

Both engines (the compiled loop and the sparse engine of assembled systems) end their
cases with these words, and test a stage's held values with :func:`held_away`.

A case is ``running`` while the engine follows it, then ``finished`` (every
stage done), ``stopped:<event>`` (a stop event of its stage) or
``failed:<reason>`` with a message saying what happened.
"""

from __future__ import annotations

__all__ = [
    "FAILURE_REASONS", "FINISHED", "RUNNING", "STOPPED_PREFIX", "FAILED_PREFIX", "HELD_TOLERANCE", "failed",
    "finished_message", "held_away", "held_away_message", "max_steps_message", "stopped", "stopped_message",
]

RUNNING = "running"
FINISHED = "finished"
STOPPED_PREFIX = "stopped:"
FAILED_PREFIX = "failed:"

#: Why a case can fail, in words.
FAILURE_REASONS = {
    "step_size_underflow": "the step size fell below min_step",
    "left_domain": "the path left the admissible domain",
    "max_steps": "max_steps accepted steps before the end of the programme",
    "singular_control": "the control is singular at a stage start, or on the branch a contact switch leads to",
    "bad_stage_start": "a held quantity is not at its held value when the stage starts",
    "memory": "the next step could store more states than the batch's limit per case (ncstab.paths.recorder)",
    "newton": "the sparse engine's steps shrank below min_step (a corrector that does not converge, or a "
              "tangent that turns too far), or no equilibrium at a stage's start",
    "domain": "the sparse engine's path left the system's domain (a bar at right angles to the axis)",
}


def stopped(event: str) -> str:
    """The status of a case stopped at ``event``."""
    return f"{STOPPED_PREFIX}{event}"


def failed(reason: str) -> str:
    """The status of a case that failed for ``reason`` (a key of :data:`FAILURE_REASONS`)."""
    return f"{FAILED_PREFIX}{reason}"


def max_steps_message(max_steps: int) -> str:
    """What a case that failed with ``max_steps`` says (both engines)."""
    return f"reached max_steps = {max_steps} accepted steps before the end of the programme"


def finished_message(stages: int) -> str:
    """What a finished case says (both engines)."""
    return f"finished all {stages} loading stage(s)"


def stopped_message(event: str, stage_number: int) -> str:
    """What a case stopped at ``event`` in stage ``stage_number`` (from 1) says (both engines)."""
    return f"stopped at {event} in stage {stage_number}"


#: A held quantity further than this part of 1 + |its held value| from it when its stage
#: starts is not at its held value: the case fails (``failed:bad_stage_start``).
HELD_TOLERANCE = 1e-9


def held_away(held, value):
    """Whether a quantity at ``value`` is not at its ``held`` value (:data:`HELD_TOLERANCE`),
    elementwise for arrays: both engines' test at a stage's start."""
    return abs(held - value) > HELD_TOLERANCE * (1 + abs(held))


def held_away_message(stage_number: int, name: str, held: float | str) -> str:
    """Why a case failed with ``bad_stage_start`` (``stage_number`` from 1): both engines' words."""
    return (f"stage {stage_number} holds {name} = {held} but {name} is not at that "
            "value when the stage starts; add a stage that drives it there first")
