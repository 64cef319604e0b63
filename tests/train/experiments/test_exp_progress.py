"""Progress under ``ecorl run``: heartbeats from the processes that train, one line per running job, and runs
sized to a time budget from this machine's measured speed.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from train.cli import main
from train.config import TrainConfig
from train.experiments.catalog import get_experiment
from train.experiments.jobs import Job
from train.experiments.sweep import ProgressMonitor, plan, progress_line
from train.experiments.timebox import Speed, estimate, fit_steps, kind_labels, makespan, resize_jobs, run_kind
from train.loop.runlog import PROGRESS_FILE, heartbeat_to, read_heartbeat

TINY = TrainConfig().replace(task="salad", steps=1200, updates_per_epoch=5, eval_every=500, eval_rollouts=2,
                             eval_horizon=10, buffer_size=2000, progress=False)


def test_a_trainer_under_heartbeat_to_writes_its_progress(tmp_path):
    from train.loop.trainer import Trainer

    path = tmp_path / PROGRESS_FILE
    trainer = Trainer(TINY)
    with heartbeat_to(path):
        trainer.run()
    trainer.close()
    beat = read_heartbeat(path)
    assert beat["step"] == beat["total"] == TINY.total_steps and beat["steps_per_s"] > 0
    assert "success" in beat["latest"]


def test_no_heartbeat_without_heartbeat_to(tmp_path, monkeypatch):
    from train.loop.trainer import Trainer

    monkeypatch.chdir(tmp_path)
    trainer = Trainer(TINY.replace(steps=700))
    trainer.run()
    trainer.close()
    assert not list(tmp_path.rglob(PROGRESS_FILE))


def test_progress_line_shows_steps_rate_eta_and_the_last_evaluation(tmp_path):
    job = Job("headline", "salad", "static-reset-free", str(tmp_path), {}, 1.0)
    assert "starting" in progress_line(job, began=0.0)
    (tmp_path / PROGRESS_FILE).write_text(json.dumps({"step": 25_000, "total": 100_200, "steps_per_s": 212.4,
                                                      "eta_s": 354, "latest": {"success": "0.03"}, "time": 10.0}))
    line = progress_line(job, began=5.0)
    assert "25,000/100,200 steps (25%)" in line and "212 steps/s" in line and "ETA 5 min 54 s" in line
    assert "last success 0.03" in line
    assert "starting" in progress_line(job, began=100.0)  # a heartbeat older than this sweep is not shown


def test_jobs_queued_behind_busy_processes_are_waiting_not_starting(tmp_path):
    """Every job not yet beating read 'starting (imports, environment, first epoch)', and '4 run(s) in progress'
    where two processes trained and two conditions waited for them.
    """
    jobs = [Job("headline", "salad", name, str(tmp_path / name), {}, 1.0) for name in ("a", "b", "c", "d")]
    monitor = ProgressMonitor(jobs, print, workers=2)
    beat = {"step": 100, "total": 1000, "steps_per_s": 50.0, "eta_s": 18, "latest": {}, "time": monitor.wall + 1}
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / PROGRESS_FILE).write_text(json.dumps(beat))
    report = monitor.report()
    assert "] 4 run(s) in progress:" in report and report.count("starting") == 3  # one process still starting
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / PROGRESS_FILE).write_text(json.dumps(beat))
    report = monitor.report()
    assert "] 2 run(s) in progress, 2 waiting:" in report and "starting" not in report
    assert report.endswith("  2 waiting for a free process: salad/c, salad/d")
    monitor.finished.update(job.name for job in jobs)
    assert monitor.report() == ""


def test_fit_steps_sizes_runs_to_the_time_budget():
    jobs = plan(get_experiment("headline-waypoint"), "quick", "/nonexistent", conditions=["static-reset-free",
                                                                                          "dynamic-reset-free"])
    speed = Speed(startup_s=5.0, random_epoch_s=1.0, greedy_epoch_s=2.0, evaluation_s=1.0)
    config = jobs[0].config
    short, longer = fit_steps(speed, config, 2, 2, 200), fit_steps(speed, config, 2, 2, 400)
    assert 10_000 <= short < longer <= 100_000 and short % 10_000 == 0
    assert fit_steps(speed, config, 2, 1, 400) < longer  # one worker: the runs take turns
    assert fit_steps(speed, config, 2, 2, 10**6) == 100_000  # never past the budget's own steps
    cfg = TrainConfig.from_dict(config)
    assert speed.run_seconds(cfg.replace(steps=short)) <= 200 < speed.run_seconds(cfg.replace(steps=short + 10_000))
    resized = resize_jobs(jobs, short)
    assert all(TrainConfig.from_dict(j.config).run.steps == short for j in resized)
    # runs resumed at `short` steps: the time left buys more steps than from scratch, never fewer than done
    resumed = fit_steps(speed, config, 2, 2, 200, done=short)
    assert short < resumed <= 100_000
    assert speed.seconds_left(cfg.replace(steps=resumed), short) <= 200 < speed.run_seconds(cfg.replace(steps=resumed))
    assert fit_steps(speed, config, 2, 2, 0, done=short) == short  # no time left: stay where they stand


def test_run_with_minutes_measures_the_machine_and_sizes_the_runs(tmp_path, capsys):
    code = main(["run", "headline-waypoint", "--budget", "smoke", "--condition", "static-reset-free",
                 "--minutes", "3", "--out", str(tmp_path), "--dry-run"])
    assert code == 0
    err = capsys.readouterr()
    assert "steps/s per seed" in err.err and "steps per seed (predicted" in err.err
    assert "1 runs" in err.err and "[   new]" in err.out


def test_run_with_too_few_minutes_says_it_will_end_late(tmp_path, capsys):
    code = main(["run", "headline-waypoint", "--budget", "smoke", "--condition", "static-reset-free",
                 "--minutes", "0.5", "--out", str(tmp_path), "--dry-run"])
    assert code == 0
    err = capsys.readouterr().err
    assert "warning: even the shortest runs (2 evaluation intervals" in err and " in 0.0 min: " in err
    advised = int(err.split("this will end late (give --minutes ")[1].split()[0])
    assert advised >= 2  # 0.5 asked, the report's 75 s alone already past it


def test_speed_is_measured_in_as_many_processes_as_will_train_side_by_side():
    from train.experiments.catalog import SMOKE, get_experiment, job_config
    from train.experiments.timebox import measure_speed_together

    exp = get_experiment("headline-waypoint")
    config = job_config("salad", exp.conditions["salad"][1], SMOKE).to_dict()
    together = measure_speed_together(config, 2)
    assert together.random_epoch_s > 0 and together.greedy_epoch_s >= together.random_epoch_s
    assert together.evaluation_s > 0 and together.startup_s > 0


def test_a_stopped_run_leaves_its_heartbeat_at_the_step_it_stopped(tmp_path):
    """progress.json said step 700 of a run that stopped at 5 700 (a heartbeat is due only every few seconds)."""
    from train.loop.runlog import Heartbeat

    class Bar:
        def update(self, n):
            pass

        def close(self):
            pass

    path = tmp_path / PROGRESS_FILE
    beat = Heartbeat(Bar(), [path], total=10_000, initial=0)
    beat.update(700)  # the first heartbeat is due at once
    beat.update(5_000)  # the next one is not due yet
    beat.close()  # the run stopped here
    assert read_heartbeat(path)["step"] == 5_700


def test_makespan_starts_the_longest_runs_first_on_the_free_process():
    assert makespan([3.0, 3.0, 2.0, 2.0, 2.0], 2) == 7.0  # 3+2+2 and 3+2
    assert makespan([5.0], 4) == 5.0 and makespan([1.0, 1.0], 1) == 2.0


def test_estimate_measures_each_kind_of_run_once_and_counts_only_the_steps_left(tmp_path):
    jobs = plan(get_experiment("dynamism-sweep"), "smoke", str(tmp_path))  # salad and hunting, five runs each
    speed = Speed(startup_s=2.0, random_epoch_s=1.0, greedy_epoch_s=1.0, evaluation_s=0.5)
    measured, lines = [], []
    seconds = estimate(jobs, 2, lines.append, measure=lambda config, copies: measured.append(copies) or speed)
    assert measured == [2, 2]  # one measurement per task, as many copies as will run at once
    each = speed.run_seconds(TrainConfig.from_dict(jobs[0].config), margin=1.0)
    assert seconds == pytest.approx(makespan([each] * 10, 2))
    assert lines[-1].startswith("estimate: 10 run(s), 2 at a time: about ")
    half = TrainConfig.from_dict(jobs[0].config).total_steps // 2  # a run stopped halfway costs half
    Path(jobs[0].run_dir).mkdir(parents=True)
    (Path(jobs[0].run_dir) / PROGRESS_FILE).write_text(json.dumps({"step": half, "time": 0.0}))
    assert estimate(jobs[:1], 1, lines.append, measure=lambda *_: speed) == pytest.approx(each / 2)


def test_run_estimate_prints_the_plan_and_the_measured_time(tmp_path, capsys):
    assert main(["run", "headline", "--budget", "smoke", "--condition", "static-reset-free", "--jobs", "1",
                 "--estimate", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "[   new] headline/salad/static-reset-free" in out and "salad, 2 seeds: " in out
    assert "estimate: 1 run(s), 1 at a time: about " in out
    assert not (tmp_path / "headline" / "salad" / "static-reset-free" / "metrics.csv").exists()  # nothing trained


def test_kinds_of_one_task_are_named_by_what_tells_them_apart(tmp_path):
    """Two kinds of salad runs both read 'salad, 10 seeds' (one with minibatches of 256)."""
    jobs = [j for j in plan(get_experiment("settings"), "paper", str(tmp_path)) if not j.is_measurement]
    labels = set(kind_labels(list(dict.fromkeys(run_kind(j) for j in jobs))))
    assert {"salad, 10 seeds, batch 64", "salad, 10 seeds, batch 256"} <= labels
