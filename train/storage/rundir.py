"""A run directory: resolved config, metrics, visitation counts and an atomically written checkpoint.

Layout::

    config.json      the resolved TrainConfig (rewritten when the run is resumed)
    metrics.csv      one row per evaluation and seed (`METRIC_COLUMNS`)
    visits.npy       (seeds, rows, cols) lifetime visitation counts, [y, x], as of the latest evaluation
    visits/STEP.npy  the same, kept at every evaluation (for heat-maps over training)
    checkpoint.npz   everything needed to continue the run exactly, as data only (`train.storage.checkpoint`)
    .lock            advisory lock of the process writing the run (its pid while held)
    tensorboard/     optional TensorBoard logs

See ``docs/run-directories.md``.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from train.config import TrainConfig
from train.loop.memory import checkpoint_limit
from train.storage.checkpoint import CHECKPOINT_NAME, LEGACY_NAME, CheckpointError, legacy_message, read_checkpoint
from train.storage.checkpoint import write_checkpoint as _write_checkpoint
from train.storage.fileio import FileLock, LockedError, atomic_file, atomic_write, is_temporary
from train.storage.safeio import UnsafeFileError, load_json, open_regular, read_npy, real_dir

__all__ = ["ADDED_COLUMNS", "METRIC_COLUMNS", "LOCK_NAME", "RunDir", "RunDirError", "atomic_file", "atomic_write",
           "check_same_run", "read_visits", "write_visits"]

METRIC_COLUMNS = ("step", "seed", "epsilon", "loss", "max_q", "top_action", "top_action_share", "corner_share",
                  "success", "made", "return", "train_reward", "steps_per_s")
"""Columns of metrics.csv. ``loss`` is the mean TD loss of the gradient steps since the previous evaluation;
``max_q`` the largest |Q| the evaluation's forward passes produced (NaN if one was not finite; absent in
files written before it existed); ``top_action`` the greedy policy's most frequent action over the validation
rollouts' steps and ``top_action_share`` its share of them; ``corner_share`` the share of the training visits
since the previous evaluation that fell on the four corner cells inside the wall (the three collapse columns
are absent in files written before them); ``made`` the share of validation rollouts in which the task's product
was made (factory: an axe, whatever the goal; NaN for the food collector; absent before it existed); ``return``
is the mean validation return; ``train_reward`` the
summed training reward since the previous evaluation; ``steps_per_s`` environment steps per second per seed."""
MAX_METRIC_ROWS = 500_000
"""Most rows of a metrics.csv that a report or a merge reads (330 seeds evaluated 300 times are 99 000)."""
MAX_METRICS_BYTES = 64 << 20
"""Largest metrics.csv that a report or a merge reads (ecorl's runs write under 1 MB)."""
ADDED_COLUMNS = ("top_action", "top_action_share", "corner_share", "made")
"""The columns that files written before the collapse measurements lack (`METRIC_COLUMNS`); a checkpoint's rows
without them still load (read as NaN)."""

EXPERIMENT_FILE = "experiment.json"
"""Description of an experiment directory (``OUT/EXPERIMENT/``, whose runs are ``TASK/CONDITION/`` below it),
written by ``ecorl run``."""

LOCK_NAME = ".lock"
"""The lock file of a run directory (held by the one process that writes the run)."""

RUN_POLICIES_DIR = "policies"
"""Where a finished experiment run keeps its exported policies (``best.npz``, ``median.npz``)."""

FILM_NAME = "video.mp4"
"""A run's film, which `ecorl report` makes of its best seed (and `ecorl video` of a policy exported there)."""
VIDEO_INFO = "video.json"
"""Sidecar of a filmed run's ``video.mp4``: the seed filmed and the episodes solved."""
STRIP_NAME = "filmstrip.png"
"""Beside a filmed run's ``video.mp4``: its first episode as a row of frames (the paper's Fig. 11-12)."""
FILM_FILES = (FILM_NAME, VIDEO_INFO, STRIP_NAME)
"""What filming a run writes into its directory."""


SUBDIRS = ("visits", "tensorboard")
"""Directories inside a run directory that ecorl writes into (never through a link)."""

MAX_VISITS_BYTES = 256 << 20
"""Largest visitation array read back (a 10-seed run's are a few kilobytes; the limit stops a planted file)."""


class RunDirError(RuntimeError):
    """A run directory cannot be used as asked (the message says why and how to fix it)."""


class RunDir:
    """The files of one run (one condition, all its seeds)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._lock = FileLock(self.path / LOCK_NAME, f"run directory {self.path}",
                              "wait for it to finish (or stop it), or choose another --out")

    config_path = property(lambda self: self.path / "config.json")
    metrics_path = property(lambda self: self.path / "metrics.csv")
    checkpoint_path = property(lambda self: self.path / CHECKPOINT_NAME)
    legacy_checkpoint_path = property(lambda self: self.path / LEGACY_NAME)
    visits_path = property(lambda self: self.path / "visits.npy")

    def has_checkpoint(self) -> bool:
        """True if the directory holds a checkpoint (raises `RunDirError` for a pickled, format-1 one)."""
        if self.checkpoint_path.exists():
            return True
        if self.legacy_checkpoint_path.exists():
            raise RunDirError(legacy_message(self.legacy_checkpoint_path))
        return False

    def is_empty(self) -> bool:
        """True if the directory is missing or holds nothing but its lock and interrupted temporaries (and
        the config.json of a run stopped before its first checkpoint, which holds no progress).
        """
        return not self.path.exists() or self.never_started()

    def never_started(self) -> bool:
        """True if the directory holds nothing but a lock, temporaries and config.json: a run stopped (or out
        of disk) before its first checkpoint was complete.
        """
        return self.path.is_dir() and all(p.name in (LOCK_NAME, "config.json") or is_temporary(p.name)
                                          for p in self.path.iterdir())

    def lock(self) -> None:
        """Take the run's lock for the rest of this process (or until `unlock`); refuse if another holds it."""
        if self._lock.held:
            return
        if self.path.exists() and not self.path.is_dir():
            raise RunDirError(f"--out {self.path} is a file, not a directory; choose a directory path")
        try:
            real_dir(self.path)
            self._lock.acquire()
            for name in SUBDIRS:  # refused now, not at the first evaluation
                if (self.path / name).is_symlink() or (self.path / name).exists():
                    real_dir(self.path / name)
        except (LockedError, UnsafeFileError) as err:
            self._lock.release()
            raise RunDirError(str(err)) from None
        for stale in self.path.iterdir():  # left by a killed writer; this process is now the only one
            if is_temporary(stale.name) and stale.is_file():
                stale.unlink(missing_ok=True)

    def unlock(self) -> None:
        """Release the run's lock."""
        self._lock.release()

    def prepare(self, cfg: TrainConfig, resume: bool) -> None:
        """Check the directory fits the request and lock it; on a fresh start write config.json."""
        if self.path.exists() and not self.path.is_dir():
            raise RunDirError(f"--out {self.path} is a file, not a directory; choose a directory path")
        if resume:
            if not self.path.is_dir() or not self.has_checkpoint():
                raise RunDirError(self._no_checkpoint_message())
            self.lock()
            return
        if not self.is_empty():
            raise RunDirError(self._occupied_message(cfg))
        self.lock()
        if not self.is_empty():  # another process filled it between the check and the lock
            raise RunDirError(f"run directory {self.path} is not empty; choose another --out")
        self.write_config(cfg)

    def _occupied_message(self, cfg: TrainConfig) -> str:
        """Why a fresh run of ``cfg`` cannot start in this non-empty directory, and what to do: --resume only where
        the run it holds was made with the settings asked for (the default --out names the knobs, not e.g. --lr).
        """
        try:
            diffs = setting_differences(TrainConfig.from_dict(load_json(self.path / "config.json")), cfg)
        except (OSError, UnsafeFileError, ValueError, TypeError, KeyError):
            diffs = []
        if diffs:
            return (f"run directory {self.path} holds a run made with other settings ({'; '.join(diffs)}); choose "
                    f"another --out for this one (or delete the directory)")
        if not (self.path / "config.json").exists():
            return (f"{self.path} is not empty and holds no run (no config.json); choose another --out, or an empty "
                    f"or new directory")
        return (f"run directory {self.path} is not empty. Pass --resume to continue the run it holds, or choose "
                f"another --out (or delete the directory) to start afresh.")

    def _no_checkpoint_message(self) -> str:
        """Why a directory without a checkpoint cannot be resumed, and what to do instead."""
        if self.never_started() and not (self.path / "config.json").exists():
            return (f"cannot resume: {self.path} holds no run (no config.json, no {CHECKPOINT_NAME}); drop --resume "
                    f"to start one there")
        if self.never_started():
            return (f"cannot resume: the run in {self.path} was stopped before its first {CHECKPOINT_NAME} was "
                    f"complete, so it holds no progress; start it afresh with the same command without --resume")
        return (f"cannot resume: {self.path} holds no {CHECKPOINT_NAME}. Start a fresh run (drop --resume) with an "
                f"empty or new --out directory.")

    def write_config(self, cfg: TrainConfig) -> None:
        """(Re)write config.json with ``cfg``."""
        atomic_write(self.config_path, (json.dumps(cfg.to_dict(), indent=2) + "\n").encode())

    def save_checkpoint(self, payload: dict[str, Any]) -> None:
        """Write ``payload`` as a data-only checkpoint (`train.storage.checkpoint`), atomically."""
        _write_checkpoint(self.checkpoint_path, payload)

    def read_checkpoint(self, keys: list[str] | None = None, limit: int | None = None) -> dict[str, Any]:
        """The verified checkpoint (only the arrays in ``keys`` when given, at most ``limit`` bytes of them);
        `RunDirError` if unusable.
        """
        if not self.path.exists():
            raise RunDirError(f"there is no run at {self.path}: nothing to resume (give the run's directory with "
                              f"--out, or train without --resume)")
        if not self.has_checkpoint() and self.never_started():
            raise RunDirError(self._no_checkpoint_message())
        if not self.has_checkpoint():
            raise RunDirError(f"{self.path} holds no {CHECKPOINT_NAME}; it is not a run directory of ecorl "
                              f"(or the run never reached its first checkpoint)")
        try:
            return read_checkpoint(self.checkpoint_path, keys, limit)
        except CheckpointError as err:
            raise RunDirError(str(err)) from None

    def saved_config(self) -> tuple[TrainConfig, int]:
        """The checkpoint's configuration and the step the run stands at (reads no arrays)."""
        from train.storage.statecheck import check_counter  # torch: only where a checkpoint is opened

        state = self.read_checkpoint(keys=[])
        try:
            return TrainConfig.from_dict(state["config"]), check_counter(state["step"], "step")
        except (KeyError, TypeError, ValueError) as err:
            raise RunDirError(f"{self.checkpoint_path} holds an unusable configuration ({err}); start a fresh "
                              f"run in another --out directory") from None

    def load_checkpoint(self, cfg: TrainConfig) -> dict[str, Any]:
        """Read and verify the checkpoint; refuse a corrupt one or one made with different settings."""
        payload = self.read_checkpoint(limit=checkpoint_limit(cfg))
        check_same_run(TrainConfig.from_dict(payload["config"]), cfg, self.checkpoint_path)
        return payload

    def restore_metrics(self, rows: list[dict[str, Any]] | None = None) -> bool:
        """Rebuild a deleted metrics.csv from the checkpoint's rows; True if it was rebuilt."""
        if self.metrics_path.exists():
            return False
        if rows is None:
            rows = self.read_checkpoint(keys=[]).get("rows", [])
        if not rows:
            return False
        self.write_metrics(rows)
        return True

    def write_metrics(self, rows: list[dict[str, Any]]) -> None:
        """Rewrite metrics.csv with ``rows`` (atomically, so a resumed run never shows stale rows)."""
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=METRIC_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
        atomic_write(self.metrics_path, buf.getvalue().encode())

    def save_visits(self, visits: np.ndarray, step: int) -> None:
        """Save the lifetime visitation counts (seeds, rows, cols) as the latest and as a snapshot."""
        for path in (self.visits_path, self.path / "visits" / f"{step:09d}.npy"):
            write_visits(path, visits)


def write_visits(path: Path, visits: np.ndarray) -> None:
    """Write one visitation array (``visits.npy`` or a snapshot ``visits/STEP.npy``) atomically."""
    buf = io.BytesIO()
    np.save(buf, visits)
    atomic_write(path, buf.getbuffer())


def read_visits(path: Path) -> np.ndarray:
    """Read one visitation array: a regular file, its header and size checked before its data is read, and the
    array itself counts (integers, seeds x rows x columns), else `UnsafeFileError`.
    """
    with open_regular(path) as f:
        visits = read_npy(f, MAX_VISITS_BYTES, str(path))
    if visits.dtype.kind not in "iu" or visits.ndim != 3:
        raise UnsafeFileError(f"{path} holds {visits.dtype} {visits.shape}, not visitation counts (integers, seeds x "
                              f"rows x columns); restore the file ecorl wrote or delete it")
    return visits


def setting_differences(saved: TrainConfig, requested: TrainConfig) -> list[str]:
    """Each result-defining setting in which ``requested`` differs from ``saved`` (a requested None, the task's
    default, matches whatever was saved), as 'key: checkpoint has A, you asked for B'.
    """
    old, new = saved.identity(), requested.identity()
    return [f"{key}: checkpoint has {old[key]!r}, you asked for {new.get(key)!r}"
            for key in old if new.get(key) is not None and old[key] != new.get(key)]


def check_same_run(saved: TrainConfig, requested: TrainConfig, where: Path) -> None:
    """Raise `RunDirError` naming every result-defining setting that differs between two configs.

    A requested None (e.g. ``eval_rollouts``) means "the task's default", which the saved, resolved config
    has filled in; it matches whatever value was saved.
    """
    if diffs := setting_differences(saved, requested):
        raise RunDirError(f"cannot resume {where}: it was made with different settings ("
                          + "; ".join(diffs) + f"). Re-run with the original settings (see "
                          f"{where.parent / 'config.json'}) or start a fresh run in another --out directory.")
