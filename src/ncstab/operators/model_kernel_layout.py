"""Where each quantity sits in a model kernel's output row, and the C signature of its callback.

:class:`KernelLayout` is the row :func:`ncstab.operators.model_kernel_source.kernel_source`
prints ``evaluate_case`` to fill (F, K, dF/dP, d(internal)/du, gaps, overlaps, M(u),
C(u), the domain code, the interactions); :data:`KERNEL_SIGNATURE` is the C signature
of ``case``, the kernel on pointers, that the compiled stage loop calls
(:meth:`ncstab.operators.model_kernel.ModelKernel.callback`).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["KERNEL_SIGNATURE", "KernelLayout"]


@dataclass(frozen=True)
class KernelLayout:
    """Where each quantity sits in a kernel's output row (and how long the row is).

    Attributes
    ----------
    n
        Number of dofs.
    forces, stiffness, load
        Offsets of F (n), K (n x n, row major) and dF/dP = -Q_ext (n; zeros
        without a load parameter).
    gradient
        Offset of d(internal)/du (n_internal x n).
    gaps, overlaps
        Offsets of the gap values (one per gap) and of the normal overlaps of
        the contacts that can open (no_tension laws, in bit order).
    mass, damping, inertia
        Offsets of M(u) and C(u) (n x n, row major) where the system has them, and
        their widths: (n * n or 0, n * n or 0).
    domain
        Offset of the domain code: -1 inside the domain, else 1 + the index of the first
        condition violated, contacts first (l* > 0, then |alpha| < pi/2, per member), then
        the system's domain conditions (the order of ``ModelBatch.domain_reasons``).
    interactions
        Per family, the offsets of its members' variables (m x k) and stored
        forces (m x k_f).
    size
        The row's length.
    """

    n: int
    n_internal: int
    n_gaps: int
    n_open: int
    family_shapes: tuple[tuple[int, int, int], ...]  # (members, variables, forces) per family
    forces: int
    stiffness: int
    load: int
    gradient: int
    gaps: int
    overlaps: int
    mass: int
    damping: int
    inertia: tuple[int, int]
    domain: int
    interactions: tuple[tuple[int, int], ...]
    size: int

    @classmethod
    def build(cls, n: int, n_internal: int, n_gaps: int, n_open: int, shapes: list[tuple[int, int, int]],
              inertia: tuple[int, int] = (0, 0)) -> KernelLayout:
        at = 0

        def take(width: int) -> int:
            nonlocal at
            at += width
            return at - width

        forces, stiffness, load = take(n), take(n * n), take(n)
        gradient, gaps, overlaps = take(n_internal * n), take(n_gaps), take(n_open)
        mass, damping, domain = take(inertia[0]), take(inertia[1]), take(1)
        interactions = tuple((take(m * k), take(m * kf)) for m, k, kf in shapes)  # the row's last block
        return cls(n, n_internal, n_gaps, n_open, tuple(shapes), forces, stiffness, load, gradient, gaps, overlaps,
                   mass, damping, tuple(inertia), domain, interactions, at)


#: The C signature of a model kernel's callback (``case`` of the generated module,
#: :meth:`ncstab.operators.model_kernel.ModelKernel.callback`):
#: ``case(u, internal, load, state, p, out, scratch)``.
KERNEL_SIGNATURE = "void(CPointer(float64), CPointer(float64), float64, int64, CPointer(float64), CPointer(float64), CPointer(float64))"
