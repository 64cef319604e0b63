"""Contract tests over every registered grid task: Gymnasium's checker, determinism, rendering, pickling."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import gridtasks

IDS = sorted(gridtasks.ENV_IDS.values())
KNOBS = [
    {},
    {"dynamism": 0.5},
    {"dynamism": 1.0, "reset_free": True},
    {"shaping": 1.0},
    {"shaping": "linear:1:0:1000", "reset_free": True},
    {"shaping": "step:1:50:0.5:100:0"},
    {"reward": "subgoal"},
    {"reward": "one_time", "reset_free": True},
    {"reward": "distance", "dynamism": 0.1, "shaping": 0.5},
]


def rollout(env, seed: int, steps: int, action_seed: int = 0):
    """Observations, rewards and ends of a random rollout (resetting when an episode ends)."""
    actions = np.random.default_rng(action_seed).integers(0, 7, steps)
    obs, _ = env.reset(seed=seed)
    trace = [obs]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(int(a))
        trace += [obs, np.array([reward, terminated, truncated, *info["agent_pos"]])]
        if terminated or truncated:
            obs, _ = env.reset()
            trace.append(obs)
    return np.concatenate([np.ravel(t) for t in trace])


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("knobs", KNOBS, ids=lambda k: ",".join(f"{a}={b}" for a, b in k.items()) or "default")
def test_check_env(env_id, knobs):
    env = gym.make(env_id, **knobs)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.unwrapped.ecology.reset_free == knobs.get("reset_free", False)


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_same_trajectory(env_id):
    kw = {"dynamism": 0.3, "shaping": "linear:1:0:500"}
    a = rollout(gym.make(env_id, **kw), seed=7, steps=600)
    b = rollout(gym.make(env_id, **kw), seed=7, steps=600)
    c = rollout(gym.make(env_id, **kw), seed=8, steps=600)
    np.testing.assert_array_equal(a, b)
    assert a.shape != c.shape or not np.array_equal(a, c)


@pytest.mark.parametrize("env_id", IDS)
def test_render_rgb_array(env_id):
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(0)
    frame = env.render()
    n = env.unwrapped.config.grid_size
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.shape[1] == n * 48 and frame.shape[0] > n * 48
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 5


@pytest.mark.parametrize("env_id", IDS)
def test_pickle_round_trip_continues_identically(env_id):
    env = gym.make(env_id, dynamism=0.5, reset_free=True).unwrapped
    env.reset(seed=3)
    for a in range(40):
        env.step(a % 7)
    clone = pickle.loads(pickle.dumps(env))
    for a in np.random.default_rng(1).integers(0, 7, 200):
        o1, r1, *_ = env.step(int(a))
        o2, r2, *_ = clone.step(int(a))
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2


@pytest.mark.parametrize("env_id", IDS)
def test_reset_free_never_ends_and_episodic_truncates_at_horizon(env_id):
    free = gym.make(env_id, reset_free=True)
    free.reset(seed=0)
    for _ in range(1500):
        _, _, terminated, truncated, _ = free.step(free.action_space.sample())
        assert not (terminated or truncated)
    episodic = gym.make(env_id, horizon=30)
    episodic.reset(seed=0)
    for t in range(1, 31):
        _, _, terminated, truncated, _ = episodic.step(0)  # walking west never completes a task
        assert not terminated
        assert truncated == (t == 30)


@pytest.mark.parametrize("env_id", IDS)
def test_observation_split_matches_space(env_id):
    env = gym.make(env_id).unwrapped
    view, inventory = env.observation_split
    assert view + inventory == env.observation_space.shape[0]
    assert view == 25 * inventory
    obs, _ = env.reset(seed=0)
    assert obs[:view].reshape(inventory, 25).sum(axis=0).min() >= 1  # every view cell shows something


@pytest.mark.parametrize("env_id", IDS)
def test_test_mdp_kwargs_make_the_evaluation_env(env_id):
    env = gym.make(env_id, dynamism=0.2, shaping=1.0, reset_free=True, reward="distance").unwrapped
    test_env = gym.make(env_id, **env.test_mdp_kwargs()).unwrapped
    assert test_env.ecology.is_test_mdp
    assert test_env.config.grid_size == env.config.grid_size
    trained_long = gym.make(env_id, horizon=999).unwrapped
    assert gym.make(env_id, **trained_long.test_mdp_kwargs()).unwrapped.config.horizon == env.config.horizon


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"reward": "dense"}, "unknown reward mode"),
        ({"dynamism": 1.5}, "dynamism must lie in"),
        ({"dynamism": -0.1}, "dynamism must lie in"),
        ({"shaping": "linear:1:0"}, "malformed shaping schedule"),
        ({"shaping": "quadratic:1:2"}, "malformed shaping schedule"),
        ({"shaping": 2.0}, "must lie in"),
        ({"horizon": 0}, "horizon must be an integer"),
        ({"grid_size": 3}, "grid_size must be an integer"),
        ({"render_mode": "human"}, "unknown render_mode"),
    ],
)
def test_bad_knobs_raise_clear_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        gridtasks.SaladEnv(**kwargs)


def test_unknown_task_parameter_lists_the_valid_ones():
    with pytest.raises(TypeError, match="valid task parameters: .*grid_size"):
        gridtasks.SaladEnv(deer_speed=0.2)
    with pytest.raises(TypeError, match=r"\['dynamsim'\] \(did you mean dynamism\?\); the knobs: dynamism"):
        gridtasks.SaladEnv(dynamsim=0.1)  # a misspelt knob is named, as the command line names a misspelt flag


def test_task_specific_choices_are_validated():
    with pytest.raises(ValueError, match="unknown deer_kind 'fast'"):
        gridtasks.HuntingEnv(deer_kind="fast")
    with pytest.raises(ValueError, match="deer_speed must be a probability"):
        gridtasks.HuntingEnv(deer_speed=1.2)
    with pytest.raises(ValueError, match="predator_count"):
        gridtasks.ScavengingEnv(predator_count=9)


@pytest.mark.parametrize("make, who", [
    (lambda: gridtasks.SaladEnv(initial_count=18), "37 free cells at reset \\(36 objects and the agent\\)"),
    (lambda: gridtasks.HuntingEnv(deer_count=34, axe_count=2), "37 free cells .* and the agent\\)"),
    (lambda: gridtasks.ScavengingEnv(food_count=63),
     "65 free cells at reset \\(63 objects, the agent and a predator\\)"),
])
def test_more_objects_than_the_grid_holds_are_refused(make, who):
    with pytest.raises(ValueError, match=f"needs {who}, but its .* grid has .*; lower the object counts"):
        make()


def test_the_fullest_grid_that_fits_still_resets():
    env = gridtasks.SaladEnv(initial_count=17)  # 34 objects + the agent in 36 cells
    env.reset(seed=0)
    assert (env.unwrapped._state[0]["agent"] >= 0).all()


@pytest.mark.parametrize("action", [-1, 7, 2.0, "north", None, True, np.array([1, 2])])
def test_action_outside_the_space_is_refused(action):
    env = gridtasks.SaladEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="invalid action"):
        env.step(action)


def test_numpy_integer_actions_are_accepted():
    env = gridtasks.SaladEnv()
    env.reset(seed=0)
    env.step(np.int64(3))
    env.step(np.array(4))


def test_step_before_reset_is_refused():
    with pytest.raises(RuntimeError, match="reset"):
        gridtasks.SaladEnv().step(0)


@pytest.mark.parametrize("env_id, name", [("gridtasks/Salad-v0", "walls"), ("gridtasks/Salad-v0", "regrow_when_empty"),
                                          ("gridtasks/Hunting-v0", "replenish"),
                                          ("gridtasks/Scavenging-v0", "spawn_on_agent")])
@pytest.mark.parametrize("value", ["no", 5, 0.5])
def test_on_off_parameters_refuse_anything_but_a_bool(env_id, name, value):
    """walls='no' used to build the walls (any truthy value read as on)."""
    with pytest.raises(ValueError, match=f"{name} must be True or False, got {value!r}"):
        gym.make(env_id, **{name: value})
    with pytest.raises(ValueError, match=f"{name} must be True or False"):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **{name: value})
    assert getattr(gym.make(env_id, **{name: np.bool_(False)}).unwrapped.config, name) is False


@pytest.mark.parametrize("kwargs, message", [
    ({"predator_count": 2.5}, "predator_count must be an integer >= 0, got 2.5"),
    ({"predator_count": "2"}, "predator_count must be an integer >= 0, got '2'"),
    ({"predator_penalty": float("nan")}, "predator_penalty is a cost and must be a finite number >= 0, got nan"),
    ({"predator_penalty": float("inf")}, "must be a finite number >= 0, got inf"),
    ({"predator_penalty": "100"}, "must be a finite number >= 0, got '100'"),
])
def test_scavenging_predator_settings_are_checked(kwargs, message):
    """A fractional count and a NaN or infinite penalty used to be accepted, a string raised a bare TypeError."""
    with pytest.raises(ValueError, match=message):
        gym.make("gridtasks/Scavenging-v0", **kwargs)


@pytest.mark.parametrize("knobs, ended", [({"horizon": 3}, "truncated"), ({"predator_count": 0}, "terminated")])
def test_stepping_an_ended_episode_is_refused_until_reset(knobs, ended):
    """The single env used to step on after its episode ended (the food collector refuses, and so does this)."""
    env = gym.make("gridtasks/Scavenging-v0", **knobs)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(20_000):  # episodes until one ends the way asked
        _, _, terminated, truncated, _ = env.step(int(rng.integers(7)))
        if (terminated or truncated) and ("terminated" if terminated else "truncated") == ended:
            break
        if terminated or truncated:
            env.reset()
    else:
        pytest.fail(f"no episode {ended} in 20 000 random steps")
    with pytest.raises(RuntimeError, match=f"the episode ended \\({ended}\\); call reset\\(\\)"):
        env.step(0)
    env.reset()
    env.step(0)


def test_the_reward_bound_covers_a_costlier_predator():
    """reward_bound stayed 200 with predator_penalty=1000, which the divergence rule scales by."""
    assert gym.make("gridtasks/Scavenging-v0").unwrapped.reward_bound == 200.0
    assert gym.make("gridtasks/Scavenging-v0", predator_penalty=1000.0).unwrapped.reward_bound == 1100.0
