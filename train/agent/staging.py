"""The minibatches of many gradient steps, gathered from the replay at once and read where the update runs.

`Replay.stage` gathers the stored (bit-packed) transitions of a run of gradient steps in one go. A `Stager`
holds one chunk of them and hands out step ``i``'s `Batch`:

- **host mode** (the CPU default): straight from the gathered arrays, unpacked by numpy;
- **static mode** (always on a GPU): from fixed buffers on the update's device, picked by a step index that
  lives on the device too and unpacked there. Every step then runs the very same kernels on the very same
  memory, so one gradient step can be captured as a CUDA graph and replayed for the others, and each chunk
  crosses to the GPU in one copy from pinned host memory instead of one copy per step.

Both modes give the same numbers: unpacking bits is exact and the gather is the same one.
"""

from __future__ import annotations

import numpy as np
import torch

from train.agent.replay import TERMINATED, Batch, Replay

STAGE_BYTES = 64 * 2**20
"""Most bytes of packed transitions staged at once (the chunk of gradient steps is sized to fit)."""


def unpack_bits(stored: torch.Tensor, count: int) -> torch.Tensor:
    """Bit-packed observations (..., width) uint8 back to float32 (..., count), as ``np.unpackbits`` (the
    first value in each byte's highest bit), in torch on the tensor's device.
    """
    shifts = torch.arange(7, -1, -1, dtype=torch.uint8, device=stored.device)
    bits = stored.unsqueeze(-1).bitwise_right_shift(shifts).bitwise_and_(1)
    return bits.flatten(-2)[..., :count].float()


class Stager:
    """One chunk of staged minibatches, in host or static mode (see the module's docstring)."""

    def __init__(self, replay: Replay, batch_size: int, steps: int, device: torch.device, static: bool) -> None:
        """Chunks of at most ``steps`` gradient steps of ``batch_size`` transitions per agent row, for
        updates on ``device``; ``static`` as above (a GPU always uses it).
        """
        self.replay = replay
        self.static = static or device.type != "cpu"
        k, width = replay.num_agents, replay.obs.shape[2]
        per_step = k * batch_size * (2 * width * replay.obs.itemsize + 1 + 4 + 1)
        self.chunk = max(1, min(steps, STAGE_BYTES // per_step))
        self._arrays: dict[str, np.ndarray] = {}
        if not self.static:
            return
        shapes = {"obs": ((k, self.chunk, 2 * batch_size, width), replay.obs.dtype),
                  "action": ((k, self.chunk, batch_size), np.uint8),
                  "reward": ((k, self.chunk, batch_size), np.float32),
                  "flags": ((k, self.chunk, batch_size), np.uint8)}
        host = {name: torch.from_numpy(np.zeros(shape, dtype)) for name, (shape, dtype) in shapes.items()}
        on_gpu = device.type != "cpu"  # then the host side of the copies is page-locked, so they run asynchronously
        self._host = {name: t.pin_memory() for name, t in host.items()} if on_gpu else host
        self.buffers = {name: t.to(device) for name, t in host.items()} if on_gpu else host
        self.index = torch.zeros(1, dtype=torch.int64, device=device)
        """The step of the chunk that `batch` reads in static mode (set by `select`)."""
        self._copied = torch.cuda.Event() if on_gpu else None

    def load(self, slots: np.ndarray) -> int:
        """Stage the transitions at ``slots`` (K, m, B) with m <= `chunk`; return m."""
        m = slots.shape[1]
        if m > self.chunk:
            raise ValueError(f"{m} gradient steps do not fit a chunk of {self.chunk}")
        arrays = self.replay.stage(slots)
        if not self.static:
            self._arrays = arrays
            return m
        if self._copied is not None:
            self._copied.synchronize()  # the last chunk's copy has left the pinned buffers
        for name, host in self._host.items():
            host[:, :m].numpy()[...] = arrays[name]
            if host is not self.buffers[name]:
                self.buffers[name][:, :m].copy_(host[:, :m], non_blocking=True)
        if self._copied is not None:
            self._copied.record()
        return m

    def select(self, i: int) -> None:
        """Make step ``i`` of the chunk the one `batch` reads (static mode; a device-side write)."""
        self.index.fill_(i)

    def batch(self, i: int) -> Batch:
        """Step ``i``'s minibatch on the update's device. In static mode it is the step `select` chose, read
        through the device-side index (so a captured graph reads whichever step is selected) and ``i`` is
        not used.
        """
        if not self.static:
            return self.replay.unpack({name: array[:, i] for name, array in self._arrays.items()})
        pick = {name: b.index_select(1, self.index).squeeze(1) for name, b in self.buffers.items()}
        obs = (unpack_bits(pick["obs"], self.replay.obs_dim) if self.replay.binary else pick["obs"].float())
        return Batch(obs_pairs=obs, actions=pick["action"].long(), rewards=pick["reward"],
                     terminated=pick["flags"].bitwise_and(int(TERMINATED)).float())

