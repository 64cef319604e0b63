"""An interrupted sweep (SIGKILL of its whole process group) finishes on re-run with nothing lost or repeated."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from train.experiments.catalog import get_experiment
from train.experiments.jobs import DONE_FILE, execute
from train.experiments.sweep import plan
from train.storage.checkpoint import CHECKPOINT_NAME, read_checkpoint

REPO = Path(__file__).resolve().parents[3]
ARGS = ("run", "episodic-vs-reset-free", "--budget", "smoke", "--steps", "4000", "--jobs", "2", "--no-progress")
DETERMINISTIC = ("step", "seed", "epsilon", "loss", "success", "return", "train_reward")
"""metrics.csv columns that must match exactly (steps_per_s is a timing)."""


def _metrics(run_dir: Path) -> list[tuple]:
    with open(run_dir / "metrics.csv") as f:
        return [tuple(row[k] for k in DETERMINISTIC) for row in csv.DictReader(f)]


def _run_dirs(root: Path) -> list[Path]:
    return sorted(p.parent for p in root.glob("episodic-vs-reset-free/salad/*/config.json"))


def _evaluated_twice(out: Path) -> bool:
    """True once a run has logged its second evaluation (so its step-700 checkpoint is on disk)."""
    for path in out.glob("episodic-vs-reset-free/salad/*/metrics.csv"):
        try:
            if "\n1200," in path.read_text():
                return True
        except FileNotFoundError:
            pass
    return False


def _checkpoint_step(run_dir: Path) -> int:
    """The step of a run's checkpoint (read from its manifest, no arrays); -1: none."""
    path = run_dir / CHECKPOINT_NAME
    return read_checkpoint(path, keys=[])["step"] if path.exists() else -1


def _kill_when_training(out: Path) -> None:
    """Start the sweep in its own process group and SIGKILL the group once a run is part-way through."""
    log = out.with_name(out.name + ".log")
    with open(log, "w") as err:  # a file, not a pipe: reading it never waits on a worker
        proc = subprocess.Popen([sys.executable, "-m", "train.cli", *ARGS, "--out", str(out)], cwd=REPO,
                                start_new_session=True, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                stderr=err)
    deadline = time.monotonic() + 240
    try:
        while not _evaluated_twice(out):
            assert proc.poll() is None, f"sweep ended before it could be interrupted: {log.read_text()}"
            assert time.monotonic() < deadline, "no evaluation logged within 240 s"
            time.sleep(0.05)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:  # the sweep and its workers are all gone already
            pass
        proc.wait()


def test_sigkill_then_rerun_matches_an_uninterrupted_sweep(tmp_path, cli):
    killed, clean = tmp_path / "killed", tmp_path / "clean"
    _kill_when_training(killed)
    dirs = _run_dirs(killed)
    assert dirs and not all((d / DONE_FILE).exists() for d in dirs), "the kill came after the sweep finished"
    assert any(0 < _checkpoint_step(d) < 4200 for d in dirs)  # a run resumes from mid-way, not from scratch

    proc = cli(*ARGS, "--out", str(killed))
    assert "2 done" in proc.stderr or "1 done" in proc.stderr
    cli(*ARGS, "--out", str(clean))

    assert [d.name for d in _run_dirs(killed)] == [d.name for d in _run_dirs(clean)] == ["static-episodic",
                                                                                         "static-reset-free"]
    for a, b in zip(_run_dirs(killed), _run_dirs(clean)):
        rows = _metrics(a)
        assert rows == _metrics(b), a.name  # nothing lost, repeated or changed
        assert len(rows) == 2 * 8 and len({r[:2] for r in rows}) == len(rows)
        np.testing.assert_array_equal(np.load(a / "visits.npy"), np.load(b / "visits.npy"))
        assert json.loads((a / DONE_FILE).read_text())["total_steps"] == 4200

    rerun = cli(*ARGS, "--out", str(killed))  # everything done: skipped, files untouched
    assert "2 skipped" in rerun.stderr


def test_longer_budget_resumes_a_finished_run(tmp_path):
    exp = get_experiment("rnd")
    short = plan(exp, "smoke", tmp_path, ["factory"])[:1]
    assert execute(short[0]).status == "done"
    assert execute(short[0]).status == "skipped"
    longer = plan(exp, "smoke", tmp_path, ["factory"], steps=1700)[:1]
    assert execute(longer[0]).status == "done"
    steps = sorted({row[0] for row in _metrics(Path(longer[0].run_dir))}, key=int)
    assert steps == ["700", "1200", "1700"]


def test_a_run_killed_before_its_first_checkpoint_starts_afresh(tmp_path):
    job = plan(get_experiment("rnd"), "smoke", tmp_path, ["factory"])[0]
    run_dir = Path(job.run_dir)
    run_dir.mkdir(parents=True)
    (run_dir / "config.json").write_text("{}")  # what a kill right after the trainer's prepare() leaves
    assert execute(job).status == "done"
    (run_dir / "notes.txt").write_text("mine")
    (run_dir / CHECKPOINT_NAME).unlink()
    (run_dir / DONE_FILE).unlink()
    result = execute(job)  # unknown files are never deleted
    assert result.status == "failed" and "notes.txt" in result.error


def test_changed_settings_are_refused(tmp_path):
    exp = get_experiment("rnd")
    job = plan(exp, "smoke", tmp_path, ["factory"])[0]
    assert execute(job).status == "done"
    changed = plan(exp, "smoke", tmp_path, ["factory"], seeds=3)[0]
    result = execute(changed)
    assert result.status == "failed" and "different settings" in result.error


@pytest.mark.parametrize("executor", ["nope"])
def test_unknown_executor(executor):
    from train.experiments.sweep import run_jobs

    with pytest.raises(ValueError, match="choose local or ray"):
        run_jobs(plan(get_experiment("rnd"), "smoke", "/nonexistent"), executor, progress=False)


@pytest.mark.slow
def test_ctrl_c_stops_cleanly_and_the_rerun_resumes(tmp_path, cli):
    out = tmp_path / "ctrl-c"
    args = ("run", "rnd", "--budget", "smoke", "--steps", "20000", "--jobs", "2", "--no-progress", "--out", str(out))
    proc = _start_sweep(args, out, "rnd/factory/*/metrics.csv")
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "re-run the same command to resume" in err
    runs = sorted(out.glob("rnd/factory/*"))
    assert len(runs) < 4 or not all((r / DONE_FILE).exists() for r in runs)  # queued runs did not start
    assert all((r / CHECKPOINT_NAME).exists() for r in runs if (r / "config.json").exists())
    cli(*args)
    assert all((out / "rnd" / "factory" / c / DONE_FILE).exists() for c in ("static", "rnd", "dynamic", "env-shaping"))


def _ctrl_c_as_at_a_terminal() -> None:
    """In the sweep's child, before exec: SIGINT back to its default, as a terminal's job gets it. A suite started
    in the background of a non-interactive shell inherits SIGINT ignored, and Python then never turns it into
    KeyboardInterrupt, so these tests would measure how pytest was launched instead of the sweep.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start_sweep(args: tuple[str, ...], out: Path, logged: str) -> subprocess.Popen:
    """``ecorl ARGS`` in its own process group (stderr piped); returns once ``out`` holds a file matching
    ``logged`` (a run has logged an evaluation).
    """
    proc = subprocess.Popen([sys.executable, "-m", "train.cli", *args], cwd=REPO, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_ctrl_c_as_at_a_terminal)
    deadline = time.monotonic() + 240
    while not list(out.glob(logged)):
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)
    return proc


def _start_long_sweep(out: Path) -> subprocess.Popen:
    """A one-condition sweep long enough (about a minute) that a run ending on its own would be noticed; returns
    once its run has logged an evaluation.
    """
    args = ("run", "headline", "--budget", "smoke", "--condition", "dynamic-reset-free", "--steps", "60000",
            "--jobs", "1", "--no-progress", "--out", str(out))
    return _start_sweep(args, out, "headline/salad/*/metrics.csv")


def _wait_or_kill(proc: subprocess.Popen, timeout_s: float = 90) -> str:
    """The sweep's stderr once it exits; a sweep still there after ``timeout_s`` is killed (group) and fails."""
    try:
        return proc.communicate(timeout=timeout_s)[1]
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        pytest.fail(f"the sweep had not exited {timeout_s:.0f} s after the signal")


def test_sigint_to_the_sweep_alone_stops_its_running_trainer(tmp_path):
    out = tmp_path / "sweep-only"
    proc = _start_long_sweep(out)
    os.kill(proc.pid, signal.SIGINT)  # `kill -INT PID`, `timeout --foreground -s INT`: the workers get nothing
    err = _wait_or_kill(proc)
    run = out / "headline" / "salad" / "dynamic-reset-free"
    assert proc.returncode == 130 and "re-run the same command to resume" in err
    assert not (run / DONE_FILE).exists() and _checkpoint_step(run) > 0  # it stopped early, with a checkpoint


def test_a_second_signal_while_the_sweep_stops_ends_it_without_hanging(tmp_path):
    out = tmp_path / "twice"
    proc = _start_long_sweep(out)
    os.kill(proc.pid, signal.SIGINT)
    time.sleep(0.3)
    os.killpg(proc.pid, signal.SIGINT)  # the second reaches the workers too, as `timeout -s INT` or Ctrl-C does
    err = _wait_or_kill(proc)
    assert proc.returncode == 130 and "re-run the same command to resume" in err


def _in_own_session(code: str, tmp_path: Path) -> str:
    """Run ``code`` in a fresh interpreter in a session of its own (any signal it sends itself never reaches
    pytest), with ``tmp_path`` importable; its stdout.
    """
    path = os.pathsep.join([str(tmp_path), str(REPO), os.environ.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, start_new_session=True, capture_output=True,
                          text=True, timeout=240, env={**os.environ, "PYTHONPATH": path})
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


_PROBE = """
import os, signal
os.kill(os.getpid(), signal.SIGINT)  # a Ctrl-C while the fork server imports its preload
open({where!r}, "w").write("survived")
"""


def test_a_ctrl_c_neither_kills_the_fork_server_while_it_imports_nor_is_lost_to_the_sweep(tmp_path):
    (tmp_path / "ecorl_probe.py").write_text(_PROBE.format(where=str(tmp_path / "probe.txt")))
    code = f"""if True:
        import os, signal, time
        from multiprocessing import forkserver
        from train.experiments import executors
        executors.WORKER_PRELOAD = ("ecorl_probe",)
        caught = []
        signal.signal(signal.SIGINT, lambda *_: caught.append(1))
        spawn = forkserver.ensure_running

        def ctrl_c_then_spawn():
            os.kill(os.getpid(), signal.SIGINT)  # a Ctrl-C that lands while the server is spawned
            time.sleep(0.3)  # time for another thread of this process to take it
            spawn()

        forkserver.ensure_running = ctrl_c_then_spawn
        executors.worker_context()
        server = forkserver._forkserver._forkserver_pid
        while not os.path.exists({str(tmp_path / "probe.txt")!r}) and not os.waitpid(server, os.WNOHANG)[0]:
            time.sleep(0.05)
        print(len(caught), os.path.exists({str(tmp_path / "probe.txt")!r}))
    """
    assert _in_own_session(code, tmp_path).split() == ["1", "True"]  # the sweep's handler took it; the server lives


def test_a_worker_of_the_fork_server_takes_ctrl_c_again(tmp_path):
    code = """if True:
        import os, signal
        from concurrent.futures import ProcessPoolExecutor
        from train.experiments import executors
        executors.WORKER_PRELOAD = ()
        ctx = executors.worker_context()
        with ProcessPoolExecutor(1, mp_context=ctx, initializer=executors._init_worker,
                                 initargs=(ctx.Event(), os.getpid())) as pool:
            print(signal.SIGINT in pool.submit(signal.pthread_sigmask, signal.SIG_BLOCK, []).result())
    """
    assert _in_own_session(code, tmp_path).split() == ["False"]  # its trainer's handler can stop it


def test_an_interrupted_sweep_ends_its_fork_server(tmp_path):
    code = """if True:
        import os
        from multiprocessing import forkserver
        from train.experiments import executors
        executors.WORKER_PRELOAD = ()
        forkserver.ensure_running()
        server = forkserver._forkserver._forkserver_pid

        def interrupted(*_):
            raise KeyboardInterrupt  # Ctrl-C while the sweep submits its jobs

        executors._collect = interrupted
        try:
            executors.run_local([None], 1, print)
        except KeyboardInterrupt:
            pass
        print(server is not None, os.path.exists(f"/proc/{server}"), forkserver._forkserver._forkserver_pid)
    """
    assert _in_own_session(code, tmp_path).split() == ["True", "False", "None"]  # ended and reaped
