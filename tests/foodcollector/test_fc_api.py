"""Gymnasium contract, the shared ecology contract, determinism, pickling, rendering and bad input."""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import foodcollector
from ecology import TEST_MDP, Ecology
from foodcollector import ENV_ID, FoodCollectorParams, decode_action, encode_action

REPO = Path(__file__).resolve().parents[2]
KNOB_GRID = [
    {"dynamism": d, "shaping": s, "reset_free": r}
    for d in (0.0, 0.5, 1.0) for s in (0.0, 1.0, "linear:1:0:1000") for r in (True, False)
]


def rollout_digest(env, seed: int, steps: int) -> str:
    """SHA-256 of every observation, reward and agent position of a seeded random-action rollout."""
    h = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    actions = np.random.default_rng(seed).integers(0, 27, size=steps)
    h.update(obs.tobytes())
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(int(a))
        h.update(obs.tobytes())
        h.update(np.array([reward, *info["agent_pos"]], dtype=np.float64).tobytes())
        if truncated:
            obs, info = env.reset()
    return h.hexdigest()


@pytest.mark.parametrize("knobs", KNOB_GRID, ids=lambda k: "-".join(f"{v}" for v in k.values()))
def test_check_env_passes_for_every_knob(knobs):
    env = gymnasium.make(ENV_ID, render_mode="rgb_array", **knobs)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=False)
    assert [str(w.message) for w in caught] == []


def test_registration_and_spaces():
    env = gymnasium.make(ENV_ID)
    assert env.spec.max_episode_steps is None
    assert env.action_space == gymnasium.spaces.Discrete(27)
    assert env.observation_space.shape == (53,) and env.observation_space.dtype == np.float32
    assert env.unwrapped.observation_split == (49, 4)
    assert sum(env.unwrapped.observation_split) == env.observation_space.shape[0]


def test_ecology_attribute_is_resolved():
    env = gymnasium.make(ENV_ID, dynamism=0.5, shaping="linear:1:0:1000", reset_free=True)
    eco = env.unwrapped.ecology
    assert isinstance(eco, Ecology)
    assert (eco.dynamism, eco.reset_free, eco.reward) == (0.5, True, "sparse")
    assert eco.shaping(0) == 1.0 and eco.shaping(500) == 0.5 and eco.shaping(2000) == 0.0


def test_test_mdp_kwargs_make_the_evaluation_mdp():
    env = gymnasium.make(ENV_ID, dynamism=1.0, shaping=1.0, reset_free=True, num_green=10, horizon=200)
    kwargs = env.unwrapped.test_mdp_kwargs()
    json.dumps(kwargs)  # plain values, fit for a config file
    test_env = gymnasium.make(ENV_ID, **kwargs).unwrapped
    assert test_env.ecology.is_test_mdp
    assert test_env.params.num_green == 10  # the same task parameters...
    assert test_env.params.horizon == foodcollector.UNITY_EPISODE_DECISIONS  # ...Unity's episode length
    assert {k: kwargs[k] for k in TEST_MDP} == TEST_MDP


def test_info_keys_and_lifetime_counter(make_env):
    env = make_env(seed=1, horizon=3)
    for _ in range(3):
        _, _, terminated, truncated, info = env.step(0)
    assert truncated and not terminated
    assert {"green_eaten", "red_eaten", "agent_pos", "lifetime_step", "solved"} <= set(info)
    assert info["solved"] is False
    assert info["agent_pos"].shape == (2,) and info["agent_pos"].dtype == np.float64
    assert info["lifetime_step"] == 3
    _, info = env.reset()  # an unseeded reset keeps the lifetime going
    assert info["lifetime_step"] == 3
    _, _, _, _, info = env.step(0)
    assert info["lifetime_step"] == 4 and info["episode_step"] == 1
    _, info = env.reset(seed=1)  # a seeded reset starts a new lifetime
    assert info["lifetime_step"] == 0


def test_episodic_truncates_at_horizon_and_then_refuses_to_step(make_env):
    env = make_env(horizon=5).unwrapped
    flags = [env.step(0)[3] for _ in range(5)]
    assert flags == [False] * 4 + [True]
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)
    env.reset()
    assert env.step(0)[3] is False


def test_default_horizon_is_unitys_1000(make_env):
    env = make_env()
    truncated = [env.step(0)[3] for _ in range(1000)]
    assert truncated.index(True) == 999


def test_vector_env_stacks_agent_positions():
    envs = gymnasium.vector.SyncVectorEnv([lambda: gymnasium.make(ENV_ID)] * 3)
    envs.reset(seed=[0, 1, 2])
    _, _, _, _, info = envs.step(np.full(3, 9))
    assert info["agent_pos"].shape == (3, 2) and info["agent_pos"].dtype == np.float64


def test_step_before_reset_raises():
    env = foodcollector.FoodCollectorEnv()
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)


def test_same_seed_same_trajectory_in_process():
    for knobs in ({}, {"dynamism": 1.0, "shaping": "linear:1:0:100", "reset_free": True}):
        a = rollout_digest(gymnasium.make(ENV_ID, horizon=150, **knobs), seed=7, steps=400)
        b = rollout_digest(gymnasium.make(ENV_ID, horizon=150, **knobs), seed=7, steps=400)
        c = rollout_digest(gymnasium.make(ENV_ID, horizon=150, **knobs), seed=8, steps=400)
        assert a == b != c


def test_same_seed_same_trajectory_across_processes():
    knobs = {"dynamism": 0.5, "shaping": "linear:1:0:300", "reset_free": False, "horizon": 250}
    script = (
        "import sys, json, gymnasium, foodcollector; sys.path.insert(0, sys.argv[1]); "
        "from test_fc_api import rollout_digest; "
        "print(rollout_digest(gymnasium.make(foodcollector.ENV_ID, **json.loads(sys.argv[2])), 11, 600))"
    )
    digests = []
    for hash_seed in ("1", "2"):
        env = {**os.environ, "PYTHONHASHSEED": hash_seed,
               "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
        out = subprocess.run([sys.executable, "-c", script, str(Path(__file__).parent), json.dumps(knobs)],
                             capture_output=True, text=True, env=env, cwd=REPO, timeout=120, check=True)
        digests.append(out.stdout.strip())
    here = rollout_digest(gymnasium.make(ENV_ID, **knobs), 11, 600)
    assert digests == [here, here]


@pytest.mark.parametrize("unwrapped", [False, True])
def test_pickle_round_trip_continues_identically(make_env, unwrapped):
    env = make_env(seed=5, dynamism=0.7, shaping="linear:1:0:500", reset_free=True)
    if unwrapped:
        env = env.unwrapped
    actions = np.random.default_rng(5).integers(0, 27, size=600).tolist()
    for a in actions[:300]:
        env.step(a)
    clone = pickle.loads(pickle.dumps(env))
    for a in actions[300:]:
        o1, r1, _, _, i1 = env.step(a)
        o2, r2, _, _, i2 = clone.step(a)
        assert np.array_equal(o1, o2) and r1 == r2
        assert np.array_equal(i1.pop("agent_pos"), i2.pop("agent_pos")) and i1 == i2


def test_render_rgb_array(make_env):
    env = make_env(render_mode="rgb_array")
    env.step(encode_action(forward=1))
    frame = env.render()
    assert frame.shape == (512, 512, 3) and frame.dtype == np.uint8
    colours = {tuple(c) for c in frame.reshape(-1, 3)[::7].tolist()}
    assert len(colours) > 10  # walls, floor, spheres, agent, rays: not a blank image
    assert env.unwrapped.frame(size=128).shape == (128, 128, 3)


def test_render_before_the_first_reset_is_refused_as_the_grid_tasks_do():
    env = foodcollector.FoodCollectorEnv(render_mode="rgb_array")  # no OrderEnforcing wrapper: the env's own check
    with pytest.raises(RuntimeError, match="call reset"):
        env.render()
    env.reset(seed=0)
    assert env.render().shape == (512, 512, 3)


def test_render_without_mode_warns_and_returns_none(make_env):
    env = make_env().unwrapped
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None


def test_observation_stays_in_space(make_env):
    env = make_env(dynamism=1.0, reset_free=True)
    space = env.observation_space
    for a in np.random.default_rng(0).integers(0, 27, size=500).tolist():
        obs, *_ = env.step(a)
        assert space.contains(obs)
    assert obs[51] == 0 and obs[52] == 0  # frozen and shoot flags


# ---- bad input ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("action", [27, -1, 100])
def test_out_of_range_actions_raise(make_env, action):
    env = make_env()
    with pytest.raises(ValueError, match=r"\[0, 27\)"):
        env.unwrapped.step(action)


@pytest.mark.parametrize("action", [3.0, "3", None, True, [3], np.array([3])])
def test_wrongly_typed_actions_raise(make_env, action):
    env = make_env()
    with pytest.raises(TypeError, match="integer"):
        env.unwrapped.step(action)


def test_numpy_integer_actions_are_accepted(make_env):
    env = make_env().unwrapped
    env.step(np.int64(9))
    env.step(np.array(9))
    assert decode_action(np.int32(26)) == (2, 2, 2)
    assert all(decode_action(encode_action(f, s, t)) == (f, s, t)
               for f in range(3) for s in range(3) for t in range(3))


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"dynamism": -0.1}, ValueError, "dynamism"),
    ({"dynamism": 1.5}, ValueError, "dynamism"),
    ({"shaping": 2.0}, ValueError, "shaping"),
    ({"shaping": "linear:1:0"}, ValueError, "schedule"),
    ({"reset_free": "yes"}, TypeError, "reset_free"),
    ({"reward": "subgoal"}, ValueError, "only its native"),
    ({"reward": "distance"}, ValueError, "only its native"),
    ({"sphere_radius": -0.75}, ValueError, "sphere_radius"),
    ({"num_green": -1}, ValueError, "num_green"),
    ({"num_red": 2.5}, TypeError, "num_red"),
    ({"num_green": 0, "num_red": 0}, ValueError, "at least one sphere"),
    ({"horizon": 0}, ValueError, "horizon"),
    ({"physics_dt": 0.0}, ValueError, "physics_dt"),
    ({"near_radius": 2.0}, ValueError, "near_radius"),
    ({"spawn_half_size": 49.8}, ValueError, "spawn_half_size"),
    ({"slowdown_factor": 1.5}, ValueError, "slowdown_factor"),
    ({"max_sphere_speed": float("nan")}, TypeError, "max_sphere_speed"),
    ({"sphere_radiuss": 1.0}, TypeError, "unknown food collector argument"),
])
def test_bad_construction_arguments_raise(kwargs, error, match):
    with pytest.raises(error, match=match):
        gymnasium.make(ENV_ID, **kwargs)


def test_unsupported_render_mode_raises():
    with pytest.raises(ValueError, match="render_mode"):
        foodcollector.FoodCollectorEnv(render_mode="human")


def test_params_object_and_kwargs_combine():
    params = FoodCollectorParams(num_green=3, num_red=4)
    env = gymnasium.make(ENV_ID, params=params, num_red=5).unwrapped
    assert (env.params.num_green, env.params.num_red) == (3, 5)
    env.reset(seed=0)
    assert env.sphere_is_green.tolist() == [True] * 3 + [False] * 5
