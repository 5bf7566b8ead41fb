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
from ncstab.operators.characteristic_polynomial import (
    characteristic_polynomial,
    hurwitz_determinants,
    hurwitz_matrix,
)
from ncstab.operators.dynamics import (
    critical_frequency,
    divergence_indicator,
    dynamic_spectrum,
    flutter_indicator,
    flutter_onset_indicator,
    frequency_discriminant,
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
    "characteristic_polynomial",
    "conjugate_tangent",
    "contact_forces",
    "critical_frequency",
    "det_K",
    "directional_second_order_work",
    "divergence_indicator",
    "dynamic_spectrum",
    "flutter_discriminant",
    "flutter_indicator",
    "flutter_onset_indicator",
    "force_controlled_mask",
    "frequency_discriminant",
    "generalized_forces",
    "hill_eigenvalue",
    "hurwitz_determinants",
    "hurwitz_matrix",
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
