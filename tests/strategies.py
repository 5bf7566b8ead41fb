"""Hypothesis strategies and shared constants for the test suite.

Kept out of ``conftest.py`` because test modules import from it (pytest puts
``tests/`` on ``sys.path``; ``conftest.py`` itself is not meant to be imported).

Everything is dimensionless (seed Eq. 37): l* = l / 2R, forces in units of
2R k_n, gamma = k_t / k_n.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from ncstab.systems import DiamondChain

#: The four laws of the seed and the class the seed gives each (Eq. 13-29).
EXPECTED_CLASS = {
    "cundall_strack": "strongly hypoelastic",
    "weakly_hypoelastic": "weakly hypoelastic",
    "mcnamara": "hyperelastic",
    "turco": "hyperelastic",
}
BASE_LAWS = tuple(EXPECTED_CLASS)
#: The DEM codes' shear-update rules that the seed's laws do not cover (docs/dem-codes.md).
DEM_LAWS = ("dem_yade_avoid_ratcheting", "dem_chrono_one_step")
NO_TENSION_LAWS = tuple(f"{name}+no_tension" for name in BASE_LAWS)
#: Laws with a total form F(u) (everything but Cundall--Strack).
TOTAL_FORM_LAWS = tuple(
    name for name in BASE_LAWS + NO_TENSION_LAWS if not name.startswith("cundall_strack")
)
#: Laws deriving from a potential (seed Eq. 17).
HYPERELASTIC_LAWS = ("mcnamara", "turco", "mcnamara+no_tension", "turco+no_tension")


@dataclass(frozen=True)
class DiamondState:
    """A state of the diamond chain drawn in contact variables, with its parameters."""

    alpha0: float
    gamma: float
    length: float
    alpha: float

    @property
    def system(self) -> DiamondChain:
        return DiamondChain(alpha0=self.alpha0)

    @property
    def q(self) -> np.ndarray:
        """Contact variables, shape (1, 2)."""
        return np.array([[self.length, self.alpha]])

    @property
    def u(self) -> np.ndarray:
        """Generalized displacements (Delta_1*, Delta_2*), shape (2,)."""
        return self.system.displacements(self.q)

    def overlap(self, law_name: str) -> float:
        """Normal overlap delta of the named law (the no_tension kink is delta = 0)."""
        if law_name.startswith("turco"):
            return float(np.cos(self.alpha - self.alpha0) - self.length)
        return float(1.0 - self.length)


@st.composite
def diamond_states(
    draw: st.DrawFn,
    alpha0: tuple[float, float] = (0.2, 1.35),
    gamma: tuple[float, float] = (0.0, 3.0),
    length: tuple[float, float] = (0.5, 1.5),
    alpha: tuple[float, float] = (0.05, 1.5),
) -> DiamondState:
    """Admissible states: alpha0 in [0.2, 1.35], gamma in [0, 3], l* in [0.5, 1.5],
    alpha in (0.05, 1.5) -- a branch well inside the first quadrant, grains neither
    interpenetrating by more than half a diameter nor more than half a diameter apart."""
    return DiamondState(
        alpha0=draw(st.floats(*alpha0)),
        gamma=draw(st.floats(*gamma)),
        length=draw(st.floats(*length)),
        alpha=draw(st.floats(*alpha, exclude_min=True, exclude_max=True)),
    )


#: An arbitrary value of Cundall--Strack's internal variable T*.
tangential_forces = st.floats(-1.0, 1.0)
