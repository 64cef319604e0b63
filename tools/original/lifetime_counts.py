"""What a released non-episodic run did in training: its environment's lifetime counters, at chosen steps.

The released environments count, from their last reset, every pick-up (``pickup_<object>``) and every object made
(``made_<object>``; factory's ``made_lava`` is a delivery) and report the counts in each step's info; rlkit logs
their mean over each epoch's 500 training steps in ``progress.csv`` (``evaluation/env_infos/<key> Mean``). A
non-episodic run is never reset, so these are lifetime counts: the difference between two steps is what the
behaviour policy did in between. Reads the files `run_released.py` writes and `docs/results/original/` ships
(``progress.csv`` or ``progress.csv.gz``, the continued parts in ``resumed-EPOCH/``)::

    python tools/original/lifetime_counts.py docs/results/original/factory-fig4/dynamic-reset-free-waypoint \
        --at 250000 500000 1000000 1225000
"""

from __future__ import annotations

import argparse
import csv
import gzip
import io
from pathlib import Path

from compare import at  # the nearest evaluation within 2 500 steps, as compare.py matches steps

KEYS = ("pickup_axe", "made_axe", "made_lava")
"""The counters shown by default: factory's axes picked up, axes made, deliveries."""


def read_progress(path: Path) -> list[dict[str, str]]:
    """The rows of one ``progress.csv`` or ``progress.csv.gz``."""
    raw = gzip.decompress(path.read_bytes()) if path.suffix == ".gz" else path.read_bytes()
    return list(csv.DictReader(io.StringIO(raw.decode())))


def epochs(seed_dir: Path) -> list[dict[str, str]]:
    """Every epoch's row of one seed, the run's first part then its resumed parts (a later part's row wins)."""
    parts = sorted(seed_dir.glob("progress.csv*")) + sorted(
        (p for p in seed_dir.glob("resumed-*/progress.csv*")), key=lambda p: int(p.parent.name.split("-")[1]))
    rows: dict[int, dict[str, str]] = {}
    for part in parts:
        rows.update({int(row["Epoch"]): row for row in read_progress(part)})
    return [rows[epoch] for epoch in sorted(rows)]


def count_at(rows: list[dict[str, str]], step: int, key: str) -> float | None:
    """The counter ``key`` in the epoch nearest ``step`` (compare.py's `at`), else None."""
    steps = [{"step": float(r["evaluation/num steps total"]), "row": r} for r in rows]
    best = at(steps, step)
    return None if best is None else float(best["row"][f"evaluation/env_infos/{key} Mean"])


def main(argv: list[str] | None = None) -> None:
    """Print a table: a row per seed and step, a column per counter."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("released", type=Path, help="a folder of released runs, seed<N>/")
    parser.add_argument("--at", type=int, nargs="+", required=True, help="training steps to read the counters at")
    parser.add_argument("--keys", nargs="+", default=list(KEYS), help=f"counters (default: {' '.join(KEYS)})")
    args = parser.parse_args(argv)
    print("| seed | step | " + " | ".join(args.keys) + " |")
    print("|---|---|" + "---|" * len(args.keys))
    for seed_dir in sorted(args.released.glob("seed*"), key=lambda p: int(p.name[4:])):
        rows = epochs(seed_dir)
        for step in args.at:
            counts = [count_at(rows, step, key) for key in args.keys]
            cells = ["—" if c is None else f"{c:,.0f}" for c in counts]
            print(f"| {seed_dir.name[4:]} | {step:,} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
