"""Every experiment end to end at the smoke budget: runs, then the report over all of them."""

from __future__ import annotations

import csv
import json
import shutil

import pytest

from train import cli
from train.experiments.catalog import EXPERIMENTS
from train.experiments.jobs import DONE_FILE
from train.experiments.report import make_report
from train.storage.checkpoint import CHECKPOINT_NAME
from train.storage.rundir import EXPERIMENT_FILE

EXPECTED_FILES = ("config.json", "metrics.csv", "checkpoint.npz", "visits.npy", DONE_FILE)


@pytest.fixture(scope="module")
def report(smoke_root, cli):
    """`ecorl report` over the whole smoke results directory (videos rendered where asked for)."""
    proc = cli("report", str(smoke_root))
    return smoke_root, proc.stdout


def test_every_experiment_has_a_smoke_run(smoke_tasks):
    assert sorted(smoke_tasks) == sorted(EXPERIMENTS)


def test_every_run_directory_is_complete(smoke_root, smoke_tasks, smoke_conditions):
    for name, tasks in smoke_tasks.items():
        exp = EXPERIMENTS[name]
        info = json.loads((smoke_root / name / EXPERIMENT_FILE).read_text())
        assert info["name"] == name and info["budget"] == "smoke"
        for task in exp.select_tasks(tasks):
            for cond in exp.select_conditions(task, smoke_conditions.get(name)):
                run = smoke_root / name / task / cond.name
                done = json.loads((run / DONE_FILE).read_text())
                if exp.is_measurement:
                    assert (run / "table.csv").exists() and (run / "table.md").exists()
                    continue
                for f in EXPECTED_FILES:
                    assert (run / f).exists(), run / f
                assert done["total_steps"] == 1200 and done["seeds"] == 2
                with open(run / "metrics.csv") as fh:
                    rows = list(csv.DictReader(fh))
                assert [int(r["step"]) for r in rows] == [700, 700, 1200, 1200]
                assert len(list((run / "visits").glob("*.npy"))) == 2


def test_report_writes_figures_tables_and_page(report, smoke_tasks):
    root, stdout = report
    md = (root / "report.md").read_text()
    page = (root / "index.html").read_text()
    for name in smoke_tasks:
        assert f"## {name} (" in md
        if name != "measure":
            assert (root / "figures" / f"{name}_curves.png").stat().st_size > 10_000
            assert f"figures/{name}_curves.png" in page
    for name, task in (("headline", "salad"), ("episodic-vs-reset-free", "salad"), ("walls", "walled-salad")):
        assert (root / "figures" / f"{name}_{task}_heatmaps.png").exists()
    assert "≈ 70%" in md and "≈ 12%" in md  # the paper's text-quoted (approximate) values beside ours
    assert "= 908 ± 480" in md  # Table 1 (exact)
    assert "(100 per evaluation at the paper's budget; this directory's runs: 10;" in md  # smoke evaluates 10
    assert str(root / "report.md") in stdout


def test_reports_have_videos_playable_in_browsers_with_filmstrips(report):
    """Both headline experiments film each condition (4 each), and so does the shaping experiment (5 on
    hunting, with the filmstrips of the paper's Fig. 11-12); no other experiment in the smoke run does.
    """
    root, _ = report
    filmed = [(name, task, cond.name) for name, task in (("headline", "salad"), ("headline-waypoint", "salad"),
                                                          ("shaping", "hunting"))
              for cond in EXPERIMENTS[name].conditions[task]]
    assert len(filmed) == 13
    for place in filmed:
        assert root.joinpath(*place, "video.mp4").stat().st_size > 1000
        assert root.joinpath(*place, "filmstrip.png").stat().st_size > 1000
    page = (root / "index.html").read_text()
    assert page.count("<video") == 13 and page.count("type='video/mp4; codecs=") == 13
    assert page.count("<figure class='strip'>") == 13
    videos = root / "figures" / "videos"
    copies = list(videos.glob("*.mp4"))
    assert len(copies) == 13 and all(b"avc1" in p.read_bytes()[:4096] for p in copies)  # H.264: browsers play it
    assert len(list(videos.glob("*-strip.png"))) == 13 and len(list(videos.glob("*.png"))) == 26  # and posters
    assert not (root / "walls" / "walled-salad" / "no-shaping-episodic" / "video.mp4").exists()


def test_measure_rows_match_the_papers_conditions(smoke_root):
    with open(smoke_root / "measure" / "factory" / "hitting-time" / "table.csv") as fh:
        hitting = [r["condition"] for r in csv.DictReader(fh)]
    with open(smoke_root / "measure" / "factory" / "entropy" / "table.csv") as fh:
        entropy = [r["condition"] for r in csv.DictReader(fh)]
    assert hitting == ["static non-episodic", "dynamic non-episodic", "shaped non-episodic"]
    assert entropy == [f"dynamism p={p}" for p in ("0", "0.01", "0.05", "0.1", "0.5")]


def test_report_of_one_experiment_directory(smoke_root, cli, tmp_path):
    cli("report", str(smoke_root / "rnd"), "--no-videos")
    md = (smoke_root / "rnd" / "report.md").read_text()
    assert "## rnd (Fig. 6 (right))" in md and "static + RND" in md and "## walls" not in md
    assert (smoke_root / "rnd" / "figures" / "rnd_curves.png").exists()
    proc = cli("report", str(tmp_path), check=False)
    assert proc.returncode == 2 and "is neither an experiment's results" in proc.stderr


def test_results_shipped_without_checkpoints_are_filmed_from_their_exported_policies(report, tmp_path):
    smoke_root, _ = report  # filmed from the checkpoints
    shipped = tmp_path / "headline-waypoint"
    shutil.copytree(smoke_root / "headline-waypoint", shipped,
                    ignore=shutil.ignore_patterns(CHECKPOINT_NAME, "video.*", "filmstrip.png", "figures"))
    make_report(shipped)
    for cond in EXPERIMENTS["headline-waypoint"].conditions["salad"]:
        run = shipped / "salad" / cond.name
        assert not (run / CHECKPOINT_NAME).exists() and (run / "policies" / "best.npz").exists()
        assert (run / "video.mp4").stat().st_size > 1000 and (run / "filmstrip.png").exists()
        info = json.loads((run / "video.json").read_text())
        best = json.loads((smoke_root / "headline-waypoint" / "salad" / cond.name / "video.json").read_text())
        assert info["seed"] == best["seed"]  # the exported best seed is the seed the checkpoint's film shows


def _frames(path) -> int:
    import cv2

    cap = cv2.VideoCapture(str(path))
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    cap.release()
    return n


def test_policy_video_from_a_run(smoke_root, tmp_path, capsys):
    run_dir = smoke_root / "headline" / "salad" / "dynamic-reset-free"
    out = tmp_path / "policy.mp4"
    assert cli.main(["video", "salad", "--policy", str(run_dir / "checkpoint.npz"), "--agent", "1",
                          "--steps", "20", "--out", str(out), "--seed", "3"]) == 0
    assert _frames(out) >= 21
    assert cli.main(["video", "salad", "--policy", str(run_dir), "--train-env", "--steps", "10",
                          "--out", str(tmp_path / "train.mp4")]) == 0
    assert cli.main(["video", "hunting", "--policy", str(run_dir), "--out", str(tmp_path / "x.mp4")]) == 2
    assert "trained on 'salad'" in capsys.readouterr().err
    assert cli.main(["video", "salad", "--policy", str(run_dir), "--agent", "5"]) == 2
    assert cli.main(["video", "salad", "--policy", str(tmp_path)]) == 2
