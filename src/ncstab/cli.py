"""The ``ncstab`` command: a thin layer over the library."""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

import ncstab

__all__ = ["main", "build_parser"]


def _format_table(rows: list[list[str]], header: list[str]) -> str:
    widths = [max(len(str(r[i])) for r in rows + [header]) for i in range(len(header))]
    line = "  ".join("-" * w for w in widths)
    out = ["  ".join(h.ljust(w) for h, w in zip(header, widths)), line]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(row.rstrip() for row in out)


def command_laws(args: argparse.Namespace) -> int:
    """Print the law catalogue with each law's computed class."""
    import sympy as sp

    from ncstab.laws import law_definition, law_names
    from ncstab.symbolic import classify, kinematic_integrability

    rows = []
    for name in law_names(with_modifiers=args.all):
        definition = law_definition(name)
        result = classify(definition)
        energy = sp.sstr(result.energy) if result.energy is not None else "-"
        rows.append([name, result.kind, definition.equations, energy, result.reason])
    print(_format_table(rows, ["law", "class", "seed", "energy W(l, alpha)", "decided by"]))
    print()
    print(f"System kinematics: {kinematic_integrability()}")
    print("Variables are dimensionless (seed Eq. 37): l = l/2R, N, T in units of 2R k_n,")
    print("W in units of k_n (2R)^2 per contact, gamma = k_t/k_n.")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ncstab",
        description=(
            "Stability analysis of non-conservative discrete systems: the diamond "
            "granular chain with hypo- and hyperelastic contact laws."
        ),
    )
    parser.add_argument("--version", action="version", version=f"ncstab {ncstab.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    laws = sub.add_parser("laws", help="print the law catalogue and each law's computed class")
    laws.add_argument(
        "--all", action="store_true", help="also list every law with the no_tension modifier"
    )
    laws.set_defaults(handler=command_laws)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "handler", None) is None:
        parser.print_help()
        return 0
    return int(args.handler(args))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
