"""The compiled loop's model functions, dispatched by the model's record, and where its machine code is kept.

:mod:`ncstab.paths.loop_dispatch` gives the shared modules of the loop the
functions of the model whose record (``DiamondModel``, ``GeneralModel``) comes
first; :mod:`ncstab.engine_cache` keeps the loop's machine code in a folder
named by a hash of every module it is built from.  Exact properties: which
function answers, the folder's name, and that any change to the engine's text
is a new name.
"""

from __future__ import annotations

import shutil
import types

import numba
import numpy as np
import pytest

from ncstab import engine_cache
from ncstab.paths import loop_diamond, loop_dispatch, loop_general_output
from ncstab.paths.loop_general import GEO
from ncstab.paths.loop_records import DiamondModel, EventColumns, GeneralModel


def test_every_model_defines_every_function_the_loop_asks_for_with_the_same_parameters():
    import inspect

    from ncstab.paths.loop_records import MODEL_FUNCTIONS

    assert [name for name in loop_dispatch.__all__ if not name.startswith("MODEL")] == list(MODEL_FUNCTIONS)
    assert loop_diamond.__all__ == loop_general_output.__all__ == list(MODEL_FUNCTIONS)
    for name in loop_dispatch.MODEL_FUNCTIONS:
        diamond, general = (getattr(module, name).py_func for module in (loop_diamond, loop_general_output))
        assert inspect.signature(diamond) == inspect.signature(general), name
        assert next(iter(inspect.signature(diamond).parameters)) == "kind", name


@pytest.mark.parametrize("rate_form, size", [(False, 4), (True, 5)])
def test_a_diamond_record_gets_the_diamond_s_function_in_plain_python_and_compiled(rate_form, size):
    # y = (v0, v1, lambda, [T], W): the diamond's state size says its form, whatever y's length
    kind, y = DiamondModel(rate_form), np.zeros(9)
    assert loop_dispatch.state_size(kind, y) == size

    @numba.njit
    def compiled(kind, y):
        return loop_dispatch.state_size(kind, y)

    assert compiled(kind, y) == size


def test_a_general_record_gets_the_general_model_s_function_in_plain_python_and_compiled():
    # a general model's state size is its array's length; its event columns are its geo row's
    kind, y = GeneralModel(rate_form=False), np.zeros(9)
    geo = np.zeros(len(GEO), dtype=np.int64)
    for slot, value in {"columns": 12, "target": 11, "cycle": 10, "turning": 6, "bifurcation": 8, "limit": 0,
                        "control": 2}.items():
        geo[GEO[slot]] = value

    @numba.njit
    def compiled(kind, y, geo):
        return loop_dispatch.state_size(kind, y), loop_dispatch.event_columns(kind, geo)

    assert loop_dispatch.state_size(kind, y) == 9
    expected = EventColumns(count=12, target=11, cycle=10, turning=6, bifurcation=8, limit=0, control=2)
    assert loop_dispatch.event_columns(kind, geo) == expected
    size, columns = compiled(kind, y, geo)
    assert size == 9 and tuple(columns) == tuple(expected)


def test_models_whose_functions_take_different_parameters_are_refused(monkeypatch):
    first = types.ModuleType("first")
    first.answer = lambda kind, y: 1
    second = types.ModuleType("second")
    second.answer = lambda kind, z: 2
    monkeypatch.setattr(loop_dispatch, "MODELS", {DiamondModel: first, GeneralModel: second})
    with pytest.raises(TypeError, match=r"second\.answer\(kind, z\): the models' answer must take the same parameters"):
        loop_dispatch._dispatched("answer")


def test_the_loop_s_machine_code_is_kept_in_a_folder_named_by_the_engine_s_text():
    from ncstab.cache import cache_directory

    folder = engine_cache.engine_folder()
    assert folder == cache_directory("compiled") / f"engine_{engine_cache.engine_digest()}"
    from ncstab.paths.loop_cases import run_cases

    assert run_cases._cache._cache_path == str(folder)  # numba's cache of the entry point


def test_a_change_to_any_module_of_the_engine_is_a_new_folder(tmp_path, monkeypatch):
    root = engine_cache._SOURCE_ROOT
    for name in engine_cache.ENGINE_MODULES:
        relative = name.replace(".", "/") + ".py"
        (tmp_path / relative).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(root / relative, tmp_path / relative)
    monkeypatch.setattr(engine_cache, "_SOURCE_ROOT", tmp_path)
    engine_cache.engine_digest.cache_clear()
    try:
        assert engine_cache.engine_digest() == _digest_with(root)  # the same text, the same name
        before = engine_cache.engine_digest()
        for name in ("ncstab.paths.loop_general_output", "ncstab.paths.events"):  # a model's module, a constant's
            engine_cache.engine_digest.cache_clear()
            path = tmp_path / (name.replace(".", "/") + ".py")
            path.write_text(path.read_text() + "\n# changed\n")
            after = engine_cache.engine_digest()
            assert after != before
            before = after
    finally:
        engine_cache.engine_digest.cache_clear()


def _digest_with(root):
    saved = engine_cache._SOURCE_ROOT
    engine_cache._SOURCE_ROOT = root
    engine_cache.engine_digest.cache_clear()
    try:
        return engine_cache.engine_digest()
    finally:
        engine_cache._SOURCE_ROOT = saved
        engine_cache.engine_digest.cache_clear()


def test_the_route_asks_whether_the_index_holds_code_for_this_kind_of_model(tmp_path):
    # one index per entry point holds both kinds of model: the diamond's code cached does
    # not make a general model's batch wait for the compiler (it runs as plain Python)
    from ncstab.paths.loop_route import machine_code_cached, runs_plain

    index = tmp_path / "loop_cases.run_cases-66.py311.nbi"
    index.write_bytes(b"")
    diamond_signature = ("array(int64, 1d, C)", "ModelRows(DiamondModel(bool x 1), ...)")
    cache_file = types.SimpleNamespace(_index_path=str(index), _load_index=lambda: {(diamond_signature, "cpu"): "1"})
    entry = types.SimpleNamespace(_cache=types.SimpleNamespace(_cache_file=cache_file))
    assert machine_code_cached(entry) and machine_code_cached(entry, DiamondModel(rate_form=True))
    assert not machine_code_cached(entry, GeneralModel(rate_form=False))
    assert not runs_plain("auto", 1, 14, entry, DiamondModel(rate_form=False))  # cached: machine code
    assert runs_plain("auto", 1, 14, entry, GeneralModel(rate_form=False))  # not cached, small: plain
    index.unlink()
    assert not machine_code_cached(entry, DiamondModel(rate_form=True))  # no index at all
