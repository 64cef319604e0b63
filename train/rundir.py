"""A run directory: resolved config, metrics, visitation counts and an atomically written checkpoint.

Layout::

    config.json      the resolved TrainConfig
    metrics.csv      one row per evaluation and seed (`METRIC_COLUMNS`)
    visits.npy       (seeds, rows, cols) lifetime visitation counts, [y, x], as of the latest evaluation
    visits/STEP.npy  the same, kept at every evaluation (for heat-maps over training)
    checkpoint.pkl   everything needed to continue the run exactly (see `save_checkpoint`)
    tensorboard/     optional TensorBoard logs
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import pickle
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from train.config import TrainConfig

METRIC_COLUMNS = ("step", "seed", "epsilon", "loss", "success", "return", "train_reward", "steps_per_s")
"""Columns of metrics.csv. ``return`` is the mean validation return; ``train_reward`` the summed training
reward since the previous evaluation; ``steps_per_s`` environment steps per second per seed."""

CHECKPOINT_MAGIC = b"ECORLCK1"
"""First bytes of a checkpoint file; a SHA-256 of the payload follows, then the pickled payload."""
DIGEST_SIZE = 32
"""Bytes of a SHA-256 digest."""


class RunDirError(RuntimeError):
    """A run directory cannot be used as asked (the message says why and how to fix it)."""


def _fsync_dir(path: Path) -> None:
    """Make a rename inside ``path`` durable."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def atomic_file(path: Path) -> Iterator[BinaryIO]:
    """Open a temporary file that replaces ``path`` (after fsync) only if the block completes.

    A crash at any point leaves either the old file or the new one, never a mix.
    """
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        yield f
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def atomic_write(path: Path, *chunks: bytes | memoryview) -> None:
    """Write ``chunks`` to ``path`` atomically (see `atomic_file`)."""
    with atomic_file(path) as f:
        for chunk in chunks:
            f.write(chunk)


def _sha256_rest(f: BinaryIO, chunk: int = 1 << 22) -> bytes:
    """SHA-256 of the rest of an open file, read in chunks."""
    digest = hashlib.sha256()
    while block := f.read(chunk):
        digest.update(block)
    return digest.digest()


class _HashingWriter:
    """A write-only file wrapper that hashes what passes through it."""

    def __init__(self, file: BinaryIO) -> None:
        self.file, self.hash = file, hashlib.sha256()

    def write(self, data) -> int:
        self.hash.update(data)
        return self.file.write(data)


class RunDir:
    """The files of one run (one condition, all its seeds)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    config_path = property(lambda self: self.path / "config.json")
    metrics_path = property(lambda self: self.path / "metrics.csv")
    checkpoint_path = property(lambda self: self.path / "checkpoint.pkl")
    visits_path = property(lambda self: self.path / "visits.npy")

    def prepare(self, cfg: TrainConfig, resume: bool) -> None:
        """Check the directory fits the request; on a fresh start create it and write config.json."""
        exists = self.path.exists() and any(self.path.iterdir())
        if resume:
            if not self.checkpoint_path.exists():
                raise RunDirError(f"cannot resume: {self.path} holds no checkpoint.pkl. Start a fresh run "
                                  f"(drop --resume) with an empty or new --out directory.")
            return
        if exists:
            raise RunDirError(f"run directory {self.path} is not empty. Pass --resume to continue the run "
                              f"it holds, or choose another --out (or delete the directory) to start afresh.")
        self.path.mkdir(parents=True, exist_ok=True)
        atomic_write(self.config_path, (json.dumps(cfg.to_dict(), indent=2) + "\n").encode())

    def save_checkpoint(self, payload: dict[str, Any]) -> None:
        """Pickle ``payload`` after a header (magic, SHA-256 of the pickle) and write it atomically.

        The pickle streams straight into the file (no in-memory copy of the replay buffer); the digest
        is written into the header once the pickle is complete.
        """
        with atomic_file(self.checkpoint_path) as f:
            f.write(CHECKPOINT_MAGIC + bytes(DIGEST_SIZE))
            writer = _HashingWriter(f)
            pickle.dump(payload, writer, protocol=pickle.HIGHEST_PROTOCOL)
            f.seek(len(CHECKPOINT_MAGIC))
            f.write(writer.hash.digest())

    def load_checkpoint(self, cfg: TrainConfig) -> dict[str, Any]:
        """Read and verify the checkpoint; refuse a corrupt one or one made with different settings."""
        path = self.checkpoint_path
        with open(path, "rb") as f:
            magic, digest = f.read(len(CHECKPOINT_MAGIC)), f.read(DIGEST_SIZE)
            if magic != CHECKPOINT_MAGIC or len(digest) != DIGEST_SIZE:
                raise RunDirError(f"{path} is not an ecorl checkpoint (bad header). Restore it or start a "
                                  f"fresh run in another --out directory.")
            body_start = f.tell()
            if _sha256_rest(f) != digest:
                raise RunDirError(f"{path} is corrupt (checksum mismatch: truncated or altered). It cannot be "
                                  f"resumed; restore it from a backup or start a fresh run in another --out.")
            f.seek(body_start)
            payload = pickle.load(f)
        check_same_run(TrainConfig.from_dict(payload["config"]), cfg, path)
        return payload

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
            path.parent.mkdir(exist_ok=True)
            buf = io.BytesIO()
            np.save(buf, visits)
            atomic_write(path, buf.getvalue())


def check_same_run(saved: TrainConfig, requested: TrainConfig, where: Path) -> None:
    """Raise `RunDirError` naming every result-defining setting that differs between two configs.

    A requested None (e.g. ``eval_rollouts``) means "the task's default", which the saved, resolved config
    has filled in; it matches whatever value was saved.
    """
    old, new = saved.identity(), requested.identity()
    diffs = [f"{key}: checkpoint has {old[key]!r}, you asked for {new.get(key)!r}"
             for key in old if new.get(key) is not None and old[key] != new.get(key)]
    if diffs:
        raise RunDirError(f"cannot resume {where}: it was made with different settings ("
                          + "; ".join(diffs) + f"). Re-run with the original settings (see "
                          f"{where.parent / 'config.json'}) or start a fresh run in another --out directory.")
