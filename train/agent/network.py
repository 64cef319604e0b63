"""Batched multilayer perceptrons for K agents (seeds) at once, with a hand-written backward pass.

All parameters of one agent live in one row of a flat ``(K, P)`` buffer; each weight is a view of shape
``(K, in, out)`` into it (stored input-major, so a layer is a single ``baddbmm`` with no transpose), each bias a
view of shape ``(K, 1, out)``. Activations have shape ``(K, N, features)``. The backward pass is written out
by hand: a few large batched products instead of autograd's many small operations, and its gradient comes
back as one ``(K, P)`` tensor that the optimiser, the per-agent gradient clipping and the Polyak update
treat in one operation each. This is what makes a network this small fast on a CPU (see
``shared/reference/perf-notes.md``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

Tensor = torch.Tensor
LayerViews = list[tuple[Tensor, Tensor]]
"""Per layer of a chain: the weight view (K, in, out) and the bias view (K, 1, out)."""

RLKIT_OUTPUT_BOUND = 3e-3
"""rlkit's uniform bound for the weights and biases of an MLP's output layer."""
RLKIT_HIDDEN_BIAS = 0.1
"""rlkit's constant bias of hidden layers."""


@dataclass(frozen=True)
class Chain:
    """An MLP ``sizes[0] -> sizes[1] -> ... -> sizes[-1]``: ReLU after every layer but the last.

    Its parameters occupy ``[offset, offset + num_params)`` of an agent's flat parameter row, layer by
    layer, each layer its weight (input-major) then its bias.
    """

    sizes: tuple[int, ...]
    offset: int = 0

    @property
    def num_params(self) -> int:
        """Number of parameters of the chain."""
        return sum(i * o + o for i, o in zip(self.sizes, self.sizes[1:]))

    @property
    def end(self) -> int:
        """Offset just past the chain's parameters."""
        return self.offset + self.num_params

    def views(self, flat: Tensor) -> LayerViews:
        """Weight and bias views into the flat ``(K, P)`` parameter (or gradient) buffer."""
        k = flat.shape[0]
        out, pos = [], self.offset
        for fan_in, fan_out in zip(self.sizes, self.sizes[1:]):
            w = flat[:, pos:pos + fan_in * fan_out].view(k, fan_in, fan_out)
            pos += fan_in * fan_out
            b = flat[:, pos:pos + fan_out].view(k, 1, fan_out)
            pos += fan_out
            out.append((w, b))
        return out

    def init(self, rng: np.random.Generator, scheme: str) -> np.ndarray:
        """Draw one agent's parameters (float32, length `num_params`) from ``rng``.

        ``rlkit``: hidden weights U(+-1/sqrt(fan_out)) (rlkit reads the fan from the *output* size), hidden
        biases 0.1, output weights and bias U(+-3e-3). ``torch``: PyTorch's ``nn.Linear`` default,
        weights and biases U(+-1/sqrt(fan_in)).
        """
        parts = []
        last = len(self.sizes) - 2
        for i, (fan_in, fan_out) in enumerate(zip(self.sizes, self.sizes[1:])):
            if scheme == "torch":
                bound = 1.0 / np.sqrt(max(fan_in, 1))
                w, b = rng.uniform(-bound, bound, (fan_in, fan_out)), rng.uniform(-bound, bound, fan_out)
            elif scheme == "rlkit" and i == last:
                w = rng.uniform(-RLKIT_OUTPUT_BOUND, RLKIT_OUTPUT_BOUND, (fan_in, fan_out))
                b = rng.uniform(-RLKIT_OUTPUT_BOUND, RLKIT_OUTPUT_BOUND, fan_out)
            elif scheme == "rlkit":
                bound = 1.0 / np.sqrt(fan_out)
                w, b = rng.uniform(-bound, bound, (fan_in, fan_out)), np.full(fan_out, RLKIT_HIDDEN_BIAS)
            else:
                raise ValueError(f"unknown init scheme {scheme!r}; choose 'rlkit' or 'torch'")
            parts += [w.ravel(), b]
        return np.concatenate(parts).astype(np.float32)


def chain_forward(layers: LayerViews, x: Tensor) -> tuple[Tensor, list[Tensor]]:
    """Run a chain on ``x`` (K, N, in); return the output (K, N, out) and each layer's input (for backward)."""
    inputs = []
    h = x
    for i, (w, b) in enumerate(layers):
        inputs.append(h)
        h = torch.baddbmm(b, h, w)
        if i < len(layers) - 1:
            h = h.relu_()
    return h, inputs


def chain_backward(layers: LayerViews, inputs: Sequence[Tensor], grad: Tensor, need_input_grad: bool
                   ) -> tuple[list[Tensor], Tensor | None]:
    """Backpropagate ``grad`` (K, N, out) through a chain whose layer inputs are ``inputs``.

    Returns the parameter gradients in flat order ([dW0, db0, dW1, db1, ...], each (K, -1)) and the
    gradient with respect to the chain's input (None unless ``need_input_grad``).
    """
    k = grad.shape[0]
    grads: list[Tensor] = []
    for i in range(len(layers) - 1, -1, -1):
        w, _ = layers[i]
        a = inputs[i]
        grads += [grad.sum(1), torch.bmm(a.transpose(1, 2), grad).view(k, -1)]
        if i > 0 or need_input_grad:
            grad = torch.bmm(grad, w.transpose(1, 2))
            if i > 0:  # the input of layer i is a ReLU output: pass the gradient where it was positive
                grad = torch.ops.aten.threshold_backward(grad, a, 0)
    grads.reverse()
    return grads, (grad if need_input_grad else None)


class QNetwork:
    """The paper's two-branch Q-network for K agents, as three chains in one flat parameter row.

    The first ``view_dim`` observation entries feed the view branch, the rest the inventory branch; the two
    linear branch outputs are concatenated and fed to the head, whose last layer gives one value per action.
    """

    def __init__(self, view_dim: int, inventory_dim: int, num_actions: int, view_layers: Sequence[int],
                 inventory_layers: Sequence[int], head_layers: Sequence[int]) -> None:
        self.view_dim, self.inventory_dim, self.num_actions = view_dim, inventory_dim, num_actions
        self.view = Chain((view_dim, *view_layers))
        self.inventory = Chain((inventory_dim, *inventory_layers), self.view.end)
        self.head = Chain((view_layers[-1] + inventory_layers[-1], *head_layers, num_actions),
                          self.inventory.end)

    @property
    def chains(self) -> tuple[Chain, Chain, Chain]:
        """The view, inventory and head chains, in parameter order."""
        return self.view, self.inventory, self.head

    @property
    def num_params(self) -> int:
        """Parameters per agent."""
        return self.head.end

    def init(self, rng: np.random.Generator, scheme: str) -> np.ndarray:
        """One agent's freshly initialised parameter row."""
        return np.concatenate([c.init(rng, scheme) for c in self.chains])

    def bind(self, flat: Tensor) -> tuple[LayerViews, LayerViews, LayerViews]:
        """Layer views of each chain into ``flat`` (K, P); valid as long as ``flat`` is updated in place."""
        return tuple(c.views(flat) for c in self.chains)

    def forward(self, bound, x: Tensor) -> tuple[Tensor, tuple]:
        """Q-values (K, N, actions) of observations ``x`` (K, N, obs_dim), and the cache for `backward`."""
        v, v_in = chain_forward(bound[0], x[..., :self.view_dim])
        i, i_in = chain_forward(bound[1], x[..., self.view_dim:])
        q, h_in = chain_forward(bound[2], torch.cat((v, i), -1))
        return q, (v_in, i_in, h_in)

    def backward(self, bound, cache: tuple, grad_q: Tensor) -> Tensor:
        """Gradient (K, P) of the loss given its gradient ``grad_q`` (K, n, actions) w.r.t. the Q-values.

        Only the first ``n`` rows of the forward batch enter the gradient, so one forward pass can also
        carry rows (such as next observations) that need no gradient.
        """
        n = grad_q.shape[1]
        v_in, i_in, h_in = ([a[:, :n] for a in part] for part in cache)
        head_grads, grad_z = chain_backward(bound[2], h_in, grad_q, True)
        split = self.view.sizes[-1]
        view_grads, _ = chain_backward(bound[0], v_in, grad_z[..., :split], False)
        inv_grads, _ = chain_backward(bound[1], i_in, grad_z[..., split:], False)
        return torch.cat(view_grads + inv_grads + head_grads, dim=1)


class MLP:
    """A single batched chain with the same interface as `QNetwork` (used by RND)."""

    def __init__(self, sizes: Sequence[int]) -> None:
        self.chain = Chain(tuple(sizes))

    @property
    def num_params(self) -> int:
        """Parameters per agent."""
        return self.chain.num_params

    def init(self, rng: np.random.Generator, scheme: str) -> np.ndarray:
        """One agent's freshly initialised parameter row."""
        return self.chain.init(rng, scheme)

    def bind(self, flat: Tensor) -> LayerViews:
        """Layer views into ``flat`` (K, P)."""
        return self.chain.views(flat)

    def forward(self, bound: LayerViews, x: Tensor) -> tuple[Tensor, list[Tensor]]:
        """Outputs (K, N, out) and the cache for `backward`."""
        return chain_forward(bound, x)

    def backward(self, bound: LayerViews, cache: list[Tensor], grad_out: Tensor) -> Tensor:
        """Gradient (K, P) given the gradient w.r.t. the first ``grad_out.shape[1]`` output rows."""
        n = grad_out.shape[1]
        grads, _ = chain_backward(bound, [a[:, :n] for a in cache], grad_out, False)
        return torch.cat(grads, dim=1)
