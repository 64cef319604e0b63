"""End-to-end smoke runs: every task trains for a few thousand steps and writes a complete run directory."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from train.config import TrainConfig
from train.loop.trainer import Trainer
from train.tasks import TASKS

TINY = dict(seeds=2, steps=2200, updates_per_epoch=50, eval_every=1000, eval_rollouts=4, eval_horizon=40,
            buffer_size=5_000, progress=False)
CONDITIONS = {
    "salad": dict(dynamism=0.1, shaping="linear:1:0:2000", reward="subgoal"),
    "hunting": dict(dynamism=0.2, reset_free=True),
    "scavenging": dict(dynamism=0.5, reward="distance"),
    "factory": dict(reset_free=True, reward="one_time", rnd=True),
    "walled-salad": dict(shaping=0.5, horizon=50),
    "foodcollector": dict(dynamism=0.5, reset_free=True),
}


def test_every_task_has_a_smoke_condition():
    assert set(CONDITIONS) == set(TASKS)


@pytest.mark.parametrize("task", list(CONDITIONS))
def test_task_trains_end_to_end(task, tmp_path):
    cfg = TrainConfig().replace(task=task, **TINY, **CONDITIONS[task])
    trainer = Trainer(cfg, tmp_path)
    try:
        rows = trainer.run()
    finally:
        trainer.close()
    assert trainer.step == cfg.total_steps == 2200
    assert [r["step"] for r in rows] == [1200, 1200, 2200, 2200]
    for row in rows:
        assert math.isfinite(row["loss"]) and math.isfinite(row["return"])
        assert 0.0 < row["max_q"] < 1e4  # the divergence gauge of every evaluation
        assert 0.0 <= row["success"] <= 1.0 if TASKS[task].metric == "success" else math.isnan(row["success"])
        assert 0 <= row["top_action"] < trainer.info.num_actions  # the collapse columns
        assert 1.0 / trainer.info.num_actions <= row["top_action_share"] <= 1.0
        assert 0.0 <= row["corner_share"] <= 1.0
    with open(tmp_path / "metrics.csv") as f:
        assert len(list(csv.DictReader(f))) == 4
    visits = np.load(tmp_path / "visits.npy")
    assert visits.shape == (2, *trainer.info.visit_shape) and visits.sum(axis=(1, 2)).tolist() == [2200, 2200]
    assert (tmp_path / "visits" / "000002200.npy").exists()
    assert json.loads((tmp_path / "config.json").read_text())["env"]["task"] == task
    assert (tmp_path / "checkpoint.npz").stat().st_size > 0


def test_episode_boundaries_are_not_terminals_on_truncation(tmp_path):
    cfg = TrainConfig().replace(task="salad", horizon=25, steps=700, updates_per_epoch=5, eval_every=500,
                                eval_rollouts=2, eval_horizon=5, buffer_size=2_000, progress=False)
    trainer = Trainer(cfg)
    trainer.train_epoch()
    flags = trainer.replay.flags[0, : trainer.replay.size[0]]
    finals = np.flatnonzero((flags & 2) == 0)  # final-observation slots, one per finished episode
    assert finals.size >= (700 // 26) - 1
    before_final = flags[finals - 1]
    rewards = trainer.replay.reward[0, finals - 1]
    # an episode that ended without a solve was truncated: stored as non-terminal; a solve terminates it
    assert np.all((before_final & 1).astype(bool) == (rewards >= 100))


@pytest.mark.parametrize("timeouts_terminal", [False, True])
def test_timeouts_are_stored_as_terminals_only_when_asked(timeouts_terminal):
    cfg = TrainConfig().replace(task="salad", horizon=10, steps=700, updates_per_epoch=1, eval_every=500,
                                eval_rollouts=2, eval_horizon=5, buffer_size=2_000, progress=False,
                                timeouts_terminal=timeouts_terminal)
    trainer = Trainer(cfg)
    trainer.train_epoch()
    flags = trainer.replay.flags[0, : trainer.replay.size[0]]
    finals = np.flatnonzero((flags & 2) == 0)  # final-observation slots, one per finished episode
    truncated = finals[trainer.replay.reward[0, finals - 1] < 100] - 1  # episodes that ran out of time
    assert truncated.size >= 20
    assert np.all((flags[truncated] & 1).astype(bool) == timeouts_terminal)
    ordinary = np.setdiff1d(np.flatnonzero(flags & 2), finals - 1)  # every other transition
    assert not (flags[ordinary] & 1).any()


@pytest.mark.parametrize("completion_terminal", [False, True])
def test_reset_free_completions_are_terminal_only_when_asked(completion_terminal):
    cfg = TrainConfig().replace(task="salad", reset_free=True, steps=700, updates_per_epoch=1, eval_every=500,
                                eval_rollouts=2, eval_horizon=5, buffer_size=2_000, progress=False,
                                completion_terminal=completion_terminal)
    trainer = Trainer(cfg)
    trainer.train_epoch()
    assert (trainer._completed() is not None) == completion_terminal  # the worlds' last_solved, where asked
    obs = np.zeros((1, trainer.info.obs_dim), dtype=np.float32)
    before = int(trainer.replay.size[0])
    for completed in (True, False):  # a completion, then an ordinary step; the world goes on after both
        trainer.learner.observe(np.array([True]), obs, np.array([4]), np.array([100.0 if completed else 0.0]),
                                np.array([False]), np.array([False]), obs, np.array([completed]))
    flags = trainer.replay.flags[0, before:int(trainer.replay.size[0])]
    assert flags.tolist() == [2 | int(completion_terminal), 2]  # no final-observation slot: no episode ended
    trainer.close()


def test_tensorboard_logging_is_optional_and_lazy(tmp_path):
    cfg = TrainConfig().replace(task="salad", steps=700, updates_per_epoch=5, eval_every=500, eval_rollouts=2,
                                eval_horizon=5, buffer_size=2_000, progress=False, tensorboard=True)
    Trainer(cfg, tmp_path).run()
    assert list((tmp_path / "tensorboard").glob("events.out.tfevents.*"))
