"""Env-agnostic measurements over rollouts: first-reward hitting time, marginal entropy, visitation, corners."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence

import numpy as np


def hitting_time(rewards: Sequence[float] | np.ndarray, threshold: float = 0.0) -> int | None:
    """Number of steps until the first reward above ``threshold`` (1-based), or None if it never came.

    With ``threshold=0`` this is the paper's first-reward hitting time; pass ``threshold=99`` to count only
    task completions (+100) when shaping rewards are present.
    """
    hits = np.flatnonzero(np.asarray(rewards, dtype=np.float64) > threshold)
    return int(hits[0]) + 1 if hits.size else None


def marginal_entropy(observations: Iterable[np.ndarray] | np.ndarray) -> float:
    """Entropy (nats) of the empirical distribution of distinct observations: H = -sum p log p.

    Observations are compared byte for byte, so pass exactly the part that defines a "state" (for the grid
    tasks, the egocentric view without the inventory, as in the paper).
    """
    counts = Counter(np.ascontiguousarray(o).tobytes() for o in observations)
    if not counts:
        raise ValueError("marginal_entropy needs at least one observation")
    return float(count_entropy(np.fromiter(counts.values(), dtype=np.int64)))


def count_entropy(counts: np.ndarray) -> np.ndarray:
    """Entropy (nats) of the distribution that non-negative ``counts`` give along their last axis, H = -sum p log p
    (zero counts add nothing; all-zero counts give 0).
    """
    counts = np.asarray(counts, dtype=np.float64)
    p = counts / np.maximum(counts.sum(-1, keepdims=True), 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        return -np.where(p > 0, p * np.log(p), 0.0).sum(-1)


def visitation_counts(positions: Iterable[Sequence[int]] | np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Count visits per cell: ``positions`` are (x, y) cells, the result is indexed [y, x] (image order)."""
    pos = np.asarray(list(positions) if not isinstance(positions, np.ndarray) else positions, dtype=np.int64)
    counts = np.zeros(shape, dtype=np.int64)
    if pos.size:
        pos = pos.reshape(-1, 2)
        if (pos < 0).any() or (pos[:, 0] >= shape[1]).any() or (pos[:, 1] >= shape[0]).any():
            raise ValueError(f"positions fall outside a grid of shape {shape} (rows, cols)")
        np.add.at(counts, (pos[:, 1], pos[:, 0]), 1)
    return counts


def corner_cells(shape: tuple[int, int], wall: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of the four corner cells of an (H, W) map just inside ``wall`` cells of border wall."""
    height, width = shape
    if min(height, width) - 2 * wall < 2:
        raise ValueError(f"a {height}x{width} map with a wall {wall} cells thick has no four inner corners")
    near, far_row, far_col = wall, height - 1 - wall, width - 1 - wall
    return np.array([near, near, far_row, far_row]), np.array([near, far_col, near, far_col])


def corner_share(visits: np.ndarray, wall: int = 1) -> np.ndarray:
    """Share of the visits in ``visits`` (..., H, W counts) that fell on the four corner cells inside the wall
    (0 where there are no visits): the corner-sitting of a collapsed policy, 4 / cells for an even spread.
    """
    visits = np.asarray(visits)
    rows, cols = corner_cells(visits.shape[-2:], wall)
    totals = visits.sum((-2, -1)).astype(np.float64)
    return visits[..., rows, cols].sum(-1) / np.maximum(totals, 1.0)
