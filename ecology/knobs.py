"""The four ecological knobs every ecorl environment takes: dynamism, shaping, reset_free, reward.

`Ecology` is the resolved, frozen value an environment exposes as ``env.unwrapped.ecology``. The
shaping knob is a *schedule*: a strength s(t) in [0, 1] as a function of the lifetime step t (a counter
that never resets). Schedules are piecewise linear, so one representation (a tuple of breakpoints) serves
the Python side and the compiled engines alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

REWARD_MODES = ("sparse", "waypoint", "subgoal", "one_time", "distance")
"""Reward modes of the grid tasks; the food collector only has ``sparse`` (its native ±1)."""

SCHEDULE_HELP = (
    "a number in [0, 1] (constant strength), 'const:V', 'linear:START:END:STEPS' "
    "(e.g. 'linear:1:0:280000'), or 'step:V0:T1:V1[:T2:V2...]' (V0 until step T1, then V1, ...)"
)


def _check_unit(name: str, value: float) -> float:
    """Return ``value`` as a float, or raise if it is not a finite number in [0, 1]."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number in [0, 1], got {value!r} of type {type(value).__name__}")
    value = float(value)
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise ValueError(f"{name} must lie in [0, 1], got {value}; pass a probability/strength between 0 and 1")
    return value


@dataclass(frozen=True)
class Schedule:
    """A piecewise-linear shaping strength s(t) over the lifetime step t.

    Between consecutive breakpoints the value is interpolated linearly; before the first breakpoint it
    is the first value and after the last the last value. Two breakpoints at the same step make a jump.
    """

    times: tuple[float, ...]
    """Breakpoint steps, non-decreasing, starting at 0."""
    values: tuple[float, ...]
    """Strength at each breakpoint, each in [0, 1]."""
    text: str = field(default="", compare=False)
    """The string the schedule was parsed from (for configs and logs)."""

    def __post_init__(self) -> None:
        if len(self.times) != len(self.values) or not self.times:
            raise ValueError("a schedule needs as many breakpoint times as values, and at least one")
        for i, v in enumerate(self.values):
            _check_unit(f"shaping schedule value #{i}", v)
        bad = [t for t in self.times if not math.isfinite(t)]
        if bad:
            raise ValueError(f"shaping schedule {self.text or str(self.times)!r} has the breakpoint step {bad[0]}; "
                             f"every step must be a finite number >= 0")
        if self.times[0] != 0 or any(b < a for a, b in zip(self.times, self.times[1:])):
            raise ValueError(f"schedule breakpoints must start at step 0 and never decrease, got {self.times}")

    @classmethod
    def constant(cls, value: float) -> Schedule:
        """A schedule that is ``value`` forever."""
        value = _check_unit("shaping", value) + 0.0  # + 0.0 turns -0.0 into 0.0 (shown as '0', not '-0')
        return cls((0.0,), (value,), text=f"{value:g}")

    @classmethod
    def linear(cls, start: float, end: float, steps: float) -> Schedule:
        """Strength moving linearly from ``start`` at step 0 to ``end`` at ``steps``, then constant."""
        if not steps > 0:
            raise ValueError(f"a linear schedule needs a positive number of steps, got {steps}")
        return cls((0.0, float(steps)), (float(start), float(end)), text=f"linear:{start:g}:{end:g}:{steps:g}")

    @property
    def is_zero(self) -> bool:
        """True when the strength is 0 at every step (the unshaped, original environment)."""
        return all(v == 0.0 for v in self.values)

    @property
    def breakpoints(self) -> np.ndarray:
        """The schedule as a float64 array of shape (K, 2): rows of (step, value), for compiled engines."""
        return np.array(list(zip(self.times, self.values)), dtype=np.float64).reshape(-1, 2)

    def __call__(self, t: float) -> float:
        """The strength at lifetime step ``t``."""
        return float(schedule_value(self.breakpoints, float(t)))

    def __str__(self) -> str:
        return self.text or ",".join(f"{t:g}@{v:g}" for t, v in zip(self.times, self.values))


def schedule_value(breakpoints: np.ndarray, t: float) -> float:
    """Evaluate a (K, 2) breakpoint array at step ``t`` (plain Python/numba-compatible arithmetic)."""
    k = breakpoints.shape[0]
    if t < breakpoints[0, 0]:
        return breakpoints[0, 1]
    for i in range(k - 1):
        t0, v0 = breakpoints[i, 0], breakpoints[i, 1]
        t1, v1 = breakpoints[i + 1, 0], breakpoints[i + 1, 1]
        if t < t1:
            return v0 + (v1 - v0) * (t - t0) / (t1 - t0)
    return breakpoints[k - 1, 1]


def parse_schedule(spec: str | float | Schedule) -> Schedule:
    """Parse a shaping schedule from a number, a `Schedule`, or a short string (see `SCHEDULE_HELP`)."""
    if isinstance(spec, Schedule):
        return spec
    if spec is None:
        raise TypeError(f"shaping must be {SCHEDULE_HELP}; got None (pass 0 for no shaping)")
    if not isinstance(spec, str):
        return Schedule.constant(spec)
    text = spec.strip()
    head, _, rest = text.partition(":")
    try:
        parts = [float(x) for x in (rest.split(":") if rest else [head])]
    except ValueError:
        raise ValueError(f"malformed shaping schedule {spec!r}: expected {SCHEDULE_HELP}") from None
    if not rest:
        return Schedule.constant(parts[0])
    if head == "const" and len(parts) == 1:
        return Schedule.constant(parts[0])
    if head == "linear" and len(parts) == 3:
        return Schedule.linear(*parts)
    if head == "step" and len(parts) >= 3 and len(parts) % 2 == 1:
        times, values = [0.0], [parts[0]]
        for t, v in zip(parts[1::2], parts[2::2]):
            times += [t, t]
            values += [values[-1], v]
        return Schedule(tuple(times), tuple(values), text=text)
    raise ValueError(f"malformed shaping schedule {spec!r}: expected {SCHEDULE_HELP}")


@dataclass(frozen=True)
class Ecology:
    """The resolved ecological knobs of one environment (validated on construction)."""

    dynamism: float = 0.0
    """Rate of change independent of the agent, in [0, 1]; 0 is the static original task."""
    shaping: Schedule = field(default_factory=lambda: Schedule.constant(0.0))
    """Environment-shaping strength schedule s(t) in [0, 1] over the lifetime step; 0 is the original task."""
    reset_free: bool = False
    """True: non-episodic (one reset, never ends). False: episodic (ends on completion or at the horizon)."""
    reward: str = "sparse"
    """Reward mode: one of `REWARD_MODES`."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "dynamism", _check_unit("dynamism", self.dynamism))
        object.__setattr__(self, "shaping", parse_schedule(self.shaping))
        if not isinstance(self.reset_free, (bool, np.bool_)):
            raise TypeError(f"reset_free must be True or False, got {self.reset_free!r}")
        object.__setattr__(self, "reset_free", bool(self.reset_free))
        if self.reward not in REWARD_MODES:
            raise ValueError(f"unknown reward mode {self.reward!r}; choose one of {', '.join(REWARD_MODES)}")

    @property
    def is_test_mdp(self) -> bool:
        """True for the evaluation MDP: static, unshaped, episodic, sparse."""
        return self.dynamism == 0 and self.shaping.is_zero and not self.reset_free and self.reward == "sparse"

    def as_dict(self) -> dict:
        """A JSON-friendly view (the shaping schedule as its string)."""
        return {"dynamism": self.dynamism, "shaping": str(self.shaping), "reset_free": self.reset_free,
                "reward": self.reward}


TEST_MDP = {"dynamism": 0.0, "shaping": 0.0, "reset_free": False, "reward": "sparse"}
"""The knobs of the evaluation MDP shared by every task (SPEC: evaluation always uses the test MDP)."""

VALIDATION_SEED_BASE = 1_000_000_000
"""Validation layout i is the test MDP reset with seed ``VALIDATION_SEED_BASE + i``; training seeds stay below."""

NUM_VALIDATION_LAYOUTS = 100
"""How many fixed validation layouts the evaluation protocol uses."""


def validation_seeds(n: int = NUM_VALIDATION_LAYOUTS) -> list[int]:
    """The fixed seeds of the first ``n`` validation layouts (never overlapping training seeds)."""
    return [VALIDATION_SEED_BASE + i for i in range(n)]
