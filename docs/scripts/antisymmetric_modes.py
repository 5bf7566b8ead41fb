"""Which fails first in an antisymmetric mode of the diamond: Hill's condition or det K?

Follows the four seed laws on the unreduced diamond (`reduction = "axes"`) for
the seed's cases, and prints a Markdown table of the displacement D1* where
each block of K first loses Hill's condition (smallest eigenvalue of its
symmetric part) and its determinant: the symmetric block (the reduced K) and
the antisymmetric block (modes D_top - D_bottom, D_left - D_right).  Zeros are
located by linear interpolation between stored states 0.002 apart in
arclength (three decimals).  docs/models.md shows the table; the test suite
checks that it is what this script prints.

    python docs/scripts/antisymmetric_modes.py
"""

from __future__ import annotations

import numpy as np

from ncstab.paths import PathOptions, SystemSpec, follow

LAWS = ["cundall_strack", "weakly_hypoelastic", "mcnamara", "turco"]
#: Symmetric and antisymmetric modes of the four axes (D_top, D_bottom, D_left, D_right).
SYMMETRIC = np.array([[1, 0], [1, 0], [0, 1], [0, 1]]) / np.sqrt(2)
ANTISYMMETRIC = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]]) / np.sqrt(2)


def _programme(F2: float) -> list[dict]:
    drive = {"hold": {"F_left": "current", "F_right": "current"}, "drive": {"D_top": 0.6, "D_bottom": 0.6}}
    if F2 == 0:
        return [{"hold": {"F_left": 0.0, "F_right": 0.0}, "drive": {"D_top": 0.6, "D_bottom": 0.6}}]
    return [{"hold": {"F_top": 0.0, "F_bottom": 0.0}, "drive": {"F_left": F2, "F_right": F2}}, drive]


def _first_zero(x: np.ndarray, values: np.ndarray) -> float:
    sign = np.sign(values)
    crossing = np.flatnonzero(sign[1:] * sign[:-1] < 0)
    if crossing.size == 0:
        return np.nan
    k = crossing[0]
    return float(x[k] - values[k] * (x[k + 1] - x[k]) / (values[k + 1] - values[k]))


def block_losses(law: str, gamma: float, F2: float) -> dict[str, float]:
    """D1* at the first loss of Hill's condition and of det K, per block, in the last stage."""
    ds = follow(
        SystemSpec("diamond", reduction="axes", secondary_contacts="ignore"), [law], _programme(F2),
        {"gamma": gamma}, PathOptions(max_step=0.002),
    ).to_dataset()
    n = int(ds["n_steps"].item())
    stage = ds["stage"].values[0, :n]
    last = stage == stage.max()
    K, D1 = ds["K"].values[0, :n][last], ds["u"].values[0, :n, 0][last]
    out = {}
    for name, modes in (("symmetric", SYMMETRIC), ("antisymmetric", ANTISYMMETRIC)):
        block = np.einsum("ia,nij,jb->nab", modes, K, modes)
        hill = np.linalg.eigvalsh(0.5 * (block + np.swapaxes(block, -1, -2)))[:, 0]
        out[f"{name} Hill"] = _first_zero(D1, hill)
        out[f"{name} det"] = _first_zero(D1, np.linalg.det(block))
    return out


def table() -> str:
    """The Markdown table of docs/models.md."""
    columns = ["symmetric Hill", "symmetric det", "antisymmetric Hill", "antisymmetric det"]
    lines = [
        "| law | γ | F2* | " + " | ".join(columns) + " |",
        "|---|---|---|" + "---|" * len(columns),
    ]
    for law in LAWS:
        for gamma in (0.5, 2.0):
            for F2 in (0.0, 0.75):
                losses = block_losses(law, gamma, F2)
                cells = ["—" if np.isnan(losses[c]) else f"{losses[c]:.3f}" for c in columns]
                lines.append(f"| {law} | {gamma:g} | {F2:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(table())
