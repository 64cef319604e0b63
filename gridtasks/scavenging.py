"""Scavenging (paper §5, Fig. 4, 5): find food while predators hunt you."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gridtasks.codes import Code
from gridtasks.engine import MAX_PREDATORS, PREDATOR_RESPAWN_IDS, code_mask
from gridtasks.env import GridTaskEnv, SpawnRules, check_positive_int, check_probability


@dataclass(frozen=True)
class ScavengingConfig(SpawnRules):
    """Parameters of the scavenging task."""

    grid_size: int = 10
    """Side of the square grid, wall ring included."""
    food_count: int = 2
    """Food placed at reset and kept on the grid (one added per step when fewer)."""
    predator_count: int = 2
    """Predators alive at any time."""
    predator_lifespan: int = 10
    """Steps a predator lives before it dies (and comes back as ``predator_respawn`` says)."""
    predator_respawn: str = "original"
    """Where and when a dead predator comes back. ``original`` (default, the original code's replenishment):
    one per step, after the food grew, on a random cell holding no object other than the agent's start cell,
    so possibly on the agent, which it then catches at once. ``off-agent`` (ecorl's rule before 2026-12, which
    the runs shipped before then trained with): at once, on a random non-wall cell other than the agent's."""
    predator_penalty: float = 100.0
    """Cost of each step the agent shares a cell with a predator (part of the task in every mode)."""
    horizon: int = 200
    """Episode length of the episodic env (the test horizon)."""
    food_growth: float = 0.0
    """Per-step probability that one more food grows (while at most (n-2)²//8 lie on the grid), every food then
    withering after int(food_count / p) steps: the released Fig. 5 script's food p 0.2. 0 (default, the paper
    text's task): food is only replenished. The test MDP grows none."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_positive_int("grid_size", self.grid_size, 5)
        check_positive_int("food_count", self.food_count, 0)
        check_positive_int("predator_lifespan", self.predator_lifespan)
        check_positive_int("horizon", self.horizon)
        check_positive_int("predator_count", self.predator_count, 0)
        check_probability("food_growth", self.food_growth)
        if self.predator_respawn not in PREDATOR_RESPAWN_IDS:
            raise ValueError(f"predator_respawn must be one of {', '.join(map(repr, PREDATOR_RESPAWN_IDS))}, "
                             f"got {self.predator_respawn!r}")
        if self.predator_count > MAX_PREDATORS:
            raise ValueError(f"predator_count must be an integer in [0, {MAX_PREDATORS}], "
                             f"got {self.predator_count!r}")
        penalty = self.predator_penalty
        if isinstance(penalty, bool) or not isinstance(penalty, (int, float, np.number)) or not 0 <= penalty < math.inf:
            raise ValueError(f"predator_penalty is a cost and must be a finite number >= 0, got {penalty!r}")


class ScavengingEnv(GridTaskEnv):
    """Scavenging: pick up food; predators chase the agent and each step caught costs -100.

    ## Actions (Discrete(7))
    | 0 west | 1 east | 2 north | 3 south | 4 pick up | 5 interact (no-op here) | 6 place |

    ## Observation (Box(0, 1, (104,), float32))
    5×5 north-up view one-hot over (0 empty, 1 wall, 2 food, 3 predator) at index
    ``channel·25 + row·5 + col``; a predator is drawn on top of whatever its cell holds (that cell then has
    two ones). Then the carried object one-hot over the same 4 channels.

    ## Rewards
    +100 for picking up food in every mode; -``predator_penalty`` (100) on each step a predator shares the
    agent's cell, in every mode. No intermediate stages, so ``waypoint``, ``subgoal`` and ``one_time`` equal sparse;
    ``distance`` adds -0.01 × L1 distance to the nearest food on otherwise unrewarded steps.

    ## Episode end
    Episodic: terminated on picking up food, truncated after ``horizon``. Reset-free: never; food is eaten.

    ## Creatures, dynamism and shaping
    Predators are not grid objects: they walk over food. Each step (after the agent acts) a predator takes
    the greedy L1 step toward the agent (ties: N, W, S, E, stay); with probability p (dynamism) it moves
    to a uniformly random one of N, W, S, E, stay instead (the original's rule). After
    ``predator_lifespan`` steps it dies; one dead predator per step is reborn, after the food grew, on a random
    cell holding no object other than the agent's start cell, so possibly on the agent, whom it catches at
    once (the original's rule; ``predator_respawn="off-agent"``: reborn at once, never on the agent's cell).
    A dead predator waiting for its turn is neither seen nor felt. At a reset the predators take object-free
    cells, the agent's included (the original places them before the agent). Food is replenished
    to ``food_count`` on the grid, one per step (it may appear under the agent, as in the original);
    ``food_growth`` p > 0 also grows one more with probability p per step and makes food wither, as salad's
    ingredients do (the released Fig. 5 script's world).
    shaping s(t): new food appears inside the salad-style window around the agent.
    Test MDP: p = 0 (chasing predators), no food growth, horizon 200.
    """

    Config = ScavengingConfig
    channels = (Code.EMPTY, Code.WALL, Code.FOOD, Code.PREDATOR)
    counted = (Code.FOOD,)

    def fill_rules(self, r) -> None:
        """Food replenishment (near the agent under shaping) and predators (random with probability p)."""
        cfg = self.config
        r["goal_pickup"] = Code.FOOD
        r["initial"][Code.FOOD] = r["replenish"][Code.FOOD] = cfg.food_count
        r["grow_prob"][Code.FOOD] = cfg.food_growth
        r["lifespan"][Code.FOOD] = int(cfg.food_count / cfg.food_growth) if cfg.food_growth > 0 else 0
        r["near_spawn"][Code.FOOD] = not self.ecology.shaping.is_zero
        r["num_predators"] = cfg.predator_count
        r["predator_lifespan"] = cfg.predator_lifespan
        r["predator_respawn"] = PREDATOR_RESPAWN_IDS[cfg.predator_respawn]
        r["predator_penalty"] = cfg.predator_penalty
        r["predator_wander_prob"] = self.ecology.dynamism
        r["targets"][Code.EMPTY] = [code_mask(Code.FOOD), 0, 0]

    def test_overrides(self) -> dict:
        """The test MDP grows no food: it is only replenished."""
        return {"food_growth": 0.0}
