"""Run and results directories from someone else: opening them never runs their code or writes outside them;
sweeps keep one writer per run and stop with their parent.
"""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import time
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from train.cli import main
from train.experiments.catalog import get_experiment
from train.experiments.executors import ORPHAN_GRACE_S
from train.experiments.jobs import DONE_FILE
from train.experiments.sweep import plan, write_experiment_file
from train.storage.checkpoint import CHECKPOINT_NAME, LEGACY_NAME
from train.storage.rundir import EXPERIMENT_FILE

REPO = Path(__file__).resolve().parents[3]


class _Exploit:
    """Unpickling this creates the marker file: proof that a loader executed the file's code."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


def _evil_npz(path: Path, marker: Path, manifest: bool) -> None:
    """A checkpoint.npz whose arrays are pickles (object arrays), optionally with a plausible manifest."""
    with zipfile.ZipFile(path, "w") as zf:
        for key in ("agent/online", "replay/obs"):
            with zf.open(f"{key}.npy", "w") as f:
                np.lib.format.write_array(f, np.array([_Exploit(marker)], dtype=object), allow_pickle=True)
        if manifest:
            state = {"version": 2, "config": {}, "step": 0, "agent": {"online": {"__tensor__": "agent/online"}}}
            text = json.dumps({"format": 2, "state": state, "sha256": {"agent/online": "0" * 64}}).encode()
            with zf.open("manifest.npy", "w") as f:
                np.lib.format.write_array(f, np.frombuffer(text, dtype=np.uint8))


@pytest.fixture
def planted(tmp_path) -> tuple[Path, Path]:
    """A results directory of the headline experiment whose four runs each carry a booby-trapped checkpoint
    (pickles, object arrays), plus a booby-trapped policy file; returns (results dir, marker path).
    """
    marker = tmp_path / "PWNED"
    out = tmp_path / "results"
    exp = get_experiment("headline")
    jobs = plan(exp, "smoke", out)
    write_experiment_file(exp, "smoke", jobs, out)
    for i, job in enumerate(jobs):
        run = Path(job.run_dir)
        run.mkdir(parents=True)
        (run / "config.json").write_text(json.dumps(job.config))
        (run / "metrics.csv").write_text("step,seed,epsilon,loss,success,return,train_reward,steps_per_s\n"
                                         "500,0,1.0,0.1,0.0,0.0,0.0,100\n500,1,1.0,0.1,0.0,0.0,0.0,100\n")
        (run / DONE_FILE).write_text(json.dumps({"total_steps": 1, "seeds": 2}))
        (run / LEGACY_NAME).write_bytes(pickle.dumps(_Exploit(marker)))
        if i % 2:
            _evil_npz(run / CHECKPOINT_NAME, marker, manifest=i == 3)
    np.savez(tmp_path / "policy.npz", params=np.array([_Exploit(marker)], dtype=object),
             header=np.array(json.dumps({"format": 1})))
    return out, marker


def _ecorl(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "train.cli", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env={**os.environ, "PYTHONPATH": str(REPO)})


def test_no_command_executes_a_planted_checkpoint(planted, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out, marker = planted
    runs = sorted((out / "headline" / "salad").iterdir())
    legacy, evil = runs[0], runs[1]
    assert (legacy / LEGACY_NAME).exists() and not (legacy / CHECKPOINT_NAME).exists()
    assert (evil / CHECKPOINT_NAME).exists()
    commands = [
        ("evaluate", str(legacy)), ("evaluate", str(evil)), ("evaluate", str(tmp_path / "policy.npz")),
        ("export", str(legacy), "--out", str(tmp_path / "p.npz")),
        ("export", str(evil), "--out", str(tmp_path / "p.npz")),
        ("video", "salad", "--policy", str(legacy), "--out", str(tmp_path / "v.mp4")),
        ("video", "salad", "--policy", str(evil / CHECKPOINT_NAME), "--out", str(tmp_path / "v.mp4")),
        ("video", "salad", "--policy", str(tmp_path / "policy.npz"), "--out", str(tmp_path / "v.mp4")),
        ("train", "salad", "--resume", "--out", str(legacy)), ("train", "salad", "--resume", "--out", str(evil)),
    ]
    for args in commands:
        capsys.readouterr()
        assert main(list(args)) == 2, args
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "Traceback" not in err, (args, err)
        assert any(s in err for s in ("pickled checkpoint (ecorl checkpoint format 1)", "corrupt or not an ecorl",
                                      "not an ecorl policy file")), (args, err)
    assert not marker.exists()
    assert not (tmp_path / "p.npz").exists() and not (tmp_path / "v.mp4").exists()

    # re-running the experiment over the results folder: every run refused, none trained or unpickled
    for job in plan(get_experiment("headline"), "smoke", out):
        (Path(job.run_dir) / DONE_FILE).unlink()
    capsys.readouterr()
    assert main(["run", "headline", "--budget", "smoke", "--out", str(out), "--jobs", "1", "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert err.count("FAILED") == 4
    assert "pickled checkpoint" in err and "corrupt or not an ecorl checkpoint" in err
    assert not marker.exists()

    # the report draws what it can and films nothing it cannot trust
    for job in plan(get_experiment("headline"), "smoke", out):
        (Path(job.run_dir) / DONE_FILE).write_text("{}")
    assert main(["report", str(out)]) == 0
    assert "no video of" in capsys.readouterr().err and (out / "report.md").exists()
    assert not marker.exists()


@pytest.mark.parametrize("name", ["../../outside/x", "headline/../../../outside"])
def test_the_report_refuses_names_outside_the_known_experiments(tmp_path, name):
    root = tmp_path / "results"
    (root / "headline").mkdir(parents=True)
    (root / "headline" / EXPERIMENT_FILE).write_text(json.dumps({"name": name, "tasks": {}}))
    proc = _ecorl("report", str(root), cwd=tmp_path)
    assert proc.returncode == 2 and "unknown experiment" in proc.stderr and "\n" not in proc.stderr.strip()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results"]  # nothing written anywhere
    assert [p.name for p in root.iterdir()] == ["headline"]


def test_the_report_refuses_unknown_conditions(tmp_path):
    root = tmp_path / "headline"
    root.mkdir()
    (root / EXPERIMENT_FILE).write_text(json.dumps({"name": "headline", "tasks": {"salad": [{"name": "../../x"}]}}))
    proc = _ecorl("report", str(root), cwd=tmp_path)
    assert proc.returncode == 2 and "does not have" in proc.stderr


def test_concurrent_task_subsets_keep_every_entry_of_experiment_json(tmp_path, monkeypatch):
    from concurrent.futures import ThreadPoolExecutor

    import train.experiments.sweep

    read = train.experiments.sweep._read_json

    def slow_read(path):  # widen the window between reading experiment.json and replacing it
        data = read(path)
        time.sleep(0.01)
        return data

    monkeypatch.setattr(train.experiments.sweep, "_read_json", slow_read)
    exp = get_experiment("dynamism")
    subsets = [plan(exp, "smoke", tmp_path, [task]) for task in exp.tasks]

    def write(jobs):  # each call opens the lock file anew, so threads contend as processes do
        for _ in range(10):
            write_experiment_file(exp, "smoke", jobs, tmp_path)

    with ThreadPoolExecutor(len(subsets)) as pool:
        list(pool.map(write, subsets))
    info = json.loads((tmp_path / "dynamism" / EXPERIMENT_FILE).read_text())
    assert info["tasks_run"] == list(exp.tasks)


def _descendants(pid: int) -> set[int]:
    """The processes that any thread of ``pid`` started, and theirs (workers are a fork server's children)."""
    kids = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            kids |= {int(c) for c in (task / "children").read_text().split()}
        except FileNotFoundError:
            pass
    return kids.union(*(_descendants(k) for k in kids))


def _state(pid: int) -> str | None:
    """A process's state letter (R, S, Z, ...); None once it is gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except FileNotFoundError:
        return None


def _alive(pid: int) -> bool:
    return _state(pid) not in (None, "Z")


def _describe(pid: int) -> str:
    """A process's command line, state and kernel wait channel, for a failure message."""
    try:
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()[:160]
        wchan = Path(f"/proc/{pid}/wchan").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return f"{pid}: gone"
    return f"{pid} [{_state(pid)}, waiting in {wchan or '-'}]: {cmd}"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and PR_SET_PDEATHSIG")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_workers_stop_when_the_sweep_dies_and_start_nothing_queued(tmp_path, sig):
    out, log = tmp_path / "out", tmp_path / "sweep.log"
    args = ("run", "rnd", "--budget", "smoke", "--steps", "200000", "--jobs", "1", "--no-progress", "--out", str(out))
    with open(log, "w") as err:  # a file, not a pipe: no read can wait on a process that outlives the sweep
        sweep = subprocess.Popen([sys.executable, "-m", "train.cli", *args], cwd=REPO, start_new_session=True,
                                 stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err)
    try:
        deadline = time.monotonic() + 120
        while not list(out.glob("rnd/factory/*/metrics.csv")):  # the first condition is training
            assert sweep.poll() is None, f"the sweep ended early: {log.read_text()}"
            assert time.monotonic() < deadline, "no condition started training within 120 s"
            time.sleep(0.1)
        workers = _descendants(sweep.pid)
        assert workers, "the sweep has no worker process"
        sweep.send_signal(sig)
        sweep.wait(timeout=60)
        limit = ORPHAN_GRACE_S + 60  # a clean stop takes about a second; a hung one ends at the grace
        deadline = time.monotonic() + limit
        while any(_alive(w) for w in workers):
            assert time.monotonic() < deadline, (f"a worker outlived its sweep by {limit:.0f} s: "  # on failure only
                                                 + "; ".join(_describe(w) for w in workers if _alive(w)))
            time.sleep(0.1)
    finally:
        try:  # the sweep's session: whatever of it still lives (the workers did not leave it)
            os.killpg(sweep.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        sweep.wait()
    if "most recent call first" in log.read_text():  # the worker's stop hung and the grace ended it: say where
        warnings.warn(f"a worker's stop hung until the orphan grace; its stacks: {log.read_text()[-6000:]}",
                      stacklevel=1)
    started = [p.name for p in out.glob("rnd/factory/*") if (p / "config.json").exists()]
    assert len(started) == 1, f"queued conditions started: {started}; the sweep said: {log.read_text()}"
    assert (out / "rnd" / "factory" / started[0] / CHECKPOINT_NAME).exists()


_GONE_SWEEP = """
import subprocess
from train.experiments import executors
sweep = subprocess.Popen(["sleep", "0"])
executors._follow_sweep(sweep.pid)
sweep.wait()  # the sweep is gone
"""
"""A worker's view of a sweep that has exited (a short-lived child followed as the sweep)."""

_WATCH = _GONE_SWEEP + """
import signal, sys, threading, time
from train.loop.runlog import stop_on_signal
executors.SWEEP_POLL_S = 0.05
terms = []
with stop_on_signal() as stop:
    signal.signal(signal.SIGTERM, lambda *_: (terms.append(1), stop.set()))
    if sys.argv[1] == "already-stopping":
        stop.set()  # as after the sweep's SIGTERM or a Ctrl-C
    threading.Thread(target=executors._watch_sweep, daemon=True).start()
    time.sleep(1.0)
print(len(terms))
"""


_HANG = _GONE_SWEEP + """
import threading
from train.loop.runlog import stop_on_signal
executors.SWEEP_POLL_S, executors.ORPHAN_GRACE_S = 0.05, 0.5
with stop_on_signal() as stop:
    stop.set()  # a signal arrived: the worker is stopping
    threading.Thread(target=executors._watch_sweep, daemon=True).start()
    lock = threading.Lock()
    lock.acquire()
    lock.acquire()  # but its stop hangs on a lock no one releases
"""


def test_an_orphan_whose_stop_hangs_prints_its_stacks_and_exits_at_the_grace():
    began = time.monotonic()
    out = subprocess.run([sys.executable, "-c", _HANG], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert out.returncode != 0
    assert time.monotonic() - began < 30
    assert "most recent call first" in out.stderr and "<string>" in out.stderr, out.stderr


@pytest.mark.parametrize("state, expected", [("running", "1"), ("already-stopping", "0")])
def test_a_worker_stops_itself_when_its_sweep_is_gone_without_a_second_signal(state, expected):
    out = subprocess.run([sys.executable, "-c", _WATCH, state], cwd=REPO, capture_output=True, text=True,
                         timeout=60, check=True)
    assert out.stdout.strip() == expected
