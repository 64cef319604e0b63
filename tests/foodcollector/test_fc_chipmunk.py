"""The arena's direct Chipmunk calls give the numbers of pymunk's public API, step for step."""

from __future__ import annotations

import numpy as np
import pymunk
import pytest

from foodcollector import chipmunk
from foodcollector.arena import Arena
from foodcollector.env import encode_action


def _rollout(make_env, calls, monkeypatch, actions, **kwargs):
    """Observations, rewards and agent positions of one seeded life, with the arena making ``calls``; and how
    often a ray started inside a sight shape (the wall-pressed path).
    """
    monkeypatch.setattr(chipmunk, "CALLS", calls)
    inside = []
    original = Arena._first_hit_from_outside

    def counted(self, start, end):
        inside.append(1)
        return original(self, start, end)

    monkeypatch.setattr(Arena, "_first_hit_from_outside", counted)
    env = make_env(seed=3, reset_free=True, **kwargs)
    rows = []
    for a in actions:
        obs, reward, _, _, info = env.step(int(a))
        rows.append(np.concatenate([obs, [reward], info["agent_pos"]]))
    return np.array(rows), len(inside)


@pytest.mark.skipif(not chipmunk.HAS_BINDINGS, reason="this pymunk does not expose Chipmunk's bindings")
@pytest.mark.parametrize("dynamism", [0.0, 0.5])
def test_direct_calls_equal_the_public_api(make_env, monkeypatch, dynamism):
    rng = np.random.default_rng(0)
    forward = encode_action(forward=1)
    # mostly straight ahead, so the agent runs into walls and presses against them; random turns and strafes
    actions = np.where(rng.random(1500) < 0.7, forward, rng.integers(0, 27, 1500))
    public, inside_public = _rollout(make_env, chipmunk.PublicCalls, monkeypatch, actions, dynamism=dynamism)
    direct, inside_direct = _rollout(make_env, chipmunk.ChipmunkCalls, monkeypatch, actions, dynamism=dynamism)
    assert inside_public > 0, "the rollout never pressed the agent against a wall; make it walk further"
    assert inside_direct == inside_public
    np.testing.assert_array_equal(direct, public)
    assert public[:, -3].any(), "no sphere was eaten: the rollout did not test contacts"


def test_pymunk_7_bindings_are_found():
    if int(pymunk.version.split(".")[0]) == 7:
        assert chipmunk.CALLS is chipmunk.ChipmunkCalls
    else:
        pytest.skip(f"pymunk {pymunk.version}: the arena uses {chipmunk.CALLS.__name__}")


def test_worlds_stepped_in_threads_equal_worlds_stepped_alone(make_env):
    """Each thread has its own ray-query buffer: worlds in a thread pool see what they see alone."""
    from concurrent.futures import ThreadPoolExecutor

    def life(seed):
        env = make_env(seed=seed, dynamism=0.5, reset_free=True)
        actions = np.random.default_rng(seed).integers(0, 27, 300)
        return np.array([env.step(int(a))[0] for a in actions])

    alone = [life(s) for s in range(4)]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(life, range(4)))
    for a, b in zip(alone, threaded):
        np.testing.assert_array_equal(a, b)
