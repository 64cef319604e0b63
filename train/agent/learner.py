"""The learner seam: what the training loop asks of a learning algorithm, and the batched double DQN behind it.

The loop (`train.loop.trainer`) owns seeds, worlds, evaluation, checkpoints and logging; a `Learner` owns
everything about learning: networks, optimiser, replay, exploration, intrinsic rewards and the schedule of
collecting and updating. Agent row ``k`` of a learner is one seed of one condition; a packed learner holds
the rows of several conditions of one task (`RowSettings` gives each row its own learning rate,
exploration schedule and RND flag), and its state can be cut into per-condition pieces that are exactly
what a learner of those rows alone would save (`state_dict(rows)`).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import torch

from train.agent.dqn import DoubleDQN
from train.agent.network import QNetwork
from train.agent.replay import Batch, Replay
from train.agent.rnd import RND
from train.agent.staging import Stager
from train.config import DQNConfig, RNDConfig

GRAPH_WARMUP = 3
"""Gradient steps run eagerly on a GPU before one is captured as a CUDA graph (the first kernels' set-up)."""
STREAMS = ("init", "explore", "sample", "rnd")
"""The random streams of each seed, spawned from its SeedSequence in this order."""


def seed_streams(seed: int) -> dict[str, np.random.Generator]:
    """The independent random generators of one seed."""
    return {name: np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))
            for i, name in enumerate(STREAMS)}


@runtime_checkable
class Learner(Protocol):
    """What the training loop needs of a learning algorithm over K agent rows."""

    num_agents: int
    device: torch.device

    def steps_to_collect(self, step: int) -> int:
        """Environment steps to take, from lifetime step ``step``, before the next `learn`."""

    def begin_collect(self, n: int) -> None:
        """Prepare ``n`` steps of acting (e.g. draw their exploration noise)."""

    def act(self, obs: np.ndarray, step: int) -> np.ndarray:
        """Training actions (K,) for observations (K, obs_dim) at lifetime step ``step``."""

    def q_values(self, obs: torch.Tensor) -> torch.Tensor:
        """Action values (K, N, actions) on the CPU of observations (K, N, obs_dim) (evaluation, policies)."""

    def greedy(self, obs: torch.Tensor) -> np.ndarray:
        """Greedy actions (K, N) for observations (K, N, obs_dim) (evaluation and policies)."""

    def observe(self, stored: np.ndarray, obs: np.ndarray, actions: np.ndarray, reward: np.ndarray,
                terminated: np.ndarray, truncated: np.ndarray, next_obs: np.ndarray,
                completed: np.ndarray | None = None) -> None:
        """Record one environment step of the rows where ``stored`` (the others only reset their world);
        ``completed``: the rows whose task was completed this step (None: unknown, none).
        """

    def learn(self) -> None:
        """The update phase that follows a collection."""

    def take_losses(self) -> np.ndarray:
        """Mean training loss (K,) since the last call (NaN where no update ran)."""

    def state_dict(self, rows: slice = slice(None)) -> dict[str, Any]:
        """Everything needed to continue agent rows ``rows`` exactly, as data."""

    def load_state_dict(self, state: dict[str, Any], rows: slice = slice(None)) -> None:
        """Restore agent rows ``rows`` from a `state_dict`."""


@dataclass(frozen=True)
class RowSettings:
    """The settings of one agent row that may differ between the conditions of a packed learner."""

    seed: int
    dqn: DQNConfig
    rnd: RNDConfig

    @property
    def lr(self) -> float:
        """Adam learning rate of this row."""
        return self.dqn.lr


class DQNLearner:
    """Batched double DQN (+ optional RND) over K rows: replay, epsilon-greedy, the original code's schedule.

    The schedule is ``warmup_steps`` steps, then epochs of ``epoch_steps`` steps each followed by
    ``updates_per_epoch`` gradient steps. Every row has its own random streams (`seed_streams`), so a row
    trained beside others follows the trajectory it follows alone, up to float rounding.
    """

    def __init__(self, rows: Sequence[RowSettings], net: QNetwork, binary_obs: bool,
                 device: str | torch.device = "cpu", graphs: bool = True, static_batches: bool = False) -> None:
        """``net``: the Q-network of every row (`QNetwork.from_config`); ``binary_obs``: observations are 0/1
        (the replay bit-packs them); ``graphs``: on a GPU, capture a gradient step as a CUDA graph and
        replay it; ``static_batches``: read minibatches as a GPU does, also on the CPU (for tests; see
        `train.agent.staging`).
        """
        self.rows = list(rows)
        self.cfg = cfg = self.rows[0].dqn  # the settings every row shares (`train.loop.packing` checks them)
        self.num_actions = net.num_actions
        obs_dim = net.view_dim + net.inventory_dim
        self.device = torch.device(device)
        streams = [seed_streams(r.seed) for r in self.rows]
        self.rngs = {name: [s[name] for s in streams] for name in STREAMS}
        self.agent = DoubleDQN(net, cfg, self.rngs["init"], [r.lr for r in self.rows], self.device)
        self.rnd_rows = np.flatnonzero([r.rnd.rnd for r in self.rows])
        self._rnd_index = torch.from_numpy(self.rnd_rows).to(self.device)  # the rows RND's bonus goes to
        self.rnd = (RND(obs_dim, self.rows[self.rnd_rows[0]].rnd, [self.rngs["rnd"][k] for k in self.rnd_rows],
                        self.device) if self.rnd_rows.size else None)
        self.replay = Replay(self.num_agents, cfg.buffer_size, obs_dim, binary_obs, cfg.float_obs_dtype)
        self.loss_sum = torch.zeros(self.num_agents, device=self.device)
        self.loss_count = 0
        self._stager = Stager(self.replay, cfg.batch_size, cfg.updates_per_epoch, self.device, static_batches)
        self.graphs = graphs and self.device.type == "cuda"
        """Replay each gradient step, and the acting forward pass, from captured CUDA graphs (on a GPU only)."""
        self._stream = torch.cuda.Stream(self.device) if self.graphs else None  # see `_capture_stream`
        self._graph: torch.cuda.CUDAGraph | None = None
        self._eager_steps = 0
        self._act_graph: tuple | None = None  # the acting forward pass's graph and its buffers (`_greedy_now`)
        self._draws = np.zeros((0, self.num_agents, 2))
        self._eps = {name: np.array([getattr(r.dqn, name) for r in self.rows], dtype=float)
                     for name in ("eps_start", "eps_end", "eps_decay_steps")}
        decay = self._eps["eps_decay_steps"]
        self._eps["decays"], self._eps["span"] = decay > 0, np.where(decay > 0, decay, 1.0)  # no 0 to divide by

    @property
    def num_agents(self) -> int:
        """K, the number of agent rows."""
        return len(self.rows)

    # ---- acting ---------------------------------------------------------------------------------------

    def steps_to_collect(self, step: int) -> int:
        """The rest of the warm-up (if any) and one epoch of steps."""
        return max(self.cfg.warmup_steps - step, 0) + self.cfg.epoch_steps

    def begin_collect(self, n: int) -> None:
        """Draw the exploration noise of the next ``n`` steps (two uniforms per row and step)."""
        self._draws = np.stack([rng.random((n, 2)) for rng in self.rngs["explore"]], axis=1)  # (n, K, 2)
        self._next_draw = 0

    def epsilon(self, step: int) -> np.ndarray:
        """Each row's exploration epsilon at lifetime step ``step`` (K,): `DQNConfig.epsilon` of every row at
        once, the same arithmetic.
        """
        eps = self._eps
        frac = np.where(eps["decays"], np.minimum(max(step, 0) / eps["span"], 1.0), 1.0)
        return eps["eps_start"] + (eps["eps_end"] - eps["eps_start"]) * frac

    def act(self, obs: np.ndarray, step: int) -> np.ndarray:
        """Epsilon-greedy actions (K,), from the noise drawn by `begin_collect`."""
        draws = self._draws[self._next_draw]
        self._next_draw += 1
        explore = draws[:, 0] < self.epsilon(step)
        actions = (draws[:, 1] * self.num_actions).astype(np.int64)
        if not explore.all():
            with torch.no_grad():
                greedy = self._greedy_now(torch.from_numpy(obs).unsqueeze(1))
            actions = np.where(explore, actions, greedy)
        return actions

    def _greedy_now(self, obs: torch.Tensor) -> np.ndarray:
        """Greedy actions (K,) for one observation per row (K, 1, obs_dim): on a GPU with graphs on, the
        forward pass is captured after its first, eager run and replayed, its input copied from pinned memory.
        """
        if not self.graphs:
            return self.greedy(obs)[:, 0]
        if self._act_graph is None:
            host, on_device = obs.pin_memory(), obs.to(self.device)
            with self._capture_stream():
                first = self.agent.q_values(on_device).argmax(-1)
                graph = torch.cuda.CUDAGraph()
                with torch.cuda.graph(graph, stream=self._stream):  # records the kernels without running them
                    out = self.agent.q_values(on_device).argmax(-1)
            self._act_graph = graph, host, on_device, out
            return first[:, 0].cpu().numpy()
        graph, host, on_device, out = self._act_graph
        host.copy_(obs)
        on_device.copy_(host, non_blocking=True)
        graph.replay()
        return out[:, 0].cpu().numpy()

    def q_values(self, obs: torch.Tensor) -> torch.Tensor:
        """Online action values (K, N, actions), on the CPU, of observations (K, N, obs_dim)."""
        return self.agent.q_values(obs.to(self.device)).cpu()

    def greedy(self, obs: torch.Tensor) -> np.ndarray:
        """Greedy actions (K, N) of observations (K, N, obs_dim)."""
        return self.agent.greedy(obs)

    # ---- storing and learning -------------------------------------------------------------------------

    def observe(self, stored: np.ndarray, obs: np.ndarray, actions: np.ndarray, reward: np.ndarray,
                terminated: np.ndarray, truncated: np.ndarray, next_obs: np.ndarray,
                completed: np.ndarray | None = None) -> None:
        """Store the transitions of the rows where ``stored``; an episode's final observation gets its own
        slot, as the last transition's next state. With ``completion_terminal``, a completed task is a terminal
        transition even where the world goes on (``completed``: the rows that completed theirs this step).
        """
        ends = terminated | (truncated & self.cfg.timeouts_terminal)  # the original's episodic rule, if asked
        if completed is not None and self.cfg.completion_terminal:
            ends = ends | completed  # the released factory script's rule, where asked
        self.replay.add(stored, self.replay.encode(obs), actions, reward, ends)
        ended = (terminated | truncated) & stored
        if ended.any():
            self.replay.add(ended, self.replay.encode(next_obs))

    def learn(self) -> None:
        """The epoch's gradient steps: every row on its own minibatch each time, staged a chunk at a time."""
        n = self.cfg.updates_per_epoch
        slots = self.replay.sample_indices(self.rngs["sample"], n, self.cfg.batch_size)
        stager = self._stager
        with torch.no_grad():
            for first in range(0, n, stager.chunk):
                for i in range(stager.load(slots[:, first:first + stager.chunk])):
                    self._gradient_step(i)

    def _gradient_step(self, i: int) -> None:
        """Gradient step ``i`` of the staged chunk: replayed from the CUDA graph once there is one, else run
        (and, after `GRAPH_WARMUP` steps on a GPU with graphs on, captured).
        """
        stager = self._stager
        if stager.static:
            stager.select(i)
        if self._graph is not None:
            self._graph.replay()
        elif not self.graphs:
            self._update(stager.batch(i))
        else:
            with self._capture_stream():
                self._update(stager.batch(i))
                self._eager_steps += 1
                if self._eager_steps == GRAPH_WARMUP:
                    self._graph = torch.cuda.CUDAGraph()
                    with torch.cuda.graph(self._graph, stream=self._stream):  # records the kernels, runs none
                        self._update(stager.batch(i))
        self.loss_count += 1

    @contextmanager
    def _capture_stream(self) -> Iterator[None]:
        """Run the enclosed GPU work on the learner's own side stream, after what the current stream has
        queued and before what it queues next. The eager steps that precede a capture run on the stream
        that captures, as PyTorch's CUDA-graph notes ask: libraries such as cuBLAS set up per-stream state on
        first use, which must not happen during a capture.
        """
        current = torch.cuda.current_stream(self.device)
        self._stream.wait_stream(current)
        with torch.cuda.stream(self._stream):
            yield
        current.wait_stream(self._stream)

    def _update(self, batch: Batch) -> None:
        """One gradient step of every row on ``batch`` (with the RND bonus on its rows)."""
        batch_size = batch.actions.shape[1]
        obs_pairs, actions = batch.obs_pairs.to(self.device), batch.actions.to(self.device)
        rewards, terminated = batch.rewards.to(self.device), batch.terminated.to(self.device)
        if self.rnd is not None:
            rnd = self._rnd_index
            rewards = rewards.index_add(0, rnd, self.rnd.bonus(obs_pairs[rnd, batch_size:]))
        self.loss_sum += self.agent.update(obs_pairs, actions, rewards, terminated)

    def take_losses(self) -> np.ndarray:
        """Mean TD loss per row since the last call (NaN before any update); resets the sums."""
        losses = (self.loss_sum / self.loss_count).cpu().numpy() if self.loss_count else np.full(
            self.num_agents, np.nan)
        self.loss_sum.zero_()
        self.loss_count = 0
        return losses

    # ---- state ----------------------------------------------------------------------------------------

    def _rnd_part(self, rows: slice) -> slice | None:
        """The rows of the RND networks that belong to agent rows ``rows`` (None if they have none)."""
        k = np.arange(self.num_agents)[rows]
        inside = np.flatnonzero(np.isin(self.rnd_rows, k))
        return slice(int(inside[0]), int(inside[-1]) + 1) if inside.size else None

    def state_dict(self, rows: slice = slice(None)) -> dict[str, Any]:
        """Networks, optimiser, replay, RND, random streams and loss sums of agent rows ``rows``."""
        part = self._rnd_part(rows)
        return {
            "agent": take_rows(self.agent.state_dict(), rows),
            "rnd": take_rows(self.rnd.state_dict(), part) if part is not None else None,
            "replay": self.replay.state_dict(rows),
            "rngs": {name: [g.bit_generator.state for g in gens[rows]] for name, gens in self.rngs.items()},
            "loss_sum": self.loss_sum[rows].cpu().clone(), "loss_count": self.loss_count,
        }

    def load_state_dict(self, state: dict[str, Any], rows: slice = slice(None)) -> None:
        """Restore agent rows ``rows``; shapes are checked first (ValueError), since copy_ would broadcast."""
        self.agent.load_state_dict(put_rows(self.agent.state_dict(), state["agent"], rows, "agent"))
        part = self._rnd_part(rows)
        if part is not None:
            self.rnd.load_state_dict(put_rows(self.rnd.state_dict(), state["rnd"], part, "rnd"))
        self.replay.load_state_dict(state["replay"], rows)
        for name, gens in self.rngs.items():
            for g, saved in zip(gens[rows], state["rngs"][name], strict=True):
                g.bit_generator.state = saved
        loss_sum = torch.as_tensor(state["loss_sum"])
        if loss_sum.shape != self.loss_sum[rows].shape:
            raise ValueError(f"loss_sum has shape {tuple(loss_sum.shape)}, this run needs "
                             f"{tuple(self.loss_sum[rows].shape)}")
        self.loss_sum[rows] = loss_sum.to(self.device)
        self.loss_count = int(state["loss_count"])


def take_rows(tree: Any, rows: slice) -> Any:
    """The agent rows ``rows`` of every tensor in ``tree`` (other values unchanged)."""
    if isinstance(tree, dict):
        return {key: take_rows(value, rows) for key, value in tree.items()}
    if isinstance(tree, torch.Tensor) and tree.dim() > 0:
        return tree[rows].cpu().clone()
    return tree


def put_rows(full: Any, part: Any, rows: slice, where: str) -> Any:
    """``full`` with agent rows ``rows`` of each tensor replaced by ``part``'s; shapes must match exactly."""
    if isinstance(full, dict):
        if not isinstance(part, dict):
            raise ValueError(f"{where} is {type(part).__name__}, not a group of arrays")
        return {key: put_rows(value, part[key], rows, f"{where}/{key}") for key, value in full.items()}
    if isinstance(full, torch.Tensor) and full.dim() > 0:
        need = full[rows].shape
        if not isinstance(part, torch.Tensor) or part.shape != need:
            shape = tuple(part.shape) if isinstance(part, torch.Tensor) else type(part).__name__
            raise ValueError(f"{where} has shape {shape}, this run needs {tuple(need)}")
        full[rows] = part.to(full.dtype)
        return full
    return part
