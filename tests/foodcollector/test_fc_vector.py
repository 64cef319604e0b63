"""Food collector worlds in worker processes give the one-process vector env's numbers exactly."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import foodcollector
from foodcollector.vector import merge_infos

KNOBS = {"dynamism": 0.5, "shaping": "linear:1:0:300", "horizon": 60}


def sync_env(num, **kwargs):
    """What `train.tasks.make_vector_env` builds for the food collector."""
    return gymnasium.vector.SyncVectorEnv([lambda: gymnasium.make(foodcollector.ENV_ID, **kwargs)] * num)


def assert_same(a, b, what):
    if isinstance(a, tuple):
        assert len(a) == len(b), what
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{what}[{i}]")
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), what
        for key in a:
            assert_same(a[key], b[key], f"{what} {key}")
    else:
        np.testing.assert_array_equal(a, b, err_msg=what)
        assert np.asarray(a).dtype == np.asarray(b).dtype, what


def test_one_worker_is_the_plain_sync_vector_env():
    env = foodcollector.make_vector_env(3, **KNOBS)
    assert type(env) is gymnasium.vector.SyncVectorEnv and env.num_envs == 3
    with pytest.raises(ValueError, match="workers must be an integer >= 1"):
        foodcollector.make_vector_env(3, workers=0)


def test_two_workers_equal_one_process_decision_for_decision():
    num, decisions = 5, 250  # chunks of 3 and 2 worlds; episodes of 60 decisions end and autoreset
    actions = np.random.default_rng(0).integers(0, foodcollector.NUM_ACTIONS, (decisions, num))
    with foodcollector.make_vector_env(num, workers=2, **KNOBS) as par:
        one = sync_env(num, **KNOBS)
        assert par.workers == 2 and par.sizes == [3, 2]
        assert_same(par.reset(seed=7), one.reset(seed=7), "reset")
        for t, a in enumerate(np.concatenate([actions[:151], actions[101:]])):
            for name, x, y in zip(("obs", "reward", "terminated", "truncated", "info"), par.step(a), one.step(a)):
                assert_same(x, y, f"{name} at decision {t}")
            if t == 100:  # save both ...
                saved = par.get_state(), [e.unwrapped.get_state() for e in one.envs], one._autoreset_envs.copy()
                assert_same(saved[0]["autoreset"], np.asarray(one._autoreset_envs, dtype=bool), "autoreset")
            if t == 150:  # ... and rewind both to decision 100: the next 50 decisions repeat
                par.set_state(saved[0])
                for e, state in zip(one.envs, saved[1]):
                    e.unwrapped.set_state(state)
                one._autoreset_envs = saved[2].copy()
        assert_same(par.reset(), one.reset(), "unseeded reset")
        assert_same(par.step(actions[0]), one.step(actions[0]), "step after the reset")
    assert par.closed and not any(p.is_alive() for p in par._procs)


def test_worker_errors_reach_the_parent_in_one_line():
    with foodcollector.make_vector_env(2, workers=2, **KNOBS) as par:
        with pytest.raises(RuntimeError, match=r"a food collector worker failed: \w+: .*reset\(\)"):
            par.step(np.zeros(2, dtype=np.int64))
        with pytest.raises(ValueError, match="3 seeds for 2 worlds"):
            par.reset(seed=[1, 2, 3])


def test_merge_infos_masks_a_key_a_chunk_lacks():
    parts = [{"a": np.array([1, 2]), "_a": np.array([True, True])}, {"b": np.array([0.5]), "_b": np.array([True])}]
    merged = merge_infos(parts, [2, 1])
    assert_same(merged["a"], np.array([1, 2, 0]), "a")
    assert_same(merged["_a"], np.array([True, True, False]), "_a")
    assert_same(merged["b"], np.array([0.0, 0.0, 0.5]), "b")
    assert_same(merged["_b"], np.array([False, False, True]), "_b")


def test_a_reset_mask_and_render_work_across_workers_as_in_one_process():
    """A mask was sent whole to each worker's chunk (an error), and workers=2 dropped the render mode."""
    outs = []
    for workers, mask in ((1, [True, False, False, True]), (2, [True, False, False, True]),
                          (1, [True, False, False, False]), (2, [True, False, False, False])):  # one chunk unreset
        mask = np.array(mask)
        vec = foodcollector.make_vector_env(4, workers, render_mode="rgb_array", horizon=50)
        vec.reset(seed=3)
        for _ in range(3):
            vec.step(np.zeros(4, dtype=np.int64))
        outs.append(vec.reset(options={"reset_mask": mask})[0])
        frames = vec.render()
        assert len(frames) == 4 and frames[0].shape == (512, 512, 3)
        vec.close()
    np.testing.assert_array_equal(outs[0], outs[1])
    np.testing.assert_array_equal(outs[2], outs[3])


def test_same_step_autoreset_across_workers_equals_one_process():
    """``autoreset_mode`` was next-step only; a worker chunk's final_info (a nested dict) could not be merged."""
    mode, num, knobs = gymnasium.vector.AutoresetMode.SAME_STEP, 3, {**KNOBS, "horizon": 15}
    actions = np.random.default_rng(4).integers(0, foodcollector.NUM_ACTIONS, (40, num))
    with foodcollector.make_vector_env(num, workers=2, autoreset_mode="same_step", **knobs) as par:
        one = foodcollector.make_vector_env(num, autoreset_mode=mode, **knobs)
        assert par.metadata["autoreset_mode"] == one.metadata["autoreset_mode"] == mode
        assert_same(par.reset(seed=3), one.reset(seed=3), "reset")
        finals = 0
        for t, a in enumerate(actions):
            got, want = par.step(a), one.step(a)
            finals += int(want[4].get("_final_obs", np.zeros(num, dtype=bool)).sum())
            *arrays, info = got
            assert_same(tuple(arrays), want[:4], f"decision {t}")
            assert info.keys() == want[4].keys(), f"info keys at decision {t}"
            for key in info:
                if key == "final_obs":  # an object array: one observation or None per world
                    for x, y in zip(info[key], want[4][key]):
                        assert (x is None and y is None) or np.array_equal(x, y), f"final_obs at decision {t}"
                else:
                    assert_same(info[key], want[4][key], f"info {key} at decision {t}")
        assert finals == 2 * num  # every world's 15-decision episode ended twice in 40 decisions
