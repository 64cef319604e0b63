"""Headless MP4 writing with OpenCV."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np


def write_video(frames: Iterable[np.ndarray], path: str | Path, fps: float = 10.0) -> Path:
    """Write RGB uint8 frames (H, W, 3) to an MP4 file and return its path.

    All frames must share one size. The file is written to a temporary name and moved into place, so an
    interrupted call never leaves a truncated video behind; a call that fails removes its temporary.
    """
    import cv2

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".partial" + path.suffix)
    writer = None
    count = 0
    try:
        for frame in frames:
            frame = np.asarray(frame)
            if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
                raise ValueError(f"frames must be uint8 RGB arrays (H, W, 3), got {frame.dtype} {frame.shape}")
            if writer is None:
                size = (frame.shape[1], frame.shape[0])
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), size)
                if not writer.isOpened():
                    raise RuntimeError(f"OpenCV could not open a video writer for {tmp}")
            elif (frame.shape[1], frame.shape[0]) != size:
                raise ValueError(f"frame {count} has size {frame.shape[:2]}, expected {size[::-1]}")
            writer.write(np.ascontiguousarray(frame[:, :, ::-1]))
            count += 1
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        if writer is not None:
            writer.release()
    if count == 0:
        raise ValueError("write_video got no frames")
    tmp.replace(path)
    return path
