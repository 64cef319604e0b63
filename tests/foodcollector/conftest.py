"""Fixtures for the food collector tests (helpers are fixtures so no test module imports another)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import foodcollector


def _make_env(seed: int = 0, **kwargs):
    """A made-and-reset food collector (through gymnasium.make, wrappers included)."""
    env = gymnasium.make(foodcollector.ENV_ID, **kwargs)
    env.reset(seed=seed)
    return env


def _park_spheres(env, y: float = -40.0) -> None:
    """Move every sphere into a row at height ``y``: behind an agent at the origin facing +y, unseen."""
    u = env.unwrapped
    for i, x in enumerate(np.linspace(-44.0, 44.0, u.params.num_spheres)):
        u.place_sphere(i, (float(x), y))


@pytest.fixture
def make_env():
    """Factory: ``make_env(seed=0, **kwargs)`` makes and resets an env."""
    return _make_env


@pytest.fixture
def park_spheres():
    """Function: ``park_spheres(env, y=-40)`` moves every sphere out of the agent's sight."""
    return _park_spheres


@pytest.fixture
def quiet_env():
    """A static env: agent at rest at the origin facing +y, every sphere parked behind it."""
    env = _make_env(seed=3)
    env.unwrapped.place_agent((0.0, 0.0), heading=90.0)
    _park_spheres(env)
    return env
