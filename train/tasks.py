"""The trainable tasks, derived from the env packages' registrations, and how to build their (vector) environments.

The trainer knows an environment only through the contract of `ecology.EcologicalEnv`: its observation
split, test MDP, task parameters and visitation map.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Any

import gymnasium as gym
import numpy as np

import foodcollector
import gridtasks
from ecology import NUM_VALIDATION_LAYOUTS, EcologicalEnv, VisitGrid
from train.config import CONFIG_OWNED_ENV_KWARGS, EnvConfig
from train.config.checks import unknown_choice


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


def _task_table() -> dict[str, Task]:
    """Every registered task: the grid tasks of `gridtasks.ENV_IDS`, then the food collector."""
    grid = [Task(name, env_id, "gridtasks", True, "success", NUM_VALIDATION_LAYOUTS)
            for name, env_id in gridtasks.ENV_IDS.items()]
    food = Task("foodcollector", foodcollector.ENV_ID, "foodcollector", False, "return", 10)
    return {task.name: task for task in (*grid, food)}


TASKS: dict[str, Task] = _task_table()
"""Every task the trainer knows, by CLI name."""


def get_task(name: str) -> Task:
    """The task called ``name`` (its package, imported above, has registered its id)."""
    if name not in TASKS:
        raise unknown_choice("task", name, TASKS)
    return TASKS[name]


DEFAULT_REWARD_BOUND = 200.0
"""A per-step |reward| no task's default rewards reach: a completion's +100 and a subgoal or penalty of 100 on the
same step (the food collector's are a few units)."""


@dataclass(frozen=True)
class EnvInfo:
    """What the trainer needs to know about a task's environment, read from one probe instance."""

    obs_dim: int
    """Length of an observation."""
    view_dim: int
    """Observation inputs read by the network's view branch (the rest go to the inventory branch)."""
    num_actions: int
    """Size of the discrete action space."""
    visit_grid: VisitGrid
    """The visitation map: its shape and the cell of each agent position."""
    test_kwargs: dict[str, Any]
    """Keyword arguments of the evaluation MDP (`test_mdp_kwargs()`)."""
    reward_bound: float = DEFAULT_REWARD_BOUND
    """The largest |reward| one step of the training environment can give (its ``reward_bound``, where it has
    one): the scale of the divergence gauge."""

    @property
    def visit_shape(self) -> tuple[int, int]:
        """Shape (rows, cols) of the visitation map, indexed [y, x]."""
        return self.visit_grid.shape


def task_parameters(task: Task) -> tuple[str, ...]:
    """The task parameters ``env_kwargs`` may set (the horizon and the ecology knobs belong to the config)."""
    from gymnasium.envs.registration import load_env_creator

    entry = gym.spec(task.env_id).entry_point
    env_class: type[EcologicalEnv] = load_env_creator(entry) if isinstance(entry, str) else entry
    return tuple(n for n in env_class.parameter_names() if n not in CONFIG_OWNED_ENV_KWARGS)


def check_env_kwargs(task: Task, env_kwargs: dict[str, Any], option: str = "--env-kwarg") -> None:
    """Raise ValueError (one line, listing the valid names) for an env kwarg the task does not take."""
    valid = task_parameters(task)
    unknown = sorted(set(env_kwargs) - set(valid))
    if unknown:
        raise ValueError(f"{task.name} has no parameter {unknown[0]!r} ({option}); its parameters are: "
                         f"{', '.join(valid)}")


def check_test_mdp(task: Task, info: EnvInfo, test_kwargs: dict[str, Any], eval_env_kwargs: dict[str, Any]) -> None:
    """Build one environment of the evaluation's test MDP (``test_kwargs``, ``eval_env_kwargs`` among them) before
    the run starts: raise ValueError (one line) for a parameter it refuses, or one that changes the observation or
    action space the network is built for, rather than at the first evaluation.
    """
    check_env_kwargs(task, eval_env_kwargs, "--eval-env-kwarg")
    try:
        env = gym.make(task.env_id, **test_kwargs)
    except (TypeError, ValueError) as err:
        raise ValueError(f"the test MDP refuses --eval-env-kwarg {eval_env_kwargs}: {err}") from None
    try:
        spaces = int(np.prod(env.observation_space.shape)), int(env.action_space.n)
    finally:
        env.close()
    if spaces != (info.obs_dim, info.num_actions):
        raise ValueError(f"--eval-env-kwarg {eval_env_kwargs} gives the test MDP {spaces[0]} observations and "
                         f"{spaces[1]} actions, the training env {info.obs_dim} and {info.num_actions}; the network "
                         f"needs the same")


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
        base: EcologicalEnv = env.unwrapped
        view_dim, inventory_dim = base.observation_split
        obs_dim = int(np.prod(env.observation_space.shape))
        if view_dim + inventory_dim != obs_dim:
            raise ValueError(f"{task.env_id}: observation_split {base.observation_split} does not add up "
                             f"to the observation size {obs_dim}")
        return EnvInfo(obs_dim, int(view_dim), int(env.action_space.n), base.visit_grid,
                       dict(base.test_mdp_kwargs()), float(getattr(base, "reward_bound", DEFAULT_REWARD_BOUND)))
    finally:
        env.close()


def make_vector_env(env_id: str, num_envs: int, kwargs: dict[str, Any], threads: int = 1) -> gym.vector.VectorEnv:
    """``num_envs`` worlds in one vector env (next-step autoreset): the task's batched engine if it has one,
    stepping its worlds on ``threads`` threads (bit-identical for any count; the other envs ignore it).
    """
    if gym.spec(env_id).vector_entry_point is not None:
        extra = {"threads": threads} if threads > 1 else {}
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs, **extra)
    return gym.vector.SyncVectorEnv([partial(gym.make, env_id, **kwargs)] * num_envs)


def step_worlds(env: gym.vector.VectorEnv, actions: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Step every world of a training vector env: (obs, reward, terminated, truncated, agent positions
    (N, 2)), fresh arrays. The grid tasks' `step_arrays` skips the info dict (the same numbers); other envs
    take `step`.
    """
    if isinstance(env, gridtasks.GridTaskVectorEnv):
        *arrays, positions = env.step_arrays(actions)
        return (*(a if env.copy else a.copy() for a in arrays), positions)  # never the env's own buffers
    obs, reward, terminated, truncated, info = env.step(actions)
    return obs, reward, terminated, truncated, np.asarray(info["agent_pos"])


def completions(env: gym.vector.VectorEnv) -> np.ndarray | None:
    """Which worlds of a training vector env completed their task on the last step (None where the task has no
    completion: the food collector).
    """
    return env.last_solved if isinstance(env, gridtasks.GridTaskVectorEnv) else None


# ---- environment state as data (for checkpoints) -------------------------------------------------------


def env_state(env: gym.vector.VectorEnv) -> dict[str, Any]:
    """The state of a training vector env as plain data: the grid tasks' batched worlds by record field, or
    each world's `get_state` (the food collector's) and the vector env's autoreset flags.
    """
    if isinstance(env, gridtasks.GridTaskVectorEnv):  # one structured record per world
        worlds = env.worlds
        return {"kind": "grid", "worlds": {name: worlds[name].copy() for name in worlds.dtype.names}}
    if isinstance(env, gym.vector.SyncVectorEnv):
        return {"kind": "sync", "autoreset": np.asarray(env._autoreset_envs, dtype=bool).copy(),
                "envs": [e.unwrapped.get_state() for e in env.envs]}
    raise TypeError(f"{type(env).__name__} has no saveable state (batched grid worlds or get_state)")


def restore_env_state(env: gym.vector.VectorEnv, state: dict[str, Any], headroom: int = 0) -> None:
    """Put `env_state` output back into ``env`` (same task and number of worlds, already reset once); grid worlds'
    counters must leave ``headroom`` (the steps the run may still take) below their maximum.
    """
    kind = state.get("kind")
    if kind == "grid" and isinstance(env, gridtasks.GridTaskVectorEnv):
        worlds = env.worlds
        saved = state["worlds"]
        if set(saved) != set(worlds.dtype.names):
            raise ValueError("the saved grid worlds do not have this task's fields")
        candidate = np.zeros_like(worlds)
        for name in worlds.dtype.names:
            _check_like(saved[name], worlds[name], f"world field {name!r}")
            candidate[name] = saved[name]
        gridtasks.check_worlds(candidate, env.rules, headroom)  # the compiled engine trusts every index it reads
        worlds[...] = candidate
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
