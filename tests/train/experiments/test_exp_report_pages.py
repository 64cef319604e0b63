"""Reports a newcomer can trust: single runs, byte-stable re-draws of shipped results, H.264 videos, one colour
per condition, and a page that leads with the shipped paper-budget panels.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest

from train.cli import main
from train.experiments.catalog import EXPERIMENTS
from train.experiments.report import make_report
from train.experiments.report.figures import CONDITION_COLORS, OTHER_COLORS, condition_color, condition_colors
from train.experiments.report.pages import default_out
from train.experiments.report.runs import REFERENCE_DIR

TINY = ["--steps", "1000", "--updates-per-epoch", "20", "--eval-every", "500", "--eval-rollouts", "3",
        "--eval-horizon", "20", "--buffer-size", "2000", "--seeds", "2", "--no-progress"]


def _digests(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_report_of_a_single_train_run(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", "salad", "--dynamism", "0.1", "--reset-free", *TINY, "--out", str(run)]) == 0
    assert main(["report", str(run)]) == 0
    out = run / "report"
    page = (out / "index.html").read_text()
    assert (out / "figures" / "run_curves.png").stat().st_size > 10_000
    assert (out / "figures" / "run_salad_heatmaps.png").exists()
    videos = list((out / "figures" / "videos").glob("*.mp4"))
    assert len(videos) == 1 and b"avc1" in videos[0].read_bytes()[:4096]  # H.264, which browsers play
    assert videos[0].with_suffix(".png").exists()  # its poster: the middle frame
    head = videos[0].read_bytes()[:65536]
    profile = head[head.find(b"avcC") + 5:head.find(b"avcC") + 8].hex().upper()  # the encoder's, e.g. 640015
    assert f"codecs=&quot;avc1.{profile}&quot;" in page  # the page names the codec the file holds
    assert "seed " in page and "(the best)" in page and "episode(s) filmed" in page
    assert str(tmp_path) not in page and str(tmp_path) not in (out / "report.md").read_text()


def test_a_single_run_report_counts_diverged_and_collapsed_seeds_as_an_experiment_does(tmp_path):
    run = tmp_path / "run"
    assert main(["train", "salad", *TINY, "--out", str(run)]) == 0  # two seeds
    lines = (run / "metrics.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    seed_1_last = [row for row in rows if row[header.index("seed")] == "1"][-1]
    for row in rows:  # seed 1 blows up and collapses at its last evaluation; seed 0 stays sound
        row[header.index("max_q")] = "1e6" if row is seed_1_last else "1.0"
        row[header.index("top_action_share")] = "0.99" if row is seed_1_last else "0.3"
    (run / "metrics.csv").write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    assert main(["report", str(run), "--no-videos"]) == 0
    table = (run / "report" / "report.md").read_text()
    assert "| 1 / 2 (seed 1) | 1 / 2 (seed 1) |" in table
    assert (run / "report" / "figures" / "run_collapse.png").exists()


def test_a_report_after_the_run_trained_on_films_its_final_policy_again(tmp_path):
    """A grown run's report showed the film of its earlier final policy (video.json still at the old step)."""
    import json

    run = tmp_path / "run"
    assert main(["train", "salad", *TINY, "--out", str(run)]) == 0
    assert main(["report", str(run)]) == 0
    first = json.loads((run / "video.json").read_text())["step"]
    assert main(["train", "salad", *TINY, "--steps", "2000", "--resume", "--out", str(run)]) == 0
    assert main(["report", str(run)]) == 0
    last = int((run / "metrics.csv").read_text().splitlines()[-1].split(",")[0])
    assert json.loads((run / "video.json").read_text())["step"] == last > first


def test_report_of_a_directory_that_is_neither_says_what_it_takes(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("hello")
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "neither an experiment's results" in err and "ecorl train run directory" in err
    # a folder of runs (or the repository's docs/): the runs deeper inside are named
    for name in ("run-a", "run-b"):
        (tmp_path / "runs" / name).mkdir(parents=True)
        (tmp_path / "runs" / name / "config.json").write_text("{}")
        (tmp_path / "runs" / name / "metrics.csv").write_text("")
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"report one of those deeper inside it: {tmp_path / 'runs' / 'run-a'}, {tmp_path / 'runs' / 'run-b'}" in err


def test_redrawing_a_shipped_result_is_byte_stable_and_leaves_it_alone(tmp_path):
    shipped = REFERENCE_DIR / "headline"
    before = _digests(shipped)
    first, second = tmp_path / "a", tmp_path / "b"
    make_report(shipped, videos=False, out=first)
    make_report(shipped, videos=False, out=second)
    assert _digests(first) == _digests(second) and _digests(first)
    assert _digests(shipped) == before
    for text in ((first / "index.html").read_text(), (first / "report.md").read_text()):
        assert str(tmp_path) not in text and str(Path.cwd()) not in text and "/home/" not in text


def test_two_directories_of_one_experiment_keep_their_own_figures(tmp_path):
    results = tmp_path / "results"
    for name in ("headline-waypoint", "headline-waypoint-1m"):  # the same experiment twice, as when one is continued
        shutil.copytree(REFERENCE_DIR / "headline-waypoint", results / name,
                        ignore=shutil.ignore_patterns("figures", "*.html", "*.md"))
    out = tmp_path / "report"
    make_report(results, videos=False, out=out)
    figures = sorted(p.name for p in (out / "figures").glob("headline*_curves.png"))
    assert figures == ["headline-waypoint-1m_curves.png", "headline-waypoint_curves.png"]
    page = (out / "report.md").read_text()
    assert all(f"figures/{name}" in page for name in figures)


def test_a_shipped_result_is_redrawn_outside_the_tracked_folder():
    assert default_out(REFERENCE_DIR / "headline") == Path("results") / "report" / "headline"
    assert default_out(Path("somewhere") / "results").name == "results"


def test_one_colour_per_condition_everywhere():
    assert len(set(CONDITION_COLORS.values())) == len(CONDITION_COLORS)
    assert condition_color("dynamic-reset-free") == CONDITION_COLORS["dynamic-reset-free"]
    assert condition_color("rf-lr3e-4") == condition_color("rf-lr3e-4")


def test_no_two_conditions_of_a_report_share_a_colour():
    names = [c.name for c in EXPERIMENTS["settings"].conditions["salad"]]  # nine, hashed to seven colours
    assert len(names) <= len(OTHER_COLORS)
    colors = condition_colors(names + ["dynamic-episodic"])
    assert len(set(colors.values())) == len(names) + 1
    assert colors["dynamic-episodic"] == CONDITION_COLORS["dynamic-episodic"]
    assert colors == condition_colors(reversed(names + ["dynamic-episodic"]))  # the order given does not matter
    alone = {n: condition_color(n) for n in names}
    assert sum(colors[n] == alone[n] for n in names) >= len(set(alone.values()))  # the first of each hash keeps it


@pytest.mark.parametrize("name", ["headline", "headline-waypoint"])
def test_a_headline_page_leads_with_the_shipped_paper_budget_panels(tmp_path, name):
    import json

    from train.experiments.catalog import get_experiment
    from train.storage.rundir import EXPERIMENT_FILE

    exp = get_experiment(name)
    root = tmp_path / "results" / name
    root.mkdir(parents=True)
    (root / EXPERIMENT_FILE).write_text(json.dumps({**exp.describe(), "budget": "quick"}))
    run = root / "salad" / "static-reset-free"
    run.mkdir(parents=True)
    (run / "metrics.csv").write_text("step,seed,epsilon,loss,success,return,train_reward,steps_per_s\n"
                                     "5000,0,1,0,0.0,0,0,1\n5000,1,1,0,0.1,0,0,1\n")
    make_report(root, videos=False)
    md = (root / "report.md").read_text()
    assert md.index("At the paper's budget") < md.index(f"## {name} (")
    other = "headline-waypoint" if name == "headline" else "headline"
    assert md.index(f"### {name}:") < md.index(f"### {other}:")  # the page's own experiment first
    assert "static non-episodic: 0.3% [0.0, 0.6], 0 / 10 seeds learned (paper ≈ 0%)" in md  # sparse headline
    assert (root / "figures" / "shipped_headline_curves.png").exists()  # one live condition: no contrast drawn


def test_the_demo_page_draws_the_live_contrast_on_its_shipped_runs_and_says_if_it_separates(tmp_path):
    import json

    from train.experiments.catalog import get_experiment
    from train.experiments.report.lead import run_summary
    from train.storage.rundir import EXPERIMENT_FILE

    exp = get_experiment("headline-waypoint")
    root = tmp_path / "results" / exp.name
    (root).mkdir(parents=True)
    (root / EXPERIMENT_FILE).write_text(json.dumps({**exp.describe(), "budget": "quick"}))
    header = "step,seed,epsilon,loss,success,return,train_reward,steps_per_s\n"
    for condition, values in (("static-reset-free", (0.0, 0.01, 0.0)), ("dynamic-reset-free", (0.0, 0.3, 0.05))):
        run = root / "salad" / condition
        run.mkdir(parents=True)
        (run / "metrics.csv").write_text(header + "".join(f"50000,{k},0.5,0,{v},0,0,1\n"
                                                          for k, v in enumerate(values)))
    make_report(root, videos=False)
    md = (root / "report.md").read_text()
    first_image = md[md.index("!["):].split("(", 1)[1].split(")", 1)[0]
    assert first_image == "figures/live_vs_shipped_headline-waypoint.png" and (root / first_image).exists()
    summary = run_summary(root)
    assert "  At 50,000 steps the intervals overlap: this run cannot tell the two apart yet." in summary
    sentence = "At 50,000 steps the intervals overlap: this run cannot tell the two apart yet."
    assert f"**{sentence}**" in md and sentence in (root / "index.html").read_text()  # the page says it too
    assert any("the decisive runs: docs/results/paper/headline-waypoint" in line for line in summary)


def test_a_demo_page_without_the_shipped_runs_says_where_they_are(tmp_path, monkeypatch):
    """A pip installation carries no docs/results/paper: the page and the terminal say so instead of dropping
    the lead in silence.
    """
    import json

    from train.experiments.catalog import get_experiment
    from train.experiments.report import runs
    from train.experiments.report.lead import run_summary
    from train.storage.rundir import EXPERIMENT_FILE

    exp = get_experiment("headline-waypoint")
    root = tmp_path / "results" / exp.name
    run = root / "salad" / "static-reset-free"
    run.mkdir(parents=True)
    (root / EXPERIMENT_FILE).write_text(json.dumps({**exp.describe(), "budget": "quick"}))
    (run / "metrics.csv").write_text("step,seed,epsilon,loss,success,return,train_reward,steps_per_s\n"
                                     "50000,0,0.5,0,0.0,0,0,1\n")
    monkeypatch.setattr(runs, "REFERENCE_DIR", tmp_path / "site-packages" / "docs" / "results" / "paper")
    make_report(root, videos=False)
    note = "come with the source repository, not with a pip installation"
    assert note in (root / "report.md").read_text() and note in (root / "index.html").read_text()
    assert note in run_summary(root)[-1]


def test_videos_are_h264_padded_to_even_sizes_and_byte_stable(tmp_path):
    import cv2
    import numpy as np

    from train.experiments.video import write_h264

    frames = [np.full((33, 41, 3), 7 * i, np.uint8) for i in range(12)]
    a, b = write_h264(frames, tmp_path / "a.mp4", fps=8), write_h264(frames, tmp_path / "b.mp4", fps=8)
    assert a.read_bytes() == b.read_bytes() and b"avc1" in a.read_bytes()[:4096]
    cap = cv2.VideoCapture(str(a))
    ok, frame = cap.read()
    cap.release()
    assert ok and frame.shape[:2] == (34, 42)
    with pytest.raises(ValueError, match="frame of size"):
        write_h264([frames[0], np.zeros((10, 10, 3), np.uint8)], tmp_path / "c.mp4")
    assert not (tmp_path / "c.mp4").exists()


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs a directory no one may write: /proc")
def test_a_video_that_cannot_be_written_is_refused_by_name_before_ffmpeg_starts():
    import numpy as np

    from train.experiments.video import write_h264

    with pytest.raises(OSError, match="cannot write /proc/x.mp4: .*; choose a writable location"):
        write_h264([np.zeros((8, 8, 3), np.uint8)], "/proc/x.mp4")


def test_a_shipped_run_is_filmed_from_its_best_policy_file_whatever_the_best_seeds_index(tmp_path):
    import json

    from train.experiments.report.runs import read_run
    from train.experiments.report.webvideo import film_best_seed

    shipped = REFERENCE_DIR / "hunting-gap" / "hunting" / "rf-lr3e-4"  # its best seed is seed 7 (47 %)
    run = read_run(shipped, "hunting", "rf-lr3e-4", "lr 3e-4")
    film_best_seed(run, tmp_path / "video.mp4", shipped / "policies" / "best.npz")
    assert json.loads((tmp_path / "video.json").read_text())["seed"] == 7
    assert (tmp_path / "video.mp4").stat().st_size > 1000 and (tmp_path / "filmstrip.png").exists()


def test_the_end_of_run_summary_names_the_task_when_a_folder_holds_several():
    import json

    from train.experiments.report.lead import run_summary
    from train.storage.rundir import EXPERIMENT_FILE

    several = run_summary(REFERENCE_DIR / "dynamism")  # every task shipped so far, factory among them
    one = run_summary(REFERENCE_DIR / "headline")  # salad alone
    shipped = json.loads((REFERENCE_DIR / "dynamism" / EXPERIMENT_FILE).read_text())["tasks_run"]
    assert len(shipped) > 1
    assert all(line.startswith(tuple(f"  {task}, " for task in shipped))
               for line in several[1:] if line.startswith("  "))
    assert all(any(line.startswith(f"  {task}, ") for line in several) for task in shipped)
    assert sum(line.startswith("  factory, static, non-episodic: ") for line in several) == 1
    assert [line for line in one if line.startswith("  ")]
    assert not any(line.startswith("  salad, ") for line in one)


def test_a_report_neither_hangs_on_a_fifo_nor_leaks_a_linked_strip_nor_decodes_huge_frames(tmp_path, capsys):
    import os

    import numpy as np

    from train.experiments.report.webvideo import find_videos, web_copy
    from train.experiments.video import write_h264

    tree = tmp_path / "tree"
    run = tree / "exp" / "salad" / "run"
    run.mkdir(parents=True)
    write_h264([np.full((40, 40, 3), i, np.uint8) for i in range(10)], run / "video.mp4")
    secret = tmp_path / "secret.txt"
    secret.write_text("not for the report")
    (run / "filmstrip.png").symlink_to(secret)  # planted beside a real film
    os.mkfifo(tree / "exp" / "hang.mp4")  # OpenCV would block on it forever
    (tree / "linked").symlink_to(run, target_is_directory=True)  # not descended into
    (tree / "exp" / "alias.mp4").symlink_to(secret)  # a video that is a link to any file
    found = find_videos(tree)
    assert found == [run / "video.mp4"]  # the FIFO, the link and what lies behind the linked folder are skipped
    err = capsys.readouterr().err
    assert "hang.mp4 is a FIFO" in err and "alias.mp4 is a symbolic link" in err
    web = web_copy(found[0], tmp_path / "out", "v", "caption", found[0])
    assert web is not None and web.strip is None and not list((tmp_path / "out").glob("*strip*"))
    assert "filmstrip.png is a symbolic link" in capsys.readouterr().err
    big = tmp_path / "big.mp4"
    write_h264([np.zeros((1400, 60, 3), np.uint8)] * 2, big)
    with pytest.raises(ValueError, match="more than ecorl's films"):
        web_copy(big, tmp_path / "out", "b", "caption")


def test_a_long_video_is_refused_at_the_pixel_budget_not_re_encoded_for_minutes(tmp_path, monkeypatch):
    import numpy as np

    import train.experiments.report.webvideo as webvideo
    from train.experiments.video import write_h264

    long = tmp_path / "long.mp4"
    write_h264([np.zeros((40, 40, 3), np.uint8)] * 30, long)
    monkeypatch.setattr(webvideo, "MAX_PIXELS_READ", 20 * 40 * 40)  # stands for 400 million: 20 of these frames
    with pytest.raises(ValueError, match="more than 32,000 pixels of frames .21 frames of 40x40"):
        webvideo.web_copy(long, tmp_path / "out", "l", "caption")
    assert not list((tmp_path / "out").glob("*.mp4"))  # no half-written copy
    monkeypatch.setattr(webvideo, "MAX_PIXELS_READ", 30 * 40 * 40)
    assert webvideo.web_copy(long, tmp_path / "out", "l", "caption") is not None


def test_labels_at_one_place_are_moved_apart_and_the_first_keeps_its_own():
    """The demo's first figure drew a live run's label (ending at 400 000 of 1 M steps) over the shipped run's."""
    from train.experiments.report.figures import pyplot
    from train.experiments.report.lead import keep_apart

    fig, ax = pyplot().subplots(figsize=(6, 3), layout="constrained")
    labels = [ax.annotate(text, (0.5, 0.5), xytext=(8, 0), textcoords="offset points", va="center",
                          bbox=dict(boxstyle="round")) for text in ("shipped: 51.3%", "live: 47.3%", "other: 0.3%")]
    keep_apart(fig, labels)
    renderer = fig.canvas.get_renderer()
    boxes = [label.get_tightbbox(renderer) for label in labels]
    assert labels[0].xyann == (8, 0)
    assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])
    assert labels[1].xyann[1] > 0 > labels[2].xyann[1]  # one line up, then one line down
