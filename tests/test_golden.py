"""Golden archives: today's studies give the archives written before the general model.

``tests/golden/*.nc`` were written by ``tests/golden/make_golden.py`` from the
main branch before the model layer became general (issue 13).  Rerunning each
study with the engine options of the time (every step stored once, ``max_step``
0.02 unless the study sets it: :func:`golden_options`) must give an identical
Dataset (``xarray.testing.assert_identical``: values bit for bit, dimensions,
coordinates and attributes), the ``created`` time stamp aside.  Any difference
is a bug, or a decision documented in CHANGELOG.md together with new golden
files.  With today's defaults (steps as long as the tolerance allows, stored in
pieces of ``sample_step``) each study must give the golden's statuses, events,
cycle work and end states to the integration's tolerance.
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import turco_bifurcation  # tests/turco_bifurcation.py
from ncstab.paths.programme import EVENTS
from ncstab.studies import Study, load_study, open_study, run_study
from ncstab.studies.archive import normalise_dataset

GOLDEN = Path(__file__).parent / "golden"
STUDIES = sorted((GOLDEN / "studies").glob("*.toml"))
#: Attributes that legitimately differ from run to run.
VOLATILE = ("created",)

#: Documented differences (CHANGELOG, general models): cases whose stored states
#: differ from the golden archive, with why.  Each is compared on its end state
#: (to ``END_STATE_TOL``) instead of bit for bit; every other case of the study is
#: identical.
#:
#: * Turco, gamma = 2, F2* = 0 (stability diagram): at D1* = 0.5607 the path meets
#:   a singular point of its mixed control (the cofactor tangent vanishes: F1*
#:   stays at 2 sqrt 2 while D1* moves on, det K = 0 along the way).  The engine
#:   before the general model crept through it with some thirty tiny steps (the
#:   tangent reversing in every trial step); the engine now keeps the direction of
#:   motion across it (the tangent oriented by continuity) and crosses in a few
#:   steps.  Both reached the same end state, on the crossing branch of neutral
#:   equilibria (F1* = 2 sqrt 2 all along it, D2* = 0.548 at D1* = 0.6).
#:   The point is a simple bifurcation point (tests/test_bifurcations.py); since over
#:   steps (CHANGELOG, 2026-12-02: ncstab.paths.over_steps) the path goes on along the
#:   branch it was on, whatever the steps, so its end state is the closed-form
#:   equilibrium on that branch (tests/turco_bifurcation.py, D2* = 0.405), not the
#:   golden's: ``END_STATES`` gives it.
KNOWN_DIFFERENCES = {
    "stability_diagram_reduced": [{"law": "turco", "gamma": 2.0, "F2_lateral": 0.0}],
}
#: The end states of known differences that are no longer the golden's: (study, case) ->
#: a function giving (u, F) at the end.
END_STATES = {
    ("stability_diagram_reduced", "turco"): lambda: turco_bifurcation.equilibrium(0.6, 0.40),
}
#: Every law of every study runs on the compiled stepper, the only engine.  The
#: goldens were made by the numpy stepper, since retired.  The reduced diamond's loop
#: (linear and cycle stages of the deformable reduced diamond, secondary contacts
#: ignored or activated, no_tension laws too) reproduces them bit for bit; on the
#: known difference above it orients the tangent by continuity and steps over the
#: point (91 stored states, against the golden's 108).  The pure-shear limit runs on
#: the general models' loop (ncstab.paths.compiled_rigid), whose sums are in another
#: order than the numpy stepper's: its studies are compared to ROUNDING_TOL.
ON_THE_GENERAL_LOOP = {"fig14_15_pure_shear_blocking"}
#: The pure-shear limit on the general loop against its golden (made by the retired
#: numpy stepper): the same steps, events and statuses, the numbers to 1e-12 (the issue's
#: bound; measured 2e-15 on the ends and events of every law).
ROUNDING_TOL = 1e-12
#: The end states of a known difference agree to rounding (both paths are projected
#: onto equilibrium to newton_tol = 1e-12).
END_STATE_TOL = 1e-12
#: An end state against its closed form (``END_STATES``): projected onto equilibrium to
#: newton_tol = 1e-12 in F, so u to 1e-12 |K^-1| (|K^-1| < 1 there); 1e-10 leaves room.
CLOSED_FORM_END_TOL = 1e-10


def _documented_changes(golden: xr.Dataset, computed: xr.Dataset) -> xr.Dataset:
    """The golden archive with the changes CHANGELOG.md documents applied (general models):

    * the ``dof``, ``i`` and ``j`` coordinates hold the system's dof names
      (``D1``, ``D2``) instead of 1, 2, with a ``force`` coordinate (``F1``,
      ``F2``) along ``dof``;
    * the ``law`` coordinate is an "interaction law" (springs have laws too);
    * the attribute ``system_settings`` states the system's structural
      settings (``reduction=symmetric``), and ``stage_drives`` what each
      loading stage drives (the figures' axes);
    * the attribute ``engine`` says which stepper ran each law (issue 14).
      The goldens were made by the numpy stepper, since retired; the compiled
      stepper, now the only engine, gives them bit for bit on the reduced
      diamond's loop, and to :data:`ROUNDING_TOL` on the general models' loop
      (:data:`ON_THE_GENERAL_LOOP`).

    and, in the variables (issue 16, dynamic stability):

    * the events ``bifurcation`` and ``divergence`` have their tables
      (``bifurcation_s``...): never found in these studies but at the known
      difference below (the reduced diamond got its branch test on 2026-12-02);
    * ``flutter`` is the growth rate max Re s of the linearised dynamics
      I s^2 + K (grains of equal mass), not the discriminant of K: checked
      here against an independent eigenvalue computation on the golden K, and
      it is positive exactly where K has complex eigenvalues (the golden's
      discriminant < 0) or a negative one;
    * ``flutter_onset_frequency`` is added (NaN: no flutter onset in these studies).

    and (issue 19, CF details): the numeric coordinates ``step`` and ``cycle``
    have ``units = "1"``, and the archive has CF's ``history`` attribute.  (Integer data variables are written with a
    ``_FillValue``, -1; it is an encoding of the file, not in the Dataset.)
    """
    names = computed["dof"].values
    changed = golden.assign_coords(
        dof=("dof", names, computed["dof"].attrs),
        i=("i", names, computed["i"].attrs),
        j=("j", names, computed["j"].attrs),
        force=("dof", computed["force"].values, computed["force"].attrs),
    )
    changed["law"].attrs = dict(computed["law"].attrs)
    changed.attrs["system_settings"] = computed.attrs["system_settings"]
    changed.attrs["stage_drives"] = computed.attrs["stage_drives"]
    laws = [str(law) for law in computed["law"].values]
    engines = dict(part.split(": ", 1) for part in computed.attrs["engine"].split("; "))
    assert list(engines) == laws
    for law, engine in engines.items():
        assert engine.startswith("compiled stepper (numba "), (law, engine)
    changed.attrs["engine"] = computed.attrs["engine"]
    assert "history" not in golden.attrs
    assert computed.attrs["history"] == f"ncstab {computed.attrs['ncstab_version']}: the study's cases followed along its loading programme"
    changed.attrs["history"] = computed.attrs["history"]
    known = xr.zeros_like(computed["n_steps"], dtype=bool)
    for case in KNOWN_DIFFERENCES.get(computed.attrs["study_name"], []):
        one = xr.ones_like(known)
        for key, value in case.items():
            one = one & (computed[key] == value)
        known = known | one
    for name in computed.data_vars:
        if name.startswith(("bifurcation_", "divergence_")) or name == "flutter_onset_frequency":
            found = computed[name]
            outside = found.where(~known)  # (a known difference is checked on its own)
            assert bool(np.all(outside.isnull() | (outside == -1))), f"{name} found on the reduced diamond"
            changed[name] = found
    changed["flutter"] = _checked_flutter(golden, computed)
    for name in ("step", "cycle"):
        if name in golden.coords:
            assert "units" not in golden[name].attrs
            changed[name].attrs = {"units": "1", **golden[name].attrs}
    return changed


def _checked_flutter(golden: xr.Dataset, computed: xr.Dataset) -> xr.DataArray:
    """The computed ``flutter`` (max Re s of I s^2 + K), once checked against numpy's
    eigenvalues of K and against the golden discriminant's sign (complex
    eigenvalues of K: s off the imaginary axis).  s^2 = -lambda(K) is compared
    (rtol 1e-10, atol 1e-13): near a zero eigenvalue of K the square root
    amplifies rounding (ds = dlambda / 2 sqrt(lambda), 1e-9 at lambda ~ 1e-12)."""
    K = computed["K"].values
    finite = np.isfinite(K).all(axis=(-2, -1))
    expected = np.full(K.shape[:-2], np.nan)
    lam = np.linalg.eigvals(K[finite]).astype(complex)
    expected[finite] = np.abs(np.sqrt(-lam).real).max(axis=-1)
    new = computed["flutter"].values
    np.testing.assert_allclose(new**2, expected**2, rtol=1e-10, atol=1e-13)
    if golden["flutter"].shape == computed["flutter"].shape:  # (a known difference changes the steps)
        complex_pair = golden["flutter"].values < -1e-12
        assert np.all(new[complex_pair] > 0)
    return computed["flutter"]


def _without_volatile(dataset: xr.Dataset) -> xr.Dataset:
    dataset = dataset.copy()
    for name in VOLATILE:
        dataset.attrs.pop(name, None)
    return dataset


def golden_options(study_file: Path, backend: str = "auto") -> Study:
    """The study with the engine options its golden archive was written with: every
    step stored once (``sample_step`` not set) and ``max_step`` 0.02 unless the study
    sets it (the defaults before ``sample_step``, CHANGELOG); the loop run as ``backend``
    says."""
    study = load_study(study_file)
    own = tomllib.loads(study_file.read_text(encoding="utf-8")).get("options", {})
    max_step = study.options.max_step if "max_step" in own else 0.02
    options = dataclasses.replace(study.options, sample_step=None, max_step=max_step, backend=backend)
    return dataclasses.replace(study, options=options)


#: The loop as machine code (``auto``: the session's warm-up compiled it) and as plain
#: Python (ncstab.plain_python): the same text, so the same golden archive, bit for bit.
BACKENDS = ("auto", "python")


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("study_file", STUDIES, ids=[p.stem for p in STUDIES])
def test_a_study_gives_its_golden_archive(study_file: Path, backend: str) -> None:
    study = golden_options(study_file, backend)
    golden = open_study(GOLDEN / f"{study.name}.nc")
    computed = normalise_dataset(run_study(study))
    golden = _documented_changes(golden, computed)
    for case in KNOWN_DIFFERENCES.get(study.name, []):
        old, new = golden.sel(case), computed.sel(case)
        end_state = END_STATES.get((study.name, case["law"]))
        expected = end_state() if end_state else None
        for k, name in enumerate(("u", "F")):
            last_old = expected[k] if expected else old[name].isel(step=int(old["n_steps"]) - 1).values
            last_new = new[name].isel(step=int(new["n_steps"]) - 1).values
            np.testing.assert_allclose(last_new, last_old, rtol=0, atol=CLOSED_FORM_END_TOL if expected else END_STATE_TOL)
        assert str(new["status"].values) == str(old["status"].values)
        golden, computed = _drop_case(golden, case), _drop_case(computed, case)
    computed, golden = _without_volatile(computed), _without_volatile(golden)
    if study.name in ON_THE_GENERAL_LOOP:  # the numbers to rounding, everything else identical
        for name, variable in golden.data_vars.items():
            if variable.dtype.kind == "f":
                np.testing.assert_allclose(computed[name].values, variable.values, rtol=0, atol=ROUNDING_TOL,
                                           err_msg=name)
                computed[name] = computed[name].copy(data=variable.values)  # (its attributes still compared)
    xr.testing.assert_identical(computed, golden)


def _drop_case(dataset: xr.Dataset, case: dict) -> xr.Dataset:
    """The Dataset without the variables' values of one case (set to a fill value), and
    without the step positions only that case reached."""
    mask = xr.ones_like(dataset["n_steps"], dtype=bool)
    for name, value in case.items():
        mask = mask & (dataset[name] != value)
    dataset = dataset.copy()
    for name, variable in dataset.data_vars.items():
        if set(mask.dims) <= set(variable.dims):
            dataset[name] = variable.where(mask, other=variable.dtype.type(0) if variable.dtype.kind in "iub" else variable.dtype.type(0) if variable.dtype.kind == "f" else "")
    longest = int(dataset["n_steps"].where(mask, 0).max())
    return dataset.isel(step=slice(0, longest))


#: Today's defaults against the golden's: two integrations of the same paths to rtol
#: 1e-10 (1e-12 for the Green paradox) with different step sequences, events located
#: to event_tol 1e-10 on each.  Measured differences: at most ~2e-9 (events' arclength
#: where a tangent is nearly parallel to the indicator's level set); 1e-7 leaves a
#: margin of about fifty, and any change of algorithm (another event, a missed sign
#: change, a different branch) moves values by 1e-4 or more.
DEFAULTS_TOL = 1e-7


@pytest.mark.parametrize("study_file", STUDIES, ids=[p.stem for p in STUDIES])
def test_with_todays_defaults_a_study_gives_the_golden_events_and_ends(study_file: Path) -> None:
    study = load_study(study_file)
    assert study.options.sample_step is not None
    golden = open_study(GOLDEN / f"{study.name}.nc")
    computed = normalise_dataset(run_study(study))
    for case in KNOWN_DIFFERENCES.get(study.name, []):
        golden, computed = _drop_case(golden, case), _drop_case(computed, case)
    np.testing.assert_array_equal(computed["status"].values, golden["status"].values)
    for event in EVENTS:
        if f"{event}_stage" not in golden:  # (bifurcation, divergence: added since, never on the diamond)
            continue
        found = golden[f"{event}_stage"].values >= 0
        np.testing.assert_array_equal(computed[f"{event}_stage"].values >= 0, found, err_msg=event)
        for field in ("s", "lam", "u", "F"):
            name = f"{event}_{field}"
            if name in golden:
                np.testing.assert_allclose(computed[name].values, golden[name].values, rtol=0, atol=DEFAULTS_TOL,
                                           err_msg=name)
    for name in ("u", "F", "work"):
        ends = [data[name].isel(step=data["n_steps"] - 1) for data in (computed, golden)]
        np.testing.assert_allclose(ends[0].values, ends[1].values, rtol=0, atol=DEFAULTS_TOL, err_msg=name)
    if "cycle_work" in golden:
        np.testing.assert_allclose(computed["cycle_work"].values, golden["cycle_work"].values, rtol=0,
                                   atol=DEFAULTS_TOL)
    # stored states never further apart than sample_step within a stage, and fewer steps taken
    s, stage = computed["s"].values, computed["stage"].values
    same_stage = (stage[..., 1:] == stage[..., :-1]) & (stage[..., 1:] >= 0)
    assert np.nanmax(np.where(same_stage, np.diff(s, axis=-1), 0.0)) <= study.options.sample_step * (1 + 1e-12)
    own = tomllib.loads(study_file.read_text(encoding="utf-8")).get("options", {})
    if "max_step" not in own:  # the default max_step went from 0.02 to 1: fewer steps
        assert int(computed["accepted_steps"].sum()) < int(golden["accepted_steps"].sum())
