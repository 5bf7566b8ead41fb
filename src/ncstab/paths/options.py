"""Options of the path engine (a frozen dataclass: change with dataclasses.replace)."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["AUTO", "BACKENDS", "PathOptions", "SystemSpec", "SECONDARY_CONTACT_MODES", "NORMAL_MODES"]

SECONDARY_CONTACT_MODES = ("activate", "ignore", "stop")
NORMAL_MODES = ("deformable", "rigid")
#: PathOptions.initial_step estimated per case.
AUTO = "auto"
#: Steppers of the path engine (PathOptions.backend).
BACKENDS = ("auto", "compiled", "python")
#: Backends that were retired, and what became of them (an old study file that names
#: one gets this sentence in its error).
RETIRED_BACKENDS = {
    "numpy": "the numpy stepper was retired: every system runs on the compiled "
    "stepper, so remove the option (backend = \"auto\" chooses how it runs)",
}


@dataclass(frozen=True)
class PathOptions:
    """Tolerances, step bounds and limits of :func:`ncstab.follow`.

    Attributes
    ----------
    rtol, atol
        Relative and absolute local error tolerances of the embedded
        Dormand--Prince 8(5,3) integrator (per step, on the state (u, lambda,
        internal variables, work)).
    newton_tol
        Residual (max norm) at which the Newton projection onto the equilibrium
        manifold stops, for laws with a total form.
    newton_max_iter
        Newton iterations before a step is rejected and retried smaller.
    initial_step
        First arclength step of every case: ``"auto"`` (default) estimates
        it per case from the tolerances and a probe step of
        ``min(1e-3, max_step)`` (Hairer's starting-step algorithm,
        :func:`ncstab.paths.integrator.initial_step_size`); a number fixes it.
    min_step, max_step
        Arclength step bounds of the integrator: by default (``max_step`` =
        1) the steps are those the tolerances need; ``sample_step`` bounds the
        spacing of stored states and sign checks.
    sample_step
        The largest arclength between two stored states, and between two
        checks of the indicators' signs (figure resolution, event detection):
        each accepted step of length h is cut into ``ceil(h / sample_step)``
        equal pieces on its DOP853 interpolant (7th order, projected onto
        equilibrium for a law with a total form); every piece's end is stored
        and its indicators checked, as a step's end is.  ``None``: ``max_step``
        (every step one piece: the engine before ``sample_step``, whose
        default ``max_step`` was 0.02).
    max_steps
        Accepted steps per case over the whole programme before the case fails
        with ``failed:max_steps``.
    event_tol
        Width of the arclength bracket within which events are located.
    backend
        How the compiled stepper's loop (:mod:`ncstab.paths.compiled`), which
        covers every system and programme, runs: ``"compiled"`` as numba's
        machine code (compiled once per machine, about a minute for the
        reduced diamond and one and a half for general models); ``"python"`` as the same text in plain Python (the same numbers,
        bit for bit; slow); ``"auto"`` (default) the machine code where numba's
        cache holds it, plain Python for a small study that would otherwise
        wait for the compiler, else the machine code
        (:mod:`ncstab.paths.loop_route`).  The archive's ``engine`` attribute
        says which numba and kernels.  ``"numpy"`` (the numpy stepper,
        retired) is an error that says so.
    """

    rtol: float = 1e-10
    atol: float = 1e-12
    newton_tol: float = 1e-12
    newton_max_iter: int = 12
    initial_step: float | str = "auto"
    min_step: float = 1e-12
    max_step: float = 1.0
    sample_step: float | None = 0.02
    max_steps: int = 20_000
    event_tol: float = 1e-10
    backend: str = "auto"

    def __post_init__(self) -> None:
        for name in ("rtol", "atol", "newton_tol", "initial_step", "min_step", "max_step", "sample_step", "event_tol"):
            value = getattr(self, name)
            if name == "initial_step" and isinstance(value, str) and value == AUTO:
                continue
            if name == "sample_step" and value is None:
                continue
            number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
            if not (number and 0 < value < float("inf")):
                allowed = ' or "auto"' if name == "initial_step" else ""
                raise ValueError(f"PathOptions.{name} must be a positive finite number{allowed}, got {value!r}")
        for name in ("newton_max_iter", "max_steps"):
            value = getattr(self, name)
            whole = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
            if not (whole and value >= 1):
                raise ValueError(f"PathOptions.{name} must be a positive integer, got {value!r}")
        if self.backend in RETIRED_BACKENDS:
            raise ValueError(f"PathOptions.backend = {self.backend!r}: {RETIRED_BACKENDS[self.backend]}")
        if self.backend not in BACKENDS:
            raise ValueError(
                f"PathOptions.backend must be one of {', '.join(BACKENDS)}, got {self.backend!r}"
            )
        if self.min_step > self.max_step:
            raise ValueError("PathOptions.min_step must not exceed max_step")

    @property
    def stored_spacing(self) -> float:
        """The largest arclength between two stored states: ``sample_step``, else ``max_step``."""
        return self.max_step if self.sample_step is None else float(self.sample_step)

    @property
    def max_pieces(self) -> int:
        """The most pieces a step is cut into: ``ceil(max_step / sample_step)`` (at least 1)."""
        return max(1, math.ceil(self.max_step / self.stored_spacing))

    def pieces(self, h: np.ndarray) -> np.ndarray:
        """How many pieces steps of lengths ``h`` are cut into: ``ceil(h / sample_step)``,
        between 1 and :attr:`max_pieces` (1 where h is not above ``sample_step``, or NaN)."""
        h = np.asarray(h, dtype=float)
        count = np.ceil(np.where(h > self.stored_spacing, h, self.stored_spacing) / self.stored_spacing)
        return np.minimum(count, self.max_pieces).astype(np.int64)


@dataclass(frozen=True)
class SystemSpec:
    """Which shipped system to follow, with its settings, and how its contacts behave.

    Attributes
    ----------
    name
        System name in :data:`ncstab.systems.SYSTEMS`: ``"diamond"``,
        ``"ring"``, ``"column"``, ``"ziegler"``.
    secondary_contacts
        ``"activate"`` (default): a frictionless unilateral normal spring of
        stiffness ratio ``kappa`` acts between non-neighbour grains once they
        touch; ``"ignore"``: the event is recorded only; ``"stop"``: the stage
        ends there.
    normal
        ``"deformable"`` (default) or ``"rigid"``: the pure-shear limit of the
        seed (k_n -> infinity, Eq. 60-68; the reduced diamond only).
    reduction, grains, links, load, file
        The system's structural settings (``None``: the default, where it has
        one): the diamond's ``reduction`` (``"symmetric"``, the seed's two
        dofs, or ``"axes"``, four), a ring's ``grains``, a column's ``links``,
        Ziegler's ``load`` (``"follower"`` or ``"dead"``), a packing's
        ``file`` (its absolute path).
    grain, contacts, rotations
        The grains of ``name = "grains"`` (``((x, y, radius, held), ...)``), their
        contacts (``((a, b), ...)``) and whether they rotate (:mod:`ncstab.systems.user_grains`).
    joints, supports, springs
        The chain of ``name = "bars"``: its joints' heights, supported joints and springs'
        stiffnesses (:mod:`ncstab.systems.user_bars`).
    """

    name: str = "diamond"
    secondary_contacts: str = "activate"
    normal: str = "deformable"
    reduction: str | None = None
    grains: int | None = None
    links: int | None = None
    load: str | None = None
    file: str | None = None
    grain: tuple | None = None
    contacts: tuple | None = None
    rotations: bool | None = None
    joints: tuple | None = None
    supports: tuple | None = None
    springs: float | tuple | None = None

    def __post_init__(self) -> None:
        from ncstab.systems import SYSTEMS

        if self.name not in SYSTEMS:
            raise ValueError(f"unknown system {self.name!r}; systems are: {', '.join(SYSTEMS)}")
        if self.secondary_contacts not in SECONDARY_CONTACT_MODES:
            raise ValueError(
                f"secondary_contacts = {self.secondary_contacts!r} is not allowed; "
                f"allowed: {', '.join(SECONDARY_CONTACT_MODES)}"
            )
        if self.normal not in NORMAL_MODES:
            raise ValueError(f"normal = {self.normal!r} is not allowed; allowed: {', '.join(NORMAL_MODES)}")
        # checked once (a grain list's geometry is checked here), and kept: ``settings``
        self.__dict__["settings"] = SYSTEMS[self.name].check_settings(self.given_settings)
        if self.normal == "rigid" and not self.is_reduced_diamond:
            raise ValueError(
                "normal = 'rigid' (the pure-shear limit, seed Eq. 60-68) is defined for the reduced "
                "diamond only (name = 'diamond', reduction = 'symmetric')"
            )

    @property
    def given_settings(self) -> dict[str, object]:
        """The structural settings given (not ``None``)."""
        values = {"reduction": self.reduction, "grains": self.grains, "links": self.links, "load": self.load,
                  "file": self.file, "grain": self.grain, "contacts": self.contacts, "rotations": self.rotations,
                  "joints": self.joints, "supports": self.supports, "springs": self.springs}
        return {k: v for k, v in values.items() if v is not None}

    @functools.cached_property
    def settings(self) -> dict[str, object]:
        """Every structural setting of the system, defaults included (checked when the spec is made)."""
        from ncstab.systems import SYSTEMS

        return SYSTEMS[self.name].check_settings(self.given_settings)

    @property
    def is_reduced_diamond(self) -> bool:
        """The seed's two-dof diamond (followed by a fused kernel)."""
        return self.name == "diamond" and self.reduction in (None, "symmetric")

    @property
    def definition(self):
        """The :class:`~ncstab.systems.SystemDefinition` (built once, cached)."""
        from ncstab.systems import system_definition

        return system_definition(self.name, tuple(sorted(self.settings.items())))
