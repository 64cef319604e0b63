"""The env contract of `ecology.contract`, and that both env packages implement it the same way."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import foodcollector
import gridtasks
from ecology import (
    EcologicalEnv,
    InvalidAction,
    VisitGrid,
    check_action,
    check_render_mode,
    check_reset_mask,
    make_test_mdp_kwargs,
    render_mode_missing,
)

ENV_IDS = [*gridtasks.ENV_IDS.values(), foodcollector.ENV_ID]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_implements_the_contract(env_id):
    env = gym.make(env_id).unwrapped
    assert isinstance(env, EcologicalEnv)
    view, inventory = env.observation_split
    assert view + inventory == env.observation_space.shape[0]
    assert set(env.test_mdp_kwargs()) >= {"dynamism", "shaping", "reset_free", "reward", "horizon"}
    assert "horizon" in type(env).parameter_names()
    assert len(env.visit_grid.shape) == 2


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("action", [2.5, "1", None, True, np.array([1]), -1, 10_000])
def test_both_env_packages_refuse_a_bad_action_alike(env_id, action):
    env = gym.make(env_id).unwrapped
    env.reset(seed=0)
    with pytest.raises(InvalidAction, match="invalid action"):
        env.step(action)


def test_an_invalid_action_is_both_a_value_and_a_type_error():
    for kind in (ValueError, TypeError):
        with pytest.raises(kind):
            check_action(1.0, 7)
    assert check_action(np.int32(3), 7) == 3 and check_action(np.array(6), 7) == 6


def test_render_mode_must_be_none_or_listed():
    assert check_render_mode(None, ["rgb_array"]) is None
    assert check_render_mode("rgb_array", ["rgb_array"]) == "rgb_array"
    with pytest.raises(ValueError, match="unknown render_mode 'human'"):
        check_render_mode("human", ["rgb_array"])


def test_a_reset_mask_is_checked_once_for_both_vector_envs():
    assert check_reset_mask(None, 3) is None and check_reset_mask({"seed": 1}, 3) is None
    np.testing.assert_array_equal(check_reset_mask({"reset_mask": [True, False, False]}, 3), [True, False, False])
    assert not check_reset_mask({"reset_mask": np.zeros(3, bool)}, 3).any()  # the grid engine: a no-op reset
    for bad, at_least_one in ((np.array([1, 0, 0]), False), (np.ones(2, bool), False), (np.zeros(3, bool), True)):
        with pytest.raises(ValueError, match=r"must be a boolean array of shape \(3,\)"):
            check_reset_mask({"reset_mask": bad}, 3, at_least_one)


def test_render_without_a_render_mode_warns_alike_everywhere():
    assert render_mode_missing("rgb_array") is False
    with pytest.warns(UserWarning, match="render\\(\\) called without render_mode; pass render_mode='rgb_array'"):
        assert render_mode_missing(None) is True


def test_the_test_mdp_sets_the_knobs_and_the_horizon_over_the_task_parameters():
    kwargs = make_test_mdp_kwargs({"horizon": 50, "dynamism": 0.3, "grid_size": 8}, 100, initial_count=1)
    assert kwargs == {"horizon": 100, "dynamism": 0.0, "grid_size": 8, "shaping": 0.0, "reset_free": False,
                      "reward": "sparse", "initial_count": 1}


def test_visit_grid_maps_positions_to_cells():
    cells = VisitGrid((8, 8)).cells(np.array([[1, 2], [7, 0]]))
    assert [c.tolist() for c in cells] == [[2, 0], [1, 7]]
    arena = VisitGrid((20, 20), (-50.0, -50.0), 0.2)
    rows, cols = arena.cells(np.array([[-50.0, 49.99], [0.0, -60.0], [52.0, 0.0]]))
    assert rows.tolist() == [19, 0, 10] and cols.tolist() == [0, 10, 19]
