"""The model functions the shared parts of the compiled stage loop call, dispatched by the model's record.

The shared parts of the loop (:mod:`ncstab.paths.loop_steps`,
:mod:`~ncstab.paths.loop_step_limits`, :mod:`~ncstab.paths.loop_start`,
:mod:`~ncstab.paths.loop_cases`) step any model: whatever depends on the model
they ask of it by calling one of the functions below, whose first argument
``kind`` is the model's record (:class:`ncstab.paths.loop_records.DiamondModel`
or :class:`~ncstab.paths.loop_records.GeneralModel`).  Each function is that of
the model's module (:data:`MODELS`: :mod:`ncstab.paths.loop_diamond`,
:mod:`ncstab.paths.loop_general_output`), which defines every name of
:data:`MODEL_FUNCTIONS` with the same parameters:

* compiled, numba picks it by the record's type when it compiles the loop for
  that model (``numba.extending.overload``): one compilation per kind of model,
  and nothing is looked up while stepping; a function the model inlines
  (``inline="always"``: those of every DOP853 stage) is inlined here too;
* run as plain Python (:mod:`ncstab.plain_python`), it is looked up by the
  record's type; called from Python, it runs the model's module as plain Python
  (the model's compiled functions have no Python wrapper: :mod:`ncstab.jit`).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from numba import extending

from ncstab.paths import loop_diamond, loop_general_output
from ncstab.paths.loop_records import MODEL_FUNCTIONS, DiamondModel, GeneralModel
from ncstab.plain_python import plain_import

__all__ = [  # noqa: RUF022 (MODEL_FUNCTIONS, in its order)
    "MODELS", "MODEL_FUNCTIONS", "state_size", "ev_size", "aux_size", "motion_size", "event_columns", "switch_bit",
    "next_state", "cuts_always", "set_state", "tries_degenerate", "evaluate", "rhs", "rhs_hot", "tangent_at",
    "no_tangent", "was_flipped", "alignment", "branch_size", "set_reference", "motion", "motion_product",
    "indicators", "state_indicator", "project", "domain_detail", "arc_through", "turn_record", "store_record",
    "store_event",
]

#: Each kind of model's record and the module of its functions.
MODELS = {DiamondModel: loop_diamond, GeneralModel: loop_general_output}


def _dispatched(name: str) -> Callable[..., Any]:
    """The function ``name`` of the model whose record is its first argument (see the module docstring)."""

    def call(kind: Any, *args: Any) -> Any:
        module = MODELS[type(kind)]
        function = getattr(module, name)
        if hasattr(function, "py_func"):  # numba's, without a Python wrapper: the module run as plain Python
            function = getattr(plain_import(module.__name__), name)
        return function(kind, *args)

    call.__name__ = call.__qualname__ = name
    call.__doc__ = f"The model's ``{name}`` (:mod:`ncstab.paths.loop_dispatch`)."
    for record, module in MODELS.items():
        function = getattr(module, name)  # (plain Python: the function itself)
        python_function = getattr(function, "py_func", function)
        signature = inspect.signature(python_function)
        if getattr(call, "__signature__", signature) != signature:
            raise TypeError(f"{module.__name__}.{name}{signature}: the models' {name} must take the same parameters")
        call.__signature__ = signature
        _overload(call, record, python_function, getattr(function, "targetoptions", {}).get("inline", "never"))
    return call


def _overload(call: Callable[..., Any], record: type, python_function: Callable[..., Any], inline: str) -> None:
    """Compile ``call`` as ``python_function`` where its first argument is a ``record``,
    inlined as the model inlines it."""

    def compiled(kind: Any, *args: Any) -> Any:
        if getattr(kind, "instance_class", None) is record:
            return python_function
        return None

    compiled.__signature__ = inspect.signature(python_function)
    options = {"error_model": "numpy", "no_cpython_wrapper": True, "no_cfunc_wrapper": True}
    extending.overload(call, inline=inline, jit_options=options)(compiled)


state_size = _dispatched("state_size")
ev_size = _dispatched("ev_size")
aux_size = _dispatched("aux_size")
motion_size = _dispatched("motion_size")
event_columns = _dispatched("event_columns")
switch_bit = _dispatched("switch_bit")
next_state = _dispatched("next_state")
cuts_always = _dispatched("cuts_always")
set_state = _dispatched("set_state")
tries_degenerate = _dispatched("tries_degenerate")
evaluate = _dispatched("evaluate")
rhs = _dispatched("rhs")
rhs_hot = _dispatched("rhs_hot")
tangent_at = _dispatched("tangent_at")
no_tangent = _dispatched("no_tangent")
was_flipped = _dispatched("was_flipped")
alignment = _dispatched("alignment")
branch_size = _dispatched("branch_size")
set_reference = _dispatched("set_reference")
motion = _dispatched("motion")
motion_product = _dispatched("motion_product")
indicators = _dispatched("indicators")
state_indicator = _dispatched("state_indicator")
project = _dispatched("project")
domain_detail = _dispatched("domain_detail")
arc_through = _dispatched("arc_through")
turn_record = _dispatched("turn_record")
store_record = _dispatched("store_record")
store_event = _dispatched("store_event")
