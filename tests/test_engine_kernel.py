"""The engine's fast paths give the quantities of the general code (issue 6, "Scale").

- The fused state kernel (:func:`ncstab.operators.tangent.compile_state_kernel`,
  used by :meth:`ncstab.paths.model.CaseBatch.evaluate`) against the general
  assembly (:func:`tangent_operator_at_contact_state`, the system's
  ``generalized_forces`` and the law's rate matrix), for every law of the
  catalogue, both smooth branches of a no_tension law and the secondary springs.
- A case's batched evaluation (stage entry, branch switching) is bitwise the same
  whatever batch it is in (no reduction across cases).
- The padded recorder keeps each case's states in order.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ncstab.laws.catalogue import no_tension_branches
from ncstab.laws.registry import law_definition, make_law
from ncstab.operators.tangent import compile_state_kernel, tangent_operator_at_contact_state
from ncstab.paths import SystemSpec
from ncstab.paths.api import case_batch
from ncstab.paths.recorder import Recorder as _Recorder
from ncstab.paths.rhs import StateLayout as _Layout
from ncstab.paths.rhs import evaluate_at as _evaluate_at
from ncstab.paths.model import NORMAL_OPEN
from ncstab.paths.tangent_field import StageArrays
from ncstab.symbolic.compile import compile_law
from ncstab.systems.diamond import DiamondChain

LAWS = ["cundall_strack", "weakly_hypoelastic", "mcnamara", "turco"]
SIZE = 64


def _states(size: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = rng.uniform(-0.08, 0.08, size=(size, 2))
    tangential = rng.uniform(-0.1, 0.1, size=size)
    gamma = rng.uniform(0.1, 3.0, size=size)
    return u, tangential, gamma


def _definitions(name: str):
    definition = law_definition(name)
    return no_tension_branches(definition) if definition.no_tension else (definition,)


@pytest.mark.parametrize("name", LAWS + ["mcnamara+no_tension", "cundall_strack+no_tension"])
def test_state_kernel_matches_the_general_assembly(name):
    u, t_internal, gamma = _states(SIZE)
    alpha0 = np.full(SIZE, 0.7)
    system = DiamondChain(alpha0=alpha0)
    q = system.contact_variables(u)
    length, alpha = q[:, 0, 0], q[:, 0, 1]
    for definition in _definitions(name):
        parameters = {"gamma": gamma}
        if "alpha0" in definition.parameter_names:
            parameters["alpha0"] = alpha0
        law = make_law(definition, **parameters)
        compiled = compile_law(definition)
        normal = compiled.normal_force(law, length, alpha)
        tangential = compiled.tangential_force(law, length, alpha) if definition.has_total_form else t_internal
        stiffness = tangent_operator_at_contact_state(system, law, q, normal[:, None], tangential[:, None])
        forces = system.generalized_forces(q, normal[:, None], tangential[:, None])
        kernel = compile_state_kernel(DiamondChain, definition)
        out = [np.broadcast_to(np.asarray(v, dtype=float), (SIZE,)) for v in kernel(
            length, alpha, np.cos(alpha), np.sin(alpha), t_internal, *law.parameter_values()
        )]
        np.testing.assert_allclose(out[0], normal, rtol=0, atol=1e-15)
        np.testing.assert_allclose(out[1], tangential, rtol=0, atol=1e-15)
        np.testing.assert_allclose(np.stack(out[2:4], -1), forces, rtol=0, atol=1e-14)
        np.testing.assert_allclose(np.stack(out[4:8], -1).reshape(SIZE, 2, 2), stiffness, rtol=0, atol=1e-13)
        if not definition.has_total_form:
            # dT = C_Tl dl + C_Ta dalpha along any du (seed Eq. 13).
            rate = compiled.rate_matrix(law, length, alpha, normal, tangential)
            jacobian = system.contact_jacobian(q)[:, 0]
            expected = rate[:, 1, 0, None] * jacobian[:, 0] + rate[:, 1, 1, None] * jacobian[:, 1]
            np.testing.assert_allclose(np.stack(out[8:10], -1), expected, rtol=0, atol=1e-14)


@pytest.mark.parametrize("name", ["mcnamara", "cundall_strack", "turco+no_tension"])
@pytest.mark.parametrize("secondary", ["ignore", "activate"])
def test_fused_evaluation_matches_the_general_evaluation(name, secondary, monkeypatch):
    u, t_internal, gamma = _states(SIZE, seed=1)
    values = {"gamma": gamma, "alpha0": np.full(SIZE, math.pi / 4)}
    batch = case_batch(name, SystemSpec(secondary_contacts=secondary), values, SIZE)
    internal = t_internal[:, None] if batch.n_internal else np.zeros((SIZE, 0))
    state = batch.initial_secondary_state(u)
    if name.endswith("no_tension"):
        state = state | (NORMAL_OPEN * (np.arange(SIZE) % 2))  # both branches in one batch
    fused = batch.evaluate(u, internal, state)
    monkeypatch.setattr(type(batch), "_kernels", property(lambda self: None))
    general = batch.evaluate(u, internal, state)
    for field in ("q", "normal", "tangential", "displacements", "forces", "stiffness", "gaps", "normal_overlap"):
        np.testing.assert_allclose(getattr(fused, field), getattr(general, field), rtol=0, atol=1e-13, err_msg=field)


@pytest.mark.parametrize("name", ["mcnamara", "cundall_strack"])
def test_the_batched_evaluation_of_a_case_does_not_depend_on_its_batch(name):
    """What stage entry and branch switching read (forces, K, the control matrix's
    blocks, the gaps) is the same bits for a case alone, in a slice or reversed."""
    size = 257
    u, t_internal, gamma = _states(size, seed=3)
    values = {"gamma": gamma, "alpha0": np.full(size, math.pi / 4)}
    batch = case_batch(name, SystemSpec(secondary_contacts="ignore"), values, size)
    layout = _Layout(2, batch.n_internal)
    y = np.zeros((size, layout.size))
    y[:, layout.v] = u
    y[:, layout.lam] = u[:, 0]
    if batch.n_internal:
        y[:, layout.internal] = t_internal[:, None]
    stage = StageArrays.empty(size, 2)

    def read(sub, st, states):
        evaluation = _evaluate_at(sub, st, states, layout)
        return np.column_stack([
            evaluation.forces, evaluation.stiffness.reshape(-1, 4), evaluation.dF_dv.reshape(-1, 4), evaluation.gaps,
        ])

    whole = read(batch, stage, y)
    for index in (np.array([5]), np.arange(3, 200, 7), np.arange(size)[::-1]):
        np.testing.assert_array_equal(read(batch.take(index), stage.take(index), y[index]), whole[index])


def test_recorder_keeps_each_case_in_order_across_growth():
    recorder = _Recorder(3)
    expected: dict[int, list[float]] = {0: [], 1: [], 2: []}
    for step in range(40):  # beyond the initial capacity of 16
        cases = np.array([0, 2]) if step % 3 else np.array([1, 0, 2])
        values = step + cases / 10
        for case, value in zip(cases, values):
            expected[int(case)].append(value)
        recorder.add(cases, s=values, stage=np.full(cases.size, step), K=np.ones((cases.size, 2, 2)) * values[:, None, None])
    steps, counts = recorder.assemble()
    assert counts.tolist() == [len(expected[c]) for c in range(3)]
    assert steps["s"].shape == (3, max(counts))
    for case in range(3):
        n = counts[case]
        assert steps["s"][case, :n].tolist() == expected[case]
        assert np.isnan(steps["s"][case, n:]).all() and (steps["stage"][case, n:] == -1).all()
        np.testing.assert_array_equal(steps["K"][case, :n, 1, 0], expected[case])


def test_recorder_doubles_for_the_next_step_and_grows_less_to_an_estimate():
    """Recorder.reserve: room for the next step doubles the capacity (8 -> 16 for 9 states);
    room for an estimate (growth 1.25) grows to the estimate, or by a quarter where it is
    short (8 -> 10 for 9); the states kept, the padding NaN and -1."""
    from ncstab.paths.recorder import Recorder

    for growth, needed, expected in ((2.0, 9, 16), (1.25, 9, 10), (1.25, 30, 30), (2.0, 30, 30)):
        recorder = Recorder(2)
        recorder.add(np.array([0, 1]), s=np.array([1.0, 2.0]), stage=np.array([3, 4]))
        assert recorder.capacity == 8
        recorder.reserve(needed, growth=growth)
        assert recorder.capacity == expected
        steps, counts = recorder.assemble()
        assert counts.tolist() == [1, 1] and steps["s"][:, 0].tolist() == [1.0, 2.0]
        assert np.isnan(recorder.arrays["s"][:, 1:]).all() and (recorder.arrays["stage"][:, 1:] == -1).all()


# --- the state kernels kept on disk (ncstab.operators.kernel_cache) ---------------------------


@pytest.mark.parametrize("name", LAWS + ["turco+no_tension", "dem_yade_avoid_ratcheting"])
def test_a_cached_state_kernel_is_the_derived_one_and_needs_no_derivation(name, tmp_path, monkeypatch):
    """A fresh process (the in-process cache bypassed) builds each kernel from its cached
    text: the same source, bit-identical outputs, and no sympy derivation on the way."""
    import inspect

    from ncstab.operators import kernel_cache, tangent

    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path))
    u, t_internal, gamma = _states(SIZE, seed=3)
    alpha0 = np.full(SIZE, 0.7)
    q = DiamondChain(alpha0=alpha0).contact_variables(u)
    length, alpha = q[:, 0, 0], q[:, 0, 1]
    for definition in _definitions(name):
        derived = tangent._derive_state_kernel(DiamondChain, definition)
        first = tangent.compile_state_kernel.__wrapped__(DiamondChain, definition)  # a miss: derived, kept
        key = kernel_cache.kernel_key(DiamondChain, definition)
        assert (tmp_path / kernel_cache.CACHE_KIND / f"{key}.json").is_file()

        def no_derivation(*args):
            raise AssertionError("a cached kernel must not be derived again")

        monkeypatch.setattr(tangent, "_derive_state_kernel", no_derivation)
        second = tangent.compile_state_kernel.__wrapped__(DiamondChain, definition)  # a hit
        monkeypatch.undo()
        monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path))
        assert inspect.getsource(second) == inspect.getsource(first) == inspect.getsource(derived)
        values = {"gamma": gamma, "alpha0": alpha0}
        arguments = (length, alpha, np.cos(alpha), np.sin(alpha), t_internal,
                     *(values.get(p, np.full(SIZE, 0.3)) for p in definition.parameter_names))
        expected = [np.asarray(v, dtype=float) for v in derived(*arguments)]
        for kernel in (first, second):
            got = [np.asarray(v, dtype=float) for v in kernel(*arguments)]
            assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(got, expected))
        # Every global name the text reads resolves to what sympy's lambdify gives it.
        names = kernel_cache.used_names(derived.__code__)
        resolved = kernel_cache.numpy_namespace(names)
        for name_read in names:
            if name_read in derived.__globals__:
                assert resolved.get(name_read) is derived.__globals__[name_read], name_read


def test_the_kernel_namespace_is_the_one_sympy_gives_a_numpy_lambdified_function():
    """Every one of the ~500 names sympy's lambdify(modules="numpy") puts in a function's
    globals resolves to the same object (the same value for the constant I), so a kernel
    built from its cached text reads what the freshly lambdified one reads."""
    import sympy as sp

    from ncstab.operators import kernel_cache

    probe = sp.lambdify([], 0, modules="numpy")
    expected = {name: value for name, value in probe.__globals__.items()
                if not name.startswith("__") and name != probe.__name__}
    resolved = kernel_cache.numpy_namespace(set(expected))
    assert len(expected) > 400
    for name, value in expected.items():
        same = resolved.get(name) is value or (isinstance(value, complex) and resolved.get(name) == value)
        assert same, name


def test_a_changed_law_or_generator_names_another_kernel_entry(monkeypatch):
    """The key covers the definition and the generating code: a changed parameter value
    in a formula, or an edited generator module, never reads the old entry."""
    from ncstab.operators import kernel_cache

    base = law_definition("mcnamara")
    other = law_definition("turco")
    assert kernel_cache.kernel_key(DiamondChain, base) == kernel_cache.kernel_key(DiamondChain, base)
    assert kernel_cache.kernel_key(DiamondChain, base) != kernel_cache.kernel_key(DiamondChain, other)
    before = kernel_cache.kernel_key(DiamondChain, base)
    monkeypatch.setattr(kernel_cache, "GENERATING_MODULES", (*kernel_cache.GENERATING_MODULES, "ncstab.cache"))
    assert kernel_cache.kernel_key(DiamondChain, base) != before


@pytest.mark.parametrize("damage", ["{not json", "source that is no function", "def broken(:\n"])
def test_a_corrupt_kernel_entry_is_derived_again(damage, tmp_path, monkeypatch):
    """Unreadable JSON, or a readable entry whose source defines no function or does
    not compile: the kernel is derived again and the entry rewritten."""
    import json

    from ncstab.cache import CACHE_FORMAT
    from ncstab.operators import kernel_cache, tangent

    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path))
    definition = law_definition("mcnamara")
    key = kernel_cache.kernel_key(DiamondChain, definition)
    entry = tmp_path / kernel_cache.CACHE_KIND / f"{key}.json"
    entry.parent.mkdir(parents=True)
    if damage.startswith("{"):
        entry.write_text(damage, encoding="utf-8")
    else:
        entry.write_text(json.dumps({"format": CACHE_FORMAT, "key": key, "value": {"source": damage}}), "utf-8")
    kernel = tangent.compile_state_kernel.__wrapped__(DiamondChain, definition)
    assert kernel(1.0, 0.5, math.cos(0.5), math.sin(0.5), 0.0, 1.0, 0.5)[0] == 0.0
    assert "_lambdifygenerated" in json.loads(entry.read_text(encoding="utf-8"))["value"]["source"]
