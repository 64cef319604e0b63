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


def _chunk(cwd: Path, seconds: int) -> subprocess.CompletedProcess:
    env = {**os.environ, "DEVICE": "cpu", "CHUNK_S": str(seconds), "OUT": str(cwd / "out"),
           "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    return subprocess.run(["bash", str(SCRIPT), "headline", "--budget", "smoke", "--condition", "static-episodic"],
                          cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_chunks_resume_until_done_and_bring_back_one_small_archive_without_checkpoints(tmp_path):
    first = _chunk(tmp_path, 1)  # stopped at once: an interrupted run, or none started yet
    assert first.returncode == 124, first.stdout + first.stderr
    assert "== not finished: run this again" in first.stdout
    finished = _chunk(tmp_path, 250)
    assert finished.returncode == 0, finished.stdout + finished.stderr
    assert "[  done] headline/salad/static-episodic" in finished.stdout and "== all done" in finished.stdout
    assert (tmp_path / "results/headline/salad/static-episodic/checkpoint.npz").exists()  # kept for later chunks
    names = tarfile.open(tmp_path / "out/results.tar.gz").getnames()
    run = "results/headline/salad/static-episodic"
    assert {f"{run}/metrics.csv", f"{run}/config.json", f"{run}/done.json", f"{run}/policies/best.npz"} <= set(names)
    assert not [n for n in names if "checkpoint" in n or n.endswith(".lock")], names
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["results.tar.gz", "status.txt"]
