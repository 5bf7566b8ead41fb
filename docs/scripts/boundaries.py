"""The figures of docs/boundaries.md: boundaries traced as curves (issue 40).

* ``boundary_paradox.png``: Ziegler's destabilization paradox as a curve family,
  the flutter load against b1 for several b2 (``studies/ziegler_flutter_boundary.toml``),
  with the undamped load 7/2 - sqrt 2;
* ``boundary_over_diagram.png``: the limit-point boundary of the McNamara diamond
  along gamma at F2* = 0.75, drawn over the 16-cell sweep of the same row.

Run from the repository root:  python docs/scripts/boundaries.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import ncstab
from ncstab.plotting.boundaries import boundary_figure, boundary_over_diagram_figure
from ncstab.studies import load_study, run_study

FIGURES = Path(__file__).resolve().parents[1] / "figures"
PROGRAMME = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.6}},
]


def main() -> None:
    root = Path(__file__).resolve().parents[2]
    family = run_study(load_study(root / "studies" / "ziegler_flutter_boundary.toml"))
    figure = boundary_figure(family)
    axes = figure.axes[0]
    axes.axhline(3.5 - np.sqrt(2.0), color="0.4", ls="--", lw=1, label="undamped 7/2 - sqrt 2")
    axes.legend(fontsize="small")
    figure.savefig(FIGURES / "boundary_paradox.png", dpi=120)

    curve = ncstab.boundary("diamond", ["mcnamara"], PROGRAMME, {"gamma": 0.5, "F2_lateral": 0.75},
                            event="limit_point", parameter="gamma", start=0.5, stop=0.3, secondary_contacts="ignore")
    grid = ncstab.follow("diamond", ["mcnamara"], PROGRAMME, {"gamma": list(np.linspace(0.3, 0.5, 16)), "F2_lateral": 0.75},
                         secondary_contacts="ignore").to_dataset()
    boundary_over_diagram_figure(curve, grid, Figure()).savefig(FIGURES / "boundary_over_diagram.png", dpi=120)


if __name__ == "__main__":
    main()
