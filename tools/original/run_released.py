r"""Train one seed of one sweep point of a released ecologicalrl script, with the released code's own trainer.

The script (e.g. ``experiments/continual/dynamic_static/deer/tool_dqn.py``) is executed as its authors ran it,
as ``__main__``, except that its calls to ``run_experiment`` (which launched EC2 jobs) are collected instead of
launched. The sweep point chosen with ``--set`` is then run in this process the way rlkit's local launcher runs
it (logger set up in ``--out``, seeds set), with the script's own ``experiment`` function: its environments,
network, replay buffer, double-DQN trainer, lifetime loop and validation, none of it edited (see ``shims.py``
for the import-time adjustments and ``README.md`` for what differs from a launch in 2019).

Beside rlkit's own files (``progress.csv``, ``validation_stats.csv``, ``visit_<epoch>.npy``, ``variant.json``) the
run writes ``metrics.csv``, one row per validation, with what ecorl's ``metrics.csv`` holds, measured the same way:
the share of validation envs solved, the largest |Q| over the validation rollouts' forward passes (every action),
the greedy action's shares over those rollouts, and the training reward since the previous validation. Nothing
it measures feeds back into training.

    python tools/original/run_released.py --checkout ../ecologicalrl --script hunting-fig4 \
        --set deer_move_prob=0.2 make_rtype=waypoint time_horizon=0 --seed 0 --out runs/original/hunting/s0
"""

from __future__ import annotations

import argparse
import ast
import copyreg
import csv
import gzip
import json
import math
import os
import pickle
import random
import runpy
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import shims  # noqa: E402

SCRIPTS = {
    "hunting-fig4": "experiments/continual/dynamic_static/deer/tool_dqn.py",
    "factory-fig4": "experiments/continual/dynamic_static/factory/dqn.py",
    "scavenging-shaping": "experiments/continual/env_shaping/monster/dqn.py",
    "hunting-shaping": "experiments/continual/env_shaping/distance_increasing/deer/tool_dqn.py",
    "salad-shaping": "experiments/continual/env_shaping/distance_increasing/axe/tool_dqn.py",
    "walls-shaping": "experiments/continual/env_shaping/env_vs_reward/wall/tool_dqn_wall_train.py",
}
"""Named released scripts; any other script path inside the checkout also works."""
NUM_ACTIONS = 7
METRIC_FIELDS = ("epoch", "step", "success", "made", "made_axe", "max_q", "top_action", "top_action_share",
                 *(f"action_{a}" for a in range(NUM_ACTIONS)), "y_pred_max", "qf_loss", "epsilon",
                 "train_reward", "train_solves", "seconds")


def add_point_arguments(parser: argparse.ArgumentParser) -> None:
    """``--checkout``, ``--script`` and ``--set``: one sweep point of a released script."""
    parser.add_argument("--checkout", type=Path, required=True, help="a checkout of jcoreyes/ecologicalrl")
    parser.add_argument("--script", required=True,
                        help=f"a released script: one of {', '.join(SCRIPTS)}, or a path inside the checkout")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                        help="env_kwargs values that pick one point of the script's sweep (Python literals; "
                             "a bare word is a string)")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_point_arguments(parser)
    parser.add_argument("--seed", type=int, required=True, help="seeds random, numpy and torch")
    parser.add_argument("--out", type=Path, required=True, help="the run's folder (must not exist or be empty)")
    parser.add_argument("--epochs", type=int, default=None,
                        help="stop after this many epochs (default: the script's num_epochs)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1, one core per seed)")
    parser.add_argument("--validate-every", type=int, default=None, metavar="EPOCHS",
                        help="validate every this many epochs instead of the script's (10); validation is about "
                             "30 %% of a hunting run's time and does not train, but draws from Python's global "
                             "random, as training's exploration does")
    parser.add_argument("--checkpoint-every", type=int, default=100, metavar="EPOCHS",
                        help="pickle the whole algorithm every this many epochs (0: never), so --resume continues")
    parser.add_argument("--resume", action="store_true",
                        help="continue the run in --out from its checkpoint (same --checkout; rlkit's own logs of "
                             "the continued part go to --out/resumed-EPOCH/)")
    return parser.parse_args(argv)


def collect_sweep(script: Path) -> list[tuple]:
    """Run ``script`` as __main__ with rlkit's ``run_experiment`` collecting (experiment, variant) instead."""
    import rlkit.launchers.launcher_util as launcher

    calls: list[tuple] = []
    launcher.run_experiment = lambda function, variant=None, **kwargs: calls.append((function, variant, kwargs))
    runpy.run_path(str(script), run_name="__main__")
    return calls


def pick(calls: list[tuple], settings: dict) -> tuple:
    """The one sweep point whose env_kwargs match ``settings`` (the script launches each point n_seeds times)."""
    points = {}
    for function, variant, kwargs in calls:
        if all(variant["env_kwargs"].get(k, object()) == v for k, v in settings.items()):
            points[json.dumps(variant, sort_keys=True, default=str)] = (function, variant, kwargs)
    if len(points) != 1:
        keys = sorted({k for _, v, _ in calls for k, val in v["env_kwargs"].items()
                       if len({json.dumps(c[1]["env_kwargs"].get(k), default=str) for c in calls}) > 1})
        raise SystemExit(f"--set matches {len(points)} sweep points, not one; the script sweeps {keys}")
    return next(iter(points.values()))


def parse_settings(pairs: list[str]) -> dict:
    """``KEY=VALUE`` strings as a dict, values read as Python literals."""
    settings = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep:
            raise SystemExit(f"--set {pair!r}: write KEY=VALUE")
        try:
            settings[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):  # a bare word: a string
            settings[key] = value
    return settings


def rows_up_to(text: str, epoch: int) -> str:
    """A ``metrics.csv`` text with each validation once and none after ``epoch``: of a row a killed run wrote past
    its checkpoint and the resumed run wrote again, the later one.
    """
    header, *rows = text.splitlines(keepends=True)
    by_epoch = {int(row.split(",", 1)[0]): row for row in rows}  # an epoch written twice: its last row
    return header + "".join(row for e, row in by_epoch.items() if e <= epoch)


class Recorder:
    """Measures validation and training without touching either, and writes ``metrics.csv``."""

    def __init__(self, out: Path, saved: dict | None = None, saved_epoch: int = -1) -> None:
        """A new ``metrics.csv`` in ``out``; or, resuming from the checkpoint after epoch ``saved_epoch`` with
        the recorder state ``saved``, the run's own, its rows written after that epoch dropped (the resumed
        run writes them again).
        """
        self.path = out / "metrics.csv"
        self.start = time.time()
        self.train_reward = 0.0
        self.train_solves = 0
        self.steps = 0
        self.collections = 0  # calls of add_paths: the warm-up, then one per epoch
        if saved is None:
            with self.path.open("w", newline="") as f:
                csv.writer(f).writerow(METRIC_FIELDS)
        else:  # a resumed run: its counters, its clock going on from the seconds already spent
            self.__dict__.update({k: v for k, v in saved.items() if k != "seconds"})
            self.start = time.time() - saved["seconds"]
            self.path.write_text(rows_up_to(self.path.read_text(), saved_epoch))

    def state(self) -> dict:
        """What a resumed run needs to go on counting."""
        return {"train_reward": self.train_reward, "train_solves": self.train_solves, "steps": self.steps,
                "collections": self.collections, "seconds": time.time() - self.start}

    def wrap_replay(self, buffer_class) -> None:
        """Count the reward, solves and steps of every path the trainer stores (the training data only)."""
        original = buffer_class.add_paths
        recorder = self

        def add_paths(self, paths):
            recorder.collections += 1
            for path in paths:
                recorder.train_reward += float(path["rewards"].sum())
                recorder.train_solves += sum(bool(info.get("solved", False)) for info in path["env_infos"])
                recorder.steps += len(path["actions"])
            return original(self, paths)

        buffer_class.add_paths = add_paths

    def wrap_validation(self, algorithm_class) -> None:
        """Record |Q| and greedy actions of every forward pass during `validate`, then a metrics row."""
        import numpy as np
        import torch
        from rlkit.core.logging import compute_stats

        original = algorithm_class.validate
        recorder = self

        def validate(self, snapshot):
            qf = self.trainer.qf
            outputs = []
            handle = qf.register_forward_hook(lambda module, inputs, output: outputs.append(output.detach()))
            try:
                stats = original(self, snapshot)
            finally:
                handle.remove()
            q = torch.cat([o.reshape(-1, o.shape[-1]) for o in outputs])
            seen = {"max_q": float(q.abs().max()) if bool(q.isfinite().all()) else math.nan,
                    "counts": np.bincount(q.argmax(-1).numpy(), minlength=NUM_ACTIONS)}
            summary = compute_stats(stats, horizon=0, task_obj=self.eval_env.task[1])
            recorder.write(self, summary, seen)
            return stats

        algorithm_class.validate = validate

    def write(self, algorithm, summary: dict, seen: dict) -> None:
        """One metrics row for the validation just run (``summary``: rlkit's compute_stats of it)."""
        counts = seen["counts"]
        total = max(int(counts.sum()), 1)
        shares = counts / total
        diag = algorithm.trainer.eval_statistics
        strategy = getattr(getattr(algorithm.expl_data_collector, "_policy", None), "es", None)
        epoch = self.collections - 2  # validation runs after the epoch's collection; epochs count from 0
        success = summary["proportion_solved"]
        row = {"epoch": epoch, "step": self.steps, "success": success, "made": summary["proportion_made"],
               "made_axe": summary["proportion_made_axe"],
               "max_q": seen["max_q"], "top_action": int(counts.argmax()), "top_action_share": float(shares.max()),
               **{f"action_{a}": float(shares[a]) for a in range(NUM_ACTIONS)},
               "y_pred_max": float(diag.get("Y Predictions Max", math.nan)),
               "qf_loss": float(diag.get("QF Loss", math.nan)),
               "epsilon": float(strategy.schedule(strategy.time)) if hasattr(strategy, "schedule") else math.nan,
               "train_reward": self.train_reward, "train_solves": self.train_solves,
               "seconds": round(time.time() - self.start, 1)}
        with self.path.open("a", newline="") as f:
            csv.DictWriter(f, METRIC_FIELDS).writerow(row)
        print(f"step {self.steps:>8}  success {success:.2f}  max|Q| {seen['max_q']:.3g}  top action "
              f"{row['top_action']} ({row['top_action_share']:.2f})  train reward {self.train_reward:g}", flush=True)
        self.train_reward, self.train_solves = 0.0, 0


CHECKPOINT = "checkpoint.pkl.gz"
"""The pickled algorithm (networks, optimiser, replay buffer, environments, collectors, exploration) and the
random generators' states (Python's, NumPy's, torch's and gym 0.10's module-level one behind
``action_space.sample()``), written every ``--checkpoint-every`` epochs."""


def _keys_view(keys: list):
    return dict.fromkeys(keys).keys()


def allow_pickling() -> None:
    """The replay buffer keeps a ``dict_keys`` view, which pickle refuses: pickle it as the view of its keys."""
    copyreg.pickle(type({}.keys()), lambda view: (_keys_view, (list(view),)))


def save_checkpoint(out: Path, algorithm, epoch: int, recorder: Recorder) -> None:
    """Pickle everything the run needs to go on after ``epoch``, atomically (a temporary file, then renamed)."""
    import numpy as np
    import torch
    from gym.spaces import prng

    state = {"algorithm": algorithm, "epoch": epoch, "recorder": recorder.state(),
             "rng": (random.getstate(), np.random.get_state(), torch.get_rng_state(), prng.np_random.get_state())}
    partial = out / f"{CHECKPOINT}.partial"
    with gzip.open(partial, "wb", compresslevel=1) as f:
        pickle.dump(state, f, protocol=4)
    os.replace(partial, out / CHECKPOINT)


def load_checkpoint(out: Path) -> dict:
    """The checkpoint of the run in ``out``, its random generators restored."""
    import numpy as np
    import torch

    with gzip.open(out / CHECKPOINT, "rb") as f:
        state = pickle.load(f)  # a file this runner wrote: pickle runs code, so resume only your own runs
    from gym.spaces import prng

    python_rng, numpy_rng, torch_rng, spaces_rng = state["rng"]
    random.setstate(python_rng)
    np.random.set_state(numpy_rng)
    torch.set_rng_state(torch_rng)
    prng.np_random.set_state(spaces_rng)  # gym 0.10's action_space.sample(), which validation's exploration calls
    return state


def hook_epoch_end(out: Path, total: int, offset: int, checkpoint_every: int, recorder: Recorder,
                   every: int = 500) -> None:
    """After each epoch: the Q-network's weights every ``every`` epochs and at the end (``qf_<epoch>.pt``), and a
    checkpoint every ``checkpoint_every``. A resumed loop counts its epochs from 0 again: ``offset`` (the epochs
    done before) makes the numbers rlkit's validation and logs see the run's own.
    """
    import torch
    from rlkit.core.rl_algorithm import BaseRLAlgorithm

    original = BaseRLAlgorithm._end_epoch

    def _end_epoch(self, epoch, *args, **kwargs):
        epoch += offset
        original(self, epoch, *args, **kwargs)
        last = epoch + 1 == total
        if epoch % every == 0 or last:
            torch.save(self.trainer.qf.state_dict(), out / f"qf_{epoch}.pt")
        if checkpoint_every and (epoch + 1) % checkpoint_every == 0 and not last:
            save_checkpoint(out, self, epoch, recorder)

    BaseRLAlgorithm._end_epoch = _end_epoch


def main(argv: list[str] | None = None) -> None:
    """Run one seed of one sweep point, or continue one from its checkpoint."""
    args = parse_args(argv)
    shims.check_checkout(args.checkout)
    script = args.checkout / SCRIPTS.get(args.script, args.script)
    if not script.is_file():
        raise SystemExit(f"no script {script}; name one of {', '.join(SCRIPTS)} or a path inside --checkout")
    if args.resume and not (args.out / CHECKPOINT).is_file():
        raise SystemExit(f"no {CHECKPOINT} in {args.out} to resume from; start the run without --resume")
    if not args.resume and args.out.exists() and any(args.out.iterdir()):
        raise SystemExit(f"{args.out} is not empty; pass a new --out, or --resume to continue its run")
    shims.install(args.checkout)
    allow_pickling()
    import numpy as np
    import torch

    torch.set_num_threads(args.threads)
    function, variant, launch = pick(collect_sweep(script), parse_settings(args.set))
    total = args.epochs or variant["algo_kwargs"]["algorithm_kwargs"]["num_epochs"]
    variant["algo_kwargs"]["algorithm_kwargs"]["num_epochs"] = total
    if args.validate_every:
        variant["algo_kwargs"]["algorithm_kwargs"]["validation_period"] = args.validate_every
    algorithm_kwargs = variant["algo_kwargs"]["algorithm_kwargs"]
    if "validation_envs_pkl" in algorithm_kwargs:
        algorithm_kwargs["validation_envs_pkl"] = shims.released_path(algorithm_kwargs["validation_envs_pkl"],
                                                                      args.checkout)
    args.out.mkdir(parents=True, exist_ok=True)

    from rlkit.core.rl_algorithm import BaseRLAlgorithm
    from rlkit.data_management.replay_buffer import ReplayBuffer
    from rlkit.launchers.launcher_util import setup_logger
    from rlkit.torch.pytorch_util import set_gpu_mode

    saved = load_checkpoint(args.out) if args.resume else None
    recorder = Recorder(args.out, saved["recorder"], saved["epoch"]) if saved else Recorder(args.out)
    recorder.wrap_replay(ReplayBuffer)
    recorder.wrap_validation(BaseRLAlgorithm)
    variant["exp_id"], variant["seed"] = "0", str(args.seed)
    done = saved["epoch"] + 1 if saved else 0
    log_dir = args.out / f"resumed-{done}" if saved else args.out  # rlkit's logger truncates its files
    setup_logger(exp_prefix=launch.get("exp_prefix", "released"), variant=variant, log_dir=str(log_dir),
                 snapshot_mode="none")
    set_gpu_mode(False)
    hook_epoch_end(args.out, total, done, args.checkpoint_every, recorder)
    if saved is None:
        random.seed(args.seed)
        np.random.seed(args.seed)
        torch.manual_seed(args.seed)
        (args.out / "command.json").write_text(json.dumps(
            {"argv": sys.argv[1:], "script": SCRIPTS.get(args.script, args.script), "adjustments": shims.ADJUSTMENTS,
             "torch": torch.__version__, "numpy": np.__version__}, indent=1) + "\n")
        function(variant)
    else:
        algorithm = saved["algorithm"]
        algorithm.num_epochs = total - done  # the release's loop counts its epochs from 0 again
        algorithm.min_num_steps_before_training = 0  # its warm-up is in the replay buffer already
        if args.validate_every:
            algorithm.validation_period = args.validate_every
        with (args.out / "resumes.jsonl").open("a") as f:
            f.write(json.dumps({"after_epoch": saved["epoch"], "argv": sys.argv[1:]}) + "\n")
        algorithm.train()
    (args.out / CHECKPOINT).unlink(missing_ok=True)
    (args.out / "done.json").write_text(json.dumps({"steps": recorder.steps,
                                                    "seconds": round(time.time() - recorder.start, 1)}) + "\n")


if __name__ == "__main__":
    main()
