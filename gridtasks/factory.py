"""Factory (paper §5, Fig. 4, 5, 6 right, Table 1): materials from workers, an axe to the depot."""

from __future__ import annotations

from dataclasses import dataclass

from gridtasks.codes import Code
from gridtasks.engine import code_mask
from gridtasks.env import EpisodeRules, GridTaskEnv, check_positive_int

WORKERS = (Code.METAL_WORKER, Code.WOOD_WORKER)
MATERIALS = (Code.METAL, Code.WOOD)
DEPOT_CELL = (1, 1)
"""(x, y) of the depot: the top-left interior corner."""


@dataclass(frozen=True)
class FactoryConfig(EpisodeRules):
    """Parameters of the factory task."""

    grid_size: int = 8
    """Side of the square grid, wall ring included."""
    max_material: int = 5
    """A worker dispenses only while at most this many of its material lie on the grid (the original's rule)."""
    horizon: int = 200
    """Episode length of the episodic env (the test horizon)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_positive_int("grid_size", self.grid_size, 5)
        check_positive_int("max_material", self.max_material, 0)
        check_positive_int("horizon", self.horizon)


class FactoryEnv(GridTaskEnv):
    """Factory: get metal and wood from the workers, combine them into an axe, deliver it to the depot.

    ## Actions (Discrete(7))
    | 0 west | 1 east | 2 north | 3 south | 4 pick up | 5 interact | 6 place |
    ``interact`` on a worker's cell with empty hands receives its material (metal worker -> metal, wood
    worker -> wood) while at most ``max_material`` of it lie on the grid. Workers cannot be picked up.
    ``place`` drops the carried material, combines metal and wood into an axe on the cell, or — carrying
    an axe on the depot — delivers it (the axe is used up, the depot stays).

    ## Observation (Box(0, 1, (208,), float32))
    5×5 north-up view one-hot over (0 empty, 1 wall, 2 metal, 3 wood, 4 axe, 5 metal worker,
    6 wood worker, 7 depot) at index ``channel·25 + row·5 + col``, then the carried object one-hot over the
    same 8 channels.

    ## Rewards
    +100 per delivery (every mode). ``waypoint`` (the original's subgoal reward, farmable): +1 every time
    the agent receives a material, makes an axe or picks one up. ``subgoal`` (ours, not farmable): +1 the
    first time in a cycle the agent receives a material, makes an axe and holds an axe. ``one_time``: as
    subgoal (dropping is part of the task, so no lost-progress penalty, as in the original).
    ``distance``: one_time, plus -0.01 × L1 distance to the next target (axe, else a worker; the other
    material or its worker when holding one; the depot when holding an axe) on otherwise unrewarded steps.

    ## Episode end
    Episodic: terminated on delivery, truncated after ``horizon``. Reset-free: never.

    ## Dynamism and shaping
    dynamism p: each step each worker, with probability p, picks one of N, W, S, E, stay at random and
    moves there if the cell holds no object (the original's rule).
    shaping s(t): with probability s(t) a worker instead steps toward the agent ("cooperative workers").
    The depot is fixed at (1, 1). Test MDP: static workers, horizon 200.
    """

    Config = FactoryConfig
    channels = (Code.EMPTY, Code.WALL, Code.METAL, Code.WOOD, Code.AXE, Code.METAL_WORKER, Code.WOOD_WORKER,
                Code.DEPOT)
    counted = (Code.METAL, Code.WOOD, Code.AXE)
    products = (Code.AXE,)

    def fill_rules(self, r) -> None:
        """Workers (random moves by dynamism, cooperative steps by shaping), recipe, delivery, stages."""
        x, y = DEPOT_CELL
        r["layout"][y, x] = Code.DEPOT
        r["recipe"][Code.METAL, Code.WOOD] = Code.AXE
        r["recipe"][Code.WOOD, Code.METAL] = Code.AXE
        r["deliver_item"], r["deliver_target"] = Code.AXE, Code.DEPOT
        r["max_material"] = self.config.max_material
        for worker in WORKERS:
            r["initial"][worker] = 1
            r["wander_prob"][worker] = self.ecology.dynamism
            r["wander_moves"][worker] = 5  # the original's workers pick among N, W, S, E and stay
            r["directed"][worker] = 1
            r["directed_by_shaping"][worker] = True
        for material in MATERIALS:
            r["stage_on_pickup"][material] = 0
        r["stage_on_made"][Code.AXE] = 1
        r["stage_on_pickup"][Code.AXE] = 2
        r["waypoint_repeats"] = True
        r["targets"][Code.EMPTY] = [code_mask(Code.AXE), code_mask(*WORKERS), 0]
        r["targets"][Code.METAL] = [code_mask(Code.WOOD), code_mask(Code.WOOD_WORKER), 0]
        r["targets"][Code.WOOD] = [code_mask(Code.METAL), code_mask(Code.METAL_WORKER), 0]
        r["targets"][Code.AXE] = [code_mask(Code.DEPOT), 0, 0]
