"""Study files: validation (every error of a file, each naming its field), the
Study they give, and the safe arithmetic expressions they may contain.

Each malformed file in ``tests/data/bad_studies`` states what it must be rejected
for in its first lines: ``# expect: <field>`` (one line per error that must be
reported) and ``# contains: <text>`` (text the error message must contain).
"""

from __future__ import annotations

import dataclasses
import math
import pickle
import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ncstab.paths import CycleStage, PathOptions, Stage, SystemSpec
from ncstab.studies import (
    DEFAULT_FIGURES,
    ExpressionError,
    Study,
    StudyFileError,
    default_output_path,
    evaluate_expression,
    load_study,
    parse_study,
)
from ncstab.studies.expressions import is_expression

DATA = Path(__file__).parent / "data"
BAD = sorted((DATA / "bad_studies").glob("*.toml"))
GOOD = sorted((DATA / "good_studies").glob("*.toml"))
ROOT = Path(__file__).parent.parent
PROJECT_STUDIES = sorted((ROOT / "studies").glob("*.toml"))

MINIMAL = """\
[study]
name = "minimal"
[laws]
names = ["mcnamara"]
[parameters]
gamma = 0.5
[[loading]]
hold = { F2 = 0.0 }
drive = { D1 = 0.05 }
"""


def expectations(path: Path) -> tuple[list[str], list[str]]:
    text = path.read_text(encoding="utf-8")
    fields = re.findall(r"^# expect: (.+?)\s*$", text, re.MULTILINE)
    contains = re.findall(r"^# contains: (.+?)\s*$", text, re.MULTILINE)
    return fields, contains


def rejected(text: str) -> StudyFileError:
    with pytest.raises(StudyFileError) as info:
        parse_study(text, "study.toml")
    return info.value


# --- malformed files -----------------------------------------------------------------------------


def test_there_are_enough_bad_study_files_and_each_states_its_expectation():
    assert len(BAD) >= 22
    for path in BAD:
        fields, _ = expectations(path)
        assert fields, f"{path.name} has no '# expect: <field>' line"


@pytest.mark.parametrize("path", BAD, ids=[p.stem for p in BAD])
def test_bad_study_is_rejected_naming_the_file_and_the_field(path, tmp_path, monkeypatch):
    # Run from an empty directory: an expression that could execute code
    # (import_expression.toml: "touch x") would leave a file here.
    monkeypatch.chdir(tmp_path)
    fields, contains = expectations(path)
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    error = info.value
    assert error.path == str(path)
    for field in fields:
        assert field in error.fields, f"{field!r} not reported; got {error.errors}"
    message = str(error)
    for text in contains:
        assert text in message
    # One line per error, each "<file>: <field>: <message>".
    lines = message.splitlines()
    assert len(lines) == len(error.errors)
    for line, (field, text) in zip(lines, error.errors):
        assert line == f"{path}: {field}: {text}"
        assert text
    assert list(tmp_path.iterdir()) == []


def test_an_expression_that_would_run_a_command_is_never_evaluated(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    error = rejected(MINIMAL.replace("gamma = 0.5", "gamma = \"__import__('os').system('touch x')\""))
    assert error.fields == ["parameters.gamma"]
    assert "__import__" in str(error)
    assert not (tmp_path / "x").exists()


def test_a_file_with_several_errors_reports_them_all_in_one_exception():
    fields, _ = expectations(DATA / "bad_studies" / "several_errors.toml")
    with pytest.raises(StudyFileError) as info:
        load_study(DATA / "bad_studies" / "several_errors.toml")
    assert sorted(info.value.fields) == sorted(fields)
    # Reported section by section, in the order the sections are documented.
    order = [f.split(".")[0].split("[")[0] for f in info.value.fields]
    assert order == ["study", "system", "laws", "parameters", "loading", "loading", "loading",
                     "options", "output", "outputs"]


def test_errors_in_several_stages_are_all_reported_with_their_stage_number():
    text = MINIMAL + """\
[[loading]]
hold = { F2 = 0.0, D2 = 0.0 }
drive = { D1 = 0.1 }
[[loading]]
hold = { F1 = 0.0 }
drive = { D2 = 0.1 }
stop_at = ["limit"]
"""
    error = rejected(text)
    assert error.fields == ["loading[2].hold.F2", "loading[3].stop_at"]


def test_a_toml_syntax_error_names_the_line():
    error = rejected(MINIMAL.replace("gamma = 0.5", "gamma = 0.5 0.6"))
    assert error.fields == ["toml"]
    assert "line 6" in str(error)
    error = rejected(MINIMAL + "gamma = [0.5,\n")
    assert "end of document, line 11" in str(error)


def test_unknown_law_lists_the_catalogue_and_a_close_match():
    error = rejected(MINIMAL.replace('["mcnamara"]', '["turko"]'))
    (field, message), = error.errors
    assert field == "laws.names"
    assert "did you mean 'turco'?" in message
    for name in ("cundall_strack", "weakly_hypoelastic", "mcnamara", "turco", "no_tension"):
        assert name in message


def test_error_is_picklable_and_keeps_its_errors():
    error = rejected(MINIMAL.replace("gamma = 0.5", "gamma = -1"))
    copy = pickle.loads(pickle.dumps(error))
    assert copy.path == error.path and copy.errors == error.errors and str(copy) == str(error)


def test_a_file_that_is_not_utf8_is_a_study_file_error(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(MINIMAL.replace("minimal", "caf\xe9").encode("latin-1"))
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    assert info.value.fields == ["toml"]


def test_a_missing_file_is_an_os_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_study(tmp_path / "nowhere.toml")


@pytest.mark.parametrize(
    "replace, field",
    [
        (("gamma = 0.5", "gamma = 0.5\nkappa = [1.0, -2.0]"), "parameters.kappa"),
        (("gamma = 0.5", "gamma = [0.5, 0.5]"), "parameters.gamma"),
        (("gamma = 0.5", "gamma = [[0.5]]"), "parameters.gamma"),
        (("gamma = 0.5", "gamma = 1979-05-27"), "parameters.gamma"),
        (("gamma = 0.5", "gamma = 0.5\nalpha0 = \"pi/2 + 1\""), "parameters.alpha0"),
        (('drive = { D1 = 0.05 }', 'drive = { D1 = "current" }'), "loading[1].drive.D1"),
        (('drive = { D1 = 0.05 }', 'drive = { D1 = true }'), "loading[1].drive.D1"),
        (('drive = { D1 = 0.05 }', 'drive = { D1 = 0.05, P = 1.0 }'), "loading[1].drive.P"),
        (('drive = { D1 = 0.05 }', 'drive = { D1 = 0.05 }\nhols = { F1 = 0 }'), "loading[1].hols"),
        (('drive = { D1 = 0.05 }', 'drive = 0.05'), "loading[1].drive"),
        (('name = "minimal"', 'name = 3'), "study.name"),
        (('name = "minimal"', 'name = "minimal"\ntitle = "x"'), "study.title"),
        (('[study]', 'version = 2\n[study]'), "version"),
        (('names = ["mcnamara"]', 'names = []'), "laws.names"),
        (('names = ["mcnamara"]', 'names = ["mcnamara+no_tensoin"]'), "laws.names"),
        (('[laws]', '[system]\nalpha0 = [0.6, 0.7]\n[laws]'), "system.alpha0"),
        (('[laws]', '[system]\nnormal = true\n[laws]'), "system.normal"),
        (('[laws]', '[system]\nnormal = "rigid"\nkappa = 1.0\n[laws]'), "system.kappa"),
        (('[laws]', '[output]\nfile = "results/"\n[laws]'), "output.file"),
        (('[laws]', '[output]\nfigures = "stability"\n[laws]'), "output.figures"),
        (('[laws]', '[output]\nfigures = ["stability", "stability"]\n[laws]'), "output.figures"),
        (('[laws]', '[options]\nmax_steps = true\n[laws]'), "options.max_steps"),
        (('[laws]', '[options]\nrtol = "nan"\n[laws]'), "options.rtol"),
        (('[study]', 'options = 3\n[study]'), "options"),
    ],
)
def test_more_malformed_fields(replace, field):
    old, new = replace
    assert old in MINIMAL
    error = rejected(MINIMAL.replace(old, new, 1))
    assert field in error.fields, error.errors


@pytest.mark.parametrize(
    "old, new, fields",
    [
        ("drive = { D1 = 0.05 }", "drive = 0.05", ["loading[1].drive"]),
        ("hold = { F2 = 0.0 }", "hold = [0.0]", ["loading[1].hold"]),
        ("drive = { D1 = 0.05 }", 'drive = { D1 = 0.05 }\ncycle = { turns = 1 }', ["loading[1].hold", "loading[1].drive"]),
        ("drive = { D1 = 0.05 }", 'drive = { D1 = "pi*D1_end" }', ["loading[1].drive.D1"]),
    ],
)
def test_an_error_is_not_followed_by_the_errors_it_causes(old, new, fields):
    assert rejected(MINIMAL.replace(old, new)).fields == fields


def test_a_free_parameter_in_a_cycle_centre_counts_as_used_and_must_be_defined():
    cycle = MINIMAL + '[[loading]]\ncycle = { center = ["c1", 0.0], turns = 1 }\n'
    error = rejected(cycle)
    assert error.fields == ["loading[2].cycle.center"]
    study = parse_study(cycle.replace("gamma = 0.5", "gamma = 0.5\nc1 = [0.05, 0.1]"))
    assert study.programme.stages[1] == CycleStage(("c1", 0.0), 1, 1, ())
    assert study.parameters["c1"] == [0.05, 0.1]


# --- valid files ---------------------------------------------------------------------------------


@pytest.mark.parametrize("path", GOOD, ids=[p.stem for p in GOOD])
def test_good_studies_load(path):
    study = load_study(path)
    assert isinstance(study, Study)
    assert study.text == path.read_text(encoding="utf-8")
    assert study.path == str(path)


@pytest.mark.parametrize("path", PROJECT_STUDIES, ids=[p.stem for p in PROJECT_STUDIES])
def test_the_project_studies_are_valid(path):
    load_study(path)


def test_a_full_study_gives_every_field():
    path = DATA / "good_studies" / "full.toml"
    study = load_study(path)
    assert study.name == "fig06_hyper_vs_hypo"
    assert study.description == "Seed Fig. 6: hyperelastic vs hypoelastic"
    assert study.system == SystemSpec("diamond", secondary_contacts="ignore", normal="deformable")
    assert study.laws == ("cundall_strack", "mcnamara", "turco+no_tension")
    # [system] parameters first, then [parameters], in file order; expressions evaluated.
    assert list(study.parameters) == ["alpha0", "kappa", "gamma", "F2_lateral", "D1_end", "center_D1"]
    assert study.parameters["alpha0"] == math.pi / 4
    assert study.parameters["kappa"] == 2.0
    assert study.parameters["gamma"] == [0.5, 2.0]
    assert study.parameters["D1_end"] == math.sqrt(2) / 4
    assert study.sweep == {"gamma": [0.5, 2.0], "center_D1": [0.05, 0.1]}
    assert study.n_cases == 3 * 2 * 2
    assert study.programme.stages == (
        Stage({"F1": 0.0}, {"F2": "F2_lateral"}),
        Stage({"F2": "current"}, {"D1": "D1_end"}, ("limit_point", "hill_loss")),
        CycleStage(("center_D1", -math.pi / 100), 4, -1, ("secondary_contact",)),
    )
    assert study.options == PathOptions(max_step=1e-2, max_steps=5000, rtol=1e-9)
    assert study.figures == ("load_rotation", "load_displacement", "load_displacement_rotation", "stability")
    assert study.output == "results/fig06.nc"
    assert default_output_path(study) == Path("results/fig06.nc")


def test_defaults_of_a_minimal_study():
    study = parse_study(MINIMAL)
    assert study.path is None and study.description == ""
    assert study.system == SystemSpec()
    assert study.system.secondary_contacts == "activate" and study.system.normal == "deformable"
    assert study.options == PathOptions()
    assert study.figures == DEFAULT_FIGURES == ("load_displacement", "load_rotation")
    assert study.output is None
    assert default_output_path(study) == Path("results") / "minimal.nc"
    assert study.parameters == {"gamma": 0.5}
    assert study.n_cases == 1


def test_the_rigid_limit_needs_no_gamma():
    study = parse_study(MINIMAL.replace("gamma = 0.5", "alpha0 = 0.7").replace("[laws]", '[system]\nnormal = "rigid"\n[laws]'))
    assert study.system.normal == "rigid"
    assert study.parameters == {"alpha0": 0.7}


def test_strings_in_stages_are_names_current_or_expressions():
    text = MINIMAL.replace("gamma = 0.5", "gamma = 0.5\nD1_end = 0.1").replace(
        "drive = { D1 = 0.05 }", 'drive = { D1 = "D1_end" }'
    ) + '[[loading]]\nhold = { F2 = "current" }\ndrive = { D1 = "pi/20" }\n'
    stages = parse_study(text).programme.stages
    assert stages[0].drive == {"D1": "D1_end"}
    assert stages[1].hold == {"F2": "current"} and stages[1].drive == {"D1": math.pi / 20}


def test_figures_may_be_empty_and_options_may_be_expressions():
    study = parse_study(MINIMAL + '[options]\nmax_step = "pi/100"\n[output]\nfigures = []\n')
    assert study.figures == ()
    assert study.options.max_step == math.pi / 100


def test_is_expression_tells_names_from_expressions():
    for name in ("F2_lateral", "current", "D1_end", "x"):
        assert not is_expression(name)
    for text in ("pi", "e", "pi/4", "0.5", "2*pi", "-1", "1e-3", "sqrt(2)", "a b"):
        assert is_expression(text)


# --- safe expressions ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, value",
    [
        ("pi/4", math.pi / 4),
        ("2*pi/5", 2 * math.pi / 5),
        ("-0.5*pi", -0.5 * math.pi),
        ("+pi", math.pi),
        ("sqrt(2)/2", math.sqrt(2) / 2),
        ("1e-3", 1e-3),
        ("3", 3.0),
        ("1_000", 1000.0),
        ("e", math.e),
        ("2**10", 1024.0),
        ("2**-3", 0.125),
        ("(1 + 2) * 3 - 4 / 8", 8.5),
        ("sin(pi/6) + cos(0) + tan(0)", math.sin(math.pi / 6) + 1.0),
        ("exp(1) - e", 0.0),
        ("log(e**2)", 2.0),
        ("log(8, 2)", 3.0),
        ("radians(45)", math.radians(45)),
        ("degrees(pi)", 180.0),
        ("  pi / 4  ", math.pi / 4),
    ],
)
def test_whitelisted_expressions_give_exact_values(text, value):
    assert evaluate_expression(text) == value


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_any_finite_float_written_as_text_evaluates_to_itself(x):
    assert evaluate_expression(repr(x)) == x


@given(st.integers(-1000, 1000), st.integers(1, 1000))
def test_rational_multiples_of_pi_are_what_python_gives(numerator, denominator):
    assert evaluate_expression(f"{numerator}*pi/{denominator}") == numerator * math.pi / denominator


@pytest.mark.parametrize(
    "text, construct",
    [
        ("pi*x", "x"),
        ("gamma", "gamma"),
        ("pi.real", "pi.real"),
        ("().__class__", "().__class__"),
        ("__import__('os').system('touch x')", "__import__('os').system"),
        ("__import__('os')", "__import__"),
        ("open('x', 'w')", "open"),
        ("exec('1')", "exec"),
        ("eval('1')", "eval"),
        ("(lambda: 1)()", "lambda: 1"),
        ("lambda: 1", "lambda: 1"),
        ("[x for x in ()]", "[x for x in ()]"),
        ("pi[0]", "pi[0]"),
        ("sqrt(x=2)", "x="),
        ("sqrt(*[4])", "*"),
        ("sqrt", "sqrt"),
        ("sqrt(1, 2)", "sqrt(1, 2)"),
        ("'pi'", "'pi'"),
        ("True", "True"),
        ("None", "None"),
        ("1j", "1j"),
        ("[1, 2]", "[1, 2]"),
        ("(1, 2)", "(1, 2)"),
        ("1 < 2", "1 < 2"),
        ("1 and 2", "1 and 2"),
        ("1 if pi else 2", "1 if pi else 2"),
        ("7 // 2", "//"),
        ("7 % 2", "%"),
        ("~1", "~"),
        ("not 1", "not"),
        ("1 << 2", "<<"),
        ("f'{pi}'", "f'{pi}'"),
        ("(y := 2)", "(y := 2)"),
        ("2**101", "2 ** 101"),
        ("2**-200", "2 ** (-200)"),
    ],
)
def test_everything_else_is_rejected_naming_the_construct(text, construct):
    with pytest.raises(ExpressionError) as info:
        evaluate_expression(text)
    assert info.value.construct == construct
    assert info.value.expression == text


@pytest.mark.parametrize(
    "text, words",
    [
        ("", "empty"),
        ("pi/", "not a valid expression"),
        ("1/0", "division by zero"),
        ("sqrt(-1)", "math domain error"),
        ("(-8)**(1/3)", "cannot be evaluated"),
        ("exp(1000)", "cannot be evaluated"),
        ("1e400", "not finite"),
        ("1e300 * 1e300", "not finite"),
        ("1e300 * 1e300 - 1e300 * 1e300", "not finite"),
        ("10**100**2", "too large"),
        ("1+" * 150 + "1", "longer than"),
        ("(" * 90 + "1" + ")" * 90, ""),
    ],
)
def test_math_errors_and_bad_syntax_are_expression_errors(text, words):
    if text.startswith("(("):  # deep but short nesting is fine
        assert evaluate_expression(text) == 1.0
        return
    with pytest.raises(ExpressionError) as info:
        evaluate_expression(text)
    assert words in str(info.value)


@given(st.text(alphabet="pi()+-*/.e0123456789 sqrtxab_'[],=", max_size=30))
def test_arbitrary_text_gives_a_finite_float_or_an_expression_error(text):
    try:
        value = evaluate_expression(text)
    except ExpressionError:
        return
    assert isinstance(value, float) and math.isfinite(value)


def test_non_strings_are_rejected():
    with pytest.raises(ExpressionError):
        evaluate_expression(3)  # type: ignore[arg-type]


def test_figure_kinds_are_those_the_plotting_layer_draws():
    from ncstab.plotting import FIGURE_KINDS as DRAWN
    from ncstab.studies import FIGURE_KINDS

    assert tuple(DRAWN) == FIGURE_KINDS


# --- the user guide (docs/study-files.md) stays true -----------------------------------------

GUIDE = ROOT / "docs" / "study-files.md"


def guide_blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", GUIDE.read_text(encoding="utf-8"), re.DOTALL)


def test_the_guide_example_study_is_valid():
    (example,) = [block for block in guide_blocks("toml") if 'name = "fig06_hyper_vs_hypo"' in block]
    study = parse_study(example)
    assert study.n_cases == 4
    assert study.output == "results/fig06.nc"


def test_the_guide_error_report_is_what_load_study_says():
    (bad,) = [block for block in guide_blocks("toml") if "[outputs]" in block]
    (report,) = [block for block in guide_blocks("text") if "several_errors.toml:" in block]
    with pytest.raises(StudyFileError) as info:
        parse_study(bad, "several_errors.toml")
    assert str(info.value) == report.strip()


def test_the_guide_lists_every_option_with_its_default():
    text = GUIDE.read_text(encoding="utf-8")
    for field in dataclasses.fields(PathOptions):
        row = re.search(rf"^\| `{field.name}` \| [^|]+ \| `([^`]+)` \|", text, re.MULTILINE)
        assert row, field.name
        if isinstance(field.default, str):
            assert row.group(1) == f'"{field.default}"', field.name
        elif field.default is None:
            assert row.group(1) == "none", field.name
        else:
            assert float(row.group(1)) == field.default, field.name


def test_a_bad_system_setting_is_reported_alone_without_follow_on_errors(tmp_path):
    """``grains = -3`` in a ring study whose stages name F3 and a free parameter: the system's
    error only (its dofs are unknown, so neither the stages' quantities nor the parameters they
    use are checked against a fallback system)."""
    path = tmp_path / "bad_ring.toml"
    path.write_text(
        '[study]\nname = "bad_ring"\n[system]\nname = "ring"\ngrains = -3\n[laws]\nnames = ["mcnamara"]\n'
        '[parameters]\ngamma = 0.5\nlateral = 0.2\n[[loading]]\nhold = { F2 = "lateral", F3 = 0.0 }\n'
        'drive = { D1 = 0.1 }\n'
    )
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    assert [field for field, _ in info.value.errors] == ["system.grains"]
