"""The training loop: the seeds of one condition, or of several conditions of one task packed together.

A trainer drives one `Learner` (`train.agent.learner`) over K agent rows. Each condition (a `Part`) owns a
contiguous block of rows, its own vector environment (world k of it reset once with seed k), its run
directory, metrics and visitation counts; the learner owns everything about learning. Packing several
conditions of a task into one trainer (`Trainer.packed`) batches their gradient steps into one call, while
every condition keeps the run directory, and the numbers up to float rounding, that it gets alone.

The schedule is the learner's (for double DQN: ``warmup_steps`` steps, then epochs of ``epoch_steps`` steps
each followed by its updates); evaluation every ``eval_every`` steps. Episodic worlds restart through
Gymnasium's next-step autoreset: the step after an episode's end only resets the world (its action is
ignored, nothing is stored), and it counts toward the step budget like any other.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from train.agent.learner import STREAMS, DQNLearner, Learner, RowSettings, seed_streams
from train.agent.network import QNetwork
from train.config import TrainConfig
from train.evaluation.protocol import Evaluator, run_evaluation_kwargs
from train.loop.memory import check_memory
from train.loop.packing import check_device, check_packable
from train.loop.parts import Part
from train.loop.runlog import RunLogger, postfix, progress_bar, stop_on_signal
from train.storage.rundir import ADDED_COLUMNS, RunDir, RunDirError
from train.storage.statecheck import check_state, steps_left
from train.tasks import (
    EnvInfo,
    Task,
    check_test_mdp,
    completions,
    env_state,
    get_task,
    make_vector_env,
    probe,
    restore_env_state,
    step_worlds,
)

__all__ = ["CHECKPOINT_VERSION", "STREAMS", "Part", "Trainer", "resolve", "seed_streams"]

CHECKPOINT_VERSION = 2
"""Version of a run's checkpoint state (the layout inside the checkpoint file, `train.storage.checkpoint`)."""


def resolve(cfg: TrainConfig, task: Task, info: EnvInfo) -> TrainConfig:
    """Fill the task-dependent defaults (validation rollouts, test horizon) into ``cfg``."""
    return cfg.replace(eval_rollouts=cfg.eval.eval_rollouts or task.eval_rollouts,
                       eval_horizon=cfg.eval.eval_horizon or int(info.test_kwargs["horizon"]))


class Trainer:
    """Trains every seed of one condition (or, built by `packed`, of several) together."""

    def __init__(self, cfg: TrainConfig, run_dir: str | Path | RunDir | None = None, resume: bool = False) -> None:
        self._build([cfg], [run_dir], [resume])

    @classmethod
    def packed(cls, cfgs: Sequence[TrainConfig], run_dirs: Sequence[str | Path | RunDir | None],
               resume: Sequence[bool]) -> Trainer:
        """One trainer for several conditions of one task (`train.loop.packing.check_packable` says which pack)."""
        trainer = cls.__new__(cls)
        trainer._build(list(cfgs), list(run_dirs), list(resume))
        return trainer

    def _build(self, cfgs: list[TrainConfig], run_dirs: list, resume: list[bool]) -> None:
        self.task = get_task(cfgs[0].env.task)
        self.info = probe(self.task, cfgs[0].env)
        cfgs = [resolve(c, self.task, self.info) for c in cfgs]
        check_packable(cfgs)
        ev = cfgs[0].eval  # a pack's conditions share it (check_packable)
        check_test_mdp(self.task, self.info, run_evaluation_kwargs(self.info.test_kwargs, ev), ev.eval_env_kwargs)
        run = cfgs[0].run
        check_device(run.device)
        if run.device.startswith("cuda"):  # full float32 products, so a GPU run matches the CPU's to rounding
            torch.backends.cuda.matmul.allow_tf32 = False
            torch.backends.cudnn.allow_tf32 = False
        torch.set_num_threads(run.threads)
        # Adam's second moments of inputs never active decay through the denormal range (CPU arithmetic ~100x slower
        # there); flushing changes only values below ~1e-38. numpy < 2.3 warns if it first reads limits after it.
        for dtype in (np.float16, np.float32, np.float64):
            np.finfo(dtype)
        torch.set_flush_denormal(True)
        settings = [RowSettings(s, c.dqn, c.rnd) for c in cfgs for s in c.run.seed_list]
        net = QNetwork.from_config(self.info.view_dim, self.info.obs_dim, self.info.num_actions, cfgs[0].dqn)
        check_memory(cfgs, self.info.obs_dim, math.prod(self.info.visit_shape), net.num_params, self.task.binary_obs)
        self.learner: Learner = DQNLearner(settings, net, self.task.binary_obs, run.device, run.cuda_graphs)
        self.parts: list[Part] = []
        start = 0
        for cfg, run_dir in zip(cfgs, run_dirs):
            rows = slice(start, start + cfg.run.seeds)
            start = rows.stop
            env = make_vector_env(self.task.env_id, cfg.run.seeds, cfg.env.env_make_kwargs, run.env_threads)
            run_dir = RunDir(run_dir) if isinstance(run_dir, (str, Path)) else run_dir
            self.parts.append(Part(cfg, rows, env, run_dir, np.zeros((cfg.run.seeds, *self.info.visit_shape),
                                                                     dtype=np.int64)))
        self.seeds = [s for p in self.parts for s in p.seeds]
        self._evaluator: Evaluator | None = None
        self._fresh_state()
        self._open_run_dirs(resume)

    # ---- the parts and their run directories ----------------------------------------------------------

    @property
    def cfg(self) -> TrainConfig:
        """The (first) condition's resolved configuration; the schedule is the same for every part."""
        return self.parts[0].cfg

    @property
    def num_agents(self) -> int:
        """K, the number of seeds (agent rows) trained together."""
        return len(self.seeds)

    @property
    def rows(self) -> list[dict[str, Any]]:
        """The metrics rows of the (first) condition."""
        return self.parts[0].metric_rows

    @property
    def visits(self) -> np.ndarray:
        """The visitation counts of the (first) condition."""
        return self.parts[0].visits

    @property
    def resumed_from(self) -> int:
        """The step a resumed run continued from (-1: a fresh run)."""
        return self.parts[0].resumed_from

    @property
    def agent(self):
        """The double-DQN networks (`train.agent.dqn.DoubleDQN`)."""
        return self.learner.agent

    @property
    def replay(self):
        """The replay buffer of every row."""
        return self.learner.replay

    def _open_run_dirs(self, resume: list[bool]) -> None:
        """Lock each part's run directory; on resume restore its checkpoint and rewrite config.json (and a
        deleted metrics.csv). Resumed parts must all stand at the same step as the fresh ones (step 0).
        """
        opened: list[Part] = []
        try:
            for part, again in zip(self.parts, resume):
                if part.run_dir is None:
                    continue
                part.run_dir.prepare(part.cfg, again)
                opened.append(part)
                if again:
                    self._resume_part(part)
            stands = {p.resumed_from if p.resumed_from >= 0 else 0 for p in self.parts}
            if len(stands) > 1:
                raise RunDirError(f"the packed runs stand at different steps ({sorted(stands)}); run them "
                                  f"separately (without --pack)")
        except BaseException:
            for part in opened:
                part.run_dir.unlock()
            self._close_envs()
            raise

    def _resume_part(self, part: Part) -> None:
        """Restore one part from its run directory's checkpoint."""
        self._load_part(part, part.run_dir.load_checkpoint(part.cfg))
        if self.step > part.cfg.total_steps:
            raise RunDirError(f"the run in {part.run_dir.path} stands at step {self.step}, beyond the "
                              f"{part.cfg.total_steps} steps asked for; ask for at least {self.step} steps")
        part.resumed_from = self.step
        part.run_dir.write_config(part.cfg)
        part.run_dir.restore_metrics(part.metric_rows)

    def _fresh_state(self) -> None:
        """Counters and accumulators of a run that has not started."""
        k = self.num_agents
        self.step = 0
        self.epoch = 0
        self.obs: np.ndarray | None = None
        self.autoreset = np.zeros(k, dtype=bool)
        self.train_reward = np.zeros(k)
        self.last_checkpoint = -1
        self._interval = [0, 0.0]  # steps and seconds of training since the last evaluation

    # ---- the two phases -------------------------------------------------------------------------------

    def start(self) -> None:
        """Reset each seed's world with its own seed (the only seeded reset of the run)."""
        self.obs = np.concatenate([p.env.reset(seed=p.seeds)[0] for p in self.parts]).astype(np.float32)

    def collect(self, n: int) -> None:
        """Take ``n`` of the learner's actions in every world and let it observe the transitions."""
        if self.obs is None:
            self.start()
        self.learner.begin_collect(n)
        for _ in range(n):
            self._env_step(self.learner.act(self.obs, self.step))

    def _env_step(self, actions: np.ndarray) -> None:
        """Step every world once with ``actions`` and record what happened."""
        stored = ~self.autoreset  # worlds whose previous step ended only reset now
        results = [step_worlds(p.env, actions[p.rows]) for p in self.parts]
        if len(results) == 1:
            obs, reward, terminated, truncated = results[0][:4]
        else:
            obs, reward, terminated, truncated = (np.concatenate([r[i] for r in results]) for i in range(4))
        self.learner.observe(stored, self.obs, actions, reward, terminated, truncated, obs, self._completed())
        self.autoreset = (terminated | truncated) & stored
        for part, result in zip(self.parts, results):
            rows, cols = self.info.visit_grid.cells(result[4])
            part.visits[np.arange(part.cfg.run.seeds), rows, cols] += 1
        self.train_reward += reward
        self.obs = obs.astype(np.float32, copy=False)
        self.step += 1

    def _completed(self) -> np.ndarray | None:
        """The worlds that completed their task on the last step, where the configuration stores completions as
        terminal (`DQNConfig.completion_terminal`); else None.
        """
        if not self.cfg.dqn.completion_terminal:
            return None
        done = [completions(p.env) for p in self.parts]
        return None if any(d is None for d in done) else np.concatenate(done)

    def learn(self) -> None:
        """The learner's update phase."""
        self.learner.learn()

    def train_epoch(self) -> None:
        """Collect what the learner's schedule asks for, then let it learn."""
        began = time.perf_counter()
        start_step = self.step
        self.collect(self.learner.steps_to_collect(self.step))
        self.learn()
        self.epoch += 1
        self._interval[0] += self.step - start_step
        self._interval[1] += time.perf_counter() - began

    # ---- evaluation and logging -----------------------------------------------------------------------

    @property
    def evaluator(self) -> Evaluator:
        """The evaluation protocol's batched environment over every row (built on first use)."""
        if self._evaluator is None:
            ev = self.cfg.eval
            self._evaluator = Evaluator(self.task.env_id, run_evaluation_kwargs(self.info.test_kwargs, ev),
                                        self.num_agents, ev.eval_rollouts, ev.eval_epsilon, self.info.num_actions,
                                        threads=self.cfg.run.env_threads)
        return self._evaluator

    def evaluate(self) -> list[list[dict[str, Any]]]:
        """Run the evaluation protocol; append one metrics row per seed to each part; return each part's rows."""
        result = self.evaluator(self.learner, self.seeds, self.step)
        steps, seconds = self._interval
        rate = steps / seconds if seconds > 0 else math.nan
        losses = self.learner.take_losses()
        out = []
        top_action, top_share = result.top_action, result.top_action_share
        for part in self.parts:
            corners = part.recent_corner_share(self.info.visit_grid.wall)
            rows = [{"step": self.step, "seed": seed, "epsilon": part.cfg.dqn.epsilon(self.step),
                     "loss": float(losses[k]), "max_q": float(result.max_q[k]),
                     "top_action": int(top_action[k]), "top_action_share": float(top_share[k]),
                     "corner_share": float(corners[i]),
                     "success": float(result.success[k]) if self.task.metric == "success" else math.nan,
                     "made": float(result.made[k]),
                     "return": float(result.returns[k]), "train_reward": float(self.train_reward[k]),
                     "steps_per_s": rate}
                    for i, (k, seed) in enumerate(zip(range(part.rows.start, part.rows.stop), part.seeds))]
            part.metric_rows += rows
            out.append(rows)
        self.train_reward[:] = 0.0
        self._interval = [0, 0.0]
        return out

    # ---- the whole run --------------------------------------------------------------------------------

    def run(self) -> list[dict[str, Any]]:
        """Train to the step budget (from wherever the run stands), evaluating and checkpointing on schedule.

        SIGINT/SIGTERM stop the run cleanly at the end of the current epoch, with a checkpoint.
        Returns the (first) condition's metrics rows; every part's are in ``parts[i].metric_rows``.
        """
        # The stop is read once per epoch, where the checkpoint is decided: a signal that lands after that
        # read (in the progress update, say) trains one more epoch and then saves, never stopping unsaved.
        cfg = self.cfg
        if self.obs is None:
            self.start()
        if self.last_checkpoint < 0:
            self.save()
        loggers = [RunLogger(p.run_dir, p.cfg, p.resumed_from if p.resumed_from >= 0 else None)
                   if p.run_dir is not None else None for p in self.parts]
        with stop_on_signal(announce=cfg.run.progress) as stop, progress_bar(cfg, self.step, len(self.parts)) as bar:
            stopping = False
            while self.epoch < cfg.num_epochs and not stopping:
                before = self.step
                self.train_epoch()
                done = self.epoch == cfg.num_epochs
                if self.epoch % cfg.eval_epochs == 0 or done:
                    latest = self.evaluate()
                    for part, logger in zip(self.parts, loggers):
                        if logger is not None:
                            logger.log(part.metric_rows, part.visits, self.step)
                    bar.set_postfix(postfix([r for rows in latest for r in rows], self.num_agents), refresh=False)
                stopping = stop.is_set()
                if done or stopping or self.step - self.last_checkpoint >= cfg.run.checkpoint_every:
                    self.save()
                bar.update(self.step - before)
        for logger in loggers:
            if logger is not None:
                logger.close()
        return self.rows

    def save(self) -> None:
        """Write each part's checkpoint (where it keeps a run directory), then continue from what they hold.

        Continuing from the saved environment state, exactly as a resumed run does, keeps a run that is
        interrupted and resumed identical to one that is not (see `train.tasks.restore_env_state`).
        """
        self.last_checkpoint = self.step
        for index, part in enumerate(self.parts):
            state = self.state_dict(index)
            if part.run_dir is not None:
                part.run_dir.save_checkpoint(state)
            if state["env"] is not None:
                restore_env_state(part.env, state["env"], steps_left(self.step))

    def state_dict(self, part: int = 0) -> dict[str, Any]:
        """Everything needed to continue one part's run exactly, as data: JSON values, arrays and tensors.

        A packed part's state is the state of the same run trained alone, so either can resume it.
        """
        p = self.parts[part]
        return {
            "version": CHECKPOINT_VERSION, "config": p.cfg.to_dict(), "step": self.step, "epoch": self.epoch,
            "obs": None if self.obs is None else self.obs[p.rows].copy(),
            "autoreset": self.autoreset[p.rows].copy(),
            "env": env_state(p.env) if self.obs is not None else None,
            **self.learner.state_dict(p.rows),
            "torch_rng": torch.get_rng_state(), "visits": p.visits.copy(),
            "visits_at_eval": (p.visits_at_eval if p.visits_at_eval is not None else np.zeros_like(p.visits)).copy(),
            "train_reward": self.train_reward[p.rows].copy(), "rows": list(p.metric_rows),
            "last_checkpoint": self.last_checkpoint,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a `state_dict` of a single-condition trainer (same resolved configuration)."""
        self._load_part(self.parts[0], state)

    def _load_part(self, part: Part, state: dict[str, Any]) -> None:
        """Restore one part from its state; refuse a wrong version or arrays of the wrong shape."""
        if state.get("version") != CHECKPOINT_VERSION:
            raise RunDirError(f"checkpoint layout version {state.get('version')} is not {CHECKPOINT_VERSION}; "
                              f"re-run the training with this ecorl in a new --out directory")
        try:
            check_state(state, self, self.parts.index(part))  # every value, before any reaches torch or the engine
            self._load_arrays(part, state)
        except (KeyError, TypeError, ValueError, RuntimeError) as err:
            raise RunDirError(f"the checkpoint does not fit this run ({type(err).__name__}: {err}); start a "
                              f"fresh run in another --out directory") from None

    def _load_arrays(self, part: Part, state: dict[str, Any]) -> None:
        """The body of `_load_part`, on a state `check_state` has accepted (shapes, dtypes, ranges)."""
        self.learner.load_state_dict(state, part.rows)
        if state["env"] is not None:
            part.env.reset(seed=part.seeds)  # a seeded reset, then every world is overwritten with its saved state
            restore_env_state(part.env, state["env"], steps_left(int(state["step"])))
        torch.set_rng_state(state["torch_rng"])
        self.step, self.epoch = int(state["step"]), int(state["epoch"])
        if state["obs"] is not None:
            if self.obs is None:
                self.obs = np.zeros((self.num_agents, self.info.obs_dim), dtype=np.float32)
            self.obs[part.rows] = state["obs"]
        self.autoreset[part.rows] = np.asarray(state["autoreset"], dtype=bool)
        part.visits[...] = state["visits"]
        # checkpoints written before the corner share existed lack it: the next interval then starts here
        part.visits_at_eval = np.array(state.get("visits_at_eval", state["visits"]), dtype=np.int64)
        self.train_reward[part.rows] = state["train_reward"]
        part.metric_rows[:] = [{**dict.fromkeys(ADDED_COLUMNS, math.nan), **row} for row in state["rows"]]
        self.last_checkpoint = int(state["last_checkpoint"])

    def _close_envs(self) -> None:
        for part in self.parts:
            part.env.close()
        if self._evaluator is not None:
            self._evaluator.close()

    def close(self) -> None:
        """Release the environments and the run directories' locks."""
        self._close_envs()
        for part in self.parts:
            if part.run_dir is not None:
                part.run_dir.unlock()
