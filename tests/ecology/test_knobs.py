"""The shared knobs: validation, schedules and their string form."""

from __future__ import annotations

import numpy as np
import pytest

from ecology import TEST_MDP, Ecology, Schedule, parse_schedule, schedule_value, validation_seeds


def test_defaults_are_the_test_mdp():
    assert Ecology().is_test_mdp
    assert Ecology(**TEST_MDP).is_test_mdp
    assert not Ecology(dynamism=0.1).is_test_mdp


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("0.5", [(0, 0.5), (10**9, 0.5)]),
        ("const:1", [(0, 1.0), (5, 1.0)]),
        ("linear:1:0:280000", [(0, 1.0), (140_000, 0.5), (280_000, 0.0), (10**7, 0.0)]),
        ("linear:0:1:100", [(0, 0.0), (25, 0.25), (100, 1.0)]),
        ("step:1:100:0.5:200:0", [(0, 1.0), (99, 1.0), (100, 0.5), (199, 0.5), (200, 0.0), (1000, 0.0)]),
        ("step:1:0:0.5", [(0, 0.5), (10, 0.5)]),  # a step at 0: the new value from the first step on
    ],
)
def test_schedules_parse_and_evaluate(text, expected):
    schedule = parse_schedule(text)
    for t, value in expected:
        assert schedule(t) == pytest.approx(value)
        assert schedule_value(schedule.breakpoints, float(t)) == pytest.approx(value)
    assert parse_schedule(str(schedule)) == schedule


@pytest.mark.parametrize("bad", ["", "linear:1:0", "linear:1:0:0", "step:1:100", "fast:1", "linear:a:b:c",
                                 "step:1:200:0:100:1"])
def test_malformed_schedules_name_the_accepted_forms(bad):
    with pytest.raises(ValueError, match="schedule|steps|breakpoints"):
        parse_schedule(bad)


@pytest.mark.parametrize("bad", [-0.1, 1.01, float("nan"), float("inf"), "1.5", "linear:2:0:10"])
def test_strength_outside_unit_interval_is_refused(bad):
    with pytest.raises(ValueError, match=r"must lie in \[0, 1\]"):
        Ecology(shaping=bad)


@pytest.mark.parametrize("bad", [-0.01, 1.5, float("nan")])
def test_dynamism_outside_unit_interval_is_refused(bad):
    with pytest.raises(ValueError, match=r"dynamism must lie in \[0, 1\], got"):
        Ecology(dynamism=bad)


def test_type_errors_name_the_knob():
    with pytest.raises(TypeError, match="dynamism must be a number"):
        Ecology(dynamism="high")
    with pytest.raises(TypeError, match="reset_free must be True or False"):
        Ecology(reset_free="yes")
    with pytest.raises(ValueError, match="unknown reward mode 'dense'; choose one of sparse"):
        Ecology(reward="dense")


def test_ecology_is_frozen_and_serialisable():
    eco = Ecology(dynamism=np.float32(0.25), shaping="linear:1:0:100", reset_free=True, reward="distance")
    assert eco.dynamism == 0.25 and isinstance(eco.dynamism, float)
    assert eco.as_dict() == {"dynamism": 0.25, "shaping": "linear:1:0:100", "reset_free": True,
                             "reward": "distance"}
    with pytest.raises(AttributeError):
        eco.dynamism = 0.5  # type: ignore[misc]
    assert Schedule.constant(0).is_zero and not parse_schedule("linear:1:0:5").is_zero


def test_validation_seeds_are_fixed_and_far_from_training_seeds():
    seeds = validation_seeds()
    assert len(seeds) == 100 == len(set(seeds))
    assert seeds == validation_seeds()
    assert min(seeds) > 10**6


def test_schedules_refuse_endless_steps_and_say_what_none_should_be():
    """'linear:1:0:inf' read as a constant 1, None named only numbers, and -0.0 printed as '-0'."""
    with pytest.raises(ValueError, match="finite"):
        parse_schedule("linear:1:0:inf")
    with pytest.raises(TypeError, match="linear:START:END:STEPS.*pass 0 for no shaping"):
        parse_schedule(None)
    assert str(parse_schedule(-0.0)) == "0"
