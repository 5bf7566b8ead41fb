"""Tangent operators and stability indicators (layer ``operators/``)."""

from ncstab.operators.indicators import (
    det_K,
    flutter_discriminant,
    force_controlled_mask,
    hill_eigenvalue,
    mixed_control_determinant,
    mixed_control_stiffness,
    normalized_second_order_work,
    second_order_work,
    skew_part,
    symmetric_part,
)
from ncstab.operators.directional_work import (
    directional_second_order_work,
    second_order_work_form,
    unstable_cone,
)
from ncstab.operators.tangent import (
    conjugate_tangent,
    contact_forces,
    generalized_forces,
    tangent_operator,
    tangent_operator_at_contact_state,
    tangent_operator_at_forces,
)

__all__ = [
    "conjugate_tangent",
    "contact_forces",
    "det_K",
    "directional_second_order_work",
    "flutter_discriminant",
    "force_controlled_mask",
    "generalized_forces",
    "hill_eigenvalue",
    "mixed_control_determinant",
    "mixed_control_stiffness",
    "normalized_second_order_work",
    "second_order_work",
    "second_order_work_form",
    "skew_part",
    "symmetric_part",
    "tangent_operator",
    "tangent_operator_at_contact_state",
    "tangent_operator_at_forces",
    "unstable_cone",
]
