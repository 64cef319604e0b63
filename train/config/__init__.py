"""Frozen configuration of one training condition: environment knobs, double DQN, RND, evaluation, run.

Every field carries its documentation as an attribute docstring (the string right below it); `field_docs`
reads them back from the source so the CLI's ``--help`` and this file never disagree. Defaults are the
original code's (Co-Reyes et al., 2020; `jcoreyes/ecologicalrl`), except where a docstring says otherwise.
Values that follow from others are properties, never stored twice.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import inspect
import re
import textwrap
from dataclasses import dataclass, field
from typing import Any

from ecology import REWARD_MODES, VALIDATION_SEED_BASE, parse_schedule
from train.config.checks import (
    MAX_EVAL_HORIZON,
    MAX_EVAL_ROLLOUTS,
    MAX_THREADS,
    check_choices,
    check_int,
    check_kwargs,
    check_layers,
    check_number,
    unknown_choice,
)

MAX_LR = 1.0
"""The largest learning rate accepted: Adam moves each weight by about the rate per step, so a rate above 1 only
ever diverges (the experiments use 1e-5 to 1e-3)."""

RUNTIME = {"runtime": True}
"""Field metadata marking settings that may change when a run is resumed (they do not alter its results)."""

CONFIG_OWNED_ENV_KWARGS = {"dynamism": "use --dynamism", "shaping": "use --shaping",
                           "reset_free": "use --reset-free or --episodic", "reward": "use --reward",
                           "horizon": "use --horizon", "render_mode": "training renders nothing; film with ecorl video"}
"""Environment arguments the config sets itself: env_kwargs may not name them (how to set each instead)."""
EVAL_OWNED_ENV_KWARGS = {"dynamism": "use --eval-dynamism", "horizon": "use --eval-horizon",
                         "shaping": "the test MDP is unshaped", "reset_free": "the test MDP is episodic",
                         "reward": "the test MDP's reward is sparse", "render_mode": "evaluation renders nothing"}
"""Test-MDP arguments the evaluation protocol sets itself: eval_env_kwargs may not name them."""


@dataclass(frozen=True)
class EnvConfig:
    """Which task, and the ecological knobs of its training environment."""

    task: str = "salad"
    """Task name: salad, hunting, scavenging, factory, walled-salad or foodcollector."""
    dynamism: float = 0.0
    """Dynamism p in [0, 1]: rate of change independent of the agent (0 = static original task)."""
    shaping: str = "0"
    """Environment-shaping strength schedule over the lifetime step: a number in [0, 1] or e.g. 'linear:1:0:280000'."""
    reset_free: bool = field(default=False, metadata={"negative": "episodic"})
    """Non-episodic training (one reset, ever) instead of episodic training."""
    reward: str = field(default="sparse", metadata={"choices": REWARD_MODES})
    """Reward mode of the training environment (the food collector only has 'sparse')."""
    horizon: int = 200
    """Episode length of episodic training (ignored when reset-free)."""
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    """Extra task parameters passed to the environment constructor (CLI: KEY=VALUE, the value read as JSON)."""

    def __post_init__(self) -> None:
        if not isinstance(self.task, str) or not self.task:
            raise ValueError(f"task must be a task name, got {self.task!r}")
        check_number("dynamism", self.dynamism, 0.0, 1.0)
        parse_schedule(self.shaping)  # a malformed or endless schedule is a one-line error
        if self.reward not in REWARD_MODES:
            raise unknown_choice("reward mode", self.reward, REWARD_MODES)
        check_int("horizon", self.horizon)
        check_kwargs("env_kwargs", self.env_kwargs, CONFIG_OWNED_ENV_KWARGS)

    @property
    def env_make_kwargs(self) -> dict[str, Any]:
        """Keyword arguments for `gymnasium.make`/`make_vec` of the training environment."""
        return {"dynamism": self.dynamism, "shaping": self.shaping, "reset_free": self.reset_free,
                "reward": self.reward, "horizon": self.horizon, **self.env_kwargs}


@dataclass(frozen=True)
class DQNConfig:
    """Double DQN with the paper's two-branch Q-network (original code, section 4 of the reference)."""

    lr: float = 1e-4
    """Adam learning rate."""
    adam_eps: float = 1e-8
    """Adam epsilon (PyTorch's default, as in the original)."""
    gamma: float = 0.99
    """Discount factor."""
    batch_size: int = 64
    """Transitions per gradient step, per seed (the paper's text says 256; its code uses 64)."""
    buffer_size: int = 500_000
    """Replay capacity per seed, in stored observations (circular, uniform sampling)."""
    tau: float = 0.001
    """Polyak rate of the target network, applied after every gradient step."""
    grad_clip: float = 5.0
    """Maximum global gradient norm per seed."""
    eps_start: float = 1.0
    """Exploration epsilon at step 0."""
    eps_end: float = 0.1
    """Exploration epsilon after the decay."""
    eps_decay_steps: int = 90_000
    """Environment steps over which epsilon falls linearly from eps_start to eps_end."""
    warmup_steps: int = 200
    """Environment steps collected before the first gradient step."""
    epoch_steps: int = 500
    """Environment steps collected per epoch (each epoch then takes updates_per_epoch gradient steps)."""
    updates_per_epoch: int = 500
    """Gradient steps per epoch."""
    view_layers: tuple[int, ...] = (64, 64, 32)
    """Layer widths of the view branch (the last one is its linear output)."""
    inventory_layers: tuple[int, ...] = (16, 16, 16)
    """Layer widths of the inventory branch (the last one is its linear output)."""
    head_layers: tuple[int, ...] = (16, 16)
    """Hidden widths of the head on the concatenated branch outputs (then one linear layer to the actions)."""
    inventory_repeat: int = 1
    """Feed the inventory repeated N times, as the released salad script's np.repeat(inventory, 8) does; 1: off."""
    init: str = field(default="rlkit", metadata={"choices": ("rlkit", "torch")})
    """Weight init: 'rlkit' (original: hidden U(+-1/sqrt(fan_out)), bias 0.1, output layers U(+-3e-3)) or 'torch'."""
    target_init: str = field(default="independent", metadata={"choices": ("independent", "copy")})
    """Target network start: its own random init ('independent', as the original) or a copy of the online one."""
    float_obs_dtype: str = field(default="float16", metadata={"choices": ("float16", "float32")})
    """Replay storage of real-valued observations (binary grid observations are always bit-packed)."""
    timeouts_terminal: bool = False
    """Store an episode cut by the time limit as terminal, so its last transition does not bootstrap (the
    original code's episodic rule); off: only a task's own end is terminal."""
    completion_terminal: bool = False
    """Reset-free training too stores a completed task as a terminal transition, so it does not bootstrap
    past it, while the world goes on (the released factory script's end_on_task_completion)."""

    def __post_init__(self) -> None:
        check_number("lr", self.lr, 0.0, MAX_LR, low_open=True)
        check_number("adam_eps", self.adam_eps, 0.0, low_open=True)
        check_number("gamma", self.gamma, 0.0, 1.0)
        check_int("batch_size", self.batch_size)
        check_int("buffer_size", self.buffer_size, 2)
        if self.buffer_size < self.batch_size:  # a minibatch would repeat a few transitions (or find none whole)
            raise ValueError(f"buffer_size ({self.buffer_size}) must be at least the batch size ({self.batch_size}); "
                             f"give --buffer-size {self.batch_size} or more, or a smaller --batch-size")
        check_number("tau", self.tau, 0.0, 1.0, low_open=True)
        check_number("grad_clip", self.grad_clip, 0.0, low_open=True)
        check_number("eps_start", self.eps_start, 0.0, 1.0)
        check_number("eps_end", self.eps_end, 0.0, 1.0)
        check_int("eps_decay_steps", self.eps_decay_steps, 0)
        check_int("warmup_steps", self.warmup_steps, 2)  # a transition must exist before the first update
        check_int("epoch_steps", self.epoch_steps)
        check_int("updates_per_epoch", self.updates_per_epoch, 0)
        check_layers("view_layers", self.view_layers)
        check_layers("inventory_layers", self.inventory_layers)
        check_layers("head_layers", self.head_layers, allow_empty=True)
        check_int("inventory_repeat", self.inventory_repeat)
        check_choices(self)

    def epsilon(self, step: int) -> float:
        """The exploration epsilon after ``step`` environment steps (linear decay, then constant)."""
        frac = min(max(step, 0) / self.eps_decay_steps, 1.0) if self.eps_decay_steps > 0 else 1.0
        return self.eps_start + (self.eps_end - self.eps_start) * frac


@dataclass(frozen=True)
class RNDConfig:
    """Random network distillation: an intrinsic bonus added to the reward at sampling time."""

    rnd: bool = False
    """Add the RND exploration bonus."""
    rnd_weight: float = 1.0
    """Weight of the normalised RND bonus added to the environment reward."""
    rnd_lr: float = 3e-4
    """Adam learning rate of the RND predictor (one step per DQN update, on the sampled next observations)."""
    rnd_layers: tuple[int, ...] = (128, 128, 32)
    """Layer widths of the RND target and predictor MLPs (the last one is the embedding size)."""

    def __post_init__(self) -> None:
        check_number("rnd_weight", self.rnd_weight, 0.0)
        check_number("rnd_lr", self.rnd_lr, 0.0, MAX_LR, low_open=True)
        check_layers("rnd_layers", self.rnd_layers)


@dataclass(frozen=True)
class EvalConfig:
    """The evaluation protocol: fixed validation layouts of the test MDP, epsilon-greedy policy."""

    eval_every: int = 5_000
    """Evaluate every this many environment steps (a multiple of epoch_steps)."""
    eval_epsilon: float = 0.1
    """Epsilon of the evaluation policy."""
    eval_rollouts: int | None = None
    """Validation rollouts per seed (default: the task's 100 validation layouts; food collector: 10 episodes)."""
    eval_horizon: int | None = None
    """Length of each validation rollout (default: the task's test horizon)."""
    eval_dynamism: float = 0.0
    """Dynamism of the test MDP the validation rollouts play (0, static: the paper's protocol; the released
    hunting scripts validated with deer moving at 0.2, or 0.1 for Fig. 5)."""
    eval_env_kwargs: dict[str, Any] = field(default_factory=dict)
    """Task parameters of the test MDP that differ from the training environment's, e.g. deer_count=1 (CLI:
    KEY=VALUE, the value read as JSON)."""

    def __post_init__(self) -> None:
        check_int("eval_every", self.eval_every)
        check_number("eval_epsilon", self.eval_epsilon, 0.0, 1.0)
        check_number("eval_dynamism", self.eval_dynamism, 0.0, 1.0)
        for name, high in (("eval_rollouts", MAX_EVAL_ROLLOUTS), ("eval_horizon", MAX_EVAL_HORIZON)):
            if getattr(self, name) is not None:
                check_int(name, getattr(self, name), high=high)
        check_kwargs("eval_env_kwargs", self.eval_env_kwargs, EVAL_OWNED_ENV_KWARGS)


@dataclass(frozen=True)
class RunConfig:
    """Seeds and budget of the run, and settings that do not change its results."""

    seeds: int = 1
    """Number of seeds of this condition trained together in one process."""
    first_seed: int = 0
    """Seed of the first agent; the others are first_seed + 1, + 2, ..."""
    steps: int = field(default=1_000_000, metadata=RUNTIME)
    """Environment steps per seed (warm-up included; rounded up to whole epochs)."""
    checkpoint_every: int = field(default=50_000, metadata=RUNTIME)
    """Write a checkpoint every this many environment steps (and at the start and the end)."""
    threads: int = field(default=1, metadata=RUNTIME)
    """torch intra-op threads (1 is fastest when several runs or processes share the CPU)."""
    tensorboard: bool = field(default=False, metadata=RUNTIME)
    """Also log the metrics to TensorBoard (in RUN_DIR/tensorboard)."""
    progress: bool = field(default=True, metadata=RUNTIME)
    """Show a progress bar."""
    env_threads: int = field(default=1, metadata=RUNTIME)
    """Threads stepping the grid worlds (same results for any count; pays only with idle cores, e.g. a GPU host)."""
    device: str = field(default="cpu", metadata=RUNTIME)
    """Where the networks, the optimiser and the updates run: cpu, cuda or cuda:N (worlds stay on the CPU)."""
    cuda_graphs: bool = field(default=True, metadata=RUNTIME)
    """On a GPU, capture one gradient step as a CUDA graph and replay it for the others (the same numbers as
    eager kernels, with far less launch overhead); no effect on the CPU."""

    def __post_init__(self) -> None:
        check_int("seeds", self.seeds)
        check_int("first_seed", self.first_seed, 0)
        check_int("steps", self.steps)
        check_int("checkpoint_every", self.checkpoint_every)
        check_int("threads", self.threads, high=MAX_THREADS)
        check_int("env_threads", self.env_threads, high=MAX_THREADS)
        if not isinstance(self.device, str) or not re.fullmatch(r"cpu|cuda(:[0-9]+)?", self.device):
            raise ValueError(f"device must be cpu, cuda or cuda:N, got {self.device!r}")
        if self.first_seed + self.seeds > VALIDATION_SEED_BASE:
            raise ValueError(f"training seeds must stay below {VALIDATION_SEED_BASE} (the validation seeds)")

    @property
    def seed_list(self) -> list[int]:
        """The seeds trained in this run."""
        return list(range(self.first_seed, self.first_seed + self.seeds))


SECTIONS = {"env": EnvConfig, "dqn": DQNConfig, "rnd": RNDConfig, "eval": EvalConfig, "run": RunConfig}
"""The sections of `TrainConfig`, by attribute name."""


@dataclass(frozen=True)
class TrainConfig:
    """One training condition with all its seeds."""

    env: EnvConfig = field(default_factory=EnvConfig)
    dqn: DQNConfig = field(default_factory=DQNConfig)
    rnd: RNDConfig = field(default_factory=RNDConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    run: RunConfig = field(default_factory=RunConfig)

    def __post_init__(self) -> None:
        if self.eval.eval_every % self.dqn.epoch_steps:
            epoch = self.dqn.epoch_steps
            nearest = max(round(self.eval.eval_every / epoch), 1) * epoch
            raise ValueError(f"eval_every ({self.eval.eval_every}) must be a multiple of epoch_steps ({epoch}), "
                             f"evaluations falling at epoch ends; give --eval-every {nearest} or change "
                             f"--epoch-steps")

    def check_trains(self) -> None:
        """Raise ValueError if the run would train nothing (its warm-up takes every step)."""
        if self.dqn.warmup_steps >= self.run.steps:
            raise ValueError(f"warmup_steps ({self.dqn.warmup_steps}) must be below steps ({self.run.steps}), or "
                             f"nothing is trained; give --steps above {self.dqn.warmup_steps} or a smaller "
                             f"--warmup-steps")

    @property
    def num_epochs(self) -> int:
        """Epochs after the warm-up (the step budget rounded up to whole epochs)."""
        after = max(self.run.steps - self.dqn.warmup_steps, 0)
        return -(-after // self.dqn.epoch_steps)

    @property
    def total_steps(self) -> int:
        """Environment steps per seed the run will take."""
        return self.dqn.warmup_steps + self.num_epochs * self.dqn.epoch_steps

    @property
    def eval_epochs(self) -> int:
        """Epochs between evaluations."""
        return self.eval.eval_every // self.dqn.epoch_steps

    def to_dict(self) -> dict[str, Any]:
        """A JSON-friendly nested dict (tuples become lists)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainConfig:
        """Rebuild a config from `to_dict` output (unknown keys, wrong types and bad values raise ValueError)."""
        if not isinstance(data, dict) or not all(isinstance(data.get(n, {}), dict) for n in SECTIONS):
            raise ValueError("a configuration must be an object of sections (env, dqn, rnd, eval, run)")
        parts = {}
        for name, section in SECTIONS.items():
            values = dict(data.get(name, {}))
            known = {f.name: f for f in dataclasses.fields(section)}
            unknown = set(values) - set(known)
            if unknown:
                raise ValueError(f"unknown {name} setting(s) {sorted(unknown)}")
            for key, value in values.items():
                if isinstance(value, list):
                    values[key] = tuple(value)
            try:
                parts[name] = section(**values)
            except TypeError as err:  # e.g. a number where a schedule string belongs
                raise ValueError(f"bad {name} setting: {err}") from None
        return cls(**parts)

    def replace(self, **flat: Any) -> TrainConfig:
        """A copy with fields changed by their (unique, section-less) names, e.g. ``replace(lr=3e-4)``."""
        owners = field_owners()
        grouped: dict[str, dict[str, Any]] = {}
        for key, value in flat.items():
            if key not in owners:
                raise KeyError(f"no config field named {key!r}")
            grouped.setdefault(owners[key], {})[key] = value
        changes = {name: dataclasses.replace(getattr(self, name), **vals) for name, vals in grouped.items()}
        return dataclasses.replace(self, **changes)

    def identity(self) -> dict[str, Any]:
        """The settings that define the run's results (everything but the RUNTIME fields)."""
        out = {}
        for name, section in SECTIONS.items():
            for f in dataclasses.fields(section):
                if not f.metadata.get("runtime"):
                    out[f.name] = _jsonable(getattr(getattr(self, name), f.name))
        return out


def _jsonable(value: Any) -> Any:
    """Tuples as lists, so values compare equal to their JSON round trip."""
    if isinstance(value, tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    return value


@functools.cache
def field_owners() -> dict[str, str]:
    """Map each field name to its section; names are unique across sections (checked here)."""
    owners: dict[str, str] = {}
    for name, section in SECTIONS.items():
        for f in dataclasses.fields(section):
            if f.name in owners:
                raise RuntimeError(f"config field {f.name!r} appears in two sections")
            owners[f.name] = name
    return owners


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """The attribute docstrings of a dataclass, read from its source: {field name: docstring}."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    body = tree.body[0].body
    docs = {}
    for node, nxt in zip(body, body[1:]):
        if (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
                and isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)):
            docs[node.target.id] = " ".join(nxt.value.value.split())
    return docs
