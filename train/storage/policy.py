"""Trained policies: one seed's Q-network, read from a run or from a small policy file.

A run's ``checkpoint.npz`` holds every seed's networks, the optimiser, the replay buffer and the
environments' state (tens to hundreds of MB). A *policy file* (``.npz``) holds what acting needs: one seed's
online parameters, the run's `TrainConfig` (which fixes the network and the task) and a little provenance
(source run, seed, step, validation success). ``ecorl export`` writes one; ``ecorl video`` reads either,
and by default the policy shipped for the task in ``train/data/policies/``.
"""

from __future__ import annotations

import csv
import io
import json
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from train.agent.network import QNetwork
from train.config import TrainConfig
from train.evaluation.protocol import (
    ActionValues,
    EvalResult,
    Evaluator,
    UniformRandom,
    evaluation_kwargs,
    run_evaluation_kwargs,
)
from train.storage.checkpoint import CHECKPOINT_NAME, LEGACY_NAME, legacy_message
from train.storage.fileio import atomic_file
from train.storage.rundir import EXPERIMENT_FILE, RUN_POLICIES_DIR, RunDir, RunDirError
from train.storage.safeio import load_json, loads_json, open_regular, read_npy, read_text, regular_file
from train.storage.statecheck import check_counter
from train.tasks import get_task, probe

POLICY_DIR = Path(__file__).resolve().parents[1] / "data" / "policies"
"""Where the repository keeps one trained policy per grid task (``<task>.npz``)."""

POLICY_FORMAT = 1
"""Version of the policy-file layout; files of another version are refused."""


@dataclass
class Policy:
    """One agent's Q-network with the configuration it was trained under."""

    cfg: TrainConfig
    """The training run's `TrainConfig` (task, knobs, network sizes, evaluation horizon)."""
    params: torch.Tensor
    """The online network's flat parameters, shape (1, P)."""
    seed: int
    """The agent's training seed."""
    meta: dict[str, Any] = field(default_factory=dict)
    """Provenance: source run, step, validation success at export, ..."""

    def __post_init__(self) -> None:
        self._info = info = probe(get_task(self.cfg.env.task), self.cfg.env)
        self._net = QNetwork.from_config(info.view_dim, info.obs_dim, info.num_actions, self.cfg.dqn)
        if self.params.shape != (1, self._net.num_params) or self.params.dtype != torch.float32:
            raise ValueError(f"policy parameters have shape {tuple(self.params.shape)} and dtype {self.params.dtype}, "
                             f"but the network of this configuration needs (1, {self._net.num_params}) float32")
        if not torch.isfinite(self.params).all():
            raise ValueError(f"the policy holds {int((~torch.isfinite(self.params)).sum())} NaN or infinite "
                             f"parameters; it cannot act (use a checkpoint of a healthy run)")
        self._bound = self._net.bind(self.params)

    @property
    def obs_dim(self) -> int:
        """Length of the observations the policy reads."""
        return self._info.obs_dim

    @property
    def test_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of the test MDP the policy is evaluated in (at the run's evaluation horizon)."""
        return run_evaluation_kwargs(self._info.test_kwargs, self.cfg.eval)

    @property
    def task(self) -> str:
        """The task the policy was trained on."""
        return self.cfg.env.task

    def q_values(self, obs: torch.Tensor) -> torch.Tensor:
        """Q-values (1, N, actions) of observations (1, N, obs_dim), as `DoubleDQN.q_values` for one agent."""
        with torch.no_grad():
            return self._net.forward(self._bound, obs)[0]

    def greedy(self, obs: torch.Tensor) -> np.ndarray:
        """Greedy actions (1, N) of observations (1, N, obs_dim), as `DoubleDQN.greedy` for one agent."""
        return self.q_values(obs).argmax(-1).numpy()

    def act(self, obs: np.ndarray) -> int:
        """The greedy action for one observation."""
        return int(self.greedy(torch.from_numpy(np.asarray(obs, dtype=np.float32)).view(1, 1, -1))[0, 0])

    def evaluate(self, rollouts: int = 100, epsilon: float | None = None, horizon: int | None = None,
                 layout_seeds: Sequence[int] | None = None, dynamism: float | None = None) -> EvalResult:
        """Success and return on the first ``rollouts`` validation layouts of the test MDP (the paper's
        protocol: epsilon-greedy with the run's evaluation epsilon unless ``epsilon`` is given); ``horizon``
        replaces the run's evaluation horizon, ``layout_seeds`` the validation layouts (one per rollout),
        ``dynamism`` the test MDP's (0, static, in the paper's protocol).
        """
        eps = self.cfg.eval.eval_epsilon if epsilon is None else epsilon
        return self._rollouts(self.test_mdp(dynamism, horizon), self, [self.seed], rollouts, eps, layout_seeds)

    def random_draws(self, draws: int, rollouts: int = 100, dynamism: float | None = None) -> EvalResult:
        """A uniform random policy on the same ``rollouts`` validation layouts of the policy's test MDP (with
        ``dynamism`` if given), ``draws`` times with independent streams (one agent each, K = ``draws``): the
        spread of the random baseline that ``evaluate(epsilon=1)`` draws once. Draw 0 is that one draw (the same
        exploration stream).
        """
        return self._rollouts(self.test_mdp(dynamism), UniformRandom(self._info.num_actions),
                              range(self.seed, self.seed + draws), rollouts, 1.0)

    def test_mdp(self, dynamism: float | None = None, horizon: int | None = None) -> dict[str, Any]:
        """`test_kwargs`, with the test MDP's dynamism replaced by ``dynamism`` and each rollout ``horizon`` long,
        where given.
        """
        ev = self.cfg.eval
        kwargs = (self.test_kwargs if horizon is None else
                  evaluation_kwargs(self._info.test_kwargs, horizon, ev.eval_dynamism, ev.eval_env_kwargs))
        return kwargs if dynamism is None else {**kwargs, "dynamism": dynamism}

    def describe_test_mdp(self, dynamism: float | None = None, horizon: bool = True) -> str:
        """The test MDP in a few words: its horizon (if ``horizon``), its dynamism and the task parameters the
        run set, at their values in the test MDP.
        """
        kwargs = self.test_mdp(dynamism)
        p = float(kwargs["dynamism"])
        words = [f"horizon {kwargs['horizon']}"] if horizon else []
        words.append("static" if p == 0 else f"dynamism {p:g}")
        named = {**self.cfg.env.env_kwargs, **self.cfg.eval.eval_env_kwargs}
        return ", ".join(words + [f"{key}={kwargs[key]}" for key in named])

    def _rollouts(self, kwargs: dict[str, Any], agent: ActionValues, seeds: Sequence[int], rollouts: int,
                  epsilon: float, layout_seeds: Sequence[int] | None = None) -> EvalResult:
        """``agent``'s evaluation (one agent per seed of ``seeds``) in this task's test MDP built from ``kwargs``."""
        evaluator = Evaluator(get_task(self.task).env_id, kwargs, len(seeds), rollouts, epsilon,
                              self._info.num_actions, layout_seeds)
        try:
            return evaluator(agent, seeds, step=0)
        finally:
            evaluator.close()


def run_config(run_dir: Path) -> TrainConfig:
    """The `TrainConfig` a run directory was made with."""
    return TrainConfig.from_dict(load_json(run_dir / "config.json"))


def resolve_run_dir(path: str | Path) -> Path:
    """The run directory of a run directory or of a checkpoint file inside one."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist; give a run directory (with config.json and "
                                f"{CHECKPOINT_NAME}) or a .npz policy file")
    run_dir = path.parent if path.is_file() else path
    if not (run_dir / CHECKPOINT_NAME).exists() and (run_dir / LEGACY_NAME).exists():
        raise RunDirError(legacy_message(run_dir / LEGACY_NAME))
    if not (run_dir / CHECKPOINT_NAME).exists() or not (run_dir / "config.json").exists():
        shipped = sorted((run_dir / RUN_POLICIES_DIR).glob("*.npz")) if run_dir.is_dir() else []
        hint = (f"; it was kept without its checkpoint: pass one of its exported policies, "
                f"{', '.join(str(p) for p in shipped)}" if shipped else "")
        raise FileNotFoundError(f"{path} is not a run directory with config.json and {CHECKPOINT_NAME} "
                                f"(nor a {CHECKPOINT_NAME} inside one, nor a .npz policy file){hint}")
    return run_dir


def validation_success(run_dir: Path, step: int | None = None, column: str = "success") -> dict[int, float]:
    """Validation success (or another metrics.csv ``column``) of each seed index at evaluation ``step``
    (default: the run's last evaluation); empty if there is no such evaluation.
    """
    path = run_dir / "metrics.csv"
    rows = list(csv.DictReader(io.StringIO(read_text(path)))) if path.exists() or path.is_symlink() else []
    if not rows:
        return {}
    seeds = run_config(run_dir).run.seed_list
    try:
        step = max(int(r["step"]) for r in rows) if step is None else step
        return {seeds.index(int(r["seed"])): float(r[column]) for r in rows if int(r["step"]) == step}
    except (KeyError, TypeError, ValueError) as err:
        raise ValueError(f"{path} is not a metrics file of this run ({err}); restore it, or delete it to "
                         f"rebuild it from the checkpoint with 'ecorl train TASK --resume'") from None


def seed_scores(run_dir: Path, step: int) -> tuple[str, dict[int, float]]:
    """What ranks a run's seeds at evaluation ``step``: ``('success', ...)``, or ``('return', ...)`` where the task
    has no success (every value NaN: the food collector).
    """
    scores = validation_success(run_dir, step)
    if scores and all(np.isnan(v) for v in scores.values()):
        return "return", validation_success(run_dir, step, "return")
    return "success", scores


def load_run(path: str | Path) -> tuple[Path, dict[str, Any]]:
    """The run directory of ``path`` and its verified checkpoint (configuration, step and online networks)."""
    run_dir = resolve_run_dir(path)
    state = RunDir(run_dir).read_checkpoint(keys=["agent/online"])
    try:
        cfg = TrainConfig.from_dict(state["config"])
        check_counter(state["step"], "step")
        online = state["agent"]["online"]
        if not isinstance(online, torch.Tensor) or online.ndim != 2 or online.shape[0] != cfg.run.seeds:
            raise ValueError(f"agent/online is not a ({cfg.run.seeds}, P) array")
    except (KeyError, TypeError, ValueError) as err:
        raise RunDirError(f"{run_dir / CHECKPOINT_NAME} holds an unusable configuration or network ({err}); "
                          f"it is not a checkpoint ecorl wrote") from None
    return run_dir, state


def run_label(run_dir: Path) -> str:
    """The name a policy file gives the run it came from: ``EXPERIMENT/TASK/CONDITION`` for a run of
    ``ecorl run``, else the run directory's own name. Never a path of the machine that exported it, since
    policy files are shipped.
    """
    run_dir = Path(run_dir).resolve()
    if (run_dir.parent.parent / EXPERIMENT_FILE).is_file():
        return "/".join(run_dir.parts[-3:])
    return run_dir.name


def _policy_of(run_dir: Path, state: dict[str, Any], seed_index: int) -> Policy:
    """Seed number ``seed_index`` of a loaded checkpoint as a `Policy`."""
    cfg = TrainConfig.from_dict(state["config"])
    if not 0 <= seed_index < cfg.run.seeds:
        raise ValueError(f"{run_dir} trained {cfg.run.seeds} seed(s); --agent must be in [0, {cfg.run.seeds})")
    step = int(state["step"])
    meta = {"source": run_label(run_dir), "step": step, "agent": seed_index}
    column, scores = seed_scores(run_dir, step)
    if seed_index in scores:
        meta[f"validation_{column}"] = scores[seed_index]
    params = state["agent"]["online"][seed_index:seed_index + 1].clone()
    return Policy(cfg, params, cfg.run.seed_list[seed_index], meta)


def policy_from_run(path: str | Path, seed_index: int = 0) -> Policy:
    """The online network of seed number ``seed_index`` in the run at ``path`` (run dir or checkpoint)."""
    return _policy_of(*load_run(path), seed_index)


def save_policy(policy: Policy, out: str | Path) -> Path:
    """Write ``policy`` as a policy file (float32 parameters, config and provenance as JSON)."""
    out = Path(out)
    if not is_policy_file(out):
        raise ValueError(f"a policy file must end in .npz (and not be named {CHECKPOINT_NAME}), got {out}")
    header = {"format": POLICY_FORMAT, "config": policy.cfg.to_dict(), "seed": policy.seed, "meta": policy.meta}
    with atomic_file(out) as f:
        np.savez_compressed(f, params=policy.params.numpy().astype(np.float32), header=np.array(json.dumps(header)))
    return out


MAX_POLICY_MEMBER_BYTES = {"params.npy": 64 << 20, "header.npy": 4 << 20}
"""Largest uncompressed members a policy file may have (a grid policy's parameters take about 60 KB)."""


def _not_a_policy(path: Path, why: str) -> ValueError:
    return ValueError(f"{path} is not an ecorl policy file ({why}); write one with "
                      f"'ecorl export RUN_DIR --out FILE.npz'")


def _read_policy_member(zf: zipfile.ZipFile, path: Path, name: str) -> np.ndarray:
    """One array of a policy file, its header's size checked against its member's before allocating."""
    info = zf.getinfo(f"{name}.npy")
    with zf.open(info) as member:
        return read_npy(member, min(info.file_size, MAX_POLICY_MEMBER_BYTES[f"{name}.npy"]), f"{path} {name!r}")


def _read_policy_arrays(path: Path) -> tuple[np.ndarray, dict[str, Any]]:
    """The parameters and the JSON header of a policy file, sizes checked before anything is read."""
    try:
        with zipfile.ZipFile(path) as zf:
            sizes = {info.filename: info.file_size for info in zf.infolist()}
            for name, limit in MAX_POLICY_MEMBER_BYTES.items():
                if name not in sizes:
                    raise _not_a_policy(path, f"no {name[:-4]!r} array")
                if sizes[name] > limit:
                    raise _not_a_policy(path, f"{name[:-4]!r} holds {sizes[name]} bytes, more than {limit}")
        with open_regular(path) as file, zipfile.ZipFile(file) as zf:
            params, header = (_read_policy_member(zf, path, name) for name in ("params", "header"))
        if header.dtype.kind != "U" or header.ndim != 0:
            raise _not_a_policy(path, f"header is {header.dtype} {header.shape}, not a JSON string")
        header = loads_json(str(header), f"the header of {path}")
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as err:
        if isinstance(err, ValueError) and "not an ecorl policy file" in str(err):
            raise
        raise _not_a_policy(path, f"{type(err).__name__}: {err}".replace("\n", " ")) from None
    if not isinstance(header, dict):
        raise _not_a_policy(path, "header is not a JSON object")
    return params, header


def load_policy_file(path: str | Path) -> Policy:
    """Read a policy file written by `save_policy`; refuse anything else with a one-line reason (not an
    archive, oversized arrays, parameters that are not finite float32, another format).
    """
    path = Path(path)
    with open_regular(path) as file:
        if not zipfile.is_zipfile(file):
            raise _not_a_policy(path, "not an .npz archive")
    params, header = _read_policy_arrays(path)
    if header.get("format") != POLICY_FORMAT:
        raise ValueError(f"{path} has policy format {header.get('format')!r}, this ecorl reads {POLICY_FORMAT}")
    if params.dtype != np.float32 or params.ndim != 2 or params.shape[0] != 1:
        raise _not_a_policy(path, f"parameters are {params.dtype} {params.shape}, expected float32 (1, P)")
    if not np.isfinite(params).all():
        raise ValueError(f"{path} holds {int((~np.isfinite(params)).sum())} NaN or infinite parameters; it cannot act "
                         f"(re-export the policy from a healthy run)")
    try:
        cfg = TrainConfig.from_dict(header["config"])
        seed = int(header["seed"])
        meta = dict(header.get("meta", {}))
    except (KeyError, TypeError, ValueError) as err:
        raise _not_a_policy(path, f"bad header: {err}") from None
    return Policy(cfg, torch.from_numpy(params), seed, meta)


def is_policy_file(path: str | Path) -> bool:
    """True for a path named like a policy file (``.npz``, but not a run's checkpoint)."""
    path = Path(path)
    return path.suffix == ".npz" and path.name != CHECKPOINT_NAME


def load_policy(path: str | Path, seed_index: int = 0) -> Policy:
    """A policy file (``.npz``), or seed number ``seed_index`` of a run directory or checkpoint."""
    path = Path(path)
    if is_policy_file(path):
        if not path.exists() and not path.is_symlink():
            raise FileNotFoundError(f"no policy file at {path}")
        regular_file(path)  # a FIFO, device or link: named as such in one line, never opened
        if seed_index:
            raise ValueError(f"{path} is a policy file, which holds one seed; the seed index {seed_index} (--agent) "
                             f"picks among a run's seeds: pass the run directory instead, or drop --agent")
        return load_policy_file(path)
    return policy_from_run(path, seed_index)


def export_policy(run_dir: str | Path, out: str | Path, seed_index: int | None = None) -> Path:
    """Write seed ``seed_index`` of a run as a policy file; by default the seed with the best validation
    success (the return where the task has no success) at the checkpoint's step.
    """
    run_dir, state = load_run(run_dir)
    if seed_index is None:
        _, scores = seed_scores(run_dir, int(state["step"]))
        seed_index = max(scores, key=lambda k: (np.nan_to_num(scores[k], nan=-np.inf), -k)) if scores else 0
    return save_policy(_policy_of(run_dir, state, seed_index), out)


def export_run_policies(run_dir: str | Path, state: dict[str, Any] | None = None) -> dict[str, Path]:
    """Write a run's best and median seed, by their last validation success (the return where the task has
    no success), as ``RUN_DIR/policies/best.npz`` and ``median.npz`` (the upper median of an even count), among
    the seeds whose weights are finite (a diverged seed's NaN network cannot act); ``state`` is the run's
    checkpoint state if already in memory. Empty if the run has no evaluation yet, or every seed diverged.
    """
    run_dir, state = (Path(run_dir), state) if state is not None else load_run(run_dir)
    step = int(state["step"])
    _, scores = seed_scores(run_dir, step)
    online = state["agent"]["online"]
    scores = {k: v for k, v in scores.items() if bool(torch.isfinite(online[k]).all())}  # diverged seeds cannot act
    if not scores:
        return {}
    ranked = sorted(scores, key=lambda k: (-np.nan_to_num(scores[k], nan=-np.inf), k))
    picks = {"best": ranked[0], "median": ranked[(len(ranked) - 1) // 2]}
    (run_dir / RUN_POLICIES_DIR).mkdir(exist_ok=True)
    return {name: save_policy(_policy_of(run_dir, state, k), run_dir / RUN_POLICIES_DIR / f"{name}.npz")
            for name, k in picks.items()}


def shipped_policy(task: str) -> Path | None:
    """The policy file shipped for ``task`` in `POLICY_DIR`, if there is one."""
    path = POLICY_DIR / f"{task}.npz"
    return path if path.is_file() else None
