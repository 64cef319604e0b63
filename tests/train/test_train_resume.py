"""Run directories: a killed run resumes to the same results; bad checkpoints and requests are refused."""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from train.cli import main
from train.config import TrainConfig
from train.loop.trainer import Trainer
from train.storage.rundir import ADDED_COLUMNS, RunDirError, check_same_run

REPO = Path(__file__).resolve().parents[2]
ARGS = ["train", "salad", "--dynamism", "0.1", "--eps-start", "0.5", "--steps", "3000", "--epoch-steps", "200",
        "--updates-per-epoch", "100", "--eval-every", "200", "--checkpoint-every", "600", "--eval-rollouts", "5",
        "--eval-horizon", "30", "--buffer-size", "5000", "--seeds", "2", "--no-progress"]
SMALL = TrainConfig().replace(task="salad", steps=800, epoch_steps=200, updates_per_epoch=20, eval_every=200,
                              eval_rollouts=3, eval_horizon=10, buffer_size=1000, progress=False)


def _metrics(run: Path) -> list[dict[str, str]]:
    with open(run / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        row.pop("steps_per_s")  # wall-clock speed is the one column allowed to differ
    return rows


def _wait_for_step(run: Path, proc: subprocess.Popen, step: int, timeout: float = 120.0) -> None:
    """Block until metrics.csv reports ``step`` (while the process is still running)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, "the run finished before it could be killed; make it longer"
        try:
            if any(int(r["step"]) >= step for r in _metrics(run)):
                return
        except (FileNotFoundError, KeyError, ValueError):
            pass
        time.sleep(0.05)
    raise TimeoutError(f"the run never reached step {step}")


def test_killed_run_resumes_to_the_same_metrics(tmp_path):
    reference, killed = tmp_path / "reference", tmp_path / "killed"
    assert main([*ARGS, "--out", str(reference)]) == 0
    proc = subprocess.Popen([sys.executable, "-m", "train.cli", *ARGS, "--out", str(killed)], cwd=REPO,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_for_step(killed, proc, 1400)  # past the checkpoints at 0 and ~600 and ~1200, with rows beyond
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    assert len(_metrics(killed)) < len(_metrics(reference))
    assert main([*ARGS, "--out", str(killed), "--resume"]) == 0
    assert _metrics(killed) == _metrics(reference)
    assert np.array_equal(np.load(killed / "visits.npy"), np.load(reference / "visits.npy"))


@pytest.mark.parametrize("task", ["scavenging", "foodcollector"])
def test_interrupted_run_resumes_exactly_in_process(task, tmp_path):
    cfg = SMALL.replace(task=task, seeds=2, dynamism=0.5, reset_free=True, steps=1400, checkpoint_every=200)
    Trainer(cfg, tmp_path / "reference").run()
    Trainer(cfg.replace(steps=600), tmp_path / "resumed").run()  # stops (with a checkpoint) at step 600
    Trainer(cfg, tmp_path / "resumed", resume=True).run()
    assert _metrics(tmp_path / "resumed") == _metrics(tmp_path / "reference")


def test_resume_can_extend_the_step_budget(tmp_path):
    Trainer(SMALL, tmp_path / "run").run()
    longer = Trainer(SMALL.replace(steps=1200), tmp_path / "run", resume=True)
    rows = longer.run()
    assert rows[-1]["step"] == 1200 and longer.step == 1200


def test_config_json_is_resolved(tmp_path):
    Trainer(SMALL, tmp_path / "run").run()
    saved = json.loads((tmp_path / "run" / "config.json").read_text())
    assert saved["eval"]["eval_rollouts"] == 3 and saved["eval"]["eval_horizon"] == 10
    assert TrainConfig.from_dict(saved).env.task == "salad"
    fresh = json.loads(json.dumps(Trainer(SMALL.replace(eval_rollouts=None, eval_horizon=None)).cfg.to_dict()))
    assert fresh["eval"]["eval_rollouts"] == 100 and fresh["eval"]["eval_horizon"] == 100  # salad's test MDP


@pytest.fixture
def finished_run(tmp_path) -> Path:
    run = tmp_path / "run"
    Trainer(SMALL, run).run()
    return run


def test_non_empty_directory_needs_resume(finished_run):
    with pytest.raises(RunDirError, match="not empty.*--resume"):
        Trainer(SMALL, finished_run)


def test_resume_without_checkpoint_is_refused(tmp_path):
    with pytest.raises(RunDirError, match="no checkpoint"):
        Trainer(SMALL, tmp_path / "empty", resume=True)


@pytest.mark.parametrize("damage", ["flip", "truncate", "header"])
def test_corrupt_checkpoint_is_refused(finished_run, damage):
    path = finished_run / "checkpoint.npz"
    data = bytearray(path.read_bytes())
    if damage == "flip":
        data[len(data) // 2] ^= 0xFF
    elif damage == "truncate":
        data = data[: len(data) // 3]
    else:
        data[:4] = b"JUNK"
    path.write_bytes(bytes(data))
    with pytest.raises(RunDirError, match="corrupt|not an ecorl checkpoint") as err:
        Trainer(SMALL, finished_run, resume=True)
    assert "another --out" in str(err.value)


def test_unresolved_request_matches_its_resolved_run(finished_run):
    saved = TrainConfig.from_dict(json.loads((finished_run / "config.json").read_text()))
    check_same_run(saved, SMALL.replace(eval_rollouts=None, eval_horizon=None), finished_run)
    with pytest.raises(RunDirError, match="eval_rollouts: checkpoint has 3, you asked for 7"):
        check_same_run(saved, SMALL.replace(eval_rollouts=7), finished_run)


def test_mismatched_checkpoint_is_refused_naming_the_setting(finished_run, capsys):
    with pytest.raises(RunDirError, match=r"dynamism: checkpoint has 0\.0, you asked for 0\.5"):
        Trainer(SMALL.replace(dynamism=0.5), finished_run, resume=True)
    code = main(["train", "salad", "--out", str(finished_run), "--resume", "--lr", "0.001", "--no-progress"])
    assert code == 2 and "with --lr 0.001: the run was made with 0.0001" in capsys.readouterr().err


def test_sigterm_stops_at_the_epoch_end_with_a_checkpoint(tmp_path, monkeypatch):
    trainer = Trainer(SMALL.replace(steps=2000), tmp_path / "run")
    epoch = trainer.train_epoch

    def epoch_then_signal():
        epoch()
        if trainer.epoch == 2:
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(trainer, "train_epoch", epoch_then_signal)
    trainer.run()
    trainer.close()  # releases the run directory's lock
    assert trainer.epoch == 2 and trainer.last_checkpoint == trainer.step == 600
    resumed = Trainer(SMALL.replace(steps=2000), tmp_path / "run", resume=True)
    assert resumed.step == 600 and resumed.epoch == 2
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL  # the handler is removed after the run


def _epochs_then_evaluate(trainer: Trainer, epochs: int) -> None:
    for _ in range(epochs):
        trainer.train_epoch()
    trainer.evaluate()


def test_corner_share_counts_the_visits_since_the_last_evaluation_across_a_resume(tmp_path):
    cfg = SMALL.replace(seeds=2, reset_free=True, checkpoint_every=10_000)
    straight = Trainer(cfg)
    _epochs_then_evaluate(straight, 1)
    _epochs_then_evaluate(straight, 2)  # an interval of two epochs
    first = Trainer(cfg, tmp_path / "run")
    _epochs_then_evaluate(first, 1)
    first.train_epoch()
    first.save()  # a checkpoint between two evaluations
    first.close()
    resumed = Trainer(cfg, tmp_path / "run", resume=True)
    _epochs_then_evaluate(resumed, 1)
    for mine, theirs in zip(resumed.rows[-2:], straight.rows[-2:]):
        assert mine["corner_share"] == theirs["corner_share"]
    interval = straight.visits - straight.parts[0].visits_at_eval
    assert interval.sum() == 0  # the snapshot moved to the last evaluation
    for trainer in (straight, resumed):
        trainer.close()


def test_a_checkpoint_from_before_the_collapse_columns_still_resumes(tmp_path):
    trainer = Trainer(SMALL.replace(steps=400), tmp_path / "run")
    trainer.run()
    state = trainer.state_dict()
    trainer.close()
    del state["visits_at_eval"]  # what a checkpoint written before issue 48 holds
    state["rows"] = [{k: v for k, v in row.items() if k not in ADDED_COLUMNS} for row in state["rows"]]
    again = Trainer(SMALL.replace(steps=400))
    again.load_state_dict(state)
    assert np.array_equal(again.parts[0].visits_at_eval, state["visits"])
    assert all(math.isnan(row["top_action_share"]) for row in again.rows)
    again.close()


def test_a_diverged_seed_resumes_and_neither_blocks_the_others_nor_is_exported(tmp_path):
    from train.storage.policy import export_run_policies, load_policy
    from train.storage.rundir import RunDir

    cfg = SMALL.replace(seeds=3, reset_free=True, steps=600)
    run = tmp_path / "run"
    trainer = Trainer(cfg, run)
    trainer.run()
    state = trainer.state_dict()
    trainer.close()
    for name in ("online", "target"):  # seed 1 blew up: its whole network is NaN
        state["agent"][name][1] = float("nan")
    RunDir(run).save_checkpoint(state)
    resumed = Trainer(cfg.replace(steps=1000), run, resume=True)  # refused before: "agent/online holds NaN"
    resumed.run()
    resumed.close()
    last = [r for r in _metrics(run) if int(r["step"]) == max(int(x["step"]) for x in _metrics(run))]
    assert math.isnan(float(last[1]["max_q"])) and all(math.isfinite(float(last[k]["max_q"])) for k in (0, 2))
    picked = {load_policy(p).seed for p in export_run_policies(run).values()}
    assert picked and 1 not in picked  # best and median among the seeds that can act
    with pytest.raises(ValueError, match="lr must be"):
        TrainConfig().replace(lr=1e30)


def test_a_stop_after_the_checkpoint_decision_trains_one_more_epoch_and_saves(tmp_path, monkeypatch):
    """A stop landing after an epoch's checkpoint decision (here: in the progress update, which writes
    progress.json) is read at the next epoch's decision: the run never stops without a checkpoint of its step.
    """
    from contextlib import contextmanager

    import train.loop.trainer as trainer_module
    from train.loop.runlog import request_stop

    trainer = Trainer(SMALL.replace(steps=2000), tmp_path / "run")
    real_bar = trainer_module.progress_bar

    @contextmanager
    def bar_that_stops(*args, **kwargs):
        with real_bar(*args, **kwargs) as bar:
            update = bar.update

            def update_then_stop(n):
                update(n)
                if trainer.epoch == 2:
                    request_stop()  # as the first SIGINT's handler does, without signalling pytest

            bar.update = update_then_stop
            yield bar

    monkeypatch.setattr(trainer_module, "progress_bar", bar_that_stops)
    trainer.run()
    trainer.close()
    assert trainer.epoch == 3 and trainer.last_checkpoint == trainer.step == 800  # unfixed: epoch 2, checkpoint 0
