"""The training loop: K seeds of one condition, one vector environment, one replay buffer, one process.

Seed k owns world k of the vector environment (reset once with seed k), row k of every network buffer and
four random streams of its own (network init, exploration, replay sampling, RND init), so its run does not
depend on which other seeds train beside it. The schedule is the original code's: ``warmup_steps`` steps,
then epochs of ``epoch_steps`` environment steps followed by ``updates_per_epoch`` gradient steps;
evaluation every ``eval_every`` steps. Episodic worlds restart through Gymnasium's next-step autoreset:
the step after an episode's end only resets the world (its action is ignored, nothing is stored), and it
counts toward the step budget like any other.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from train.agent.dqn import DoubleDQN
from train.agent.network import QNetwork
from train.agent.replay import Replay
from train.agent.rnd import RND
from train.config import TrainConfig
from train.evaluate import Evaluator, evaluation_kwargs
from train.memory import check_memory
from train.rundir import RunDir, RunDirError
from train.runlog import RunLogger, postfix, progress_bar, stop_on_signal
from train.statecheck import check_state
from train.tasks import EnvInfo, Task, env_state, get_task, make_vector_env, probe, restore_env_state

STREAMS = ("init", "explore", "sample", "rnd")
"""The random streams of each seed, spawned from its SeedSequence in this order."""
CHECKPOINT_VERSION = 2
"""Version of `Trainer.state_dict` (the layout inside the checkpoint file, `train.checkpoint`)."""


def resolve(cfg: TrainConfig, task: Task, info: EnvInfo) -> TrainConfig:
    """Fill the task-dependent defaults (validation rollouts, test horizon) into ``cfg``."""
    return cfg.replace(eval_rollouts=cfg.eval.eval_rollouts or task.eval_rollouts,
                       eval_horizon=cfg.eval.eval_horizon or int(info.test_kwargs["horizon"]))


def seed_streams(seed: int) -> dict[str, np.random.Generator]:
    """The independent random generators of one seed."""
    return {name: np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))
            for i, name in enumerate(STREAMS)}


class Trainer:
    """Trains every seed of one condition together; optionally keeps a run directory."""

    def __init__(self, cfg: TrainConfig, run_dir: str | Path | RunDir | None = None, resume: bool = False) -> None:
        self.task = get_task(cfg.env.task)
        self.info = probe(self.task, cfg.env)
        self.cfg = cfg = resolve(cfg, self.task, self.info)
        torch.set_num_threads(cfg.run.threads)
        # Adam's second moments of inputs that are never active decay through the denormal range, where
        # CPU arithmetic is ~100x slower; flushing only changes values below ~1e-38 (to zero).
        torch.set_flush_denormal(True)
        net = QNetwork(self.info.view_dim, self.info.obs_dim - self.info.view_dim, self.info.num_actions,
                       cfg.dqn.view_layers, cfg.dqn.inventory_layers, cfg.dqn.head_layers)
        check_memory(cfg, self.info.obs_dim, math.prod(self.info.visit_shape), net.num_params, self.task.binary_obs)
        self.seeds = cfg.run.seed_list
        streams = [seed_streams(s) for s in self.seeds]
        self.rngs = {name: [s[name] for s in streams] for name in STREAMS}
        self.agent = DoubleDQN(net, cfg.dqn, self.rngs["init"])
        self.rnd = RND(self.info.obs_dim, cfg.rnd, self.rngs["rnd"]) if cfg.rnd.rnd else None
        self.replay = Replay(self.num_agents, cfg.dqn.buffer_size, self.info.obs_dim, self.task.binary_obs,
                             cfg.dqn.float_obs_dtype)
        self.env = make_vector_env(self.task.env_id, self.num_agents, cfg.env.env_make_kwargs)
        self._evaluator: Evaluator | None = None
        self.run_dir = RunDir(run_dir) if isinstance(run_dir, (str, Path)) else run_dir
        self._fresh_state()
        self.resumed_from = -1
        """The step a resumed run continued from (-1: a fresh run)."""
        if self.run_dir is not None:
            self._open_run_dir(resume)

    def _open_run_dir(self, resume: bool) -> None:
        """Lock the run directory; on resume restore the checkpoint and rewrite config.json (and a deleted
        metrics.csv).
        """
        try:
            self.run_dir.prepare(self.cfg, resume)
            if resume:
                self.load_state_dict(self.run_dir.load_checkpoint(self.cfg))
                if self.step > self.cfg.total_steps:
                    raise RunDirError(f"the run in {self.run_dir.path} stands at step {self.step}, beyond the "
                                      f"{self.cfg.total_steps} steps asked for; ask for at least {self.step} steps")
                self.resumed_from = self.step
                self.run_dir.write_config(self.cfg)
                self.run_dir.restore_metrics(self.rows)
        except BaseException:
            self.run_dir.unlock()
            self.env.close()
            raise

    @property
    def num_agents(self) -> int:
        """K, the number of seeds trained together."""
        return len(self.seeds)

    def _fresh_state(self) -> None:
        """Counters and accumulators of a run that has not started."""
        k = self.num_agents
        self.step = 0
        self.epoch = 0
        self.obs: np.ndarray | None = None
        self.autoreset = np.zeros(k, dtype=bool)
        self.visits = np.zeros((k, *self.info.visit_shape), dtype=np.int64)
        self.loss_sum = torch.zeros(k)
        self.loss_count = 0
        self.train_reward = np.zeros(k)
        self.rows: list[dict[str, Any]] = []
        self.last_checkpoint = -1
        self._interval = [0, 0.0]  # steps and seconds of training since the last evaluation
        self._agent_index = np.arange(k)

    # ---- the two phases -------------------------------------------------------------------------------

    def start(self) -> None:
        """Reset each seed's world with its own seed (the only seeded reset of the run)."""
        self.obs, _ = self.env.reset(seed=list(self.seeds))

    def collect(self, n: int) -> None:
        """Take ``n`` epsilon-greedy environment steps in every world and store the transitions."""
        if self.obs is None:
            self.start()
        draws = np.stack([rng.random((n, 2)) for rng in self.rngs["explore"]], axis=1)  # (n, K, 2)
        random_actions = (draws[..., 1] * self.info.num_actions).astype(np.int64)
        for i in range(n):
            explore = draws[i, :, 0] < self.cfg.dqn.epsilon(self.step)
            actions = random_actions[i]
            if not explore.all():
                with torch.no_grad():
                    greedy = self.agent.greedy(torch.from_numpy(self.obs).unsqueeze(1))[:, 0]
                actions = np.where(explore, actions, greedy)
            self._env_step(actions)

    def _env_step(self, actions: np.ndarray) -> None:
        """Step every world once with ``actions`` and record what happened."""
        stored = ~self.autoreset  # worlds whose previous step ended only reset now
        encoded = self.replay.encode(self.obs)
        obs, reward, terminated, truncated, info = self.env.step(actions)
        self.replay.add(stored, encoded, actions, reward, terminated)
        ended = (terminated | truncated) & stored
        if ended.any():  # the final observation gets its own slot: it is the last transition's next state
            self.replay.add(ended, self.replay.encode(obs))
        self.autoreset = ended
        rows, cols = self.info.visit_grid.cells(info["agent_pos"])
        self.visits[self._agent_index, rows, cols] += 1
        self.train_reward += reward
        self.obs = obs
        self.step += 1

    def learn(self, n: int) -> None:
        """Take ``n`` gradient steps for every seed, each on its own minibatch."""
        slots = self.replay.sample_indices(self.rngs["sample"], n, self.cfg.dqn.batch_size)
        with torch.no_grad():
            for i in range(n):
                batch = self.replay.batch(slots[:, i])
                rewards = batch.rewards
                if self.rnd is not None:
                    rewards = rewards + self.rnd.bonus(batch.next_obs)
                self.loss_sum += self.agent.update(batch.obs_pairs, batch.actions, rewards, batch.terminated)
                self.loss_count += 1

    def train_epoch(self) -> None:
        """Collect one epoch of steps (after the warm-up, if not done yet), then learn from the buffer."""
        began = time.perf_counter()
        start_step = self.step
        if self.step < self.cfg.dqn.warmup_steps:
            self.collect(self.cfg.dqn.warmup_steps - self.step)
        self.collect(self.cfg.dqn.epoch_steps)
        self.learn(self.cfg.dqn.updates_per_epoch)
        self.epoch += 1
        self._interval[0] += self.step - start_step
        self._interval[1] += time.perf_counter() - began

    # ---- evaluation and logging -----------------------------------------------------------------------

    @property
    def evaluator(self) -> Evaluator:
        """The evaluation protocol's batched environment (built on first use)."""
        if self._evaluator is None:
            test_kwargs = evaluation_kwargs(self.info.test_kwargs, self.cfg.eval.eval_horizon)
            self._evaluator = Evaluator(self.task.env_id, test_kwargs, self.num_agents,
                                        self.cfg.eval.eval_rollouts, self.cfg.eval.eval_epsilon,
                                        self.info.num_actions)
        return self._evaluator

    def evaluate(self) -> list[dict[str, Any]]:
        """Run the evaluation protocol, append one metrics row per seed, and return those rows."""
        result = self.evaluator(self.agent, self.seeds, self.step)
        steps, seconds = self._interval
        rate = steps / seconds if seconds > 0 else math.nan
        losses = (self.loss_sum / max(self.loss_count, 1)).tolist()
        rows = []
        for k, seed in enumerate(self.seeds):
            rows.append({
                "step": self.step, "seed": seed, "epsilon": self.cfg.dqn.epsilon(self.step),
                "loss": losses[k] if self.loss_count else math.nan,
                "success": float(result.success[k]) if self.task.metric == "success" else math.nan,
                "return": float(result.returns[k]), "train_reward": float(self.train_reward[k]),
                "steps_per_s": rate,
            })
        self.rows += rows
        self.loss_sum.zero_()
        self.loss_count = 0
        self.train_reward[:] = 0.0
        self._interval = [0, 0.0]
        return rows

    # ---- the whole run --------------------------------------------------------------------------------

    def run(self) -> list[dict[str, Any]]:
        """Train to the step budget (from wherever the run stands), evaluating and checkpointing on schedule.

        SIGINT/SIGTERM stop the run cleanly at the end of the current epoch, with a checkpoint.
        Returns all metrics rows.
        """
        cfg = self.cfg
        if self.obs is None:
            self.start()
        if self.last_checkpoint < 0:
            self.save()
        resumed = self.resumed_from >= 0
        logger = RunLogger(self.run_dir, cfg, self.step if resumed else None) if self.run_dir is not None else None
        with stop_on_signal() as stop, progress_bar(cfg, self.step) as bar:
            while self.epoch < cfg.num_epochs and not stop.is_set():
                before = self.step
                self.train_epoch()
                done = self.epoch == cfg.num_epochs
                if self.epoch % cfg.eval_epochs == 0 or done:
                    rows = self.evaluate()
                    if logger is not None:
                        logger.log(self, rows)
                    bar.set_postfix(postfix(rows, self.num_agents, cfg), refresh=False)
                if done or stop.is_set() or self.step - self.last_checkpoint >= cfg.run.checkpoint_every:
                    self.save()
                bar.update(self.step - before)
        if logger is not None:
            logger.close()
        return self.rows

    def save(self) -> None:
        """Write a checkpoint (if this trainer keeps a run directory), then continue from what it holds.

        Continuing from the saved environment state, exactly as a resumed run does, keeps a run that is
        interrupted and resumed identical to one that is not (see `train.tasks.restore_env_state`).
        """
        self.last_checkpoint = self.step
        state = self.state_dict()
        if self.run_dir is not None:
            self.run_dir.save_checkpoint(state)
        if state["env"] is not None:
            restore_env_state(self.env, state["env"])

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to continue the run exactly, as data: JSON values, arrays and tensors."""
        return {
            "version": CHECKPOINT_VERSION, "config": self.cfg.to_dict(), "step": self.step,
            "epoch": self.epoch, "obs": self.obs, "autoreset": self.autoreset.copy(),
            "env": env_state(self.env) if self.obs is not None else None,
            "agent": self.agent.state_dict(), "rnd": self.rnd.state_dict() if self.rnd else None,
            "replay": self.replay.state_dict(),
            "rngs": {name: [g.bit_generator.state for g in gens] for name, gens in self.rngs.items()},
            "torch_rng": torch.get_rng_state(),
            "visits": self.visits.copy(), "loss_sum": self.loss_sum.clone(), "loss_count": self.loss_count,
            "train_reward": self.train_reward.copy(), "rows": list(self.rows),
            "last_checkpoint": self.last_checkpoint,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a `state_dict` (same resolved configuration); refuse arrays of the wrong shape."""
        if state.get("version") != CHECKPOINT_VERSION:
            raise RunDirError(f"checkpoint layout version {state.get('version')} is not {CHECKPOINT_VERSION}; "
                              f"re-run the training with this ecorl in a new --out directory")
        try:
            check_state(state, self)  # every value, before any reaches torch, a generator or the engine
            self._load_arrays(state)
        except (KeyError, TypeError, ValueError, RuntimeError) as err:
            raise RunDirError(f"the checkpoint does not fit this run ({type(err).__name__}: {err}); start a "
                              f"fresh run in another --out directory") from None

    def _load_arrays(self, state: dict[str, Any]) -> None:
        """The body of `load_state_dict`."""
        _check_shapes(state["agent"], self.agent.state_dict(), "agent")
        if self.rnd is not None:
            _check_shapes(state["rnd"], self.rnd.state_dict(), "rnd")
        if state["env"] is not None:
            self.start()  # a seeded reset, then every world is overwritten with its saved state
            restore_env_state(self.env, state["env"])
        self.agent.load_state_dict(state["agent"])
        if self.rnd is not None:
            self.rnd.load_state_dict(state["rnd"])
        self.replay.load_state_dict(state["replay"])
        for name, gens in self.rngs.items():
            for g, saved in zip(gens, state["rngs"][name], strict=True):
                g.bit_generator.state = saved
        torch.set_rng_state(state["torch_rng"])
        k = self.num_agents
        for name, shape in (("visits", self.visits.shape), ("train_reward", (k,)), ("autoreset", (k,)),
                            ("obs", None if state["obs"] is None else (k, self.info.obs_dim))):
            if shape is not None and np.shape(state[name]) != shape:
                raise ValueError(f"{name} has shape {np.shape(state[name])}, this run needs {shape}")
        self.step, self.epoch = int(state["step"]), int(state["epoch"])
        self.obs = None if state["obs"] is None else np.asarray(state["obs"], dtype=np.float32)
        self.autoreset = np.asarray(state["autoreset"], dtype=bool).copy()
        self.visits[...] = state["visits"]
        self.loss_sum.copy_(state["loss_sum"])
        self.loss_count = int(state["loss_count"])
        self.train_reward[:] = state["train_reward"]
        self.rows = list(state["rows"])
        self.last_checkpoint = int(state["last_checkpoint"])

    def close(self) -> None:
        """Release the environments and the run directory's lock."""
        self.env.close()
        if self.run_dir is not None:
            self.run_dir.unlock()
        if self._evaluator is not None:
            self._evaluator.close()


def _check_shapes(saved: Any, live: Any, where: str) -> None:
    """Raise ValueError where a saved tensor's shape differs from the live one (copy_ would broadcast)."""
    if isinstance(live, dict):
        for key, value in live.items():
            _check_shapes(saved[key], value, f"{where}/{key}")
    elif isinstance(live, torch.Tensor) and (not isinstance(saved, torch.Tensor) or saved.shape != live.shape):
        shape = tuple(saved.shape) if isinstance(saved, torch.Tensor) else type(saved).__name__
        raise ValueError(f"{where} has shape {shape}, this run needs {tuple(live.shape)}")
