"""Rollout videos for the report: render the missing ones, and re-encode MP4s to WebM for browsers."""

from __future__ import annotations

import os
import sys
from contextlib import contextmanager
from pathlib import Path

from train.checkpoint import CHECKPOINT_NAME
from train.experiments.report.runs import ExperimentResults
from train.fileio import atomic_path, is_temporary


def render_missing_videos(exp: ExperimentResults) -> list[Path]:
    """Render ``video.mp4`` (seed 0's final policy in the test MDP) for finished runs without one."""
    from train.experiments.video import record_video
    from train.rundir import RunDirError

    made = []
    for run in exp.runs:
        target = run.path / "video.mp4"
        if run.done and not target.exists() and (run.path / CHECKPOINT_NAME).exists():
            try:
                made.append(record_video(None, target, policy_path=run.path).path)
            except (RunDirError, ValueError, FileNotFoundError) as err:
                print(f"ecorl report: no video of {run.path}: {err}", file=sys.stderr)
    return made


def find_videos(root: Path) -> list[Path]:
    """Every MP4 below ``root`` (run directories and the top level), sorted."""
    return sorted(p for p in root.rglob("*.mp4") if ".partial" not in p.name and not is_temporary(p.name))


@contextmanager
def _quiet_stderr():
    """Silence the process's stderr (file descriptor 2, so C libraries too) inside the block."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def web_copy(video: Path, out_dir: Path, root: Path) -> Path | None:
    """A WebM (VP8) copy of an MP4 for the HTML page (OpenCV's MP4 codec does not play in browsers)."""
    import cv2

    name = "_".join(video.relative_to(root).with_suffix("").parts) + ".webm"
    target = out_dir / name
    if target.exists() and target.stat().st_mtime >= video.stat().st_mtime:
        return target
    cap = cv2.VideoCapture(str(video))
    try:
        with atomic_path(target) as tmp:
            if not _transcode(cap, tmp):
                raise _NoFrames
    except _NoFrames:
        return None
    finally:
        cap.release()
    return target


class _NoFrames(Exception):
    """A video that could not be read or re-encoded (its web copy is skipped)."""


def _transcode(cap, out: Path) -> bool:
    """Re-encode every frame of an opened capture to a VP8 WebM at ``out``; False if nothing was written."""
    import cv2

    fps = cap.get(cv2.CAP_PROP_FPS) or 8.0
    writer = None
    try:
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            if writer is None:
                with _quiet_stderr():  # FFMPEG names its tag fallback on stderr; the file is fine
                    writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"VP80"), fps,
                                             (frame.shape[1], frame.shape[0]))
                if not writer.isOpened():
                    return False
            writer.write(frame)
    finally:
        if writer is not None:
            writer.release()
    return writer is not None
