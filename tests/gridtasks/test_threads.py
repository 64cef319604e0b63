"""The batched engine across threads gives the sequential loop's numbers bit for bit; `step_arrays` equals `step`."""

from __future__ import annotations

import gymnasium as gym
import numba
import numpy as np
import pytest

import gridtasks
from gridtasks.vector import GridTaskVectorEnv

IDS = sorted(gridtasks.ENV_IDS.values())
KNOBS = {
    "episodic": {"dynamism": 0.3, "shaping": "linear:1:0:200", "reward": "waypoint", "horizon": 30,
                 "replay_unsolved": 70},
    "reset-free": {"dynamism": 0.2, "shaping": "linear:1:0:300", "reset_free": True, "reward": "distance"},
}
POOL = numba.config.NUMBA_NUM_THREADS
needs_two_threads = pytest.mark.skipif(POOL < 2, reason="numba's thread pool has a single thread here")


def make(env_id, num, **kwargs):
    return gym.make_vec(env_id, num_envs=num, vectorization_mode="vector_entry_point", **kwargs)


def assert_same(a, b, what):
    if isinstance(a, tuple):
        assert len(a) == len(b), what
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{what}[{i}]")
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), what
        for key in a:
            assert_same(a[key], b[key], f"{what} {key}")
    elif isinstance(a, np.ndarray) and a.dtype.names:
        for name in a.dtype.names:
            np.testing.assert_array_equal(a[name], b[name], err_msg=f"{what} field {name}")
    else:
        np.testing.assert_array_equal(a, b, err_msg=what)
        assert np.asarray(a).dtype == np.asarray(b).dtype, what


@needs_two_threads
@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("knobs", list(KNOBS), ids=list(KNOBS))
def test_threaded_stepping_equals_sequential_bit_for_bit(env_id, knobs):
    num, steps = 13, 300
    one, two = make(env_id, num, **KNOBS[knobs]), make(env_id, num, threads=2, **KNOBS[knobs])
    assert (one.unwrapped.threads, two.unwrapped.threads) == (1, 2)
    actions = np.random.default_rng(1).integers(0, 7, (steps, num))
    assert_same(one.reset(seed=5), two.reset(seed=5), "reset")
    ended = 0
    for t in range(steps):
        if t == 150:  # an unseeded reset mid-life (a new episode for every world) goes through the threads too
            assert_same(one.reset(), two.reset(), f"reset at {t}")
        out_one, out_two = one.step(actions[t]), two.step(actions[t])
        for name, a, b in zip(("obs", "reward", "terminated", "truncated", "info"), out_one, out_two):
            assert_same(a, b, f"{name} at step {t}")
        assert_same(one.unwrapped.worlds, two.unwrapped.worlds, f"worlds at step {t}")
        ended += int((out_one[2] | out_one[3]).sum())
    assert knobs == "reset-free" or ended > 0  # episodic worlds went through autoresets


@needs_two_threads
def test_threads_change_nothing_but_the_threads_of_the_call():
    vec = make("gridtasks/Salad-v0", 4, threads=2)
    before = numba.get_num_threads()
    vec.reset(seed=0)
    vec.step(np.zeros(4, dtype=np.int64))
    assert numba.get_num_threads() == before


@needs_two_threads
def test_validation_envs_on_threads_hold_the_same_layouts():
    one, obs_one = gridtasks.make_validation_envs("factory", n=12, copies=2)
    two, obs_two = gridtasks.make_validation_envs("factory", n=12, copies=2, threads=2)
    assert two.threads == 2
    assert_same(obs_one, obs_two, "obs")
    assert_same(one.worlds, two.worlds, "worlds")


def test_threads_must_fit_numbas_pool():
    with pytest.raises(ValueError, match="threads must be an integer >= 1"):
        make("gridtasks/Salad-v0", 2, threads=0)
    with pytest.raises(ValueError, match=f"exceeds numba's thread pool of {POOL}.*NUMBA_NUM_THREADS"):
        make("gridtasks/Salad-v0", 2, threads=POOL + 1)


@pytest.mark.parametrize("threads", [1, 2] if POOL >= 2 else [1])
@pytest.mark.parametrize("copy", [True, False])
def test_step_arrays_equals_step(threads, copy):
    knobs = {"dynamism": 0.4, "reward": "one_time", "horizon": 25}  # scavenging: predators catch
    full = GridTaskVectorEnv(gridtasks.TASKS["scavenging"], 9, **knobs)
    fast = GridTaskVectorEnv(gridtasks.TASKS["scavenging"], 9, copy=copy, threads=threads, **knobs)
    with pytest.raises(RuntimeError, match=r"call reset\(\) before step_arrays\(\)"):
        fast.step_arrays(np.zeros(9, dtype=np.int64))
    full.reset(seed=2)
    fast.reset(seed=2)
    caught = solved = ended = 0
    for a in np.random.default_rng(3).integers(0, 7, (200, 9)):
        obs, rew, term, trunc, info = full.step(a)
        out = fast.step_arrays(a)
        assert len(out) == 5
        for name, x, y in zip(("obs", "reward", "terminated", "truncated", "agent_pos"), out,
                              (obs, rew, term, trunc, info["agent_pos"])):
            assert_same(x, y, name)
        assert_same(fast.last_solved, info["solved"], "solved")
        assert_same(fast.last_caught, info["caught"], "caught")
        caught, solved, ended = caught + info["caught"].sum(), solved + info["solved"].sum(), ended + trunc.sum()
        assert_same(full.worlds, fast.worlds, "worlds")
    assert caught > 0 and ended > 0  # the comparison covered predators and autoresets
    with pytest.raises(ValueError, match="must lie in"):
        fast.step_arrays(np.full(9, 7))
