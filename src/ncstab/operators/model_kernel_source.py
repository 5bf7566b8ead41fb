"""The text of a general model's compiled kernel, printed from its symbolic definition.

:func:`kernel_source` prints one module per system, laws and secondary-contact
mode: each member's kinematics q(u), J = dq/du and H = d2q/du2 on its own
dofs, each law's totals, conjugates Q, conjugate tangent D = dQ/dq and rate
rows C of its internal forces (both smooth branches of a no_tension law), the
load vector Q_ext(u) and its Jacobian, and the gaps (with their derivatives
where closed gaps carry springs), each after common-subexpression elimination;
then ``evaluate_case``, which runs them member by member and assembles them
(:mod:`ncstab.operators.model_assembly`) into one row of :class:`KernelLayout`,
and ``evaluate_batch``, which runs the cases of a batch one after the other.
:mod:`ncstab.operators.model_kernel` caches, imports and calls it.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from ncstab.generated_modules import compiled_functions
from ncstab.laws.catalogue import no_tension_branches
from ncstab.operators.model_assembly import ASSEMBLY
from ncstab.operators.model_kernel_layout import KERNEL_SIGNATURE, KernelLayout
from ncstab.symbolic.interaction import derive_interaction
from ncstab.symbolic.powers import LARGEST_UNROLLED, power_product
from ncstab.systems.definition import SystemDefinition

__all__ = ["KERNEL_SIGNATURE", "KernelLayout", "kernel_source"]


class _Printer(PythonCodePrinter):
    """Python printer for numba: math functions, Piecewise as conditional expressions,
    integer powers as numba's products (:func:`ncstab.symbolic.powers.power_product`)."""

    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": True, "allow_unknown_functions": False})

    def _print_Pow(self, expr: sp.Expr, rational: bool = False) -> str:  # noqa: N802 (sympy's name)
        base, exponent = expr.as_base_exp()
        if exponent.is_Integer and 0 < abs(int(exponent)) <= LARGEST_UNROLLED:
            text = self._print(base)
            return power_product(text if base.is_Symbol else f"({text})", int(exponent))
        return super()._print_Pow(expr, rational=rational)


def _clean(expression: Any) -> sp.Expr:
    # Dirac deltas (second derivatives of Macaulay brackets) vanish off the kink, as in
    # ncstab.symbolic.compile.lambdify_broadcast
    return sp.sympify(expression).replace(sp.DiracDelta, lambda *args: sp.Integer(0))


def _statements(targets: list[str], expressions: list[Any], names: dict[sp.Symbol, str], indent: str) -> list[str]:
    """``target = expression`` lines after common-subexpression elimination, the symbols
    in ``names`` printed as the local variables they name."""
    renamed = {symbol: sp.Symbol(name, real=True) for symbol, name in names.items()}
    cleaned = [_clean(e).xreplace(renamed) for e in expressions]
    replacements, reduced = sp.cse(cleaned, symbols=sp.numbered_symbols("x_"))
    printer = _Printer()
    lines = [f"{indent}{symbol} = {printer.doprint(value)}" for symbol, value in replacements]
    lines += [f"{indent}{target} = {printer.doprint(value)}" for target, value in zip(targets, reduced)]
    return lines


def _function(name: str, arguments: str, prelude: list[str], body: list[str]) -> str:
    lines = [f"@njit\ndef {name}({arguments}):", *prelude, *(body or ["    pass"])]
    if not body or not body[-1].lstrip().startswith("return"):
        lines.append("    return")
    return "\n".join(lines) + "\n"


def _own_dofs(expressions: Any, dofs: tuple[sp.Symbol, ...]) -> tuple[list[list[int]], int]:
    """Each item's own dofs (those its expressions depend on: a family member's variables,
    a gap's distance) and the largest count (at least 1)."""
    locals_ = []
    for item in expressions:
        free = set().union(*(sp.sympify(e).free_symbols for e in item))
        locals_.append([i for i, symbol in enumerate(dofs) if symbol in free])
    return locals_, max(1, max(len(x) for x in locals_))


def _internal(law: Any) -> tuple[int, ...]:
    return tuple(i for i, t in enumerate(law.force_totals) if t is None)


def _kinematics_function(f: int, family: Any, locals_: list[list[int]], width: int, names: dict, prelude: list[str],
                         dofs: tuple[sp.Symbol, ...]) -> str:
    """``kinematics_f(m, u, p, out)``: member m's q, J and H on its own dofs into
    ``out[0:k]``, ``out[k:k + k width]``, ``out[k + k width:]``."""
    k = len(family.variables[0])
    body = []
    for m, (q, own) in enumerate(zip(family.variables, locals_)):
        targets, entries = [], []
        for c, expression in enumerate(q):
            targets.append(f"out[{c}]")
            entries.append(expression)
            for a, i in enumerate(own):
                gradient = sp.diff(expression, dofs[i])
                targets.append(f"out[{k + c * width + a}]")
                entries.append(gradient)
                for b, j in enumerate(own):
                    targets.append(f"out[{k + k * width + (c * width + a) * width + b}]")
                    entries.append(sp.diff(gradient, dofs[j]))
        body.append(f"    if m == {m}:")
        body += _statements(targets, entries, names, "        ")
    return _function(f"kinematics_{f}", "m, u, p, out", prelude, body)


def _law_parameters_function(f: int, family: Any, law: Any, system_names: dict, slot: int) -> tuple[str, tuple[str, ...]]:
    """``law_parameters_f(m, p, out)``: the law's parameters of member m, fixed by the
    geometry or the case's (from ``p[slot:]``), and the names of the case's."""
    fixed = dict(family.member_parameters)
    free = tuple(spec.name for spec in law.parameters if spec.name not in fixed)
    body = []
    for m in range(family.size):
        targets = [f"out[{j}]" for j, spec in enumerate(law.parameters) if spec.name in fixed]
        entries = [fixed[spec.name][m] for spec in law.parameters if spec.name in fixed]
        if targets:
            body.append(f"    if m == {m}:")
            body += _statements(targets, entries, system_names, "        ")
    body += [f"    out[{j}] = p[{slot + free.index(spec.name)}]" for j, spec in enumerate(law.parameters) if spec.name not in fixed]
    prelude = [f"    {name} = p[{j}]" for j, name in enumerate(system_names.values())]
    return _function(f"law_parameters_{f}", "m, p, out", prelude, body), free


def _law_functions(f: int, law: Any, branches: tuple[Any, ...], internal: tuple[int, ...], no_tension: bool) -> list[str]:
    """Per smooth branch b, ``totals_f_b(q, lp, out)`` (the forces with a total form) and
    ``response_f_b(q, f, lp, out)`` (Q, D, then the rate rows of the internal forces);
    ``overlap_f(q, lp)`` for a no_tension law."""
    k, kf = len(law.variables), len(law.force_symbols)
    q_names = {s: f"q_{c}" for c, s in enumerate(law.variables)}
    f_names = {s: f"f_{c}" for c, s in enumerate(law.force_symbols)}
    lp_names = {s: f"lp_{c}" for c, s in enumerate(law.parameter_symbols)}
    prelude = [f"    q_{c} = q[{c}]" for c in range(k)] + [f"    lp_{c} = lp[{c}]" for c in range(len(law.parameters))]
    functions = []
    for b, branch in enumerate(branches):
        derivation = derive_interaction(branch)
        totals = [(i, t) for i, t in enumerate(derivation.totals) if t is not None]
        body = _statements([f"out[{i}]" for i, _ in totals], [t for _, t in totals], {**q_names, **lp_names}, "    ")
        functions.append(_function(f"totals_{f}_{b}", "q, lp, out", prelude, body))
        entries = list(branch.conjugate_expressions) + list(derivation.conjugate_tangent)
        entries += [derivation.rate_matrix[i, c] for i in internal for c in range(k)]
        body = _statements([f"out[{e}]" for e in range(len(entries))], entries, {**q_names, **f_names, **lp_names}, "    ")
        functions.append(_function(f"response_{f}_{b}", "q, f, lp, out", prelude + [f"    f_{c} = f[{c}]" for c in range(kf)], body))
    if no_tension:
        body = _statements(["delta"], [branches[0].normal_overlap], {**q_names, **lp_names}, "    ") + ["    return delta"]
        functions.append(_function(f"overlap_{f}", "q, lp", prelude, body))
    return functions


def kernel_source(definition: SystemDefinition, laws: tuple[Any, ...], activate: bool) -> str:
    """The generated module of a model (``activate``: closed gaps carry springs).

    Besides the kernel, the module holds its output layout (``LAYOUT_FIELDS``, the
    fields of :class:`KernelLayout`) and, per family, the names of the law parameters
    a case gives (``FREE_PARAMETERS``, in the order of its parameter row after the
    system's parameters; the others are fixed per member by the geometry).
    """
    dofs = definition.dof_symbols
    n = len(dofs)
    system_names = {p.symbol: f"p_{j}" for j, p in enumerate(definition.parameters)}
    prelude = [f"    u_{i} = u[{i}]" for i in range(n)] + [f"    {name} = p[{j}]" for j, name in enumerate(system_names.values())]
    geometry_names = {**{symbol: f"u_{i}" for i, symbol in enumerate(dofs)}, **system_names}
    no_tension = [bool(getattr(law, "no_tension", False)) for law in laws]
    shapes = [(f.size, len(f.variables[0]), len(law.force_symbols)) for f, law in zip(definition.families, laws)]
    layout = KernelLayout.build(
        n, sum(f.size * len(_internal(law)) for f, law in zip(definition.families, laws)), len(definition.gaps),
        sum(f.size for f, nt in zip(definition.families, no_tension) if nt), shapes,
        (n * n if definition.mass else 0, n * n if definition.damping else 0),
    )
    functions, calls, free_names, globals_ = [], [], [], []
    slot = len(definition.parameters)
    internal_at, open_bit, overlap_at = 0, len(definition.gaps), layout.overlaps
    work = 0
    for f, (family, law) in enumerate(zip(definition.families, laws)):
        locals_, width = _own_dofs(family.variables, dofs)
        k, kf = len(family.variables[0]), len(law.force_symbols)
        internal = _internal(law)
        globals_.append(f"LOCAL_{f} = np.array({[row + [0] * (width - len(row)) for row in locals_]!r}, dtype=np.int64)")
        globals_.append(f"COUNT_{f} = np.array({[len(row) for row in locals_]!r}, dtype=np.int64)")
        functions.append(_kinematics_function(f, family, locals_, width, geometry_names, prelude, dofs))
        text, free = _law_parameters_function(f, family, law, system_names, slot)
        functions.append(text)
        free_names.append(free)
        slot += len(free)
        branches = no_tension_branches(law) if no_tension[f] else (law,)
        functions += _law_functions(f, law, branches, internal, no_tension[f])
        work = max(work, k + k * width + k * width * width, len(law.parameters), kf, k + k * k + len(internal) * k)
        calls.append(_family_call(f, family, law, k, kf, width, internal, internal_at, open_bit, overlap_at, layout, no_tension[f]))
        internal_at += family.size * len(internal)
        if no_tension[f]:
            open_bit += family.size
            overlap_at += family.size
    if definition.load is not None:
        vector = sp.Matrix(definition.load.vector)
        entries = list(vector) + list(vector.jacobian(sp.Matrix(dofs)))
        body = _statements([f"out[{e}]" for e in range(len(entries))], entries, geometry_names, "    ")
        functions.append(_function("load_vector", "u, p, out", prelude, body))
        work = max(work, n + n * n)
    gap_count = len(definition.gaps)
    if gap_count:
        distances = [g.distance for g in definition.gaps]
        values = list(distances)
        if activate:  # closed gaps carry springs: their gradients and Hessians on their own dofs too
            locals_, width = _own_dofs([(g,) for g in distances], dofs)
            padded = [own + [None] * (width - len(own)) for own in locals_]
            values += [sp.diff(g, dofs[i]) if i is not None else 0 for g, own in zip(distances, padded) for i in own]
            values += [
                sp.diff(g, dofs[i], dofs[j]) if i is not None and j is not None else 0
                for g, own in zip(distances, padded) for i in own for j in own
            ]
            globals_.append(f"GAP_WEIGHTS = np.array({[float(g.weight) for g in definition.gaps]!r})")
            globals_.append(f"GAP_LOCAL = np.array({[row + [0] * (width - len(row)) for row in locals_]!r}, dtype=np.int64)")
            globals_.append(f"GAP_COUNT = np.array({[len(row) for row in locals_]!r}, dtype=np.int64)")
        body = _statements([f"out[{e}]" for e in range(len(values))], values, geometry_names, "    ")
        functions.append(_function("gap_geometry" if activate else "gap_values", "u, p, out", prelude, body))
        work = max(work, len(values))
    for name, matrix in (("mass", definition.mass), ("damping", definition.damping)):
        if matrix:
            entries = [entry for row in matrix for entry in row]
            body = _statements([f"out[{e}]" for e in range(n * n)], entries, geometry_names, "    ")
            functions.append(_function(f"{name}_values", "u, p, out", prelude, body))
            work = max(work, n * n)
    if definition.domain:
        body = _statements([f"out[{e}]" for e in range(len(definition.domain))], [c.expression for c in definition.domain],
                           geometry_names, "    ")
        functions.append(_function("domain_values", "u, p, out", prelude, body))
        work = max(work, len(definition.domain))
    globals_.append(f"LAYOUT_FIELDS = {dataclasses.asdict(layout)!r}")
    globals_.append(f"FREE_PARAMETERS = {tuple(free_names)!r}")
    return _module_text(definition, layout, globals_, functions, calls, slot, work, activate)


def _family_call(f, family, law, k, kf, width, internal, internal_at, open_bit, overlap_at, layout, no_tension) -> str:
    """The statements of ``evaluate_case`` for family f: every member in turn."""
    lines = [
        f"    # family {f}: {family.name!r} ({family.size} {family.kind}s)",
        f"    for m in range({family.size}):",
        f"        kinematics_{f}(m, u, p, kin)",
        f"        law_parameters_{f}(m, p, lp)",
    ]
    if no_tension:
        lines += [
            f"        if (state >> ({open_bit} + m)) & 1:  # the normal contact is open",
            f"            totals_{f}_1(kin, lp, fv)",
        ]
        for c, i in enumerate(internal):
            lines.append(f"            fv[{i}] = internal[{internal_at} + m * {len(internal)} + {c}]")
        lines.append(f"            response_{f}_1(kin, fv, lp, response)")
        lines.append("        else:")
        pad = "            "
    else:
        pad = "        "
    lines.append(f"{pad}totals_{f}_0(kin, lp, fv)")
    for c, i in enumerate(internal):
        lines.append(f"{pad}fv[{i}] = internal[{internal_at} + m * {len(internal)} + {c}]")
    lines.append(f"{pad}response_{f}_0(kin, fv, lp, response)")
    if no_tension:
        lines.append(f"        out[{overlap_at} + m] = overlap_{f}(kin, lp)")
    lines.append(
        f"        add_member(out, {layout.forces}, {layout.stiffness}, {layout.n}, {float(family.weight)!r}, "
        f"LOCAL_{f}[m], COUNT_{f}[m], {k}, {width}, kin, response)"
    )
    for c, _ in enumerate(internal):
        row = f"({internal_at} + m * {len(internal)} + {c}) * {layout.n}"
        lines.append(
            f"        add_rate_row(out, {layout.gradient} + {row}, LOCAL_{f}[m], COUNT_{f}[m], {k}, {width}, kin, "
            f"response[{k + k * k}:], {c})"
        )
    q_at, f_at = layout.interactions[f]
    lines += [
        f"        for c in range({k}):",
        f"            out[{q_at} + m * {k} + c] = kin[c]",
        f"        for c in range({kf}):",
        f"            out[{f_at} + m * {kf} + c] = fv[c]",
    ]
    return "\n".join(lines)


def _module_text(definition, layout: KernelLayout, globals_, functions, calls, rows: int, work: int, activate: bool) -> str:
    n = layout.n
    load = [
        "    load_vector(u, p, kin)",
        f"    for i in range({n}):",
        f"        out[{layout.forces} + i] -= load * kin[i]",
        f"        out[{layout.load} + i] = -kin[i]",
        f"        for j in range({n}):",
        f"            out[{layout.stiffness} + i * {n} + j] -= load * kin[{n} + i * {n} + j]",
    ] if definition.load is not None else []
    if not layout.n_gaps:
        gaps = []
    elif activate:  # secondary contacts activated: closed gaps carry springs
        gaps = [
            "    gap_geometry(u, p, kin)",
            (f"    add_gap_springs(out, {layout.forces}, {layout.stiffness}, {n}, {layout.gaps}, "
             f"GAP_LOCAL, GAP_COUNT, state, p[{rows}], GAP_WEIGHTS, kin)"),
        ]
    else:
        gaps = ["    gap_values(u, p, kin)", f"    for g in range({layout.n_gaps}):", f"        out[{layout.gaps} + g] = kin[g]"]
    body = "\n".join(calls)
    domain = _inertia_lines(definition, layout) + _domain_lines(definition, layout)
    return f'''"""The compiled kernel of the model {definition.name!r}, generated by ncstab.operators.model_kernel_source: do not edit."""
import math

import numba
import numpy as np

njit = numba.njit(cache=True, error_model="numpy")


{compiled_functions(*ASSEMBLY)}

#: the case's parameter row: the system's parameters, each family's free law parameters,
#: then kappa
ROW = {rows + 1}
#: scratch per call (member kinematics, law parameters, forces, response)
WORK = {work}
SIZE = {layout.size}
{chr(10).join(globals_)}


{(chr(10) + chr(10)).join(functions)}

@njit
def evaluate_case(u, internal, load, state, p, out, scratch):
    """One case: F, K, dF/dP, d(internal)/du, gaps, overlaps and interactions into out."""
    for e in range({layout.interactions[0][0] if layout.interactions else layout.size}):
        out[e] = 0.0
    kin = scratch[0:WORK]
    lp = scratch[WORK:2 * WORK]
    fv = scratch[2 * WORK:3 * WORK]
    response = scratch[3 * WORK:4 * WORK]
{body}
{chr(10).join(load)}
{chr(10).join(gaps)}
{chr(10).join(domain)}


def case(u, internal, load, state, p, out, scratch):
    """evaluate_case on pointers: compiled as a C callback of KERNEL_SIGNATURE on demand
    (ModelKernel.callback), the compiled stage loop's ``law``."""
    evaluate_case(numba.carray(u, ({n},)), numba.carray(internal, ({max(layout.n_internal, 1)},)), load, state,
                  numba.carray(p, (ROW,)), numba.carray(out, (SIZE,)), numba.carray(scratch, (4 * WORK,)))


@njit
def evaluate_batch(u, internal, load, state, p, out):
    """Every case of a batch, one after the other."""
    scratch = np.empty(4 * WORK)
    for b in range(u.shape[0]):
        evaluate_case(u[b], internal[b], load[b], state[b], p[b], out[b], scratch)
'''


def _inertia_lines(definition: SystemDefinition, layout: KernelLayout) -> list[str]:
    """The lines of ``evaluate_case`` that write M(u) and C(u) (:class:`KernelLayout`)."""
    lines = []
    for name, at, width in (("mass", layout.mass, layout.inertia[0]), ("damping", layout.damping, layout.inertia[1])):
        if width:
            lines += [f"    {name}_values(u, p, kin)", f"    for e in range({width}):", f"        out[{at} + e] = kin[e]"]
    return lines


def _domain_lines(definition: SystemDefinition, layout: KernelLayout) -> list[str]:
    """The lines of ``evaluate_case`` that write the domain code (:class:`KernelLayout`)."""
    checks = []
    for f, family in enumerate(definition.families):
        if family.kind == "contact":
            q_at, k = layout.interactions[f][0], layout.family_shapes[f][1]
            for m in range(family.size):
                checks += [f"out[{q_at + m * k}] > 0", f"abs(out[{q_at + m * k + 1}]) < 0.5 * math.pi"]
    if definition.domain:
        checks += [f"kin[{e}] > 0" for e in range(len(definition.domain))]
    lines = [f"    out[{layout.domain}] = -1.0"]
    if definition.domain:
        lines.append("    domain_values(u, p, kin)")
    for code, check in reversed(list(enumerate(checks))):  # the first violated wins
        lines.append(f"    if not ({check}):")
        lines.append(f"        out[{layout.domain}] = {float(code + 1)!r}")
    return lines
