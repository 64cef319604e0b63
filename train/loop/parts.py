"""One condition inside a trainer (`train.loop.trainer.Trainer`): its rows of the learner, its worlds, its outputs."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ecology import corner_share
from train.config import TrainConfig
from train.storage.rundir import RunDir

__all__ = ["Part"]


@dataclass
class Part:
    """One condition inside a trainer: its rows of the learner, its worlds and what it writes."""

    cfg: TrainConfig
    rows: slice
    env: Any
    run_dir: RunDir | None
    visits: np.ndarray
    metric_rows: list[dict[str, Any]] = field(default_factory=list)
    visits_at_eval: np.ndarray | None = None
    """The visitation counts at the previous evaluation (None: zero), for the corner share of the visits since."""
    resumed_from: int = -1
    """The step a resumed run continued from (-1: a fresh run)."""

    @property
    def seeds(self) -> list[int]:
        """The seeds of this condition."""
        return self.cfg.run.seed_list

    def recent_corner_share(self, wall: int) -> np.ndarray:
        """(seeds,) each seed's share of its training visits since the previous evaluation on the four corner
        cells inside a ``wall`` cells thick border (`ecology.corner_share`); the visits so far become the next
        interval's start.
        """
        start = self.visits_at_eval if self.visits_at_eval is not None else 0
        share = corner_share(self.visits - start, wall)
        self.visits_at_eval = self.visits.copy()
        return share
