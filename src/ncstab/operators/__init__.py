"""Tangent operators and stability indicators (layer ``operators/``)."""

from __future__ import annotations

from ncstab.lazy_imports import lazy_attributes

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

#: Imported on first use: the tangent operators import the laws (sympy), which a
#: figure of stored indicators (``ncstab plot``) does not need.
__getattr__, __dir__ = lazy_attributes(
    __name__,
    {
        "det_K": "ncstab.operators.indicators",
        "flutter_discriminant": "ncstab.operators.indicators",
        "force_controlled_mask": "ncstab.operators.indicators",
        "hill_eigenvalue": "ncstab.operators.indicators",
        "mixed_control_determinant": "ncstab.operators.indicators",
        "mixed_control_stiffness": "ncstab.operators.indicators",
        "normalized_second_order_work": "ncstab.operators.indicators",
        "second_order_work": "ncstab.operators.indicators",
        "skew_part": "ncstab.operators.indicators",
        "symmetric_part": "ncstab.operators.indicators",
        "characteristic_polynomial": "ncstab.operators.characteristic_polynomial",
        "hurwitz_determinants": "ncstab.operators.characteristic_polynomial",
        "hurwitz_matrix": "ncstab.operators.characteristic_polynomial",
        "critical_frequency": "ncstab.operators.dynamics",
        "divergence_indicator": "ncstab.operators.dynamics",
        "dynamic_spectrum": "ncstab.operators.dynamics",
        "flutter_indicator": "ncstab.operators.dynamics",
        "flutter_onset_indicator": "ncstab.operators.dynamics",
        "frequency_discriminant": "ncstab.operators.dynamics",
        "directional_second_order_work": "ncstab.operators.directional_work",
        "second_order_work_form": "ncstab.operators.directional_work",
        "unstable_cone": "ncstab.operators.directional_work",
        "conjugate_tangent": "ncstab.operators.tangent",
        "contact_forces": "ncstab.operators.tangent",
        "generalized_forces": "ncstab.operators.tangent",
        "tangent_operator": "ncstab.operators.tangent",
        "tangent_operator_at_contact_state": "ncstab.operators.tangent",
        "tangent_operator_at_forces": "ncstab.operators.tangent",
    },
    globals(),
)
