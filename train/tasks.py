"""The trainable tasks: CLI name -> Gymnasium id, and how to build their (vector) environments."""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from functools import partial
from typing import Any

import gymnasium as gym
import numpy as np

from train.config import CONFIG_OWNED_ENV_KWARGS, EnvConfig


@dataclass(frozen=True)
class Task:
    """One task as the trainer sees it."""

    name: str
    """CLI name."""
    env_id: str
    """Registered Gymnasium id."""
    package: str
    """Package whose import registers the id."""
    binary_obs: bool
    """Observations are in {0, 1} (bit-packed in replay)."""
    metric: str
    """Evaluation metric: 'success' (fraction of validation rollouts solved) or 'return' (mean return)."""
    eval_rollouts: int
    """Default validation rollouts per seed."""


TASKS: dict[str, Task] = {t.name: t for t in (
    Task("salad", "gridtasks/Salad-v0", "gridtasks", True, "success", 100),
    Task("hunting", "gridtasks/Hunting-v0", "gridtasks", True, "success", 100),
    Task("scavenging", "gridtasks/Scavenging-v0", "gridtasks", True, "success", 100),
    Task("factory", "gridtasks/Factory-v0", "gridtasks", True, "success", 100),
    Task("walled-salad", "gridtasks/WalledSalad-v0", "gridtasks", True, "success", 100),
    Task("foodcollector", "foodcollector/FoodCollector-v0", "foodcollector", False, "return", 10),
)}
"""Every task the trainer knows, by CLI name."""

FOOD_COLLECTOR_BINS = 20
"""Visitation maps of the food collector bin its 100 x 100 arena into this many cells per side."""
FOOD_COLLECTOR_HALF_SIZE = 50.0
"""Half the side of the food collector's arena (walls at +-50 units)."""


def get_task(name: str) -> Task:
    """The task called ``name``, its package imported (so its ids are registered)."""
    if name not in TASKS:
        raise ValueError(f"unknown task {name!r}; choose one of: {', '.join(TASKS)}")
    task = TASKS[name]
    importlib.import_module(task.package)
    return task


@dataclass(frozen=True)
class EnvInfo:
    """What the trainer needs to know about a task's environment, read from one probe instance."""

    obs_dim: int
    view_dim: int
    num_actions: int
    visit_shape: tuple[int, int]
    """Shape (rows, cols) of the visitation map, indexed [y, x]."""
    grid: bool
    """Agent positions are grid cells (else continuous arena coordinates, binned for the map)."""
    test_kwargs: dict[str, Any]
    """Keyword arguments of the evaluation MDP (`test_mdp_kwargs()`)."""


def task_parameters(task: Task) -> tuple[str, ...]:
    """The task parameters ``env_kwargs`` may set (the horizon and the ecology knobs belong to the config)."""
    import dataclasses

    from gymnasium.envs.registration import load_env_creator

    entry = gym.spec(task.env_id).entry_point
    env_class = load_env_creator(entry) if isinstance(entry, str) else entry
    if hasattr(env_class, "Config"):
        names = [f.name for f in dataclasses.fields(env_class.Config)]
    else:
        from foodcollector.params import PARAM_NAMES

        names = list(PARAM_NAMES)
    return tuple(n for n in names if n not in CONFIG_OWNED_ENV_KWARGS)


def check_env_kwargs(task: Task, env_kwargs: dict[str, Any]) -> None:
    """Raise ValueError (one line, listing the valid names) for an env kwarg the task does not take."""
    valid = task_parameters(task)
    unknown = sorted(set(env_kwargs) - set(valid))
    if unknown:
        raise ValueError(f"{task.name} has no parameter {unknown[0]!r} (--env-kwarg); its parameters are: "
                         f"{', '.join(valid)}")


def probe(task: Task, env_cfg: EnvConfig) -> EnvInfo:
    """Build one training environment and read its spaces, observation split and test MDP.

    The training ``horizon`` is left out of the probe: an environment's ``test_mdp_kwargs()`` may echo
    its own horizon, and the test MDP must keep the task's test horizon.
    """
    check_env_kwargs(task, env_cfg.env_kwargs)
    kwargs = {k: v for k, v in env_cfg.env_make_kwargs.items() if k != "horizon"}
    try:
        env = gym.make(task.env_id, **kwargs)
    except TypeError as err:  # a parameter of the wrong type: the task's own one-line message
        raise ValueError(str(err)) from None
    try:
        base = env.unwrapped
        view_dim, inventory_dim = base.observation_split
        obs_dim = int(np.prod(env.observation_space.shape))
        if view_dim + inventory_dim != obs_dim:
            raise ValueError(f"{task.env_id}: observation_split {base.observation_split} does not add up "
                             f"to the observation size {obs_dim}")
        grid = hasattr(base, "grid_shape")
        shape = tuple(base.grid_shape) if grid else (FOOD_COLLECTOR_BINS,) * 2
        return EnvInfo(obs_dim, int(view_dim), int(env.action_space.n), shape, grid,
                       dict(base.test_mdp_kwargs()))
    finally:
        env.close()


def make_vector_env(env_id: str, num_envs: int, kwargs: dict[str, Any]) -> gym.vector.VectorEnv:
    """``num_envs`` worlds in one vector env (next-step autoreset): the task's batched engine if it has one."""
    if gym.spec(env_id).vector_entry_point is not None:
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
    return gym.vector.SyncVectorEnv([partial(gym.make, env_id, **kwargs)] * num_envs)


def visit_cells(agent_pos: np.ndarray, shape: tuple[int, int], grid: bool) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of each agent's cell in the visitation map: grid cells (x, y) -> [y, x]; the food
    collector's arena coordinates binned into ``shape`` cells (row from y, column from x, -50 first)."""
    pos = np.asarray(agent_pos)
    if grid:
        return pos[:, 1].astype(np.int64), pos[:, 0].astype(np.int64)
    scaled = (pos + FOOD_COLLECTOR_HALF_SIZE) * (shape[0] / (2 * FOOD_COLLECTOR_HALF_SIZE))
    cells = np.clip(scaled.astype(np.int64), 0, shape[0] - 1)
    return cells[:, 1], cells[:, 0]


# ---- environment state as data (for checkpoints) -------------------------------------------------------


def env_state(env: gym.vector.VectorEnv) -> dict[str, Any]:
    """The state of a training vector env as plain data: grid worlds by record field, or each food
    collector's `get_state` and the vector env's autoreset flags."""
    if hasattr(env, "worlds"):  # the grid tasks' batched engine: one structured record per world
        worlds = env.worlds
        return {"kind": "grid", "worlds": {name: worlds[name].copy() for name in worlds.dtype.names}}
    if isinstance(env, gym.vector.SyncVectorEnv) and all(hasattr(e.unwrapped, "get_state") for e in env.envs):
        return {"kind": "sync", "autoreset": np.asarray(env._autoreset_envs, dtype=bool).copy(),
                "envs": [e.unwrapped.get_state() for e in env.envs]}
    raise TypeError(f"{type(env).__name__} has no saveable state (grid worlds or get_state)")


def restore_env_state(env: gym.vector.VectorEnv, state: dict[str, Any]) -> None:
    """Put `env_state` output back into ``env`` (same task and number of worlds, already reset once)."""
    kind = state.get("kind")
    if kind == "grid" and hasattr(env, "worlds"):
        worlds = env.worlds
        saved = state["worlds"]
        if set(saved) != set(worlds.dtype.names):
            raise ValueError("the saved grid worlds do not have this task's fields")
        for name in worlds.dtype.names:
            _check_like(saved[name], worlds[name], f"world field {name!r}")
        for name in worlds.dtype.names:
            worlds[name] = saved[name]
        return
    if kind == "sync" and isinstance(env, gym.vector.SyncVectorEnv):
        if len(state["envs"]) != len(env.envs):
            raise ValueError(f"the checkpoint holds {len(state['envs'])} worlds, this run has {len(env.envs)}")
        autoreset = np.asarray(state["autoreset"])
        _check_like(autoreset, np.asarray(env._autoreset_envs, dtype=bool), "autoreset flags")
        for e, saved in zip(env.envs, state["envs"]):
            e.unwrapped.set_state(saved)
        env._autoreset_envs = autoreset.copy()
        return
    raise ValueError(f"the checkpoint's environment state ({kind!r}) does not fit {type(env).__name__}")


def _check_like(saved: Any, live: np.ndarray, what: str) -> None:
    """Refuse a saved array whose shape or dtype differs from the live one."""
    if not isinstance(saved, np.ndarray) or saved.shape != live.shape or saved.dtype != live.dtype:
        got = f"{saved.dtype} {saved.shape}" if isinstance(saved, np.ndarray) else type(saved).__name__
        raise ValueError(f"saved {what} is {got}, expected {live.dtype} {live.shape}")
