"""Copy a finished condition's run directory into the shipped results, and print its seeds one by one.

    python tools/ship_run.py RUN_DIR DEST_DIR

RUN_DIR is what `ecorl run` wrote for one condition (`OUT/EXPERIMENT/TASK/CONDITION`); DEST_DIR is where it is
shipped (`docs/results/paper/EXPERIMENT/TASK/CONDITION`). Copied: `config.json`, `done.json`, `metrics.csv`,
`visits.npy` and `policies/`, plus the visitation snapshots the report's heat-maps draw (`heatmap_snapshot_files`);
never the checkpoint. A run shipped there before leaves nothing behind (`clear_replaced_run`). The experiment's
`experiment.json` is copied beside the task folders when missing. Then
`ecorl report DEST_EXPERIMENT --out DEST_EXPERIMENT` rebuilds the page.

The per-seed table printed after the copy (final and best validation success, largest |Q| at the end and at any
evaluation, the greedy top-action share at the end, the training reward per evaluation interval early and late)
is what a stop note or a verdict quotes; it reads only the shipped `metrics.csv`. Outside the package and its tests.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import statistics
import sys
from pathlib import Path

from train.experiments.jobs import RESULT_FILES, clear_run_files
from train.experiments.report.figures import heatmap_snapshot_files

COPIED_FILES = ("config.json", "done.json", "metrics.csv", "visits.npy")


def ship(run_dir: Path, dest: Path) -> None:
    """Copy the run's shipped files from `run_dir` to `dest` (refusing an unfinished run)."""
    if not (run_dir / "done.json").exists():
        sys.exit(f"error: {run_dir} has no done.json: the run has not finished; ship it when `ecorl run` ends")
    clear_replaced_run(dest)
    dest.mkdir(parents=True, exist_ok=True)
    for name in COPIED_FILES:
        shutil.copy2(run_dir / name, dest / name)
    if (run_dir / "policies").is_dir():
        shutil.copytree(run_dir / "policies", dest / "policies", dirs_exist_ok=True)
    for snapshot in heatmap_snapshot_files(run_dir):
        (dest / "visits").mkdir(exist_ok=True)
        shutil.copy2(snapshot, dest / "visits" / snapshot.name)
    experiment_file = run_dir.parent.parent / "experiment.json"
    if experiment_file.exists() and not (dest.parent.parent / "experiment.json").exists():
        shutil.copy2(experiment_file, dest.parent.parent / "experiment.json")


def clear_replaced_run(dest: Path) -> None:
    """Remove every result of a run shipped earlier to ``dest`` (`RESULT_FILES`, what ``--restart`` clears), so that
    none outlives it: the new run would not overwrite all its policies and heat-map snapshots, nor its film
    (`ecorl report` keeps a film made at the run's last step, and a re-run ends at the same step).
    """
    if dest.is_dir():
        clear_run_files(dest, RESULT_FILES)


def read_seeds(metrics_csv: Path) -> dict[int, list[dict[str, float]]]:
    """The metrics rows of each seed, in step order, every value a float (empty cells as nan)."""
    seeds: dict[int, list[dict[str, float]]] = {}
    with metrics_csv.open(newline="") as handle:
        for row in csv.DictReader(handle):
            values = {key: float(value) if value != "" else float("nan") for key, value in row.items()}
            seeds.setdefault(int(values["seed"]), []).append(values)
    for rows in seeds.values():
        rows.sort(key=lambda values: values["step"])
    return seeds


def seed_line(seed: int, rows: list[dict[str, float]]) -> str:
    """One seed's summary: final/best success, largest |Q| final/any, top-action share, early/late training reward."""
    fifth = max(1, len(rows) // 5)
    early = statistics.fmean(row["train_reward"] for row in rows[:fifth])
    late = statistics.fmean(row["train_reward"] for row in rows[-fifth:])
    best = max(rows, key=lambda row: row["success"])
    last = rows[-1]
    return (
        f"seed {seed}: final {last['success']:.0%}, best {best['success']:.0%} at {int(best['step'])}; "
        f"max|Q| final {last['max_q']:.3g}, any {max(row['max_q'] for row in rows):.3g}; "
        f"top action {last.get('top_action_share', float('nan')):.0%}; "
        f"train reward per interval first fifth {early:.3g}, last fifth {late:.3g}"
    )


def main() -> None:
    """Parse the command line, copy, and print the per-seed table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path, help="OUT/EXPERIMENT/TASK/CONDITION as `ecorl run` wrote it")
    parser.add_argument("dest", type=Path, help="docs/results/paper/EXPERIMENT/TASK/CONDITION")
    args = parser.parse_args()
    ship(args.run_dir, args.dest)
    done = json.loads((args.dest / "done.json").read_text())
    print(
        f"shipped {args.run_dir} -> {args.dest} ({done['seeds']} seeds, {done['total_steps']} steps, "
        f"{done['seconds'] / 60:.0f} min)"
    )
    for seed, rows in sorted(read_seeds(args.dest / "metrics.csv").items()):
        print(seed_line(seed, rows))


if __name__ == "__main__":
    main()
