"""Many food collector worlds stepped in parallel worker processes, for a host with many cores.

`make_vector_env` builds ``num_envs`` worlds. With ``workers=1`` (default) that is the one-process
``gymnasium.vector.SyncVectorEnv`` the trainer has always used. With ``workers=N`` the worlds are split into N
contiguous chunks, each a ``SyncVectorEnv`` in its own process (`FoodCollectorVectorEnv`): a step sends each
process its slice of the actions and joins the slices of the results. Every world lives in exactly one
process, draws only from its own seeded stream and is stepped with the same action, so the observations,
rewards, flags and infos are those of the one-process env, number for number.
"""

from __future__ import annotations

import multiprocessing
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, SyncVectorEnv, VectorEnv

from ecology import check_autoreset_mode, check_reset_mask, render_mode_missing
from foodcollector import ENV_ID


def _check_count(name: str, value: Any) -> int:
    """A count >= 1, or a one-line error naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def make_vector_env(num_envs: int, workers: int = 1, autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                    **kwargs: Any) -> VectorEnv:
    """``num_envs`` food collector worlds on ``workers`` processes, resetting as ``autoreset_mode`` says
    (`gymnasium.vector.AutoresetMode`, next-step by default); ``kwargs`` go to every world as to
    ``gymnasium.make``. ``workers=1``: the plain in-process ``SyncVectorEnv``.
    """
    _check_count("num_envs", num_envs)
    _check_count("workers", workers)
    mode = check_autoreset_mode(autoreset_mode)
    if workers == 1:
        return SyncVectorEnv([lambda: gym.make(ENV_ID, **kwargs) for _ in range(num_envs)], autoreset_mode=mode)
    return FoodCollectorVectorEnv(num_envs, workers, autoreset_mode=mode, **kwargs)


def _chunk_sizes(num_envs: int, workers: int) -> list[int]:
    """Worlds per worker: contiguous chunks as equal as possible (no empty chunk)."""
    workers = min(workers, num_envs)
    return [num_envs // workers + (i < num_envs % workers) for i in range(workers)]


def _worker(conn, num_envs: int, autoreset_mode: AutoresetMode, kwargs: dict) -> None:
    """A worker process: a ``SyncVectorEnv`` of its chunk, driven by (command, argument) messages."""
    import foodcollector  # noqa: F401 (registers the id in a spawned process)

    env = make_vector_env(num_envs, 1, autoreset_mode, **kwargs)

    def reset(arg):
        seeds, options = arg
        mask = (options or {}).get("reset_mask")
        if mask is not None and not mask.any():  # none of this chunk's worlds: they go on as they are
            return np.stack([e.unwrapped._observe() for e in env.envs]), {}
        return env.reset(seed=seeds, options=options)

    commands = {
        "reset": reset,
        "step": env.step,
        "render": lambda _: env.render(),
        "get_state": lambda _: {"autoreset": np.asarray(env._autoreset_envs, dtype=bool).copy(),
                                "envs": [e.unwrapped.get_state() for e in env.envs]},
        "set_state": lambda state: _set_chunk_state(env, state),
    }
    try:
        while True:
            command, arg = conn.recv()
            if command == "close":
                break
            try:
                conn.send((True, commands[command](arg)))
            except Exception as err:  # the parent raises it with the worker's message
                conn.send((False, f"{type(err).__name__}: {err}"))
    finally:
        env.close()
        conn.close()


def _set_chunk_state(env: SyncVectorEnv, state: dict) -> None:
    """Put one chunk's saved worlds and autoreset flags back."""
    for e, saved in zip(env.envs, state["envs"]):
        e.unwrapped.set_state(saved)
    env._autoreset_envs = np.asarray(state["autoreset"], dtype=bool).copy()


def merge_infos(parts: list[dict], sizes: list[int]) -> dict:
    """Join the batched info dicts of consecutive chunks into the dict one vector env over all worlds gives
    (each key's values side by side, with its ``_key`` mask; a key a chunk lacks is masked out there).
    """
    merged: dict[str, Any] = {}
    keys = dict.fromkeys(k for part in parts for k in part if not k.startswith("_"))
    for key in keys:
        masks = [np.asarray(part.get(f"_{key}", np.zeros(n, dtype=bool))) for part, n in zip(parts, sizes)]
        merged[f"_{key}"] = np.concatenate(masks)
        if any(isinstance(part.get(key), dict) for part in parts):  # final_info: a nested info, merged alike
            merged[key] = merge_infos([part.get(key, {}) for part in parts], sizes)
            continue
        template = next(np.asarray(part[key]) for part in parts if key in part)
        merged[key] = np.concatenate([np.asarray(part[key]) if key in part else _unset(template, n)
                                      for part, n in zip(parts, sizes)])
    return merged


def _unset(template: np.ndarray, n: int) -> np.ndarray:
    """``n`` unset entries of an info array like ``template``: None in an object array (``final_obs``), else 0."""
    if template.dtype == object:
        return np.full(n, None, dtype=object)
    return np.zeros((n, *template.shape[1:]), template.dtype)


class FoodCollectorVectorEnv(VectorEnv):
    """Food collector worlds in ``workers`` processes (see the module docstring); make it with `make_vector_env`.

    ``reset(seed=s)`` seeds world i with ``s + i`` (or ``seed[i]`` given a list), as ``SyncVectorEnv`` does, and
    ``autoreset_mode`` is ``SyncVectorEnv``'s, with the same infos (``final_obs`` and ``final_info`` included).
    The workers start from a clean server process (``context="forkserver"``, the default), which does not
    copy the parent's threads; like every non-fork start, it imports the main script, so a script that makes
    this env runs its code under ``if __name__ == "__main__":``.
    `get_state` / `set_state` save and restore every world and the autoreset flags. Call `close` (or use it
    as a context manager) to end the worker processes.
    """

    metadata: ClassVar[dict] = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int, workers: int, context: str = "forkserver",
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, **kwargs: Any):
        _check_count("num_envs", num_envs)
        _check_count("workers", workers)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        probe = gym.make(ENV_ID, **kwargs)
        self.single_observation_space, self.single_action_space = probe.observation_space, probe.action_space
        self.render_mode = probe.render_mode
        probe.close()
        self.num_envs = int(num_envs)
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, self.num_envs)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self.sizes = _chunk_sizes(self.num_envs, workers)
        self._starts = np.cumsum([0, *self.sizes])
        ctx = multiprocessing.get_context(context)
        self._conns, self._procs = [], []
        for n in self.sizes:
            parent, child = ctx.Pipe()
            proc = ctx.Process(target=_worker, args=(child, n, self.autoreset_mode, kwargs), daemon=True)
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)

    def __enter__(self) -> FoodCollectorVectorEnv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def workers(self) -> int:
        """Number of worker processes."""
        return len(self.sizes)

    def _ask(self, command: str, args: list) -> list:
        """Send every worker its command, then gather the answers in order (the workers run meanwhile)."""
        if self.closed:
            raise RuntimeError("this vector env is closed")
        for conn, arg in zip(self._conns, args):
            conn.send((command, arg))
        answers = []
        for conn, proc in zip(self._conns, self._procs):
            try:
                answers.append(conn.recv())
            except (EOFError, ConnectionError):
                proc.join(timeout=5)
                raise RuntimeError(f"a food collector worker process died (exit code {proc.exitcode}; its error "
                                   f"is printed above); a script that starts workers must run its code under "
                                   f"`if __name__ == '__main__':`") from None
        for ok, answer in answers:
            if not ok:
                raise RuntimeError(f"a food collector worker failed: {answer}")
        return [answer for _, answer in answers]

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None):
        """Reset every world (world i seeded with ``seed + i``), or those ``options["reset_mask"]`` selects.
        Returns (obs, info).
        """
        if seed is None:
            seeds = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"reset got {len(seeds)} seeds for {self.num_envs} worlds")
        mask = check_reset_mask(options, self.num_envs, at_least_one=True)  # as SyncVectorEnv (workers=1) asks
        spans = list(zip(self._starts[:-1], self._starts[1:]))
        chunk_options = [options if mask is None else {**options, "reset_mask": mask[a:b]}
                         for a, b in spans]
        parts = self._ask("reset", [(seeds[a:b], o) for (a, b), o in zip(spans, chunk_options)])
        return np.concatenate([obs for obs, _ in parts]), merge_infos([i for _, i in parts], self.sizes)

    def step(self, actions):
        """Step every world. Returns batched (obs, rewards, terminated, truncated, info)."""
        actions = np.asarray(actions)
        if actions.shape[:1] != (self.num_envs,):
            raise ValueError(f"actions must have shape ({self.num_envs},), got {actions.shape}")
        parts = self._ask("step", [actions[a:b] for a, b in zip(self._starts[:-1], self._starts[1:])])
        obs, rew, term, trunc = (np.concatenate([p[k] for p in parts]) for k in range(4))
        return obs, rew, term, trunc, merge_infos([p[4] for p in parts], self.sizes)

    def render(self) -> tuple[np.ndarray, ...] | None:
        """One RGB frame per world (``render_mode="rgb_array"``), in world order; None without a render mode."""
        if render_mode_missing(self.render_mode):
            return None
        return tuple(frame for part in self._ask("render", [None] * self.workers) for frame in part)

    def get_state(self) -> dict[str, Any]:
        """Every world's `get_state` and the autoreset flags, as one ``SyncVectorEnv`` over them would hold."""
        parts = self._ask("get_state", [None] * self.workers)
        return {"autoreset": np.concatenate([p["autoreset"] for p in parts]),
                "envs": [s for p in parts for s in p["envs"]]}

    def set_state(self, state: dict[str, Any]) -> None:
        """Restore a `get_state` of the same number of worlds."""
        if len(state["envs"]) != self.num_envs:
            raise ValueError(f"the state holds {len(state['envs'])} worlds, this env has {self.num_envs}")
        auto = np.asarray(state["autoreset"], dtype=bool)
        self._ask("set_state", [{"autoreset": auto[a:b], "envs": state["envs"][a:b]}
                                for a, b in zip(self._starts[:-1], self._starts[1:])])

    def close_extras(self, **kwargs: Any) -> None:
        """End the worker processes."""
        for conn in self._conns:
            try:
                conn.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
        for proc in self._procs:
            proc.join(timeout=5)
            if proc.is_alive():
                proc.terminate()
        for conn in self._conns:
            conn.close()
