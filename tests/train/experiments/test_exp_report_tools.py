"""``python -m train.experiments.report.matched`` (runs of different lengths compared where their evaluations meet)
and ``...report.corners`` (time spent in the grid's corners, and how evenly the visits spread).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from train.experiments.report.matched import main, matched_table


def _run(path, task, returns_by_step):
    """A run directory: config.json naming the task, metrics.csv with one row per (step, seed)."""
    path.mkdir(parents=True)
    (path / "config.json").write_text(json.dumps({"env": {"task": task}}))
    lines = ["step,seed,epsilon,loss,max_q,success,return,train_reward,steps_per_s"]
    for step, values in returns_by_step.items():
        lines += [f"{step},{k},0.1,0.0,1.0,{v if task != 'foodcollector' else 'nan'},{v},0.0,1.0"
                  for k, v in enumerate(values)]
    (path / "metrics.csv").write_text("\n".join(lines) + "\n")
    return path


def test_a_short_and_a_long_run_meet_at_their_common_steps(tmp_path):
    long = _run(tmp_path / "long", "foodcollector", {100: [1.0, 3.0], 200: [5.0, 5.0], 300: [9.0, 9.0]})
    short = _run(tmp_path / "short", "foodcollector", {100: [0.0, 0.0], 200: [2.0, 4.0]})
    lines = matched_table([long, short], at=[200, 300], average_to=[200]).splitlines()
    assert lines[0] == "| run | at 200 | at 300 | average to 200 |"
    assert lines[2] == f"| {long.as_posix()} | 5.0 [5.0, 5.0] | 9.0 [9.0, 9.0] | 3.5 [3.0, 4.0] |"
    assert lines[3].startswith(f"| {short.as_posix()} | 3.0 [2.0, 4.0] | — | 1.5 [1.0, 2.0] |")


def test_a_grid_run_reads_in_success_percent(tmp_path):
    run = _run(tmp_path / "grid", "salad", {100: [0.5, 0.5]})
    assert "| 50.0% [50.0, 50.0] |" in matched_table([run], at=[100])


def test_the_command_names_a_bad_directory_and_wants_steps(tmp_path, capsys):
    assert main([str(tmp_path), "--at", "5"]) == 1
    assert "is not a run directory" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([str(tmp_path)])


def test_corner_shares_count_the_four_cells_inside_the_outer_wall(tmp_path):
    from train.experiments.report.corners import corner_shares, corner_table, evenness, main

    visits = np.zeros((2, 5, 6), np.int64)
    visits[0, 1, 1], visits[0, 3, 4], visits[0, 2, 2] = 3, 1, 4  # two corners (4 visits) and the middle (4)
    visits[1, 2, 3] = 5  # no corner at all
    assert corner_shares(visits).tolist() == [0.5, 0.0]
    (tmp_path / "run" / "visits").mkdir(parents=True)
    np.save(tmp_path / "run" / "visits" / "000000100.npy", visits)
    lines = corner_table([tmp_path / "run"]).splitlines()
    # four cells reached in all, two of them corners: spread evenly, half the visits would be in corners
    # seed 0 spreads 3:1:4 over three of the four cells reached, seed 1 stays on one: evenness, the entropy over
    # the four cells as a share of log 4, is 70.3 % and 0 %
    h = -sum(q * np.log(q) for q in (3 / 8, 1 / 8, 4 / 8)) / np.log(4)
    assert evenness(visits, visits.sum(0) > 0) == pytest.approx([h, 0.0])
    assert evenness(np.full((1, 3, 3), 7), np.ones((3, 3), bool)) == pytest.approx([1.0])  # all cells alike
    assert lines[2] == f"| {(tmp_path / 'run').as_posix()} | 100 | 25.0% [0.0, 50.0] | 50.0% | 35.1% [0.0, 70.3] |"
    assert main([str(tmp_path)]) == 1  # no visits/ there


def test_the_collapse_tool_reads_exported_policies_and_the_late_corner_visits(tmp_path):
    from train.config import TrainConfig
    from train.experiments.report.collapse import action_name, collapse_table, main
    from train.loop.trainer import Trainer
    from train.storage.policy import export_run_policies

    cfg = TrainConfig().replace(task="hunting", seeds=2, steps=1_000, epoch_steps=250, updates_per_epoch=10,
                                eval_every=500, eval_rollouts=3, eval_horizon=10, buffer_size=1_000,
                                reset_free=True, progress=False)
    trainer = Trainer(cfg, tmp_path / "run")
    trainer.run()
    trainer.close()
    export_run_policies(tmp_path / "run")
    table = collapse_table([tmp_path / "run"]).splitlines()
    assert len(table) == 3 and table[2].startswith(f"| {(tmp_path / 'run').as_posix()} | best (seed ")
    assert "median (seed " in table[2] and table[2].endswith(" | 700–1,200 |")  # warm-up 200, then 500-step evals
    assert table[2].count("collapsed") == 2  # each policy is judged, whichever way
    assert action_name(7, 2) == "north" and action_name(27, 9 + 3 + 2) == "forward +, strafe +, turn -"
    assert main([str(tmp_path / "nothing")]) == 1


def test_collapse_md_lists_exactly_the_shipped_runs_its_command_measures(monkeypatch):
    """collapse.md's table re-derives from its command: every shipped run trained before the collapse columns,
    in the command's order, and none of the later ones (their reports count collapse).
    """
    from train.experiments.report.collapse import records_collapse, run_dirs_of

    root = Path(__file__).resolve().parents[3]
    monkeypatch.chdir(root)  # the table names the runs by their paths from the repository's root
    rows = [line.split("|")[1].strip() for line in Path("docs/results/paper/collapse.md").read_text().splitlines()
            if line.startswith("| docs/")]
    measured = run_dirs_of(Path("docs/results/paper"))
    assert rows == [run.as_posix() for run in measured]
    assert not any(records_collapse(run) for run in measured)
    assert records_collapse(Path("docs/results/paper/factory-released/factory/dynamic-reset-free"))
