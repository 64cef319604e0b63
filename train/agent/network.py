"""Batched multilayer perceptrons for K agents (seeds) at once, with a hand-written backward pass.

All parameters of one agent live in one row of a flat ``(K, P)`` buffer; each weight is a view of shape
``(K, in, out)`` into it (stored input-major, so a layer is a single ``baddbmm`` with no transpose), each bias a
view of shape ``(K, 1, out)``. Activations have shape ``(K, N, features)``. The backward pass is written out
by hand: a few large batched products instead of autograd's many small operations, and its gradient comes
back as one ``(K, P)`` tensor (each layer writes its part in place) that the optimiser, the per-agent
gradient clipping and the Polyak update treat in one operation each. This is what makes a network this
small fast on a CPU (measured in docs/speed.md).

Grid observations are 0/1 with a few active entries (25 of 125 for salad's 5 x 5 x 5 view), so for large
batches the first view layer is computed as the sum of the weight rows of the active entries and the bias
(`QNetwork.view_index`, one ``embedding_bag``), which equals the dense product up to float rounding; its
backward stays dense.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
import torch

Tensor = torch.Tensor
LayerViews = list[tuple[Tensor, Tensor]]
"""Per layer of a chain: the weight view (K, in, out) and the bias view (K, 1, out)."""

SPARSE_MIN_ROWS = 2048
"""Fewest observations (K x N) for which `QNetwork.view_index` builds a sparse index. On salad (one torch
thread, a shared 2-core Xeon) the sum of weight rows is 1.8x (K = 10) and 2.3x (K = 40) faster than the
dense product at N = 128, but finding the active cells costs nearly as much as the product, so only large
batches, whose index serves both the online and the target forward, gain (an update at K = 40: 1.14x)."""
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


def chain_backward(layers: LayerViews, inputs: Sequence[Tensor], grad: Tensor, need_input_grad: bool,
                   out: LayerViews) -> Tensor | None:
    """Backpropagate ``grad`` (K, N, out) through a chain whose layer inputs are ``inputs``.

    Writes each layer's weight and bias gradients into ``out`` (the chain's views into a flat gradient
    buffer) and returns the gradient with respect to the chain's input (None unless ``need_input_grad``).
    """
    for i in range(len(layers) - 1, -1, -1):
        w, _ = layers[i]
        a = inputs[i]
        dw, db = out[i]
        if dw.is_contiguous():  # one agent: the view is plain memory
            torch.bmm(a.transpose(1, 2), grad, out=dw)
        else:  # bmm into a batch-strided output loops over the batch on the CPU: copy instead
            dw.copy_(torch.bmm(a.transpose(1, 2), grad))
        torch.sum(grad, 1, keepdim=True, out=db)
        if i > 0 or need_input_grad:
            grad = torch.bmm(grad, w.transpose(1, 2))
            if i > 0:  # the input of layer i is a ReLU output: pass the gradient where it was positive
                grad = torch.ops.aten.threshold_backward(grad, a, 0)
    return grad if need_input_grad else None


def grad_buffer(net: QNetwork | MLP, like: Tensor) -> tuple[Tensor, tuple]:
    """``net``'s (K, P) gradient buffer for ``like``'s K and dtype, and its layer views: made once, then
    reused by every backward pass (each overwrites all of it).
    """
    key = (like.shape[0], like.dtype)
    if key not in net._grads:
        grad = like.new_empty(like.shape[0], net.num_params)
        net._grads[key] = grad, net.bind(grad)
    return net._grads[key]


@numba.njit(cache=True)
def _active_cells(x: np.ndarray, per_agent: int, view_dim: int, max_width: int) -> np.ndarray:  # pragma: no cover
    """Per row of ``x`` (K * N, obs_dim), its bias row and active view rows in `ViewIndex` numbering.

    Agent ``a`` owns rows ``a * N ...``; its view entry ``j`` is table row ``a * (view_dim + 1) + j``, its
    bias ``j = view_dim``. Returns (K * N, 2 + width) int32: the bias row, the active rows, then at least
    one padding slot ``K * (view_dim + 1)``; or an empty array if a view entry is neither 0 nor 1 or a row
    has more than ``max_width`` active entries. Branch-free loops: the 0/1 pattern is unpredictable.
    """
    rows = x.shape[0]
    width, bad = 0, False
    for r in range(rows):
        count = 0
        for j in range(view_dim):
            v = x[r, j]
            count += v != 0.0
            bad |= (v != 0.0) & (v != 1.0)
        width = max(width, count)
    if bad or width > max_width:
        return np.empty((0, 0), np.int32)
    pad = (rows // per_agent) * (view_dim + 1)
    out = np.empty((rows, width + 2), np.int32)
    for r in range(rows):
        base = (r // per_agent) * (view_dim + 1)
        out[r, 0] = base + view_dim
        c = 1
        for j in range(view_dim):
            out[r, c] = base + j  # kept only where x is 1: the next slot is written next
            c += x[r, j] != 0.0
        out[r, c:] = pad
    return out


@dataclass(frozen=True)
class ViewIndex:
    """The active cells of binary view observations, for the first view layer's sparse forward.

    ``rows`` (K, N, W) are row numbers into the table of every agent's first-layer weight rows and bias
    (agent ``k``'s row ``j`` is ``k * (view_dim + 1) + j``), then a zero row that fills unused slots.
    """

    rows: Tensor

    def tail(self, start: int) -> ViewIndex:
        """The index of observations ``start:`` of every agent."""
        return ViewIndex(self.rows[:, start:].contiguous())


class QNetwork:
    """The paper's two-branch Q-network for K agents, as three chains in one flat parameter row.

    The first ``view_dim`` observation entries feed the view branch, the rest the inventory branch (each
    inventory entry repeated ``inventory_repeat`` times in a row, as ``np.repeat``); the two linear branch
    outputs are concatenated and fed to the head, whose last layer gives one value per action.
    """

    def __init__(self, view_dim: int, inventory_dim: int, num_actions: int, view_layers: Sequence[int],
                 inventory_layers: Sequence[int], head_layers: Sequence[int], inventory_repeat: int = 1) -> None:
        self.view_dim, self.inventory_dim, self.num_actions = view_dim, inventory_dim, num_actions
        self.inventory_repeat = inventory_repeat
        self._layers = (tuple(view_layers), tuple(inventory_layers), tuple(head_layers))
        self.view = Chain((view_dim, *view_layers))
        self.inventory = Chain((inventory_dim * inventory_repeat, *inventory_layers), self.view.end)
        self.head = Chain((view_layers[-1] + inventory_layers[-1], *head_layers, num_actions),
                          self.inventory.end)
        self._tables: dict[tuple, Tensor] = {}
        self._grads: dict[tuple, tuple[Tensor, tuple]] = {}  # see `grad_buffer`

    @classmethod
    def from_config(cls, view_dim: int, obs_dim: int, num_actions: int, dqn) -> QNetwork:
        """The network a `train.config.DQNConfig` ``dqn`` describes, for observations of ``obs_dim`` entries
        whose first ``view_dim`` are the view.
        """
        return cls(view_dim, obs_dim - view_dim, num_actions, dqn.view_layers, dqn.inventory_layers,
                   dqn.head_layers, dqn.inventory_repeat)

    def with_inventory_repeat(self, repeat: int) -> QNetwork:
        """This network with the inventory repeated ``repeat`` times (itself if it already is)."""
        if repeat == self.inventory_repeat:
            return self
        return QNetwork(self.view_dim, self.inventory_dim, self.num_actions, *self._layers, inventory_repeat=repeat)

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

    def view_index(self, x: Tensor, min_rows: int | None = None) -> ViewIndex | None:
        """The active view cells of observations ``x`` (K, N, obs_dim), or None where the sparse forward
        does not apply (a view entry other than 0 and 1, more than a third of the view active, not on the
        CPU) or does not pay (fewer than ``min_rows`` rows, default `SPARSE_MIN_ROWS`).
        """
        k, n, obs_dim = x.shape
        if k * n < (SPARSE_MIN_ROWS if min_rows is None else min_rows) or x.device.type != "cpu":
            return None
        flat = np.ascontiguousarray(x.detach().numpy()).reshape(k * n, obs_dim)
        rows = _active_cells(flat, n, self.view_dim, self.view_dim // 3)
        if rows.size == 0:
            return None
        return ViewIndex(torch.from_numpy(rows).view(k, n, -1))

    def _first_view_layer(self, w: Tensor, index: ViewIndex) -> Tensor:
        """The first view layer (before its ReLU) as the sum of the weight rows of the active cells.

        The bias row is one of the summed rows (the bias folded into the sum); the products are exact
        for 0/1 inputs, so this equals the dense product up to float rounding.
        """
        k, d, out = w.shape
        key = (k, d, out, w.dtype)
        if key not in self._tables:  # the weight rows and bias of every agent, then a zero padding row
            self._tables[key] = torch.zeros(k * (d + 1) + 1, out, dtype=w.dtype)
        table = self._tables[key]
        # the bias of a layer follows its weights in the flat row, so one strided view holds both
        table[:-1].view(k, d + 1, out).copy_(w.as_strided((k, d + 1, out), w.stride()))
        rows = index.rows
        h = torch.nn.functional.embedding_bag(rows.view(-1, rows.shape[-1]), table, mode="sum")
        return h.view(k, rows.shape[1], out)

    def _view_forward(self, layers: LayerViews, x: Tensor, index: ViewIndex | None) -> tuple[Tensor, list[Tensor]]:
        """The view branch: the first layer sparse when ``index`` is given, the rest as `chain_forward`."""
        if index is None:
            return chain_forward(layers, x)
        h = self._first_view_layer(layers[0][0], index)
        if len(layers) == 1:
            return h, [x]
        out, inputs = chain_forward(layers[1:], h.relu_())
        return out, [x, *inputs]

    def _inventory_input(self, x: Tensor) -> Tensor:
        """The inventory part of observations ``x``, each entry repeated ``inventory_repeat`` times."""
        inventory = x[..., self.view_dim:]
        return inventory if self.inventory_repeat == 1 else inventory.repeat_interleave(self.inventory_repeat, -1)

    def forward(self, bound, x: Tensor, index: ViewIndex | None = None) -> tuple[Tensor, tuple]:
        """Q-values (K, N, actions) of observations ``x`` (K, N, obs_dim), and the cache for `backward`.

        ``index`` (`view_index` of ``x``) makes the first view layer a sum of weight rows.
        """
        v, v_in = self._view_forward(bound[0], x[..., :self.view_dim], index)
        i, i_in = chain_forward(bound[1], self._inventory_input(x))
        q, h_in = chain_forward(bound[2], torch.cat((v, i), -1))
        return q, (v_in, i_in, h_in)

    def backward(self, bound, cache: tuple, grad_q: Tensor) -> Tensor:
        """Gradient (K, P) of the loss given its gradient ``grad_q`` (K, n, actions) w.r.t. the Q-values.

        Only the first ``n`` rows of the forward batch enter the gradient, so one forward pass can also
        carry rows (such as next observations) that need no gradient. Every layer writes its gradient
        straight into the returned buffer, which the next call reuses.
        """
        n = grad_q.shape[1]
        v_in, i_in, h_in = ([a[:, :n] for a in part] for part in cache)
        grad, views = grad_buffer(self, grad_q)
        grad_z = chain_backward(bound[2], h_in, grad_q, True, views[2])
        split = self.view.sizes[-1]
        chain_backward(bound[0], v_in, grad_z[..., :split], False, views[0])
        chain_backward(bound[1], i_in, grad_z[..., split:], False, views[1])
        return grad


class MLP:
    """A single batched chain with the same interface as `QNetwork` (used by RND)."""

    def __init__(self, sizes: Sequence[int]) -> None:
        self.chain = Chain(tuple(sizes))
        self._grads: dict[tuple, tuple[Tensor, LayerViews]] = {}  # see `grad_buffer`

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
        """Gradient (K, P) given the gradient w.r.t. the first ``grad_out.shape[1]`` output rows (a buffer
        that the next call reuses).
        """
        n = grad_out.shape[1]
        grad, views = grad_buffer(self, grad_out)
        chain_backward(bound, [a[:, :n] for a in cache], grad_out, False, views)
        return grad
