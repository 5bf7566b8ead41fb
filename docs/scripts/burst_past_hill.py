"""The burst past Hill's loss: kinetic energy against minus the second-order work.

Follows the seed's diamond (McNamara, gamma = 0.5) under the seed's mixed control
(F1 = 0 while F2 rises to 0.75, then F2 held and D1 driven to 0.58, past Hill's
loss at D1 = 0.561), releases D1 with both forces held and the state displaced
by 1e-4 along the direction of negative second-order work (the eigenvector of
K_sym with the negative eigenvalue), and draws the kinetic energy of the motion
beside -(d2W(Delta u) - d2W(delta)) / 2, d2W(x) = x . K x / 2 the second-order
work per contact of the displacement from the equilibrium.  Writes
docs/figures/burst_past_hill.png; tests/test_dynamic_stages.py checks the
agreement it shows.

    python docs/scripts/burst_past_hill.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ncstab.dynamics import DynamicStage, follow_motions
from ncstab.paths import SystemSpec, follow

OUT = Path(__file__).resolve().parents[1] / "figures" / "burst_past_hill.png"


def main() -> None:
    path = follow(SystemSpec("diamond", secondary_contacts="ignore"), ["mcnamara"],
                  [{"hold": {"F1": 0.0}, "drive": {"F2": 0.75}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.58}}],
                  {"gamma": 0.5})
    result = path.results[0]
    last = result.n_steps[0] - 1
    start, stiffness = result.steps["u"][0, last], result.steps["K"][0, last]
    vectors = np.linalg.eigh(0.5 * (stiffness + stiffness.T))[1]
    direction = 1e-4 * vectors[:, 0]
    motion = follow_motions(path, DynamicStage(30.0, {"D1": direction[0], "D2": direction[1]}, samples=601))[0][0]
    increment = motion.u - start
    d2W = 0.5 * np.einsum("ti,ij,tj->t", increment, stiffness, increment)
    figure = Figure(figsize=(6.4, 4.8))
    axis = figure.subplots()
    axis.semilogy(motion.time, motion.kinetic_energy, label="kinetic energy (dynamic stage)")
    axis.semilogy(motion.time, -0.5 * (d2W - d2W[0]), "--", label="-(d2W(Du) - d2W(delta)) / 2")
    axis.set_xlabel("time (units of sqrt(m / k_n))")
    axis.set_ylabel("energy per contact (k_n (2R)^2)")
    axis.set_title(f"McNamara diamond released past Hill's loss ({motion.status}, t = {motion.message.split()[-1]})", fontsize=9)
    axis.legend(loc="best")
    figure.tight_layout()
    figure.savefig(OUT, dpi=100)
    print(OUT)


if __name__ == "__main__":
    main()
