"""The batched engine agrees with the single env world for world, and obeys the vector API."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gridtasks
from ecology import validation_seeds

IDS = sorted(gridtasks.ENV_IDS.values())
KNOBS = [
    {"dynamism": 0.3, "reward": "distance", "horizon": 40},
    {"dynamism": 0.1, "shaping": "linear:1:0:300", "reset_free": True, "reward": "one_time"},
]


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("knobs", KNOBS, ids=["episodic", "reset-free"])
def test_batched_worlds_match_single_envs_step_for_step(env_id, knobs):
    num, steps, seed = 4, 300, 11
    vec = gym.make_vec(env_id, num_envs=num, vectorization_mode="vector_entry_point", **knobs)
    singles = [gym.make(env_id, **knobs) for _ in range(num)]
    actions = np.random.default_rng(0).integers(0, 7, (steps, num))
    vobs, _ = vec.reset(seed=seed)
    sobs = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    np.testing.assert_array_equal(vobs, np.stack(sobs))
    pending_reset = [False] * num
    for t in range(steps):
        vobs, vrew, vterm, vtrunc, vinfo = vec.step(actions[t])
        for i, env in enumerate(singles):
            if pending_reset[i]:  # next-step autoreset: the vector world resets, its action is ignored
                obs, _ = env.reset()
                rew, term, trunc, solved = 0.0, False, False, False
                pending_reset[i] = False
            else:
                obs, rew, term, trunc, info = env.step(int(actions[t, i]))
                solved = info["solved"]
                pending_reset[i] = term or trunc
                made = {key: value for key, value in info.items() if key.startswith("made_")}
                assert made == {key: vinfo[key][i] for key in vinfo if key.startswith("made_")}  # per product
            np.testing.assert_array_equal(vobs[i], obs, err_msg=f"world {i} step {t}")
            assert (vrew[i], vterm[i], vtrunc[i], vinfo["solved"][i]) == (rew, term, trunc, solved)


def test_batched_same_seed_same_trajectory_and_seed_list():
    def run(seed):
        vec = gym.make_vec("gridtasks/Hunting-v0", num_envs=8, vectorization_mode="vector_entry_point",
                           dynamism=0.4, reset_free=True)
        out = [vec.reset(seed=seed)[0]]
        for a in np.random.default_rng(5).integers(0, 7, (100, 8)):
            out.append(vec.step(a)[0])
        return np.stack(out)

    np.testing.assert_array_equal(run(3), run(3))
    np.testing.assert_array_equal(run([3, 4, 5, 6, 7, 8, 9, 10]), run(3))
    assert not np.array_equal(run(3), run(4))


def test_vector_env_spaces_and_action_validation():
    vec = gym.make_vec("gridtasks/Factory-v0", num_envs=5, vectorization_mode="vector_entry_point")
    obs, info = vec.reset(seed=0)
    assert obs.shape == (5, 208) and obs.dtype == np.float32
    assert vec.single_action_space.n == 7 and vec.action_space.shape == (5,)
    assert info["agent_pos"].shape == (5, 2)
    with pytest.raises(ValueError, match="shape"):
        vec.step(np.zeros(4, dtype=int))
    with pytest.raises(ValueError, match="must lie in"):
        vec.step(np.full(5, 7))
    with pytest.raises(ValueError, match="4 seeds for 5 worlds"):
        vec.reset(seed=[1, 2, 3, 4])


def test_vector_render_gives_one_frame_per_world():
    vec = gym.make_vec("gridtasks/Scavenging-v0", num_envs=3, vectorization_mode="vector_entry_point",
                       render_mode="rgb_array")
    vec.reset(seed=0)
    frames = vec.render()
    assert len(frames) == 3 and frames[0].shape == frames[2].shape


@pytest.mark.parametrize("task", sorted(gridtasks.TASKS))
def test_validation_layouts_are_fixed_and_match_the_test_mdp(task):
    first = gridtasks.validation_layouts(task, n=20)
    again = gridtasks.validation_layouts(task, n=20, dynamism=0.5, shaping=1.0, reset_free=True)
    np.testing.assert_array_equal(first["grid"], again["grid"])
    assert len({g.tobytes() + a.tobytes() for g, a in zip(first["grid"], first["agent"])}) == 20
    single = gridtasks.make_test_env(task)
    single.reset(seed=validation_seeds(20)[7])
    np.testing.assert_array_equal(single.world["grid"], first["grid"][7])
    assert single.ecology.is_test_mdp


def test_salad_validation_layouts_hold_one_of_each_ingredient():
    grids = gridtasks.validation_layouts("salad", n=50)["grid"]
    assert ((grids == gridtasks.Code.LETTUCE).sum(axis=(1, 2)) == 1).all()
    assert ((grids == gridtasks.Code.CARROT).sum(axis=(1, 2)) == 1).all()


def test_validation_copies_repeat_the_same_layouts():
    vec, obs = gridtasks.make_validation_envs("hunting", n=10, copies=3)
    np.testing.assert_array_equal(obs[:10], obs[10:20])
    np.testing.assert_array_equal(vec.worlds["grid"][:10], vec.worlds["grid"][20:])


@pytest.mark.parametrize("env_id", IDS)
def test_every_vector_mode_gives_the_single_envs_info_keys_stacked(env_id):
    """The engine's info had no pick-up counts, and "sync" stacked the single env's tuple positions as objects."""
    single = gym.make(env_id).reset(seed=0)[1]
    _, batched = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point").reset(seed=0)
    _, synced = gym.make_vec(env_id, num_envs=3, vectorization_mode="sync").reset(seed=0)
    assert set(batched) == set(synced) | {"made", "_made"}  # plus the total of every product, as the trainer logs
    assert set(single) == {key for key in synced if not key.startswith("_")}
    for key in synced:
        if key.startswith("_"):  # Gymnasium's masks: which worlds reported the key (all of them, each step)
            np.testing.assert_array_equal(batched[key], synced[key])
    for info in (batched, synced):
        assert info["agent_pos"].shape == (3, 2) and info["agent_pos"].dtype == np.int64
    np.testing.assert_array_equal(batched["agent_pos"], synced["agent_pos"])


def test_a_reset_mask_resets_only_the_worlds_it_selects_as_sync_does():
    """``options["reset_mask"]`` (Gymnasium 1.x) used to be ignored: every world was reset."""
    mask = np.array([True, False, True, False])
    outs = []
    for mode in ("vector_entry_point", "sync"):
        vec = gym.make_vec("gridtasks/Salad-v0", num_envs=4, vectorization_mode=mode, dynamism=0.2)
        before = vec.reset(seed=7)[0]
        for _ in range(3):
            stepped = vec.step(np.array([1, 2, 3, 1]))[0]
        after = vec.reset(options={"reset_mask": mask})[0]
        np.testing.assert_array_equal(after[~mask], stepped[~mask])
        outs.append(after)
        if mode == "vector_entry_point":
            assert list(vec.unwrapped.worlds["episode_step"]) == [0, 3, 0, 3]
            np.testing.assert_array_equal(vec.reset(seed=7, options={"reset_mask": mask})[0][mask], before[mask])
    np.testing.assert_array_equal(*outs)


def test_bad_reset_masks_and_seeds_are_one_line_errors():
    vec = gym.make_vec("gridtasks/Hunting-v0", num_envs=3, vectorization_mode="vector_entry_point")
    with pytest.raises(RuntimeError, match="first reset"):
        vec.reset(seed=0, options={"reset_mask": np.array([True, False, False])})
    vec.reset(seed=range(3))
    with pytest.raises(ValueError, match=r"boolean array of shape \(3,\)"):
        vec.reset(options={"reset_mask": np.array([1, 0, 0])})
    for bad, held in ((3.0, "float"), ("12", "str"), ([1.9, 2, 3], "list of float, int"), (True, "bool"),
                      (np.arange(3.0), "ndarray of float64")):
        with pytest.raises(TypeError, match=f"seed must be an int, or one int or None per world, got {held}$"):
            vec.reset(seed=bad)
    with pytest.raises(ValueError, match="copy must be True or False"):
        gym.make_vec("gridtasks/Hunting-v0", num_envs=2, vectorization_mode="vector_entry_point", copy="no")


@pytest.mark.parametrize("env_id", IDS)
def test_every_spec_serialises(env_id):
    """The registry held classes and partials, so ``EnvSpec.to_json`` refused every grid id."""
    spec = gym.spec(env_id)
    assert gym.envs.registration.EnvSpec.from_json(spec.to_json()) == spec
    vec = gym.make_vec(env_id, num_envs=2)  # the string vector entry point loads
    assert type(vec.unwrapped).__name__ == "GridTaskVectorEnv"


def test_a_none_seed_continues_that_worlds_life_and_a_reset_clears_solved_and_caught_as_sync():
    """None in a seed list started a new life in the batched env but not in "sync"; a reset kept the last
    step's solved and caught.
    """
    outs = {}
    for mode in ("vector_entry_point", "sync"):
        vec = gym.make_vec("gridtasks/Scavenging-v0", num_envs=3, vectorization_mode=mode, dynamism=0.5,
                           predator_count=3, reset_free=True)
        vec.reset(seed=0)
        rng = np.random.default_rng(1)
        caught = False
        for _ in range(400):
            info = vec.step(rng.integers(0, 7, 3))[4]
            caught = caught or info["caught"].any()
            if info["caught"].any():
                break
        assert caught
        obs, info = vec.reset(seed=[None, 7, None])
        outs[mode] = (obs, info["lifetime_step"])
        assert not info["caught"].any() and not info["solved"].any()
    np.testing.assert_array_equal(outs["vector_entry_point"][0], outs["sync"][0])
    np.testing.assert_array_equal(outs["vector_entry_point"][1], outs["sync"][1])
    assert outs["sync"][1][1] == 0 and outs["sync"][1][0] > 0


@pytest.mark.parametrize("mode", [gym.vector.AutoresetMode.SAME_STEP, gym.vector.AutoresetMode.DISABLED])
def test_every_autoreset_mode_steps_as_sync_does(mode):
    """``make_vec(..., autoreset_mode=...)`` was refused as an unknown task parameter: next-step only."""
    knobs = {"dynamism": 0.3, "horizon": 6}
    num, steps = 4, 40
    envs = {"batched": gym.make_vec("gridtasks/Salad-v0", num_envs=num, vectorization_mode="vector_entry_point",
                                    autoreset_mode=mode, **knobs),
            "sync": gym.make_vec("gridtasks/Salad-v0", num_envs=num, vectorization_mode="sync",
                                 vector_kwargs={"autoreset_mode": mode}, **knobs)}
    assert envs["batched"].metadata["autoreset_mode"] == mode
    actions = np.random.default_rng(2).integers(0, 7, (steps, num))
    outs = {name: [vec.reset(seed=5)[0]] for name, vec in envs.items()}
    ended_worlds = 0
    for t in range(steps):
        for name, vec in envs.items():
            obs, rew, term, trunc, info = vec.step(actions[t])
            outs[name].append((obs, rew, term, trunc, info["solved"], info["lifetime_step"]))
            ended = term | trunc
            if mode == gym.vector.AutoresetMode.SAME_STEP and ended.any():
                np.testing.assert_array_equal(info["_final_obs"], ended)
                np.testing.assert_array_equal(info["final_info"]["_solved"], ended)
                outs[name].append((np.stack(info["final_obs"][ended]), info["final_info"]["solved"],
                                   info["final_info"]["completions"]))
            if mode == gym.vector.AutoresetMode.DISABLED and ended.any():
                outs[name].append(vec.reset(options={"reset_mask": ended})[0])
        ended_worlds += int(ended.sum())
    assert ended_worlds >= num  # every world's 6-step episodes ended several times
    for got, want in zip(outs["batched"], outs["sync"], strict=True):
        for a, b in zip(got, want, strict=True) if isinstance(got, tuple) else [(got, want)]:
            np.testing.assert_array_equal(a, b)


def test_a_disabled_autoreset_refuses_to_step_an_ended_world_and_modes_are_checked():
    vec = gym.make_vec("gridtasks/Hunting-v0", num_envs=2, vectorization_mode="vector_entry_point",
                       autoreset_mode="disabled", horizon=1)
    vec.reset(seed=0)
    vec.step(np.zeros(2, dtype=int))
    with pytest.raises(RuntimeError, match=r"world\(s\) \[0, 1\] ended .*reset_mask"):
        vec.step(np.zeros(2, dtype=int))
    same = gym.make_vec("gridtasks/Hunting-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        autoreset_mode="SameStep")
    same.reset(seed=0)
    with pytest.raises(RuntimeError, match="step_arrays.*SAME_STEP"):
        same.unwrapped.step_arrays(np.zeros(2, dtype=int))
    with pytest.raises(ValueError, match="autoreset_mode must be one of AutoresetMode.NEXT_STEP"):
        gym.make_vec("gridtasks/Hunting-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     autoreset_mode="same")
