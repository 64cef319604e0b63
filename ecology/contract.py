"""The contract between an ecorl environment and the trainer, written down once.

Every environment (the grid tasks and the food collector) implements `EcologicalEnv`: the resolved knobs
(``ecology``), the split of its observation into the network's two branches, the keyword arguments of its
test MDP, the task parameters it takes, and the map from agent positions to cells of a visitation map
(`VisitGrid`). The validators below are the ones both environment packages use, so a bad action or render
mode is refused with the same exception and message everywhere.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from gymnasium.vector import AutoresetMode

from ecology.knobs import TEST_MDP, Ecology
from ecology.measure import corner_cells


class InvalidAction(ValueError, TypeError):
    """An action outside an environment's discrete action space.

    Both a ValueError (a value out of range) and a TypeError (not an integer), so callers may catch
    either: the grid tasks documented ValueError, the food collector TypeError for a wrongly typed action.
    """


@dataclass(frozen=True)
class VisitGrid:
    """The cells of an environment's visitation map and how agent positions fall into them."""

    shape: tuple[int, int]
    """(rows, columns) of the map, indexed [y, x] (image order)."""
    origin: tuple[float, float] = (0.0, 0.0)
    """The (x, y) position of the corner of cell [0, 0]."""
    cells_per_unit: float = 1.0
    """Cells per unit of distance (1 for grid cells)."""
    wall: int = 0
    """Cells of wall along every edge of the map (the grid tasks' wall ring: 1); its corners lie inside it."""

    def corners(self) -> tuple[np.ndarray, np.ndarray]:
        """(rows, cols) of the map's four corner cells inside its wall: where a stuck agent sits (`corner_share`)."""
        return corner_cells(self.shape, self.wall)

    def cells(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row and column of each (x, y) position in ``positions`` (shape (N, 2)), clipped to the map."""
        pos = np.asarray(positions)
        scaled = (pos - np.asarray(self.origin)) * self.cells_per_unit
        cells = scaled.astype(np.int64)
        rows = np.minimum(np.maximum(cells[:, 1], 0), self.shape[0] - 1)  # np.clip, at a fraction of its cost
        cols = np.minimum(np.maximum(cells[:, 0], 0), self.shape[1] - 1)
        return rows, cols


@runtime_checkable
class EcologicalEnv(Protocol):
    """What the trainer asks of every environment (``env.unwrapped``)."""

    ecology: Ecology
    """The resolved knobs: dynamism, shaping schedule, reset-free, reward mode."""

    @property
    def observation_split(self) -> tuple[int, int]:
        """(view inputs, inventory inputs): the observation's two parts, read by the network's two branches."""

    @property
    def visit_grid(self) -> VisitGrid:
        """The visitation map of this environment's agent positions (``info["agent_pos"]``)."""

    def test_mdp_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``gymnasium.make`` that give this task's evaluation MDP."""

    @classmethod
    def parameter_names(cls) -> tuple[str, ...]:
        """The task parameters the environment takes as keyword arguments (besides the knobs)."""


def make_test_mdp_kwargs(params: Mapping[str, Any], horizon: int, **overrides: Any) -> dict[str, Any]:
    """A task's test-MDP arguments: its parameters, the `TEST_MDP` knobs, its test horizon and overrides."""
    return {**params, **TEST_MDP, "horizon": horizon, **overrides}


def check_action(action: Any, num_actions: int, names: Sequence[str] = ()) -> int:
    """Return ``action`` as an int, or raise `InvalidAction` unless it is an integer in [0, num_actions)."""
    if isinstance(action, np.ndarray) and action.shape == ():
        action = action.item()
    is_int = isinstance(action, (int, np.integer)) and not isinstance(action, (bool, np.bool_))
    if not is_int or not 0 <= action < num_actions:
        named = f" ({', '.join(names)})" if names else ""
        raise InvalidAction(f"invalid action {action!r}: expected an integer in [0, {num_actions}){named}")
    return int(action)


def check_reset_mask(options: Mapping[str, Any] | None, num_envs: int, at_least_one: bool = False) -> np.ndarray | None:
    """Gymnasium's ``options["reset_mask"]`` of a vector env's reset as a boolean array of shape (num_envs,), None
    without one; a mask of another dtype or shape (or, ``at_least_one``, with no True) is a one-line ValueError.
    """
    mask = (options or {}).get("reset_mask")
    if mask is None:
        return None
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != (num_envs,) or (at_least_one and not mask.any()):
        need = " with at least one True" if at_least_one else ""
        raise ValueError(f"options['reset_mask'] must be a boolean array of shape ({num_envs},){need}, got dtype "
                         f"{mask.dtype}, shape {mask.shape}")
    return mask


def check_autoreset_mode(mode) -> AutoresetMode:
    """``mode`` as an `AutoresetMode` (a member, its value such as ``"SameStep"``, or its name such as
    ``"same_step"``), or a one-line ValueError naming the three.
    """
    if isinstance(mode, AutoresetMode):
        return mode
    for member in AutoresetMode:
        if isinstance(mode, str) and mode.lower() in (member.value.lower(), member.name.lower()):
            return member
    choices = ", ".join(f"AutoresetMode.{m.name}" for m in AutoresetMode)
    raise ValueError(f"autoreset_mode must be one of {choices} (gymnasium.vector.AutoresetMode), got {mode!r}")


def render_mode_missing(render_mode: str | None) -> bool:
    """True, with Gymnasium's warning, when an env asked to ``render()`` has no render mode (it returns None)."""
    if render_mode is not None:
        return False
    import gymnasium as gym

    gym.logger.warn("render() called without render_mode; pass render_mode='rgb_array'")
    return True


def can_render(render_mode: str | None, laid_out: bool) -> bool:
    """Whether an env can draw a frame: False, with Gymnasium's warning, without a render mode; an error before
    its first reset (``laid_out`` False), when there is no world to draw yet.
    """
    if render_mode_missing(render_mode):
        return False
    if not laid_out:
        raise RuntimeError("call reset() before render(): no world has been laid out yet")
    return True


def check_render_mode(render_mode: str | None, modes: Sequence[str]) -> str | None:
    """Return ``render_mode``, or raise ValueError unless it is None or one of ``modes``."""
    if render_mode is not None and render_mode not in modes:
        choices = ", ".join(repr(m) for m in modes)
        raise ValueError(f"unknown render_mode {render_mode!r}; choose None or one of {choices}")
    return render_mode
