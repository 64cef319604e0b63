"""What a training run reports while it runs: the progress bar, and at each evaluation metrics.csv, the
visitation counts and (optionally) TensorBoard scalars; and the stop signal that ends it cleanly.
"""

from __future__ import annotations

import math
import signal
import threading
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import numpy as np

from train.config import TrainConfig
from train.rundir import RunDir
from train.safeio import real_dir

if TYPE_CHECKING:
    from train.trainer import Trainer


def postfix(rows: list[dict[str, Any]], num_agents: int, cfg: TrainConfig) -> dict[str, str]:
    """Progress-bar summary of the latest evaluation: aggregate steps/s and mean metric over seeds."""
    out = {"sps": f"{rows[0]['steps_per_s'] * num_agents:.0f}"}
    success = [r["success"] for r in rows]
    if not any(math.isnan(s) for s in success):
        out["success"] = f"{np.mean(success):.2f}"
    else:
        out["return"] = f"{np.mean([r['return'] for r in rows]):.1f}"
    return out


@contextmanager
def progress_bar(cfg: TrainConfig, initial: int):
    """A tqdm bar over environment steps per seed (a silent stand-in when disabled)."""
    from tqdm import tqdm

    bar = tqdm(total=cfg.total_steps, initial=initial, unit="step", disable=not cfg.run.progress,
               desc=f"{cfg.env.task} x{cfg.run.seeds}", dynamic_ncols=True)
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


@contextmanager
def stop_on_signal():
    """An event set by SIGINT/SIGTERM while inside the block (main thread only; elsewhere never set).

    The first signal sets it (the run stops at the end of its epoch, with a checkpoint; an evaluation polls
    `stop_requested` and stops at once, raising `Interrupted`); a second signal raises `Interrupted`.
    """
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum, frame):
        if stop.is_set():
            raise Interrupted(f"a second {signal.Signals(signum).name}")
        stop.set()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    _STOPS.append(stop)
    try:
        yield stop
    finally:
        _STOPS.remove(stop)
        for sig, old in previous.items():
            signal.signal(sig, old)


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

    def log(self, trainer: Trainer, rows: list[dict[str, Any]]) -> None:
        """Persist the latest evaluation."""
        self.run_dir.write_metrics(trainer.rows)
        self.run_dir.save_visits(trainer.visits, trainer.step)
        if self.writer is None:
            return
        for key in ("success", "return", "loss", "epsilon", "train_reward", "steps_per_s"):
            values = [r[key] for r in rows]
            if not any(math.isnan(v) for v in values):
                self.writer.add_scalar(f"{key}/mean", float(np.mean(values)), trainer.step)
                for r in rows:
                    self.writer.add_scalar(f"{key}/seed_{r['seed']}", r[key], trainer.step)

    def close(self) -> None:
        """Flush TensorBoard."""
        if self.writer is not None:
            self.writer.close()
