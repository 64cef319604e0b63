"""train/ is layered: config and tasks <- agent <- the training loop <- experiments <- cli, nothing upward.

Every import in every module counts, those inside functions too (the heavy ones are lazy). The env packages
depend on `ecology` only, and `ecology` on nothing of ours.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

LAYERS = ("base", "agent", "loop", "experiments", "cli")
"""The layers of train/, lowest first."""


def layer(module: str) -> str:
    """The layer of a train module: its subpackage, else base (config, tasks) or loop (the rest)."""
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in ("agent", "experiments", "cli"):
        return parts[1]
    return "base" if len(parts) == 1 or parts[1] in ("config", "tasks") else "loop"


def module_name(path: Path) -> str:
    """The dotted name of a source file of the repository."""
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(path: Path) -> set[str]:
    """Every module ``path`` imports, at the top or inside a function (absolute imports only)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module)
            out |= {f"{node.module}.{alias.name}" for alias in node.names}
    return out


def sources(package: str) -> list[Path]:
    """The Python files of one of our packages."""
    return sorted((REPO / package).rglob("*.py"))


@pytest.mark.parametrize("path", sources("train"), ids=lambda p: str(p.relative_to(REPO)))
def test_train_modules_import_only_their_layer_or_lower(path):
    mine = LAYERS.index(layer(module_name(path)))
    upward = sorted(name for name in imported(path)
                    if name.startswith("train.") and LAYERS.index(layer(name)) > mine)
    assert not upward, f"{module_name(path)} ({LAYERS[mine]}) imports from a higher layer: {upward}"


@pytest.mark.parametrize("package, allowed", [("ecology", {"ecology"}), ("gridtasks", {"ecology", "gridtasks"}),
                                              ("foodcollector", {"ecology", "foodcollector"})])
def test_env_packages_depend_on_ecology_only(package, allowed):
    ours = {"ecology", "gridtasks", "foodcollector", "train"}
    for path in sources(package):
        used = {name.split(".")[0] for name in imported(path)} & ours
        assert used <= allowed, f"{module_name(path)} imports {sorted(used - allowed)}"


def test_importing_the_agent_loads_nothing_of_the_pipeline():
    script = ("import sys, train.agent.dqn, train.agent.replay, train.agent.rnd\n"
              "print(' '.join(m for m in sys.modules if m.startswith(('train.experiments', 'train.cli', "
              "'train.loop.trainer'))))")
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_importing_the_trainer_loads_nothing_of_the_pipeline():
    script = ("import sys, train.loop.trainer, train.storage.policy\n"
              "print(' '.join(m for m in sys.modules if m.startswith(('train.experiments', 'train.cli'))))")
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_the_command_line_loads_torch_only_for_a_command_that_needs_it():
    """``ecorl --help`` and a mistyped option answer at once: torch takes seconds to import."""
    script = "import sys, train.cli\ntrain.cli.build_parser()\nprint('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
