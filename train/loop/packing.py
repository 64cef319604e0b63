"""Which conditions can train packed in one learner, and on which device.

Conditions of one task pack into one trainer when they differ only in what a learner row may hold on its
own (`PER_ROW`): the environment's knobs, the learning rate, the exploration schedule, the RND flag and the
seeds. Everything else (network, batch, replay size, schedule, evaluation, step budget, RND's own settings)
is shared, because the packed gradient step and the lockstep loop run it once for all rows.
"""

from __future__ import annotations

import json
from collections.abc import Sequence

import torch

from train.config import TrainConfig

PER_ROW = {"env": ("dynamism", "shaping", "reset_free", "reward", "horizon", "env_kwargs"),
           "dqn": ("lr", "eps_start", "eps_end", "eps_decay_steps"),
           "rnd": ("rnd",),
           "run": ("seeds", "first_seed")}
"""Settings that may differ between the conditions of one pack, by config section."""


def shared_settings(cfg: TrainConfig) -> dict[str, object]:
    """The settings every condition of a pack must share, as ``section.name`` -> value."""
    data = cfg.to_dict()
    return {f"{section}.{name}": value for section, fields in data.items() for name, value in fields.items()
            if name not in PER_ROW.get(section, ())}


def pack_key(cfg: TrainConfig) -> str:
    """Conditions with equal keys can share one trainer."""
    return json.dumps(shared_settings(cfg), sort_keys=True)


def check_packable(cfgs: Sequence[TrainConfig]) -> None:
    """Raise ValueError naming the first shared setting on which two conditions of a pack differ."""
    first = shared_settings(cfgs[0])
    for cfg in cfgs[1:]:
        for key, value in shared_settings(cfg).items():
            if first[key] != value:
                raise ValueError(f"cannot pack these conditions: they differ in {key} ({first[key]!r} vs "
                                 f"{value!r}); run them separately (without --pack)")


def group_packable(cfgs: Sequence[TrainConfig]) -> list[list[int]]:
    """Indices of ``cfgs`` grouped into packs (first-appearance order)."""
    groups: dict[str, list[int]] = {}
    for i, cfg in enumerate(cfgs):
        groups.setdefault(pack_key(cfg), []).append(i)
    return list(groups.values())


def check_device(device: str) -> None:
    """Raise ValueError (one line, with the fix) unless torch can use ``device`` here."""
    if device == "cpu":
        return
    if device.startswith("cuda"):
        if not torch.cuda.is_available():
            raise ValueError(f"--device {device}: this machine has no CUDA device (torch {torch.__version__}, "
                             f"torch.cuda.is_available() is False); use --device cpu")
        index = int(device.partition(":")[2] or 0)
        if index >= torch.cuda.device_count():
            raise ValueError(f"--device {device}: only {torch.cuda.device_count()} CUDA device(s) here; "
                             f"use cuda:0 .. cuda:{torch.cuda.device_count() - 1}")
        return
    raise ValueError(f"unknown device {device!r}; use cpu, cuda or cuda:N")
