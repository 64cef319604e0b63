"""Staged minibatches: the GPU's way of reading them (static buffers, a device-side step index, bits unpacked
by torch) gives exactly the CPU's numbers, chunk by chunk, and a CUDA graph replays the eager gradient step.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from train.agent import staging
from train.agent.learner import DQNLearner, RowSettings
from train.agent.network import QNetwork
from train.agent.replay import Replay
from train.agent.staging import Stager, unpack_bits
from train.config import TrainConfig

TINY = TrainConfig().replace(task="salad", warmup_steps=50, epoch_steps=50, updates_per_epoch=12, batch_size=8,
                             buffer_size=300, lr=1e-3)


def test_torch_unpacks_bits_as_numpy_does():
    packed = np.random.default_rng(0).integers(0, 256, (3, 5, 17), dtype=np.uint8)
    for count in (130, 136, 1):
        expected = np.unpackbits(packed, axis=-1, count=count).astype(np.float32)
        assert torch.equal(unpack_bits(torch.from_numpy(packed), count), torch.from_numpy(expected))


def _filled_replay(num_agents: int = 3, steps: int = 120, binary: bool = True, seed: int = 0) -> Replay:
    """A replay with ``steps`` random transitions per agent, a few of them ending episodes."""
    rng = np.random.default_rng(seed)
    replay = Replay(num_agents, 100, 130, binary)
    everyone = np.ones(num_agents, dtype=bool)
    for _ in range(steps):
        obs = (rng.random((num_agents, 130)) < 0.2).astype(np.float32)
        if not binary:
            obs *= rng.random((num_agents, 130)).astype(np.float32)
        ends = rng.random(num_agents) < 0.05
        replay.add(everyone, replay.encode(obs), rng.integers(0, 7, num_agents), rng.normal(size=num_agents), ends)
        if ends.any():
            replay.add(ends, replay.encode(obs))
    return replay


@pytest.mark.parametrize("binary", [True, False])
def test_static_batches_are_the_host_batches(binary):
    replay = _filled_replay(binary=binary)
    slots = replay.sample_indices([np.random.default_rng(k) for k in range(3)], 5, 8)
    host = Stager(replay, 8, 5, torch.device("cpu"), static=False)
    static = Stager(replay, 8, 5, torch.device("cpu"), static=True)
    assert host.load(slots) == static.load(slots) == 5
    for i in range(5):
        static.select(i)
        a, b, direct = host.batch(i), static.batch(i), replay.batch(slots[:, i])
        for name in ("obs_pairs", "actions", "rewards", "terminated"):
            assert torch.equal(getattr(a, name), getattr(b, name)), name
            assert torch.equal(getattr(a, name), getattr(direct, name)), name


def test_a_chunk_too_big_is_refused():
    replay = _filled_replay()
    stager = Stager(replay, 8, 4, torch.device("cpu"), static=True)
    with pytest.raises(ValueError, match="do not fit a chunk of 4"):
        stager.load(np.zeros((3, 5, 8), dtype=np.int64))


def _learner(rnd: bool = False, **kwargs) -> DQNLearner:
    """Three rows (the last with RND if ``rnd``), their replay filled, ready to learn."""
    rows = [RowSettings(k, TINY.dqn, TINY.replace(rnd=rnd and k == 2).rnd) for k in range(3)]
    net = QNetwork.from_config(125, 130, 7, TINY.dqn)
    learner = DQNLearner(rows, net, binary_obs=True, **kwargs)
    learner.replay = _filled_replay()
    learner._stager = Stager(learner.replay, TINY.dqn.batch_size, TINY.dqn.updates_per_epoch, learner.device,
                             kwargs.get("static_batches", False))
    return learner


@pytest.mark.parametrize("rnd", [False, True])
def test_learning_from_static_batches_in_small_chunks_is_learning_from_the_host(rnd, monkeypatch):
    reference = _learner(rnd)
    for _ in range(2):
        reference.learn()
    monkeypatch.setattr(staging, "STAGE_BYTES", 3 * 8 * (2 * 17 + 6) * 5)  # chunks of 5 of the 12 steps
    static = _learner(rnd, static_batches=True)
    assert static._stager.chunk == 5
    for _ in range(2):
        static.learn()
    assert torch.equal(static.agent.online, reference.agent.online)
    assert torch.equal(static.agent.target, reference.agent.target)
    assert np.array_equal(static.take_losses(), reference.take_losses())
    if rnd:
        assert torch.equal(static.rnd.predictor, reference.rnd.predictor)
        assert torch.equal(static.rnd.moments.count, reference.rnd.moments.count)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("rnd", [False, True])
def test_a_cuda_graph_replays_the_eager_gradient_step(rnd):
    torch.backends.cuda.matmul.allow_tf32 = False
    cpu, eager, graphed = _learner(rnd), _learner(rnd, device="cuda", graphs=False), _learner(rnd, device="cuda")
    for learner in (cpu, eager, graphed):
        for _ in range(3):
            learner.learn()
    assert graphed._graph is not None and eager._graph is None
    assert torch.equal(graphed.agent.online.cpu(), eager.agent.online.cpu())
    scale = cpu.agent.online.abs().max()
    assert float((eager.agent.online.cpu() - cpu.agent.online).abs().max() / scale) < 1e-5
    loaded = _learner(rnd, device="cuda")
    loaded.learn()  # captured; then a checkpoint's state is loaded in place and the graph sees it
    loaded.load_state_dict(graphed.state_dict())
    for learner in (loaded, graphed):
        learner.learn()
    assert torch.equal(loaded.agent.online, graphed.agent.online)


def test_the_memory_check_counts_what_a_chunk_stages():
    from train.loop.memory import estimate_bytes

    replay = _filled_replay()
    stager = Stager(replay, TINY.dqn.batch_size, TINY.dqn.updates_per_epoch, torch.device("cpu"), static=False)
    slots = replay.sample_indices([np.random.default_rng(k) for k in range(3)], stager.chunk, TINY.dqn.batch_size)
    stager.load(slots)
    staged = sum(a.nbytes for a in stager._arrays.values())
    estimate = estimate_bytes(TINY.replace(seeds=3), 130, 64, 1000, True)["staged minibatches"]
    assert staged <= estimate <= 2 * staged


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_a_cuda_graph_acts_as_the_eager_forward_pass():
    torch.backends.cuda.matmul.allow_tf32 = False
    eager, graphed = _learner(device="cuda", graphs=False), _learner(device="cuda")
    rng = np.random.default_rng(0)
    for _ in range(3):
        for learner in (eager, graphed):
            learner.learn()  # the weights change in place between the steps
            learner.begin_collect(4)
        for _ in range(4):
            obs = (rng.random((3, 130)) < 0.2).astype(np.float32)
            assert np.array_equal(graphed.act(obs, 10**6), eager.act(obs, 10**6))
    assert graphed._act_graph is not None and eager._act_graph is None
