"""Checks on a checkpoint's values before any of them reaches torch, numpy's generators or the engine.

A checkpoint is data read from a file that anyone may have edited (and re-signed: its SHA-256 digests only
catch accidents). `check_state` compares the saved tree with the live one of the trainer that will load it:
the same keys, arrays of the same shape and dtype, finite network weights, counters that are not negative,
replay pointers inside the buffer, random-generator states that their generators accept. The grid worlds
are checked where they are restored (`gridtasks.check_worlds`, through `train.tasks.restore_env_state`).
Every refusal is a ValueError with a one-line message; the trainer turns it into a `RunDirError`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch

from train.tasks import env_state

MAX_COUNTER = 2**62
"""Largest count a checkpoint may hold."""
MAX_STEP = 2**54
"""Largest step a checkpoint may hold: a run's budget is at most 2**53 steps (`train.config.checks.MAX_INT`),
and a run stops within an epoch of it."""
MAX_ROWS = 10_000_000
"""Most metric rows a checkpoint may hold."""
REPLAY_FLAG_BITS = 0b11
"""Bits a replay slot's flags may set (episode start, terminated)."""


def check_counter(value: Any, what: str, low: int = 0, high: int = MAX_COUNTER) -> int:
    """``value`` as an int in [low, high], else ValueError."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= int(value) <= high:
        raise ValueError(f"{what} is {value!r}, not an integer in [{low}, {high}]")
    return int(value)


def _array(value: Any, like: np.ndarray | torch.Tensor, what: str, shape: tuple | None = None) -> np.ndarray:
    """``value`` as a numpy array of ``like``'s dtype (and ``shape``, default ``like``'s), else ValueError."""
    want_dtype = like.dtype if isinstance(like, np.ndarray) else torch.empty(0, dtype=like.dtype).numpy().dtype
    got = value.detach().numpy() if isinstance(value, torch.Tensor) else value
    shape = tuple(like.shape) if shape is None else shape
    if not isinstance(got, np.ndarray) or got.dtype != want_dtype or got.shape != shape:
        found = f"{got.dtype} {got.shape}" if isinstance(got, np.ndarray) else type(value).__name__
        raise ValueError(f"{what} is {found}, this run needs {want_dtype} {shape}")
    return got


def _finite(array: np.ndarray, what: str) -> None:
    if array.dtype.kind == "f" and not np.isfinite(array).all():
        raise ValueError(f"{what} holds {int((~np.isfinite(array)).sum())} NaN or infinite values")


def check_tree(saved: Any, live: Any, what: str, finite: bool = True) -> None:
    """Same structure as ``live``: tensors/arrays of its dtype and shape with finite values (any values where
    not ``finite``), ints >= 0, booleans, finite floats, equal strings, generator states their generator accepts.
    """
    if isinstance(live, dict) and "bit_generator" in live:
        check_rng_state(saved, getattr(np.random, live["bit_generator"])(), what)
    elif isinstance(live, dict):
        if not isinstance(saved, dict) or set(saved) != set(live):
            raise ValueError(f"{what} does not have this run's fields")
        for key, value in live.items():
            check_tree(saved[key], value, f"{what}/{key}", finite)
    elif isinstance(live, list):
        if not isinstance(saved, list) or len(saved) != len(live):
            raise ValueError(f"{what} does not hold {len(live)} entries")
        for i, (a, b) in enumerate(zip(saved, live)):
            check_tree(a, b, f"{what}/{i}", finite)
    elif isinstance(live, str):
        if saved != live:
            raise ValueError(f"{what} is {saved!r}, not {live!r}")
    elif isinstance(live, (torch.Tensor, np.ndarray)):
        array = _array(saved, live, what)
        if finite:
            _finite(array, what)
    elif isinstance(live, bool):
        if not isinstance(saved, bool):
            raise ValueError(f"{what} is {saved!r}, not true or false")
    elif isinstance(live, int):
        check_counter(saved, what)
    elif isinstance(live, float):
        if not isinstance(saved, (int, float)) or not math.isfinite(saved):
            raise ValueError(f"{what} is {saved!r}, not a finite number")


def check_rng_state(saved: Any, live: np.random.Generator | np.random.BitGenerator, what: str) -> None:
    """A numpy generator state that ``live``'s bit generator accepts (tried on a scratch copy)."""
    bits = live.bit_generator if isinstance(live, np.random.Generator) else live
    if not isinstance(saved, dict) or saved.get("bit_generator") != type(bits).__name__:
        raise ValueError(f"{what} is not a {type(bits).__name__} state")
    try:
        type(bits)().state = saved
    except (TypeError, ValueError, KeyError, OverflowError) as err:
        raise ValueError(f"{what} is not a valid generator state ({err})") from None


def check_torch_rng(saved: Any) -> None:
    """A torch CPU generator state that torch accepts (tried on a scratch generator)."""
    _array(saved, torch.get_rng_state(), "torch_rng")
    try:
        torch.Generator().set_state(saved)
    except (RuntimeError, TypeError, ValueError) as err:
        raise ValueError(f"torch_rng is not a valid generator state ({' '.join(str(err).split())})") from None


def check_replay(saved: Any, live: dict[str, np.ndarray], capacity: int, num_actions: int) -> None:
    """Replay arrays of this run's layout, pointers inside the buffer, actions and flags in range."""
    if not isinstance(saved, dict) or set(saved) != set(live):
        raise ValueError("replay does not have this run's fields")
    k = live["ptr"].shape[0]
    size = _array(saved["size"], live["size"], "replay/size")
    ptr = _array(saved["ptr"], live["ptr"], "replay/ptr")
    if size.min(initial=0) < 0 or size.max(initial=0) > capacity or ptr.min(initial=0) < 0 \
            or ptr.max(initial=0) >= capacity:
        raise ValueError(f"replay pointers lie outside the buffer of {capacity} slots")
    if np.any((size < capacity) & (ptr != size)):
        raise ValueError("replay pointers disagree with the replay sizes")
    used = int(size.max(initial=0))
    width = live["obs"].shape[2]
    _array(saved["obs"], live["obs"], "replay/obs", (k, used, width))
    action = _array(saved["action"], live["action"], "replay/action", (k, used))
    _finite(_array(saved["reward"], live["reward"], "replay/reward", (k, used)), "replay/reward")
    flags = _array(saved["flags"], live["flags"], "replay/flags", (k, used))
    if action.size and (action.min() < 0 or action.max() >= num_actions):
        raise ValueError(f"replay actions lie outside [0, {num_actions})")
    if np.any(flags & ~np.uint8(REPLAY_FLAG_BITS)):
        raise ValueError("replay flags hold unknown bits")
    if _array(saved["obs"], live["obs"], "replay/obs", (k, used, width)).dtype.kind == "f":
        _finite(saved["obs"], "replay/obs")


def check_rows(rows: Any, columns: tuple[str, ...], optional: tuple[str, ...] = ()) -> None:
    """Metric rows: a list of dicts with exactly ``columns`` (or all but the ``optional`` ones, as written before
    those existed), each value a number.
    """
    if not isinstance(rows, list) or len(rows) > MAX_ROWS:
        raise ValueError("rows is not a list of metric rows")
    allowed = (set(columns), set(columns) - set(optional))
    for row in rows:
        if not isinstance(row, dict) or set(row) not in allowed or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in row.values()):
            raise ValueError(f"a metric row is not a mapping of {', '.join(columns)} to numbers")


def steps_left(step: int) -> int:
    """Most steps a run at ``step`` may still take: counters that grow once per step must leave this much room
    below their maximum, so that every checkpoint the run writes later is accepted as well.
    """
    return max(0, MAX_STEP - int(step))


def check_state(state: dict[str, Any], trainer: Any, part: int = 0) -> None:
    """Raise ValueError unless ``state`` (a checkpoint's tree) is one that part ``part`` of ``trainer`` may
    load, value by value.
    """
    from train.storage.rundir import ADDED_COLUMNS, METRIC_COLUMNS

    live = trainer.state_dict(part)
    piece = trainer.parts[part]
    cfg = piece.cfg
    step = check_counter(state.get("step"), "step", 0, MAX_STEP)
    check_counter(state.get("epoch"), "epoch", 0, step)
    check_counter(state.get("loss_count"), "loss_count", 0, MAX_COUNTER - steps_left(step))
    check_counter(state.get("last_checkpoint"), "last_checkpoint", -1, step)
    # a diverged seed's weights and optimiser moments may be NaN or infinite: they stay in its own row (every
    # update is per seed), so the run resumes and the other seeds train on
    check_tree(state.get("agent"), live["agent"], "agent", finite=False)
    if live["rnd"] is not None:
        check_tree(state.get("rnd"), live["rnd"], "rnd", finite=False)
    check_replay(state.get("replay"), live["replay"], cfg.dqn.buffer_size, trainer.info.num_actions)
    rngs = state.get("rngs")
    streams = {name: gens[piece.rows] for name, gens in trainer.learner.rngs.items()}
    if not isinstance(rngs, dict) or set(rngs) != set(streams):
        raise ValueError("rngs does not hold this run's random streams")
    for name, gens in streams.items():
        if not isinstance(rngs[name], list) or len(rngs[name]) != len(gens):
            raise ValueError(f"rngs/{name} does not hold one state per seed")
        for k, (saved, gen) in enumerate(zip(rngs[name], gens)):
            check_rng_state(saved, gen, f"rngs/{name}/{k}")
    check_torch_rng(state.get("torch_rng"))
    k = cfg.run.seeds
    visits = _array(state.get("visits"), live["visits"], "visits")
    if visits.min(initial=0) < 0:
        raise ValueError("visits holds negative counts")
    if "visits_at_eval" in state:  # absent in checkpoints written before the corner share
        earlier = _array(state["visits_at_eval"], live["visits_at_eval"], "visits_at_eval")
        if earlier.min(initial=0) < 0 or (earlier > visits).any():
            raise ValueError("visits_at_eval holds counts that are negative or above the visits")
    _array(state.get("autoreset"), live["autoreset"], "autoreset")
    _finite(_array(state.get("train_reward"), live["train_reward"], "train_reward"), "train_reward")
    _array(state.get("loss_sum"), live["loss_sum"], "loss_sum")
    obs = state.get("obs")
    if obs is not None:
        if not isinstance(obs, np.ndarray) or obs.dtype.kind != "f" or obs.shape != (k, trainer.info.obs_dim):
            raise ValueError(f"obs is not a float array of shape {(k, trainer.info.obs_dim)}")
        _finite(obs, "obs")
        if trainer.task.binary_obs and not np.isin(obs, (0.0, 1.0)).all():
            raise ValueError("obs holds values other than 0 and 1, which this task never observes")
    if state.get("env") is not None:  # the grid worlds are checked value by value where they are restored
        check_tree(state["env"], env_state(piece.env), "env")
    check_rows(state.get("rows"), METRIC_COLUMNS, ADDED_COLUMNS)
