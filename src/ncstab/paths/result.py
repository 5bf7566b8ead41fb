"""The result of :func:`ncstab.follow`: states, statuses and events, and its Dataset."""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

import ncstab
from ncstab.operators.indicators import (
    det_K,
    flutter_discriminant,
    hill_eigenvalue,
    skew_part,
    symmetric_part,
)
from ncstab.paths.engine import CaseResult
from ncstab.paths.options import PathOptions, SystemSpec
from ncstab.paths.programme import EVENTS, LoadingProgramme, Stage
from ncstab.paths.variables import CASE_DIMENSION, EVENT_FIELDS, VARIABLES

if TYPE_CHECKING:  # pragma: no cover
    import xarray

    from ncstab.laws.definition import LawDefinition
    from ncstab.paths.api import ParameterGrid

__all__ = ["Path", "parameter_attributes"]


@dataclass(frozen=True)
class Path:
    """Paths of every law and every case of a sweep.

    Attributes
    ----------
    laws
        Law names (the first sweep dimension).
    grid
        The parameter grid (further sweep dimensions, in order).
    system, programme, options
        What was followed and how.
    results
        One :class:`~ncstab.paths.engine.CaseResult` per law, cases flat in C
        order over the grid.
    definitions
        The laws' definitions, in the order of :attr:`laws` (user laws are
        not in the catalogue); empty: looked up by name.
    """

    laws: tuple[str, ...]
    grid: "ParameterGrid"
    system: SystemSpec
    programme: LoadingProgramme
    options: PathOptions
    results: tuple[CaseResult, ...]
    dof_names: tuple[str, ...]
    force_names: tuple[str, ...]
    study_text: str = ""
    definitions: tuple["LawDefinition", ...] = ()

    def law_definition(self, name: str) -> "LawDefinition":
        """The definition of one of :attr:`laws` (from :attr:`definitions` when given, else the catalogue)."""
        from ncstab.laws.registry import law_definition

        known = {law: definition for law, definition in zip(self.laws, self.definitions)}
        return known[name] if name in known else law_definition(name)

    @property
    def force_unit(self) -> str:
        """Unit of forces: 2R k_n, or 2R k_t in the pure-shear limit (seed Eq. 62)."""
        return "2R k_t" if self.system.normal == "rigid" else "2R k_n"

    @property
    def shape(self) -> tuple[int, ...]:
        """Sweep shape: (law, *swept parameters)."""
        return (len(self.laws),) + self.grid.shape

    @property
    def status(self) -> np.ndarray:
        """Per-case status, shape :attr:`shape`."""
        return np.stack([r.status for r in self.results]).reshape(self.shape)

    @property
    def message(self) -> np.ndarray:
        return np.stack([r.message for r in self.results]).reshape(self.shape)

    @property
    def succeeded(self) -> np.ndarray:
        """True where a case finished or stopped at an event (did not fail)."""
        return ~np.char.startswith(self.status.astype(str), "failed")

    def case(self, law: str, **parameters: float) -> tuple[CaseResult, int]:
        """(result of the law, flat case index) of one case, by parameter values."""
        result = self.results[self.laws.index(law)]
        index = []
        for name, values in self.grid.sweep.items():
            if name not in parameters:
                raise KeyError(f"give a value for the swept parameter {name!r}")
            matches = np.flatnonzero(np.isclose(values, parameters[name], rtol=0, atol=1e-12))
            if matches.size == 0:
                raise KeyError(f"{name} = {parameters[name]} is not in the sweep {values}")
            index.append(int(matches[0]))
        flat = int(np.ravel_multi_index(index, self.grid.shape)) if index else 0
        return result, flat

    def to_dataset(self, directions: int | None = None) -> "xarray.Dataset":
        """The labelled Dataset of ARCHITECTURE.md ("Dataset of a path study").

        Dimensions: ``law``, the swept parameters in order, then ``step``,
        ``dof``, ``i``, ``j``.  Paths of different lengths are NaN-padded
        along ``step``; ``n_steps`` gives each case's length.

        Parameters
        ----------
        directions
            If given (M >= 4), add the directional second-order work map
            ``d2W_dir`` (dims ..., step, theta) on M directions theta in
            [0, pi) (d2W is pi-periodic), and per step the unstable cone
            ``cone_width``, ``cone_lower``, ``cone_upper`` (exact roots).
        """
        import xarray as xr

        sweep_dims = ["law", *self.grid.sweep]
        shape = self.shape
        n = len(self.dof_names)
        length = max(int(r.n_steps.max()) if r.n_steps.size else 0 for r in self.results)

        def stacked(key: str) -> np.ndarray:
            arrays = []
            for r in self.results:
                a = r.steps[key]
                pad = length - a.shape[1]
                if pad:
                    fill = -1 if a.dtype.kind == "i" else np.nan
                    a = np.concatenate([a, np.full((a.shape[0], pad) + a.shape[2:], fill, dtype=a.dtype)], 1)
                arrays.append(a)
            array = np.stack(arrays)
            return array.reshape(shape + array.shape[2:])

        K = stacked("K")
        du = stacked("du")
        dF = np.einsum("...ij,...j->...i", K, du)
        with np.errstate(invalid="ignore", divide="ignore"):
            d2w = np.einsum("...i,...i->...", dF, du) / (np.linalg.norm(dF, axis=-1) * np.linalg.norm(du, axis=-1))
        stage = stacked("stage")
        mixed = self._mixed_control(K, stage)

        step_dims = [*sweep_dims, "step"]
        data = {
            "u": (step_dims + ["dof"], stacked("u")),
            "F": (step_dims + ["dof"], stacked("F")),
            "alpha": (step_dims, stacked("alpha")),
            "l": (step_dims, stacked("l")),
            "N": (step_dims, stacked("N")),
            "T": (step_dims, stacked("T")),
            "s": (step_dims, stacked("s")),
            "stage": (step_dims, stage.astype(np.int32)),
            "lam": (step_dims, stacked("lam")),
            "work": (step_dims, stacked("work")),
            "K": (step_dims + ["i", "j"], K),
            "K_sym": (step_dims + ["i", "j"], symmetric_part(K)),
            "K_skew": (step_dims + ["i", "j"], skew_part(K)),
            "det_K": (step_dims, det_K(K)),
            "hill": (step_dims, hill_eigenvalue(K)),
            "d2W": (step_dims, d2w),
            "flutter": (step_dims, flutter_discriminant(K)),
            "mixed_control": (step_dims, mixed),
            "n_steps": (sweep_dims, np.stack([r.n_steps for r in self.results]).reshape(shape).astype(np.int32)),
            "status": (sweep_dims, self.status.astype(str)),
            "message": (sweep_dims, self.message.astype(str)),
            "accepted_steps": (
                sweep_dims,
                np.stack([r.counters["accepted"] for r in self.results]).reshape(shape).astype(np.int32),
            ),
            "rejected_steps": (
                sweep_dims,
                np.stack([r.counters["rejected"] for r in self.results]).reshape(shape).astype(np.int32),
            ),
        }
        if directions is not None:
            from ncstab.operators.directional_work import directional_second_order_work, unstable_cone

            if int(directions) < 4:
                raise ValueError(f"directions must be at least 4, got {directions}")
            theta = np.linspace(0.0, np.pi, int(directions), endpoint=False)
            data["d2W_dir"] = (step_dims + ["theta"], directional_second_order_work(K, theta))
            width, lower, upper = unstable_cone(K)
            data["cone_width"] = (step_dims, width)
            data["cone_lower"] = (step_dims, lower)
            data["cone_upper"] = (step_dims, upper)
        n_cycles = self.results[0].cycles["work"].shape[1] if self.results[0].cycles else 0
        if n_cycles:
            def cycle_array(key: str) -> np.ndarray:
                array = np.stack([r.cycles[key] for r in self.results])
                return array.reshape(shape + array.shape[2:])

            work = cycle_array("work")
            data["cycle_work"] = ([*sweep_dims, "cycle"], work)
            data["cumulative_work"] = ([*sweep_dims, "cycle"], np.cumsum(work, axis=-1))
            data["cycle_force_gap"] = ([*sweep_dims, "cycle", "dof"], cycle_array("force_gap"))
            data["cycle_T_drift"] = ([*sweep_dims, "cycle"], cycle_array("tangential_drift"))
        for name, (dims, values) in list(data.items()):
            units, long_name, description = VARIABLES[name]
            if self.system.normal == "rigid" and name in ("F", "N", "T"):
                description = description.replace("2R k_n", "2R k_t") + " (pure-shear limit: forces in units of 2R k_t, seed Eq. 62)"
                long_name = long_name.replace("*", "^")
            attrs = {"long_name": long_name, "description": description}
            if units:
                attrs["units"] = units
            data[name] = (dims, values, attrs)
        for event in EVENTS:
            for suffix, (units, long_name, description) in EVENT_FIELDS.items():
                values = np.stack([r.events[event][suffix] for r in self.results])
                values = values.reshape(shape + values.shape[2:])
                dims = sweep_dims + {2: ["dof"], 3: ["i", "j"]}.get(values.ndim - len(shape) + 1, [])
                if suffix == "stage":
                    values = values.astype(np.int32)
                data[f"{event}_{suffix}"] = (
                    dims,
                    values,
                    {
                        "units": units,
                        "long_name": long_name.format(event=event),
                        "description": description.format(event=event),
                    },
                )
        classes = self._law_classes()
        coords = {
            "law": ("law", np.array(self.laws, dtype=str), {"long_name": "contact interaction law"}),
            "law_class": ("law", np.array([classes[l] for l in self.laws], dtype=str), {
                "long_name": "computed class of the law",
                "description": "hyperelastic, weakly hypoelastic or strongly hypoelastic (ncstab.symbolic.classify)",
            }),
            "step": ("step", np.arange(length, dtype=np.int32), {"long_name": "stored state index"}),
            "dof": ("dof", np.arange(1, n + 1, dtype=np.int32), {
                "long_name": "degree of freedom",
                "description": ", ".join(f"{i + 1}: {d}/{f}" for i, (d, f) in enumerate(zip(self.dof_names, self.force_names))),
            }),
            "i": ("i", np.arange(1, n + 1, dtype=np.int32), {"long_name": "matrix row (dof)"}),
            "j": ("j", np.arange(1, n + 1, dtype=np.int32), {"long_name": "matrix column (dof)"}),
        }
        for name, values in self.grid.sweep.items():
            coords[name] = (name, values, parameter_attributes(name))
        if directions is not None:
            coords["theta"] = ("theta", theta, {
                "units": "rad", "long_name": "loading direction theta",
                "description": "direction of du = (cos theta, sin theta) in the (Delta_1*, Delta_2*) plane; d2W is pi-periodic"})
        if n_cycles:
            coords["cycle"] = ("cycle", np.arange(1, n_cycles + 1, dtype=np.int32), {
                "long_name": "cycle number", "description": "turns of the cycle stages, in programme order"})
            units, long_name, description = VARIABLES["cycle_stage"]
            coords["cycle_stage"] = ("cycle", self.results[0].cycles["stage"].astype(np.int32), {
                "units": units, "long_name": long_name, "description": description})
            stage_direction = [getattr(st, "direction", 0) for st in self.programme.stages]
            coords["cycle_direction"] = (
                "cycle",
                np.array([stage_direction[k] for k in self.results[0].cycles["stage"]], dtype=np.int32),
                {"units": "1", "long_name": "direction of each cycle",
                 "description": "1 counterclockwise, -1 clockwise in the (Delta_1*, Delta_2*) plane"},
            )
        attrs = {
            "Conventions": "CF-1.10",
            "title": "ncstab path study",
            "ncstab_version": ncstab.__version__,
            "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "study": self.study_text,
            "system": self.system.name,
            "secondary_contacts": self.system.secondary_contacts,
            "normal": self.system.normal,
            "law_class": "; ".join(f"{l}: {classes[l]}" for l in self.laws),
            "force_unit": self.force_unit,
            "source": "Challamel, Nicot, Wautier, Darve & Lerbet (2022), J. Eng. Mech. 148(9) 04022053",
        }
        for name, value in self.grid.fixed.items():
            attrs[f"parameter_{name}"] = value
        dataset = xr.Dataset({k: v for k, v in data.items()}, coords=coords, attrs=attrs)
        return dataset

    def _law_classes(self) -> dict[str, str]:
        from ncstab.symbolic.classification import classify

        return {name: classify(self.law_definition(name)).kind for name in self.laws}

    def _mixed_control(self, K: np.ndarray, stage: np.ndarray) -> np.ndarray:
        """det K_SS per stored state, with S the force-controlled dofs of its stage."""
        from ncstab.operators.indicators import mixed_control_determinant

        out = np.full(stage.shape, np.nan)
        for k, st in enumerate(self.programme.stages):
            where = stage == k
            if not where.any():
                continue
            if isinstance(st, Stage):
                controlled = [i for i, f in enumerate(self.force_names) if f in st.controls()]
            else:
                controlled = []
            out[where] = mixed_control_determinant(K[where], controlled)
        return out


def parameter_attributes(name: str) -> dict[str, str]:
    """Attributes of the coordinate of a swept parameter (units, long_name, description)."""
    from ncstab.laws.definition import ALPHA0_SPEC, GAMMA_SPEC

    known = {
        "gamma": ("1", "stiffness ratio gamma", GAMMA_SPEC.description),
        "alpha0": ("rad", "initial orientation alpha0", ALPHA0_SPEC.description),
        "kappa": ("1", "secondary contact stiffness ratio kappa", "stiffness of the secondary-contact springs / k_n"),
        CASE_DIMENSION: ("1", "case index", "flat index of the case in the whole sweep (C order over the swept parameters)"),
    }
    units, long_name, description = known.get(name, ("1", name, f"study parameter {name}"))
    return {"units": units, "long_name": long_name, "description": description}
