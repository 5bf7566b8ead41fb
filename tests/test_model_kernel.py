"""The compiled model kernels of general models (ncstab.operators.model_kernel).

The kernel is what every general model's forces, tangent operator, internal
rates, gaps and loads come from; tests/test_models.py checks its K against
central differences, potentials' Hessians and tangents derived by hand for
total-form laws and loads.  Here, what those leave: the rate-form laws (K
along the law, the internal rate of seed Eq. 13), the springs of closed gaps,
the open branch of a no_tension law, and batch independence.

Central differences use h = 1e-6: truncation ~h^2 |F'''| ~ 1e-12, rounding
~1e-16 |F| / h ~ 1e-10; 1e-8 leaves margin and still fails on any wrong term
(they are O(0.1-1)).
"""

from __future__ import annotations

import numpy as np
import pytest

from ncstab.paths import SystemSpec
from ncstab.paths.api import case_batch

SIZE = 6
H = 1e-6
FD_TOL = 1e-8


def _batch(spec: SystemSpec, law: str, size: int = SIZE, **values):
    rng = np.random.default_rng(11)
    values = {"gamma": rng.uniform(0.3, 2.0, size), **values}
    return case_batch(law, spec, values, size)


def _states(batch, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = rng.uniform(-0.08, 0.08, size=(batch.size, batch.n_dof))
    internal = rng.uniform(-0.1, 0.1, size=(batch.size, batch.n_internal))
    return u, internal


def _directional(function, u: np.ndarray, direction: np.ndarray) -> np.ndarray:
    return (function(u + H * direction, H) - function(u - H * direction, -H)) / (2 * H)


RATE_CASES = {
    "ring6-cundall_strack": (SystemSpec("ring", grains=6, secondary_contacts="ignore"), "cundall_strack"),
    "axes-cundall_strack+no_tension": (SystemSpec("diamond", reduction="axes"), "cundall_strack+no_tension"),
    "axes-dem_yade": (SystemSpec("diamond", reduction="axes", secondary_contacts="ignore"), "dem_yade_avoid_ratcheting"),
}


@pytest.mark.parametrize("name", list(RATE_CASES))
def test_the_tangent_of_a_rate_law_is_the_derivative_of_the_forces_along_the_law(name):
    """K du = d/de F(u + e du, internal + e G du) with G = d(internal)/du: K is the
    derivative along the law (seed Eq. 30-34), the internal variables moving at their
    rate.  Half the normal contacts open where the law has no tension."""
    spec, law = RATE_CASES[name]
    batch = _batch(spec, law)
    u, internal = _states(batch)
    state = batch.initial_secondary_state(u)
    if batch.columns.normal_contacts:
        state = state | (np.arange(SIZE) % 2) << len(batch.definition.gaps)
    here = batch.evaluate(u, internal, state)
    assert here.internal_gradient is not None and batch.n_internal > 0
    rng = np.random.default_rng(5)
    for _ in range(3):
        direction = rng.normal(size=u.shape)
        moved = np.einsum("bkn,bn->bk", here.internal_gradient, direction)

        def forces(v, e, moved=moved):
            return batch.evaluate(v, internal + e * moved, state).forces

        expected = _directional(forces, u, direction)
        np.testing.assert_allclose(np.einsum("bij,bj->bi", here.stiffness, direction), expected, rtol=0, atol=FD_TOL)


def test_the_internal_rate_of_cundall_strack_is_gamma_l_dalpha():
    """Seed Eq. 13: dT = gamma l dalpha, so row m of d(internal)/du is gamma l_m
    dalpha_m/du, with dalpha/du by central differences of the contact angles."""
    spec, law = RATE_CASES["ring6-cundall_strack"]
    batch = _batch(spec, law)
    u, internal = _states(batch)
    here = batch.evaluate(u, internal)
    (variables, _), = here.interactions
    gamma = batch.law_values[0]["gamma"]
    for j in range(batch.n_dof):
        step = np.zeros(batch.n_dof)
        step[j] = H

        def angles(v, e):
            return batch.evaluate(v, internal).interactions[0][0][..., 1]

        dalpha = _directional(angles, u, step / H)
        expected = gamma[:, None] * variables[..., 0] * dalpha
        np.testing.assert_allclose(here.internal_gradient[:, :, j], expected, rtol=0, atol=FD_TOL)


def test_closed_gaps_carry_springs_of_energy_w_kappa_g2_over_2():
    """A ring of six grains with secondary contacts activated: closing its nine gaps
    (second and third neighbours; curved, so their Hessians count) adds the gradient of
    w kappa g^2 / 2 to F (the gaps by central differences), and K stays the derivative
    of F."""
    kappa = np.linspace(0.5, 3.0, SIZE)
    batch = _batch(SystemSpec("ring", grains=6, secondary_contacts="activate"), "mcnamara", kappa=kappa)
    u, internal = _states(batch)
    open_, closed = np.zeros(SIZE, dtype=int), np.full(SIZE, batch.gap_bits)
    springs = batch.evaluate(u, internal, closed).forces - batch.evaluate(u, internal, open_).forces
    weights = np.array([g.weight for g in batch.definition.gaps])

    def energy(v, e):
        gaps = batch.evaluate(v, internal, open_).gaps
        return 0.5 * kappa * np.sum(weights * gaps**2, axis=-1)

    stiffness = batch.evaluate(u, internal, closed).stiffness
    for j in range(batch.n_dof):
        step = np.zeros(batch.n_dof)
        step[j] = 1.0
        np.testing.assert_allclose(springs[:, j], _directional(energy, u, step), rtol=0, atol=FD_TOL)

        def forces(v, e):
            return batch.evaluate(v, internal, closed).forces

        np.testing.assert_allclose(stiffness[:, :, j], _directional(forces, u, step), rtol=0, atol=FD_TOL)
    assert np.abs(springs).max() > 1e-3  # the springs act: the check above is not 0 = 0


def test_an_open_normal_contact_carries_no_normal_force():
    """mcnamara+no_tension on the axes diamond: a contact whose bit is set follows the
    open branch (delta replaced by 0: N = 0) while its overlap is still the closed law's
    delta = 1 - l; the closed contacts keep N = 1 - l (seed Eq. 18)."""
    batch = _batch(SystemSpec("diamond", reduction="axes", secondary_contacts="ignore"), "mcnamara+no_tension")
    u, internal = _states(batch)
    state = np.arange(SIZE) % 16  # every pattern of open contacts among the four
    here = batch.evaluate(u, internal, state << len(batch.definition.gaps))
    length = here.q[..., 0]
    is_open = (state[:, None] >> np.arange(4)) & 1 == 1
    np.testing.assert_allclose(here.normal_overlap, 1 - length, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(here.normal[is_open], 0.0)
    np.testing.assert_allclose(here.normal[~is_open], (1 - length)[~is_open], rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    "spec, law",
    [(SystemSpec("ring", grains=5), "turco"), (SystemSpec("column", links=4), None), (SystemSpec("ziegler"), None)],
)
def test_a_case_evaluates_the_same_alone_and_in_a_batch(spec, law):
    """The kernel runs the cases of a batch one after the other: bit for bit the same."""
    from ncstab.paths.api import resolve_model

    model = resolve_model(spec, [law] if law else None)
    batch = case_batch(model.laws[0], model, {"gamma": np.linspace(0.5, 2.0, SIZE)} if law else {}, SIZE)
    u, internal = _states(batch)
    load = np.linspace(0.0, 1.5, SIZE)
    together = batch.evaluate(u, internal, load=load)
    for b in (0, 3, SIZE - 1):
        alone = batch.take(np.array([b])).evaluate(u[b : b + 1], internal[b : b + 1], load=load[b : b + 1])
        np.testing.assert_array_equal(alone.forces[0], together.forces[b])
        np.testing.assert_array_equal(alone.stiffness[0], together.stiffness[b])


KERNEL_SCRIPT = """
import sys
import numpy as np
from ncstab.paths import SystemSpec
from ncstab.paths.api import case_batch
from ncstab.operators import model_kernel

if sys.argv[1] == "cached":  # sympy must not print the module again
    def refuse(*args):
        raise AssertionError("the kernel was printed again")
    model_kernel.kernel_source = refuse
from ncstab.paths.api import resolve_model
model = resolve_model(SystemSpec("ziegler", load="dead"), None)
batch = case_batch(model.laws[0], model, {}, 1)
K = batch.evaluate(np.array([[0.1, 0.2]]), np.zeros((1, 0)), load=np.array([0.5])).stiffness[0]
print(repr(K.tolist()))
"""


def test_a_cached_kernel_is_imported_without_sympy_and_a_damaged_one_written_again(tmp_path):
    """A second process finds the model's module by name (kernel_source replaced by a
    function that raises); a truncated module is printed and compiled again. K of
    Ziegler's dead-load pendulum is the same every time."""
    import os
    import subprocess
    import sys

    environment = {**os.environ, "NCSTAB_CACHE_DIR": str(tmp_path)}

    def run(mode: str) -> str:
        done = subprocess.run([sys.executable, "-c", KERNEL_SCRIPT, mode], capture_output=True, text=True,
                              env=environment, timeout=300, check=False)
        assert done.returncode == 0, done.stderr[-2000:]
        return done.stdout

    first = run("new")
    (module,) = (tmp_path / "compiled").glob("model_*.py")
    assert run("cached") == first
    module.write_text(module.read_text()[:200])  # cut in the middle of the docstring
    assert run("new") == first
    assert "def evaluate_case" in module.read_text()


def _column_with(extra) -> object:
    """Hencky's column of 3 links whose load gains ``extra`` (an expression of w1)."""
    import dataclasses

    from ncstab.systems.definition import SystemDefinition
    from ncstab.systems.registry import system_definition

    shipped = system_definition("column", (("links", 3),))
    w1 = shipped.dof_symbols[0]
    load = dataclasses.replace(shipped.load, vector=tuple(v + extra(w1) for v in shipped.load.vector))
    return SystemDefinition(name="exotic", title="a column with an exotic load", dofs=shipped.dofs,
                            forces=shipped.forces, families=shipped.families, load=load, domain=shipped.domain,
                            parameters=shipped.parameters)


def test_a_function_outside_the_math_module_is_refused_naming_the_system_and_the_function():
    import sympy as sp

    from ncstab import follow

    with pytest.raises(ValueError, match=r"system 'exotic': .* besselj is not a function of Python's math module"):
        follow(_column_with(lambda w: sp.besselj(0, w)), None, [{"drive": {"P": 0.5}}])


def test_a_kernel_numba_cannot_compile_is_refused_naming_the_system(tmp_path, monkeypatch):
    """A generated module whose kernel calls an unknown function (a stand-in for any
    numba compilation error): a ValueError naming the system, not numba's traceback.
    The machine-code route is forced: a small study whose kernel is not cached runs it
    as plain Python (ncstab.paths.loop_route), where the unknown name is a NameError, not
    numba's error (run alone, the test failed so; in the full suite it passed)."""
    import sympy as sp

    from ncstab import follow
    from ncstab.operators import model_kernel
    from ncstab.paths import loop_route

    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(loop_route, "evaluates_plain", lambda *args: False)
    monkeypatch.setattr(loop_route, "runs_plain", lambda *args: False)
    real = model_kernel.kernel_source
    monkeypatch.setattr(model_kernel, "kernel_source",
                        lambda *args: real(*args).replace("        add_member(out", "        no_such_helper(out"))
    with pytest.raises(ValueError, match=r"system 'exotic': numba cannot compile its kernel"):
        follow(_column_with(lambda w: sp.erf(w) / 100), None, [{"drive": {"P": 0.5}}])


def test_a_swept_column_case_equals_the_case_followed_alone_bit_for_bit():
    """Hencky's column of 6 links, an imperfection sweep through the buckling load: each
    case's end state is the same bits swept or alone (the kernel, the cofactor tangent
    and the Newton correction run case by case; batched LAPACK calls made them differ
    by up to 7e-14 before, which a chunked or a dask run would have seen)."""
    from ncstab import follow

    others = {f"F{i}": 0.0 for i in range(2, 6)}
    programme = [
        {"hold": others, "drive": {"F1": "eps"}},
        {"hold": {**others, "F1": "current"}, "drive": {"P": 1.1 * 4 * np.sin(np.pi / 12) ** 2}},
    ]
    eps = [-1e-3, -2e-4, 0.0, 3e-4, 1e-3]
    swept = follow(SystemSpec("column", links=6), None, programme, {"eps": eps}).to_dataset().squeeze()
    for k, value in enumerate(eps):
        alone = follow(SystemSpec("column", links=6), None, programme, {"eps": value}).to_dataset().squeeze()
        case = swept.isel(eps=k)
        steps = int(alone["n_steps"].item())
        assert steps == int(case["n_steps"].item())
        for name in ("u", "F", "load"):
            np.testing.assert_array_equal(alone[name].isel(step=steps - 1).values, case[name].isel(step=steps - 1).values)


def test_numba_keeps_its_machine_code_in_the_cache_folder_not_beside_ncstab():
    """Every compiled function lives in a generated module of the cache folder
    ``compiled`` (ncstab.generated_modules): after a general model's path (its kernel,
    the cofactor tangent, the Newton correction) nothing of numba's lies beside
    ncstab's own files (a read-only installation, ``ncstab cache clear``)."""
    from pathlib import Path

    import ncstab
    from ncstab import follow

    follow(SystemSpec("column", links=4), None, [{"drive": {"P": 0.7}}])
    package = Path(ncstab.__file__).parent
    assert not [p for pattern in ("*.nbi", "*.nbc") for p in package.rglob(pattern)]
