"""One replay buffer for K agents: each agent's stream of observations, stored once and compactly.

Slot ``j`` of agent ``k`` holds one observation and, when it starts a transition, the action taken from it,
the reward and whether the next state is terminal; the next observation is slot ``j + 1`` (circularly). An
episode's final observation gets a slot of its own that starts no transition, so every observation is
stored once. Binary observations (the grid tasks, values in {0, 1}) are bit-packed (130 values -> 17
bytes) and unpacked at sample time; real-valued ones are stored as float16 or float32.

Validity: a slot is sampled only if it starts a transition and is not the newest slot (whose successor is
not written yet). When the ring wraps, the oldest slot is overwritten; its predecessor is then the newest
slot, which is never sampled, so no transition ever pairs observations from different times.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

TERMINATED = np.uint8(1)
"""Flag bit: the transition starting at this slot ends in a terminal state."""
STARTS = np.uint8(2)
"""Flag bit: this slot starts a transition (it is not an episode's final observation)."""


@dataclass
class Batch:
    """B transitions per agent, as tensors with a leading agent axis."""

    obs_pairs: torch.Tensor
    """(K, 2B, obs_dim) float32: the observations, then their next observations."""
    actions: torch.Tensor
    """(K, B) int64."""
    rewards: torch.Tensor
    """(K, B) float32."""
    terminated: torch.Tensor
    """(K, B) float32, 1 where the next state is terminal (not merely truncated)."""

    @property
    def next_obs(self) -> torch.Tensor:
        """(K, B, obs_dim): the next observations."""
        return self.obs_pairs[:, self.actions.shape[1]:]


class Replay:
    """Circular per-agent storage of observations, actions, rewards and terminal flags."""

    def __init__(self, num_agents: int, capacity: int, obs_dim: int, binary: bool,
                 float_dtype: str = "float16") -> None:
        self.capacity, self.obs_dim, self.binary = capacity, obs_dim, binary
        width = (obs_dim + 7) // 8 if binary else obs_dim
        dtype = np.uint8 if binary else np.dtype(float_dtype)
        # np.zeros maps untouched pages lazily, so memory grows with the filled part only
        self.obs = np.zeros((num_agents, capacity, width), dtype=dtype)
        self.action = np.zeros((num_agents, capacity), dtype=np.uint8)
        self.reward = np.zeros((num_agents, capacity), dtype=np.float32)
        self.flags = np.zeros((num_agents, capacity), dtype=np.uint8)
        self.ptr = np.zeros(num_agents, dtype=np.int64)
        self.size = np.zeros(num_agents, dtype=np.int64)
        self._row_offsets = np.arange(num_agents)[:, None] * capacity  # flat index of each agent's slot 0

    @staticmethod
    def bytes_needed(num_agents: int, capacity: int, obs_dim: int, binary: bool, float_dtype: str = "float16") -> int:
        """Bytes of a full buffer of this shape (what `nbytes` will be), computed before allocating it."""
        width = (obs_dim + 7) // 8 if binary else obs_dim * np.dtype(float_dtype).itemsize
        return num_agents * capacity * (width + 1 + 4 + 1)  # observation, action, reward, flags

    @property
    def num_agents(self) -> int:
        """K."""
        return self.ptr.shape[0]

    @property
    def nbytes(self) -> int:
        """Bytes of the full-capacity arrays (what a filled buffer occupies)."""
        return self.obs.nbytes + self.action.nbytes + self.reward.nbytes + self.flags.nbytes

    def encode(self, obs: np.ndarray) -> np.ndarray:
        """Observations (K, obs_dim) in storage form (a fresh array)."""
        if not self.binary:
            return obs.astype(self.obs.dtype)
        if ((obs != 0) & (obs != 1)).any():
            raise ValueError("a binary replay got an observation value outside {0, 1}")
        return np.packbits(obs.astype(np.bool_), axis=-1)

    def decode(self, stored: np.ndarray) -> torch.Tensor:
        """Stored observations (..., width) back to float32 (..., obs_dim), exactly."""
        if self.binary:
            stored = np.unpackbits(stored, axis=-1, count=self.obs_dim)
        return torch.from_numpy(stored).float()

    def add(self, mask: np.ndarray, encoded_obs: np.ndarray, action: np.ndarray | None = None,
            reward: np.ndarray | None = None, terminated: np.ndarray | None = None) -> None:
        """Append one slot for each agent where ``mask``; without an action the slot starts no transition."""
        agents = np.flatnonzero(mask)
        if agents.size == 0:
            return
        slot = self.ptr[agents]
        self.obs[agents, slot] = encoded_obs[agents]
        if action is None:
            self.action[agents, slot] = 0
            self.reward[agents, slot] = 0.0
            self.flags[agents, slot] = 0
        else:
            self.action[agents, slot] = action[agents]
            self.reward[agents, slot] = reward[agents]
            self.flags[agents, slot] = STARTS | (terminated[agents].astype(np.uint8) * TERMINATED)
        self.ptr[agents] = (slot + 1) % self.capacity
        self.size[agents] = np.minimum(self.size[agents] + 1, self.capacity)

    def sample_indices(self, rngs: Sequence[np.random.Generator], num_batches: int, batch_size: int
                       ) -> np.ndarray:
        """Uniform transition slots (K, num_batches, batch_size), each agent drawing from its own ``rngs[k]``."""
        out = np.empty((self.num_agents, num_batches, batch_size), dtype=np.int64)
        for k, rng in enumerate(rngs):
            out[k] = self._draw(k, rng, (num_batches, batch_size))
        return out

    def _draw(self, k: int, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        """Slots of agent k, uniform over its valid transition starts (rejecting final observations)."""
        candidates = int(self.size[k]) - 1  # all but the newest slot
        oldest = (int(self.ptr[k]) - int(self.size[k])) % self.capacity
        newest = (int(self.ptr[k]) - 1) % self.capacity
        starts = np.count_nonzero(self.flags[k, :int(self.size[k])] & STARTS)
        if candidates < 1 or starts - bool(self.flags[k, newest] & STARTS) < 1:
            raise RuntimeError(f"agent {k} has no complete transition to sample yet")
        slots = (oldest + rng.integers(0, candidates, shape)) % self.capacity
        bad = (self.flags[k, slots] & STARTS) == 0
        while bad.any():
            slots[bad] = (oldest + rng.integers(0, candidates, int(bad.sum()))) % self.capacity
            bad = (self.flags[k, slots] & STARTS) == 0
        return slots

    def stage(self, slots: np.ndarray) -> dict[str, np.ndarray]:
        """The stored transitions starting at ``slots`` (K, m, B), still packed: ``obs`` (K, m, 2B, width), the
        B observations of each step then their next observations, and ``action``, ``reward``, ``flags``
        (K, m, B). One gather for m gradient steps (`train.agent.staging`).
        """
        # np.take on flat indices is several times faster than two-axis fancy indexing
        start = slots + self._row_offsets[:, :, None]
        pairs = np.concatenate((start, start - slots + (slots + 1) % self.capacity), axis=2)
        return {"obs": np.take(self.obs.reshape(-1, self.obs.shape[2]), pairs, axis=0),
                "action": np.take(self.action, start), "reward": np.take(self.reward, start),
                "flags": np.take(self.flags, start)}

    def batch(self, slots: np.ndarray) -> Batch:
        """The transitions starting at ``slots`` (K, B), unpacked."""
        return self.unpack({name: array[:, 0] for name, array in self.stage(slots[:, None]).items()})

    def unpack(self, step: dict[str, np.ndarray]) -> Batch:
        """One gradient step's staged transitions (``obs`` (K, 2B, width), the rest (K, B)) as a `Batch`."""
        return Batch(
            obs_pairs=self.decode(step["obs"]),
            actions=torch.from_numpy(step["action"].astype(np.int64)),
            rewards=torch.from_numpy(np.ascontiguousarray(step["reward"])),
            terminated=torch.from_numpy((step["flags"] & TERMINATED).astype(np.float32)),
        )

    def state_dict(self, rows: slice = slice(None)) -> dict[str, Any]:
        """Views of the filled part of the buffer of agents ``rows`` (slots beyond their sizes are all zero).

        The arrays are views, not copies: pickle or copy them before the buffer changes. The state of a row
        range is what a buffer of just those agents would hold, so a packed run saves what a separate one does.
        """
        size = self.size[rows]
        used = int(size.max()) if size.size else 0
        return {"obs": self.obs[rows, :used], "action": self.action[rows, :used],
                "reward": self.reward[rows, :used], "flags": self.flags[rows, :used],
                "ptr": self.ptr[rows].copy(), "size": size.copy()}

    def load_state_dict(self, state: dict[str, Any], rows: slice = slice(None)) -> None:
        """Restore a `state_dict` into agents ``rows`` of this (same-shaped) buffer."""
        agents = len(range(*rows.indices(self.num_agents)))
        if state["obs"].shape[0] != agents or state["obs"].shape[2] != self.obs.shape[2]:
            raise ValueError("the saved replay buffer does not match this run's agents or observation size")
        used = state["obs"].shape[1]
        shapes = [state[n].shape for n in ("action", "reward", "flags")]
        if used > self.capacity or any(shape != (agents, used) for shape in shapes):
            raise ValueError("the saved replay buffer does not match this run's capacity")
        if state["ptr"].shape != (agents,) or state["size"].shape != (agents,):
            raise ValueError("the saved replay pointers do not match this run's agents")
        for name in ("obs", "action", "reward", "flags"):
            getattr(self, name)[rows, :used] = state[name]
        self.ptr[rows] = state["ptr"]
        self.size[rows] = state["size"]
