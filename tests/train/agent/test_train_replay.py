"""The replay buffer: exact round trips, one slot per observation, episode boundaries and wrap-around."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from train.agent.replay import Replay


def _binary(rng, k, d):
    return rng.integers(0, 2, (k, d)).astype(np.float32)


@pytest.mark.parametrize("dim", [1, 8, 130, 208])
def test_binary_observations_round_trip_exactly(dim):
    rng = np.random.default_rng(0)
    replay = Replay(2, 16, dim, binary=True)
    obs = _binary(rng, 2, dim)
    stored = replay.encode(obs)
    assert stored.dtype == np.uint8 and stored.shape == (2, (dim + 7) // 8)
    assert torch.equal(replay.decode(stored), torch.from_numpy(obs))


def test_binary_replay_rejects_non_binary_values():
    replay = Replay(1, 4, 3, binary=True)
    with pytest.raises(ValueError, match="outside"):
        replay.encode(np.array([[0.0, 0.5, 1.0]], dtype=np.float32))


def test_float_observations_round_trip():
    rng = np.random.default_rng(1)
    obs = rng.normal(size=(2, 53)).astype(np.float32)
    exact = Replay(2, 8, 53, binary=False, float_dtype="float32")
    assert torch.equal(exact.decode(exact.encode(obs)), torch.from_numpy(obs))
    half = Replay(2, 8, 53, binary=False, float_dtype="float16")
    assert torch.allclose(half.decode(half.encode(obs)), torch.from_numpy(obs), rtol=1e-3, atol=1e-3)


def _fill_stream(replay, rng, steps, end_every=None):
    """Write one agent's stream as the trainer does (reward = time step; an episode ends every ``end_every``)."""
    obs = _binary(rng, 1, replay.obs_dim)
    for t in range(steps):
        nxt = _binary(rng, 1, replay.obs_dim)
        ended = end_every is not None and (t + 1) % end_every == 0
        replay.add(np.array([True]), replay.encode(obs), np.array([t % 7]), np.array([float(t)], np.float32),
                   np.array([ended and t % 2 == 0]))
        if ended:
            replay.add(np.array([True]), replay.encode(nxt))  # final observation, its own slot
            nxt = _binary(rng, 1, replay.obs_dim)  # the reset observation starts the next episode
        obs = nxt


def test_sampled_transitions_pair_each_observation_with_its_successor():
    rng = np.random.default_rng(2)
    replay = Replay(1, 1000, 12, binary=True)
    _fill_stream(replay, rng, 300, end_every=7)
    slots = replay.sample_indices([np.random.default_rng(3)], 50, 64).reshape(1, -1)
    batch = replay.batch(slots)
    n = slots.shape[1]
    stored = replay.decode(replay.obs[0])
    for j, slot in enumerate(slots[0]):
        assert replay.flags[0, slot] & 2  # starts a transition
        assert torch.equal(batch.obs_pairs[0, j], stored[slot])
        assert torch.equal(batch.obs_pairs[0, n + j], stored[slot + 1])
        assert batch.rewards[0, j].item() == replay.reward[0, slot]


def test_episode_end_keeps_final_observation_and_terminal_flag():
    rng = np.random.default_rng(4)
    replay = Replay(1, 100, 10, binary=True)
    first = _binary(rng, 1, 10)
    final = _binary(rng, 1, 10)
    replay.add(np.array([True]), replay.encode(first), np.array([3]), np.array([100.0]), np.array([True]))
    replay.add(np.array([True]), replay.encode(final))
    replay.add(np.array([True]), replay.encode(_binary(rng, 1, 10)), np.array([1]), np.array([0.0]),
               np.array([False]))
    replay.add(np.array([True]), replay.encode(_binary(rng, 1, 10)), np.array([2]), np.array([0.0]),
               np.array([False]))
    slots = replay.sample_indices([np.random.default_rng(0)], 1, 200)[:, 0]
    assert set(slots[0].tolist()) == {0, 2}  # never the final observation (1) nor the newest slot (3)
    batch = replay.batch(np.array([[0]]))
    assert torch.equal(batch.next_obs[0, 0], torch.from_numpy(final[0]))
    assert batch.terminated[0, 0].item() == 1.0 and batch.actions[0, 0].item() == 3


def test_wrap_around_overwrites_oldest_and_stays_consistent():
    rng = np.random.default_rng(5)
    replay = Replay(1, 50, 9, binary=True)
    _fill_stream(replay, rng, 180, end_every=11)
    assert replay.size[0] == 50
    newest = (replay.ptr[0] - 1) % 50
    slots = replay.sample_indices([np.random.default_rng(6)], 20, 64)
    assert newest not in slots
    assert np.all(replay.flags[0, slots[0]] & 2)
    # successors are chronological: rewards (= time step) of consecutive starting slots increase by one
    for slot in slots[0].ravel():
        nxt = (slot + 1) % 50
        if replay.flags[0, nxt] & 2:
            assert replay.reward[0, nxt] == replay.reward[0, slot] + 1


def test_agents_have_independent_streams_and_sizes():
    rng = np.random.default_rng(7)
    replay = Replay(3, 20, 5, binary=True)
    obs = _binary(rng, 3, 5)
    mask = np.array([True, False, True])
    for _ in range(4):
        replay.add(mask, replay.encode(obs), np.zeros(3, int), np.zeros(3, np.float32), np.zeros(3, bool))
    assert replay.size.tolist() == [4, 0, 4]
    with pytest.raises(RuntimeError, match="no complete transition"):
        replay.sample_indices([np.random.default_rng(i) for i in range(3)], 1, 4)


def test_state_dict_round_trip():
    rng = np.random.default_rng(8)
    replay = Replay(1, 64, 20, binary=True)
    _fill_stream(replay, rng, 40, end_every=9)
    copy = Replay(1, 64, 20, binary=True)
    copy.load_state_dict(replay.state_dict())
    for name in ("obs", "action", "reward", "flags", "ptr", "size"):
        assert np.array_equal(getattr(copy, name), getattr(replay, name))


def test_full_buffer_of_ten_seeds_is_compact():
    replay = Replay(10, 500_000, 130, binary=True)
    assert replay.nbytes < 200 * 2**20  # 17 bytes per grid observation + 6 per transition
