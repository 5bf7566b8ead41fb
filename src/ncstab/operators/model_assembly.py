"""The assembly of F, K and the internal rates, one member at a time.

Every generated model kernel (:mod:`ncstab.operators.model_kernel_source`)
holds these functions, compiled by numba with the rest of it (their text is
pasted into the module: numba keeps its machine code in the cache folder), and
calls them after its own code (each member's kinematics, each law's response).
They implement (seed Eq. 5, 9, 16 and their derivative, Eq. 30-34 for a
contact)

    F += w J^T Q,   K += w [J^T D J + sum_c Q_c H_c],   d(internal)/du += C J,

with J = dq/du (k x L) and H = d2q/du2 (k x L x L) on the member's own L dofs,
Q its conjugate forces, D = dQ/dq along the law and C the rate rows of the
forces that are internal variables, scattered into the n dofs; and the
secondary-contact springs of closed gaps (energy w kappa g^2 / 2), each gap's
derivatives on its own dofs:

    F += w kappa g grad g,   K += w kappa (grad g grad g^T + g hess g).
"""

from __future__ import annotations

__all__ = ["ASSEMBLY", "add_gap_springs", "add_member", "add_rate_row"]


def add_member(out, forces_at, stiffness_at, n, weight, local, count, k, width, kinematics, response):
    # kinematics = (q (k), J (k x width), H (k x width x width)); response = (Q (k), D (k x k), ...)
    jacobian_at, hessian_at = k, k + k * width
    for a in range(count):
        total = 0.0
        for c in range(k):
            total += kinematics[jacobian_at + c * width + a] * response[c]
        out[forces_at + local[a]] += weight * total
    for a in range(count):
        for b in range(count):
            total = 0.0
            for c in range(k):
                row = 0.0
                for d in range(k):
                    row += response[k + c * k + d] * kinematics[jacobian_at + d * width + b]
                total += kinematics[jacobian_at + c * width + a] * row
                total += response[c] * kinematics[hessian_at + (c * width + a) * width + b]
            out[stiffness_at + local[a] * n + local[b]] += weight * total


def add_rate_row(out, row_at, local, count, k, width, kinematics, rates, force):
    # d(force)/du = sum_c C[force, c] J[c, :], scattered into the row of the internal variable
    for a in range(count):
        total = 0.0
        for c in range(k):
            total += rates[force * k + c] * kinematics[k + c * width + a]
        out[row_at + local[a]] += total


def add_gap_springs(out, forces_at, stiffness_at, n, gaps_at, local, counts, state, kappa, weights, geometry):
    # geometry = (g (count), grad g (count x width), hess g (count x width x width)) on each
    # gap's own dofs local[g, :counts[g]] (local: count x width); the springs of closed gaps,
    # scattered into the n dofs
    count, width = local.shape
    for g in range(count):
        value = geometry[g]
        out[gaps_at + g] = value
        if (state >> g) & 1:
            scale = kappa * weights[g]
            gradient_at = count + g * width
            hessian_at = count + count * width + g * width * width
            for a in range(counts[g]):
                out[forces_at + local[g, a]] += scale * value * geometry[gradient_at + a]
                for b in range(counts[g]):
                    term = geometry[gradient_at + a] * geometry[gradient_at + b]
                    term += value * geometry[hessian_at + a * width + b]
                    out[stiffness_at + local[g, a] * n + local[g, b]] += scale * term


#: The functions every generated model kernel holds.
ASSEMBLY = (add_member, add_rate_row, add_gap_springs)
