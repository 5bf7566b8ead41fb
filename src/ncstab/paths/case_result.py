"""The result of one law's batch of cases, and its event tables."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ncstab.paths.programme import EVENTS

__all__ = ["CaseResult", "as_strings", "empty_events"]


@dataclass
class CaseResult:
    """Result of one law's batch of cases (see :class:`ncstab.paths.PathResult`).

    Attributes
    ----------
    steps
        Padded arrays ``(B, n_steps_max, ...)``: ``s``, ``stage``, ``u``, ``F``,
        ``lam``, ``internal``, ``work``, ``K``, ``du`` (unit tangent), ``dlam``,
        ``load`` (systems with a load parameter) and the interaction variables
        of the system (``l``, ``alpha``, ``N``, ``T`` of a granular system,
        ``theta``, ``moment`` of springs; with a member axis where a family
        has several members).
    n_steps
        Stored states per case, ``(B,)``.
    status, message
        Per case: ``finished``, ``stopped:<event>`` or ``failed:<reason>``, and a
        sentence saying what happened.
    events
        Per event name: arrays ``found (B,)``, ``s``, ``s_lower``, ``s_upper``,
        ``stage``, ``lam``, ``u (B, n)``, ``F (B, n)``, ``K (B, n, n)``, the
        interaction variables as in ``steps`` and ``load``.
    counters
        ``accepted``, ``rejected``, ``located`` per case.
    cycles
        Per turn of every cycle stage (in programme order): ``work`` (B, C),
        the work over the turn (from the integrated work, not a quadrature of
        stored states); ``force_gap`` (B, C, n), F at the end minus F at the
        start of the turn; ``tangential_drift`` (B, C[, m]), the same for T
        (the internal variable of a rate law); ``stage`` (C,).
    engine
        Which stepper ran the batch, in words (the archive's ``engine``
        attribute): the compiled stepper with numba's version, and the kernel
        of the model it ran (:func:`ncstab.paths.engine_choice.choose_engine`).
    """

    steps: dict[str, np.ndarray]
    n_steps: np.ndarray
    status: np.ndarray
    message: np.ndarray
    events: dict[str, dict[str, np.ndarray]]
    counters: dict[str, np.ndarray]
    engine: str
    cycles: dict[str, np.ndarray] = field(default_factory=dict)


def as_strings(values: np.ndarray) -> np.ndarray:
    """``values.astype(str)`` for an object array of strings: by distinct value where
    there are few (statuses, messages: 20x faster than converting every entry)."""
    distinct = set(values.tolist())
    if values.size == 0 or len(distinct) > 32:
        return values.astype(str)
    strings = np.empty(values.shape, dtype=f"<U{max(1, *map(len, distinct))}")
    for text in distinct:
        strings[values == text] = text
    return strings


def empty_events(size: int, n: int, interaction_shapes: dict[str, tuple[int, ...]]) -> dict[str, dict[str, np.ndarray]]:
    """Per event name, its table of first occurrences (nothing found yet).

    ``interaction_shapes``: the batch's interaction fields and their shapes
    after the case axis (``{"l": (), ...}`` for the diamond), plus ``load``
    where the system has a load parameter.  Each field is one block over the
    events, each table holding a contiguous row of it (a dozen allocations
    for the lot, not six dozen).
    """
    shapes = {
        "found": ((size,), False), "s": ((size,), np.nan), "s_lower": ((size,), np.nan),
        "s_upper": ((size,), np.nan), "stage": ((size,), -1), "lam": ((size,), np.nan),
        "u": ((size, n), np.nan), "F": ((size, n), np.nan),
        **{name: ((size, *shape), np.nan) for name, shape in interaction_shapes.items()},
        "K": ((size, n, n), np.nan),
    }
    blocks = {
        key: np.full((len(EVENTS), *shape), blank, dtype=type(blank))
        for key, (shape, blank) in shapes.items()
    }
    return {name: {key: block[e] for key, block in blocks.items()} for e, name in enumerate(EVENTS)}
