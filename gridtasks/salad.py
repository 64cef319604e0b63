"""Salad-making (paper §5, Fig. 2, 4, 5, 6) and walled salad-making (appendix, Fig. 8–10)."""

from __future__ import annotations

from dataclasses import dataclass

from gridtasks.codes import Code
from gridtasks.engine import code_mask
from gridtasks.env import GridTaskEnv, SpawnRules, check_positive_int

INGREDIENTS = (Code.LETTUCE, Code.CARROT)


@dataclass(frozen=True)
class SaladConfig(SpawnRules):
    """Parameters of the salad-making task."""

    grid_size: int = 8
    """Side of the square grid, wall ring included."""
    initial_count: int = 2
    """Lettuces and carrots each placed at reset (training preset 2; the test MDP uses 1)."""
    regrow_when_empty: bool = True
    """When no lettuce (carrot) is left on the grid, one grows back at once (off in the test MDP)."""
    horizon: int = 100
    """Episode length of the episodic env (the test horizon)."""
    walls: bool = False
    """Add the appendix's three fixed inner walls (a 'W' maze; needs grid_size >= 8)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_positive_int("grid_size", self.grid_size, 5)
        check_positive_int("initial_count", self.initial_count, 0)
        check_positive_int("horizon", self.horizon)
        if self.walls and self.grid_size < 8:
            raise ValueError(f"walls need grid_size >= 8, got {self.grid_size}")


@dataclass(frozen=True)
class WalledSaladConfig(SaladConfig):
    """Parameters of walled salad-making: salad on a 10×10 grid with three fixed walls."""

    grid_size: int = 10
    """Side of the square grid, wall ring included."""
    horizon: int = 500
    """Episode length of the episodic env (the test horizon)."""
    walls: bool = True
    """The three fixed inner walls."""


def inner_wall_cells(n: int) -> list[tuple[int, int]]:
    """(x, y) cells of the appendix's three vertical walls at x = (i+1)·n//4, alternately hanging from the
    top and standing on the bottom, each n//2 - 1 long (on 10×10: x=2 y=1..4, x=5 y=5..8, x=7 y=1..4).
    """
    length = n // 2 - 1
    cells = []
    for i in range(3):
        x = (i + 1) * n // 4
        ys = range(1, 1 + length) if i % 2 == 0 else range(n - 1 - length, n - 1)
        cells += [(x, y) for y in ys]
    return cells


class SaladEnv(GridTaskEnv):
    """Salad-making: put a lettuce and a carrot together, then pick up the salad.

    ## Actions (Discrete(7))
    | 0 west | 1 east | 2 north | 3 south | 4 pick up | 5 interact (no-op here) | 6 place |
    Walls block moves. ``pick up`` takes the object under the agent into its single-slot inventory;
    ``place`` drops the carried object on an empty cell, or combines it with the object under the agent
    (lettuce + carrot, either way round -> salad, left on the cell).

    ## Observation (Box(0, 1, (130,), float32))
    The 5×5 north-up window centred on the agent, one-hot per cell over the channels
    (0 empty, 1 wall, 2 lettuce, 3 carrot, 4 salad) at index ``channel·25 + row·5 + col`` (row 0 is north,
    the centre cell shows the object under the agent, cells outside the grid read as wall), then the
    carried object one-hot over the same 5 channels (all zero when empty-handed).

    ## Rewards
    +100 for picking up a salad (the task) in every mode. ``waypoint`` (the original's subgoal reward, as
    its released Fig. 4 scripts trained): +1 on every pick-up of an ingredient and every salad made, so
    pick-up / drop loops farm it. ``subgoal`` (ours, not farmable): +1 the first time in a cycle the
    agent holds an ingredient and the first time it makes a salad. ``one_time``: subgoal, plus -100 for
    dropping a carried ingredient on an empty cell (lost progress). ``distance``: one_time, plus on
    otherwise unrewarded steps -0.01 × L1 distance to the nearest object needed next (the salad if one
    exists, else an ingredient; the other ingredient when holding one). A cycle ends with each salad.

    ## Episode end
    Episodic: terminated when the salad is picked up, truncated after ``horizon`` steps. Reset-free:
    never; the picked-up salad is consumed and the world goes on.

    ## Dynamism and shaping
    dynamism p: each step each ingredient grows at a random empty cell with probability p, and every
    ingredient withers when its age reaches ``int(initial_count / p)`` (the expected count stays about
    ``initial_count`` while that lifespan is long; where it is 1, e.g. ``initial_count=1`` at p > 0.5, an
    ingredient withers in the step it grows and the grid stays empty, as the original's formula makes it);
    growth stops while more than (n-2)²//8 of a kind are on the grid. p = 0:
    ingredients are permanent and regrow only when none of a kind is left on the grid
    (``regrow_when_empty``). As in the original, growth comes before ageing (a grown ingredient can be
    picked up on lifespan - 1 steps), populations are counted on the grid only (picking up the last
    lettuce grows one at once; ``count_carried`` changes this) and an ingredient may grow under the agent
    (never on its start cell; ``spawn_on_agent=False`` forbids it).
    shaping s(t): new ingredients grow inside a square around the agent whose side shrinks from the whole
    grid (s=0) to 2 cells (s=1); side = 2 + floor((1 - s)·(2n - 2)). Its top-left cell is the agent's minus
    side // 2, clipped at the grid's edge, and its wall cells take nothing, so beside a wall it holds fewer
    cells (in a corner a 2-cell window holds only the agent's own), as in the original
    (``spawn_window="shifted"`` moves it inside the wall ring instead).
    Test MDP: 1 lettuce and 1 carrot, nothing grows or withers, horizon 100 (walled: 500).
    """

    Config = SaladConfig
    channels = (Code.EMPTY, Code.WALL, Code.LETTUCE, Code.CARROT, Code.SALAD)
    counted = (Code.LETTUCE, Code.CARROT, Code.SALAD)
    products = (Code.SALAD,)

    def fill_rules(self, r) -> None:
        """Recipes, growth (dynamism), the spawn window (shaping) and the reward stages of salad-making."""
        cfg, p = self.config, self.ecology.dynamism
        if cfg.walls:
            for x, y in inner_wall_cells(cfg.grid_size):
                r["layout"][y, x] = Code.WALL
        r["recipe"][Code.LETTUCE, Code.CARROT] = Code.SALAD
        r["recipe"][Code.CARROT, Code.LETTUCE] = Code.SALAD
        r["goal_pickup"] = Code.SALAD
        for code in INGREDIENTS:
            r["initial"][code] = cfg.initial_count
            r["replenish"][code] = 1 if cfg.regrow_when_empty else 0
            r["grow_prob"][code] = p
            r["lifespan"][code] = int(cfg.initial_count / p) if p > 0 else 0
            r["near_spawn"][code] = not self.ecology.shaping.is_zero
            r["stage_on_pickup"][code] = 0
            r["loses_progress_on_drop"][code] = True
        r["stage_on_made"][Code.SALAD] = 1
        r["waypoint_repeats"] = True
        r["targets"][Code.EMPTY] = [code_mask(Code.SALAD), code_mask(*INGREDIENTS), 0]
        r["targets"][Code.LETTUCE] = [code_mask(Code.CARROT), 0, 0]
        r["targets"][Code.CARROT] = [code_mask(Code.LETTUCE), 0, 0]

    def test_overrides(self) -> dict:
        """The test MDP has one of each ingredient and nothing regrows."""
        return {"initial_count": 1, "regrow_when_empty": False}


class WalledSaladEnv(SaladEnv):
    """Walled salad-making (appendix): salad-making on 10×10 with three fixed inner walls.

    Everything is as in `SaladEnv` (actions, 130-value observation, rewards, knobs) except the grid and
    the horizon: vertical walls at x = 2, 5, 7 alternately hanging from the top and standing on the
    bottom, each 4 cells long, make a 'W'-shaped maze; the test horizon is 500.
    """

    Config = WalledSaladConfig
