"""Hunting (paper §5, Fig. 4, 5, 6): an axe, a deer, food."""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym

from gridtasks.codes import Code
from gridtasks.engine import code_mask
from gridtasks.env import (
    DirectedMoves,
    GridTaskEnv,
    SpawnRules,
    check_choice,
    check_positive_int,
    check_probability,
)

DEER_KINDS = {"wander": Code.DEER, "easy": Code.DEER_EASY, "hard": Code.DEER_HARD}
SHAPING_MECHANISMS = ("easy_deer", "nearby")
ALL_DEER = (Code.DEER, Code.DEER_EASY, Code.DEER_HARD)


@dataclass(frozen=True)
class HuntingConfig(SpawnRules, DirectedMoves):
    """Parameters of the hunting task."""

    grid_size: int = 8
    """Side of the square grid, wall ring included."""
    deer_count: int = 2
    """Deer placed at reset and, with ``replenish``, kept on the grid (one added per step when fewer)."""
    axe_count: int = 2
    """Axes placed at reset and, with ``replenish``, kept on the grid."""
    replenish: bool = True
    """Replace hunted deer and used axes (off in the test MDP)."""
    deer_kind: str = "wander"
    """'wander' (moves only by dynamism), 'hard' (steps away from the agent with probability deer_speed)
    or 'easy' (steps toward it with probability deer_speed)."""
    deer_speed: float = 0.0
    """Probability per step of a hard deer's flight or an easy deer's approach."""
    shaping_mechanism: str = "easy_deer"
    """'easy_deer' (paper): a fraction s of newly spawned deer are easy; 'nearby' (original code): new
    deer and axes appear in a window around the agent, as salad's ingredients."""
    horizon: int = 200
    """Episode length of the episodic env (the test horizon)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_positive_int("grid_size", self.grid_size, 5)
        check_positive_int("deer_count", self.deer_count, 0)
        check_positive_int("axe_count", self.axe_count, 0)
        check_positive_int("horizon", self.horizon)
        check_choice("deer_kind", self.deer_kind, tuple(DEER_KINDS))
        check_probability("deer_speed", self.deer_speed)
        check_choice("shaping_mechanism", self.shaping_mechanism, SHAPING_MECHANISMS)


class HuntingEnv(GridTaskEnv):
    """Hunting: pick up an axe, place it on a deer to get food (the axe is used up), pick up the food.

    ## Actions (Discrete(7))
    | 0 west | 1 east | 2 north | 3 south | 4 pick up | 5 interact (no-op here) | 6 place |
    Deer cannot be picked up; ``place`` with an axe on a deer's cell turns the deer into food.

    ## Observation (Box(0, 1, (130,), float32))
    5×5 north-up view one-hot over (0 empty, 1 wall, 2 axe, 3 deer (every kind), 4 food) at index
    ``channel·25 + row·5 + col``, then the carried object one-hot over the same 5 channels.

    ## Rewards
    +100 for picking up food (every mode). ``subgoal`` and ``waypoint`` (the original's hunting subgoal
    reward is progress-based, so the two coincide here): +1 the first time in a cycle the agent holds an
    axe and the first time it makes food. ``one_time``: subgoal, plus -100 for dropping the axe on an
    empty cell. ``distance``: one_time, plus -0.01 × L1 distance to the nearest food, else axe (empty
    hands), or deer (holding an axe) on otherwise unrewarded steps.

    ## Episode end
    Episodic: terminated on picking up food, truncated after ``horizon``. Reset-free: never; food is eaten.

    ## Dynamism and shaping
    dynamism p: each step each deer (that took no directed step) picks one of N, W, S, E at random with
    probability p and moves there if the cell holds no object; deer never step onto walls or objects, but
    may step onto the agent. As in the original, deer move after the agent's move and before its
    pick-up / place. Replenishment counts the grid only (two axes stay on the grid while the agent
    carries a third; ``count_carried`` changes this), and new deer and axes may appear under the agent
    (``spawn_on_agent``).
    shaping s(t), ``shaping_mechanism='easy_deer'`` (paper): a fraction s(t) of newly spawned deer
    (including the initial ones, drawn at reset) are easy, the rest are of ``deer_kind``.
    directed steps (``deer_speed`` > 0; ``directed_moves='original'``, the original's rule): a hard deer flees
    the cell the agent stood on before its move this step, an easy deer approaches its cell after it; the
    first best of N, W, S, E, stay, not taken when that cell holds an object. ``'current-free'``: both aim at
    the agent's cell after its move and take the best step among free cells.
    ``'nearby'`` (original code): replenished deer and axes appear inside the salad-style window around
    the agent. Test MDP: static deer, no replenishment, horizon 200.
    """

    Config = HuntingConfig
    channels = (Code.EMPTY, Code.WALL, Code.AXE, Code.DEER, Code.FOOD)
    counted = (Code.AXE, Code.FOOD)
    products = (Code.FOOD,)

    def fill_rules(self, r) -> None:
        """Recipes, deer movement (dynamism), easy deer or spawn window (shaping), reward stages."""
        cfg, p = self.config, self.ecology.dynamism
        for deer in ALL_DEER:
            r["channel"][deer] = self.channels.index(Code.DEER)
            r["recipe"][Code.AXE, deer] = Code.FOOD
            r["wander_prob"][deer] = p
        r["directed"][Code.DEER_EASY], r["directed_prob"][Code.DEER_EASY] = 1, cfg.deer_speed
        r["directed"][Code.DEER_HARD], r["directed_prob"][Code.DEER_HARD] = -1, cfg.deer_speed
        cfg.fill_directed_rules(r, aim_before_move=(Code.DEER_HARD,))  # the original's easy deer aim after it
        r["base_deer"] = DEER_KINDS[cfg.deer_kind]
        r["creatures_before_hands"] = True  # the original moves deer before the agent's pick-up / place
        r["goal_pickup"] = Code.FOOD
        r["initial"][Code.DEER], r["initial"][Code.AXE] = cfg.deer_count, cfg.axe_count
        if cfg.replenish:
            r["replenish"][Code.DEER], r["replenish"][Code.AXE] = cfg.deer_count, cfg.axe_count
        shaped = not self.ecology.shaping.is_zero
        r["easy_deer_shaping"] = shaped and cfg.shaping_mechanism == "easy_deer"
        if r["easy_deer_shaping"] and cfg.deer_speed == 0:
            gym.logger.warn("hunting's easy-deer shaping changes nothing while deer_speed is 0 (easy deer approach "
                            "the agent with probability deer_speed); set deer_speed, e.g. 0.2 as the shaping "
                            "experiments do, or shaping_mechanism='nearby'")
        r["near_spawn"][Code.DEER] = r["near_spawn"][Code.AXE] = shaped and cfg.shaping_mechanism == "nearby"
        r["stage_on_pickup"][Code.AXE] = 0
        r["stage_on_made"][Code.FOOD] = 1
        r["loses_progress_on_drop"][Code.AXE] = True
        r["targets"][Code.EMPTY] = [code_mask(Code.FOOD), code_mask(Code.AXE), 0]
        r["targets"][Code.AXE] = [code_mask(*ALL_DEER), 0, 0]

    def test_overrides(self) -> dict:
        """The test MDP keeps the deer kind and speed but replenishes nothing."""
        return {"replenish": False}
