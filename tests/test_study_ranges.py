"""Ranges in study files: ``gamma = { start = 0.1, stop = 2.0, num = 64 }``.

A linear range is ``numpy.linspace`` exactly, a log range ``numpy.geomspace``
exactly (compared with ``assert_array_equal``: the same floats, endpoints
included); a step range is ``start + k*step`` with ``stop`` itself as the last
value when it is reached to within ``RANGE_STEP_TOL * |step|``.  Every bad range
makes ``ncstab run`` exit with code 2, naming the key, before anything runs.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ncstab.cli import main
from ncstab.studies import StudyFileError, parse_study
from ncstab.studies.study import MAX_RANGE_VALUES, RANGE_STEP_TOL

STUDY = """\
[study]
name = "ranges"
[laws]
names = ["mcnamara"]
[parameters]
gamma = 0.5
{parameter} = {value}
[[loading]]
hold = {{ F2 = 0.0 }}
drive = {{ D1 = 0.05 }}
"""


def swept(value: str, parameter: str = "alpha0") -> list[float]:
    """The values a study file gives for ``parameter = value``."""
    text = STUDY.format(parameter=parameter, value=value)
    if parameter == "gamma":
        text = text.replace("gamma = 0.5\n", "", 1)
    return parse_study(text, "ranges.toml").parameters[parameter]


# --- the values ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "table, expected",
    [
        ("{ start = 0.1, stop = 2.0, num = 64 }", np.linspace(0.1, 2.0, 64)),
        ("{ start = 0.0, stop = 0.8, num = 64 }", np.linspace(0.0, 0.8, 64)),
        ("{ start = 2.0, stop = 0.1, num = 7 }", np.linspace(2.0, 0.1, 7)),
        ("{ start = 0.5, stop = 0.5, num = 1 }", np.array([0.5])),
        ("{ start = 0.5, stop = 3, num = 1 }", np.linspace(0.5, 3.0, 1)),
    ],
)
def test_a_range_is_numpy_linspace_exactly(table, expected):
    values = swept(table, "gamma")
    np.testing.assert_array_equal(values, expected)
    assert values[0] == expected[0] and values[-1] == expected[-1]  # endpoints exact


def test_bounds_may_be_expressions():
    values = swept('{ start = "pi/6", stop = "pi/3", num = 5 }')
    np.testing.assert_array_equal(values, np.linspace(math.pi / 6, math.pi / 3, 5))
    assert values[0] == math.pi / 6 and values[-1] == math.pi / 3


def test_a_log_range_is_numpy_geomspace_exactly():
    values = swept('{ start = 1e-3, stop = 1e3, num = 7, scale = "log" }', "gamma")
    np.testing.assert_array_equal(values, np.geomspace(1e-3, 1e3, 7))
    # Evenly spaced in log: each value ten times the previous, to rounding (a few ulp).
    np.testing.assert_allclose(np.diff(np.log10(values)), 1.0, rtol=0, atol=1e-12)
    assert values[0] == 1e-3 and values[-1] == 1e3


@pytest.mark.parametrize(
    "table, expected",
    [
        # 0.1 * 3 = 0.30000000000000004 passes stop by 4e-17 (rounding): stop itself.
        ("{ start = 0, stop = 0.3, step = 0.1 }", [0.0, 0.1, 0.2, 0.3]),
        ("{ start = 0.3, stop = 0, step = -0.1 }", [0.3, 0.3 - 0.1, 0.3 - 0.2, 0.0]),
        # 0.9 < 1 and 1.2 > 1: stop is not reached, the last value is 0.3 * 3.
        ("{ start = 0, stop = 1, step = 0.3 }", [0.0, 0.3, 0.6, 0.3 * 3]),
        ("{ start = 2, stop = 2, step = 0.5 }", [2.0]),
        ('{ start = "pi/4", stop = "pi/2", step = "pi/8" }', [math.pi / 4, math.pi / 4 + math.pi / 8, math.pi / 2]),
    ],
)
def test_a_step_range_goes_from_start_to_stop(table, expected):
    assert swept(table, "gamma" if "pi" not in table else "kappa") == expected


@given(
    start=st.floats(-10, 10),
    span=st.floats(1e-3, 10),
    count=st.integers(1, 200),
    descending=st.booleans(),
)
def test_step_ranges_are_start_plus_k_step_and_never_pass_stop(start, span, count, descending):
    step = span / count * (-1 if descending else 1)
    stop = start + span * (-1 if descending else 1)
    text = STUDY.format(parameter="x", value=f"{{ start = {start!r}, stop = {stop!r}, step = {step!r} }}")
    text = text.replace('drive = { D1 = 0.05 }', 'drive = { D1 = "x" }')
    values = np.array(parse_study(text).parameters["x"])
    k = np.arange(values.size)
    # Every value but a last one snapped to stop is start + k step, computed the same way.
    np.testing.assert_array_equal(values[:-1], start + step * k[:-1])
    assert values[-1] == stop or values[-1] == start + step * k[-1]
    # Not past stop (beyond the rounding tolerance), and no room for one more step.
    direction = np.sign(step)
    assert direction * (values[-1] - stop) <= RANGE_STEP_TOL * abs(step)
    assert direction * (stop - values[-1]) < abs(step) * (1 + 1e-9)
    # (stop - start) / step = count in real numbers; in floats within ~1e-10 of it (stop is
    # rounded to ~1e-15 |start|, step >= 5e-6), well inside RANGE_STEP_TOL: count + 1 values.
    assert values.size == count + 1


def test_a_long_explicit_sweep_is_checked_for_repeats_in_linear_time():
    # 100,000 values took 118 s with list.count (quadratic); a set takes well under a second.
    values = np.linspace(0.1, 2.0, 100_000)
    listed = "[" + ", ".join(repr(float(v)) for v in values) + "]"
    np.testing.assert_array_equal(swept(listed, "gamma"), values)
    repeated = "[" + ", ".join(repr(float(v)) for v in values) + ", 0.1, 2.0]"
    with pytest.raises(StudyFileError, match=r"parameters\.gamma: value\(s\) 0\.1, 2 appear more than once"):
        swept(repeated, "gamma")


# --- bad ranges: exit 2 from `ncstab run`, the key named ------------------------------------------

BAD_RANGES = [
    ("{ start = 0.1, stop = 2.0, num = 0 }", "parameters.gamma.num", "from 1 to"),
    ("{ start = 0.1, stop = 2.0, num = -3 }", "parameters.gamma.num", "from 1 to"),
    ("{ start = 0.5, stop = 0.5, num = 3 }", "parameters.gamma.num", "would repeat"),
    ("{ start = 0.1, stop = inf, num = 3 }", "parameters.gamma.stop", "not finite"),
    ("{ start = nan, stop = 2.0, num = 3 }", "parameters.gamma.start", "not finite"),
    ('{ start = "1/0", stop = 2.0, num = 3 }', "parameters.gamma.start", "cannot be evaluated"),
    ("{ start = 0.1, stop = 2.0, num = 3, step = 0.1 }", "parameters.gamma.step", "not both"),
    ("{ start = 0.1, stop = 2.0 }", "parameters.gamma", "needs num"),
    ("{ stop = 2.0, num = 3 }", "parameters.gamma", "needs start"),
    ("{ start = 0.1, stop = 2.0, nm = 3 }", "parameters.gamma.nm", "did you mean 'num'"),
    ("{ start = 0.1, stop = 2.0, num = 3.0 }", "parameters.gamma.num", "TOML integer"),
    ("{ start = 0.1, stop = 2.0, num = true }", "parameters.gamma.num", "TOML integer"),
    ('{ start = 0, stop = 2.0, num = 3, scale = "log" }', "parameters.gamma.start", "bounds > 0"),
    ('{ start = 1, stop = -2.0, num = 3, scale = "log" }', "parameters.gamma.stop", "bounds > 0"),
    ('{ start = 1, stop = 2.0, num = 3, scale = "ln" }', "parameters.gamma.scale", "linear, log"),
    ('{ start = 1, stop = 2.0, step = 0.1, scale = "log" }', "parameters.gamma.scale", "not step"),
    (f"{{ start = 0.1, stop = 2.0, num = {MAX_RANGE_VALUES + 1} }}", "parameters.gamma.num", "from 1 to"),
    ("{ start = 0, stop = 2.0, step = 1e-9 }", "parameters.gamma.step", "more than"),
    ("{ start = 0, stop = 2.0, step = 0 }", "parameters.gamma.step", "does not go from"),
    ("{ start = 0, stop = 2.0, step = -0.5 }", "parameters.gamma.step", "does not go from"),
    ("{ start = -1, stop = 2.0, num = 4 }", "parameters.gamma", ">= 0"),  # the law's own range
]


@pytest.mark.parametrize("table, field, message", BAD_RANGES, ids=[b[1] + ":" + b[2] for b in BAD_RANGES])
def test_a_bad_range_exits_2_naming_the_key(table, field, message, tmp_path, monkeypatch, capsys):
    study = tmp_path / "bad_range.toml"
    study.write_text(STUDY.format(parameter="gamma", value=table).replace("gamma = 0.5\n", "", 1))
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(study)]) == 2
    errors = capsys.readouterr().err
    line = next((line for line in errors.splitlines() if f": {field}: " in line), None)
    assert line is not None, errors
    assert message in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad_range.toml"]  # nothing run or written


def test_a_range_in_system_is_refused():
    text = STUDY.format(parameter="kappa", value="1.0").replace(
        "[laws]", '[system]\nalpha0 = { start = 0.5, stop = 1.0, num = 3 }\n[laws]'
    )
    with pytest.raises(StudyFileError, match=r"system\.alpha0: a sweep \(range\) belongs in \[parameters\]"):
        parse_study(text)
