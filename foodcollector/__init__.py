"""A 2D pymunk re-creation of Unity ML-Agents' FoodCollector with the ecology knobs.

Importing the package registers ``foodcollector/FoodCollector-v0``::

    import gymnasium, foodcollector
    env = gymnasium.make("foodcollector/FoodCollector-v0", dynamism=0.5, shaping="linear:1:0:280000",
                         reset_free=True, render_mode="rgb_array")

See `foodcollector.env.FoodCollectorEnv` for the full specification, and `foodcollector.make_vector_env`
for many worlds stepped in parallel worker processes (``workers=N``).
"""

from __future__ import annotations

import gymnasium

from foodcollector.env import ACTION_TABLE, NUM_ACTIONS, FoodCollectorEnv, decode_action, encode_action
from foodcollector.params import RAY_ANGLES_DEG, UNITY_EPISODE_DECISIONS, FoodCollectorParams

ENV_ID = "foodcollector/FoodCollector-v0"

# No max_episode_steps: the env truncates episodic runs itself, and reset-free runs must never end.
if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="foodcollector.env:FoodCollectorEnv")

from foodcollector.vector import FoodCollectorVectorEnv, make_vector_env  # noqa: E402 (needs ENV_ID)

__all__ = [
    "ACTION_TABLE",
    "ENV_ID",
    "NUM_ACTIONS",
    "RAY_ANGLES_DEG",
    "UNITY_EPISODE_DECISIONS",
    "FoodCollectorEnv",
    "FoodCollectorParams",
    "FoodCollectorVectorEnv",
    "decode_action",
    "encode_action",
    "make_vector_env",
]
