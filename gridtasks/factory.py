"""Factory (paper §5, Fig. 4, 5, 6 right, Table 1): materials from workers, an axe to the depot."""

from __future__ import annotations

from dataclasses import dataclass

from gridtasks.codes import Code
from gridtasks.engine import code_mask
from gridtasks.env import DirectedMoves, GridTaskEnv, check_choice, check_positive_int

WORKERS = (Code.METAL_WORKER, Code.WOOD_WORKER)
MATERIALS = (Code.METAL, Code.WOOD)
DEPOT_CELL = (1, 1)
"""(x, y) of the depot: the top-left interior corner."""
GOALS = ("deliver", "make_axe")
"""What completes the factory task: delivering an axe to the depot (the released code) or making one (the
paper's text: 'combine them to make an axe')."""
LADDERS = ("released", "flat")
"""How the subgoal reward modes pay (`FactoryConfig.reward_ladder`)."""
RELEASED_DELIVERY = 10_000.0
"""The released factory reward for a delivery in its waypoint, one-time and distance modes (100^2)."""
RELEASED_AXE = 100.0
"""The released factory reward for making an axe (waypoint) and holding one (waypoint, one-time, distance)."""


@dataclass(frozen=True)
class FactoryConfig(DirectedMoves):
    """Parameters of the factory task."""

    grid_size: int = 8
    """Side of the square grid, wall ring included."""
    max_material: int = 5
    """A worker dispenses only while at most this many of its material lie on the grid (the original's rule)."""
    horizon: int = 200
    """Episode length of the episodic env (the test horizon)."""
    goal: str = "deliver"
    """'deliver' (an axe to the depot: the released code's task) or 'make_axe' (the paper's text): what counts
    as solved, in training and in the test MDP."""
    reward_ladder: str = "released"
    """'released': the released code's factory rewards in the waypoint, one-time and distance modes (material 1,
    axe made 100 and axe picked up 100 in waypoint; metal 1, wood 1, axe held 100 once a cycle in one-time and
    distance; a delivery 10 000). 'flat': every stage +1 and the task +100, as in the other tasks. The sparse and
    subgoal modes and the 'make_axe' goal always pay flat."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_positive_int("grid_size", self.grid_size, 5)
        check_positive_int("max_material", self.max_material, 0)
        check_positive_int("horizon", self.horizon)
        check_choice("goal", self.goal, GOALS)
        check_choice("reward_ladder", self.reward_ladder, LADDERS)


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
    +100 per completion in the sparse and subgoal modes. ``waypoint`` (the original's, farmable): every time
    the agent receives or picks up a material, makes an axe or picks one up. ``subgoal`` (ours, not farmable):
    +1 the first time in a cycle the agent receives a material, makes an axe and holds an axe. ``one_time``:
    once a cycle per stage (dropping is part of the task, so no lost-progress penalty, as in the original).
    ``distance``: one_time, plus -0.01 × L1 distance to the next target (axe, else a worker; the other
    material or its worker when holding one; the depot when holding an axe) on otherwise unrewarded steps.
    How much each pays is ``reward_ladder``'s: 'released' (default, the original's factory code): waypoint
    pays 1 per material, 100 per axe made, 100 per axe picked up and 10 000 per delivery; one_time and
    distance pay metal 1, wood 1 (held, or combined onto), an axe held 100 and a delivery 10 000. 'flat':
    +1 per stage (material, axe made, axe held) and +100 per delivery. With ``goal='make_axe'`` the task is
    complete when an axe is made (+100; the stages are the two materials, +1 each), and a reset-free world
    uses the axe up.

    ## Episode end
    Episodic: terminated on completion (delivery, or an axe made), truncated after ``horizon``. Reset-free:
    never.

    ## Dynamism and shaping
    dynamism p: each step each worker, with probability p, picks one of N, W, S, E, stay at random and
    moves there if the cell holds no object (the original's rule).
    shaping s(t): with probability s(t) a worker instead steps toward the agent ("cooperative workers"): with
    ``directed_moves='original'`` (the original's rule) toward the cell the agent stood on before its move this
    step, the first best of N, W, S, E, stay, not taken when that cell holds an object; with ``'current-free'``
    toward its cell after the move, the best step among free cells (so a worker beside the agent steps onto
    its cell, where it blocks a drop).
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
        r["max_material"] = self.config.max_material
        for worker in WORKERS:
            r["initial"][worker] = 1
            r["wander_prob"][worker] = self.ecology.dynamism
            r["wander_moves"][worker] = 5  # the original's workers pick among N, W, S, E and stay
            r["directed"][worker] = 1
            r["directed_by_shaping"][worker] = True
        self.config.fill_directed_rules(r, aim_before_move=WORKERS)
        r["waypoint_repeats"] = True
        if self.config.goal == "make_axe":
            r["goal_made"] = Code.AXE
            r["stage_on_pickup"][Code.METAL], r["stage_on_pickup"][Code.WOOD] = 0, 1  # +1 per material
        else:
            r["deliver_item"], r["deliver_target"] = Code.AXE, Code.DEPOT
            self._fill_ladder(r)
        r["targets"][Code.EMPTY] = [code_mask(Code.AXE), code_mask(*WORKERS), 0]
        r["targets"][Code.METAL] = [code_mask(Code.WOOD), code_mask(Code.WOOD_WORKER), 0]
        r["targets"][Code.WOOD] = [code_mask(Code.METAL), code_mask(Code.METAL_WORKER), 0]
        r["targets"][Code.AXE] = [code_mask(Code.DEPOT), 0, 0]

    def _fill_ladder(self, r) -> None:
        """The stages of the delivery task and what reaching each pays (`FactoryConfig.reward_ladder`)."""
        mode = self.ecology.reward
        if self.config.reward_ladder == "flat" or mode not in ("waypoint", "one_time", "distance"):
            r["stage_on_pickup"][Code.METAL] = r["stage_on_pickup"][Code.WOOD] = 0
            r["stage_on_made"][Code.AXE], r["stage_on_pickup"][Code.AXE] = 1, 2
            return
        r["stage_on_pickup"][Code.METAL], r["stage_on_pickup"][Code.WOOD], r["stage_on_pickup"][Code.AXE] = 0, 1, 3
        r["stage_reward"][:] = [1.0, 1.0, RELEASED_AXE, RELEASED_AXE]
        r["completion_reward"] = RELEASED_DELIVERY
        if mode == "waypoint":  # every event pays: an axe made 100 (stage 2), whatever it was made from
            r["stage_on_made"][Code.AXE] = 2
        else:  # once a cycle: combining onto an ingredient reaches that ingredient's stage, making pays nothing
            r["stage_on_placed"][Code.METAL], r["stage_on_placed"][Code.WOOD] = 0, 1
            r["stage_on_made"][Code.AXE] = -1
