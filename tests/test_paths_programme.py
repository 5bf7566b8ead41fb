"""Loading programmes: malformed ones are refused, naming the stage and the field.

Also the other inputs of ``follow``: parameters, options and the system
specification are checked before any path is computed.
"""

from __future__ import annotations

import numpy as np
import pytest

from ncstab.paths import (
    CycleStage,
    PathOptions,
    ProgrammeError,
    Stage,
    SystemSpec,
    follow,
    parse_programme,
)

GOOD = {"hold": {"F2": 0.0}, "drive": {"D1": 0.1}}

#: (programme, 1-based stage or None, field) of every malformed programme.
BAD_PROGRAMMES = {
    "dof controlled twice": (
        [GOOD, {"hold": {"D1": 0.0, "F2": 0.0}, "drive": {"F1": 0.5}}],
        2,
        "drive.F1",
    ),
    "dof controlled twice by holds": (
        [{"hold": {"D1": 0.0, "F1": 0.0}, "drive": {"D2": 0.1}}],
        1,
        "hold.F1",
    ),
    "dof not controlled": ([{"drive": {"D1": 0.1}}], 1, "hold"),
    "unknown driven quantity": ([{"hold": {"F2": 0.0}, "drive": {"D3": 0.1}}], 1, "drive.D3"),
    "unknown held quantity": (
        [GOOD, {"hold": {"D3": 0.0, "F2": 0.0}, "drive": {"D1": 0.1}}],
        2,
        "hold.D3",
    ),
    "nothing driven": ([{"hold": {"F2": 0.0, "D1": 0.1}}], 1, "drive"),
    "a dof driven twice": ([{"hold": {"F2": 0.0}, "drive": {"D1": 0.1, "F1": 0.2}}], 1, "drive.F1"),
    "a load parameter on a system without one": ([{"drive": {"P": 2.0}}], 1, "drive.P"),
    "a cycle plane naming an unknown dof": (
        [GOOD, {"cycle": {"center": [0.0, 0.0], "dofs": ["D1", "D_top"]}}],
        2,
        "cycle.dofs",
    ),
    "a cycle plane naming one dof twice": ([GOOD, {"cycle": {"dofs": ["D2", "D2"]}}], 2, "cycle.dofs"),
    "held and driven": ([{"hold": {"F2": 0.0, "D1": 0.0}, "drive": {"D1": 0.1}}], 1, "drive.D1"),
    "current as a drive target": (
        [{"hold": {"F2": 0.0}, "drive": {"D1": "current"}}],
        1,
        "drive.D1",
    ),
    "unknown stop_at event": ([GOOD, {**GOOD, "stop_at": ["buckling"]}], 2, "stop_at"),
    "stop_at not a list": ([{**GOOD, "stop_at": 3}], 1, "stop_at"),
    "boolean value": ([{"hold": {"F2": True}, "drive": {"D1": 0.1}}], 1, "hold.F2"),
    "non-finite value": ([{"hold": {"F2": 0.0}, "drive": {"D1": float("inf")}}], 1, "drive.D1"),
    "not a parameter name": ([{"hold": {"F2": "2 x"}, "drive": {"D1": 0.1}}], 1, "hold.F2"),
    "cycle with turns = 0": (
        [GOOD, {"cycle": {"center": [0.0, 0.0], "turns": 0}}],
        2,
        "cycle.turns",
    ),
    "cycle with fractional turns": ([GOOD, {"cycle": {"turns": 1.5}}], 2, "cycle.turns"),
    "cycle with direction = 2": (
        [GOOD, {"cycle": {"center": [0.0, 0.0], "direction": 2}}],
        2,
        "cycle.direction",
    ),
    "cycle centre of wrong length": (
        [GOOD, {"cycle": {"center": [0.0, 0.0, 0.0]}}],
        2,
        "cycle.center",
    ),
    "cycle with an unknown key": ([GOOD, {"cycle": {"centre": [0.0, 0.0]}}], 2, "cycle.centre"),
    "cycle with hold": ([GOOD, {"cycle": {}, "hold": {"F2": 0.0}}], 2, "hold"),
    "unknown key in a stage": ([{**GOOD, "stopat": ["limit_point"]}], 1, "stopat"),
    "stage not a table": ([GOOD, 3], 2, "loading"),
    "empty programme": ([], None, "loading"),
}


@pytest.mark.parametrize("name", list(BAD_PROGRAMMES))
def test_a_malformed_programme_names_its_stage_and_field(name):
    stages, stage, field = BAD_PROGRAMMES[name]
    with pytest.raises(ProgrammeError) as error:
        parse_programme(stages)
    assert error.value.stage == stage
    assert error.value.field == field
    text = str(error.value)
    assert repr(field) in text
    assert (
        (f"loading stage {stage}," in text) if stage is not None else ("loading programme" in text)
    )


def test_programme_error_is_a_value_error_and_follow_raises_it():
    with pytest.raises(ProgrammeError) as error:
        follow(
            "diamond",
            "mcnamara",
            [GOOD, {"hold": {"F2": 0.0}, "drive": {"D3": 0.2}}],
            {"gamma": 0.5},
        )
    assert isinstance(error.value, ValueError)
    assert (error.value.stage, error.value.field) == (2, "drive.D3")


def test_a_valid_programme_parses_to_stages():
    programme = parse_programme(
        [
            {"hold": {"F1": 0.0}, "drive": {"F2": "F2l"}},
            {"hold": {"F2": "current"}, "drive": {"D1": 0.6}, "stop_at": "limit_point"},
            {"cycle": {"center": ["c1", 0.0], "turns": 2, "direction": -1}},
        ]
    )
    first, second, third = programme.stages
    assert first == Stage({"F1": 0.0}, {"F2": "F2l"}, ())
    assert second.driven == ("D1", 0.6) and second.stop_at == ("limit_point",)
    assert third == CycleStage(("c1", 0.0), 2, -1, ())
    # 'current' is a keyword, not a parameter.
    assert programme.parameter_references() == {"F2l", "c1"}
    # Built stages are re-validated: parsing is idempotent.
    assert parse_programme(programme.stages) == programme


def test_a_built_stage_is_revalidated():
    with pytest.raises(ProgrammeError) as error:
        parse_programme([Stage(hold={"F2": 0.0}, drive={"D1": "current"})])
    assert (error.value.stage, error.value.field) == (1, "drive.D1")


# --- parameters, options and the system: checked before any path is followed --------------


def test_an_undefined_parameter_is_named():
    with pytest.raises(ValueError, match="undefined parameter.*'F2l'"):
        follow(
            "diamond",
            "mcnamara",
            [{"hold": {"F1": 0.0}, "drive": {"F2": "F2l"}}],
            {"gamma": 0.5, "alpha0": np.pi / 4},
        )


@pytest.mark.parametrize("unused", [{"F2l": 0.3}, {"bogus": [0.1, 0.2]}])
def test_an_unused_parameter_is_named(unused):
    name = next(iter(unused))
    with pytest.raises(ValueError, match=f"'{name}'.*used by neither"):
        follow("diamond", "mcnamara", [GOOD], {"gamma": 0.5, **unused})


@pytest.mark.parametrize(
    ("parameters", "name"),
    [
        ({"gamma": []}, "gamma"),
        ({"gamma": [0.5, float("nan")]}, "gamma"),
        ({"gamma": "big"}, "gamma"),
    ],
)
def test_a_bad_parameter_value_is_named(parameters, name):
    with pytest.raises(ValueError, match=f"'{name}'"):
        follow("diamond", "mcnamara", [GOOD], parameters)


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("rtol", 0.0),
        ("atol", -1e-12),
        ("newton_tol", float("nan")),
        ("initial_step", "small"),
        ("min_step", 0.0),
        ("max_step", float("inf")),
        ("event_tol", -1.0),
        ("max_steps", 0),
        ("max_steps", 2.5),
        ("newton_max_iter", 0),
    ],
)
def test_a_bad_option_is_named(option, value):
    with pytest.raises(ValueError, match=f"PathOptions.{option} "):
        PathOptions(**{option: value})


def test_min_step_above_max_step_is_refused():
    with pytest.raises(ValueError, match="min_step"):
        PathOptions(min_step=0.1, max_step=0.01)


@pytest.mark.parametrize(
    ("field", "value"), [("secondary_contacts", "maybe"), ("name", "hexagon"), ("normal", "soft")]
)
def test_a_bad_system_spec_is_named(field, value):
    with pytest.raises(ValueError) as error:
        SystemSpec(**{field: value})
    text = str(error.value)
    assert repr(value) in text
    assert field in text or (field == "name" and "system" in text)


def test_options_are_frozen():
    options = PathOptions()
    with pytest.raises(AttributeError):
        options.rtol = 1.0  # type: ignore[misc]
