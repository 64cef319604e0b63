"""Run directories you can trust: one writer, resumes that keep their settings, bad input as one line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from run_metrics import metrics_without_timing

from train.cli import main
from train.storage.policy import load_policy_file, save_policy

REPO = Path(__file__).resolve().parents[2]
TINY = ["--epoch-steps", "200", "--updates-per-epoch", "10", "--eval-every", "200", "--eval-rollouts", "2",
        "--eval-horizon", "10", "--buffer-size", "1000", "--no-progress"]


def _train(out: Path, *extra: str, task: str = "salad") -> int:
    return main(["train", task, "--steps", "400", *TINY, *extra, "--out", str(out)])


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("finished") / "run"
    assert _train(run, "--lr", "0.0003", "--seeds", "2") == 0
    return run


# ---- one writer ----------------------------------------------------------------------------------------


def test_a_second_writer_is_refused_naming_the_holder(finished, capsys):
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from train.storage.fileio import FileLock; "
         "lock = FileLock(sys.argv[1], 'x', 'y').acquire(); print('locked', flush=True); time.sleep(60)",
         str(finished / ".lock")], cwd=REPO, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        before = {p.name: p.stat().st_mtime_ns for p in finished.iterdir()}
        assert main(["train", "salad", "--resume", "--steps", "600", "--out", str(finished)]) == 2
        err = _one_line_error(capsys)
        assert f"in use by another ecorl process (pid {holder.pid})" in err
        assert {p.name: p.stat().st_mtime_ns for p in finished.iterdir()} == before  # nothing written
    finally:
        holder.kill()
        holder.wait()


def test_the_lock_is_free_again_once_the_writer_is_gone(finished, capsys):
    holder = subprocess.run([sys.executable, "-c", "import sys; from train.storage.fileio import FileLock; "
                             "FileLock(sys.argv[1], 'x', 'y').acquire()", str(finished / ".lock")], cwd=REPO)
    assert holder.returncode == 0
    assert main(["train", "salad", "--resume", "--out", str(finished)]) == 0  # finished already: nothing to do


# ---- resume keeps the run's settings -------------------------------------------------------------------


def test_resume_inherits_every_setting_and_may_grow_the_run(tmp_path, capsys):
    reference, run = tmp_path / "reference", tmp_path / "run"
    assert main(["train", "salad", "--steps", "600", *TINY, "--lr", "0.0003", "--seeds", "2", "--out",
                 str(reference)]) == 0
    assert _train(run, "--lr", "0.0003", "--seeds", "2") == 0
    assert main(["train", "salad", "--resume", "--out", str(run)]) == 0  # no flags: nothing changes
    assert metrics_without_timing(run)[-1]["step"] == "400"
    assert main(["train", "salad", "--resume", "--steps", "600", "--out", str(run)]) == 0
    saved = json.loads((run / "config.json").read_text())
    assert saved["run"]["steps"] == 600 and saved["dqn"]["lr"] == 0.0003 and saved["run"]["seeds"] == 2
    # the same as a run asked for 600 steps from the start
    assert metrics_without_timing(run) == metrics_without_timing(reference)


def test_a_fresh_run_in_a_folder_holding_one_of_other_settings_is_not_told_to_resume(finished, capsys):
    # the default --out names the knobs, not e.g. --lr: --resume would refuse the new rate
    assert _train(finished, "--lr", "0.001", "--seeds", "2") == 2
    assert "holds a run made with other settings (lr: checkpoint has 0.0003, you asked for 0.001)" in \
        _one_line_error(capsys)
    assert _train(finished, "--lr", "0.0003", "--seeds", "2") == 2  # the same settings: resume it
    assert "Pass --resume to continue the run it holds" in _one_line_error(capsys)


def test_resuming_a_folder_that_does_not_exist_says_there_is_no_run(tmp_path, capsys):
    assert main(["train", "salad", "--resume", "--out", str(tmp_path / "nowhere")]) == 2
    assert f"there is no run at {tmp_path / 'nowhere'}: nothing to resume" in _one_line_error(capsys)


def test_resume_takes_the_steps_the_run_was_made_with_though_they_round_up_to_an_epoch(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", "salad", "--steps", "450", *TINY, "--out", str(run)]) == 0  # 450 ends at step 600
    assert metrics_without_timing(run)[-1]["step"] == "600"
    assert main(["train", "salad", "--resume", "--steps", "450", "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["train", "salad", "--resume", "--steps", "399", "--out", str(run)]) == 2
    assert "--steps 399 is below step 600" in _one_line_error(capsys)


@pytest.mark.parametrize(("flags", "message"), [
    (["--steps", "200"], "--steps 200 is below step 400"),
    (["--lr", "0.001"], "with --lr 0.001: the run was made with 0.0003"),
    (["--seeds", "3"], "with --seeds 3: the run was made with 2"),
    (["--eval-rollouts", "5"], "with --eval-rollouts 5: the run was made with 2"),
    (["--env-kwarg", "initial_count=1"], "with --env-kwarg initial_count=1: the run was made with none"),
])
def test_resume_refuses_a_change_of_results(finished, flags, message, capsys):
    before = (finished / "config.json").read_bytes()
    assert main(["train", "salad", "--resume", *flags, "--out", str(finished)]) == 2
    assert message in _one_line_error(capsys)
    assert (finished / "config.json").read_bytes() == before


def test_a_deleted_metrics_file_is_rebuilt_from_the_checkpoint(finished, capsys):
    rows = metrics_without_timing(finished)
    (finished / "metrics.csv").unlink()
    assert main(["train", "salad", "--resume", "--out", str(finished)]) == 0
    assert metrics_without_timing(finished) == rows


# ---- bad input: one line, exit status 2, nothing written -----------------------------------------------


BAD_INPUTS = [
    (["--steps", "0"], "steps must be an integer >= 1, got 0"),
    (["--steps", "-5"], "steps must be an integer >= 1, got -5"),
    (["--buffer-size", "32"], "buffer-size (32) must be at least the batch size (64)"),
    (["--eval-every", "0"], "--eval-every must be an integer >= 1, got 0"),
    (["--lr", "nan"], "lr must be a finite number in (0, 1], got nan"),
    (["--lr", "inf"], "lr must be a finite number in (0, 1], got inf"),
    (["--lr", "-1"], "lr must be a finite number in (0, 1], got -1.0"),
    (["--lr", "1e30"], "lr must be a finite number in (0, 1], got 1e+30"),
    (["--shaping", "step:0:nan:1"], "has the breakpoint step nan"),
    (["--env-kwarg", "colour=red"], "salad has no parameter 'colour' (--env-kwarg); its parameters are: "),
    (["--env-kwarg", "dynamism=0.5"], "--env-kwarg may not set 'dynamism'"),
    (["--env-kwarg", "horizon=50"], "--env-kwarg may not set 'horizon'"),
    (["--env-kwarg", "reset_free=true"], "--env-kwarg may not set 'reset_free'"),
    (["--env-kwarg", "render_mode=rgb_array"], "--env-kwarg may not set 'render_mode'"),
    (["--env-kwarg", "walls=5"], "walls must be True or False, got 5"),
    (["--eval-env-kwarg", "colour=red"], "salad has no parameter 'colour' (--eval-env-kwarg)"),
    (["--eval-env-kwarg", "grid_size=3"], "the test MDP refuses --eval-env-kwarg {'grid_size': 3}: grid_size must be "
                                          "an integer >= 5, got 3"),
    (["--seeds", "5000", "--buffer-size", "100000000"], "use fewer --seeds or a smaller --buffer-size"),
    (["--eval-epsilon", "7"], "--eval-epsilon must be a finite number in [0, 1], got 7.0"),
    (["--grad-clip", "-1"], "--grad-clip must be a finite number > 0, got -1.0"),
    (["--view-layers", "0"], "--view-layers must be one or more layer widths >= 1"),
    (["--steps", "abc"], "argument --steps: expected an integer, got abc"),
]


@pytest.mark.parametrize(("flags", "message"), BAD_INPUTS, ids=[" ".join(f) for f, _ in BAD_INPUTS])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(flags, message, tmp_path, capsys):
    out = tmp_path / "run"
    try:
        code = main(["train", "salad", *flags, "--no-progress", "--out", str(out)])
    except SystemExit as exit_:  # argparse's own errors
        code = exit_.code
    assert code == 2
    assert message in _one_line_error(capsys)
    assert not out.exists()


def test_a_folder_of_other_files_is_refused_without_offering_to_resume_a_run_it_lacks(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["train", "salad", "--out", str(tmp_path)]) == 2
    err = _one_line_error(capsys)
    assert "is not empty and holds no run (no config.json); choose another --out" in err and "--resume" not in err
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_out_pointing_at_a_file_is_refused(tmp_path, capsys):
    target = tmp_path / "notes.txt"
    target.write_text("mine")
    assert main(["train", "salad", "--out", str(target)]) == 2
    assert "is a file, not a directory" in _one_line_error(capsys)
    assert target.read_text() == "mine"


@pytest.mark.parametrize("command", [["train", "salad"], ["demo", "--steps", "2"], ["run", "rnd", "--budget", "smoke"],
                                     ["report", "FINISHED", "--no-videos"], ["merge-seeds", "FINISHED", "FINISHED"]])
def test_out_under_a_file_names_the_file(command, finished, tmp_path, capsys):
    """Used to print '[Errno 20] Not a directory: ...' (train, run, report), '[Errno 17] File exists: ...' (demo,
    merge-seeds) or 'not an empty directory' (merge-seeds).
    """
    command = [str(finished) if word == "FINISHED" else word for word in command]
    target = tmp_path / "notes.txt"
    target.write_text("mine")
    out = target / "run" / "deeper"
    assert main([*command, "--out", str(out)]) == 2
    assert f"--out {out} lies under {target}, a file, not a directory; choose another --out" in \
        _one_line_error(capsys)
    assert main([*command, "--out", str(target)]) == 2
    assert f"--out {target} is a file, not a directory" in _one_line_error(capsys)
    assert target.read_text() == "mine"


def test_an_unusable_out_names_the_path_and_what_to_check(tmp_path, capsys):
    """Used to print Python's '[Errno 36] File name too long: ...' as the whole message."""
    out = tmp_path / ("x" * 300)
    assert main(["train", "salad", "--steps", "400", "--out", str(out)]) == 2
    assert _one_line_error(capsys).endswith(f"error: cannot use {out}: File name too long; check the path, its "
                                            f"permissions and the free disk space, or choose another path")


# ---- TensorBoard after a resume ------------------------------------------------------------------------


def test_tensorboard_shows_each_step_once_after_a_resume(tmp_path, monkeypatch):
    pytest.importorskip("tensorboard")
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    run = tmp_path / "run"
    assert _train(run, "--tensorboard", "--checkpoint-every", "200") == 0
    assert main(["train", "salad", "--resume", "--steps", "800", "--checkpoint-every", "200", "--out", str(run)]) == 0
    # a process killed after logging step 800 but before its checkpoint: its checkpoint says 600
    from train.storage.checkpoint import read_checkpoint, write_checkpoint

    state = read_checkpoint(run / "checkpoint.npz")
    state.update(step=600, epoch=state["epoch"] - 1, rows=[r for r in state["rows"] if r["step"] <= 600])
    state["last_checkpoint"] = 600
    write_checkpoint(run / "checkpoint.npz", state)
    assert main(["train", "salad", "--resume", "--out", str(run)]) == 0
    events = EventAccumulator(str(run / "tensorboard"))
    events.Reload()
    steps = [e.step for e in events.Scalars("loss/mean")]
    assert steps == sorted(set(steps)) and steps[-1] == 800


# ---- policy files --------------------------------------------------------------------------------------


@pytest.fixture
def policy(finished, tmp_path) -> Path:
    path = tmp_path / "good.npz"
    assert main(["export", str(finished), "--out", str(path)]) == 0
    return path


def _rewrite(path: Path, params: np.ndarray) -> Path:
    with np.load(path) as data:
        header = data["header"]
    bad = path.with_name("bad.npz")
    np.savez(bad, params=params, header=header)
    return bad


@pytest.mark.parametrize(("damage", "message"), [
    ("float64", "parameters are float64"),
    ("nan", "NaN or infinite parameters"),
    ("huge", "more than"),
    ("object", "not an ecorl policy file"),
])
def test_bad_policy_files_are_refused_in_one_line(policy, damage, message, capsys, monkeypatch):
    import train.storage.policy

    params = load_policy_file(policy).params.numpy()
    limits = {**train.storage.policy.MAX_POLICY_MEMBER_BYTES, "params.npy": 8 * params.size + 1024}
    monkeypatch.setattr(train.storage.policy, "MAX_POLICY_MEMBER_BYTES", limits)  # this network, with room to spare
    if damage == "float64":
        params = params.astype(np.float64)
    elif damage == "nan":
        params = params.copy()
        params[0, 3] = np.nan
    elif damage == "huge":
        params = np.zeros((1, 4 * params.size), dtype=np.float32)
    else:
        params = np.array([{"x": 1}], dtype=object)
    bad = _rewrite(policy, params)
    capsys.readouterr()
    assert main(["evaluate", str(bad), "--rollouts", "1"]) == 2
    assert message in _one_line_error(capsys)


def test_saving_a_policy_writes_no_temporary(policy, tmp_path):
    save_policy(load_policy_file(policy), tmp_path / "copy.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copy.npz", "good.npz"]
    assert os.path.getsize(tmp_path / "copy.npz") > 0


def test_a_finished_sweep_run_rebuilds_its_deleted_metrics(tmp_path):
    from train.experiments.catalog import get_experiment
    from train.experiments.jobs import execute
    from train.experiments.sweep import plan

    job = plan(get_experiment("rnd"), "smoke", tmp_path, ["factory"])[0]
    assert execute(job).status == "done"
    run = Path(job.run_dir)
    rows = metrics_without_timing(run)
    (run / "metrics.csv").unlink()
    assert execute(job).status == "skipped"
    assert metrics_without_timing(run) == rows


def test_the_checkpoint_is_plain_data_numpy_opens_without_pickle(finished):
    with np.load(finished / "checkpoint.npz", allow_pickle=False) as data:
        arrays = {name: data[name] for name in data.files}
    assert not any(a.dtype.hasobject for a in arrays.values())
    manifest = json.loads(arrays.pop("manifest").tobytes().decode())
    assert manifest["format"] == 2 and manifest["state"]["step"] == 400
    assert set(manifest["sha256"]) == set(arrays)
    assert {"agent/online", "replay/obs", "env/worlds/grid", "torch_rng"} <= set(arrays)
    assert manifest["state"]["rngs"]["explore"][0]["bit_generator"] == "PCG64"
