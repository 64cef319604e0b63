"""What a training run reports while it runs: the progress bar, and at each evaluation metrics.csv, the
visitation counts and (optionally) TensorBoard scalars; and the stop signal that ends it cleanly.
"""

from __future__ import annotations

import json
import math
import os
import signal
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from train.config import TrainConfig
from train.storage.rundir import RunDir
from train.storage.safeio import real_dir


def postfix(rows: list[dict[str, Any]], num_agents: int) -> dict[str, str]:
    """Progress-bar summary of the latest evaluation: steps/s of all seeds together and mean metric over seeds
    (the bar's own rate counts the steps of one seed).
    """
    out = {"all seeds step/s": f"{rows[0]['steps_per_s'] * num_agents:.0f}"}
    success = [r["success"] for r in rows]
    if not any(math.isnan(s) for s in success):
        out["success"] = f"{np.mean(success):.2f}"
    else:
        out["return"] = f"{np.mean([r['return'] for r in rows]):.1f}"
    return out


PROGRESS_FILE = "progress.json"
"""A run directory's heartbeat under a sweep: step, total, steps/s, ETA and the last evaluation, rewritten
every few seconds by the process that trains it, so that the sweep can show each run's progress."""

HEARTBEAT_EVERY_S = 5.0
"""Seconds between two heartbeat writes."""

_heartbeat_paths: list[Path] = []
"""Where this process's trainer writes its heartbeat (set by `heartbeat_to`; empty: nowhere)."""


@contextmanager
def heartbeat_to(*paths: str | Path):
    """Inside the block, a trainer of this process writes its progress to ``paths`` (`PROGRESS_FILE` of each
    run it trains: a packed trainer trains several).
    """
    global _heartbeat_paths
    previous, _heartbeat_paths = _heartbeat_paths, [Path(p) for p in paths]
    try:
        yield
    finally:
        _heartbeat_paths = previous


class Heartbeat:
    """A progress bar's twin that writes the run's progress as JSON (atomically) every few seconds."""

    def __init__(self, bar, paths: list[Path], total: int, initial: int) -> None:
        self.bar, self.paths, self.total = bar, list(paths), total
        self.step, self.start_step, self.began, self.last = initial, initial, time.monotonic(), -math.inf
        self.latest: dict[str, str] = {}

    def update(self, n: int) -> None:
        """Advance the bar by ``n`` steps; write the heartbeat when it is due."""
        self.bar.update(n)
        self.step += n
        if time.monotonic() - self.last >= HEARTBEAT_EVERY_S or self.step >= self.total:
            self.write()

    def set_postfix(self, values: dict[str, str], refresh: bool = True) -> None:
        """Show the latest evaluation on the bar and in the heartbeat."""
        self.bar.set_postfix(values, refresh=refresh)
        self.latest = dict(values)

    def write(self) -> None:
        """Write the heartbeat now."""
        from train.storage.fileio import atomic_text

        self.last = now = time.monotonic()
        rate = (self.step - self.start_step) / max(now - self.began, 1e-9)
        eta = (self.total - self.step) / rate if rate > 0 else None
        beat = {"step": self.step, "total": self.total, "steps_per_s": round(rate, 1),
                "eta_s": None if eta is None else round(eta), "latest": self.latest, "time": time.time()}
        for path in self.paths:
            try:
                atomic_text(path, json.dumps(beat) + "\n")
            except OSError:  # progress is a courtesy: never stop training for it
                pass

    def close(self) -> None:
        """Write the heartbeat a last time (a run stopped early stands where it stopped), and close the bar."""
        self.write()
        self.bar.close()


def read_heartbeat(path: str | Path) -> dict[str, Any] | None:
    """A run's heartbeat (`PROGRESS_FILE`), or None when there is none (yet) or it cannot be read."""
    try:
        beat = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return beat if isinstance(beat, dict) and "step" in beat else None


@contextmanager
def progress_bar(cfg: TrainConfig, initial: int, conditions: int = 1):
    """A tqdm bar over environment steps per seed (a silent stand-in when disabled); under `heartbeat_to`,
    also the heartbeat files.
    """
    from tqdm import tqdm

    what = f"{cfg.env.task} x{cfg.run.seeds}" if conditions == 1 else f"{cfg.env.task}: {conditions} conditions"
    bar = tqdm(total=cfg.total_steps, initial=initial, unit="step", desc=f"{what}, steps per seed",
               disable=not cfg.run.progress, dynamic_ncols=True)
    if _heartbeat_paths:
        bar = Heartbeat(bar, _heartbeat_paths, cfg.total_steps, initial)
    try:
        yield bar
    finally:
        bar.close()


class Interrupted(KeyboardInterrupt):
    """A signal stopped the run where it could not checkpoint: inside an evaluation, or a second signal.

    The last checkpoint stands; a resumed run continues from it exactly.
    """


_STOPS: list[threading.Event] = []
"""The events of the `stop_on_signal` blocks this process is inside."""


def stop_requested() -> bool:
    """True once SIGINT/SIGTERM arrived inside a `stop_on_signal` block (polled by long loops)."""
    return any(stop.is_set() for stop in _STOPS)


def request_stop() -> None:
    """Stop every `stop_on_signal` block of this process as a first signal would (at its epoch's end, with a
    checkpoint): how a sweep's worker passes on a stop that reached only the sweep.
    """
    for stop in list(_STOPS):
        stop.set()


FIRST_SIGNAL_NOTE = ("\nstopping at the end of this epoch, with a checkpoint; a second Ctrl-C stops at once, without "
                     "saving this epoch (the last checkpoint stands)\n")
"""What an interactive run says when the first signal arrives (an epoch of many seeds can take minutes)."""


@contextmanager
def stop_on_signal(announce: bool = False):
    """An event set by SIGINT/SIGTERM while inside the block (main thread only; elsewhere never set).

    The first signal sets it (the run stops at the end of its epoch, with a checkpoint; an evaluation polls
    `stop_requested` and stops at once, raising `Interrupted`) and, with ``announce``, says so on stderr; a second
    signal raises `Interrupted`.
    """
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum, frame):
        if stop.is_set():
            raise Interrupted(f"a second {signal.Signals(signum).name}")
        stop.set()
        if announce:
            _write_stderr(FIRST_SIGNAL_NOTE)

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    _STOPS.append(stop)
    try:
        yield stop
    finally:
        _STOPS.remove(stop)
        for sig, old in previous.items():
            signal.signal(sig, old)


def _write_stderr(text: str) -> None:
    """``text`` on stderr straight through its file descriptor: a signal handler may run while the progress bar is
    inside a write to ``sys.stderr``, and a second buffered write there would raise a reentrant-call error.
    """
    try:
        os.write(sys.stderr.fileno(), text.encode())
    except (AttributeError, OSError, ValueError):  # no file descriptor (captured), or a closed one
        pass


class RunLogger:
    """Writes metrics.csv, the visitation counts and (optionally) TensorBoard scalars at each evaluation."""

    def __init__(self, run_dir: RunDir, cfg: TrainConfig, resumed_at: int | None = None) -> None:
        """``resumed_at``: the step a resumed run continues from; TensorBoard drops what a killed process
        logged after it, so no step appears twice.
        """
        self.run_dir = run_dir
        self.writer = None
        if cfg.run.tensorboard:
            try:
                from torch.utils.tensorboard import SummaryWriter  # lazy: TensorBoard is optional
            except ImportError as err:
                raise ImportError(f"--tensorboard needs the tensorboard package ({err}); install it with "
                                  f"pip install 'ecorl[tensorboard]', or drop --tensorboard") from err
            purge = None if resumed_at is None else resumed_at + 1
            self.writer = SummaryWriter(log_dir=str(real_dir(run_dir.path / "tensorboard")), purge_step=purge)

    def log(self, metric_rows: list[dict[str, Any]], visits: np.ndarray, step: int) -> None:
        """Persist the run's metrics after an evaluation (the rows of step ``step`` are its last ones)."""
        self.run_dir.write_metrics(metric_rows)
        self.run_dir.save_visits(visits, step)
        if self.writer is None:
            return
        rows = [r for r in metric_rows if r["step"] == step]
        for key in ("success", "return", "loss", "max_q", "epsilon", "train_reward", "steps_per_s"):
            values = [r[key] for r in rows]
            if not any(math.isnan(v) for v in values):
                self.writer.add_scalar(f"{key}/mean", float(np.mean(values)), step)
                for r in rows:
                    self.writer.add_scalar(f"{key}/seed_{r['seed']}", r[key], step)

    def close(self) -> None:
        """Flush TensorBoard."""
        if self.writer is not None:
            self.writer.close()
