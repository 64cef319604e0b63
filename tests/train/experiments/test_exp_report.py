"""Report pieces on synthetic run directories: statistics, paper values, figures, markdown."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from train.experiments.catalog import get_experiment
from train.experiments.jobs import DONE_FILE
from train.experiments.report import make_report
from train.experiments.report.paper import format_paper, load_paper, paper_value
from train.experiments.report.runs import read_metrics
from train.experiments.report.stats import bootstrap_ci
from train.experiments.sweep import EXPERIMENT_FILE
from train.rundir import METRIC_COLUMNS


def test_bootstrap_ci_brackets_the_mean():
    values = np.array([[0.0, 0.2, 0.4, 0.6], [1.0, 1.0, 1.0, 1.0]])
    mean, low, high = bootstrap_ci(values)
    np.testing.assert_allclose(mean, [0.3, 1.0])
    assert low[0] < 0.3 < high[0] and 0.0 <= low[0] and high[0] <= 0.6
    assert low[1] == high[1] == 1.0
    m1, l1, h1 = bootstrap_ci(np.array([[0.5]]))
    assert m1[0] == l1[0] == h1[0] == 0.5
    again = bootstrap_ci(values)
    np.testing.assert_array_equal(again[1], low)  # seeded: the same interval every time


def test_paper_values_and_their_marks():
    paper = load_paper()
    dyn = paper["dynamism"]
    v = paper_value(dyn, "salad", "dynamic-reset-free")
    assert v["value"] == pytest.approx(0.70) and v["approximate"]
    assert format_paper(v) == "≈ 70% (Fig. 4)"
    assert format_paper(None) == "—"
    assert format_paper({"value": 0.5, "approximate": False, "figure": "T"}) == "= 50% (T)"
    assert paper_value(paper["headline"], "salad", "static-episodic")["value"] == pytest.approx(0.12)
    table = [x for x in paper["measure"]["values"] if x["measure"] == "entropy"]
    assert [x["mean"] for x in table] == [6.2, 7.6, 7.9, 8.4, 8.6] and not any(x["approximate"] for x in table)
    assert any("RND" in c["text"] for c in paper["rnd"]["claims"])
    assert not any("RND" in c["text"] for c in paper["dynamism-sweep"]["claims"])


def _fake_run(run_dir, seeds, steps, success, grid=(8, 8)):
    run_dir.mkdir(parents=True)
    with open(run_dir / "metrics.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=METRIC_COLUMNS)
        writer.writeheader()
        for i, step in enumerate(steps):
            for k in range(seeds):
                writer.writerow({"step": step, "seed": k, "epsilon": 0.1, "loss": 1.0,
                                 "success": success(i, k), "return": 0.0, "train_reward": 0.0, "steps_per_s": 1.0})
    (run_dir / "visits").mkdir()
    for i, step in enumerate(steps):
        np.save(run_dir / "visits" / f"{step:09d}.npy", np.full((seeds, *grid), i + 1, dtype=np.int64))
    (run_dir / DONE_FILE).write_text("{}")


def test_report_on_synthetic_runs(tmp_path):
    exp = get_experiment("episodic-vs-reset-free")
    root = tmp_path / "results"
    info = {**exp.describe(), "budget": "quick", "tasks_run": ["salad"]}
    (root / exp.name).mkdir(parents=True)
    (root / exp.name / EXPERIMENT_FILE).write_text(json.dumps(info))
    steps = list(range(5_000, 55_000, 5_000))
    _fake_run(root / exp.name / "salad" / "static-episodic", 3, steps, lambda i, k: 0.1 * k)
    _fake_run(root / exp.name / "salad" / "static-reset-free", 3, steps[:4], lambda i, k: 0.0)
    (root / exp.name / "salad" / "static-reset-free" / DONE_FILE).unlink()  # still running
    paths = make_report(root, videos=False)
    names = sorted(p.name for p in paths)
    assert names == ["episodic-vs-reset-free_curves.png", "episodic-vs-reset-free_salad_heatmaps.png",
                     "index.html", "report.md"]
    md = (root / "report.md").read_text()
    assert "| salad | static, episodic | 10.0% [" in md and "| 0 / 3 | 3 | 50000 | ≈ 12% (Fig. 2) |" in md
    assert "| salad | static, non-episodic | 0.0% [0.0, 0.0] | 0 / 3 | 3 | 20000 | ≈ 0% (Fig. 2) |" in md
    assert "1 run(s) not finished yet" in md
    steps_read, values = read_metrics(root / exp.name / "salad" / "static-episodic" / "metrics.csv", "success")
    assert steps_read.tolist() == steps and values.shape == (10, 3)
    assert "<video" not in (root / "index.html").read_text()


def test_loose_videos_in_the_results_directory_are_shown(tmp_path):
    from ecology import write_video

    test_report_on_synthetic_runs(tmp_path)
    root = tmp_path / "results"
    write_video([np.zeros((32, 32, 3), np.uint8)] * 4, root / "demo.mp4", fps=4)
    make_report(root, videos=False)
    page = (root / "index.html").read_text()
    assert "<h2>Videos</h2>" in page and "demo.mp4" in page


def test_report_tabulates_milestones_with_the_seeds_that_learned(tmp_path):
    exp = get_experiment("settings")
    assert exp.milestones == (250_000, 500_000)
    root = tmp_path / "results"
    (root / exp.name).mkdir(parents=True)
    (root / exp.name / EXPERIMENT_FILE).write_text(json.dumps({**exp.describe(), "budget": "paper"}))
    steps = [245_200, 250_200, 255_200, 300_200]  # stops before 500 000
    # seed 0 learns at the second evaluation, seed 1 hovers at the threshold, seed 2 never learns
    success = lambda i, k: [0.9 if i >= 1 else 0.1, 0.2, 0.0][k]  # noqa: E731
    _fake_run(root / exp.name / "salad" / "rf-lr3e-4", 3, steps, success)
    make_report(root, videos=False)
    md = (root / "report.md").read_text()
    assert "at 250,000 steps: mean [95% CI]; seeds > 20%" in md
    row = next(line for line in md.splitlines() if line.startswith("| salad | non-episodic, lr 3e-4 |")
               and "learned" in line)
    # the evaluation closest to 250 000 (250 200, not 245 200); 0.2 is not above the threshold
    assert "| 36.7% [" in row and row.endswith("learned 1 / 3 | — |"), row


def test_quick_curves_are_drawn_over_the_shipped_paper_budget_runs(tmp_path, monkeypatch):
    import train.experiments.report.runs as report

    exp = get_experiment("headline")
    shipped, root = tmp_path / "paper", tmp_path / "results"
    for base, steps, seeds in ((shipped, range(50_200, 1_000_201, 50_000), 4), (root, range(5_200, 30_201, 5_000), 2)):
        (base / exp.name).mkdir(parents=True)
        (base / exp.name / EXPERIMENT_FILE).write_text(json.dumps({**exp.describe(), "budget": "quick"}))
        for cond in exp.conditions["salad"]:
            _fake_run(base / exp.name / "salad" / cond.name, seeds, list(steps), lambda i, k: min(1.0, 0.01 * i))
    monkeypatch.setattr(report, "REFERENCE_DIR", shipped)
    quick = report.load_experiment(root / exp.name)
    reference = report.load_reference(quick)
    assert reference is not None and {r.condition for r in reference.runs} == {c.name for c in exp.conditions["salad"]}
    assert report.load_reference(report.load_experiment(shipped / exp.name)) is None  # not drawn over itself
    make_report(root, videos=False)
    md = (root / "report.md").read_text()
    assert "Dashed: the mean of the shipped run, 4 seeds × 1 M steps" in md
    assert (root / "figures" / f"{exp.name}_curves.png").stat().st_size > 10_000
