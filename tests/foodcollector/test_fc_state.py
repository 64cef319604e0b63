"""The food collector's state as plain data: `get_state` / `set_state` continue a trajectory exactly."""

from __future__ import annotations

import json

import numpy as np
import pytest

from foodcollector.env import FoodCollectorEnv


def _rollout(env: FoodCollectorEnv, actions) -> list[tuple[bytes, float]]:
    return [(obs.tobytes(), reward) for obs, reward, *_ in (env.step(int(a)) for a in actions)]


def _plain(value) -> bool:
    """True if ``value`` holds only JSON values and float arrays (nothing that needs pickle)."""
    if isinstance(value, dict):
        return all(isinstance(k, str) and _plain(v) for k, v in value.items())
    if isinstance(value, list):
        return all(_plain(v) for v in value)
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "fiub"
    return value is None or isinstance(value, (bool, int, float, str))


@pytest.mark.parametrize("dynamism", [0.0, 0.5])
def test_restored_state_continues_exactly(dynamism):
    rng = np.random.default_rng(1)
    actions = rng.choice([0, 3, 9, 10, 11], size=160)  # mostly forward: the agent meets the walls
    kwargs = {"dynamism": dynamism, "reset_free": True, "shaping": "linear:1:0:300"}
    live = FoodCollectorEnv(**kwargs)
    live.reset(seed=3)
    _rollout(live, actions[:80])
    state = live.get_state()
    assert _plain(state)
    json.dumps({k: v for k, v in state.items() if not isinstance(v, np.ndarray)}, default=lambda a: a.tolist())
    live.set_state(state)  # what the trainer does after each checkpoint
    restored = FoodCollectorEnv(**kwargs)
    restored.reset(seed=99)  # a different world, entirely replaced by the state
    restored.set_state(state)
    assert _rollout(restored, actions[80:]) == _rollout(live, actions[80:])
    assert restored.lifetime_step == live.lifetime_step == 160


def test_state_of_another_size_is_refused():
    small = FoodCollectorEnv(num_green=2, num_red=2)
    small.reset(seed=0)
    with pytest.raises(ValueError, match="spheres"):
        FoodCollectorEnv().set_state(small.get_state())
