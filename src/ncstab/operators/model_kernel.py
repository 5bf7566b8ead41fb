"""Compiled model kernels: F, K, internal rates, gaps and loads of a general model, per case.

A model (a :class:`~ncstab.systems.SystemDefinition` and one law per family)
gets one generated module (:func:`ncstab.operators.model_kernel_source.kernel_source`:
each member's kinematics, each law's response, the loads and gaps, printed
from their symbolic definitions, and ``evaluate_case``, which assembles

    F = sum_f w_f sum_m J_m^T Q_m - P Q_ext(u) + gap springs,
    K = dF/du = sum_f w_f sum_m [J_m^T D_m J_m + sum_c Q_mc H_mc] - P dQ_ext/du + ...

(seed Eq. 5, 9, 16, 30-34) into one row of
:class:`~ncstab.operators.model_kernel_source.KernelLayout`).  The module is kept in
the cache folder ``compiled`` (:func:`ncstab.generated_modules.load_named_module`)
under a name hashed from the model (:func:`kernel_name`), beside its numba
machine code: sympy runs once per model and machine, numba compiles once per
model and machine.  A case's numbers never depend on its batch.
"""

from __future__ import annotations

import functools
import hashlib
import sys
from pathlib import Path
from typing import Any

import numba
import numpy as np
import sympy as sp

from ncstab.operators import model_assembly, model_kernel_layout, model_kernel_source
from ncstab.operators.model_kernel_source import KERNEL_SIGNATURE, KernelLayout, kernel_source
from ncstab.systems.definition import SystemDefinition

__all__ = ["KernelLayout", "ModelKernel", "kernel_name", "kernel_source", "model_kernel"]


class ModelKernel:
    """The compiled kernel of one model, and the parameter rows of its cases.

    The module is named by a hash of the model (its definition's and laws' repr, which
    say all of their symbolic content), of whether closed gaps carry springs, of this
    generator's and the assembly's source and of the numba, numpy and sympy versions:
    a process that finds it in the cache imports it without running sympy.

    Parameters
    ----------
    definition, laws
        The system and one law per family (:class:`~ncstab.paths.model_batch.ModelBatch`).
    activate
        Whether closed gaps carry springs (``secondary_contacts = "activate"``).
    """

    def __init__(self, definition: SystemDefinition, laws: tuple[Any, ...], activate: bool) -> None:
        from sympy.printing.codeprinter import PrintMethodNotImplementedError

        from ncstab.generated_modules import load_named_module

        self.definition = definition
        try:
            self.module = load_named_module(
                kernel_name(definition, laws, activate), lambda: kernel_source(definition, laws, activate)
            )
        except PrintMethodNotImplementedError as error:
            function = str(error).split(": ")[-1].split("\n")[0]
            raise ValueError(
                f"system {definition.name!r}: its compiled kernel cannot be printed: {function} is not a function "
                "of Python's math module (the kernels are compiled with numba; write it with math functions)"
            ) from None
        self.layout = KernelLayout(**self.module.LAYOUT_FIELDS)
        self.free_parameters = self.module.FREE_PARAMETERS

    def parameter_rows(self, parameters: dict, law_values: tuple[dict, ...], kappa: Any, size: int) -> np.ndarray:
        """Each case's parameter row ``(B, ROW)``: the system's parameters, each family's
        free law parameters (:attr:`free_parameters`), then kappa."""
        columns = [parameters[p.name] for p in self.definition.parameters]
        for names, values in zip(self.free_parameters, law_values):
            columns += [values[name] for name in names]
        columns.append(kappa)
        rows = np.empty((size, len(columns)))
        for j, column in enumerate(columns):
            rows[:, j] = np.asarray(column, dtype=float).reshape(-1) if np.ndim(column) else float(column)
        return rows

    def evaluate(self, u: np.ndarray, internal: np.ndarray, load: np.ndarray, state: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """The kernel's output rows ``(B, layout.size)`` at a batch of states."""
        size = u.shape[0]
        out = np.empty((size, self.layout.size))
        if size == 0:
            return out
        from ncstab.paths.loop_route import evaluates_plain

        from ncstab.plain_python import PLAIN_ERRORS

        if evaluates_plain(size, self.module.evaluate_batch):
            try:
                with np.errstate(all="ignore"):
                    self._evaluate(self.plain_batch, u, internal, load, state, rows, out)
                return out
            except PLAIN_ERRORS:  # a division by zero of Python floats: compiled, inf as numba gives
                pass
        self._evaluate(self._compiled_batch(), u, internal, load, state, rows, out)
        return out

    def _evaluate(
        self, batch: Any, u: np.ndarray, internal: np.ndarray, load: np.ndarray, state: np.ndarray, rows: np.ndarray,
        out: np.ndarray,
    ) -> None:
        size = u.shape[0]
        batch(
            np.ascontiguousarray(u, dtype=float),
            np.ascontiguousarray(internal, dtype=float).reshape(size, self.layout.n_internal),
            np.ascontiguousarray(np.broadcast_to(load, (size,)), dtype=float),
            np.ascontiguousarray(np.broadcast_to(state, (size,)), dtype=np.int64),
            rows,
            out,
        )

    @functools.cached_property
    def callback(self) -> Any:
        """``case`` of the module as a C callback of :data:`KERNEL_SIGNATURE` (compiled once per
        model and machine, cached beside the module): the compiled stage loop's ``law``."""
        try:
            return numba.cfunc(KERNEL_SIGNATURE, cache=True, error_model="numpy")(self.module.case)
        except numba.core.errors.NumbaError as error:
            first = str(error).strip().splitlines()[0]
            raise ValueError(f"system {self.definition.name!r}: numba cannot compile its kernel: {first}") from None

    @functools.cached_property
    def plain_case(self) -> Any:
        """``case`` of the module as plain Python (:mod:`ncstab.plain_python`): the plain
        stage loop's ``law``, nothing compiled."""
        from ncstab.plain_python import plain_module

        return plain_module(self.module).case

    @functools.cached_property
    def plain_batch(self) -> Any:
        """``evaluate_batch`` of the module as plain Python (:mod:`ncstab.plain_python`)."""
        from ncstab.plain_python import plain_module

        return plain_module(self.module).evaluate_batch

    def _compiled_batch(self) -> Any:
        """``evaluate_batch``, compiled (a numba error becomes a ValueError naming the system)."""
        batch = self.module.evaluate_batch
        if not batch.signatures:
            try:
                batch.compile("(f8[:, ::1], f8[:, ::1], f8[::1], i8[::1], f8[:, ::1], f8[:, ::1])")
            except numba.core.errors.NumbaError as error:
                first = str(error).strip().splitlines()[0]
                raise ValueError(f"system {self.definition.name!r}: numba cannot compile its kernel: {first}") from None
        return batch


def kernel_name(definition: SystemDefinition, laws: tuple[Any, ...], activate: bool) -> str:
    """The cached module's name: ``model_`` and a hash of all it is printed from."""
    modules = (sys.modules[__name__], model_kernel_source, model_kernel_layout, model_assembly)
    generator = b"".join(Path(module.__file__).read_bytes() for module in modules)
    versions = repr((numba.__version__, np.__version__, sp.__version__))
    digest = hashlib.sha256(repr((definition, laws, activate)).encode() + generator + versions.encode())
    return f"model_{digest.hexdigest()[:20]}"


@functools.cache
def model_kernel(definition: SystemDefinition, laws: tuple[Any, ...], activate: bool) -> ModelKernel:
    """The :class:`ModelKernel` of a model, built once per process."""
    return ModelKernel(definition, laws, activate)
