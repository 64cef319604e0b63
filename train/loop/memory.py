"""What a run will hold in memory, estimated before anything is allocated, and the refusal of too much.

Every buffer that grows with the number of seeds counts: the replay buffers, each seed's networks with their
optimiser moments and gradients, RND's networks, a minibatch with its activations, the sampled replay slots of
an epoch, the visitation counts, and the training and evaluation worlds. The estimate errs high.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

from train.config import TrainConfig

FLOAT = 4
"""Bytes of a float32."""
NETWORK_COPIES = 6
"""Float copies of a network's parameters per seed: online, target, two Adam moments, gradient, update."""
WORLD_BYTES_PER_CELL = 5 * 2
"""A grid world's cell (code and age), doubled for the step buffers."""


def _mlp_params(widths: tuple[int, ...]) -> int:
    return sum((a + 1) * b for a, b in zip(widths, widths[1:]))


def estimate_bytes(cfg: TrainConfig, obs_dim: int, cells: int, num_params: int, binary: bool) -> dict[str, int]:
    """Bytes of each per-seed buffer of a run of ``cfg`` (all seeds), by name."""
    from train.agent.replay import Replay  # torch: imported by the commands that size a run, not by every one
    from train.agent.staging import STAGE_BYTES

    k, d = cfg.run.seeds, cfg.dqn
    widest = max(obs_dim, *d.view_layers, *d.inventory_layers, *d.head_layers)
    parts = {
        "replay": Replay.bytes_needed(k, d.buffer_size, obs_dim, binary, d.float_obs_dtype),
        "networks": k * num_params * FLOAT * NETWORK_COPIES,
        "minibatch": k * d.batch_size * (2 * obs_dim + 8 * widest) * FLOAT,
        "replay slots": k * d.updates_per_epoch * d.batch_size * 8,
        "staged minibatches": min(STAGE_BYTES, Replay.bytes_needed(k, 2 * d.updates_per_epoch * d.batch_size,
                                                                   obs_dim, binary, d.float_obs_dtype)),
        "visits and worlds": k * cells * (8 + WORLD_BYTES_PER_CELL),
        "evaluation": k * (cfg.eval.eval_rollouts or 1) * (cells * WORLD_BYTES_PER_CELL + obs_dim * FLOAT),
    }
    if cfg.rnd.rnd:
        parts["rnd"] = k * _mlp_params((obs_dim, *cfg.rnd.rnd_layers)) * FLOAT * NETWORK_COPIES
    return parts


def memory_bytes() -> int | None:
    """Physical memory of this machine in bytes (None where unknown)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(cfgs: TrainConfig | Sequence[TrainConfig], obs_dim: int, cells: int, num_params: int,
                 binary: bool) -> int:
    """Refuse a run (or a pack of runs) whose buffers would not fit in this machine's memory, before
    allocating any; return its bytes.
    """
    cfgs = [cfgs] if isinstance(cfgs, TrainConfig) else list(cfgs)
    parts: dict[str, int] = {}
    for cfg in cfgs:
        for name, size in estimate_bytes(cfg, obs_dim, cells, num_params, binary).items():
            parts[name] = parts.get(name, 0) + size
    seeds = sum(cfg.run.seeds for cfg in cfgs)
    need, have = sum(parts.values()), memory_bytes()
    if have is not None and need > have:
        top = ", ".join(f"{name} {size / 2**30:.1f} GiB" for name, size in sorted(parts.items(), key=lambda p: -p[1])
                        if size >= need / 20)
        raise ValueError(f"this run needs about {need / 2**30:.1f} GiB ({top}) for {seeds} seeds, more than "
                         f"this machine's {have / 2**30:.1f} GiB of memory; use fewer --seeds or a smaller "
                         f"--buffer-size (or --batch-size, or smaller layers)")
    return need


def checkpoint_limit(cfg: TrainConfig) -> int:
    """The most bytes of arrays a checkpoint of a run of ``cfg`` can hold (with room to spare)."""
    from train.agent.network import QNetwork
    from train.tasks import get_task, probe

    task = get_task(cfg.env.task)
    info = probe(task, cfg.env)
    params = QNetwork.from_config(info.view_dim, info.obs_dim, info.num_actions, cfg.dqn).num_params
    parts = estimate_bytes(cfg, info.obs_dim, math.prod(info.visit_shape), params, task.binary_obs)
    return 2 * sum(parts.values()) + (64 << 20)
