"""SIGKILL in the middle of a write leaves the previous good file in place, and the run resumes bit-exactly.

Each test runs an ``ecorl`` command in a fresh interpreter in which one write step is wrapped so that the
process kills itself (SIGKILL, no clean-up possible) at a chosen moment of a chosen write.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from run_metrics import metrics_without_timing

from train.cli import main
from train.storage.checkpoint import CHECKPOINT_NAME, read_checkpoint
from train.storage.fileio import is_temporary
from train.storage.policy import load_policy_file

REPO = Path(__file__).resolve().parents[2]

KILLER = """
import os, signal, sys
import {module} as target
original = target.{attr}
calls = 0
def killing(*args, **kwargs):
    global calls
    if {condition}:
        calls += 1
        if calls == {nth}:
            os.kill(os.getpid(), signal.SIGKILL)
    return original(*args, **kwargs)
target.{attr} = killing
from train.cli import main
sys.exit(main(sys.argv[1:]))
"""
"""A program that runs ``ecorl ARGS`` with ``module.attr`` wrapped to SIGKILL the process at its nth matching call."""


def run_killed(args: list[str], module: str, attr: str, condition: str, nth: int = 1) -> None:
    """Run ``ecorl args`` in a subprocess that SIGKILLs itself inside the nth matching ``module.attr`` call."""
    program = KILLER.format(module=module, attr=attr, condition=condition, nth=nth)
    proc = subprocess.run([sys.executable, "-c", program, *args], cwd=REPO, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == -signal.SIGKILL, f"the command was not killed:\n{proc.stderr}"


def train_args(task: str, out: Path) -> list[str]:
    """A small reset-free, dynamic run with checkpoints at steps 0, 400, 800 and 1200 (the food collector's
    evaluations long enough to collect spheres and touch walls, so that they are compared too).
    """
    horizon = "300" if task == "foodcollector" else "10"
    return ["train", task, "--steps", "1200", "--epoch-steps", "200", "--updates-per-epoch", "20", "--eval-every",
            "400", "--checkpoint-every", "400", "--eval-rollouts", "2", "--eval-horizon", horizon, "--buffer-size",
            "2000", "--seeds", "2", "--dynamism", "0.5", "--reset-free", "--no-progress", "--out", str(out)]


@pytest.mark.parametrize("task", ["salad", "foodcollector"])
def test_kill_during_a_checkpoint_write_keeps_the_previous_one_and_resumes_exactly(task, tmp_path):
    reference, killed = tmp_path / "reference", tmp_path / "killed"
    assert main(train_args(task, reference)) == 0
    # the third checkpoint (step 800) dies while its replay buffer streams into the temporary file
    run_killed(train_args(task, killed), "train.storage.checkpoint", "_write_member", "args[1] == 'replay/obs'", nth=3)
    assert any(is_temporary(p.name) for p in killed.iterdir())  # the half-written temporary
    assert read_checkpoint(killed / CHECKPOINT_NAME, keys=[])["step"] == 400  # the previous one, intact
    assert main([*train_args(task, killed), "--resume"]) == 0
    assert metrics_without_timing(killed) == metrics_without_timing(reference)
    assert np.array_equal(np.load(killed / "visits.npy"), np.load(reference / "visits.npy"))
    assert not any(is_temporary(p.name) for p in killed.iterdir())  # cleared by the resumed run


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("run") / "salad"
    assert main(["train", "salad", "--steps", "400", "--epoch-steps", "200", "--updates-per-epoch", "10",
                 "--eval-every", "200", "--eval-rollouts", "2", "--eval-horizon", "10", "--buffer-size", "1000",
                 "--no-progress", "--out", str(run)]) == 0
    return run


def test_kill_during_a_policy_export_keeps_the_previous_file(finished_run, tmp_path):
    policy = tmp_path / "policy.npz"
    assert main(["export", str(finished_run), "--out", str(policy), "--agent", "0"]) == 0
    before = policy.read_bytes()
    run_killed(["export", str(finished_run), "--out", str(policy), "--agent", "0"], "train.storage.fileio", "_replace",
               "str(args[1]).endswith('policy.npz')")
    assert policy.read_bytes() == before
    assert load_policy_file(policy).meta["step"] == 400


def test_kill_during_a_report_keeps_the_previous_report(tmp_path):
    from train.experiments.catalog import get_experiment
    from train.experiments.sweep import plan, run_jobs, write_experiment_file

    exp = get_experiment("rnd")
    jobs = plan(exp, "smoke", tmp_path, ["factory"])[:1]
    write_experiment_file(exp, "smoke", jobs, tmp_path)
    assert [r.status for r in run_jobs(jobs, "local", workers=1, progress=False)] == ["done"]
    root = tmp_path / "rnd"
    assert main(["report", str(root), "--no-videos"]) == 0
    before = {name: (root / name).read_bytes() for name in ("report.md", "index.html")}
    for name in before:
        (root / "figures" / "rnd_curves.png").unlink(missing_ok=True)
        run_killed(["report", str(root), "--no-videos"], "train.storage.fileio", "_replace",
                   f"str(args[1]).endswith('{name}')")
        assert (root / name).read_bytes() == before[name]
    assert (root / "figures" / "rnd_curves.png").stat().st_size > 0  # written (atomically) before the kill


def test_a_first_signal_says_the_run_stops_at_its_epoch_end(capfd):
    """A run of many seeds went silent for minutes after Ctrl-C while it finished its epoch."""
    import os
    import time

    from train.loop.runlog import FIRST_SIGNAL_NOTE, stop_on_signal

    for announce in (True, False):
        with stop_on_signal(announce=announce) as stop:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)  # the handler runs between two bytecodes of the main thread
            assert stop.is_set()
        assert (FIRST_SIGNAL_NOTE.strip() in capfd.readouterr().err) == announce
