"""Statistics over seeds: the percentile bootstrap, and how one evaluation's per-seed values are summed up."""

from __future__ import annotations

import numpy as np

CI_LEVEL = 0.95
"""Confidence level of every interval the report shows."""
BOOTSTRAP_SAMPLES = 2000
"""Bootstrap resamples per interval."""


LEARNED = 0.2
"""A seed 'learned' the task when it solves more than this fraction of the validation layouts (outcomes are
bimodal: a seed finds the task or it does not)."""


def bootstrap_ci(values: np.ndarray, level: float = CI_LEVEL, samples: int = BOOTSTRAP_SAMPLES,
                 seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean over the last axis (seeds) and its percentile-bootstrap confidence interval.

    ``values`` is (..., seeds); returns (mean, low, high), each of shape (...). With one seed the
    interval collapses onto the value.
    """
    values = np.asarray(values, dtype=np.float64)
    n = values.shape[-1]
    mean = values.mean(-1)
    if n < 2:
        return mean, mean.copy(), mean.copy()
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, n, size=(samples, n))
    boots = values[..., idx].mean(-1)  # (..., samples)
    tail = (1.0 - level) / 2.0 * 100.0
    low, high = np.percentile(boots, [tail, 100.0 - tail], axis=-1)
    return mean, low, high


def metric_scale(metric: str) -> tuple[float, str]:
    """(factor, unit) that shows a metric: success as a percentage, returns as they are."""
    return (100.0, "%") if metric == "success" else (1.0, "")


def summarize(values: np.ndarray, metric: str) -> tuple[str, str]:
    """('mean [95% CI]', 'k / S' seeds learned, or '—' for returns) of one evaluation's per-seed values."""
    mean, low, high = bootstrap_ci(values)
    scale, unit = metric_scale(metric)
    ours = f"{float(mean) * scale:.1f}{unit} [{float(low) * scale:.1f}, {float(high) * scale:.1f}]"
    learned = f"{int((values > LEARNED).sum())} / {values.size}" if metric == "success" else "—"
    return ours, learned
