"""Double-DQN pieces: the target, the epsilon schedule, the hand-written backward pass, Adam and clipping."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from train.agent.dqn import DoubleDQN, FlatAdam, clip_grad_norm_per_agent, double_dqn_target
from train.agent.network import QNetwork
from train.config import DQNConfig


def test_target_uses_online_argmax_and_target_values():
    online = torch.tensor([[1.0, 5.0, 2.0]])  # online picks action 1
    target = torch.tensor([[10.0, 3.0, 7.0]])  # ... which the target values at 3 (its own max would be 10)
    y = double_dqn_target(online, target, torch.tensor([1.0]), torch.tensor([0.0]), gamma=0.5)
    assert y.item() == pytest.approx(1.0 + 0.5 * 3.0)


def test_target_masks_terminal_but_not_truncation():
    online = torch.tensor([[0.0, 1.0], [0.0, 1.0]])
    target = torch.tensor([[4.0, 8.0], [4.0, 8.0]])
    reward = torch.tensor([2.0, 2.0])
    # a terminal transition does not bootstrap; a truncated one is stored as non-terminal and does
    terminated = torch.tensor([1.0, 0.0])
    y = double_dqn_target(online, target, reward, terminated, gamma=0.9)
    assert y.tolist() == pytest.approx([2.0, 2.0 + 0.9 * 8.0])


def test_target_broadcasts_over_agents_and_batch():
    q = torch.randn(3, 5, 7)
    qt = torch.randn(3, 5, 7)
    r, d = torch.randn(3, 5), torch.zeros(3, 5)
    y = double_dqn_target(q, qt, r, d, 0.99)
    expect = r + 0.99 * qt.gather(-1, q.argmax(-1, keepdim=True)).squeeze(-1)
    assert torch.allclose(y, expect)


def test_epsilon_schedule_is_linear_then_flat():
    cfg = DQNConfig()
    assert cfg.epsilon(0) == 1.0
    assert cfg.epsilon(45_000) == pytest.approx(0.55)
    assert cfg.epsilon(90_000) == pytest.approx(0.1)
    assert cfg.epsilon(1_000_000) == pytest.approx(0.1)
    # the original's rule: max(1 - 1e-5 t, 0.1)
    for t in (1, 777, 12_345, 89_999):
        assert cfg.epsilon(t) == pytest.approx(max(1 - 1e-5 * t, 0.1))


def _net(view=20, inv=6, actions=7):
    return QNetwork(view, inv, actions, (8, 8, 4), (5, 5, 3), (6, 6))


@pytest.mark.parametrize("scheme", ["rlkit", "torch"])
def test_backward_matches_autograd(scheme):
    net = _net()
    rng = np.random.default_rng(0)
    flat = torch.tensor(np.stack([net.init(rng, scheme) for _ in range(3)]), dtype=torch.float64)
    x = torch.tensor(rng.integers(0, 2, (3, 10, 26)), dtype=torch.float64)
    grad_q = torch.randn(3, 5, 7, dtype=torch.float64)
    q, cache = net.forward(net.bind(flat), x)
    mine = net.backward(net.bind(flat), cache, grad_q)  # only the first 5 rows carry gradient
    leaf = flat.clone().requires_grad_(True)
    q2, _ = net.forward(net.bind(leaf), x)
    (q2[:, :5] * grad_q).sum().backward()
    assert torch.allclose(q, q2)
    assert torch.allclose(mine, leaf.grad, atol=1e-12)


def test_rlkit_init_bounds():
    net = _net()
    row = torch.from_numpy(net.init(np.random.default_rng(1), "rlkit"))[None]
    view_layers = net.bind(row)[0]
    (w0, b0), (w1, b1), (w2, b2) = view_layers
    assert w0.abs().max() <= 1 / np.sqrt(8) and torch.all(b0 == 0.1)  # hidden: fan = output size (rlkit)
    assert w2.abs().max() <= 3e-3 and b2.abs().max() <= 3e-3  # output layer


@pytest.mark.parametrize("fused", [True, False], ids=["fused", "plain"])
def test_flat_adam_is_textbook_adam(fused):
    # Kingma & Ba with bias correction, eps added to the corrected root (PyTorch's rule); torch.optim
    # itself is not used here because its first step imports the compiler stack (seconds).
    lr, b1, b2, eps = 1e-2, 0.9, 0.999, 1e-8
    params = torch.randn(2, 50, dtype=torch.float64)
    mine, ref = params.clone(), params.clone()
    m, v = torch.zeros_like(ref), torch.zeros_like(ref)
    flat_adam = FlatAdam(mine, lr=lr, eps=eps, fused=fused)
    for t in range(1, 6):
        grad = torch.randn(2, 50, dtype=torch.float64)
        m = b1 * m + (1 - b1) * grad
        v = b2 * v + (1 - b2) * grad**2
        ref = ref - lr * (m / (1 - b1**t)) / ((v / (1 - b2**t)).sqrt() + eps)
        flat_adam.step(mine, grad)
    assert flat_adam.steps == 5
    assert torch.allclose(mine, ref, atol=1e-12)


def _adam_steps(params: torch.Tensor, grads: list[torch.Tensor], per_row: bool | None = None) -> torch.Tensor:
    """``params`` after one FlatAdam step per gradient (all on the parameters' device)."""
    params = params.clone()
    adam = FlatAdam(params, lr=1e-3)
    if per_row is not None:
        adam.per_row = per_row
    for grad in grads:
        adam.step(params, grad.to(params.device))
    return params.cpu()


def test_flat_adam_hands_the_cpu_kernel_one_tensor_per_row():
    assert FlatAdam(torch.zeros(3, 5), lr=1e-3).per_row


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_flat_adam_on_cuda_updates_a_row_as_if_alone():
    # Why FlatAdam hands the CUDA kernel one (K, P) tensor: each row comes out bit for bit as when updated
    # row by row or alone, so a seed's training does not depend on the seeds beside it. Rows of 1 001 floats
    # start off any vector boundary.
    gen = torch.Generator().manual_seed(0)
    params = torch.randn(7, 1001, generator=gen).cuda()
    grads = [torch.randn(7, 1001, generator=gen) for _ in range(5)]
    assert not FlatAdam(params, lr=1e-3).per_row
    flat, by_rows = _adam_steps(params, grads), _adam_steps(params, grads, per_row=True)
    alone = _adam_steps(params[3:4], [g[3:4] for g in grads])
    assert torch.equal(flat, by_rows)
    assert torch.equal(flat[3], alone[0])


def test_gradient_clipping_is_per_agent():
    grad = torch.tensor([[3.0, 4.0], [0.3, 0.4]])  # norms 5 and 0.5
    clip_grad_norm_per_agent(grad, 1.0)
    assert torch.linalg.vector_norm(grad, dim=1).tolist() == pytest.approx([1.0, 0.5], rel=1e-5)


def test_update_reduces_td_error_on_a_fixed_batch():
    cfg = DQNConfig(lr=1e-2, init="torch")
    agent = DoubleDQN(_net(), cfg, [np.random.default_rng(s) for s in range(2)])
    gen = torch.Generator().manual_seed(0)
    obs = torch.randint(0, 2, (2, 16, 26), generator=gen).float()
    actions = torch.randint(0, 7, (2, 8), generator=gen)
    rewards = torch.randn(2, 8, generator=gen)
    terminated = torch.ones(2, 8)  # no bootstrapping: a pure regression target
    first = agent.update(obs, actions, rewards, terminated)
    for _ in range(200):
        last = agent.update(obs, actions, rewards, terminated)
    assert torch.all(last < 0.1 * first)


def test_target_network_follows_online_by_polyak():
    cfg = DQNConfig(tau=0.5, target_init="independent")
    agent = DoubleDQN(_net(), cfg, [np.random.default_rng(0)])
    assert not torch.equal(agent.online, agent.target)
    before = agent.target.clone()
    obs = torch.zeros(1, 4, 26)
    agent.update(obs, torch.zeros(1, 2, dtype=torch.long), torch.ones(1, 2), torch.zeros(1, 2))
    assert torch.allclose(agent.target, 0.5 * before + 0.5 * agent.online)
    copied = DoubleDQN(_net(), DQNConfig(target_init="copy"), [np.random.default_rng(0)])
    assert torch.equal(copied.online, copied.target)
