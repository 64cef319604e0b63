"""Time and peak memory of `ecorl report` on crafted results trees (the cases of the hostile-trees issue).

    python benchmarks/bench_hostile_report.py            # every case, 120 s each at most
    python benchmarks/bench_hostile_report.py --keep DIR # leave the crafted trees in DIR

Each case copies one small, real results tree (a smoke-budget run of one condition) and plants one file in it:
a 300-frame full-HD MP4 beside the run, a FIFO named like a video, metrics.csv files of 200 000 and 20 000
seeds and one at the caps (1 024 seeds, 300 evaluations), a 5 000-frame MP4 at the largest frame read, a 200 MB
metrics.csv and a 90 MB experiment.json. Then `ecorl report` runs on it in a subprocess; the
table gives its exit code, wall time, peak resident memory (``os.wait4``) and the first line it printed on
stderr. The aim: every case answers within 60 s and 1 GB, with a one-line refusal or a report.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
EXPERIMENT, TASK, CONDITION = "headline", "salad", "static-reset-free"


def base_tree(root: Path) -> Path:
    """A smoke-budget results tree of one condition, trained once."""
    out = root / "base"
    subprocess.run([sys.executable, "-m", "train.cli", "run", EXPERIMENT, "--budget", "smoke", "--task", TASK,
                    "--condition", CONDITION, "--out", str(out), "--no-progress"], check=True, cwd=REPO,
                   capture_output=True)
    return out / EXPERIMENT


def _metrics(path: Path, seeds: int, steps: int = 2) -> None:
    with open(path, "w") as fh:
        fh.write("step,seed,success\n")
        for step in range(1, steps + 1):
            fh.writelines(f"{5000 * step},{k},0.0\n" for k in range(seeds))


def _long_metrics(path: Path, size: int) -> None:
    with open(path, "w") as fh:
        fh.write("step,seed,success\n")
        line = "".join(f"{5000 * (i + 1)},0,0.0\n" for i in range(100_000))
        while fh.tell() < size:
            fh.write(line)


def _video(path: Path, frames: int = 300, size: tuple[int, int] = (1920, 1080)) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30, size)
    frame = np.zeros((size[1], size[0], 3), dtype=np.uint8)
    for i in range(frames):
        frame[:, :, i % 3] = i % 255
        writer.write(frame)
    writer.release()


def _experiment_json(path: Path, size: int) -> None:
    path.write_text('{"name": "headline", "tasks": {}, "pad": "' + "x" * size + '"}')


CASES = {
    "a 300-frame full-HD MP4 beside the run": lambda run, exp: _video(run / "bomb.mp4"),
    "a FIFO named video.mp4": lambda run, exp: os.mkfifo(run / "video.mp4"),
    "metrics.csv of 200 000 seeds (9 MB)": lambda run, exp: _metrics(run / "metrics.csv", 200_000, 1),
    "metrics.csv of 20 000 seeds": lambda run, exp: _metrics(run / "metrics.csv", 20_000),
    "metrics.csv of 1 024 seeds x 300 evaluations (the most read)": lambda run, exp: _metrics(
        run / "metrics.csv", 1_024, 300),
    "a 5 000-frame 1280x720 MP4 beside the run": lambda run, exp: _video(run / "long.mp4", 5_000, (1280, 720)),
    "a 200 MB metrics.csv": lambda run, exp: _long_metrics(run / "metrics.csv", 200 << 20),
    "a 90 MB experiment.json": lambda run, exp: _experiment_json(exp / "experiment.json", 90 << 20),
}


def report(exp: Path, limit: float) -> tuple[int, float, float, str]:
    """(exit code, seconds, peak MB, first stderr line) of `ecorl report exp` in a subprocess."""
    began = time.perf_counter()
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen([sys.executable, "-m", "train.cli", "report", str(exp), "--no-videos"], cwd=REPO,
                                stdout=subprocess.DEVNULL, stderr=err)
        deadline = began + limit
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                proc.kill()
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
        seconds = time.perf_counter() - began
        err.seek(0)
        lines = [line for line in err.read().decode(errors="replace").splitlines() if line.strip()]
    code = os.waitstatus_to_exitcode(status)
    first = next((line for line in lines if "skipped" in line or "error" in line.lower()), lines[0] if lines else "")
    return code, seconds, usage.ru_maxrss / 1024, first[:150]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit", type=float, default=120.0, help="seconds before a report is killed")
    parser.add_argument("--keep", type=Path, default=None, help="build the trees here and keep them")
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="hostile-report-")) if args.keep is None else args.keep
    root.mkdir(parents=True, exist_ok=True)
    try:
        base = base_tree(root)
        print("| case | exit | seconds | peak MB | what it said |\n|---|---|---|---|---|")
        for i, (name, plant) in enumerate(CASES.items()):
            exp = root / f"case{i}" / EXPERIMENT
            shutil.copytree(base, exp, symlinks=True)
            shutil.rmtree(exp / "figures", ignore_errors=True)
            plant(exp / TASK / CONDITION, exp)
            code, seconds, peak, said = report(exp, args.limit)
            print(f"| {name} | {code} | {seconds:.1f} | {peak:.0f} | {said} |", flush=True)
            shutil.rmtree(root / f"case{i}") if args.keep is None else None
    finally:
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
