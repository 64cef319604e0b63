"""The batched Q-network's fast paths equal the plain dense computation up to float rounding."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from train.agent.dqn import DoubleDQN
from train.agent.network import QNetwork
from train.config import DQNConfig

VIEW, INV, ACTIONS = 24, 4, 5


def _net(repeat: int = 1) -> QNetwork:
    return QNetwork(VIEW, INV, ACTIONS, (8, 8, 4), (5, 5, 3), (6,), inventory_repeat=repeat)


def _one_hot_obs(k: int, n: int, seed: int = 0) -> torch.Tensor:
    """Grid-like observations: 6 cells of 4 one-hot channels, a few rows with extra or no active cells."""
    rng = np.random.default_rng(seed)
    x = np.zeros((k, n, VIEW + INV), np.float32)
    cells = rng.integers(0, 4, (k, n, 6))
    x[..., :VIEW].reshape(k, n, 6, 4)[np.arange(k)[:, None, None], np.arange(n)[None, :, None],
                                       np.arange(6), cells] = 1.0
    x[0, 0, :VIEW] = 0.0  # nothing active
    x[-1, -1, [0, 1]] = 1.0  # more active entries than the rest
    x[..., VIEW:] = rng.integers(0, 2, (k, n, INV))
    return torch.from_numpy(x)


def _params(net: QNetwork, k: int, dtype=torch.float32) -> torch.Tensor:
    rng = np.random.default_rng(1)
    return torch.tensor(np.stack([net.init(rng, "torch") for _ in range(k)]), dtype=dtype)


def _dense_reference(net: QNetwork, flat: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Q-values by plain products: each layer x @ W + b, ReLU between (the network's definition)."""
    def chain(layers, h):
        for i, (w, b) in enumerate(layers):
            h = h @ w + b
            h = h.relu() if i < len(layers) - 1 else h
        return h
    view, inv, head = net.bind(flat)
    inventory = x[..., VIEW:].repeat_interleave(net.inventory_repeat, -1)
    return chain(head, torch.cat((chain(view, x[..., :VIEW]), chain(inv, inventory)), -1))


def test_sparse_first_layer_equals_dense_forward():
    net, x = _net(), _one_hot_obs(3, 12)
    flat = _params(net, 3)
    index = net.view_index(x, min_rows=0)
    assert index is not None and index.rows.shape[:2] == (3, 12)
    sparse = net.forward(net.bind(flat), x, index)[0]
    dense = net.forward(net.bind(flat), x)[0]
    assert torch.allclose(sparse, dense, rtol=1e-5, atol=1e-6)
    assert torch.allclose(dense, _dense_reference(net, flat, x), rtol=1e-5, atol=1e-6)
    tail = net.forward(net.bind(flat), x[:, 7:], index.tail(7))[0]  # the next-observation half
    assert torch.allclose(tail, dense[:, 7:], rtol=1e-5, atol=1e-6)


def test_view_index_declines_non_binary_dense_or_small_inputs():
    net, x = _net(), _one_hot_obs(2, 6)
    assert net.view_index(x) is None  # 12 rows: below the default minimum
    real = x.clone()
    real[1, 2, 3] = 0.5
    assert net.view_index(real, min_rows=0) is None
    crowded = x.clone()
    crowded[0, 1, :VIEW] = 1.0  # every view entry active: the dense product is cheaper
    assert net.view_index(crowded, min_rows=0) is None
    assert net.view_index(x, min_rows=0) is not None


def test_update_with_sparse_index_equals_dense_update():
    cfg = DQNConfig(init="torch", target_init="independent")
    x = _one_hot_obs(4, 16, seed=3)
    actions = torch.randint(0, ACTIONS, (4, 8), generator=torch.Generator().manual_seed(0))
    rewards, terminated = torch.randn(4, 8, generator=torch.Generator().manual_seed(1)), torch.zeros(4, 8)
    dense_net, sparse_net = _net(), _net()
    dense_net.view_index = lambda obs: None
    sparse_net.view_index = lambda obs: QNetwork.view_index(sparse_net, obs, min_rows=0)
    agents = [DoubleDQN(n, cfg, [np.random.default_rng(s) for s in range(4)]) for n in (dense_net, sparse_net)]
    losses = [a.update(x, actions, rewards, terminated) for a in agents]
    assert torch.allclose(losses[0], losses[1], rtol=1e-5)
    for a, b in zip(agents[0].state_dict().values(), agents[1].state_dict().values()):
        if isinstance(a, torch.Tensor):
            assert torch.allclose(a, b, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("k", [1, 3])
def test_backward_writes_the_autograd_gradient(k):
    net = _net()
    flat = _params(net, k, torch.float64)
    x = _one_hot_obs(k, 10).double()
    grad_q = torch.randn(k, 6, ACTIONS, dtype=torch.float64)
    q, cache = net.forward(net.bind(flat), x)
    mine = net.backward(net.bind(flat), cache, grad_q).clone()
    leaf = flat.clone().requires_grad_(True)
    (_dense_reference(net, leaf, x)[:, :6] * grad_q).sum().backward()
    assert torch.allclose(mine, leaf.grad, atol=1e-12)
    again = net.backward(net.bind(flat), cache, grad_q)  # the buffer is reused, the result the same
    assert torch.equal(again, mine)


def test_inventory_repeat_feeds_the_repeated_inventory():
    repeated, plain = _net(repeat=3), QNetwork(VIEW, INV * 3, ACTIONS, (8, 8, 4), (5, 5, 3), (6,))
    assert repeated.num_params == plain.num_params  # the same weights: 3 rows per inventory entry
    flat = _params(repeated, 2)
    x = _one_hot_obs(2, 7)
    x_repeated = torch.from_numpy(np.concatenate(  # what np.repeat(inventory, 3) feeds the original's network
        [x[..., :VIEW].numpy(), np.repeat(x[..., VIEW:].numpy(), 3, axis=-1)], -1))
    assert torch.equal(repeated.forward(repeated.bind(flat), x)[0], plain.forward(plain.bind(flat), x_repeated)[0])


def test_inventory_repeat_trains_every_copy_of_the_rows():
    net = _net(repeat=4)
    flat = _params(net, 1)
    x = _one_hot_obs(1, 6)
    x[..., VIEW:] = 1.0
    q, cache = net.forward(net.bind(flat), x)
    grad = net.backward(net.bind(flat), cache, torch.randn(1, 6, ACTIONS))
    dw = net.bind(grad)[1][0][0][0]  # the inventory branch's first weights, (INV * 4, out)
    copies = dw.view(INV, 4, -1)
    assert torch.all(copies.abs().sum(-1) > 0)  # every copy has its own, non-zero gradient ...
    assert torch.allclose(copies, copies[:, :1].expand_as(copies))  # ... the same for all copies of an entry
    # so under Adam each copy moves by about lr: the entry's summed weight moves 4x faster, which scaling the
    # input by 4 would not do (Adam's step does not grow with the gradient)


def test_dqn_builds_the_configured_inventory_repeat():
    agent = DoubleDQN(_net(), DQNConfig(inventory_repeat=8), [np.random.default_rng(0)])
    assert agent.net.inventory_repeat == 8
    assert agent.online.shape == (1, _net(repeat=8).num_params)
    agent.update(_one_hot_obs(1, 4), torch.zeros(1, 2, dtype=torch.long), torch.ones(1, 2), torch.zeros(1, 2))
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="inventory_repeat must be an integer >= 1"):
            DQNConfig(inventory_repeat=bad)


def test_trainer_and_policy_use_the_configured_inventory_repeat():
    from train.config import TrainConfig
    from train.loop.trainer import Trainer
    from train.storage.policy import Policy

    cfg = TrainConfig().replace(task="salad", seeds=2, inventory_repeat=8, buffer_size=1000, warmup_steps=50,
                                epoch_steps=50, updates_per_epoch=20, eval_every=50, progress=False)
    trainer = Trainer(cfg)
    try:
        trainer.train_epoch()
        assert trainer.agent.net.inventory_repeat == 8
        policy = Policy(trainer.cfg, trainer.agent.online[1:2].clone(), 1)
        obs = torch.from_numpy(np.random.default_rng(0).integers(0, 2, (1, 32, policy.obs_dim)).astype(np.float32))
        np.testing.assert_array_equal(policy.greedy(obs), trainer.agent.greedy(obs.expand(2, -1, -1))[1:])
    finally:
        trainer.close()


def test_a_seed_in_a_sparse_batch_follows_its_run_alone():
    from train.config import TrainConfig
    from train.loop.trainer import Trainer

    def trained(first_seed: int, seeds: int) -> Trainer:
        cfg = TrainConfig().replace(task="salad", dynamism=0.1, first_seed=first_seed, seeds=seeds, eps_start=0.3,
                                    buffer_size=1000, warmup_steps=100, epoch_steps=100, updates_per_epoch=30,
                                    eval_every=100, progress=False)
        trainer = Trainer(cfg)
        for _ in range(2):
            trainer.train_epoch()
        trainer.close()
        return trainer

    together = trained(0, 16)  # 16 x 128 observations per update: the sparse first layer
    assert together.agent.net.view_index(torch.zeros(16, 128, together.info.obs_dim)) is not None  # its size
    alone = trained(5, 1)  # 128 observations: the dense product
    assert torch.allclose(alone.agent.online[0], together.agent.online[5], rtol=1e-4, atol=1e-6)
    assert torch.allclose(alone.agent.target[0], together.agent.target[5], rtol=1e-4, atol=1e-6)
