"""The subcommands: parsers, ``measure``, ``video``, ``run --list/--dry-run``, and their wiring into ``ecorl``."""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import cv2
import numpy as np
import pytest

from train import cli


def _frames(path) -> int:
    cap = cv2.VideoCapture(str(path))
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    cap.release()
    return n


def test_parsers_attach_to_any_subparsers():
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="command", required=True)
    for command in cli.COMMANDS:
        command.add_parser(sub)
    args = parser.parse_args(["run", "dynamism", "--task", "salad", "hunting", "--budget", "smoke", "--jobs", "3"])
    assert (args.experiment, args.task, args.budget, args.jobs, args.executor) == (["dynamism"], ["salad", "hunting"],
                                                                                   "smoke", 3, "local")
    args = parser.parse_args(["measure", "entropy", "--task", "all"])
    assert (args.measurement, args.task, args.seeds, args.steps) == ("entropy", "all", 25, 50_000)
    args = parser.parse_args(["video", "salad", "--random", "--steps", "5"])
    assert args.random and args.steps == 5 and args.handler is cli.video.handle
    with pytest.raises(SystemExit):
        parser.parse_args(["video", "salad", "--random", "--policy", "x"])
    with pytest.raises(SystemExit):  # --steps used to win silently, the summary then naming one episode
        parser.parse_args(["video", "salad", "--random", "--steps", "5", "--episodes", "2"])


def test_every_whole_number_flag_reads_powers_of_ten_as_the_docs_promise():
    plain = [f"ecorl {name} {action.option_strings[0]}"
             for name, sub in cli.build_parser()._subparsers._group_actions[0].choices.items()
             for action in sub._actions if action.type is int]
    assert not plain, f"argparse's int refuses 1e6: {plain}"
    args = cli.build_parser().parse_args(["evaluate", "policy.npz", "--fresh", "1e3", "--agent", "0e0"])
    assert (args.fresh, args.agent) == (1000, 0)


def test_ecorl_cli_has_the_subcommands_once_wired():
    parser = cli.build_parser()
    names = set(parser._subparsers._group_actions[0].choices)
    assert {"run", "report", "measure", "video"} <= names


def test_a_bare_ecorl_shows_the_commands_and_version_names_the_package(capsys):
    assert cli.main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: ecorl") and all(name in out for name in ("train", "run", "report", "evaluate"))
    with pytest.raises(SystemExit) as stop:
        cli.main(["--version"])
    assert stop.value.code == 0 and capsys.readouterr().out.startswith("ecorl ")


def test_run_list_and_dry_run(capsys, tmp_path):
    assert cli.main(["run", "--list"]) == 0
    out = capsys.readouterr().out
    assert "headline (Fig. 4 (salad panel))" in out and "paper  20 runs x 10 seeds" in out
    assert cli.main(["run", "hunting-inventory", "--list"]) == 0  # only those named
    out = capsys.readouterr().out
    assert out.startswith("hunting-inventory (") and "headline" not in out
    assert cli.main(["run", "shaping", "--task", "foodcollector", "--budget", "paper", "--dry-run",
                          "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and all(line.startswith("[   new] shaping/foodcollector/") for line in out)
    assert "10 seeds x 1250200 steps" in out[0] and "shaping=linear:1:0:280000" in out[0]
    assert not (tmp_path / "shaping").exists()
    with pytest.raises(SystemExit):
        cli.main(["run", "rnd", "--task", "salad"])


def test_dry_run_names_the_settings_that_tell_two_conditions_apart(capsys, tmp_path):
    assert cli.main(["run", "factory-make-axe", "--budget", "paper", "--condition", "dynamic-reset-free",
                     "dynamic-reset-free-inv8", "--dry-run", "--out", str(tmp_path)]) == 0
    lines = dict(line.split(": ", 1) for line in capsys.readouterr().out.splitlines())
    plain, inv8 = lines["[   new] factory-make-axe/factory/dynamic-reset-free"], \
        lines["[   new] factory-make-axe/factory/dynamic-reset-free-inv8"]
    assert plain.endswith("reward=sparse, goal=make_axe") and inv8.endswith("goal=make_axe, inventory_repeat=8")
    assert cli.main(["run", "headline", "--budget", "paper", "--condition", "dynamic-episodic", "--dry-run",
                     "--out", str(tmp_path)]) == 0
    assert "lr=0.0003" in capsys.readouterr().out  # salad's tuned rate, beside the default 1e-4
    assert cli.main(["run", "hunting-released-fig4", "--budget", "paper", "--dry-run", "--out", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert all(("horizon=100" in line) == (", episodic," in line) for line in lines)  # only an episode ends by it
    assert any("horizon=100" in line for line in lines)


def test_dry_run_shows_the_packs_and_the_seed_range(capsys, tmp_path):
    both = ["run", "factory-make-axe", "--budget", "paper", "--condition", "static-reset-free", "static-episodic",
            "--dry-run", "--out", str(tmp_path)]
    assert cli.main(both + ["--pack", "--jobs", "1", "--first-seed", "10"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1] == ("[  pack] factory-make-axe/factory/[static-episodic, static-reset-free]: trained as one "
                         "process, 20 seeds")
    assert all(line.endswith(", seeds 10-19") for line in lines[:-1]) and len(lines) == 3
    assert cli.main(both) == 0
    assert "[  pack]" not in capsys.readouterr().out  # without --pack, one process per condition
    assert cli.main(["run", "headline", "headline-waypoint", "--budget", "smoke", "--task", "salad", "--condition",
                     "static-reset-free", "--pack", "--jobs", "1", "--dry-run", "--out", str(tmp_path)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == ("[  pack] salad/[headline/static-reset-free, "
                                                        "headline-waypoint/static-reset-free]: trained as one "
                                                        "process, 4 seeds")


def test_run_all_plans_every_training_experiment_and_each_copy_once(capsys, tmp_path):
    assert cli.main(["run", "--all", "--budget", "paper", "--task", "salad", "--dry-run", "--out", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    copies = [line for line in lines if line.startswith("[  copy]")]
    assert "[  copy] dynamism-sweep/salad/p0: the same run as headline/salad/static-reset-free, copied when it " \
           "finishes" in copies
    trained = [line.split("]")[1].split(":")[0].strip() for line in lines if not line.startswith("[  copy]")]
    assert len(trained) == len(set(trained)) and "headline/salad/static-reset-free" in trained
    assert not any(name.startswith("measure/") for name in trained)  # Table 1 measures, it trains nothing
    with pytest.raises(SystemExit):
        cli.main(["run", "headline", "shaping", "--minutes", "5", "--out", str(tmp_path)])
    assert "--minutes applies to one experiment" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["run", "headline", "--all", "--out", str(tmp_path)])
    assert "--all runs every experiment that trains; drop the names" in capsys.readouterr().err


def test_a_dry_run_says_whether_a_copy_is_there_or_copied_at_once(capsys):
    shipped = str(Path(__file__).resolve().parents[3] / "docs" / "results" / "paper")
    assert cli.main(["run", "headline", "dynamism-sweep", "dynamism", "--budget", "paper", "--task", "salad",
                     "--condition", "static-reset-free", "p0", "--dry-run", "--out", shipped]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "[  done] dynamism-sweep/salad/p0: the same run as headline/salad/static-reset-free, copied" in lines
    assert ("[  copy] dynamism/salad/static-reset-free: the same run as headline/salad/static-reset-free, finished: "
            "copied by this command") in lines


def test_one_experiment_copies_a_finished_run_of_another_with_the_same_settings(capsys, tmp_path):
    """`dynamism`'s static non-episodic salad is `headline`'s: run after it into the same --out, it is copied, not
    trained again (the speed column would differ), and a condition with files of its own is left to train.
    """
    one = ["--budget", "smoke", "--task", "salad", "--condition", "static-reset-free", "--out", str(tmp_path),
           "--no-progress"]
    assert cli.main(["run", "headline", *one]) == 0
    capsys.readouterr()
    assert cli.main(["run", "dynamism", *one, "--dry-run"]) == 0
    assert capsys.readouterr().out.startswith("[  copy] dynamism/salad/static-reset-free: the same run as "
                                              "headline/salad/static-reset-free, finished: copied by this command")
    assert cli.main(["run", "dynamism", *one]) == 0
    assert "dynamism/salad/static-reset-free: the same run as headline/salad/static-reset-free, copied" in \
        capsys.readouterr().err
    original, copy = (tmp_path / name / "salad" / "static-reset-free" for name in ("headline", "dynamism"))
    assert (copy / "metrics.csv").read_bytes() == (original / "metrics.csv").read_bytes()
    assert (copy / "done.json").is_file() and not list(copy.glob("checkpoint.*"))
    assert cli.main(["run", "episodic-vs-reset-free", *one[:-1], "--restart", "static-reset-free", "--dry-run"]) == 0
    assert capsys.readouterr().out.startswith("[restart] episodic-vs-reset-free/salad/static-reset-free")
    own = tmp_path / "episodic-vs-reset-free" / "salad" / "static-reset-free"
    own.mkdir(parents=True)
    (own / "notes.txt").write_text("mine")
    # a folder with the user's own file is not filled with a copy: planned as its own run, which cannot start there
    assert cli.main(["run", "episodic-vs-reset-free", *one, "--dry-run"]) == 1
    out = capsys.readouterr().out
    assert out.startswith("[ clash] episodic-vs-reset-free/salad/static-reset-free") and "(notes.txt)" in out


@pytest.mark.parametrize("bad", ["-1", "0", "nan", "inf"])
def test_run_refuses_a_time_budget_that_is_no_time(bad, capsys, tmp_path):
    with pytest.raises(SystemExit):
        cli.main(["run", "headline", "--minutes", bad, "--dry-run", "--out", str(tmp_path)])
    assert f"expected a number of minutes > 0, got {bad}" in capsys.readouterr().err


def test_measure_writes_tables(capsys, tmp_path):
    assert cli.main(["measure", "hitting-time", "--task", "salad", "--seeds", "3", "--steps", "300",
                          "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "static non-episodic" in out and "shaped non-episodic" in out and "±" in out
    with open(tmp_path / "hitting-time_salad.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["condition"] for r in rows] == ["static non-episodic", "dynamic non-episodic", "shaped non-episodic"]
    assert all(int(r["seeds"]) == 3 and 0 < float(r["mean"]) <= 300 for r in rows)
    assert "| static non-episodic |" in (tmp_path / "hitting-time_salad.md").read_text()


def test_measure_all_tasks(tmp_path, capsys):
    assert cli.main(["measure", "entropy", "--task", "all", "--seeds", "2", "--steps", "50",
                          "--out", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.glob("*.csv")) == sorted(
        f"entropy_{t}.csv" for t in ("salad", "hunting", "scavenging", "factory", "walled-salad"))


def test_random_video(tmp_path, capsys):
    out = tmp_path / "hunt.mp4"
    assert cli.main(["video", "hunting", "--random", "--steps", "12", "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    assert _frames(out) >= 13


class _CountingEnv:
    """Episodes of ``length`` steps, solved when the action was 1 on the last step; frames number the steps."""

    def __init__(self, length: int) -> None:
        self.length, self.t, self.resets = length, 0, 0

    def reset(self, seed=None):
        self.t, self.resets = 0, self.resets + 1
        return 0, {}

    def step(self, action):
        self.t += 1
        end = self.t == self.length
        return 0, 0.0, end, False, {"solved": end and action == 1}

    def render(self):
        return np.full((2, 2, 3), self.t, np.uint8)


def test_film_counts_whole_episodes_and_solved_ones():
    from train.experiments.video import film_rollout

    actions = iter([0, 0, 1, 0, 0, 0, 0, 0, 1])
    film = film_rollout(_CountingEnv(3), lambda obs: next(actions), seed=0, episodes=3)
    assert (film.episodes, film.solved) == (3, 2)
    assert len(film.frames) == 1 + 3 * 3 + 2  # first reset, 9 steps, two resets between episodes
    assert film.first_episode == 4  # its reset frame and three steps
    assert (film.ended, film.steps) == (3, 9)
    film = film_rollout(_CountingEnv(3), lambda obs: 1, seed=0, steps=4)
    assert (film.episodes, film.ended, film.solved, len(film.frames)) == (2, 1, 1, 1 + 4 + 1)
    assert film.first_episode == 4
    assert film_rollout(_CountingEnv(9), lambda obs: 1, seed=0, steps=5).first_episode == 6  # cut short


def test_a_film_cut_inside_an_episode_does_not_count_the_part_as_an_episode():
    from train.experiments.video import Video

    cut = Video(Path("v.mp4"), episodes=2, solved=1, total_return=1.0, metric="success", ended=1, steps=4)
    assert cut.summary() == "1 solve(s) in the 4 steps filmed (1 whole episode(s) and part of one more)"
    first = Video(Path("v.mp4"), episodes=1, solved=0, total_return=2.5, metric="return", ended=0, steps=40)
    assert first.summary() == "return 2.5 over the 40 steps filmed (part of one episode)"
    whole = Video(Path("v.mp4"), episodes=3, solved=2, total_return=0.0, metric="success", ended=3, steps=9)
    assert whole.summary() == "solved 2 of the 3 episode(s) filmed"


@pytest.mark.parametrize(("max_frames", "episodes", "frames"), [(1, 1, 4), (4, 1, 4), (5, 2, 8), (9, 3, 12)])
def test_a_film_starts_no_episode_past_its_frame_budget(max_frames, episodes, frames):
    from train.experiments.video import film_rollout

    film = film_rollout(_CountingEnv(3), lambda obs: 0, seed=0, episodes=3, max_frames=max_frames)
    assert (film.episodes, len(film.frames)) == (episodes, frames)  # the first episode whole, however long


def test_a_default_film_keeps_to_the_frame_budget_and_asked_episodes_do_not(monkeypatch, tmp_path, capsys):
    from foodcollector.params import UNITY_EPISODE_DECISIONS
    from train.experiments import video

    assert UNITY_EPISODE_DECISIONS + 1 >= video.VIDEO_MAX_FRAMES  # a food-collector film is one episode
    assert video.VIDEO_MAX_FRAMES > 2 * (200 + 1)  # three episodes of a grid task with horizon 200
    asked = []

    def fake_record(task, out, **kwargs):
        asked.append((kwargs["episodes"], kwargs["max_frames"]))
        return video.Video(Path(out), 1, 0, 0.0, "return")

    monkeypatch.setattr(video, "record_video", fake_record)
    for extra in ([], ["--episodes", "5"]):
        assert cli.main(["video", "foodcollector", "--random", "--out", str(tmp_path / "fc.mp4"), *extra]) == 0
    assert asked == [(video.VIDEO_EPISODES, video.VIDEO_MAX_FRAMES), (5, None)]


def test_a_filmstrip_shows_an_episode_frame_by_frame(tmp_path):
    import cv2

    from train.experiments.video import STRIP_HEIGHT, write_filmstrip

    frames = [np.full((10, 20, 3), 20 * t % 256, np.uint8) for t in range(30)]
    strip = cv2.imread(str(write_filmstrip(frames[:4], tmp_path / "short.png")))
    tile = 2 * STRIP_HEIGHT + 4  # frames twice as wide as high, a border of 2 on each side
    assert strip.shape == (STRIP_HEIGHT + 22, 4 * tile, 3)  # all four frames of a short episode
    strip = cv2.imread(str(write_filmstrip(frames, tmp_path / "long.png", count=5)))
    assert strip.shape[1] == 5 * tile  # five evenly spaced frames: t = 0, 7, 14, 22, 29
    shades = [int(strip[STRIP_HEIGHT, i * tile + tile // 2, 0]) for i in range(5)]
    assert shades == [20 * t % 256 for t in (0, 7, 14, 22, 29)]
    with pytest.raises(ValueError, match="no frames"):
        write_filmstrip([], tmp_path / "none.png")


def test_run_condition_subset(capsys, tmp_path):
    assert cli.main(["run", "headline", "--budget", "paper", "--dry-run", "--out", str(tmp_path),
                     "--condition", "dynamic-reset-free", "static-episodic"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line.split()[2].rstrip(":") for line in out] == [
        "headline/salad/static-episodic", "headline/salad/dynamic-reset-free"]  # panel order, not argument order
    with pytest.raises(SystemExit):
        cli.main(["run", "headline", "--condition", "dynamic", "--dry-run", "--out", str(tmp_path)])
    assert "unknown headline/salad condition 'dynamic'; choose one of static-episodic" in capsys.readouterr().err
    assert cli.main(["run", "headline", "--dry-run", "--out", str(tmp_path), "--condition", "dynamic-reset-free",
                     "--condition", "static-episodic"]) == 0  # a repeated flag adds its names, as one does
    assert len(capsys.readouterr().out.splitlines()) == 2


@pytest.mark.parametrize(("argv", "said"), [
    (["headline", "--condition", "dynamic-non-episodic"], "did you mean dynamic-reset-free?"),  # the paper's word
    (["headline", "--condition", "Static-Reset-Free"], "did you mean static-reset-free?"),
    (["headline", "dynamism", "--condition", "dynamic-resetfree"],
     "unknown condition 'dynamic-resetfree'; did you mean dynamic-reset-free?"),
    (["headline", "dynamism", "--task", "salid"], "unknown task 'salid'; did you mean salad?"),
    (["headline", "--address", "auto"], "--address names a Ray cluster and applies only with --executor ray"),
    (["headline", "--steps", "100"], "its 200-step warm-up takes all 100 steps; give --steps above 200")])
def test_run_refuses_a_mistake_in_one_line_that_names_the_fix(argv, said, capsys, tmp_path):
    with pytest.raises(SystemExit) as stop:
        cli.main(["run", *argv, "--dry-run", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert stop.value.code == 2 and len(err.splitlines()) == 1 and said in err, err
    assert "--warmup-steps" not in err  # a flag ecorl run does not have


def test_an_unfinished_sweep_names_each_run_and_why():
    from train.cli.run import _unfinished_message
    from train.experiments.jobs import JobResult

    message = _unfinished_message([
        JobResult("salad/a", "failed", 1.0, "disk full"),
        JobResult("salad/b", "interrupted"),
        JobResult("salad/c", "failed", 1.0, "run x is in use by another ecorl process (pid 7); wait"),
    ])
    assert "\n" not in message
    assert "1 failed (salad/a; their errors are above)" in message
    assert "1 stopped at a checkpoint (salad/b)" in message
    assert "1 trained by another ecorl process (salad/c; it may finish them)" in message



@pytest.mark.parametrize(("statuses", "code"), [(("interrupted", "done"), 130), (("interrupted", "failed"), 1),
                                                (("interrupted", "kept"), 1)])
def test_a_sweep_its_workers_stopped_exits_as_after_ctrl_c(statuses, code, monkeypatch, tmp_path, capsys):
    """A Ctrl-C reaches the workers, which stop at a checkpoint; when the sweep's own process took it as no
    KeyboardInterrupt, it used to exit 1 ("runs: 4 interrupted") instead of 130. A failure still exits 1.
    """
    import train.experiments.sweep as sweep
    from train.experiments.jobs import JobResult

    def results(jobs, *args):
        return [JobResult(job.name, status, 1.0, "why") for job, status in zip(jobs, statuses)]

    monkeypatch.setattr(sweep, "run_jobs", results)
    assert cli.main(["run", "headline", "--budget", "smoke", "--out", str(tmp_path), "--no-progress",
                     "--condition", "static-episodic", "dynamic-reset-free"]) == code
    assert "re-run" in capsys.readouterr().err

@pytest.mark.parametrize("name, message", [("films", "is a directory; give the file to write, e.g. --out "),
                                           ("film.gif", "writes an H.264 MP4; give a file name ending in .mp4")])
def test_video_out_must_name_an_mp4_file(name, message, tmp_path, capsys):
    """A directory used to fail after rendering with a temporary file's name ([Errno 21] ... '.films.ecorl-tmp-...'),
    and film.gif silently received an MP4.
    """
    (tmp_path / "films").mkdir()
    assert cli.main(["video", "salad", "--random", "--steps", "2", "--out", str(tmp_path / name)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["films"] and not any((tmp_path / "films").iterdir())


def test_dry_run_says_which_runs_clash_with_the_settings_asked_for(capsys, tmp_path):
    """A run directory made with other settings used to be planned as [resume], then the run failed."""
    import json

    from train.experiments.catalog import get_experiment
    from train.experiments.sweep import plan

    job = plan(get_experiment("headline"), "smoke", tmp_path, conditions=["static-episodic"])[0]
    run_dir = tmp_path / "headline" / "salad" / "static-episodic"
    run_dir.mkdir(parents=True)
    (run_dir / "config.json").write_text(json.dumps(job.config))
    args = ["run", "headline", "--budget", "smoke", "--condition", "static-episodic", "--dry-run", "--out",
            str(tmp_path)]
    assert cli.main(args) == 0
    assert capsys.readouterr().out.startswith("[   new] headline/salad/static-episodic")
    assert cli.main([*args, "--first-seed", "3"]) == 1  # a run that will fail: the dry run says so, and fails
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("[ clash] headline/salad/static-episodic")
    assert "first_seed: checkpoint has 0, you asked for 3" in out[1] and "--restart static-episodic" in out[1]


def test_dry_run_plans_every_run_when_a_finished_one_clashes_with_the_seeds_asked_for(capsys, tmp_path):
    """A finished run of 2 seeds and --seeds 3: the dry run used to stop with that run's error and plan nothing."""
    import json

    from train.experiments.catalog import get_experiment
    from train.experiments.sweep import plan

    job = plan(get_experiment("headline"), "smoke", tmp_path, conditions=["static-episodic"])[0]
    run_dir = tmp_path / "headline" / "salad" / "static-episodic"
    run_dir.mkdir(parents=True)
    (run_dir / "config.json").write_text(json.dumps(job.config))
    (run_dir / "done.json").write_text(json.dumps({"total_steps": 10**9, "seeds": 2}))
    assert cli.main(["run", "headline", "--budget", "smoke", "--seeds", "3", "--dry-run", "--out", str(tmp_path)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("[ clash] headline/salad/static-episodic") and "seeds: checkpoint has 2" in out[1]
    assert [line.split("]")[0] for line in out[2:]] == ["[   new"] * 3  # the other three conditions


def test_dry_run_says_a_folder_holding_foreign_files_will_fail(capsys, tmp_path):
    """Planned as [new] before, and the run then failed: ecorl never deletes files it did not write."""
    run_dir = tmp_path / "headline" / "salad" / "static-episodic"
    run_dir.mkdir(parents=True)
    (run_dir / "notes.txt").write_text("mine")
    args = ["run", "headline", "--budget", "smoke", "--condition", "static-episodic", "--dry-run", "--out",
            str(tmp_path)]
    assert cli.main(args) == 1
    captured = capsys.readouterr()
    out = captured.out.splitlines()
    assert out[0].startswith("[ clash] headline/salad/static-episodic")
    assert "holds files ecorl did not write (notes.txt)" in out[1]
    assert "1 run(s) will fail" in captured.err
    assert cli.main([*args, "--restart", "static-episodic"]) == 1  # a restart deletes only what ecorl wrote


def test_a_finished_run_is_done_whatever_else_its_folder_holds(capsys, tmp_path):
    """A shipped run (no checkpoint; the report's film beside it, a note of the user's) was planned as a clash, as
    if it would start afresh; under a restart only the user's file is foreign (the film is the run's, cleared with it).
    """
    import json

    from train.experiments.catalog import get_experiment
    from train.experiments.sweep import plan
    from train.storage.rundir import FILM_FILES

    job = plan(get_experiment("headline"), "smoke", tmp_path, conditions=["static-episodic"])[0]
    run_dir = tmp_path / "headline" / "salad" / "static-episodic"
    run_dir.mkdir(parents=True)
    (run_dir / "config.json").write_text(json.dumps(job.config))
    (run_dir / "done.json").write_text(json.dumps({"total_steps": 10**9, "seeds": job.config["run"]["seeds"]}))
    for name in (*FILM_FILES, "notes.txt"):
        (run_dir / name).write_text("")
    args = ["run", "headline", "--budget", "smoke", "--condition", "static-episodic", "--dry-run", "--out",
            str(tmp_path)]
    assert cli.main(args) == 0
    assert capsys.readouterr().out.startswith("[  done] headline/salad/static-episodic")
    assert cli.main([*args, "--restart", "static-episodic"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("[ clash]") and "holds files ecorl did not write (notes.txt)" in out[1]


def test_dry_run_says_a_stopped_run_past_the_steps_asked_for_will_fail(capsys, tmp_path):
    """A run stopped at step 5 700 was planned as [resume] for --steps 1000; the run then failed ('stands at step')."""
    args = ["run", "headline", "--budget", "smoke", "--condition", "static-episodic", "--no-progress", "--out",
            str(tmp_path)]
    assert cli.main([*args, "--steps", "2000"]) == 0
    (tmp_path / "headline" / "salad" / "static-episodic" / "done.json").unlink()  # as if stopped at its last epoch
    capsys.readouterr()
    assert cli.main([*args, "--steps", "1000", "--dry-run"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("[ clash] headline/salad/static-episodic")
    assert "stands at step 2200, beyond the 1200 steps asked for" in out[1]


def test_local_processes_default_to_the_cpus_this_process_may_use(monkeypatch):
    """A cluster job or container pinned to 4 of a node's 64 cores runs 4 local processes, not 64."""
    import os

    from train.cli.run import _packing
    from train.experiments import executors

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2, 3}, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    assert executors.usable_cpus() == 4
    args = argparse.Namespace(device=None, jobs=None, pack=True)
    assert _packing(args) == 4 and _packing(argparse.Namespace(device=None, jobs=2, pack=True)) == 2
    monkeypatch.delattr(os, "sched_getaffinity")
    assert executors.usable_cpus() == 64
