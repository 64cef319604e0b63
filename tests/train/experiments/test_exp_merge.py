"""`ecorl merge-seeds` joins runs of parts of a condition's seeds into the run of all of them."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from train.cli import main
from train.config import TrainConfig
from train.experiments.catalog import get_experiment
from train.experiments.jobs import job_is_done, read_done
from train.experiments.merge import merge_seed_runs
from train.experiments.sweep import plan, write_experiment_file
from train.loop.trainer import Trainer
from train.storage.policy import load_policy_file
from train.storage.rundir import RunDirError

RUN = ["run", "episodic-vs-reset-free", "--budget", "smoke", "--task", "salad", "--condition", "static-episodic",
       "--jobs", "1", "--no-progress"]
CONDITION = "episodic-vs-reset-free/salad/static-episodic"


def _rows(run_dir):
    with open(run_dir / "metrics.csv", newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """One run of seeds 0-2, the same seeds as two parts (0 and 1-2), and seed 2 alone, at the smoke budget."""
    root = tmp_path_factory.mktemp("merge")
    for out, extra in (("whole", ["--seeds", "3"]), ("part-a", ["--seeds", "1"]),
                       ("part-b", ["--seeds", "2", "--first-seed", "1"]),
                       ("part-c", ["--seeds", "1", "--first-seed", "2"])):
        assert main([*RUN, *extra, "--out", str(root / out)]) == 0
    return root


def test_merged_parts_are_the_run_of_all_their_seeds(trained, tmp_path):
    exp = get_experiment("episodic-vs-reset-free")
    [job] = plan(exp, "smoke", tmp_path, ["salad"], 3, conditions=["static-episodic"])
    write_experiment_file(exp, "smoke", [job], tmp_path)  # as 'ecorl run' leaves it
    merged = merge_seed_runs([trained / "part-b" / CONDITION, trained / "part-a" / CONDITION], job.run_dir)
    whole = trained / "whole" / CONDITION
    assert job_is_done(job)  # the merged config is the one 'ecorl run --seeds 3' asks for, and it is finished
    got, want = _rows(merged), _rows(whole)
    assert [(r["step"], r["seed"]) for r in got] == [(r["step"], r["seed"]) for r in want]
    for column in ("epsilon", "loss", "max_q", "success", "return", "train_reward"):  # the seeds learn
        assert [r[column] for r in got] == [r[column] for r in want]  # independently, bit for bit
    for name in ["visits.npy"] + [f"visits/{p.name}" for p in (whole / "visits").glob("*.npy")]:
        assert np.array_equal(np.load(merged / name), np.load(whole / name)), name
    for pick in ("best", "median"):
        ours, theirs = load_policy_file(merged / "policies" / f"{pick}.npz"), load_policy_file(
            whole / "policies" / f"{pick}.npz")
        assert ours.seed == theirs.seed and ours.meta["agent"] == theirs.meta["agent"]
        assert ours.cfg.run.seeds == 3 and ours.meta["source"] == theirs.meta["source"] == CONDITION
    done = read_done(merged)
    assert done["seeds"] == 3 and [m["seeds"] for m in done["merged_from"]] == ["0-0", "1-2"]
    assert not (merged / "checkpoint.npz").exists()


def test_parts_that_are_not_one_runs_seeds_are_refused(trained, tmp_path):
    a, b = trained / "part-a" / CONDITION, trained / "part-b" / CONDITION
    with pytest.raises(ValueError, match="at least two"):
        merge_seed_runs([a], tmp_path / "x")
    with pytest.raises(ValueError, match="overlap"):
        merge_seed_runs([a, trained / "whole" / CONDITION], tmp_path / "x")
    with pytest.raises(ValueError, match="leave a gap"):
        merge_seed_runs([a, trained / "part-c" / CONDITION], tmp_path / "x")
    unfinished = Trainer(TrainConfig().replace(task="salad", seeds=2, first_seed=1, steps=2_000, warmup_steps=100,
                                               epoch_steps=100, progress=False), tmp_path / "unfinished")
    unfinished.train_epoch()
    unfinished.save()
    unfinished.close()
    with pytest.raises(RunDirError, match="stands at step [0-9,]+ of 2,000: finish it first"):
        merge_seed_runs([a, tmp_path / "unfinished"], tmp_path / "x")
    with pytest.raises(ValueError, match="drop --first-seed"):  # a measurement has no training seeds to split
        plan(get_experiment("measure"), "smoke", tmp_path, first_seed=1)
    merge_seed_runs([a, b], tmp_path / "merged")
    with pytest.raises(RunDirError, match="is not an empty directory; merge into a new --out"):
        merge_seed_runs([a, b], tmp_path / "merged")


def test_the_command_merges_and_names_a_part_trained_otherwise(trained, tmp_path, capsys):
    other = tmp_path / "other"
    assert main([*RUN[:7], "static-reset-free", *RUN[8:], "--seeds", "1", "--first-seed", "1",
                 "--out", str(other)]) == 0
    part_a, part_b = trained / "part-a" / CONDITION, trained / "part-b" / CONDITION
    merged = tmp_path / "results" / CONDITION
    assert main(["merge-seeds", str(part_a), str(part_b), "--out", str(merged)]) == 0
    assert "seeds 0-2 of 2 runs" in capsys.readouterr().out
    assert (tmp_path / "results/episodic-vs-reset-free/experiment.json").is_file()  # the report finds the run
    assert load_policy_file(merged / "policies" / "best.npz").meta["source"] == CONDITION
    assert main(["report", str(tmp_path / "results"), "--out", str(tmp_path / "report")]) == 0
    assert "| salad | static, episodic | 0.0% [0.0, 0.0] | 0 / 3 |" in (tmp_path / "report/report.md").read_text()
    assert main(["merge-seeds", str(part_a), str(other / "episodic-vs-reset-free/salad/static-reset-free"),
                 "--out", str(tmp_path / "mixed")]) != 0
    err = capsys.readouterr().err
    assert "other settings" in err and "reset_free" in err


def test_a_failed_merge_leaves_nothing_behind_and_a_planted_part_file_is_refused(trained, tmp_path, monkeypatch):
    import shutil

    import train.experiments.merge as merge

    first, second = trained / "part-a" / CONDITION, trained / "part-b" / CONDITION
    out = tmp_path / "results" / CONDITION

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(merge, "export_run_policies", fail)
    with pytest.raises(OSError, match="disk full"):
        merge_seed_runs([first, second], out)
    assert not out.exists() and not list(out.parent.glob(".*merging*"))  # no half-written run, no leftovers
    monkeypatch.undo()
    copied = tmp_path / "bad" / CONDITION
    shutil.copytree(second, copied)
    lines = (copied / "metrics.csv").read_text().splitlines()
    cells = lines[1].split(",")
    cells[2] = "<b>x</b>"  # a text cell where a number belongs
    (copied / "metrics.csv").write_text("\n".join([lines[0], ",".join(cells), *lines[2:]]) + "\n")
    with pytest.raises(RunDirError, match="line 2 is not a metrics row"):
        merge_seed_runs([first, copied], tmp_path / "other")
    assert not (tmp_path / "other").exists()
