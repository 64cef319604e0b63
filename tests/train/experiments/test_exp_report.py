"""Report pieces on synthetic run directories: statistics, paper values, figures, markdown."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from train.experiments.catalog import get_experiment
from train.experiments.jobs import DONE_FILE
from train.experiments.report import make_report
from train.experiments.report.figures import (
    HEATMAP_POINTS,
    curve_panels,
    heatmap_snapshot_files,
    report_colors,
    visit_snapshots,
)
from train.experiments.report.paper import format_paper, load_paper, paper_value
from train.experiments.report.runs import load_experiment, read_metrics
from train.experiments.report.stats import COLLAPSE_SHARE, bootstrap_ci
from train.storage.rundir import EXPERIMENT_FILE, METRIC_COLUMNS


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
    # a claim naming a list of experiments speaks of each of them, and of no other
    sweep_claims = [c["text"] for c in paper["dynamism-sweep"]["claims"]]
    assert len(sweep_claims) == 2 and [c["text"] for c in paper["dynamism-sweep-waypoint"]["claims"]] == sweep_claims


def _fake_run(run_dir, seeds, steps, success, grid=(8, 8), loss=lambda i, k: 1.0, max_q=lambda i, k: 50.0,
              columns=METRIC_COLUMNS, top_share=None):
    run_dir.mkdir(parents=True)
    with open(run_dir / "metrics.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for i, step in enumerate(steps):
            for k in range(seeds):
                writer.writerow({"step": step, "seed": k, "epsilon": 0.1, "loss": loss(i, k), "max_q": max_q(i, k),
                                 "success": success(i, k), "return": 0.0, "train_reward": 0.0, "steps_per_s": 1.0,
                                 **({} if top_share is None else {"top_action": 2, "top_action_share": top_share(i, k),
                                                                  "corner_share": 0.1})})
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
    assert "| salad | static, episodic | 10.0% [" in md
    assert "| 0 / 3 | — | 0 / 3 | — | 3 | 50000 | ≈ 12% (Fig. 2) |" in md
    assert ("| salad | static, non-episodic | 0.0% [0.0, 0.0] | 0 / 3 | — | 0 / 3 | — | 3 | 20000 | ≈ 0% (Fig. 2) |"
            in md)
    assert "2000 resamples, generator seed 0" in md and "seeds diverged" in md
    assert "1 run(s) not finished yet" in md
    steps_read, values = read_metrics(root / exp.name / "salad" / "static-episodic" / "metrics.csv", "success")
    assert steps_read.tolist() == steps and values.shape == (10, 3)
    assert "<video" not in (root / "index.html").read_text()


def test_report_counts_collapsed_seeds_and_draws_their_top_action_share(tmp_path):
    exp = get_experiment("episodic-vs-reset-free")
    root = tmp_path / "results"
    (root / exp.name).mkdir(parents=True)
    (root / exp.name / EXPERIMENT_FILE).write_text(json.dumps({**exp.describe(), "budget": "quick"}))
    steps = [5_000, 10_000, 15_000]
    # seed 1 collapses at the last evaluation only; seed 2 sits at the threshold, which is not above it
    share = lambda i, k: [0.3, 0.9 if i == 2 else 0.4, COLLAPSE_SHARE][k]  # noqa: E731
    _fake_run(root / exp.name / "salad" / "static-reset-free", 3, steps, lambda i, k: 0.0, top_share=share)
    _fake_run(root / exp.name / "salad" / "static-episodic", 3, steps, lambda i, k: 0.0)  # written before it
    paths = make_report(root, videos=False)
    assert "episodic-vs-reset-free_collapse.png" in {p.name for p in paths}
    md = (root / "report.md").read_text()
    assert "| salad | static, non-episodic | 0.0% [0.0, 0.0] | 0 / 3 | — | 0 / 3 | 1 / 3 (seed 1) | 3 |" in md
    assert "| salad | static, episodic | 0.0% [0.0, 0.0] | 0 / 3 | — | 0 / 3 | — | 3 |" in md
    assert "Seeds collapsed: a seed collapsed when" in md and "![greedy top-action share]" in md
    run = next(r for r in load_experiment(root / exp.name).runs if r.condition == "static-reset-free")
    assert run.top_shares(1).tolist() == [0.3, 0.4, COLLAPSE_SHARE]


def test_walls_curves_get_a_panel_per_setting_and_other_experiments_one_per_task(tmp_path):
    steps = [5_000, 10_000]
    for name, task, conditions in (("walls", "walled-salad", ["one-time-reward-episodic", "no-shaping-reset-free",
                                                               "env-shaping-sparse-reset-free",
                                                               "one-time-reward-reset-free"]),
                                   ("dynamism", "salad", ["static-episodic", "dynamic-reset-free"])):
        root = tmp_path / name
        root.mkdir()
        (root / EXPERIMENT_FILE).write_text(json.dumps({**get_experiment(name).describe(), "budget": "quick"}))
        for condition in conditions:
            _fake_run(root / task / condition, 2, steps, lambda i, k: 0.0)
    panels = curve_panels(load_experiment(tmp_path / "walls"))
    walls = [(title, [r.condition for r in runs]) for _, title, runs in panels]
    assert walls == [("walled-salad, non-episodic", ["env-shaping-sparse-reset-free", "one-time-reward-reset-free",
                                                     "no-shaping-reset-free"]),
                     ("walled-salad, episodic", ["one-time-reward-episodic"])]
    dynamism = [(title, len(runs)) for _, title, runs in curve_panels(load_experiment(tmp_path / "dynamism"))]
    assert dynamism == [("salad", 2)]
    colors = report_colors(load_experiment(tmp_path / "walls"))  # one arm, one colour in both panels
    assert colors["one-time-reward-episodic"] == colors["one-time-reward-reset-free"]
    assert len({colors[c] for c in ("no-shaping-reset-free", "env-shaping-sparse-reset-free",
                                    "one-time-reward-episodic")}) == 3


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
    assert "| 36.7% [" in row and row.endswith("learned 1 / 3 at 90%; diverged 0 | — |"), row


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


def test_bootstrap_intervals_do_not_depend_on_what_was_computed_before():
    few = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.81, 0.0, 0.0])  # one learned seed: a lumpy bootstrap
    other = np.linspace(0.0, 1.0, 7)
    first = bootstrap_ci(few)
    np.random.seed(123)
    np.random.random(10)  # the global generator must not matter either
    bootstrap_ci(other)
    bootstrap_ci(np.stack([other, other]))
    again = bootstrap_ci(few)
    assert [float(x) for x in first] == [float(x) for x in again]
    assert float(first[1]) < float(first[2])


def test_the_divergence_rule():
    from train.experiments.report.stats import DIVERGED_LOSS, blown, diverged, q_bound

    assert q_bound(0.99) == pytest.approx(20_000.0) and q_bound(1.0) == float("inf")
    loss = np.array([[1.0, 2 * DIVERGED_LOSS, np.nan, 1.0, 1.0], [1.0, 1.0, np.nan, 1.0, 1.0]])
    max_q = np.array([[10.0, 10.0, 10.0, 3e4, np.nan], [10.0, 10.0, 10.0, 10.0, 10.0]])
    # a blown loss, a NaN loss (no gradient step: no evidence), |Q| beyond the bound, a non-finite Q
    assert blown(loss, max_q, 0.99).tolist() == [[False, True, False, True, True], [False] * 5]
    assert blown(loss, max_q, 0.999).tolist()[0][3] is False  # the bound follows the run's discount
    assert diverged(blown(loss, max_q, 0.99)).tolist() == [False, True, False, True, True]


def test_divergence_is_marked_and_old_metrics_without_max_q_still_load(tmp_path):
    from train.experiments.report.runs import read_run
    from train.storage.rundir import METRIC_COLUMNS as columns

    old = tuple(c for c in columns if c != "max_q")
    steps = [5_200, 10_200, 15_200]
    # seed 1's loss blows up at the second evaluation and recovers; seed 2's Q does at the last
    loss = lambda i, k: 5e3 if (i, k) == (1, 1) else 1.0  # noqa: E731
    max_q = lambda i, k: 1e6 if (i, k) == (2, 2) else 40.0  # noqa: E731
    _fake_run(tmp_path / "new", 3, steps, lambda i, k: 0.5, loss=loss, max_q=max_q)
    _fake_run(tmp_path / "old", 3, steps, lambda i, k: 0.5, loss=loss, max_q=max_q, columns=old)
    assert "max_q" not in (tmp_path / "old" / "metrics.csv").read_text()
    new_run = read_run(tmp_path / "new", "salad", "c", "c")
    old_run = read_run(tmp_path / "old", "salad", "c", "c")
    assert new_run.diverged(0).tolist() == [False, False, False]
    assert new_run.diverged(1).tolist() == [False, True, False]
    assert new_run.diverged().tolist() == [False, True, True]  # once diverged, always marked
    assert old_run.diverged().tolist() == [False, True, False]  # the loss alone
    from train.experiments.report.stats import format_diverged

    assert format_diverged(new_run.diverged(), new_run.seed_ids) == "2 / 3 (seeds 1, 2)"
    assert format_diverged(old_run.diverged(), old_run.seed_ids) == "1 / 3 (seed 1)"


def test_learned_level_gives_the_learned_seeds_range_and_mean():
    from train.experiments.report.stats import learned_level

    values = np.array([0.28, 0.86, 0.10, 0.75, 0.0])  # three seeds above the 20 % threshold
    assert learned_level(values, "success") == "28–86% (mean 63%)"
    assert learned_level(np.array([0.05, 0.56]), "success") == "56%"
    assert learned_level(np.array([0.05, 0.2]), "success") == "—"  # exactly at the threshold is not learned
    assert learned_level(np.array([3.0, 9.0]), "return") == "—"  # returns have no learning threshold


_METRICS = "step,seed,success,loss\n100,0,0.5,1.0\n100,1,0.25,1.0\n200,0,0.75,1.0\n200,1,0.5,1.0\n"


def _columns(tmp_path, text):
    from train.experiments.report.runs import read_columns

    (tmp_path / "metrics.csv").write_text(text)
    return read_columns(tmp_path / "metrics.csv", ("success",))


def test_a_last_line_cut_short_by_an_interrupted_run_is_dropped(tmp_path):
    steps, seeds, (success,) = _columns(tmp_path, _METRICS.replace("200,1,0.5,1.0\n", "200,1,0.4"))
    assert steps.tolist() == [100] and seeds.tolist() == [0, 1]  # step 200 lacks seed 1 now
    assert success.tolist() == [[0.5, 0.25]]


@pytest.mark.parametrize("text, message", [
    ("garbage,,\n\x00\x01\n", "is not an ecorl metrics file"),
    (_METRICS.replace("200,0,0.75", "200,zero,0.75"), "line 4 is not a metrics row"),
    (_METRICS.replace("100,1,0.25,1.0", "100,1"), "line 3 is not a metrics row .fewer cells"),
])
def test_a_damaged_metrics_file_is_refused_by_name(tmp_path, text, message):
    from train.experiments.report.runs import ReportError

    with pytest.raises(ReportError, match=message) as caught:
        _columns(tmp_path, text)
    assert "metrics.csv" in str(caught.value) and "--restart" in str(caught.value)


@pytest.mark.parametrize("evaluations", [1, 3, 4, 7, 300])
def test_keeping_only_the_heatmap_snapshots_draws_the_same_heatmaps(tmp_path, evaluations):
    run_dir = tmp_path / "run"
    _fake_run(run_dir, 2, [5_000 * (i + 1) for i in range(evaluations)], lambda i, k: 0.0)
    before = visit_snapshots(run_dir)
    kept = set(heatmap_snapshot_files(run_dir))
    for f in (run_dir / "visits").glob("*.npy"):
        if f not in kept:
            f.unlink()
    after = visit_snapshots(run_dir)
    assert len(before) == min(evaluations, HEATMAP_POINTS) == len(kept)
    assert [s for s, _ in after] == [s for s, _ in before]
    assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(after, before))


def test_a_task_that_pays_more_per_step_scales_the_divergence_bounds():
    from train.experiments.report.stats import blown

    loss, max_q = np.array([[5e3, 10.0]]), np.array([[1e4, 5e5]])
    assert blown(loss, max_q, 0.99).tolist() == [[True, True]]  # 200 / 0.01 = 20 000; loss above 1 000
    assert blown(loss, max_q, 0.99, reward_bound=10_100).tolist() == [[False, False]]  # 1 010 000; 2.55e6


def test_the_reports_reward_bound_reads_a_costlier_predator_from_the_runs_config(tmp_path):
    """The report's bound stayed 200 for scavenging with predator_penalty=1000 (its env said 1 100)."""
    import json

    from train.config import TrainConfig
    from train.experiments.report.runs import reward_bound, run_config

    for penalty, bound in ((None, 200.0), (1000.0, 1100.0)):
        cfg = TrainConfig().to_dict()
        cfg["env"].update(task="scavenging", env_kwargs={} if penalty is None else {"predator_penalty": penalty})
        (tmp_path / "config.json").write_text(json.dumps(cfg))
        assert reward_bound(run_config(tmp_path)) == bound


def test_a_planted_results_file_cannot_make_the_report_read_or_gather_without_bound(tmp_path, monkeypatch):
    import train.experiments.report.stats as stats
    from train.experiments.report.runs import MAX_SEEDS, ReportError, read_columns, trusted_info
    from train.storage.rundir import MAX_METRIC_ROWS, MAX_METRICS_BYTES
    from train.storage.safeio import UnsafeFileError

    wide = tmp_path / "metrics.csv"
    wide.write_text("step,seed,success\n" + "".join(f"5000,{k},0.0\n" for k in range(MAX_SEEDS + 1)))
    with pytest.raises(ReportError, match=f"holds more than {MAX_SEEDS:,} seeds"):
        read_columns(wide, ("success",))
    long = tmp_path / "long.csv"  # 1 000 seeds, 501 evaluations: refused at the row cap, before the rest is parsed
    long.write_text("step,seed,success\n" + "".join(f"{5000 * (i // 1000)},{i % 1000},0.0\n"
                                                   for i in range(MAX_METRIC_ROWS + 1000)))
    with pytest.raises(ReportError, match=f"{MAX_METRIC_ROWS:,} rows"):
        read_columns(long, ("success",))
    huge = tmp_path / "huge.csv"
    with open(huge, "w") as fh:
        fh.write("step,seed,success\n")
        fh.truncate(MAX_METRICS_BYTES + 1)
    with pytest.raises(UnsafeFileError, match="larger than"):
        read_columns(huge, ("success",))
    (tmp_path / "exp").mkdir()
    padding = "x" * (5 << 20)  # ecorl writes about 10 KB
    (tmp_path / "exp" / EXPERIMENT_FILE).write_text('{"name": "headline", "tasks": {}, "pad": "' + padding + '"}')
    with pytest.raises(ReportError, match="not valid JSON"):
        trusted_info(tmp_path / "exp")
    values = np.random.default_rng(0).random((9, 40))
    whole = bootstrap_ci(values)
    monkeypatch.setattr(stats, "BOOTSTRAP_BYTES", 3 * 2000 * 40 * 8)  # three rows at a time, then two, and so on
    assert all(np.array_equal(a, b) for a, b in zip(whole, bootstrap_ci(values)))


@pytest.mark.parametrize("checkpoint", [True, False])
def test_a_run_stopped_before_its_first_evaluation_is_named_with_the_command_that_resumes_it(tmp_path, checkpoint):
    from train.config import TrainConfig
    from train.experiments.report.runs import ReportError
    from train.storage.checkpoint import CHECKPOINT_NAME
    from train.storage.rundir import RunDir

    run = tmp_path / "run"
    run.mkdir()
    RunDir(run).write_config(TrainConfig().replace(task="hunting"))  # what `ecorl train` wrote, without metrics.csv
    if checkpoint:
        (run / CHECKPOINT_NAME).write_bytes(b"")
    with pytest.raises(ReportError) as raised:
        make_report(run, videos=False)
    message = str(raised.value)
    assert "\n" not in message and "before its first evaluation" in message
    resume = f"ecorl train hunting --resume --out {run}"
    assert (resume in message) == checkpoint and ("train it again" in message) != checkpoint


def test_an_experiment_report_names_its_conditions_not_evaluated_yet(tmp_path):
    exp = get_experiment("headline")
    root = tmp_path / "results" / exp.name
    root.mkdir(parents=True)
    (root / EXPERIMENT_FILE).write_text(json.dumps({**exp.describe(), "budget": "quick", "tasks_run": ["salad"]}))
    _fake_run(root / "salad" / "static-episodic", 3, [5_000, 10_000], lambda i, k: 0.1 * k)
    (root / "salad" / "static-reset-free").mkdir()  # started (config.json), stopped before its first evaluation
    (root / "salad" / "static-reset-free" / "config.json").write_text("{}")
    (root / "salad" / "dynamic-episodic").mkdir()  # started, nothing written yet
    make_report(root, videos=False)
    line = ("Not evaluated yet, so not shown: salad/dynamic-episodic, salad/static-reset-free; re-run the same "
            "command to train them.")  # not dynamic-reset-free: never started, perhaps never asked for
    assert line in (root / "report.md").read_text() and line in (root / "index.html").read_text()


def test_a_curve_of_one_evaluation_is_drawn_as_a_point():
    from train.experiments.report.figures import point_marker

    assert point_marker(np.array([5_000])) == "o"  # a line through one point would draw nothing
    assert point_marker(np.array([5_000, 10_000])) is None
