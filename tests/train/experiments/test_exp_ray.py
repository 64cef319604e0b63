"""The Ray executor against a local Ray instance started (and stopped) by the test."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

RAY = str(Path(sys.executable).with_name("ray"))
"""The ``ray`` command of this interpreter's environment (a virtual environment need not be on PATH)."""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def ray_head(tmp_path, monkeypatch):
    """``ray start --head --block`` in its own process group; the whole group is stopped afterwards.

    Token authentication is off for the head and every driver the test starts: with a ``~/.ray/auth_token`` at
    hand (one was written here when ``ecorl run --executor ray`` started a local Ray) Ray 2.60's drivers sent a
    token the head refused, and the test failed.
    """
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    port = _free_port()
    temp = Path("/tmp") / f"ecorl-ray-{os.getpid()}"  # Ray's socket paths must stay short
    log = open(tmp_path / "ray.log", "w")
    proc = subprocess.Popen([RAY, "start", "--head", "--block", "--port", str(port), "--num-cpus", "2",
                             "--include-dashboard", "false", "--disable-usage-stats", "--temp-dir", str(temp)],
                            start_new_session=True, stdout=log, stderr=subprocess.STDOUT)
    try:
        yield f"127.0.0.1:{port}"
    finally:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            pass
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # whatever of this group is still alive
        except ProcessLookupError:
            pass
        proc.wait()
        log.close()
        subprocess.run(["rm", "-rf", str(temp)], check=False)


def _layout(root: Path) -> set[tuple[str, ...]]:
    """Relative paths of the result files that do not depend on timing."""
    return {p.relative_to(root).parts for p in root.rglob("*") if p.is_file()}


def _drop_timing(rows: list[str]) -> list[str]:
    """metrics.csv lines without their last column (steps_per_s, a timing)."""
    return [r.rsplit(",", 1)[0] for r in rows]


def test_ray_executor_gives_the_local_layout(ray_head, tmp_path, cli):
    args = ("run", "rnd", "--budget", "smoke", "--condition", "static", "rnd", "--no-progress")  # with and without RND
    deadline = time.monotonic() + 60
    while True:  # the head needs a few seconds before it accepts drivers
        proc = cli(*args, "--executor", "ray", "--address", ray_head, "--out", str(tmp_path / "ray"), check=False)
        if proc.returncode == 0 or time.monotonic() > deadline:
            break
        time.sleep(2)
    assert proc.returncode == 0, proc.stderr
    assert "2 done" in proc.stderr
    cli(*args, "--out", str(tmp_path / "local"))
    assert _layout(tmp_path / "ray") == _layout(tmp_path / "local")
    again = cli(*args, "--executor", "ray", "--address", ray_head, "--out", str(tmp_path / "ray"))
    assert "2 skipped" in again.stderr
    for cond in ("static", "rnd"):
        ray_rows = (tmp_path / "ray" / "rnd" / "factory" / cond / "metrics.csv").read_text().splitlines()
        local_rows = (tmp_path / "local" / "rnd" / "factory" / cond / "metrics.csv").read_text().splitlines()
        assert _drop_timing(ray_rows) == _drop_timing(local_rows)


@pytest.mark.parametrize("address, message", [
    ("nonsense", "is not HOST:PORT"),
    ("head:port", "is not HOST:PORT"),
])
def test_a_malformed_cluster_address_is_refused(address, message):
    from train.experiments.executors import check_ray_address

    with pytest.raises(RuntimeError, match=message):
        check_ray_address(address)


def test_a_cluster_address_where_nothing_listens_is_refused_at_once():
    from train.experiments.executors import check_ray_address

    port = _free_port()  # closed again: nothing listens there
    with pytest.raises(RuntimeError, match=f"no Ray cluster answers at 127.0.0.1:{port} .*--executor local"):
        check_ray_address(f"127.0.0.1:{port}")
    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen()
        check_ray_address(f"ray://127.0.0.1:{listening.getsockname()[1]}")  # something answers: go on
    for local in (None, "auto", "local"):
        check_ray_address(local)
