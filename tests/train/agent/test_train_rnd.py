"""RND: the bonus is larger for novel observations, normalised per seed, and never stored in replay."""

from __future__ import annotations

import numpy as np
import torch

from train.agent.rnd import RND, RunningMoments
from train.config import RNDConfig, TrainConfig
from train.loop.trainer import Trainer


def test_running_moments_match_numpy():
    rng = np.random.default_rng(0)
    values = rng.normal(3.0, 2.0, (2, 300))
    moments = RunningMoments(2)
    for chunk in np.split(values, 6, axis=1):
        moments.update(torch.from_numpy(chunk))
    assert torch.allclose(moments.mean, torch.from_numpy(values.mean(1)))
    assert torch.allclose(moments.std.double(), torch.from_numpy(values.std(1)), rtol=1e-5)


def test_bonus_shrinks_for_familiar_observations():
    rnd = RND(30, RNDConfig(rnd=True, rnd_lr=1e-3), [np.random.default_rng(s) for s in range(2)])
    gen = torch.Generator().manual_seed(0)
    familiar = torch.randint(0, 2, (2, 64, 30), generator=gen).float()
    for _ in range(300):
        rnd.bonus(familiar)
    novel = torch.randint(0, 2, (2, 64, 30), generator=gen).float()
    assert torch.all(rnd.bonus(novel).mean(1) > 2 * rnd.bonus(familiar).mean(1))


def test_bonus_is_added_at_sampling_time_not_stored(monkeypatch):
    cfg = TrainConfig().replace(task="factory", rnd=True, rnd_weight=1000.0, steps=700, updates_per_epoch=20,
                                eval_every=500, eval_rollouts=2, eval_horizon=5, buffer_size=2_000,
                                progress=False)
    trainer = Trainer(cfg)
    seen = []
    update = trainer.agent.update
    monkeypatch.setattr(trainer.agent, "update", lambda o, a, r, d: seen.append(r.clone()) or update(o, a, r, d))
    trainer.train_epoch()
    stored = trainer.replay.reward[:, : trainer.replay.size.max()]
    assert np.all(np.isin(stored, [0.0, 100.0]))  # sparse environment rewards only
    assert all(torch.any(r > 1.0) for r in seen)  # the weighted bonus reached the learner
