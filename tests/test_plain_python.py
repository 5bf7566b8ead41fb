"""The compiled loop's text run as plain Python (ncstab.plain_python, ncstab.paths.loop_route).

The plain route executes the same generated text as numba compiles, so it must give the
same numbers bit for bit: the golden archives are checked on both routes in
tests/test_golden.py (``BACKENDS``), and the shipped studies below.  Here: the pieces that
make the bits the same (integer powers in numba's order, the math module's values where
CPython raises), the route's choice, and the fall-back to the machine code.
"""

from __future__ import annotations

import math
import types

import numba
import numpy as np
import pytest
import xarray as xr

from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.paths.loop_route import PYTHON_WORK, evaluates_plain, machine_code_cached, runs_plain
from ncstab.plain_python import _MATH, _carray
from ncstab.symbolic.powers import power_product

#: Arguments spread over four decades: enough that x**k and numba's product differ for
#: thousands of them (counted below), so an equality is not a coincidence.
ARGUMENTS = np.random.default_rng(7).uniform(0.1, 10.0, 20_000)


@pytest.mark.parametrize("exponent", [2, 3, 4, 5, 7, 12, -1, -2, -3, -5])
def test_an_integer_power_printed_as_products_is_numba_s_power_bit_for_bit(exponent: int) -> None:
    namespace: dict = {}
    exec(f"def printed(x):\n    return {power_product('x', exponent)}\n", namespace)  # noqa: S102 - our own text
    printed = namespace["printed"]
    compiled = numba.njit(eval(f"lambda x: x ** {exponent}"))  # noqa: S307 - a literal of this test
    plain = np.array([printed(float(x)) for x in ARGUMENTS])
    machine = np.array([compiled(float(x)) for x in ARGUMENTS])
    np.testing.assert_array_equal(plain, machine)
    if abs(exponent) > 2:  # the C library's pow is not numba's product: the printing matters
        assert np.count_nonzero(ARGUMENTS**exponent != machine) > 100


def test_a_power_beyond_the_unrolled_range_is_refused() -> None:
    with pytest.raises(ValueError, match="exponent 0"):
        power_product("x", 0)
    with pytest.raises(ValueError, match="exponent 65"):
        power_product("x", 65)


def test_the_math_stand_in_gives_numpy_s_values_where_cpython_raises() -> None:
    assert math.isnan(_MATH.sqrt(-1.0))
    assert _MATH.log(0.0) == -math.inf
    assert _MATH.exp(1000.0) == math.inf
    assert math.isnan(_MATH.acos(2.0))
    # and math's own value everywhere else (the C library's, as numba calls it)
    for x in ARGUMENTS[:2000]:
        assert _MATH.atan2(x, 3.0) == math.atan2(x, 3.0)
        assert _MATH.sqrt(x) == math.sqrt(x)


def test_carray_reads_an_array_s_pointer_as_a_view_of_it() -> None:
    values = np.arange(6.0)
    view = _carray(values[2:].ctypes, (3,))
    np.testing.assert_array_equal(view, [2.0, 3.0, 4.0])
    view[0] = -1.0
    assert values[2] == -1.0


def _entry(tmp_path, cached: bool) -> types.SimpleNamespace:
    """A stand-in for a dispatcher whose numba cache index exists or not."""
    index = tmp_path / "loop.run_cases-1.py311.nbi"
    if cached:
        index.write_bytes(b"")
    return types.SimpleNamespace(_cache=types.SimpleNamespace(_cache_file=types.SimpleNamespace(_index_path=str(index))))


def test_the_route_follows_the_backend_the_cache_and_the_work(tmp_path) -> None:
    (tmp_path / "cold").mkdir()
    cold = _entry(tmp_path / "cold", False)
    (tmp_path / "warm").mkdir()
    warm = _entry(tmp_path / "warm", True)
    assert machine_code_cached(warm) and not machine_code_cached(cold)
    assert not machine_code_cached(object())  # not a numba dispatcher: nothing cached
    assert runs_plain("python", 10**6, 100, warm)
    assert not runs_plain("compiled", 1, 1, cold)
    assert not runs_plain("auto", 1, 4, warm)  # cached machine code always serves
    assert runs_plain("auto", 1, 14, cold)  # a ring of six grains, cold: plain
    assert runs_plain("auto", 441, 4, cold)  # 441 cases of Ziegler's pendulum: 15 s plain
    assert not runs_plain("auto", PYTHON_WORK, 2, cold)  # a sweep: compiled
    assert evaluates_plain(100, cold) and not evaluates_plain(100, warm)


PROGRAMME = [{"hold": {"F2": 0.0, "F3": 0.0, "F5": 0.0, "F6": 0.0}, "drive": {"D1": 0.05, "D4": 0.05}}]


def _ring(backend: str) -> xr.Dataset:
    path = follow(SystemSpec("ring", grains=6, secondary_contacts="ignore"), ["cundall_strack", "mcnamara"], PROGRAMME,
                  {"gamma": 0.5}, PathOptions(backend=backend))
    dataset = path.to_dataset()
    dataset.attrs.pop("created", None)
    return dataset


def test_a_ring_gives_the_same_archive_bit_for_bit_on_both_routes() -> None:
    # a general model with a rate law and a total law: the model kernel's powers
    # (x**-2 of the branch lengths) and the loop's tangent, Newton and DOP853 in both
    xr.testing.assert_identical(_ring("python"), _ring("compiled"))


def test_a_plain_run_that_raises_runs_again_compiled(monkeypatch) -> None:
    import tqdm.auto

    from ncstab.paths import stepper

    calls = {"plain": 0}
    run = stepper.BatchStepper.run

    def failing(self):
        if self.compiled.plain:
            calls["plain"] += 1
            self.progress(1)  # a case that ended before the failure
            raise ZeroDivisionError("float division by zero")
        return run(self)

    told: list[int] = []

    class Bar:
        def __init__(self, *args, **kwargs) -> None:
            pass

        def update(self, count: int) -> None:
            told.append(count)

        def close(self) -> None:
            pass

    monkeypatch.setattr(stepper.BatchStepper, "run", failing)
    monkeypatch.setattr(tqdm.auto, "tqdm", Bar)
    path = follow(SystemSpec(secondary_contacts="ignore"), "mcnamara", [{"hold": {"F2": 0.0}, "drive": {"D1": 0.1}}],
                  {"gamma": [1.0, 2.0]}, PathOptions(backend="python"), progress=True)
    assert calls["plain"] == 1
    assert sorted(np.asarray(path.status).ravel().tolist()) == ["finished", "finished"]
    assert sum(told) == 2  # each case told once, across both runs


def test_a_chunk_of_a_large_study_weighs_the_study_s_work_not_its_own(monkeypatch) -> None:
    """``--chunk-cases 1`` on a sweep must not run every chunk as plain Python: the route
    counts the study's cases (``study_cases``), as the chunked runner passes them."""
    from ncstab.paths import loop_route
    from ncstab.paths.api import case_batch, resolve_model
    from ncstab.paths.engine_choice import choose_engine
    from ncstab.paths.programme import parse_programme

    monkeypatch.setattr(loop_route, "machine_code_cached", lambda entry, kind=None: False)  # a new machine
    model = resolve_model(SystemSpec(secondary_contacts="ignore"), ["mcnamara"])
    batch = case_batch(model.laws[0], model, {"gamma": np.array([1.0])}, 1)
    programme = parse_programme([{"hold": {"F2": 0.0}, "drive": {"D1": 0.1}}])
    alone, _ = choose_engine(batch, programme, PathOptions())
    chunk, _ = choose_engine(batch, programme, PathOptions(), study_cases=4096)
    assert alone.plain and not chunk.plain
