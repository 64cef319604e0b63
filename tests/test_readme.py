"""Every command the README shows runs as printed in the set-up's environment (training shortened to seconds).

The README's shell blocks start with ``source .venv/bin/activate``; here the environment is the one running the
tests, its ``bin/`` first on PATH, in a fresh working directory. A command that trains (``--steps N``) trains 1 200
steps instead; the two set-up commands (``make ...``) are what runs this suite, so they are not run again.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
SHORT_TRAINING = ["--eval-every", "500", "--eval-rollouts", "4", "--updates-per-epoch", "20"]


CLI_DOC = REPO / "docs" / "cli.md"


def blocks(language: str, page: Path = README) -> list[str]:
    """The fenced code blocks in ``language`` of ``page`` (the README), in order."""
    return re.findall(rf"```{language}\n(.*?)```", page.read_text(), re.S)


def commands() -> list[str]:
    """The shell commands of the README's bash blocks, comments dropped, set-up lines left out."""
    out = []
    for block in blocks("bash"):
        for line in block.splitlines():
            command = line.split("#", 1)[0].strip()
            if command and not command.startswith(("make ", "source ")):
                out.append(command)
    return out


def shortened(command: str) -> list[str]:
    """``command`` as arguments, any ``--steps N`` cut to 1 200 with a short evaluation."""
    args = shlex.split(command)
    if "--steps" in args:
        args[args.index("--steps") + 1] = "1200"
        args += SHORT_TRAINING
    return args


def test_the_readme_shows_both_set_up_commands_and_how_to_enter_the_environment():
    text = README.read_text()
    assert "make demo" in text and "make test" in text and "source .venv/bin/activate" in text
    assert len(text.splitlines()) <= 120
    for block in blocks("bash")[1:]:  # every block after the two set-up commands enters the environment first
        assert block.startswith("source .venv/bin/activate\n"), block


def test_every_readme_command_runs_as_printed(tmp_path):
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
           "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"}
    found = commands()
    assert any(c.startswith("ecorl train") for c in found) and any(c.startswith("ecorl report") for c in found)
    for command in found:
        proc = subprocess.run(shortened(command), cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
        said = f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"
        assert proc.returncode == 0, f"{command!r} exited {proc.returncode}:\n{said}"
    untracked = {p.relative_to(tmp_path).parts[0] for p in tmp_path.rglob("*") if p.is_file()}
    assert untracked <= {"runs", "results"}, untracked  # everything a command writes goes under runs/ or results/


PYTHON_BLOCKS = [(page, i) for page in (README, CLI_DOC) for i in range(len(blocks("python", page)))]


@pytest.mark.parametrize("page, index", PYTHON_BLOCKS, ids=[f"{p.name}-{i}" for p, i in PYTHON_BLOCKS])
def test_every_python_block_of_the_readme_and_the_cli_page_runs(page, index, tmp_path):
    proc = subprocess.run([sys.executable, "-c", blocks("python", page)[index]], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"})
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_the_package_data_every_installation_needs_is_declared():
    """The paper's numbers and the trained policies live in train/data and travel in wheels: every file there
    matches a package-data pattern of pyproject.toml (a new file type would otherwise be left out of wheels).
    """
    tomllib = pytest.importorskip("tomllib")
    patterns = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["train"]
    data = REPO / "train" / "data"
    files = [p for p in data.rglob("*") if p.is_file() and "__pycache__" not in p.parts]
    assert {p.parent.name for p in files} == {"paper", "policies"}
    missing = [p for p in files if not any(p.relative_to(REPO / "train").match(pattern) for pattern in patterns)]
    assert not missing, f"not in pyproject.toml's package-data: {missing}"
