"""The look of every figure: sizes, fonts, colours, markers, names and labels."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from fractions import Fraction

import numpy as np
from matplotlib import colormaps

__all__ = [
    "AXIS_LABELS",
    "EVENT_MARKERS",
    "FAILED_COLOUR",
    "FIGURE_SIZE",
    "LAW_NAMES",
    "PARAMETER_SYMBOLS",
    "RC_PARAMS",
    "case_colours",
    "fixed_parameters_text",
    "force_label",
    "format_parameter",
    "law_display_name",
    "parameter_symbol",
    "symbolic_text",
]

#: Figure size in inches (one column of a two-column journal page, scaled 2x).
FIGURE_SIZE = (6.4, 4.8)

#: matplotlib settings applied while a figure is drawn and saved.
RC_PARAMS: dict[str, object] = {
    "font.size": 10,
    "axes.titlesize": 10,
    "axes.labelsize": 10,
    "xtick.labelsize": 9,
    "ytick.labelsize": 9,
    "legend.fontsize": 8,
    "legend.framealpha": 0.9,
    "axes.grid": True,
    "grid.color": "0.88",
    "grid.linewidth": 0.6,
    "axes.axisbelow": True,
    "lines.linewidth": 1.6,
    "savefig.facecolor": "white",
    "mathtext.fontset": "dejavusans",
}

#: Law names as a reader of the seed knows them.
LAW_NAMES: dict[str, str] = {
    "linear_spring": "linear springs",
    "cundall_strack": "Cundall–Strack (hypoelastic)",
    "weakly_hypoelastic": "weakly hypoelastic",
    "mcnamara": "McNamara et al. 2008 (hyperelastic)",
    "turco": "Turco et al. 2019 (hyperelastic)",
}

#: Law modifiers (``"mcnamara+no_tension"``) as appended to the display name.
MODIFIER_NAMES: dict[str, str] = {"no_tension": "no tension"}

#: Swept-parameter names as symbols.
PARAMETER_SYMBOLS: dict[str, str] = {
    "b1": r"$b_1$",
    "b2": r"$b_2$",
    "m1": r"$m_1$",
    "m2": r"$m_2$",
    "branch": "branch",
    "gamma": r"$\gamma$",
    "alpha0": r"$\alpha_0$",
    "kappa": r"$\kappa$",
}

#: A free parameter named after a force or a displacement (``F2_lateral``, ``D1_max``):
#: the quantity it gives, dimensionless (seed Eq. 37).
_QUANTITY_NAME = re.compile(r"^(?P<quantity>[FD])(?P<dof>\d+)(?:_\w*)?$")

#: Words of plain-text descriptions written as the symbols of the figures (titles).
_TEXT_SYMBOLS: tuple[tuple[re.Pattern[str], str], ...] = tuple(
    (re.compile(pattern), symbol)
    for pattern, symbol in (
        (r"\balpha_?0\b", "α₀"),
        (r"\balpha_?max\b", "α_max"),
        (r"\balpha\b", "α"),
        (r"\bgamma\b", "γ"),
        (r"\bkappa\b", "κ"),
        (r"\bDelta_?1\b", "Δ₁"),
        (r"\bDelta_?2\b", "Δ₂"),
        (r"\bF1\b", "F₁"),
        (r"\bF2\b", "F₂"),
        (r"\bpi\b", "π"),
    )
)

#: event -> (marker, marker size, filled, legend text).  One legend entry per
#: event kind present in a figure.
EVENT_MARKERS: dict[str, tuple[str, float, bool, str]] = {
    "limit_point": ("o", 6.5, True, "limit point (det K = 0)"),
    "hill_loss": ("s", 10.0, False, "loss of Hill's condition"),
    "controllability_loss": ("^", 9.0, False, "loss of controllability"),
    "turning_point": ("v", 9.0, False, "turning point"),
    "secondary_contact": ("x", 8.0, False, "secondary contact"),
    "flutter_onset": ("*", 11.0, True, "flutter onset"),
    "bifurcation": ("D", 8.0, True, "bifurcation point"),
    "divergence": ("P", 9.0, True, "divergence"),
    # every extremum_<name> of [output] extrema (ncstab.paths.extrema) takes this style
    "extremum": ("p", 9.0, True, "first extremum ([output] extrema)"),
}

#: Cases of one law from which colours follow a colormap.
COLORMAP_MIN_CASES = 4

#: Colour of failed cases (drawn dashed).
FAILED_COLOUR = "0.6"

#: Axis labels with symbols and units.  Forces depend on the normal (see
#: :func:`force_label`).
AXIS_LABELS: dict[str, str] = {
    "alpha": r"$\alpha$ (rad)",
    "alpha_deg": r"$\alpha$ (deg)",
    "D1": r"$\Delta_1^* = \Delta_1/2R$",
    "det_K": r"$\det K^*$",
    "hill": r"$\lambda_{\min}(K^*_{\mathrm{sym}})$",
    "d2W": "normalised $d^2W$",
}


def force_label(normal: str) -> str:
    """Label of the vertical force axis: F1* (units 2R k_n) or F1-hat (2R k_t, rigid normal)."""
    if normal == "rigid":
        return r"$\hat F_1 = F_1/(2R\,k_t)$"
    return r"$F_1^* = F_1/(2R\,k_n)$"


def law_display_name(name: str) -> str:
    """``"mcnamara+no_tension"`` -> ``"McNamara et al. 2008 (hyperelastic), no tension"``."""
    base, *modifiers = [part.strip() for part in str(name).split("+")]
    text = LAW_NAMES.get(base, base)
    for modifier in modifiers:
        text += ", " + MODIFIER_NAMES.get(modifier, modifier)
    return text


def _pi_fraction(value: float) -> str | None:
    """``pi/4`` for 0.785..., None when value/pi is not a simple fraction."""
    if value == 0:
        return None
    fraction = Fraction(value / math.pi).limit_denominator(12)
    if not math.isclose(float(fraction) * math.pi, value, rel_tol=0, abs_tol=1e-12):
        return None
    num, den = fraction.numerator, fraction.denominator
    head = "π" if num == 1 else ("−π" if num == -1 else f"{num}π")
    return head if den == 1 else f"{head}/{den}"


def parameter_symbol(name: str) -> str:
    """The symbol of a parameter for labels: ``gamma`` -> γ, ``F2_lateral`` -> F₂*.

    Known names (:data:`PARAMETER_SYMBOLS`); a free parameter named after a
    generalized force or displacement (``F2_lateral``, ``D1_target``) is that
    dimensionless quantity, :math:`F_2^*` or :math:`\\Delta_1^*`; any other name is
    itself.
    """
    if name in PARAMETER_SYMBOLS:
        return PARAMETER_SYMBOLS[name]
    match = _QUANTITY_NAME.match(name)
    if match:
        letter = "F" if match["quantity"] == "F" else r"\Delta"
        dof = match["dof"] if len(match["dof"]) == 1 else "{" + match["dof"] + "}"
        return rf"${letter}_{dof}^*$"
    return name


def symbolic_text(text: str) -> str:
    """Plain-text words written as symbols: ``"gamma = 2, F2* = 0, alpha0 = pi/4"`` ->
    ``"γ = 2, F₂* = 0, α₀ = π/4"`` (whole words only; nothing else changes)."""
    for pattern, symbol in _TEXT_SYMBOLS:
        text = pattern.sub(symbol, text)
    return text


def format_parameter(name: str, value: object) -> str:
    """``"γ = 0.5"``, ``"α₀ = π/4"``: a parameter and its value for a label."""
    symbol = parameter_symbol(name)
    if isinstance(value, (float, np.floating, int, np.integer)) and not isinstance(value, bool):
        number = float(value)
        text = (_pi_fraction(number) if name.startswith("alpha") else None) or f"{number:.4g}"
    else:
        text = str(value)
    return f"{symbol} = {text}"


def case_colours(laws: Sequence[str], n_cases: int) -> list[object]:
    """One colour per case.

    A sweep of one law over four cases or more is coloured along a colormap
    (ordered like the sweep, seed Fig. 8); otherwise cases get distinct
    qualitative colours (tab10, or tab20 past ten curves).
    """
    if n_cases == 0:
        return []
    if len(set(laws)) == 1 and n_cases >= COLORMAP_MIN_CASES:
        cmap = colormaps["viridis"]
        return [cmap(x) for x in np.linspace(0.0, 0.8, n_cases)]
    palette = colormaps["tab10" if n_cases <= 10 else "tab20"].colors
    return [palette[k % len(palette)] for k in range(n_cases)]


def fixed_parameters_text(attrs: Mapping[str, object]) -> str:
    """``"γ = 2, α₀ = π/4"`` from the ``parameter_<name>`` attributes of a Dataset."""
    parts = []
    for key, value in attrs.items():
        if key.startswith("parameter_"):
            parts.append(format_parameter(key[len("parameter_") :], value))
    return ", ".join(parts)
