"""`check_worlds`: every state the engine reaches passes, states it cannot reach are refused in one line."""

from __future__ import annotations

import numpy as np
import pytest

import gridtasks
from gridtasks import check_worlds


@pytest.mark.parametrize("task", list(gridtasks.TASKS))
@pytest.mark.parametrize("kwargs", [{}, {"reset_free": True, "dynamism": 0.1}], ids=["episodic", "reset-free"])
def test_every_reached_state_passes(task, kwargs):
    vec = gridtasks.GridTaskVectorEnv(gridtasks.TASKS[task], 4, **kwargs)
    vec.reset(seed=0)
    rng = np.random.default_rng(0)
    for t in range(600):
        vec.step(rng.integers(0, 7, 4))
        if t % 50 == 0:
            check_worlds(vec.worlds, vec.rules)


def _changed(field: str, value) -> tuple[np.ndarray, np.ndarray]:
    vec = gridtasks.GridTaskVectorEnv(gridtasks.TASKS["scavenging"], 2)
    vec.reset(seed=0)
    worlds = vec.worlds.copy()
    worlds[field][1] = value
    return worlds, vec.rules


@pytest.mark.parametrize("field, value, message", [
    ("agent", [10**9, 10**9], "agent at (1000000000, 1000000000)"),
    ("agent", [0, 3], "not on a free cell"),
    ("grid", 255, "cell code 255"),
    ("grid", int(gridtasks.Code.METAL), "cell code 10"),
    ("inventory", 250, "inventory code 250"),
    ("pred", [[40, 3]] * 4, "predator 0 at (40, 3)"),
    ("episode_step", -1, "episode_step lies outside"),
    ("age", 2**31 - 1, "age lies outside"),
])
def test_unreachable_states_are_refused(field, value, message):
    worlds, rules = _changed(field, value)
    with pytest.raises(ValueError, match="world 1 ") as err:
        check_worlds(worlds, rules)
    assert message in str(err.value) and "\n" not in str(err.value)
