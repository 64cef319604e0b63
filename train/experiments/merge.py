r"""Join runs that each trained a part of one condition's seeds into the run directory of all of them.

So a condition's seeds can train on several cores or machines, e.g. ten seeds as two runs of five::

    ecorl run shaping --budget paper --task foodcollector --condition no-shaping --seeds 5 --out part-a
    ecorl run shaping --budget paper --task foodcollector --condition no-shaping --seeds 5 --first-seed 5 \
        --out part-b
    ecorl merge-seeds part-a/shaping/foodcollector/no-shaping part-b/shaping/foodcollector/no-shaping \
        --out results/shaping/foodcollector/no-shaping

The seeds of a run learn independently (each its own worlds, network, replay buffer and random streams), and on
the CPU their gradient steps do not depend on the seeds beside them, so the merged metrics are those of one
process training all the seeds (``tests/train/experiments/test_exp_merge.py`` trains both ways and compares
exactly), but for rare greedy near ties that the batched one-observation forward pass can break differently and,
on grid tasks, a process of 16 or more seeds, whose sparse first layer rounds otherwise (docs/cli.md). The
merged directory has no checkpoint: it holds the finished results (config.json, metrics.csv, the visitation
counts, policies/ and, where every part has one, done.json), which the report reads and whose policies
``ecorl video`` and ``ecorl evaluate`` play; it cannot be trained further.
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from train.config import TrainConfig
from train.experiments.jobs import DONE_FILE, read_done
from train.storage.fileio import atomic_dir, atomic_text
from train.storage.policy import export_run_policies, load_run
from train.storage.rundir import (
    EXPERIMENT_FILE,
    LOCK_NAME,
    MAX_METRIC_ROWS,
    MAX_METRICS_BYTES,
    METRIC_COLUMNS,
    RunDir,
    RunDirError,
    read_visits,
    write_visits,
)
from train.storage.safeio import read_text

SPLIT_SETTINGS = ("seeds", "first_seed")
"""The settings in which the parts of one run differ."""


@dataclass
class _Part:
    """One finished part run: its directory, configuration, metrics rows and online networks."""

    path: Path
    cfg: TrainConfig
    step: int
    rows: list[dict[str, str]]
    online: torch.Tensor

    @property
    def seed_range(self) -> str:
        """Its seeds as 'first-last'."""
        return f"{self.cfg.run.first_seed}-{self.cfg.run.first_seed + self.cfg.run.seeds - 1}"


def merge_seed_runs(parts: Sequence[str | Path], out: str | Path) -> Path:
    """Write into ``out`` (a new or empty directory) the run of all the seeds of ``parts``: finished runs
    (checkpoint at the last step) of one configuration but their seeds, which must follow one another without
    a gap. Returns ``out``; `ValueError` or `RunDirError` (naming the part and the fix) when they do not fit.

    The merged run is built in a hidden folder beside ``out`` and moved into place whole, so an interrupted or
    failed merge leaves ``out`` as it was (the hidden folder says what it is); its policies and done marker,
    which name the run by where it lies, are written once it is in place, and a failure there removes it.
    """
    if len(parts) < 2:
        raise ValueError("name at least two run directories to merge (each trained some of the seeds)")
    out = Path(out).resolve()
    if out.is_symlink() or (out.exists() and (not out.is_dir() or any(out.iterdir()))):
        raise RunDirError(f"{out} is not an empty directory; merge into a new --out (or empty this one first)")
    loaded = sorted((_read_part(Path(p)) for p in parts), key=lambda part: part.cfg.run.first_seed)
    _check_parts(loaded)
    cfg = loaded[0].cfg.replace(seeds=sum(part.cfg.run.seeds for part in loaded))
    with atomic_dir(out, "merging") as building:
        run = RunDir(building)
        run.prepare(cfg, resume=False)  # writes config.json
        try:
            run.write_metrics(sorted((row for part in loaded for row in part.rows),
                                     key=lambda row: (int(row["step"]), int(row["seed"]))))
            _write_visits(run.path, loaded)
        finally:
            run.unlock()
        (building / LOCK_NAME).unlink(missing_ok=True)
    try:
        state = {"config": cfg.to_dict(), "step": loaded[0].step,
                 "agent": {"online": torch.cat([part.online for part in loaded])}}
        _write_experiment_file(out, loaded[0].path)  # first: the policies name their run after it
        export_run_policies(out, state)
        _write_done(out, cfg, loaded)
    except BaseException:
        shutil.rmtree(out, ignore_errors=True)
        raise
    return out


def _read_part(path: Path) -> _Part:
    """A part run, refused unless it finished (its checkpoint at its last step) and has metrics."""
    run_dir, state = load_run(path)
    cfg = TrainConfig.from_dict(state["config"])
    step = int(state["step"])
    if step < cfg.total_steps:
        raise RunDirError(f"{run_dir} stands at step {step:,} of {cfg.total_steps:,}: finish it first (resume it "
                          f"with the command that started it), then merge")
    rows = _read_metric_rows(run_dir / "metrics.csv")
    seeds = {int(row["seed"]) for row in rows}
    if not rows or not seeds <= set(cfg.run.seed_list):
        raise RunDirError(f"{run_dir / 'metrics.csv'} holds no evaluation of this run's seeds "
                          f"{cfg.run.seed_list}; restore it, or delete it and rebuild it with "
                          f"'ecorl train TASK --resume --out {run_dir}'")
    return _Part(run_dir, cfg, step, rows, state["agent"]["online"])


def _read_metric_rows(path: Path) -> list[dict[str, str]]:
    """The rows of a part's metrics.csv, each cell checked: known columns only, a number in every cell (step and
    seed whole numbers of at most 2**53), no short row; else `RunDirError` naming the file and the line.
    """
    reader = csv.DictReader(io.StringIO(read_text(path, MAX_METRICS_BYTES), newline=""))
    header = reader.fieldnames or []
    rows = []
    for row in reader:
        if reader.line_num > MAX_METRIC_ROWS:
            raise RunDirError(f"{path} holds more than {MAX_METRIC_ROWS:,} rows, more than a run of ecorl writes; "
                              f"restore the part's file")
        rows.append(row)
    unknown = sorted(set(header) - set(METRIC_COLUMNS))
    if unknown or not {"step", "seed"} <= set(header):
        raise RunDirError(f"{path} is not an ecorl metrics file (its columns {header[:6]}); restore the part's file")
    for number, row in enumerate(rows, start=2):
        try:
            if None in row.values() or None in row:
                raise ValueError("a short or long row")
            values = {k: float(v) for k, v in row.items() if v != ""}
            if not all(0 <= values[k] <= 2**53 and values[k] == int(values[k]) for k in ("step", "seed")):
                raise ValueError("step and seed must be whole numbers from 0 to 2**53")
        except (KeyError, ValueError) as err:
            raise RunDirError(f"{path} line {number} is not a metrics row ({err}); restore the part's file") from None
    return rows


def _check_parts(parts: list[_Part]) -> None:
    """Refuse parts that are not one run's seeds: other settings, overlapping or missing seeds, other
    evaluations or visitation snapshots.
    """
    first = parts[0]
    same = {k: v for k, v in first.cfg.identity().items() if k not in SPLIT_SETTINGS}
    for part in parts[1:]:
        other = {k: v for k, v in part.cfg.identity().items() if k not in SPLIT_SETTINGS}
        diffs = [f"{k}: {same[k]!r} vs {other.get(k)!r}" for k in same if same[k] != other.get(k)]
        if diffs:
            raise ValueError(f"{part.path} was trained with other settings than {first.path} "
                             f"({'; '.join(diffs)}); merge only parts of one condition")
    for before, after in zip(parts, parts[1:]):
        follows = before.cfg.run.first_seed + before.cfg.run.seeds
        if after.cfg.run.first_seed != follows:
            gap = "overlap" if after.cfg.run.first_seed < follows else "leave a gap"
            raise ValueError(f"the seeds of {before.path} ({before.seed_range}) and {after.path} "
                             f"({after.seed_range}) {gap}; train parts with --first-seed set so that each begins "
                             f"where the one before ends")
    for part in parts[1:]:
        for what, ours, theirs in (("evaluations", _eval_steps(part), _eval_steps(first)),
                                   ("visitation snapshots", _snapshots(part.path), _snapshots(first.path))):
            if ours != theirs:
                raise ValueError(f"{part.path} and {first.path} hold different {what}; merge only finished "
                                 f"parts of one condition")


def _eval_steps(part: _Part) -> set[int]:
    """The steps at which the part evaluated its seeds."""
    return {int(row["step"]) for row in part.rows}


def _snapshots(run_dir: Path) -> list[str]:
    """The names of a run's visitation snapshots (``visits/STEP.npy``)."""
    return sorted(p.name for p in (run_dir / "visits").glob("*.npy"))


def _write_visits(out: Path, parts: list[_Part]) -> None:
    """The parts' visitation counts, latest and every snapshot, joined along the seed axis."""
    names = [f"visits/{name}" for name in _snapshots(parts[0].path)]
    names += ["visits.npy"] if (parts[0].path / "visits.npy").exists() else []
    (out / "visits").mkdir(exist_ok=True)
    for name in names:
        write_visits(out / name, np.concatenate([read_visits(part.path / name) for part in parts]))


def _write_experiment_file(out: Path, part: Path) -> None:
    """Where the parts are conditions of an ``ecorl run`` experiment and ``out`` is the same condition's
    directory in an experiment directory that has no experiment file yet, write the experiment's description
    there (so the report finds the merged run): the known experiment's own (`trusted_info`), never the part's
    bytes, and only for a task and condition it has.
    """
    from train.experiments.report.runs import trusted_info

    source, target = part.parent.parent, out.parent.parent / EXPERIMENT_FILE
    same_place = (out.name, out.parent.name) == (part.name, part.parent.name)
    if not same_place or not (source / EXPERIMENT_FILE).is_file() or os.path.lexists(target):
        return
    info = trusted_info(source)
    conditions = [c.get("name") for c in info.get("tasks", {}).get(part.parent.name, [])]
    if part.name not in conditions:
        raise RunDirError(f"{source / EXPERIMENT_FILE} does not list {part.parent.name}/{part.name}, the part's own "
                          f"condition; restore it or merge into a --out outside an experiment directory")
    atomic_text(target, json.dumps(info, indent=2) + "\n")


def _write_done(out: Path, cfg: TrainConfig, parts: list[_Part]) -> None:
    """A done marker for the merged run where every part has one (parts of an ``ecorl run`` condition)."""
    markers = []
    for part in parts:
        marker = read_done(part.path)
        if marker is None:
            return
        markers.append({"seeds": part.seed_range, **{k: marker[k] for k in ("seconds", "finished") if k in marker}})
    done: dict[str, Any] = {"total_steps": cfg.total_steps, "seeds": cfg.run.seeds,
                            "finished": time.strftime("%Y-%m-%dT%H:%M:%S"), "merged_from": markers}
    atomic_text(out / DONE_FILE, json.dumps(done, indent=2) + "\n")
