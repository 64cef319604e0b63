"""Sharing one GPU between processes: N trainers side by side, with the card time-sliced (the default) and
under CUDA MPS (one server multiplexing every process's kernels), their summed agent-steps/s.

    python benchmarks/bench_gpu_share.py --procs 1 2 4 8 --k 40      # on a GPU machine, as root for MPS

Each process is `bench_gpu.py --modes "cuda graphs"` at K seeds (salad, the experiments' settings), started
together; the sum of their rates is what N experiments run side by side get from the card. MPS is started
with ``nvidia-cuda-mps-control -d`` and stopped after; where it cannot start, the MPS column says so. Compare
the columns of one run only.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parent / "bench_gpu.py"
RATE_LINE = re.compile(r"^\s*(\d+)\s+([\d,]+)\s")


def side_by_side(procs: int, k: int, epochs: int, env: dict[str, str]) -> float:
    """Summed agent-steps/s of ``procs`` bench_gpu processes started together (nan where one failed)."""
    command = [sys.executable, str(BENCH), "--ks", str(k), "--epochs", str(epochs), "--modes", "cuda graphs"]
    running = [subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
               for _ in range(procs)]
    total = 0.0
    for proc in running:
        out, _ = proc.communicate()
        rates = [float(m.group(2).replace(",", "")) for line in out.splitlines() if (m := RATE_LINE.match(line))]
        if proc.returncode or not rates:
            print(f"  a process failed (exit {proc.returncode}): {out.strip().splitlines()[-1:]}", flush=True)
            return float("nan")
        total += rates[-1]
    return total


def start_mps(env: dict[str, str]) -> str | None:
    """Start an MPS control daemon for ``env`` (its pipe and log folders set there); None, or why it failed."""
    control = shutil.which("nvidia-cuda-mps-control")
    if control is None:
        return "nvidia-cuda-mps-control not found"
    folder = tempfile.mkdtemp(prefix="mps-")
    env.update(CUDA_MPS_PIPE_DIRECTORY=f"{folder}/pipe", CUDA_MPS_LOG_DIRECTORY=f"{folder}/log")
    os.makedirs(env["CUDA_MPS_PIPE_DIRECTORY"]), os.makedirs(env["CUDA_MPS_LOG_DIRECTORY"])
    done = subprocess.run([control, "-d"], env=env, capture_output=True, text=True)
    time.sleep(1)
    return None if done.returncode == 0 else f"exit {done.returncode}: {(done.stderr or done.stdout).strip()}"


def stop_mps(env: dict[str, str]) -> None:
    """Ask the MPS control daemon of ``env`` to quit."""
    subprocess.run(["nvidia-cuda-mps-control"], input="quit\n", env=env, capture_output=True, text=True)
    time.sleep(1)


def main() -> None:
    """Time-sliced first, then MPS, for each number of processes."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--procs", type=int, nargs="+", default=[1, 2, 4, 8], help="processes side by side")
    parser.add_argument("--k", type=int, default=40, help="seeds per process")
    parser.add_argument("--epochs", type=int, default=3, help="timed epochs of 500 steps per process")
    args = parser.parse_args()
    plain = {n: side_by_side(n, args.k, args.epochs, dict(os.environ)) for n in args.procs}
    env = dict(os.environ)
    failure = start_mps(env)
    mps = {} if failure else {n: side_by_side(n, args.k, args.epochs, env) for n in args.procs}
    if not failure:
        stop_mps(env)
    print(f"K = {args.k} per process; summed agent-steps/s"
          + (f" (MPS did not start: {failure})" if failure else ""))
    print("| processes | time-sliced | MPS |\n|---|---|---|")
    for n in args.procs:
        print(f"| {n} | {plain[n]:,.0f} | {mps[n]:,.0f} |" if n in mps else f"| {n} | {plain[n]:,.0f} | — |")


if __name__ == "__main__":
    main()
