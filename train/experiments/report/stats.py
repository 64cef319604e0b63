"""Statistics over seeds: the percentile bootstrap, and how one evaluation's per-seed values are summed up."""

from __future__ import annotations

import math

import numpy as np

CI_LEVEL = 0.95
"""Confidence level of every interval the report shows."""
BOOTSTRAP_SAMPLES = 2000
"""Bootstrap resamples per interval (every interval of the report and of the docs)."""
BOOTSTRAP_SEED = 0
"""Seed of the resampling generator, fresh for every interval: an interval depends only on its values, not on
what was computed before it. With few distinct values (e.g. <= 3 seeds that learned) the bounds move by
points with this seed, so it is fixed here and stated in the report."""
BOOTSTRAP_NOTE = (f"percentile bootstrap over seeds, {BOOTSTRAP_SAMPLES} resamples, generator seed "
                  f"{BOOTSTRAP_SEED}")
"""How every interval is made, as the report states it."""


BOOTSTRAP_BYTES = 256 << 20
"""The most memory one bootstrap gathers at once; beyond it the resamples are taken a block of rows at a time."""

LEARNED = 0.2
"""A seed 'learned' the task when it solves more than this fraction of the validation layouts (outcomes are
bimodal: a seed finds the task or it does not)."""

DIVERGED_LOSS = 1e3
"""A mean TD loss between two evaluations above this is a blow-up (an RMS TD error above 31.6 where a
completion is worth +100)."""
REWARD_BOUND = 200.0
"""Per-step reward magnitude that no task reaches (the largest, a completion's +100, plus a +1 subgoal or a
-100 penalty, stays within it): no true value |Q| exceeds ``REWARD_BOUND / (1 - gamma)``."""
DIVERGED_RULE = (f"a seed diverged when, at any evaluation up to the one shown, its mean TD loss since the "
                 f"previous evaluation exceeded {DIVERGED_LOSS:g} or its largest |Q| on the validation "
                 f"rollouts exceeded {REWARD_BOUND:g} / (1 - gamma) ({REWARD_BOUND / 0.01:,.0f} at gamma 0.99) "
                 f"or was not finite; where a task pays more per step (the released factory ladder's 10 000), "
                 f"{REWARD_BOUND:g} is its largest reward plus 100 and the loss bound grows with its square")
"""The divergence rule in words (the report and docs/fidelity.md state it)."""


COLLAPSE_SHARE = 0.6
"""A seed 'collapsed' when its greedy policy takes one action at more than this share of its validation steps
(an even policy over 7 actions takes each at 1/7; a policy that solves the grid tasks moves in several
directions and picks up and places)."""
COLLAPSED_RULE = (f"a seed collapsed when, at the evaluation shown, its greedy policy chose one action at more "
                  f"than {COLLAPSE_SHARE:.0%} of its validation steps ('—': the run predates this measurement)")
"""The collapse rule in words (the report and docs/fidelity.md state it)."""


def collapsed(top_share: np.ndarray) -> np.ndarray:
    """Where the greedy policy collapsed onto one action, elementwise over top-action shares (NaN: unknown, False)."""
    with np.errstate(invalid="ignore"):
        return np.asarray(top_share, dtype=np.float64) > COLLAPSE_SHARE


def format_collapsed(top_share: np.ndarray, seeds: np.ndarray) -> str:
    """'c / S' seeds collapsed (`collapsed`), with their numbers when there are any; '—' when no seed's share is
    known (runs written before the collapse columns).
    """
    top_share = np.asarray(top_share, dtype=np.float64)
    if np.isnan(top_share).all():
        return "—"
    return format_diverged(collapsed(top_share), seeds)


def q_bound(gamma: float, reward_bound: float = REWARD_BOUND) -> float:
    """The largest |Q| a value estimate can have at discount ``gamma`` when no step pays more than
    ``reward_bound`` (see `REWARD_BOUND`).
    """
    return math.inf if gamma >= 1.0 else reward_bound / (1.0 - gamma)


def blown(loss: np.ndarray, max_q: np.ndarray, gamma: float, reward_bound: float = REWARD_BOUND) -> np.ndarray:
    """Where a seed's values blew up at an evaluation, elementwise (the rule of `DIVERGED_RULE`).

    ``loss`` and ``max_q`` are per evaluation and seed. A NaN loss (no gradient step since the previous
    evaluation) says nothing; a NaN ``max_q`` is a non-finite Q-value, a blow-up. Files written before
    ``max_q`` existed give it as 0 (no evidence), so their rule is the loss alone. ``reward_bound``: the task's
    largest per-step |reward| (the run's `train.tasks.EnvInfo.reward_bound`), which scales both bounds.
    """
    loss, max_q = np.asarray(loss, dtype=np.float64), np.asarray(max_q, dtype=np.float64)
    scale = max(reward_bound, REWARD_BOUND) / REWARD_BOUND
    with np.errstate(invalid="ignore"):
        return (loss > DIVERGED_LOSS * scale**2) | ~(max_q <= q_bound(gamma, max(reward_bound, REWARD_BOUND)))


def diverged(blown_so_far: np.ndarray) -> np.ndarray:
    """(S,) seeds that diverged by evaluation E, from the (E, S) `blown` matrix of its evaluations."""
    return np.asarray(blown_so_far, dtype=bool).reshape(-1, np.shape(blown_so_far)[-1]).any(0)


def bootstrap_ci(values: np.ndarray, level: float = CI_LEVEL, samples: int = BOOTSTRAP_SAMPLES,
                 seed: int = BOOTSTRAP_SEED) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    tail = (1.0 - level) / 2.0 * 100.0
    if values.size * samples * 8 <= BOOTSTRAP_BYTES:  # every report of ecorl's own runs: one gather
        low, high = np.percentile(values[..., idx].mean(-1), [tail, 100.0 - tail], axis=-1)
        return mean, low, high
    rows = values.reshape(-1, n)  # a planted file of many seeds or evaluations: a block of rows at a time
    step = max(2, BOOTSTRAP_BYTES // (samples * n * 8))
    starts = [s for s in range(0, rows.shape[0], step) if rows.shape[0] - s != 1 or s == 0]  # no block of one row
    boots = np.concatenate([rows[a:b][:, idx].mean(-1) for a, b in zip(starts, [*starts[1:], rows.shape[0]])])
    low, high = np.percentile(boots.reshape(*values.shape[:-1], samples), [tail, 100.0 - tail], axis=-1)
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


def learned_level(values: np.ndarray, metric: str) -> str:
    """The final success of the seeds that learned: '28-86% (mean 63%)', one value alone, '—' when none
    learned or for returns (no learning threshold).
    """
    values = np.asarray(values, dtype=np.float64)
    level = values[values > LEARNED] * 100.0
    if metric != "success" or level.size == 0:
        return "—"
    if level.size == 1:
        return f"{level[0]:.0f}%"
    return f"{level.min():.0f}–{level.max():.0f}% (mean {level.mean():.0f}%)"


def format_diverged(flags: np.ndarray, seeds: np.ndarray) -> str:
    """'d / S', with the diverged seeds' numbers when there are any: '2 / 10 (seeds 3, 7)'."""
    flags = np.asarray(flags, dtype=bool)
    text = f"{int(flags.sum())} / {flags.size}"
    if flags.any():
        text += f" (seed{'s' if flags.sum() > 1 else ''} {', '.join(str(int(s)) for s in np.asarray(seeds)[flags])})"
    return text
