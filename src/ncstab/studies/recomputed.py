"""K along the paths of an archive that does not store it, computed from the states it does.

The lean archive of a large sweep leaves out ``K``, ``K_sym`` and ``K_skew``
(docs/archive.md).  For the seed's reduced diamond K at a stored state is a
function of the displacements ``u``, the law and its parameters, and, for a
law whose tangential force is an internal variable (Cundall--Strack:
``T`` depends on the loading history), of the stored ``T`` (seed Eq. 38):
:func:`tangent_operators` evaluates it with
:func:`ncstab.operators.tangent_operator`, which the path engine's
operator agrees with to rounding.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ncstab.operators.tangent import tangent_operator
from ncstab.paths.api import resolve_model

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

__all__ = ["tangent_operators"]


def tangent_operators(dataset: "xr.Dataset") -> "xr.DataArray":
    """K = dF*/dDelta* at every stored state of an archive of the seed's reduced diamond.

    Parameters
    ----------
    dataset
        An archive (:func:`~ncstab.studies.open_study`) of the reduced diamond
        with deformable contacts and secondary contacts ``"ignore"`` or
        ``"stop"`` (an activated secondary contact adds its spring to K, and
        the archive does not store when it touches).  It needs ``u`` and, for
        a law without a total tangential form, ``T``: the lean default keeps both.

    Returns
    -------
    xarray.DataArray
        ``K`` with the dimensions of the archive's ``K`` (sweep, ``step``,
        ``i``, ``j``), NaN past each case's last step, named ``K``, with the
        archive's units and descriptions.

    Raises
    ------
    ValueError
        Another system, rigid contacts, activated secondary contacts, or a
        variable missing; the message says which.
    """
    import xarray as xr

    from ncstab.paths.variables import VARIABLES
    from ncstab.studies.study import parse_study
    from ncstab.systems import DiamondChain

    study = parse_study(str(dataset.attrs.get("study", "")), "<archive>")
    if not study.system.is_reduced_diamond or study.system.normal != "deformable":
        raise ValueError("K is computed again for the seed's reduced diamond with deformable contacts only")
    if study.system.secondary_contacts == "activate":
        raise ValueError("with activated secondary contacts K includes their springs, which the archive does not "
                         "say when they touch: run the study with variables = \"all\" to keep K")
    sweep = [d for d in dataset["status"].dims if d != "law"]
    fixed = {k[len("parameter_"):]: float(v) for k, v in dataset.attrs.items() if k.startswith("parameter_")}
    u = dataset["u"].transpose("law", *sweep, "step", "dof")
    blocks = []
    for law_name in dataset["law"].values.tolist():
        definition = study.law_definition(law_name)
        model = resolve_model(study.system, [definition])
        law_definition = model.laws[0]

        def parameter(name: str, default: float | None) -> np.ndarray:
            if name in sweep:
                values = dataset[name].broadcast_like(dataset["status"].sel(law=law_name))
                return np.asarray(values.transpose(*sweep).values, dtype=float)[..., None]
            return np.asarray(fixed.get(name, default), dtype=float)

        alpha0 = parameter("alpha0", np.pi / 4)
        system = DiamondChain(alpha0=alpha0)
        values = {p.name: parameter(p.name, p.default) for p in law_definition.parameters if p.name != "alpha0"}
        if "alpha0" in {p.name for p in law_definition.parameters}:
            values["alpha0"] = alpha0
        from ncstab.laws.registry import make_law

        law = make_law(law_definition, **values)
        states = np.asarray(u.sel(law=law_name).values, dtype=float)
        finite = np.isfinite(states).all(axis=-1)
        safe = np.where(finite[..., None], states, 0.0)
        tangential = None
        if not law.has_total_form:
            if "T" not in dataset:
                raise ValueError(f"law {law_name!r} has T as an internal variable: K needs the archive's 'T'")
            T = np.asarray(dataset["T"].sel(law=law_name).transpose(*sweep, "step").values, dtype=float)
            tangential = np.where(finite, T, 0.0)[..., None]
        with np.errstate(all="ignore"):
            K = tangent_operator(system, law, safe, tangential=tangential)
        blocks.append(np.where(finite[..., None, None], K, np.nan))
    units, long_name, description = VARIABLES["K"]
    return xr.DataArray(
        np.stack(blocks), dims=("law", *sweep, "step", "i", "j"), name="K",
        coords={name: dataset[name] for name in ("law", *sweep, "step", "i", "j") if name in dataset.coords},
        attrs={"units": units, "long_name": long_name, "description": description},
    )
