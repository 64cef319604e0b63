"""Compile every numba kernel once: ``python -m train.warmup`` (`make setup` runs it).

numba compiles a kernel at its first call and caches the machine code beside its source
(``__pycache__/*.nbi``, ``*.nbc``), which any later process loads in milliseconds. In a fresh clone nothing is
cached yet, so every process compiles the kernels it calls itself: the two workers of `make test` each paid
about a minute on a 2-core machine. This trains every task for one short epoch, with one and with two
environment threads (one alone where numba's pool holds one thread: a single-CPU machine, container or job), and
evaluates it, which calls each kernel the trainer and the environments use.
"""

from __future__ import annotations

import time

import numba

from train.config import TrainConfig
from train.loop.trainer import Trainer
from train.tasks import TASKS

WARMUP = TrainConfig().replace(seeds=2, steps=100, epoch_steps=50, updates_per_epoch=5, warmup_steps=20, batch_size=512,
                               eval_rollouts=2, eval_horizon=10, progress=False)
"""A run that touches every kernel and costs little beside the compiling (a batch of 512 for 2 seeds: enough rows
for the network's sparse first layer, `SPARSE_MIN_ROWS`)."""


def warm_up() -> float:
    """Train and evaluate every task once (compiling and caching its kernels); return the seconds taken."""
    began = time.perf_counter()
    for task in TASKS:
        for env_threads in range(1, min(2, numba.config.NUMBA_NUM_THREADS) + 1):  # one CPU: no threaded kernels
            trainer = Trainer(WARMUP.replace(task=task, dynamism=0.1, env_threads=env_threads))
            trainer.train_epoch()
            trainer.evaluate()
            trainer.close()
    return time.perf_counter() - began


if __name__ == "__main__":
    print("compiling the grid engine's numba kernels once, for every task (1-2 minutes on 2 cores; every later "
          "process loads them from the cache) ...", flush=True)
    print(f"numba kernels compiled and cached in {warm_up():.0f} s")
