"""The compiled (numba) stepper, ``PathOptions(backend="compiled")``.

The compiled stepper mirrors the numpy stepper (:class:`ncstab.paths.stepper.BatchStepper`)
step for step: same DOP853 tableau, step-size control, Newton projection,
Illinois event location, first-event tables, stops and failures.  It is checked

1. against the numpy stepper on the four smooth laws and several programmes
   (limit points, Hill loss, controllability loss, secondary contacts that
   stop or are only recorded, ``max_steps`` failures, many small steps);
2. for its fallback: what it does not cover runs the numpy code, bitwise;
3. against the seed directly: the McNamara limit point (maximum of Eq. 53) and
   a scipy integration of the Cundall--Strack rate form (Eq. 38);
4. for batch independence: a case alone and inside a batch give the same bits;
5. for option validation (``PathOptions.backend``, study files).

numba compiles each law's loop once per process (a few seconds per law), so
every path is followed once (module-level cache) and shared by the tests.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

pytest.importorskip("numba")

from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.paths.api import ParameterGrid, case_batch
from ncstab.paths.programme import parse_programme
from ncstab.systems.closed_forms import mcnamara_load_rotation

ALPHA0 = math.pi / 4
IGNORE = SystemSpec(secondary_contacts="ignore")
STOP = SystemSpec(secondary_contacts="stop")
ACTIVATE = SystemSpec(secondary_contacts="activate")
LAWS = ("cundall_strack", "weakly_hypoelastic", "mcnamara", "turco")

#: Backends compared.  Both take the same steps (same tableau, same
#: accept/reject decisions, same event brackets), so the differences start as
#: rounding (~1e-16: numpy's SIMD transcendental functions against numba's
#: libm) and are propagated over at most a few hundred steps of a stable
#: integration, through Newton projections and event location.  Values that
#: do not depend on where the path is sampled (located events, and stored
#: states moved to the same arclength, see SHIFT_TOL) agree to ~1e-14; rtol
#: 1e-9 / atol 1e-11 leave orders of magnitude of margin and still catch any
#: difference of algorithm (another step, bracket or Newton count moves values
#: by 1e-10 .. 1e-3).
RTOL = 1e-9
ATOL = 1e-11
#: The stored states themselves are sampled at arclengths s that differ by
#: more than rounding: the DOP853 error estimate is a difference of O(h)
#: stage sums that cancels to ~1e-12, so a rounding difference of the state
#: (1e-16) changes the error norm by ~1e-7 relative and the next step length
#: (h ~ err^(-1/8)) by ~1e-8 relative (measured on the preload programme:
#: steps identical to the bit for 110 steps, then relative step differences
#: of 1e-8 with states that differ by 1e-16).  The step-size controller does
#: not amplify these (h err^(-1/8) with err ~ h^8 is dead-beat), so the offsets
#: are a random walk of ~1e-10 per step: observed up to 6e-9 over 200 steps.
#: Each stored value is compared after moving it along the path by that
#: offset (first order, with the stored tangent where there is one, else
#: bounded by twice the local rate along the path).
SHIFT_TOL = 1e-7

UNIAXIAL = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.2}}]
PRELOAD = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.6}},
]
PRELOAD_STOP = [PRELOAD[0], {**PRELOAD[1], "stop_at": ["limit_point"]}]
#: Top and bottom grains touch where 2 l cos(alpha) = 1, i.e. (F2 = 0 held)
#: Delta_1 = cos(alpha0) - 1/2: from 0.325 (alpha0 = 0.6) to 0.04 (alpha0 = 1.0),
#: all before Delta_1 = 0.4.
CONTACT = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.4}}]

UNIAXIAL_GRID = {"gamma": list(np.linspace(0.1, 2.0, 4)), "alpha0": list(np.linspace(0.3, 1.2, 4))}
#: 64 cases; low gamma and high F2* reach limit points, Hill loss and
#: controllability loss (seed Fig. 9-11); gamma = 0.5, F2* = 0.75 is the
#: McNamara limit point of test 3; F2* = 0 makes the first stage zero-length.
#: Not gamma = 2: Turco at gamma = 2, F2* = 0 runs into a singular point near
#: Delta = (0.56, 0.35) where K21 and K22 vanish together (the tangent is
#: 0/0): the numpy stepper crawls through it with 29 rejected steps and step
#: lengths down to 3e-8; its error norms jump between 1e-7 and 1e6 from one
#: trial step to the next, so rounding is amplified without bound, and the
#: backends' step sequences part (28 against 29 rejections): two backends
#: cannot be compared step by step there.
PRELOAD_GRID = {
    "gamma": [0.1, 0.25, 0.4, 0.5, 0.75, 1.0, 1.5, 1.9],
    "alpha0": ALPHA0,
    "F2_lateral": [0.0, 0.2, 0.4, 0.5, 0.6, 0.7, 0.75, 0.8],
}
CONTACT_GRID = {"gamma": [0.5, 2.0], "alpha0": list(np.linspace(0.6, 1.0, 8))}

#: Long steps stored in pieces (see the "pieces_*" programmes).
PIECES = PathOptions(max_step=0.5, sample_step=0.02)

#: name -> (system, programme, parameters, options)
PROGRAMMES = {
    "uniaxial": (IGNORE, UNIAXIAL, UNIAXIAL_GRID, PathOptions()),
    "preload": (IGNORE, PRELOAD, PRELOAD_GRID, PathOptions()),
    "preload_stop_limit": (IGNORE, PRELOAD_STOP, PRELOAD_GRID, PathOptions()),
    "contact_stop": (STOP, CONTACT, CONTACT_GRID, PathOptions()),
    "contact_ignore": (IGNORE, CONTACT, CONTACT_GRID, PathOptions()),
    # The secondary springs switch on where a gap closes (a located switch that
    # cuts the step, may flip the orientation, and goes on on the other branch).
    "contact_activate": (ACTIVATE, CONTACT, {**CONTACT_GRID, "kappa": [1.0, 3.0]}, PathOptions()),
    "preload_activate": (
        ACTIVATE, PRELOAD, {"gamma": [0.1, 1.0, 2.0], "alpha0": [0.6, 0.8, 1.0], "F2_lateral": [0.0, 0.6]},
        # A McNamara case chatters at a contact (it opens and closes at every step):
        # bounded here, it fails with max_steps on both steppers.
        PathOptions(max_steps=400),
    ),
    # With steps of at most 0.02, n_steps of the uniaxial cases is 17..48: some fail, some finish.
    "max_steps": (IGNORE, UNIAXIAL, UNIAXIAL_GRID, PathOptions(max_steps=25, max_step=0.02)),
    # Delta_1 = 1.2 > cos(alpha0): the top grain would pass the chain's centre,
    # failed:left_domain.  Not gamma = 2: there McNamara and Turco go on to
    # l* -> 0 (K11 ~ 1e4), where the error norm amplifies rounding by ~1e6,
    # and fail with step_size_underflow after step sequences that rounding
    # decides (the "step_underflow" programme fails on purpose instead).
    "leave_domain": (
        IGNORE,
        [{"hold": {"F2": 0.0}, "drive": {"D1": "D1_end"}}],
        {"gamma": 0.5, "alpha0": [0.6, ALPHA0], "D1_end": [0.3, 1.2]},
        PathOptions(),
    ),
    # Steps of 0.1 that cannot shrink below 0.03: a rejected step near a limit
    # point or a sharp turn fails the case with step_size_underflow.
    "step_underflow": (
        IGNORE,
        PRELOAD,
        {"gamma": [0.1, 0.5, 1.0, 1.9], "alpha0": ALPHA0, "F2_lateral": [0.0, 0.4, 0.75]},
        PathOptions(initial_step=0.1, max_step=0.1, min_step=0.03),
    ),
    # 150 to 450 steps per case.
    "small_max_step": (
        IGNORE, UNIAXIAL, {"gamma": [0.1, 2.0], "alpha0": list(np.linspace(0.3, 1.2, 4))}, PathOptions(max_step=0.002)
    ),
    # Steps as long as the tolerance allows, cut into pieces of at most 0.02 on the
    # interpolant (PathOptions.sample_step): stored states and sign checks at the
    # pieces' ends, crossings located and steps cut inside a piece.
    "pieces_preload_stop_limit": (IGNORE, PRELOAD_STOP, PRELOAD_GRID, PIECES),
    "pieces_contact_activate": (ACTIVATE, CONTACT, {**CONTACT_GRID, "kappa": [1.0, 3.0]}, PIECES),
    "pieces_max_steps": (IGNORE, UNIAXIAL, UNIAXIAL_GRID, dataclasses.replace(PIECES, max_steps=3)),
}

_CACHE: dict[tuple[str, str, str], object] = {}


def compiled(options: PathOptions) -> PathOptions:
    return dataclasses.replace(options, backend="compiled")


def numpy_stepper(options: PathOptions) -> PathOptions:
    return dataclasses.replace(options, backend="numpy")


def run(law: str, name: str, backend: str):
    """The Path of ``law`` on programme ``name`` with ``backend`` (followed once per module)."""
    key = (law, name, backend)
    if key not in _CACHE:
        system, programme, parameters, options = PROGRAMMES[name]
        options = compiled(options) if backend == "compiled" else numpy_stepper(options)
        _CACHE[key] = follow(system, law, programme, parameters, options)
    return _CACHE[key]


@pytest.fixture(scope="module", autouse=True)
def _clear_cache():
    yield
    _CACHE.clear()


# --- comparison helpers ------------------------------------------------------------------------


def _excess(expected: np.ndarray, value: np.ndarray, allowed: np.ndarray) -> tuple[float, int]:
    """Largest |value - expected| / allowed over the finite entries, and its flat index."""
    diff = np.abs(value - expected)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(expected), diff / allowed, 0.0)
    if ratio.size == 0:
        return 0.0, -1
    ratio = np.where(np.isnan(ratio), 0.0, ratio)
    flat = int(np.argmax(ratio))
    return float(ratio.ravel()[flat]), flat


def _assert_same_places(where: str, a: np.ndarray, b: np.ndarray) -> None:
    """Same shape; integers, booleans and strings equal; NaN and inf in the same places."""
    assert a.shape == b.shape, f"{where}: shape {b.shape} != {a.shape}"
    if a.dtype.kind in "biuUSO" or b.dtype.kind in "biuUSO":
        np.testing.assert_array_equal(b, a, err_msg=where)
        return
    mismatch = np.flatnonzero((np.isnan(a) != np.isnan(b)).ravel() | (np.isinf(a) & (a != b)).ravel())
    assert mismatch.size == 0, (
        f"{where}: NaN/inf in different places, first at flat index {mismatch[0]} "
        f"(shape {a.shape}): numpy {a.ravel()[mismatch[0]]!r}, compiled {b.ravel()[mismatch[0]]!r}"
    )


class _Worst:
    """The worst comparison so far (for one message naming the key)."""

    def __init__(self, where: str) -> None:
        self.where, self.excess, self.text = where, 0.0, ""

    def update(self, key: str, expected: np.ndarray, value: np.ndarray, allowed: np.ndarray) -> None:
        excess, flat = _excess(expected, value, allowed)
        if excess > self.excess:
            e, v, tol = expected.ravel()[flat], value.ravel()[flat], np.broadcast_to(allowed, expected.shape).ravel()[flat]
            index = np.unravel_index(flat, expected.shape)
            self.excess = excess
            self.text = (
                f"{self.where}: worst key {key!r} at index {tuple(int(i) for i in index)}: expected {e!r}, "
                f"compiled {v!r} (|diff| = {abs(e - v):.3e}, allowed {tol:.3e}: {excess:.3g} times)"
            )

    def check(self) -> None:
        assert self.excess <= 1.0, self.text


def assert_tables_close(reference: dict, value: dict, where: str, rtol: float = RTOL, atol: float = ATOL) -> None:
    """Every array of ``value`` equals ``reference``: integers and booleans exactly,
    floats within rtol/atol with NaN (and inf) in the same places.  On failure the
    message names the worst key, its index and both values."""
    assert set(value) == set(reference), f"{where}: keys {sorted(value)} != {sorted(reference)}"
    worst = _Worst(where)
    for key, ref in reference.items():
        a, b = np.asarray(ref), np.asarray(value[key])
        _assert_same_places(f"{where}[{key!r}]", a, b)
        if a.dtype.kind == "f":
            worst.update(key, a, b, atol + rtol * np.abs(a))
    worst.check()


def _local_rate(values: np.ndarray, s: np.ndarray) -> np.ndarray:
    """|d values / ds| at each stored state, the larger of the two neighbouring
    secants (0 over zero-length intervals: a state stored twice at a stage entry)."""
    ds = np.diff(s, axis=1).reshape(s.shape[:1] + (s.shape[1] - 1,) + (1,) * (values.ndim - 2))
    dv = np.abs(np.diff(values, axis=1))
    with np.errstate(invalid="ignore", divide="ignore"):
        secant = np.where(ds > 0, dv / ds, 0.0)
    secant = np.where(np.isfinite(secant), secant, 0.0)
    pad = np.zeros(secant.shape[:1] + (1,) + secant.shape[2:])
    return np.maximum(np.concatenate([pad, secant], axis=1), np.concatenate([secant, pad], axis=1))


def assert_steps_on_the_same_path(reference: dict, value: dict, rtol: float = RTOL, atol: float = ATOL) -> None:
    """Stored states of two backends: the same points of the same path (see SHIFT_TOL).

    The arclengths differ by at most SHIFT_TOL; u, F, lambda and W, moved by
    the offset along the stored tangent (du, K du, dlambda, F . du / 2), equal
    within rtol/atol; every other float within rtol/atol plus twice the offset
    times the local rate along the path.
    """
    assert set(value) == set(reference), f"steps: keys {sorted(value)} != {sorted(reference)}"
    for key, ref in reference.items():
        _assert_same_places(f"steps[{key!r}]", np.asarray(ref), np.asarray(value[key]))
    s = reference["s"]
    shift = np.nan_to_num(value["s"] - s)
    worst_shift = float(np.max(np.abs(shift))) if shift.size else 0.0
    assert worst_shift <= SHIFT_TOL, (
        f"steps['s']: the backends sample the path {worst_shift:.3e} apart in arclength "
        f"(case, step {np.unravel_index(np.argmax(np.abs(shift)), shift.shape)})"
    )
    du, forces = reference["du"], reference["F"]
    tangent = {
        "u": du,
        "F": np.einsum("...ij,...j->...i", reference["K"], du),
        "lam": reference["dlam"],
        "work": 0.5 * np.sum(forces * du, axis=-1),
    }
    worst = _Worst("steps")
    for key, a in reference.items():
        b = value[key]
        if a.dtype.kind != "f" or key == "s":
            continue
        offset = shift.reshape(shift.shape + (1,) * (a.ndim - 2))
        if key in tangent:
            worst.update(key, a + offset * tangent[key], b, atol + rtol * np.abs(a))
        else:
            worst.update(key, a, b, atol + rtol * np.abs(a) + 2 * np.abs(offset) * _local_rate(a, s))
    worst.check()


def assert_results_close(reference, value) -> None:
    """Two CaseResults: same statuses, messages, step counts and counters; the
    stored states on the same path; events and cycle tables within rtol/atol."""
    np.testing.assert_array_equal(value.status, reference.status, err_msg="status")
    np.testing.assert_array_equal(value.message, reference.message, err_msg="message")
    np.testing.assert_array_equal(value.n_steps, reference.n_steps, err_msg="n_steps")
    assert set(value.counters) == set(reference.counters)
    for name in reference.counters:
        np.testing.assert_array_equal(value.counters[name], reference.counters[name], err_msg=f"counters[{name!r}]")
    assert_steps_on_the_same_path(reference.steps, value.steps)
    assert set(value.events) == set(reference.events)
    for name in reference.events:
        assert_tables_close(reference.events[name], value.events[name], f"events[{name!r}]")
    assert_tables_close(reference.cycles, value.cycles, "cycles")


def assert_results_identical(reference, value) -> None:
    """Two CaseResults bitwise equal (NaN equal to NaN)."""
    np.testing.assert_array_equal(value.status, reference.status, err_msg="status")
    np.testing.assert_array_equal(value.message, reference.message, err_msg="message")
    np.testing.assert_array_equal(value.n_steps, reference.n_steps, err_msg="n_steps")
    for group in ("counters", "steps", "cycles"):
        a, b = getattr(reference, group), getattr(value, group)
        assert set(b) == set(a), group
        for key in a:
            np.testing.assert_array_equal(b[key], a[key], err_msg=f"{group}[{key!r}]")
    assert set(value.events) == set(reference.events)
    for name, table in reference.events.items():
        assert set(value.events[name]) == set(table)
        for key in table:
            np.testing.assert_array_equal(value.events[name][key], table[key], err_msg=f"events[{name!r}][{key!r}]")


def batch_and_programme(spec: SystemSpec, law: str, programme, parameters):
    """The engine's CaseBatch and parsed programme, as ``follow`` builds them."""
    definition = spec.definition
    parsed = parse_programme(programme, definition.dofs, definition.forces, definition.load_parameter)
    grid = ParameterGrid.from_mapping(parameters)
    return case_batch(law, spec, grid.case_values(), grid.size), parsed


def one_case(result, k: int) -> dict:
    """Case ``k`` of a CaseResult, states cut to its n_steps."""
    n = int(result.n_steps[k])
    return {
        "status": result.status[k],
        "message": result.message[k],
        "n_steps": result.n_steps[k],
        **{f"counter_{name}": values[k] for name, values in result.counters.items()},
        **{f"step_{key}": values[k, :n] for key, values in result.steps.items()},
        **{f"{name}_{key}": values[k] for name, table in result.events.items() for key, values in table.items()},
    }


# --- 1. the compiled stepper takes the numpy stepper's steps -----------------------------------


def _check_reference(name: str, law: str, path) -> None:
    """The numpy reference does what the programme is meant to exercise."""
    result = path.results[0]
    status = path.status.ravel()
    found = {event: int(table["found"].sum()) for event, table in result.events.items()}
    if name == "preload" and law != "turco":
        assert found["limit_point"] >= 2 and found["hill_loss"] >= 2, found
        if law != "mcnamara":
            assert found["controllability_loss"] >= 1, found
    if name == "preload_stop_limit" and law != "turco":
        assert (status == "stopped:limit_point").sum() >= 2, status
        assert (status == "finished").sum() >= 10, status
    if name in ("contact_stop", "contact_ignore"):
        assert found["secondary_contact"] == status.size, found
        expected = "stopped:secondary_contact" if name == "contact_stop" else "finished"
        assert np.all(status == expected), status
    if name == "contact_activate":
        assert found["secondary_contact"] == status.size, found
        assert np.all(status == "finished"), status
    if name == "preload_activate":
        assert found["secondary_contact"] >= 4, found
        assert (status == "finished").sum() >= status.size // 2, status  # alpha0 = 1 leaves the domain
    if name == "max_steps":
        assert 0 < (status == "failed:max_steps").sum() < status.size, status
        assert (status == "finished").sum() > 0, status
    if name == "leave_domain":
        assert status.tolist() == ["finished", "failed:left_domain"] * 2, status
    if name == "step_underflow":
        assert (status == "finished").sum() >= 10, status
        if law != "weakly_hypoelastic":
            assert (status == "failed:step_size_underflow").sum() >= 1, status
    if name == "small_max_step":
        assert result.n_steps.min() >= 100, result.n_steps
    if name.startswith("pieces_"):
        # several stored states per accepted step (the pieces), never two further apart than 0.02
        assert (result.n_steps > result.counters["accepted"] + 2).any(), (result.n_steps, result.counters["accepted"])
        gaps = np.diff(result.steps["s"], axis=1)
        assert np.nanmax(gaps) <= 0.02 * (1 + 1e-12), np.nanmax(gaps)
    if name == "pieces_preload_stop_limit" and law != "turco":
        assert (status == "stopped:limit_point").sum() >= 2, status
    if name == "pieces_contact_activate":
        assert found["secondary_contact"] == status.size, found
        assert np.all(status == "finished"), status
    if name == "pieces_max_steps":
        # a step counts once, whatever its pieces: failed cases took exactly 3
        failed = status == "failed:max_steps"
        assert 0 < failed.sum() < status.size, status
        assert np.all(result.counters["accepted"][failed] == 3), result.counters["accepted"]
        assert (result.n_steps[failed] > 4).all(), result.n_steps


@pytest.mark.parametrize("name", list(PROGRAMMES))
@pytest.mark.parametrize("law", LAWS)
def test_compiled_backend_takes_the_numpy_steps(law, name):
    from ncstab.paths.compiled import unsupported_reason

    system, programme, parameters, _ = PROGRAMMES[name]
    batch, parsed = batch_and_programme(system, law, programme, parameters)
    # Otherwise the comparison would be the numpy stepper against itself.
    assert unsupported_reason(batch, parsed) is None
    reference = run(law, name, "numpy")
    _check_reference(name, law, reference)
    path = run(law, name, "compiled")
    assert path.options.backend == "compiled"
    assert_results_close(reference.results[0], path.results[0])


def test_the_dataset_records_which_engine_ran_each_law():
    """``engine`` attribute: the compiled stepper with numba's version where it ran (the
    pure-shear limit too, on the general models' loop), the numpy stepper where asked for."""
    import numba

    laws = ["cundall_strack", "mcnamara+no_tension"]
    grid = {"gamma": [0.5, 2.0], "alpha0": ALPHA0}
    path = follow(IGNORE, laws, UNIAXIAL, grid, compiled(PathOptions()))
    parts = dict(part.split(": ", 1) for part in path.to_dataset().attrs["engine"].split("; "))
    assert list(parts) == laws
    for law in laws:
        assert parts[law] == f"compiled stepper (numba {numba.__version__}), numpy stepper for what it leaves"
    rigid = SystemSpec(normal="rigid", secondary_contacts="ignore")
    pure_shear = [{"hold": {"F2": 0.0}, "drive": {"F1": 1.0}}]
    on_rigid = follow(rigid, ["mcnamara", "cundall_strack"], pure_shear, {"alpha0": [0.7, ALPHA0]},
                      compiled(PathOptions()))
    parts = dict(part.split(": ", 1) for part in on_rigid.to_dataset().attrs["engine"].split("; "))
    for law in ("mcnamara", "cundall_strack"):
        assert parts[law] == (f"compiled stepper (numba {numba.__version__}) with the pure-shear limit's kernel, "
                              "numpy stepper for what it leaves"), parts[law]
    assert follow(IGNORE, laws[0], UNIAXIAL, grid, numpy_stepper(PathOptions())).to_dataset().attrs[
        "engine"
    ] == "cundall_strack: numpy stepper"


#: Extension opens the normal contact of a no_tension law (delta < 0: no normal
#: spring), compression closes it again: two located switches per case.
TENSION = [{"hold": {"F2": 0.0}, "drive": {"D1": -0.1}}, {"hold": {"F2": 0.0}, "drive": {"D1": 0.1}}]
TENSION_GRID = {"gamma": [0.5, 1.0, 2.0], "alpha0": [0.6, ALPHA0, 1.0]}


@pytest.mark.parametrize("law", LAWS)
def test_a_no_tension_law_opens_and_closes_its_contact_as_on_the_numpy_stepper(law):
    """The compiled stepper follows the open branch where the normal contact's bit is set
    and switches at the located zero of the overlap, as the numpy stepper does: same
    statuses and steps, states within RTOL/ATOL (as for the smooth laws above); to the
    bit for Cundall--Strack, whose kernels read no alpha."""
    from ncstab.paths.compiled import unsupported_reason

    law = f"{law}+no_tension"
    batch, parsed = batch_and_programme(IGNORE, law, TENSION, TENSION_GRID)
    assert unsupported_reason(batch, parsed) is None
    reference = follow(IGNORE, law, TENSION, TENSION_GRID, numpy_stepper(PathOptions()))
    path = follow(IGNORE, law, TENSION, TENSION_GRID, PathOptions())
    assert path.results[0].engine.startswith("compiled stepper")
    assert reference.succeeded.all(), reference.message
    normal = reference.results[0].steps["N"].reshape(len(reference.status.ravel()), -1)
    # Every case followed both branches: open (no normal force) and closed again (N > 0).
    assert np.all(np.any(normal == 0, axis=1) & np.any(normal > 0, axis=1)), normal
    assert_results_close(reference.results[0], path.results[0])
    if law == "cundall_strack+no_tension":
        assert_results_identical(reference.results[0], path.results[0])


def test_unsupported_reason_is_none_for_a_smooth_linear_programme():
    from ncstab.paths.compiled import unsupported_reason

    for law in LAWS:
        batch, parsed = batch_and_programme(IGNORE, law, PRELOAD_STOP, PRELOAD_GRID)
        assert unsupported_reason(batch, parsed) is None, law


def test_without_numba_the_compiled_backend_asks_for_the_extra(monkeypatch):
    import ncstab.paths.compiled as compiled_module

    monkeypatch.setattr(compiled_module, "NUMBA_AVAILABLE", False)
    with pytest.raises(RuntimeError, match=r"needs numba, a dependency of ncstab: pip install numba"):
        follow(IGNORE, "mcnamara", UNIAXIAL, {"gamma": 0.5, "alpha0": ALPHA0}, compiled(PathOptions()))


# --- 3. the compiled stepper against the seed, directly ----------------------------------------


def test_compiled_mcnamara_limit_point_is_the_maximum_of_eq53():
    path = run("mcnamara", "preload_stop_limit", "compiled")
    result, k = path.case("mcnamara", gamma=0.5, F2_lateral=0.75)
    assert result.status[k] == "stopped:limit_point"
    limit = {key: values[k] for key, values in result.events["limit_point"].items()}
    assert limit["found"] and limit["stage"] == 1
    assert limit["s_upper"] - limit["s_lower"] <= 1e-10  # event_tol
    # The maximum of seed Eq. (53) (compression branch) at F2* = 0.75.
    alpha = np.linspace(0.5, 1.4, 20001)
    values = mcnamara_load_rotation(alpha, 0.5, ALPHA0, F2=0.75, branch=-1)
    best = int(np.nanargmax(values))
    found = minimize_scalar(
        lambda a: -mcnamara_load_rotation(a, 0.5, ALPHA0, F2=0.75, branch=-1),
        bounds=(alpha[best - 1], alpha[best + 1]),
        method="bounded",
        options={"xatol": 1e-12},
    )
    f1_max = -found.fun
    assert abs(f1_max - 1.428769555) < 1e-9
    # dF1/dalpha = 0 at the maximum: the 1e-10 bracket in arclength costs ~1e-20
    # in F1; the stored F is on the equilibrium manifold to newton_tol 1e-12.
    assert abs(limit["F"][0] - f1_max) < 1e-9
    assert abs(limit["F"][1] - 0.75) < 1e-10
    assert abs(limit["alpha"] - found.x) < 1e-5  # alpha is only O(sqrt(F1 error)) at a maximum
    # The stop state is the last stored state.
    n = result.n_steps[k]
    assert result.steps["s"][k, n - 1] == limit["s"]


def cundall_strack_rhs(gamma: float, alpha0: float):
    """dy/dD1 for y = (D2, F1) with F2 = 0 held, seed Eq. (38) and (35)
    (as benchmarks/bench_sweep_cundall_strack.py's baseline_rhs)."""
    c0, s0 = math.cos(alpha0), math.sin(alpha0)

    def rhs(d1: float, y: np.ndarray) -> list[float]:
        d2, f1 = y
        vertical, horizontal = c0 - d1, s0 - d2
        length = math.hypot(vertical, horizontal)
        c, s = vertical / length, horizontal / length
        k11 = 2 * c * c + 2 * gamma * s * s
        k12 = 2 * (1 - gamma) * c * s
        k21 = 2 * (1 - gamma) * c * s + s / length * f1
        k22 = 2 * s * s + 2 * gamma * c * c - c / length * f1
        dd2 = -k21 / k22
        return [dd2, k11 + k12 * dd2]

    return rhs


def test_compiled_cundall_strack_matches_solve_ivp_of_eq38():
    path = run("cundall_strack", "uniaxial", "compiled")
    result = path.results[0]
    values = path.grid.case_values()
    assert np.all(result.status == "finished")
    assert not result.events["turning_point"]["found"].any()  # Delta_1 monotone: the ivp's variable
    for k in range(result.status.size):
        n = int(result.n_steps[k])
        u, forces = result.steps["u"][k, :n], result.steps["F"][k, :n]
        gamma, alpha0 = values["gamma"][k], values["alpha0"][k]
        reference = solve_ivp(
            cundall_strack_rhs(gamma, alpha0), (0.0, 0.2), [0.0, 0.0],
            method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True,
        )
        assert reference.success
        expected = reference.sol(u[:, 0])
        # Cundall--Strack is not projected (T is an internal variable): the
        # engine's local rtol 1e-10 over <= 50 steps gives global errors
        # well below 1e-8 (observed ~1e-11 on the numpy stepper).
        np.testing.assert_allclose(u[:, 1], expected[0], rtol=0, atol=1e-8, err_msg=f"case {k}")
        np.testing.assert_allclose(forces[:, 0], expected[1], rtol=0, atol=1e-8, err_msg=f"case {k}")
        np.testing.assert_allclose(forces[:, 1], 0.0, rtol=0, atol=1e-8, err_msg=f"case {k}")
        assert abs(u[-1, 0] - 0.2) < 1e-9


# --- 4. a case's result does not depend on its batch --------------------------------------------


@pytest.mark.parametrize("law", ["mcnamara", "cundall_strack"])
@pytest.mark.parametrize(("gamma", "f2"), [(0.5, 0.75), (1.9, 0.0), (0.1, 0.8)])
def test_compiled_case_alone_equals_the_case_in_a_batch_of_64(law, gamma, f2):
    batch_path = run(law, "preload", "compiled")
    assert batch_path.results[0].status.size == 64
    result, k = batch_path.case(law, gamma=gamma, F2_lateral=f2)
    alone = follow(
        IGNORE, law, PRELOAD, {"gamma": gamma, "alpha0": ALPHA0, "F2_lateral": f2}, compiled(PathOptions())
    )
    expected, got = one_case(result, k), one_case(alone.results[0], 0)
    assert set(got) == set(expected)
    for key in expected:
        np.testing.assert_array_equal(got[key], expected[key], err_msg=key)


# --- 5. options ---------------------------------------------------------------------------------


def test_backend_option_is_validated():
    assert PathOptions().backend == "auto"
    assert PathOptions(backend="compiled").backend == "compiled"
    with pytest.raises(ValueError, match="backend"):
        PathOptions(backend="fortran")
    with pytest.raises(ValueError, match=r"PathOptions\.backend"):
        PathOptions(backend=3)


STUDY = """\
[study]
name = "compiled"
[laws]
names = ["mcnamara"]
[parameters]
gamma = 0.5
[[loading]]
hold = { F2 = 0.0 }
drive = { D1 = 0.05 }
"""


def test_a_study_file_may_choose_the_compiled_backend():
    from ncstab.studies import parse_study

    study = parse_study(STUDY + '[options]\nbackend = "compiled"\n', "study.toml")
    assert study.options.backend == "compiled"
    assert parse_study(STUDY + '[options]\nbackend = "numpy"\n').options.backend == "numpy"
    assert parse_study(STUDY).options.backend == "auto"
    assert parse_study(STUDY + '[options]\nbackend = "auto"\n').options.backend == "auto"


@pytest.mark.parametrize("value", ["3", '"x"', '"fortran"', "true"])
def test_a_study_file_with_a_bad_backend_is_rejected_naming_the_field(value):
    from ncstab.studies import StudyFileError, parse_study

    with pytest.raises(StudyFileError) as info:
        parse_study(STUDY + f"[options]\nbackend = {value}\n", "study.toml")
    assert "options.backend" in info.value.fields, info.value.errors


def test_the_compiled_loop_is_generated_once_and_cached_on_disk():
    """The loop of a form (rate or total) and each law's kernel are modules in the cache
    directory, with numba's cache beside them."""
    from ncstab.cache import cache_directory

    follow(SystemSpec(secondary_contacts="ignore"), "cundall_strack", [{"hold": {"F2": 0.0}, "drive": {"D1": 0.01}}],
           {"gamma": 1.0}, PathOptions(backend="compiled"))
    directory = cache_directory("compiled")
    modules = sorted(directory.glob("ncstab_stage_loop_*.py"))
    assert modules, directory
    loaded = [sys.modules[m.stem] for m in modules if m.stem in sys.modules]
    assert any(module.rate_form for module in loaded)  # Cundall-Strack's form
    kernels = [sys.modules[m.stem] for m in directory.glob("ncstab_law_*.py") if m.stem in sys.modules]
    assert kernels and all(hasattr(module, "LAW") for module in kernels), kernels
    assert len(modules) <= 2  # one loop per form (rate, total), whatever the laws
    index = {p.name.split(".")[1].split("-")[0] for p in (directory / "__pycache__").glob("*.nbi")}
    assert {"run_cases", "start", "LAW"} <= index, index


def test_a_cache_directory_that_cannot_be_written_falls_back_to_a_temporary_one(tmp_path, monkeypatch):
    from ncstab.paths import compiled_source

    blocked = tmp_path / "file"
    blocked.write_text("not a directory")
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(blocked / "cache"))  # mkdir fails: a file is in the way
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    source = '"""A generated module."""\nVALUE = 42\n'
    module = compiled_source.load_module(source, "ncstab_test")
    assert module.VALUE == 42
    assert Path(module.__file__).parent.parent == tmp_path / "tmp"
    assert compiled_source.load_module(source, "ncstab_test") is module  # loaded once per process


def test_a_long_stage_grows_the_recorder_once_not_at_every_doubling(monkeypatch):
    """Paused cases (recorder full) get room for the rest of their stage at once, estimated
    from their progress in lambda: 200 states per case take one growth beyond the first
    call's, where doubling from 8 would take five.  The states are those of one case alone."""
    from ncstab.paths.recorder import Recorder

    growths = []
    reserve = Recorder.reserve

    def counting(self, needed, **kwargs):
        before = self.capacity
        reserve(self, needed, **kwargs)
        if self.capacity > before:
            growths.append(self.capacity)

    monkeypatch.setattr(Recorder, "reserve", counting)
    programme = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.2}}]
    options = PathOptions(max_step=0.002)
    grid = {"gamma": [0.5, 1.0, 1.5]}
    path = follow(IGNORE, "cundall_strack", programme, grid, options)
    steps = int(path.results[0].n_steps.max())
    assert steps > 100
    assert len(growths) <= 2, growths  # the first call's pause, then the estimate
    assert growths[-1] >= steps
    monkeypatch.setattr(Recorder, "reserve", reserve)
    alone = follow(IGNORE, "cundall_strack", programme, {"gamma": 1.0}, options).to_dataset()
    in_sweep = path.to_dataset()["u"].sel(gamma=1.0).values[0, : alone.sizes["step"]]
    np.testing.assert_array_equal(alone["u"].values[0], in_sweep)


#: Turco, gamma = 2, F2* = 0 (the golden reduced stability diagram, tests/test_golden.py):
#: at D1* = 0.5607 the path meets a singular point of its mixed control, where the
#: cofactor tangent passes through zero and changes sign while the path goes on.
SINGULAR = [{"hold": {"F1": 0.0}, "drive": {"F2": 0.0}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}]


def test_the_tangent_is_oriented_by_continuity_across_a_singular_point_as_on_the_numpy_stepper():
    """Each tangent continues the motion at the start of its step (tangent_field
    ._continue_reference): across the singular point both steppers go straight on and
    give the same case to the bit.  Without the continuity the compiled stepper crept
    through it in smaller steps (the golden archive's 108 steps)."""
    spec = SystemSpec(secondary_contacts="ignore")
    parameters = {"gamma": [2.0]}
    options = PathOptions(max_step=0.05)
    reference = follow(spec, "turco", SINGULAR, parameters, numpy_stepper(options))
    path = follow(spec, "turco", SINGULAR, parameters, compiled(options))
    assert path.results[0].engine.startswith("compiled stepper")
    assert reference.succeeded.all(), reference.message
    d1 = reference.results[0].steps["u"][0, : int(reference.results[0].n_steps[0]), 0]
    assert d1.max() == pytest.approx(0.6, abs=1e-12) and np.any(np.abs(d1 - 0.5607) < 0.05)  # it got across
    assert_results_identical(reference.results[0], path.results[0])


#: Green's paradox on the compiled stepper: a linear stage, then two clockwise turns
#: of a circle off the current state (the turn's end and the stage's target located
#: as crossings), then one counterclockwise turn, secondary contacts switching
#: where the circle meets them.
CYCLES = [
    {"hold": {"F2": 0.0}, "drive": {"D1": 0.05}},
    {"cycle": {"center": [0.03, 0.0], "turns": 2, "direction": -1}},
    {"cycle": {"center": [0.05, 0.04], "turns": 1, "direction": 1}},
]


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("spec", [IGNORE, ACTIVATE], ids=["ignore", "activate"])
def test_cycle_stages_run_compiled_as_on_the_numpy_stepper(law, spec):
    """Cycle stages on the compiled stepper: the control path on the circle (projection,
    tangent, event location), each turn closed where its crossing cuts the step and
    its work, force gap and drift of T tabled -- the numpy stepper's result to the bit."""
    from ncstab.paths.compiled import unsupported_reason

    parameters = {"gamma": [0.5, 2.0], "alpha0": [0.6, ALPHA0]}
    batch, parsed = batch_and_programme(spec, law, CYCLES, parameters)
    assert unsupported_reason(batch, parsed) is None
    options = PathOptions(max_step=0.2)
    reference = follow(spec, law, CYCLES, parameters, numpy_stepper(options))
    path = follow(spec, law, CYCLES, parameters, options)
    assert path.results[0].engine.startswith("compiled stepper")
    assert reference.succeeded.all(), reference.message
    work = reference.results[0].cycles["work"]
    assert work.shape == (4, 3) and np.isfinite(work).all()  # every turn closed and tabled
    if spec is ACTIVATE:  # the second circle reaches the left-right contact for alpha0 = 0.6
        assert reference.results[0].events["secondary_contact"]["found"].any()
    assert_results_identical(reference.results[0], path.results[0])
