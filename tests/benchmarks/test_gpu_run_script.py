"""benchmarks/gpu_run.sh, the chunk runner for lent GPU machines, run here on the CPU at the smoke budget: a
lent minute lost to a broken script is not given back.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tarfile
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "gpu_run.sh"
EPISODIC = ["headline", "--budget", "smoke", "--condition", "static-episodic"]
RESET_FREE = ["headline", "--budget", "smoke", "--condition", "static-reset-free"]


def _run(cwd: Path, args: list[str], seconds: float = 250, **env: str) -> subprocess.CompletedProcess:
    """The script in ``cwd`` on the CPU, a chunk of at most ``seconds``."""
    env = {**os.environ, "DEVICE": "cpu", "CHUNK_S": str(seconds), "OUT": str(cwd / "out"),
           "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}", **env}
    return subprocess.run(["bash", str(SCRIPT), *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=300)


def _slow_start(tmp_path: Path) -> str:
    """A folder for PYTHONPATH whose sitecustomize holds every Python 5 s before it runs anything: a chunk that
    stops sooner stops before its trainer starts, however idle or busy the machine (a chunk of 0.2 s alone let a
    smoke run finish under CI's load).
    """
    site = tmp_path / "slow-site"
    site.mkdir()
    (site / "sitecustomize.py").write_text("import time\ntime.sleep(5)\n")
    return str(site)


def test_chunks_resume_until_done_side_by_side_and_bring_back_one_small_archive(tmp_path):
    first = _run(tmp_path, EPISODIC, seconds=0.5, PYTHONPATH=_slow_start(tmp_path))
    assert first.returncode == 124, first.stdout + first.stderr
    assert "== not finished: run this again" in first.stdout
    finished = _run(tmp_path, [*EPISODIC, "+", *RESET_FREE])  # a lone "+": two runs side by side
    assert finished.returncode == 0, finished.stdout + finished.stderr
    status = (tmp_path / "out/status.txt").read_text().splitlines()
    assert [line.split(":")[0] for line in status] == ["[  done] headline/salad/static-episodic",
                                                       "[  done] headline/salad/static-reset-free"]
    assert "== all done" in finished.stdout
    assert (tmp_path / "results/headline/salad/static-episodic/checkpoint.npz").exists()  # kept for later chunks
    names = tarfile.open(tmp_path / "out/results.tar.gz").getnames()
    run = "results/headline/salad/static-episodic"
    assert {f"{run}/metrics.csv", f"{run}/config.json", f"{run}/done.json", f"{run}/policies/best.npz"} <= set(names)
    assert not [n for n in names if "checkpoint" in n or n.endswith(".lock")], names  # both runs finished
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["results.tar.gz", "status.txt"]


def test_keeps_the_callers_python_path(tmp_path):
    """On a lent machine an earlier step may have installed gymnasium into a folder named by PYTHONPATH; the
    script must add the repository to that path, not replace it (a lent run once lost its gymnasium so).
    """
    site = tmp_path / "site"
    site.mkdir()
    seen = tmp_path / "seen"  # each Python that imports from the caller's folder writes its PYTHONPATH here
    (site / "sitecustomize.py").write_text(
        f"import os\nwith open({str(seen)!r}, 'a') as f:\n    f.write(os.environ['PYTHONPATH'] + '\\n')\n")
    _run(tmp_path, EPISODIC, seconds=1, PYTHONPATH=str(site))
    root = str(SCRIPT.parents[1])
    assert any(root in line.split(os.pathsep) for line in seen.read_text().splitlines())  # the trainer's Pythons


def test_unfinished_checkpoints_travel_to_the_next_lease_and_a_failing_run_says_so(tmp_path):
    lease, later = tmp_path / "lease", tmp_path / "later"
    unfinished, finished = lease / "results/x/salad/a", lease / "results/x/salad/b"
    for run in (unfinished, finished):
        run.mkdir(parents=True)
        (run / "checkpoint.npz").write_bytes(os.urandom(1000))
        (run / "metrics.csv").write_text("step\n")
        (run / ".lock").write_text("1")
    (finished / "done.json").write_text("{}")
    failed = _run(lease, ["no-such-experiment"])  # trains nothing: only the packing runs
    assert failed.returncode not in (0, 124)
    assert "== failed" in failed.stdout and "all done" not in failed.stdout
    assert "no-such-experiment" in failed.stderr  # ecorl's own message names it
    archive = lease / "out/results.tar.gz"
    names = set(tarfile.open(archive).getnames())
    assert "results/x/salad/a/checkpoint.npz" in names  # resumable at the next lease
    assert "results/x/salad/b/checkpoint.npz" not in names and "results/x/salad/b/done.json" in names
    assert not [n for n in names if n.endswith(".lock")]

    (later / "gpu-state").mkdir(parents=True)
    (later / "gpu-state/results.tar.gz").write_bytes(archive.read_bytes())
    unpacked = _run(later, ["no-such-experiment"])
    assert "== resumed from gpu-state: 1 unfinished runs" in unpacked.stdout, unpacked.stdout + unpacked.stderr
    assert (later / "results/x/salad/a/checkpoint.npz").read_bytes() == (unfinished / "checkpoint.npz").read_bytes()


def test_an_archive_too_big_for_one_command_comes_back_in_parts_over_two_commands(tmp_path):
    """A command brings back 64 MiB at most (a lent walls chunk lost its fifth part so): four 15 MiB parts go
    at once, the rest with ``--rest``, and they join back into the archive.
    """
    run = tmp_path / "results/x/salad/a"
    run.mkdir(parents=True)
    (run / "checkpoint.npz").write_bytes(os.urandom(61 * 2**20))  # random bytes: gzip cannot shrink them
    first = _run(tmp_path, ["no-such-experiment"])
    assert "1 more part(s) of the archive wait here" in first.stdout, first.stdout + first.stderr
    assert "1 unfinished runs travel with their checkpoints" in first.stdout
    sent = sorted((tmp_path / "out").glob("results.tar.gz*"))
    assert [p.name for p in sent] == [f"results.tar.gz.0{i}" for i in range(4)]
    assert all(p.stat().st_size <= 15 * 2**20 for p in sent)
    joined = b"".join(p.read_bytes() for p in sent)
    rest = _run(tmp_path, ["--rest"])
    assert rest.returncode == 0 and "more part" not in rest.stdout, rest.stdout + rest.stderr
    assert sorted(p.name for p in (tmp_path / "out").glob("results.tar.gz*")) == ["results.tar.gz.04"]
    archive = tmp_path / "joined.tar.gz"
    archive.write_bytes(joined + (tmp_path / "out/results.tar.gz.04").read_bytes())
    member = tarfile.open(archive).extractfile("results/x/salad/a/checkpoint.npz").read()
    assert member == (run / "checkpoint.npz").read_bytes()
    assert _run(tmp_path, ["--rest"]).stdout == ""  # nothing left: it sends nothing


def test_rest_before_any_chunk_says_there_is_nothing_to_send(tmp_path):
    nothing = _run(tmp_path, ["--rest"])
    assert nothing.returncode == 2 and "no chunk has packed an archive here" in nothing.stderr
