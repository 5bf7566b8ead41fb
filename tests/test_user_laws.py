"""User laws by formula: parsed by a whitelist, classified, followed, archived, refused.

References are independent of the code under test: the catalogue's own laws
(McNamara, Cundall--Strack), an integration of the seed's equilibrium Eq. (4)
written here with scipy, and quadratures of the work over a circle (seed Eq. 5,
9, 16).  Malformed laws go through the command line (``ncstab run``) and must
exit 2 naming the law and the key, without running anything.
"""

from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import xarray as xr
from scipy.integrate import quad, solve_ivp

import ncstab
from ncstab.cli import main
from ncstab.laws import (
    ALPHA,
    ALPHA0,
    GAMMA,
    L,
    FormulaError,
    UserLawError,
    law_definition,
    make_law,
    parse_formula,
    user_law,
)
from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.studies import StudyFileError, open_study, parse_study, run_study, run_study_chunked, write_dataset
from ncstab.symbolic import classify, compile_law

A0 = math.pi / 4
SYSTEM = SystemSpec(secondary_contacts="ignore")
#: Lateral preload then D1 driven past the limit point of McNamara's law (seed Fig. 6).
PROGRAMME = [
    {"hold": {"F1": 0.0}, "drive": {"F2": 0.1}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.3}},
]
FIELDS = ("u", "F", "alpha", "l", "N", "T", "K", "s")

MCNAMARA_FORMULAS = {"normal": "-(l - 1)", "tangential": "gamma*(alpha - alpha0)/l"}
MCNAMARA_ENERGY = {"energy": "(l - 1)**2/2 + gamma*(alpha - alpha0)**2/2"}
TURCO_ENERGY = {"energy": "(l - cos(alpha - alpha0))**2/2 + gamma*sin(alpha - alpha0)**2/2"}
CUNDALL_STRACK_RATES = {"normal_rate": "-dl", "tangential_rate": "gamma*l*dalpha"}
SINE_SHEAR = {"normal": "-(l - 1)", "tangential": "gamma*sin(alpha - alpha0)"}


def same_paths(path, reference: str, other: str, tolerance: float) -> None:
    """Every stored field of two laws of one Path agrees to ``tolerance``."""
    a = path.results[path.laws.index(reference)]
    b = path.results[path.laws.index(other)]
    np.testing.assert_array_equal(a.n_steps, b.n_steps)
    assert list(a.status) == list(b.status)
    for field in FIELDS:
        difference = np.nan_to_num(a.steps[field] - b.steps[field])
        assert np.max(np.abs(difference)) <= tolerance, field


# --- the formula parser -------------------------------------------------------------------------

NAMES = {"l": L, "alpha": ALPHA, "alpha0": ALPHA0, "gamma": GAMMA}


def test_numbers_are_exact_and_names_are_the_law_symbols():
    expression = parse_formula("0.1*l**2 - 3/2 + gamma*(alpha - alpha0)", NAMES, law="x", key="normal")
    assert expression - (sp.Rational(1, 10) * L**2 - sp.Rational(3, 2) + GAMMA * (ALPHA - ALPHA0)) == 0


def test_every_whitelisted_function_is_sympys():
    text = "sin(l) + cos(l) + tan(l) + exp(l) + log(l) + log(l, 2) + sqrt(l) + atan2(alpha, l) + abs(alpha) + pi"
    expected = (sp.sin(L) + sp.cos(L) + sp.tan(L) + sp.exp(L) + sp.log(L) + sp.log(L, 2) + sp.sqrt(L)
                + sp.atan2(ALPHA, L) + sp.Abs(ALPHA) + sp.pi)
    assert parse_formula(text, NAMES, law="x", key="normal") - expected == 0


@pytest.mark.parametrize(
    "text, token",
    [
        ("gamma*x", "x"),
        ("T", "T"),  # not a name of a total normal force
        ("l.real", "l.real"),
        ("os.system('touch x')", "os.system"),
        ("__import__('os')", "__import__"),
        ("(lambda: 1)()", "lambda: 1"),
        ("l[0]", "l[0]"),
        ("sin(x=1)", "x="),
        ("'l'", "'l'"),
        ("l < 1", "l < 1"),
        ("l if alpha else 1", "l if alpha else 1"),
        ("l // 2", "//"),
        ("[l for l in ()]", "[l for l in ()]"),
        ("l**101", "l ** 101"),
        ("(l**100)**100", "(l ** 100) ** 100"),
        ("2**2**2**2**2", "2 ** 2 ** 2 ** 2 ** 2"),
        ("1/0", "1 / 0"),
        ("sin", "sin"),
        ("sin(l, 2)", "sin(l, 2)"),
        ("gamma*(alpha", ""),
        ("-" * 60 + "l", ""),
        ("+".join(["l"] * 300), ""),
        ("l*" * 600 + "l", ""),
        ("log(0)", ""),
    ],
)
def test_everything_else_is_refused_naming_law_key_and_token(text, token):
    with pytest.raises(FormulaError) as info:
        parse_formula(text, NAMES, law="my_law", key="normal")
    assert info.value.token == token
    assert (info.value.law, info.value.key) == ("my_law", "normal")
    assert str(info.value).startswith("law 'my_law', key 'normal': ")


def test_errors_pickle_and_say_what_is_allowed():
    with pytest.raises(FormulaError) as info:
        parse_formula("gamma*x", NAMES, law="my_law", key="tangential")
    assert "l, alpha, alpha0, gamma, pi" in str(info.value)
    copy = pickle.loads(pickle.dumps(info.value))
    assert (str(copy), copy.token, copy.formula) == (str(info.value), "x", "gamma*x")


# --- building laws ------------------------------------------------------------------------------


def test_a_law_typed_as_mcnamaras_formulas_is_mcnamaras_law():
    for formulas in (MCNAMARA_FORMULAS, MCNAMARA_ENERGY):
        definition = user_law("typed", **formulas)
        catalogue = law_definition("mcnamara")
        assert sp.simplify(definition.normal_total - catalogue.normal_total) == 0
        assert sp.simplify(definition.tangential_total - catalogue.tangential_total) == 0
        result = classify(definition)
        assert result.kind == "hyperelastic"
        # Its energy is the seed's Eq. (19) (dimensionless), up to a constant.
        eq19 = (L - 1) ** 2 / 2 + GAMMA * (ALPHA - ALPHA0) ** 2 / 2
        assert sp.simplify(sp.diff(result.energy - eq19, L)) == 0
        assert sp.simplify(sp.diff(result.energy - eq19, ALPHA)) == 0


def test_rate_forms_keep_t_as_an_internal_variable_and_integrate_the_normal_rate():
    definition = user_law("typed", normal_rate="-dl + 0*dalpha", tangential_rate="gamma*l*dalpha")
    assert definition.internal_variables == ("T",) and definition.tangential_force is None
    assert sp.simplify(definition.normal_total - (1 - L)) == 0
    assert [sp.simplify(c) for c in definition.tangential_rate] == [0, GAMMA * L]
    # A normal rate with an alpha part integrates to N with N = 0 at (1, alpha0).
    coupled = user_law("coupled", normal_rate="-dl + gamma*cos(alpha)*dalpha", tangential="0")
    assert sp.simplify(coupled.normal_total - (1 - L + GAMMA * (sp.sin(ALPHA) - sp.sin(ALPHA0)))) == 0


def test_classes_follow_the_seeds_conditions():
    cases = {
        "hyperelastic": [MCNAMARA_FORMULAS, MCNAMARA_ENERGY, TURCO_ENERGY,
                         {"normal_rate": "-dl", "tangential_rate": "(gamma*dalpha - T*dl)/l"}],  # Eq. (21)
        "weakly hypoelastic": [SINE_SHEAR, {"normal": "-(l - 1)", "tangential": "gamma*(alpha - alpha0)"},
                               {"normal_rate": "-dl", "tangential_rate": "gamma*dalpha"}],  # Eq. (26)
        "strongly hypoelastic": [CUNDALL_STRACK_RATES,
                                 {"normal": "-(l - 1)", "tangential_rate": "gamma*l**2*dalpha"}],
    }
    for kind, laws in cases.items():
        for formulas in laws:
            assert classify(user_law("typed", **formulas)).kind == kind, formulas


def test_sine_shear_fails_eq17_with_the_residual_derived_by_hand():
    # N = 1 - l, T = gamma sin(alpha - alpha0): -dN/dalpha = 0 while
    # d(l T)/dl = T, so the residual -dN/dalpha - d(lT)/dl is -gamma sin(alpha - alpha0).
    result = classify(user_law("sine_shear", **SINE_SHEAR))
    assert result.deciding_condition.name.startswith("Eq. (17)") and not result.deciding_condition.holds
    assert sp.simplify(result.deciding_condition.residual + GAMMA * sp.sin(ALPHA - ALPHA0)) == 0


def test_declared_parameters_are_validated_and_swept():
    definition = user_law("scaled", normal="-(l - 1)", tangential="mu*gamma*sin(alpha - alpha0)",
                          parameters={"mu": {"min": 0, "max": 2, "default": 1}})
    assert definition.parameter_names == ("gamma", "alpha0", "mu")
    with pytest.raises(ValueError, match="'mu'"):
        make_law(definition, gamma=1.0, mu=3.0)
    law = make_law(definition, gamma=1.0)
    assert float(law.parameters["mu"]) == 1.0


def test_a_no_tension_user_law_brackets_its_own_normal_force():
    definition = law_definition("sine_shear+no_tension", {"sine_shear": user_law("sine_shear", **SINE_SHEAR)})
    law = make_law(definition, gamma=0.5)
    compiled = compile_law(definition)
    # Open contact (l > 1): no normal force; closed: N = 1 - l.
    assert compiled.normal_force(law, np.array(1.1), np.array(A0)) == 0.0
    assert compiled.normal_force(law, np.array(0.9), np.array(A0)) == pytest.approx(0.1, abs=1e-15)


# --- paths ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def typed_paths():
    """Catalogue laws and the same laws typed as formulas, one Path (about 3 s)."""
    laws = ["mcnamara", user_law("mcnamara_typed", **MCNAMARA_FORMULAS),
            user_law("mcnamara_energy", **MCNAMARA_ENERGY),
            "cundall_strack", user_law("cundall_strack_typed", **CUNDALL_STRACK_RATES)]
    return follow(SYSTEM, laws, PROGRAMME, {"gamma": [0.5, 2.0], "alpha0": A0})


@pytest.mark.parametrize("typed", ["mcnamara_typed", "mcnamara_energy"])
def test_mcnamaras_formulas_give_mcnamaras_path(typed_paths, typed):
    # The same expressions compile to the same kernel: the paths agree to
    # rounding (asserted 1e-12), and the archive calls the typed law hyperelastic.
    assert (typed_paths.status == "finished").all()
    same_paths(typed_paths, "mcnamara", typed, 1e-12)
    assert dict(zip(typed_paths.laws, typed_paths.to_dataset()["law_class"].values))[typed] == "hyperelastic"


def test_cundall_stracks_rate_form_gives_cundall_stracks_path(typed_paths):
    same_paths(typed_paths, "cundall_strack", "cundall_strack_typed", 1e-12)
    classes = dict(zip(typed_paths.laws, typed_paths.to_dataset()["law_class"].values))
    assert classes["cundall_strack_typed"] == "strongly hypoelastic"


def test_sine_shear_path_is_an_independent_integration_of_eq4():
    # With F2 held at 0 and D1 driven, Eq. (4) F2 = 2 N sin(alpha) - 2 T cos(alpha) = 0
    # defines D2(D1); differentiating, dD2/dD1 = -(dF2/dD1)/(dF2/dD2) with the chain
    # rule through Eq. (1), (10)-(11).  scipy's DOP853 at rtol 1e-13 is accurate to
    # ~1e-14; the engine projects every state on Eq. (4) to 1e-12.  Compared at the
    # engine's stored D1 values to 1e-9.
    gamma = 0.5
    path = follow(SYSTEM, [user_law("sine_shear", **SINE_SHEAR)], [{"hold": {"F2": 0.0}, "drive": {"D1": 0.2}}],
                  {"gamma": gamma, "alpha0": A0})
    result = path.results[0]
    assert list(result.status) == ["finished"]
    n = int(result.n_steps[0])
    u, forces = result.steps["u"][0, :n], result.steps["F"][0, :n]

    def geometry(d1: float, d2: float) -> tuple[float, float]:
        x, y = math.cos(A0) - d1, math.sin(A0) - d2
        return math.hypot(x, y), math.atan2(y, x)

    def slope(d1: float, state: np.ndarray) -> list[float]:
        length, alpha = geometry(d1, state[0])
        df2_dl = -2 * math.sin(alpha)
        df2_dalpha = 2 * (1 - length) * math.cos(alpha) - 2 * gamma * math.cos(2 * alpha - A0)
        dl = (-math.cos(alpha), -math.sin(alpha))
        dalpha = (math.sin(alpha) / length, -math.cos(alpha) / length)
        along = [df2_dl * dl[k] + df2_dalpha * dalpha[k] for k in range(2)]
        return [-along[0] / along[1]]

    solution = solve_ivp(slope, (0.0, 0.2), [0.0], method="DOP853", rtol=1e-13, atol=1e-15, dense_output=True)
    d2 = solution.sol(u[:, 0])[0]
    np.testing.assert_allclose(u[:, 1], d2, rtol=0, atol=1e-9)
    f1 = []
    for d1, d2_k in zip(u[:, 0], d2):
        length, alpha = geometry(d1, d2_k)
        f1.append(2 * (1 - length) * math.cos(alpha) + 2 * gamma * math.sin(alpha - A0) * math.sin(alpha))
    np.testing.assert_allclose(forces[:, 0], f1, rtol=0, atol=1e-9)
    np.testing.assert_allclose(forces[:, 1], 0.0, rtol=0, atol=1e-9)
    assert u[-1, 0] == pytest.approx(0.2, abs=1e-12)


def test_follow_takes_a_law_with_its_parameter_values():
    definition = user_law("scaled", normal="-(l - 1)", tangential="mu*gamma*sin(alpha - alpha0)",
                          parameters={"mu": {"min": 0}})
    stage = [{"hold": {"D2": 0.0}, "drive": {"D1": 0.05}}]
    path = follow(SYSTEM, [make_law(definition, gamma=0.5, mu=1.5)], stage, {"alpha0": A0})
    result = path.results[0]
    n = int(result.n_steps[0])
    alpha, tangential = result.steps["alpha"][0, :n], result.steps["T"][0, :n]
    np.testing.assert_allclose(tangential, 1.5 * 0.5 * np.sin(alpha - A0), rtol=0, atol=1e-14)


# --- cycles: Green's paradox for user laws ----------------------------------------------------

CYCLE_OPTIONS = PathOptions(rtol=1e-13, atol=1e-16, event_tol=1e-13, max_step=0.5)


def loop_integral(integrand, centre: tuple[float, float]) -> float:
    """oint integrand(l, alpha) l dalpha counterclockwise around the circle through u = 0
    centred at ``centre`` (seed Eq. 1, 11), by adaptive quadrature to 1e-12."""
    radius = math.hypot(*centre)
    start = math.atan2(-centre[1], -centre[0])

    def f(lam: float) -> float:
        theta = start + lam
        d1, d2 = centre[0] + radius * math.cos(theta), centre[1] + radius * math.sin(theta)
        dd1, dd2 = -radius * math.sin(theta), radius * math.cos(theta)
        x, y = math.cos(A0) - d1, math.sin(A0) - d2
        alpha = math.atan2(y, x)
        return integrand(math.hypot(x, y), alpha) * (math.sin(alpha) * dd1 - math.cos(alpha) * dd2)

    return quad(f, 0.0, 2 * math.pi, epsabs=0.0, epsrel=1e-12, limit=200)[0]


@pytest.fixture(scope="module")
def user_cycles():
    laws = [user_law("mcnamara_typed", **MCNAMARA_FORMULAS), user_law("turco_energy", **TURCO_ENERGY),
            user_law("sine_shear", **SINE_SHEAR), user_law("cundall_strack_typed", **CUNDALL_STRACK_RATES),
            "cundall_strack"]
    return follow(SYSTEM, laws, [{"cycle": {"center": ["c1", 0.0], "turns": 2, "direction": 1}}],
                  {"gamma": 0.5, "alpha0": A0, "c1": [0.03, 0.06]}, CYCLE_OPTIONS)


def test_hyperelastic_user_laws_do_no_work_over_a_cycle(user_cycles):
    # W = oint dW = 0 (seed Eq. 16-19, 29); the engine's error on W is ~1e-14 (test_cycles).
    for name in ("mcnamara_typed", "turco_energy"):
        work = user_cycles.results[user_cycles.laws.index(name)].cycles["work"]
        assert work.shape == (2, 2)
        assert np.all(np.abs(work) <= 1e-12), name


def test_a_weakly_hypoelastic_user_law_does_the_work_of_its_formula(user_cycles):
    # T = gamma sin(alpha - alpha0) is a state function, so every turn does the same
    # W = gamma oint sin(alpha - alpha0) l dalpha (N = N(l) does none).  Engine error
    # ~1e-11 relative at these options (test_cycles); asserted 1e-9.
    result = user_cycles.results[user_cycles.laws.index("sine_shear")]
    for case, c1 in enumerate([0.03, 0.06]):
        expected = 0.5 * loop_integral(lambda length, alpha: math.sin(alpha - A0), (c1, 0.0))
        assert abs(expected) > 1e-6
        np.testing.assert_allclose(result.cycles["work"][case], [expected, expected], rtol=1e-9)


def test_a_strongly_hypoelastic_user_law_drifts_like_cundall_strack(user_cycles):
    # Turn k from rest costs gamma I^2 (k + 1/2) with I = oint l dalpha (test_cycles);
    # the typed law must give the catalogue's numbers to 1e-12.
    typed = user_cycles.results[user_cycles.laws.index("cundall_strack_typed")].cycles
    catalogue = user_cycles.results[user_cycles.laws.index("cundall_strack")].cycles
    np.testing.assert_allclose(typed["work"], catalogue["work"], rtol=0, atol=1e-12)
    for case, c1 in enumerate([0.03, 0.06]):
        loop = loop_integral(lambda length, alpha: 1.0, (c1, 0.0))
        np.testing.assert_allclose(typed["work"][case], 0.5 * loop**2 * np.array([0.5, 1.5]), rtol=1e-9)


# --- study files ------------------------------------------------------------------------------

STUDY = """\
[study]
name = "user_laws"
[system]
secondary_contacts = "ignore"
[laws]
names = ["mcnamara", "scaled_sine", "typed_cs", "scaled_sine+no_tension"]
[laws.scaled_sine]
description = "a sine shear law scaled by mu"
normal = "-(l - 1)"
tangential = "mu*gamma*sin(alpha - alpha0)"
parameters = { mu = { min = 0, max = "pi", default = 1 } }
[laws.typed_cs]
normal_rate = "-dl"
tangential_rate = "gamma*l*dalpha"
[parameters]
gamma = [0.5, 2.0]
mu = [1.0, 1.5]
[[loading]]
hold = { D2 = 0.0 }
drive = { D1 = 0.04 }
[[loading]]
hold = { F2 = "current" }
drive = { D1 = 0.06 }
[options]
max_step = 0.01
"""


@pytest.fixture(scope="module")
def study():
    return parse_study(STUDY, "user_laws.toml")


def test_a_study_carries_its_user_laws(study):
    assert study.laws == ("mcnamara", "scaled_sine", "typed_cs", "scaled_sine+no_tension")
    assert [d.name for d in study.user_laws] == ["scaled_sine", "typed_cs"]
    assert study.law_definition("scaled_sine+no_tension").no_tension
    assert study.sweep == {"gamma": [0.5, 2.0], "mu": [1.0, 1.5]}
    assert pickle.loads(pickle.dumps(study)) == study


@pytest.fixture(scope="module")
def reference(study, tmp_path_factory):
    path = tmp_path_factory.mktemp("reference") / "user_laws.nc"
    write_dataset(run_study(study), path)
    return open_study(path)


def test_the_archive_has_the_user_laws_their_classes_and_the_swept_parameter(reference):
    classes = dict(zip(reference["law"].values, reference["law_class"].values))
    assert classes == {"mcnamara": "hyperelastic", "scaled_sine": "weakly hypoelastic",
                       "typed_cs": "strongly hypoelastic", "scaled_sine+no_tension": "weakly hypoelastic"}
    assert (reference["status"].values == "finished").all()
    # The swept mu reaches the law: on the first (kinematic) stage T = mu gamma sin(alpha - alpha0).
    case = reference.sel(law="scaled_sine", gamma=2.0, mu=1.5)
    first = case["stage"].values == 0
    np.testing.assert_allclose(case["T"].values[first], 1.5 * 2.0 * np.sin(case["alpha"].values[first] - A0),
                               rtol=0, atol=1e-13)


def assert_same_archive(path: Path, reference: xr.Dataset) -> None:
    archive = open_study(path)
    assert archive.attrs.pop("created")
    expected = reference.copy()
    expected.attrs.pop("created")
    xr.testing.assert_identical(archive, expected)


def test_a_chunked_run_uses_the_user_laws(study, reference, tmp_path):
    output = tmp_path / "chunked.nc"
    run_study_chunked(study, output, chunk_cases=3)
    assert_same_archive(output, reference)


def test_user_laws_reach_a_dask_worker_in_another_process(study, reference, tmp_path):
    # The Study (and its LawDefinitions) is pickled to a worker process that has
    # never seen these laws; its archive must be the in-process one, bit for bit.
    distributed = pytest.importorskip("dask.distributed")
    import dask

    with dask.config.set({"temporary-directory": str(tmp_path / "scratch")}), distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        output = tmp_path / "dask.nc"
        run_study_chunked(study, output, chunk_cases=4, scheduler=cluster.scheduler_address)
    assert_same_archive(output, reference)


def test_ncstab_laws_lists_a_studys_laws_and_explains_one(tmp_path, capsys):
    path = tmp_path / "user_laws.toml"
    path.write_text(STUDY, encoding="utf-8")
    assert main(["laws", str(path)]) == 0
    out = capsys.readouterr().out
    rows = {line.split()[0]: line for line in out.splitlines() if line.split() and line.split()[0] in
            ("mcnamara", "scaled_sine", "typed_cs", "scaled_sine+no_tension")}
    assert "strongly hypoelastic" in rows["typed_cs"] and "weakly hypoelastic" in rows["scaled_sine"]
    assert main(["laws", str(path), "--explain", "scaled_sine"]) == 0
    out = capsys.readouterr().out
    mu = sp.Symbol("mu", real=True, nonnegative=True)
    residual = sp.sstr(-GAMMA * mu * sp.sin(ALPHA - ALPHA0))  # derived by hand: see the sine-shear test
    assert f"residual: {residual}" in out
    assert "class: weakly hypoelastic -- decided by Eq. (17) hyperelasticity" in out
    # A user law is known only with its study.
    assert main(["laws", "--explain", "scaled_sine"]) == 2
    assert "unknown law 'scaled_sine'" in capsys.readouterr().err


def test_user_laws_need_a_deformable_normal():
    text = STUDY.replace('secondary_contacts = "ignore"', 'secondary_contacts = "ignore"\nnormal = "rigid"')
    text = text.replace("gamma = [0.5, 2.0]\n", "")
    with pytest.raises(StudyFileError) as info:
        parse_study(text)
    assert "laws.scaled_sine" in info.value.fields


# --- malformed user laws: exit 2, law and key named, nothing run -----------------------------

BASE = """\
[study]
name = "bad_user_law"
[laws]
names = {names}
{table}
[parameters]
gamma = 0.5
[[loading]]
hold = {{ F2 = 0.0 }}
drive = {{ D1 = 0.05 }}
"""

#: (law table, field that must be reported, text the message must contain)
MALFORMED = [
    ('normal = "-(l - 1)"\ntangential = "gamma*x"', "laws.bad.tangential", "'x'"),
    ('normal = "__import__(\'os\').system(\'touch PWNED\')"\ntangential = "0"', "laws.bad.normal", "__import__"),
    ('normal = "-(l - 1)"\ntangential = "open(\'PWNED\', \'w\')"', "laws.bad.tangential", "'open'"),
    ('normal = "-(l - 1)"\ntangential = "gamma.__class__"', "laws.bad.tangential", "attribute access"),
    ('normal = "-(l - 1)"\ntangential = "(lambda: 1)()"', "laws.bad.tangential", "lambda"),
    ('normal = "l**1000"\ntangential = "0"', "laws.bad.normal", "too large"),
    ('normal = "-(l - 1)"\ntangential_rate = "gamma*dalpha**2"', "laws.bad.tangential_rate", "not linear"),
    ('normal = "-(l - 1)"\ntangential_rate = "gamma*l*dalpha*dl"', "laws.bad.tangential_rate", "not linear"),
    ('normal = "-(l - 1)"', "laws.bad.tangential", "missing"),
    ('normal = "-(l - 1)"\nnormal_rate = "-dl"\ntangential = "0"', "laws.bad.normal_rate", "not both"),
    ('energy = "(l - 1)**2/2"\ntangential = "0"', "laws.bad.tangential", "energy"),
    ('normal_rate = "-dl + T*dalpha"\ntangential = "0"', "laws.bad.normal_rate", "depends on T"),
    ('normal_rate = "-dl + l*dalpha"\ntangential = "0"', "laws.bad.normal_rate", "give the normal force"),
    ('normal = "-(l - 1)"\ntangential = "gamma*dalpha"', "laws.bad.tangential", "'dalpha'"),
    ('normal = "-(l - 1)"\ntangential = "gamma*(alpha"', "laws.bad.tangential", "not a valid expression"),
    ('normal = "-(l - 1)"\ntangential = "l[0]"', "laws.bad.tangential", "subscript"),
    ('normal = "-(l - 1)"\ntangential = "sin(x=1)"', "laws.bad.tangential", "keyword argument"),
    ('normal = "1/0"\ntangential = "0"', "laws.bad.normal", "division by zero"),
    ('normal = 1.0\ntangential = "0"', "laws.bad.normal", "formula string"),
    ('normal = "-(l - 1)"\ntangent = "0"', "laws.bad.tangent", "unknown key"),
    ('normal = "-(l - 1)"\ntangential = "mu*alpha"', "laws.bad.tangential", "'mu'"),
    ('normal = "-(l - 1)"\ntangential = "gamma*alpha"\nparameters = { mu = { min = 0 } }',
     "laws.bad.parameters.mu", "no formula"),
    ('normal = "-(l - 1)"\ntangential = "mu*alpha"\nparameters = { mu = { min = 2, max = 1 } }',
     "laws.bad.parameters.mu", "empty"),
    ('normal = "-(l - 1)"\ntangential = "kappa*alpha"\nparameters = { kappa = {} }',
     "laws.bad.parameters.kappa", "choose another name"),
]


def write_bad(tmp_path: Path, table: str, names: str = '["bad"]', header: str = "[laws.bad]") -> Path:
    path = tmp_path / "bad.toml"
    path.write_text(BASE.format(names=names, table=f"{header}\n{table}"), encoding="utf-8")
    return path


def assert_refused(path: Path, field: str, words: str, capsys, tmp_path: Path) -> None:
    assert main(["run", str(path), "-q"]) == 2
    err = capsys.readouterr().err
    line = next((line for line in err.splitlines() if f": {field}: " in line), None)
    assert line is not None, err
    assert words in line, line
    assert len(err.strip().splitlines()) == 1, err  # one line, no traceback
    assert not (tmp_path / "PWNED").exists()
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize("table, field, words", MALFORMED, ids=[f[1] + ":" + f[2] for f in MALFORMED])
def test_a_malformed_user_law_exits_2_naming_law_and_key(table, field, words, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert_refused(write_bad(tmp_path, table), field, words, capsys, tmp_path)


def test_a_user_law_may_not_take_a_catalogue_name(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = write_bad(tmp_path, 'normal = "-(l - 1)"\ntangential = "0"', '["mcnamara"]', "[laws.mcnamara]")
    assert_refused(path, "laws.mcnamara", "catalogue law", capsys, tmp_path)


def test_a_user_law_must_be_listed(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = write_bad(tmp_path, 'normal = "-(l - 1)"\ntangential = "0"', '["mcnamara"]')
    assert_refused(path, "laws.bad", "not listed", capsys, tmp_path)


def test_user_law_errors_are_value_errors_that_pickle():
    with pytest.raises(UserLawError) as info:
        user_law("bad", normal="-(l - 1)")
    assert isinstance(info.value, ValueError) and (info.value.law, info.value.key) == ("bad", "tangential")
    copy = pickle.loads(pickle.dumps(info.value))
    assert str(copy) == str(info.value)


def test_ncstab_exports_the_user_law_api():
    assert ncstab.laws.user_law is user_law


# --- the user guide (docs/user-laws.md) stays true ------------------------------------------

GUIDE = Path(__file__).parent.parent / "docs" / "user-laws.md"


def guide_blocks(language: str) -> list[str]:
    import re

    return re.findall(rf"```{language}\n(.*?)```", GUIDE.read_text(encoding="utf-8"), re.DOTALL)


def test_the_guide_study_and_its_explanation_are_what_ncstab_says(tmp_path, capsys):
    (study_text,) = guide_blocks("toml")
    path = tmp_path / "my_laws.toml"
    path.write_text(study_text, encoding="utf-8")
    study = parse_study(study_text)
    assert study.laws == ("mcnamara", "sine_shear", "my_rate_law", "sine_shear+no_tension")
    explanation = next(block for block in guide_blocks("text") if block.startswith("sine_shear:"))
    assert main(["laws", str(path), "--explain", "sine_shear"]) == 0
    assert capsys.readouterr().out == explanation


def test_the_guide_errors_are_what_ncstab_run_says(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    errors = next(block for block in guide_blocks("text") if block.startswith("bad.toml:")).splitlines()
    tables = ['normal = "-(l - 1)"\ntangential = "gamma*x"', 'normal = "-(l - 1)"\ntangential_rate = "gamma*dalpha**2"',
              'normal = "__import__(\'os\').system(\'touch PWNED\')"\ntangential = "0"']
    for table, expected in zip(tables, errors, strict=True):
        write_bad(tmp_path, table, '["my_law"]', "[laws.my_law]")
        assert main(["run", "bad.toml", "-q"]) == 2
        assert capsys.readouterr().err.splitlines()[0] == expected
    assert not (tmp_path / "PWNED").exists()


def test_the_guide_python_example_runs_and_prints_what_it_says(capsys):
    (code,) = guide_blocks("python")
    exec(compile(code, str(GUIDE), "exec"), {})  # the documentation's own example, not user input
    lines = capsys.readouterr().out.splitlines()
    assert lines == ["weakly hypoelastic", "['hyperelastic' 'weakly hypoelastic' 'strongly hypoelastic']"]
