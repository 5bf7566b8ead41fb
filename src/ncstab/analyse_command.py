"""``ncstab analyse PACKING.nc --law NAME``: K, Hill's eigenvalue, inertia and modes of a packing, as an archive.

:func:`analyse` reads and validates the packing (:mod:`ncstab.systems.packing`:
a malformed one is an :class:`~ncstab.systems.packing.PackingError`, exit code
2, nothing written) and the given directions
(:mod:`ncstab.operators.packing_directions`: a malformed one is a
``DirectionsError``, exit code 2), assembles K with the law
(:mod:`ncstab.operators.packing_analysis`), adds the second-order work of the
directions and the exact unstable cones (the plane of the two softest modes of
K_sym, and the planes of given pairs of directions) and returns the archive as an
``xarray.Dataset`` (written to ``output`` when given: to a temporary file
beside it, then renamed, so that a failed write leaves nothing).  Every variable
has ``units``, ``long_name`` and ``description``; docs/packings.md lists them.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

__all__ = ["add_analyse_parser", "analyse", "analysis_dataset", "command_analyse", "default_analysis_path"]


def default_analysis_path(packing: str | os.PathLike[str]) -> Path:
    """``results/<file stem>_analysis.nc``."""
    return Path("results") / f"{Path(packing).stem}_analysis.nc"


def _law(name: str):
    from ncstab.laws.definition import LawDefinition
    from ncstab.laws.registry import law_definition
    from ncstab.studies.errors import InvalidInputError

    try:
        law = law_definition(name)
    except ValueError as error:
        raise InvalidInputError(f"--law: {error}") from None
    if not isinstance(law, LawDefinition):
        raise InvalidInputError(f"--law: {name!r} is a spring law, not a contact law")
    return law


def analyse(packing: Any, law: str | Any = "mcnamara", gamma: float = 1.0, modes: int = 6,
            output: str | os.PathLike[str] | None = None, loops: bool = False, directions: Any = None,
            cone_planes: Any = (), keep_rattlers: bool = False, friction: float | None = None,
            probe: Any = None):
    """Analyse a packing: the archive of ``ncstab analyse`` as an ``xarray.Dataset``.

    Parameters
    ----------
    packing
        A packing file's path, or a :class:`~ncstab.systems.packing.Packing`.
    law
        A law name of the catalogue (``"cundall_strack"``, ``"mcnamara+no_tension"``),
        or a law definition (a user law).
    gamma
        k_t / k_n (seed Eq. 37).
    modes
        How many of the smallest eigenpairs of K_sym to keep.
    output
        Where to write the archive (NetCDF); None: not written.
    loops
        Also the grain loops, by increasing Hill eigenvalue as rings
        (:mod:`ncstab.systems.mesostructures`): ``loop_hill``, ``loop_length``,
        ``loop_grains`` along ``loop``.
    directions
        Directions over the free dofs whose second-order work d^T K d / d^T d
        is wanted (``direction_d2W``): a file's path (CSV with a header of dof
        names, or ``.npy``), an array ``(p, n)`` or ``(n,)`` in the order of
        ``Packing.dof_names()``, or a mapping {name: vector}
        (:mod:`ncstab.operators.packing_directions`).
    cone_planes
        Pairs of directions (names or 0-based rows, ``"a,b"`` or ``(a, b)``):
        the exact unstable cone in each pair's plane, after the plane of the
        two softest modes of K_sym, which is always given (``cone_width``,
        ``cone_lower``, ``cone_upper`` along ``plane``).
    keep_rattlers
        Keep the rattlers in K (default: held, their contacts removed;
        :mod:`ncstab.operators.rattlers`); ``rattler`` and ``rattlers`` say which.
    friction
        The Coulomb ratio mu, over the packing's ``friction`` (docs/friction.md); with
        either, ``contact_state``, the consistent ``hill``, ``hill_direction``, ``hill_sticking``.
    probe
        Prescribed dof increments, ``"x3=1e-4,y3=0"`` or {name: value}: ``probe_du``, ``probe_dF``,
        ``probe_contact_state`` (:mod:`ncstab.operators.incremental_probe`).

    Raises
    ------
    InvalidInputError
        A malformed packing, law, option or direction (exit code 2), before
        anything is computed or written.
    """
    from dataclasses import replace

    import numpy as np

    from ncstab.operators.analysis_size import check_analysis_size
    from ncstab.operators.packing_analysis import analyse_packing
    from ncstab.operators.packing_directions import cone_planes as cone_planes_of
    from ncstab.operators.packing_directions import directions_from, resolve_planes
    from ncstab.operators.rattlers import rattler_mask, without_rattlers
    from ncstab.studies.errors import InvalidInputError
    from ncstab.systems.packing import Packing, PackingError, read_packing

    if not np.isfinite(gamma) or gamma < 0:
        raise InvalidInputError(f"--gamma: {gamma!r} is not a non-negative number")
    if int(modes) < 0:
        raise InvalidInputError(f"--modes: {modes!r} is negative")
    definition = _law(law) if isinstance(law, str) else law
    original = packing if isinstance(packing, Packing) else read_packing(packing)
    rattler = rattler_mask(original)
    value = original if keep_rattlers or not rattler.any() else without_rattlers(original, rattler)
    check_analysis_size(original, int(modes))  # before any factorization: refuse what cannot fit
    given = None if directions is None else directions_from(directions, value)
    from ncstab.operators.friction_variables import friction_variables, parse_probe
    from ncstab.systems.packing import validate_friction

    mu = value.friction if friction is None else validate_friction(friction, value.n_contacts, name="--friction")
    probed = None if probe is None else parse_probe(probe, value.dof_names())
    planes = resolve_planes([cone_planes] if isinstance(cone_planes, str) else cone_planes or (), given)
    if value.n_dof == 0 and original.n_dof > 0:
        raise PackingError(f"{original.source}: every free grain is a rattler (fewer than two force-carrying "
                           "contacts, variable 'normal_force'): no dof left; --keep-rattlers keeps them")
    result = analyse_packing(value, definition, float(gamma), max(int(modes), 2))  # the cone's plane: 2 modes
    cones = cone_planes_of(result.tangent.K, result.modes[:2], planes)
    result = replace(result, mode_values=result.mode_values[:int(modes)], modes=result.modes[:int(modes)],
                     participation=result.participation[:int(modes)])
    dataset = analysis_dataset(value, result, definition.name, float(gamma))
    dataset = dataset.merge(direction_variables(value, result, given, cones))
    dataset = dataset.merge(sample_variables(original, rattler, keep_rattlers))
    dataset["fixed"] = dataset.fixed.copy(data=original.fixed.astype(np.int8))  # as given (rattlers: `rattler`)
    if loops:
        dataset = dataset.merge(loop_variables(value, result))
    if mu is not None or probed is not None:
        dataset.update(friction_variables(value, result.tangent, mu, probed))
    if output is not None:
        write_analysis(dataset, output)
    return dataset


def _attrs(units: str, long_name: str, description: str, **more: Any) -> dict[str, Any]:
    return {"units": units, "long_name": long_name, "description": description, **more}


def analysis_dataset(packing, result, law_name: str, gamma: float):
    """The archive of an analysis (:class:`~ncstab.operators.packing_analysis.PackingAnalysis`)."""
    import numpy as np
    import xarray as xr

    import ncstab
    from ncstab.operators.packing_analysis import mode_components
    from ncstab.systems.packing import ATTRIBUTES

    K = result.tangent.K.tocoo()
    stiffness = "k_n (per mean grain diameter for x, y; times it for theta)"
    tol = {"tolerance": result.tolerance, "tolerance_rule": "|lambda| <= 1e-9 max |diag K_sym|"}
    grain_vars = {name: ("grain", getattr(packing, name) if name != "fixed" else packing.fixed.astype(np.int8),
                         _attrs(*ATTRIBUTES[name])) for name in ("x", "y", "radius", "fixed")}
    contact_vars = {
        "grain_a": ("contact", packing.contacts[:, 0].astype(np.int32), _attrs(*ATTRIBUTES["grain_a"])),
        "grain_b": ("contact", packing.contacts[:, 1].astype(np.int32), _attrs(*ATTRIBUTES["grain_b"])),
        "normal_force": ("contact", result.tangent.forces[:, 0], _attrs(*ATTRIBUTES["normal_force"])),
        "tangential_force": ("contact", result.tangent.forces[:, 1], _attrs(*ATTRIBUTES["tangential_force"])),
        "contact_scale": ("contact", result.tangent.contacts.scale, _attrs(
            "mean grain diameter", "contact length scale rho",
            "rest length of the contact's normal law, rho = |d| + N; the law sees l = |d|/rho (docs/packings.md)")),
        "contact_alpha0": ("contact", np.asarray(np.broadcast_to(result.tangent.parameters["alpha0"],
                                                                 (packing.n_contacts,)), dtype=float), _attrs(
            "rad", "contact reference angle alpha0",
            "the law's alpha0: its tangential force at the state is the packing's (beta = alpha at the state)")),
    }
    free = packing.free
    data = {
        "hill": ((), result.hill, _attrs(stiffness, "Hill's eigenvalue",
                                          "smallest eigenvalue of K_sym = (K + K^T)/2 over the free dofs; "
                                          "Hill's condition holds while it is positive")),
        "negative_eigenvalues": ((), np.int32(result.negative_eigenvalues), _attrs(
            "1", "negative eigenvalues of K_sym", "count of eigenvalues below -tolerance (Sylvester's inertia)",
            **tol)),
        "zero_eigenvalues": ((), np.int32(result.zero_eigenvalues), _attrs(
            "1", "zero eigenvalues of K_sym", "count of eigenvalues within +-tolerance (Sylvester's inertia)",
            **tol)),
        "det_K_sign": ((), np.int8(result.det_sign), _attrs(
            "1", "sign of det K", "-1, 0 or 1 (0: K is singular: no held grain, a free grain without contact, "
            "or zero eigenvalues of a symmetric K)")),
        "K_asymmetry": ((), result.asymmetry, _attrs("1", "asymmetry of K", "max |K - K^T| / max |K|")),
        "mode_eigenvalue": (("mode",), result.mode_values, _attrs(
            stiffness, "eigenvalue of K_sym", "the smallest eigenvalues of K_sym, ascending")),
        "mode": (("mode", "grain", "component"), mode_components(packing, result.modes), _attrs(
            "1 (x, y: mean grain diameter; theta: rad, per unit mode)", "eigenvector of K_sym",
            "unit eigenvector over the free dofs, per grain and component (held grains 0), largest entry positive")),
        "participation": (("mode", "grain"), result.participation, _attrs(
            "1", "participation of each grain in the mode",
            "share of the mode's squared norm on the grain's three dofs (sums to 1 over the grains)")),
        "K_row": (("nonzero",), K.row.astype(np.int32), _attrs("1", "row of K", "index into the free dofs")),
        "K_col": (("nonzero",), K.col.astype(np.int32), _attrs("1", "column of K", "index into the free dofs")),
        "K_value": (("nonzero",), K.data, _attrs(stiffness, "entry of K", "K[K_row, K_col] = K_value (coordinate "
                                                  "form; free dofs x<i>, y<i>, theta<i> in grain order)")),
        "R": (("dof",), result.tangent.R, _attrs(
            "k_n mean grain diameter (theta: times the diameter)", "internal generalized force",
            "R = sum_c rho^2 J^T Q* over the free dofs: equal to the applied loads at an equilibrium")),
        "dof_grain": (("dof",), np.repeat(free, 3).astype(np.int32), _attrs("1", "grain of the dof",
                                                                            "0-based grain index of each free dof")),
        "dof_name": (("dof",), np.array(packing.dof_names(), dtype=str), _attrs(
            "1", "name of the dof", "x<i>, y<i>, theta<i> (i the 0-based grain) of each free dof, in K's order")),
        **grain_vars, **contact_vars,
    }
    coords = {"component": ("component", np.array(["x", "y", "theta"]), _attrs(
        "1", "dof component", "x, y: translations of the grain's centre; theta: its rotation"))}
    dataset = xr.Dataset({name: (dims, value, attrs) for name, (dims, value, attrs) in data.items()}, coords=coords)
    dataset.attrs.update({"title": "ncstab packing analysis", "Conventions": "CF-1.8", "law": law_name,
                          "gamma": gamma, "packing": packing.source, "n_grains": packing.n_grains,
                          "n_contacts": packing.n_contacts, "n_dof": int(result.tangent.K.shape[0]),
                          "ncstab_version": ncstab.__version__,
                          "source": "ncstab analyse (docs/packings.md)"})
    return dataset


def sample_variables(packing, rattler, kept: bool):
    """The sample's variables: ``stress`` (Love-Weber, every contact of ``packing``), ``rattler``, ``rattlers``."""
    import numpy as np
    import xarray as xr

    from ncstab.operators.packing_stress import love_weber_stress
    from ncstab.operators.rattlers import RATTLER_TOLERANCE

    stress = love_weber_stress(packing)
    rule = (f"a free grain with fewer than two force-carrying contacts (N > {RATTLER_TOLERANCE:g} max N), removed "
            "recursively; none where no contact is compressed")
    xyz = ("xyz", np.array(["x", "y"]), _attrs("1", "axis", "x, y"))
    return xr.Dataset({
        "stress": (("xyz", "xyz_column"), stress.stress, _attrs(
            "k_n", "Love-Weber stress", "sigma_ij = (1/V) sum_c f_i l_j, f the force of grain a on grain b "
            "(N n - T t), l = x_b - x_a, over every contact of the packing (rattlers' included): compression "
            "positive; per unit thickness", volume=stress.volume, volume_rule=stress.volume_rule)),
        "rattler": (("grain",), rattler.astype(np.int8), _attrs(
            "1", "rattler", f"1: {rule}; " + ("kept in K (--keep-rattlers)" if kept else
                                              "held and its contacts removed from K"),
            tolerance=RATTLER_TOLERANCE, kept=int(kept))),
        "rattlers": ((), np.int32(rattler.sum()), _attrs("1", "number of rattlers", rule,
                                                         tolerance=RATTLER_TOLERANCE, kept=int(kept))),
    }, coords={"xyz": xyz, "xyz_column": ("xyz_column", *xyz[1:])})


def direction_variables(packing, result, directions, cones):
    """The second-order work of the given directions (none: no ``direction``) and the unstable cones, per plane."""
    import numpy as np
    import xarray as xr

    from ncstab.operators.packing_analysis import mode_components
    from ncstab.operators.packing_directions import direction_work

    stiffness = "k_n (per mean grain diameter for x, y; times it for theta)"
    per_dof = "1 (x, y: mean grain diameter; theta: rad)"
    root = "exact root of d(t)^T K d(t) = 0, d(t) = cos t e1 + sin t e2"
    data: dict[str, Any] = {
        "cone_width": (("plane",), np.array([c.width for c in cones]), _attrs(
            "rad", "width of the unstable cone in the plane",
            "total angle t over the full circle of directions d(t) = cos t e1 + sin t e2 of the plane (cone_basis) "
            "where d^T K d < 0: 0 where the projected form is positive definite (Hill's condition holds in the "
            "plane), 2 pi where it is negative definite")),
        "cone_lower": (("plane",), np.array([c.lower for c in cones]), _attrs(
            "rad", "lower bound of the unstable cone in the plane",
            f"{root}, angle from e1 towards e2, in [0, pi), bounding one of the two opposite unstable cones (the "
            "other is shifted by pi); NaN where there is no cone or where every direction of the plane is unstable")),
        "cone_upper": (("plane",), np.array([c.upper for c in cones]), _attrs(
            "rad", "upper bound of the unstable cone in the plane",
            f"{root}: cone_lower + cone_width/2; NaN where there is no cone or every direction is unstable")),
        "cone_hill": (("plane",), np.array([c.hill for c in cones]), _attrs(
            stiffness, "Hill's eigenvalue in the plane",
            "min over t of d(t)^T K d(t): the smallest eigenvalue of the symmetric part of cone_form")),
        "cone_form": (("plane", "basis", "basis_column"), np.stack([c.form for c in cones]), _attrs(
            stiffness, "K projected on the plane", "B = E^T K E, E = [e1 e2] (cone_basis): d(t)^T K d(t) = "
            "B11 cos^2 t + (B12 + B21) cos t sin t + B22 sin^2 t")),
        "cone_basis": (("plane", "basis", "grain", "component"),
                       np.stack([mode_components(packing, c.basis) for c in cones]), _attrs(
            per_dof, "orthonormal basis e1, e2 of the plane",
            "per grain and component (held grains 0); plane 'softest modes': the two smallest eigenvectors of "
            "K_sym; plane 'a,b': Gram-Schmidt of the directions a and b (e1 along a)")),
    }
    coords: dict[str, Any] = {"plane": ("plane", np.array([c.label for c in cones]), _attrs(
        "1", "plane of directions", "'softest modes', or the names of the two given directions spanning it"))}
    if directions is not None:
        data["direction_d2W"] = (("direction",), direction_work(result.tangent.K, directions), _attrs(
            stiffness, "second-order work of the direction",
            "d^T K d / d^T d over the free dofs (= d^T K_sym d / d^T d): negative where Hill's condition fails "
            "in that direction", source=directions.source))
        data["direction_vector"] = (("direction", "grain", "component"),
                                    mode_components(packing, directions.vectors), _attrs(
            per_dof, "the given direction", "as given (not normalised), per grain and component (held grains 0)"))
        coords["direction"] = ("direction", np.array(directions.names), _attrs(
            "1", "direction name", "the name column of the directions file, else the 0-based row"))
    return xr.Dataset({name: (dims, value, attrs) for name, (dims, value, attrs) in data.items()}, coords=coords)


def loop_variables(packing, result):
    """The grain loops as archive variables, the loops that lose Hill's condition first coming first."""
    import numpy as np
    import xarray as xr

    from ncstab.systems.mesostructures import grain_loops, loop_stiffness

    found = grain_loops(packing)
    hill = loop_stiffness(packing, found, result.tangent.blocks)
    order = np.argsort(hill, kind="stable")
    stiffness = "k_n (per mean grain diameter for x, y; times it for theta)"
    return xr.Dataset({
        "loop_hill": (("loop",), hill[order], _attrs(
            stiffness, "Hill's eigenvalue of the loop as a ring",
            "smallest eigenvalue of the ring's K_sym on its deformations (rigid motions excluded); ascending: "
            "the loops that lose Hill's condition first come first")),
        "loop_length": (("loop",), found.lengths[order].astype(np.int32), _attrs(
            "1", "grains in the loop", "number of grains (and contacts) of the loop")),
        "loop_grains": (("loop", "loop_member"), found.padded()[order].astype(np.int32), _attrs(
            "1", "grains of the loop", "0-based grain indices around the loop, -1 past its end")),
    })


def write_analysis(dataset, output: str | os.PathLike[str]) -> Path:
    """Write the archive atomically (a temporary file beside it, then renamed); errors as RunError (exit 3)."""
    from ncstab.studies.errors import OutputPathError, WriteError, write_error

    path = Path(output)
    if path.is_dir():
        raise OutputPathError(f"-o: {path} is a directory, not an archive path")
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        dataset.to_netcdf(temporary)
        os.replace(temporary, path)
    except (OSError, RuntimeError) as error:
        if temporary.exists():
            temporary.unlink()
        raise (write_error(error, path) or WriteError(f"could not write {path}: {error}")) from None
    return path


def command_analyse(args: argparse.Namespace) -> int:
    """``ncstab analyse``: write the archive and print its path and Hill's eigenvalue."""
    import numpy as np

    output = Path(args.output) if args.output else default_analysis_path(args.packing)
    try:
        dataset = analyse(args.packing, args.law, args.gamma, args.modes, output=output, loops=args.loops,
                          directions=args.directions, cone_planes=args.cone_plane or (),
                          keep_rattlers=args.keep_rattlers, friction=args.friction, probe=args.probe)
    except np.linalg.LinAlgError as error:
        from ncstab.studies.errors import RunError

        raise RunError(f"could not complete the analysis of {args.packing}: {error}", "nothing was written") from None
    except RuntimeError as error:
        from ncstab.studies.errors import RunError

        if "ARPACK" in str(error) or "singular" in str(error).lower() or "factor" in str(error).lower():
            raise RunError(f"could not complete the analysis of {args.packing}: {error}",
                           "nothing was written") from None
        raise
    print(f"{output}: hill = {float(dataset.hill):.6g}, negative eigenvalues = {int(dataset.negative_eigenvalues)}, "
          f"zero eigenvalues = {int(dataset.zero_eigenvalues)}, sign det K = {int(dataset.det_K_sign)}, "
          f"rattlers = {int(dataset.rattlers)}{' (kept)' if args.keep_rattlers else ''}")
    if "contact_state" in dataset:
        print(f"friction: {int(dataset.sliding_contacts)} sliding, {int(dataset.open_contacts)} open contacts; "
              f"hill = {float(dataset.hill):.6g} on the consistent branch, hill_sticking = "
              f"{float(dataset.hill_sticking):.6g}")
    if "probe_du" in dataset:
        print(f"probe: {int((dataset.probe_contact_state == 1).sum())} contacts slide, "
              f"{int((dataset.probe_contact_state == 2).sum())} open ({dataset.probe_dF.attrs['method']})")
    if "direction" in dataset.sizes:
        work = dataset.direction_d2W.values
        print(f"{len(work)} directions: d2W from {work.min():.6g} to {work.max():.6g}, "
              f"{int((work < 0).sum())} negative")
    for k, label in enumerate(dataset.plane.values):
        width, lower, upper = (float(dataset[name][k]) for name in ("cone_width", "cone_lower", "cone_upper"))
        cone = (f"width {width:.6g} rad, from {lower:.6g} to {upper:.6g} rad" if np.isfinite(lower) else
                "every direction" if width > 0 else "none: Hill's condition holds in the plane")
        plane = "the two softest modes" if label == "softest modes" else f"directions {label}"
        print(f"unstable cone in the plane of {plane}: {cone}")
    if args.loops and dataset.sizes.get("loop", 0):
        lost = int((dataset.loop_hill < 0).sum())
        print(f"{dataset.sizes['loop']} grain loops, {lost} without Hill's condition; lowest loop Hill eigenvalue "
              f"{float(dataset.loop_hill[0]):.6g}")
    return 0


def add_analyse_parser(sub, parents: list) -> None:
    """The ``analyse`` subcommand (standard library only at import)."""
    parser = sub.add_parser(
        "analyse", parents=parents,
        help="analyse a granular packing: K, Hill's eigenvalue, inertia, modes (docs/packings.md)",
        description="Assemble K of a packing file (NetCDF: grains, contacts, forces) with a contact law and "
        "write Hill's eigenvalue, the inertia of K_sym, the sign of det K, the smallest modes with each "
        "grain's participation, K itself, the exact unstable cone in the plane of the two softest modes and the "
        "second-order work of given directions. Exit code 2: invalid packing or option, nothing written; "
        "3: the analysis or the write could not complete.")
    parser.add_argument("packing", metavar="PACKING.nc", help="the packing file")
    parser.add_argument("--law", required=True, metavar="NAME", help="a contact law (ncstab laws lists them)")
    parser.add_argument("--gamma", type=float, default=1.0, metavar="G", help="k_t/k_n (default 1)")
    parser.add_argument("--modes", type=int, default=6, metavar="K",
                        help="how many of the smallest eigenpairs of K_sym to keep (default 6)")
    parser.add_argument("--loops", action="store_true",
                        help="also the grain loops with their own Hill eigenvalue as rings, lowest first")
    parser.add_argument("--directions", metavar="FILE",
                        help="directions whose second-order work d^T K d / d^T d is wanted: a CSV file with a "
                        "header of dof names (x<i>,y<i>,theta<i>; optional name column; unnamed dofs 0), one "
                        "direction a line, or a .npy array of rows over every free dof")
    parser.add_argument("--cone-plane", action="append", metavar="A,B",
                        help="also the exact unstable cone in the plane of two --directions (names or 0-based rows); "
                        "repeatable (the plane of the two softest modes of K_sym is always given)")
    parser.add_argument("--keep-rattlers", action="store_true",
                        help="keep the rattlers (free grains with fewer than two force-carrying contacts, found "
                        "recursively) in K; by default they are held and their contacts removed")
    parser.add_argument("--friction", type=float, metavar="MU",
                        help="Coulomb ratio mu of every contact (over the packing's 'friction'): contacts at the "
                        "limit slide or unload, open ones separate; Hill on the consistent branch (docs/friction.md)")
    parser.add_argument("--probe", metavar="DOF=VALUE[,DOF=VALUE...]",
                        help="the incremental response to these dof increments, every other free dof at constant "
                        "force, each contact on its consistent branch (docs/friction.md)")
    parser.add_argument("-o", "--output", metavar="OUT.nc",
                        help="archive path (default results/<packing stem>_analysis.nc)")
    parser.set_defaults(handler=command_analyse)
