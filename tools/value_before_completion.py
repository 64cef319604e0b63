"""How much value a trained policy's Q-network gives the steps that lead to a task completion.

    python tools/value_before_completion.py POLICY.npz [POLICY.npz ...] [--completions 300] [--before 20]

For each exported policy (`policies/best.npz` of a shipped run), worlds of its own training environment (task,
dynamism, reward, env parameters, with or without resets, as trained) are stepped by a uniform random behaviour
until ``--completions`` tasks are completed. For each completion, the observations of the ``--before`` steps before
it are kept (k = 0 is the state in which the completing action was taken; windows that cross a reset are dropped).
Printed per k: the mean greedy value max_a Q(s), the mean Q of the action the behaviour took, and, against a
baseline of random states from the same worlds, the share of those states whose greedy value the window's state
beats. At k = 0 it also prints how often the completing action is the greedy one, and its Q minus the best other
action's (its advantage as the network sees it); then the same two numbers for those states with the agent's own
cell emptied and with its hands emptied, which tell a network that ties the value to the state (its greedy value
drops when the state is changed) from one that also ties it to the completing action (its advantage drops too).

A learner that has assigned credit shows values rising toward the completion (k -> 0) and above the random
states'; one that has not shows a flat profile at the random states' level. Outside the package and its tests:
a diagnostic whose figures `docs/results/paper/figures.md` quotes with this command.
"""

from __future__ import annotations

import argparse
from collections import deque
from pathlib import Path

import numpy as np
import torch

from train.storage.policy import load_policy
from train.tasks import completions, get_task, make_vector_env, probe, step_worlds

WORLDS = 64
"""Worlds stepped side by side."""
VIEW_CELLS, CENTRE = 25, 12
"""The grid tasks' observation: a 5×5 view one-hot per channel (index channel·25 + cell), the agent's cell at 12,
then the carried object one-hot."""


def completion_windows(policy, completions_wanted: int, before: int, seed: int = 0
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Windows (E, before + 1, obs_dim) of observations ending in the state of a completing action (k = 0 last),
    the actions taken in them (E, before + 1), and as many random states (E, obs_dim) from the same worlds.
    """
    env_cfg = policy.cfg.env
    env = make_vector_env(get_task(env_cfg.task).env_id, WORLDS, env_cfg.env_make_kwargs)
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    history = [deque(maxlen=before + 1) for _ in range(WORLDS)]
    resetting = np.zeros(WORLDS, dtype=bool)
    windows, actions, random_states = [], [], []
    n_actions = int(env.single_action_space.n)
    while len(windows) < completions_wanted:
        act = rng.integers(n_actions, size=WORLDS)
        for i in np.flatnonzero(~resetting):
            history[i].append((obs[i].copy(), int(act[i])))
        obs, _, terminated, truncated, _ = step_worlds(env, act)
        for i in np.flatnonzero(completions(env) & ~resetting):
            if len(history[i]) == before + 1:
                windows.append(np.stack([o for o, _ in history[i]]))
                actions.append([a for _, a in history[i]])
                random_states.append(obs[rng.integers(WORLDS)].copy())
        for i in np.flatnonzero(resetting):
            history[i].clear()
        resetting = terminated | truncated
    env.close()
    return np.stack(windows), np.asarray(actions), np.stack(random_states)


def q_values(policy, obs: np.ndarray) -> np.ndarray:
    """The policy's Q-values of observations (..., obs_dim), shaped (..., actions)."""
    flat = torch.from_numpy(obs.reshape(1, -1, obs.shape[-1]).astype(np.float32))
    return policy.q_values(flat)[0].numpy().reshape(*obs.shape[:-1], -1)


def advantage(q: np.ndarray, actions: np.ndarray) -> np.ndarray:
    """Per row of ``q`` (N, actions): the Q of ``actions`` (N,) minus the best other action's."""
    others = np.where(np.arange(q.shape[-1]) == actions[:, None], -np.inf, q).max(-1)
    return q[np.arange(len(q)), actions] - others


def value_profile(policy, windows: np.ndarray, actions: np.ndarray, random_states: np.ndarray) -> list[str]:
    """Lines of the printed table: per k, mean greedy value, mean Q of the taken action, share above random."""
    q_windows, q_random = q_values(policy, windows), q_values(policy, random_states)
    values, random_values = q_windows.max(-1), q_random.max(-1)
    taken = np.take_along_axis(q_windows, actions[..., None], -1)[..., 0]
    before = windows.shape[1] - 1
    last, completing = q_windows[:, -1], actions[:, -1]
    greedy_last = (last.argmax(-1) == completing).mean()
    edge = advantage(last, completing)
    lines = [f"random states: greedy value {random_values.mean():.2f} (median {np.median(random_values):.2f})",
             f"k = 0: the completing action is greedy in {greedy_last:.0%} of {len(windows)} completions; its Q minus "
             f"the best other action's: median {np.median(edge):+.2f} "
             f"[quartiles {np.quantile(edge, 0.25):+.2f}, {np.quantile(edge, 0.75):+.2f}]",
             "   k   max_a Q   Q(taken)   above random"]
    for k in (0, 1, 2, 3, 5, 10, 15, 20):
        if k <= before:
            col = before - k
            above = (values[:, col, None] > random_values[None, :]).mean()
            lines.append(f"{k:4d} {values[:, col].mean():9.2f} {taken[:, col].mean():10.2f} {above:13.0%}")
    return lines


def counterfactual_lines(policy, windows: np.ndarray, actions: np.ndarray) -> list[str]:
    """Lines comparing, at k = 0, the completing action's advantage and the greedy value of the states as seen
    with the same states with the agent's own cell emptied, or with its hands emptied: whether the network ties
    the value to the state or to the action that completes the task.
    """
    states, completing = windows[:, -1], actions[:, -1]
    view_dim = probe(get_task(policy.cfg.env.task), policy.cfg.env).view_dim
    centre_cells = CENTRE + VIEW_CELLS * np.arange(view_dim // VIEW_CELLS)
    emptied_centre = states.copy()
    emptied_centre[:, centre_cells] = 0.0
    emptied_centre[:, CENTRE] = 1.0  # channel 0 is an empty cell
    emptied_hands = states.copy()
    emptied_hands[:, view_dim:] = 0.0
    lines = ["k = 0 states        completing action's advantage (median)   greedy value (median)"]
    for name, obs in (("as seen", states), ("own cell emptied", emptied_centre), ("hands emptied", emptied_hands)):
        q = q_values(policy, obs)
        lines.append(f"{name:18s} {np.median(advantage(q, completing)):+20.2f} {np.median(q.max(-1)):28.2f}")
    return lines


def main() -> None:
    """Print the value profile before completions for each policy named."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policies", nargs="+", type=Path, help="exported policies (.npz)")
    parser.add_argument("--completions", type=int, default=300, help="completions to collect (default: 300)")
    parser.add_argument("--before", type=int, default=20, help="steps kept before each completion (default: 20)")
    args = parser.parse_args()
    for path in args.policies:
        policy = load_policy(path)
        cfg = policy.cfg.env
        if get_task(cfg.task).metric != "success":
            parser.error(f"{path} is a {cfg.task} policy: that task has no completions to look before; "
                         "give a grid task's policy")
        print(f"\n{path} (seed {policy.seed}; {cfg.task}, p {cfg.dynamism}, "
              f"{'reset-free' if cfg.reset_free else 'episodic'}, {cfg.reward}, {cfg.env_kwargs or ''})")
        windows, actions, random_states = completion_windows(policy, args.completions, args.before)
        print("\n".join(value_profile(policy, windows, actions, random_states)))
        print("\n".join(counterfactual_lines(policy, windows, actions)))


if __name__ == "__main__":
    main()
