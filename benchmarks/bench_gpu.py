"""The trainer on a GPU: CPU/CUDA parity first, then training speed at K seeds in one process, CPU vs CUDA.

    python benchmarks/bench_gpu.py                      # parity, then K = 10, 40, 330: cpu, cuda eager, graphs
    python benchmarks/bench_gpu.py --ks 10 40 --epochs 4
    python benchmarks/bench_gpu.py --ks 330 1000 --modes "cuda graphs" --adam per-row   # Adam's two layouts

Parity: the same seeds trained two epochs on the CPU and on the GPU (TF32 off) must give online weights
within 1e-5 (relative to the largest weight), and the GPU with each gradient step replayed as a CUDA graph
exactly the weights of eager kernels. Speed: aggregate agent-steps per second (K seeds x environment
steps, each step with its gradient step) of the salad trainer, timed over whole epochs after one untimed
epoch, the CPU with one torch thread. Without CUDA it says so and times the CPU only. Absolute rates move
between runs and machines; compare the CPU and CUDA columns of one run.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from train.agent.dqn import FlatAdam  # noqa: E402
from train.config import TrainConfig  # noqa: E402
from train.loop.trainer import Trainer  # noqa: E402

BASE = TrainConfig().replace(task="salad", dynamism=0.1, reset_free=True, lr=3e-4, warmup_steps=500,
                             buffer_size=50_000, eval_every=500_000, progress=False, threads=1)
"""Salad, the experiments' settings; a smaller replay so K = 330 fits any host."""


MODES = {"cpu": {"device": "cpu"}, "cuda eager": {"device": "cuda", "cuda_graphs": False},
         "cuda graphs": {"device": "cuda", "cuda_graphs": True}}
"""The trainers timed: the CPU, and a GPU with eager kernels and with each gradient step a CUDA graph."""


def parity() -> tuple[float, float]:
    """Largest |CPU - CUDA| online weight after two epochs, relative to the largest weight, and the largest
    |eager - graphs| difference (CUDA graphs replay the eager kernels, so 0).
    """
    cfg = BASE.replace(seeds=4, updates_per_epoch=50)
    trained = []
    for mode in MODES.values():
        trainer = Trainer(cfg.replace(**mode))
        trainer.train_epoch()
        trainer.train_epoch()
        trained.append(trainer.agent.online.detach().cpu())
        trainer.close()
    cpu, eager, graphs = trained
    return float((cpu - eager).abs().max() / cpu.abs().max()), float((eager - graphs).abs().max())


def rate(k: int, mode: str, epochs: int) -> tuple[float, float, float]:
    """(agent-steps per second, seconds of the first, untimed epoch (warm-up, first kernels, graph capture),
    share of the time spent collecting) of K seeds trained as `MODES` ``mode`` says.
    """
    device = MODES[mode]["device"]
    trainer = Trainer(BASE.replace(seeds=k, **MODES[mode]))
    began = time.perf_counter()
    trainer.train_epoch()  # the warm-up and one epoch: allocation, first kernels
    first = time.perf_counter() - began
    _sync(device)
    collecting = learning = 0.0
    steps = trainer.step
    for _ in range(epochs):
        began = time.perf_counter()
        trainer.collect(trainer.learner.steps_to_collect(trainer.step))
        _sync(device)
        middle = time.perf_counter()
        trainer.learn()
        _sync(device)
        collecting, learning = collecting + middle - began, learning + time.perf_counter() - middle
    done = (trainer.step - steps) * k
    trainer.close()
    return done / (collecting + learning), first, collecting / (collecting + learning)


def profile(k: int, device: str, rows: int = 25) -> None:
    """Print torch's profile of one epoch's updates at K seeds on ``device`` (the heaviest ops first)."""
    trainer = Trainer(BASE.replace(seeds=k, device=device))
    trainer.train_epoch()
    trainer.collect(trainer.learner.steps_to_collect(trainer.step))
    activities = [torch.profiler.ProfilerActivity.CPU]
    if device.startswith("cuda"):
        activities.append(torch.profiler.ProfilerActivity.CUDA)
    with torch.profiler.profile(activities=activities) as prof:
        trainer.learn()
        _sync(device)
    key = "self_cuda_time_total" if device.startswith("cuda") else "self_cpu_time_total"
    print(prof.key_averages().table(sort_by=key, row_limit=rows))
    trainer.close()


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def main() -> None:
    """Parity, then the table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ks", type=int, nargs="+", default=[10, 40, 330], help="seeds trained together")
    parser.add_argument("--epochs", type=int, default=3, help="timed epochs of 500 steps per K and device")
    parser.add_argument("--profile", type=int, metavar="K", help="only print a profile of one epoch's updates "
                        "at K seeds (on CUDA if there is one)")
    parser.add_argument("--modes", nargs="+", choices=list(MODES), default=list(MODES),
                        help="the trainers to time (default: all there are here)")
    parser.add_argument("--adam", choices=["default", "per-row", "flat"], default="default",
                        help="how Adam's fused kernel gets the K rows: per row (the CPU's default), as one (K, P) "
                        "tensor (CUDA's default), or each device's default")
    args = parser.parse_args()
    FlatAdam.PER_ROW = {"default": None, "per-row": True, "flat": False}[args.adam]
    if args.profile:
        profile(args.profile, "cuda" if torch.cuda.is_available() else "cpu")
        return
    modes = [m for m in args.modes if m == "cpu"]
    if torch.cuda.is_available():
        torch.backends.cuda.matmul.allow_tf32 = False
        torch.backends.cudnn.allow_tf32 = False
        modes += [m for m in args.modes if m != "cpu"]
    else:
        modes = ["cpu"]
        print(f"no CUDA device here (torch {torch.__version__}): timing the CPU trainer only")
    if len(modes) == len(MODES):  # parity compares all three
        error, graphs = parity()
        print(f"parity after two epochs: CPU vs CUDA max relative weight difference {error:.2e} "
              f"({'ok' if error <= 1e-5 else 'FAILED: above 1e-5'}); eager vs CUDA graphs {graphs:.2e} "
              f"({'ok' if graphs == 0 else 'FAILED: not identical'})")
    print(f"agent-steps/s, seconds of the first (untimed) epoch, share of the time collecting; per K (Adam: "
          f"{args.adam}):")
    print(f"{'K':>5s} " + " ".join(f"{m:>30s}" for m in modes))
    for k in args.ks:
        cells = []
        for mode in modes:
            steps_per_s, first, collecting = rate(k, mode, args.epochs)
            cells.append(f"{steps_per_s:>14,.0f} {first:>7.1f} s {collecting:>5.0%}")
        print(f"{k:>5d} " + " ".join(cells), flush=True)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    gpu = f", GPU peak {torch.cuda.max_memory_allocated() / 2**20:.0f} MiB" if modes != ["cpu"] else ""
    print(f"peak RSS {peak:.0f} MiB{gpu}")


if __name__ == "__main__":
    main()
