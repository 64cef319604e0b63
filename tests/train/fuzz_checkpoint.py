"""Seeded mutations of a real checkpoint, each re-signed as ecorl signs it and resumed.

Run as a script (in a subprocess, so that a crash of compiled code is seen as a failure, not as the end of
the test run)::

    python fuzz_checkpoint.py RUN_DIR WORK_DIR SEED COUNT STEPS [--all] [--only TOP_LEVEL_KEY]
    python fuzz_checkpoint.py resume STEPS RUN_DIR...
    python fuzz_checkpoint.py cli CASES.json      (each case: [label, ecorl arguments])

For each mutation: copy RUN_DIR, change one value of its checkpoint (a world field, a replay pointer, a
random-generator state, a weight, a counter, ...), rewrite it with `train.storage.checkpoint.write_checkpoint` (which
recomputes every digest), then ``ecorl train TASK --resume --steps STEPS``. One JSON line per case on stdout:
its label, the exit status and what it printed on stderr (or the exception that escaped).
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch


def leaves(tree: Any, path: tuple = ()) -> list[tuple]:
    """Every path into ``tree`` (dict keys and list indices), containers included."""
    out = [path]
    if isinstance(tree, dict):
        for key, value in tree.items():
            out += leaves(value, (*path, key))
    elif isinstance(tree, list):
        for i, value in enumerate(tree):
            out += leaves(value, (*path, i))
    return out


def get(tree: Any, path: tuple) -> Any:
    """The node at ``path``."""
    for key in path:
        tree = tree[key]
    return tree


def kinds_of(node: Any) -> list[str]:
    """The mutations that apply to a node."""
    if isinstance(node, (np.ndarray, torch.Tensor)):
        kinds = ["big", "negative", "shape", "dtype"]
        if node.dtype in (np.float32, np.float64, torch.float32, torch.float64, np.float16, torch.float16):
            kinds += ["nan", "inf"]
        if node.dtype in (np.uint8, torch.uint8):
            kinds.append("all255")
        size = node.size if isinstance(node, np.ndarray) else node.numel()
        return kinds if size else ["shape", "dtype"]
    if isinstance(node, bool):
        return ["text", "none"]
    if isinstance(node, int):
        return ["negative", "huge", "float", "text", "none"]
    if isinstance(node, float):
        return ["nan", "inf", "text", "none"]
    if isinstance(node, str):
        return ["empty", "number"]
    if isinstance(node, dict):
        return ["drop"] if node else ["none"]
    if isinstance(node, list):
        return ["drop", "none"] if node else ["none"]
    return ["text"]


def _mutate_array(node: Any, kind: str, rng: np.random.Generator) -> Any:
    tensor = isinstance(node, torch.Tensor)
    a = node.numpy().copy() if tensor else node.copy()
    flat = a.reshape(-1)
    i = int(rng.integers(flat.size)) if flat.size else 0
    if kind == "big":
        flat[i] = np.iinfo(a.dtype).max if a.dtype.kind in "iu" else (True if a.dtype.kind == "b" else 1e30)
        if a.dtype.kind == "i":
            flat[i] = 10**9 if rng.random() < 0.5 else np.iinfo(a.dtype).max
    elif kind == "negative":
        flat[i] = -1 if a.dtype.kind != "u" else np.iinfo(a.dtype).max
    elif kind in ("nan", "inf"):
        flat[i] = np.nan if kind == "nan" else np.inf
    elif kind == "all255":
        a[...] = 255
    elif kind == "shape":
        a = a[..., :-1] if a.ndim else a.reshape(1)
    elif kind == "dtype":
        a = a.astype(np.float64 if a.dtype != np.float64 else np.int8)
    return torch.from_numpy(np.ascontiguousarray(a)) if tensor else a


def mutate(node: Any, kind: str, rng: np.random.Generator) -> Any:
    """A mutated copy of ``node``."""
    if isinstance(node, (np.ndarray, torch.Tensor)):
        return _mutate_array(node, kind, rng)
    simple = {"negative": -1, "huge": 2**70, "float": 0.5, "text": "x", "none": None, "nan": float("nan"),
              "inf": float("inf"), "empty": "", "number": 7}
    if kind in simple:
        return simple[kind]
    if kind == "drop" and isinstance(node, dict):
        return dict(list(node.items())[1:])
    return node[:-1]


def cases(state: dict[str, Any], rng: np.random.Generator, count: int | None, prefix: str | None = None
          ) -> list[tuple[tuple, str]]:
    """(path, kind) of ``count`` mutations drawn without replacement (all of them when count is None), only
    under the top-level key ``prefix`` when given.
    """
    every = [(path, kind) for path in leaves(state) if path and prefix in (None, path[0])
             for kind in kinds_of(get(state, path))]
    if count is None or count >= len(every):
        return every
    # every world field and the replay pointers first: the values the compiled code indexes with
    risky = [c for c in every if c[0][:1] in (("env",), ("replay",), ("rngs",), ("torch_rng",))]
    rest = [c for c in every if c not in risky]
    pick = [risky[i] for i in rng.permutation(len(risky))] + [rest[i] for i in rng.permutation(len(rest))]
    return sorted(pick[:count], key=every.index)


def run_cli(label: str, argv: list[str]) -> dict:
    """``ecorl ARGV`` in this process: its exit status and stderr (or the exception that escaped); what it prints
    on stdout (its result) is dropped, since this script's own stdout carries one JSON line per case.
    """
    from train.cli import main

    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    except BaseException as exc:  # what must never happen: an exception past the one-line error path
        return {"case": label, "rc": "exception", "err": f"{type(exc).__name__}: {exc}"[:300]}
    return {"case": label, "rc": rc, "err": err.getvalue().strip()}


def resume(run_dir: Path, steps: int, label: str) -> dict:
    """``ecorl train TASK --resume --out RUN_DIR --steps STEPS``."""
    from train.storage.checkpoint import read_checkpoint

    try:
        task = read_checkpoint(run_dir / "checkpoint.npz", keys=[])["config"]["env"]["task"]
        task = task if isinstance(task, str) else "salad"
    except Exception:  # a mutated manifest or configuration: the trainer must refuse it
        task = "salad"
    return run_cli(label, ["train", task, "--resume", "--out", str(run_dir), "--steps", str(steps), "--no-progress"])


def run_case(source: Path, work: Path, path: tuple, kind: str, rng: np.random.Generator, steps: int) -> dict:
    """Mutate one copy of ``source`` and resume it; what happened."""
    from train.storage.checkpoint import read_checkpoint, write_checkpoint

    shutil.rmtree(work, ignore_errors=True)
    shutil.copytree(source, work)
    state = read_checkpoint(work / "checkpoint.npz")
    parent = get(state, path[:-1])
    parent[path[-1]] = mutate(parent[path[-1]], kind, rng)
    write_checkpoint(work / "checkpoint.npz", state)
    return resume(work, steps, "/".join(map(str, path)) + f":{kind}")


def main(argv: list[str]) -> int:
    """Run the mutation cases, or resume each DIR, or run each CLI case; one JSON line each."""
    if argv[0] == "cli":  # a JSON file of [label, argv] pairs
        for label, args in json.loads(Path(argv[1]).read_text()):
            began = time.monotonic()
            print(json.dumps({**run_cli(label, args), "seconds": round(time.monotonic() - began, 2)}), flush=True)
        return 0
    if argv[0] == "resume":
        for run_dir in argv[2:]:
            print(json.dumps(resume(Path(run_dir), int(argv[1]), run_dir)), flush=True)
        return 0
    source, work, seed, count, steps = Path(argv[0]), Path(argv[1]), int(argv[2]), int(argv[3]), int(argv[4])
    from train.storage.checkpoint import read_checkpoint

    rng = np.random.default_rng(seed)
    state = read_checkpoint(source / "checkpoint.npz")
    prefix = argv[argv.index("--only") + 1] if "--only" in argv else None
    for i, (path, kind) in enumerate(cases(state, rng, None if "--all" in argv else count, prefix)):
        print(json.dumps(run_case(source, work / f"case{i}", path, kind, rng, steps)), flush=True)
        shutil.rmtree(work / f"case{i}", ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
