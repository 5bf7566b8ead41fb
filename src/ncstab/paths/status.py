"""The status vocabulary of a case (a leaf module: every layer of the engine reads it).

A case is ``running`` while the engine follows it, then ``finished`` (every
stage done), ``stopped:<event>`` (a stop event of its stage) or
``failed:<reason>`` with a message saying what happened.
"""

from __future__ import annotations

__all__ = [
    "FAILURE_REASONS", "FINISHED", "RUNNING", "STOPPED_PREFIX", "FAILED_PREFIX", "failed", "finished_message", "max_steps_message",
    "stopped", "stopped_message",
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
