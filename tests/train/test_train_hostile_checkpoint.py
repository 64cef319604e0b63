"""Crafted checkpoints: no value read from a run directory reaches the compiled engine or torch unchecked.

Every case is resumed in a subprocess (`fuzz_checkpoint.py`), so a crash of compiled code fails the test
instead of ending the test run. A crafted checkpoint is re-signed the way ecorl signs one (its digests only
catch accidents); what it may lead to is a one-line error (exit 2) or a resume that runs to its end.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gridtasks.records import MAX_COUNT
from train.cli import main
from train.storage.checkpoint import read_checkpoint, write_checkpoint
from train.storage.statecheck import steps_left

REPO = Path(__file__).resolve().parents[2]
FUZZ = Path(__file__).with_name("fuzz_checkpoint.py")
TINY = ["--epoch-steps", "200", "--updates-per-epoch", "10", "--eval-every", "200", "--eval-rollouts", "2",
        "--eval-horizon", "10", "--buffer-size", "1000", "--no-progress", "--seeds", "2"]


def fuzz(*args: str, timeout: float = 600) -> list[dict]:
    """Run the fuzz script in a subprocess; its JSON lines (the subprocess must exit 0: no crash)."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, str(FUZZ), *map(str, args)], capture_output=True, text=True,
                          cwd=REPO, env=env, timeout=timeout)
    assert proc.returncode == 0, f"the resume crashed (exit {proc.returncode}): {proc.stderr[-2000:]}"
    return [json.loads(line) for line in proc.stdout.splitlines()]


def assert_clean(results: list[dict]) -> None:
    """Each case: exit 0, or exit 2 with one line and no traceback."""
    for r in results:
        assert r["rc"] in (0, 2), r
        if r["rc"] == 2:
            assert "\n" not in r["err"] and "Traceback" not in r["err"], r
            assert r["err"].startswith("ecorl train: error:"), r


@pytest.fixture(scope="module")
def source(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("source") / "run"
    assert main(["train", "salad", "--steps", "400", *TINY, "--out", str(run)]) == 0
    return run


def _crafted(source: Path, where: Path, change) -> Path:
    """A copy of ``source`` whose checkpoint ``change(state)`` edited, re-signed as ecorl signs it."""
    import shutil

    shutil.copytree(source, where)
    state = read_checkpoint(where / "checkpoint.npz")
    change(state["env"]["worlds"])
    write_checkpoint(where / "checkpoint.npz", state)
    return where


def _set(field: str, value, index=(0,)):
    def change(worlds):
        worlds[field][index] = value
    return change


HOSTILE_WORLDS = {
    "agent far outside the grid": (_set("agent", [10**9, 10**9]), "agent at (1000000000, 1000000000)"),
    "agent off an 8x8 grid": (_set("agent", [3, 40]), "agent at (3, 40)"),
    "every cell code 255": (_set("grid", 255, (slice(None),)), "cell code 255"),
    "inventory code 250": (_set("inventory", 250), "inventory code 250"),
    "a wall removed from the ring": (_set("grid", 0, (0, 0, 0)), "walls differ"),
    "negative lifetime clock": (_set("lifetime_step", -5), "lifetime_step lies outside"),
    # accepted before, then the check of the run's own next checkpoint refused the clock it had stepped past it
    "a clock at the largest count, no room to step": (_set("lifetime_step", MAX_COUNT), "lifetime_step lies outside"),
}


def test_crafted_world_records_are_refused_in_one_line(source, tmp_path):
    dirs = {name: _crafted(source, tmp_path / f"case{i}", change)
            for i, (name, (change, _)) in enumerate(HOSTILE_WORLDS.items())}
    results = fuzz("resume", 600, *dirs.values())
    assert len(results) == len(dirs)
    for (name, (_, message)), r in zip(HOSTILE_WORLDS.items(), results):
        assert r["rc"] == 2, (name, r)
        assert message in r["err"] and "\n" not in r["err"], (name, r)


def test_an_untouched_resigned_checkpoint_resumes(source, tmp_path):
    run = _crafted(source, tmp_path / "same", lambda worlds: None)
    [result] = fuzz("resume", 600, run)
    assert result["rc"] == 0, result
    assert np.isfinite(read_checkpoint(run / "checkpoint.npz", keys=[])["step"])


def test_a_clock_with_just_the_room_a_run_needs_resumes_and_resumes_again(source, tmp_path):
    step = int(read_checkpoint(source / "checkpoint.npz", keys=[])["step"])
    run = _crafted(source, tmp_path / "edge", _set("lifetime_step", MAX_COUNT - steps_left(step)))
    for steps in (600, 800):
        [result] = fuzz("resume", steps, run)
        assert result["rc"] == 0, result
    assert int(read_checkpoint(run / "checkpoint.npz", keys=[])["step"]) >= 800


def test_mutating_any_field_gives_a_one_line_error_or_a_resume(source, tmp_path):
    """A seeded sample of single-field mutations (world fields, replay, RNG states first), in seconds."""
    results = fuzz(source, tmp_path / "work", 0, 40, 600)
    assert len(results) == 40
    assert_clean(results)
    assert any(r["rc"] == 2 for r in results) and any(r["rc"] == 0 for r in results)


def test_mutating_a_food_collectors_saved_state_gives_a_one_line_error_or_a_resume(tmp_path):
    """The food collector's environment state (pymunk bodies, spheres, counters, generators), sampled."""
    run = tmp_path / "food"
    assert main(["train", "foodcollector", "--steps", "400", *TINY, "--out", str(run)]) == 0
    results = fuzz(run, tmp_path / "work", 0, 30, 600, "--only", "env")
    assert len(results) == 30
    assert_clean(results)
    assert any(r["rc"] == 2 for r in results)


@pytest.mark.slow
def test_mutating_every_field_gives_a_one_line_error_or_a_resume(source, tmp_path):
    """Every mutation of every field of the checkpoint (679 cases; about a minute on an idle machine)."""
    results = fuzz(source, tmp_path / "work", 1, 0, 600, "--all", timeout=3000)
    assert len(results) > 200
    assert_clean(results)
