"""Rollout videos for the report: film the best seed of finished runs, and give the page H.264 copies with
a poster frame and a caption.

A filmed run directory holds ``video.mp4`` and ``video.json`` (which seed, episodes filmed and solved). The
page never points into the run directories: each video is re-encoded as H.264 MP4 (plays in every browser)
into the report's own ``figures/videos/`` beside a PNG of its middle frame, so the page can be copied anywhere.
"""

from __future__ import annotations

import html
import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from train.experiments.report.runs import ExperimentResults, Run
from train.storage.checkpoint import CHECKPOINT_NAME
from train.storage.fileio import atomic_text, atomic_write, is_temporary
from train.storage.rundir import FILM_NAME, STRIP_NAME, VIDEO_INFO
from train.storage.safeio import UnsafeFileError, load_json, no_link_below, read_bytes, regular_file

SMOKE_FILM_STEPS = 40
"""Steps filmed of a run at the smoke budget (seconds of training, for tests: 40 frames show the film works)."""


def best_seed(run: Run) -> int:
    """Index of the seed with the highest last evaluation (the first of equals)."""
    return int(np.argmax(run.values[-1])) if run.values.size else 0


def film_best_seed(run: Run, target: Path, policy: Path | None = None, steps: int | None = None) -> Path:
    """Film the best seed of ``run`` (its final policy in the test MDP) into ``target``, with its sidecar and
    the filmstrip of its first episode; ``policy``: the best seed's exported policy file, where the run kept
    no checkpoint (shipped results); ``steps``: a film of that many steps instead of the films' `VIDEO_EPISODES`
    episodes.
    """
    from train.experiments.video import record_video

    index = best_seed(run)
    video = record_video(None, target, policy_path=policy or run.path, seed_index=0 if policy else index,
                         strip=target.with_name(STRIP_NAME), steps=steps)
    info = {"seed": int(run.seed_ids[index]), "episodes": video.episodes, "solved": video.solved,
            "metric": video.metric, "summary": video.summary(),
            "final": float(run.values[-1][index]), "step": int(run.steps[-1])}
    atomic_text(target.with_name(VIDEO_INFO), json.dumps(info, indent=2) + "\n")
    return video.path


def render_missing_videos(exp: ExperimentResults, root: Path | None = None) -> list[Path]:
    """Film the best seed of every finished run that has no ``video.mp4`` yet, or one filmed at an earlier step
    (the run trained on since), from its checkpoint or, without one, its exported best policy
    (``policies/best.npz``); a run reached through a symbolic link below ``root`` (the tree the report was given)
    is not filmed.
    """
    from train.storage.rundir import RUN_POLICIES_DIR, RunDirError

    made = []
    steps = SMOKE_FILM_STEPS if exp.info.get("budget") == "smoke" else None
    for run in exp.runs:
        target = run.path / FILM_NAME
        exported = run.path / RUN_POLICIES_DIR / "best.npz"
        has_checkpoint = (run.path / CHECKPOINT_NAME).exists()
        if run.done and not _film_is_current(run, target) and (has_checkpoint or exported.is_file()):
            try:
                no_link_below(root or exp.path, target)
                made.append(film_best_seed(run, target, None if has_checkpoint else exported, steps))
            except (RunDirError, ValueError, FileNotFoundError) as err:
                print(f"ecorl report: no video of {run.path}: {err}", file=sys.stderr)
    return made


def _film_is_current(run: Run, target: Path) -> bool:
    """True when ``target`` exists and its sidecar does not name an earlier step than the run's last evaluation
    (films made before sidecars recorded their step count as current).
    """
    if not target.exists():
        return False
    try:
        filmed = load_json(target.with_name(VIDEO_INFO)).get("step")
    except (OSError, ValueError, AttributeError):
        return True
    return not isinstance(filmed, int) or filmed >= int(run.steps[-1])


def find_videos(root: Path) -> list[Path]:
    """Every MP4 below ``root`` (run directories and the top level) except the report's own copies, sorted: only
    regular files reached through no symbolic link (a link or a FIFO is named on stderr and skipped).
    """
    found = []
    for path in sorted(root.rglob("*.mp4")):
        if ".partial" in path.name or is_temporary(path.name) or "figures" in path.relative_to(root).parts[:1]:
            continue
        try:
            found.append(regular_file(no_link_below(root, path)))
        except (UnsafeFileError, OSError) as err:
            print(f"ecorl report: skipped a video: {err}", file=sys.stderr)
    return found


@dataclass(frozen=True)
class WebVideo:
    """A video as the page shows it: an H.264 copy, its poster frame and a caption."""

    mp4: Path
    poster: Path
    caption: str
    source: Path
    """The video it copies."""
    strip: Path | None = None
    """A copy of the filmstrip beside the source video, if it has one."""


def h264_codec(mp4: Path) -> str | None:
    """The RFC 6381 codecs string of an H.264 MP4 (``avc1.PPCCLL``: profile, constraints and level, read from its
    ``avcC`` box near the start, where a fast-start file keeps it), or None where there is none to read.
    """
    with open(mp4, "rb") as f:
        head = f.read(1 << 16)
    at = head.find(b"avcC")
    if at < 0 or len(head) < at + 8:
        return None
    return "avc1." + head[at + 5:at + 8].hex().upper()


def caption_of(video: Path, root: Path) -> str:
    """Where the video comes from and, from its sidecar, the seed filmed and how its episodes went."""
    where = video.parent.relative_to(root).as_posix() if video.name == FILM_NAME else video.name
    try:
        info = load_json(video.with_name(VIDEO_INFO)) if video.name == FILM_NAME else {}
    except (OSError, ValueError):
        info = {}
    if not isinstance(info, dict) or "seed" not in info:
        return where
    return f"{where}: seed {info['seed']} (the best), {info.get('summary', '')}".rstrip(", ")


MAX_FRAMES_READ = 5_000
"""Most frames of a video the report re-encodes (ecorl's films hold at most about 1 200)."""
MAX_FRAME_SIDE = 1_280
"""Largest frame height or width the report re-encodes (ecorl's frames are a few hundred pixels a side)."""
MAX_STRIP_BYTES = 16 << 20
"""Largest filmstrip PNG copied into a report (ecorl's are a few hundred kilobytes)."""
MAX_PIXELS_READ = 400_000_000
"""Most pixels (frames x height x width) of one video the report re-encodes: decoding and encoding time grow
with them (ecorl's longest film, the food collector's 1 001 frames of 512 x 512, holds 262 million)."""


def _frames(cap, path: Path, poster_at: int, kept: dict):
    """The capture's frames as RGB arrays, one at a time (never all in memory), at most `MAX_FRAMES_READ`, each at
    most `MAX_FRAME_SIDE` a side, at most `MAX_PIXELS_READ` pixels in all (else ValueError); frame ``poster_at``
    (or the last before it) is kept in ``kept``.
    """
    pixels = 0
    for index in range(MAX_FRAMES_READ):
        ok, frame = cap.read()
        if not ok:
            return
        if max(frame.shape[:2]) > MAX_FRAME_SIDE:
            raise ValueError(f"{path} has frames of {frame.shape[1]}x{frame.shape[0]} pixels, more than ecorl's "
                             f"films ({MAX_FRAME_SIDE} a side)")
        pixels += frame.shape[0] * frame.shape[1]
        if pixels > MAX_PIXELS_READ:
            raise ValueError(f"{path} holds more than {MAX_PIXELS_READ:,} pixels of frames ({index + 1} frames of "
                             f"{frame.shape[1]}x{frame.shape[0]}), more than ecorl's films")
        if index <= poster_at:
            kept["poster"] = frame
        yield frame[:, :, ::-1]


def web_copy(video: Path, out_dir: Path, name: str, caption: str, source: Path | None = None) -> WebVideo | None:
    """Re-encode ``video`` as ``out_dir/name.mp4`` (H.264) with ``name.png``, its middle frame, streaming frame by
    frame; None if the video cannot be read. ``video`` and its filmstrip must be regular files (`regular_file`).
    """
    import cv2

    from train.experiments.video import write_h264

    regular_file(video)  # before OpenCV opens it by name: a FIFO would block it forever
    cap = cv2.VideoCapture(str(video))
    kept: dict = {}
    try:
        fps = cap.get(cv2.CAP_PROP_FPS) or 8.0
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        mp4 = write_h264(_frames(cap, video, min(count, MAX_FRAMES_READ) // 2, kept), out_dir / f"{name}.mp4",
                         fps=fps)
    except ValueError as err:
        if "no frames" in str(err):
            return None
        raise
    finally:
        cap.release()
    ok, png = cv2.imencode(".png", np.ascontiguousarray(kept["poster"]))
    if not ok:
        return None
    poster = atomic_write(out_dir / f"{name}.png", png.tobytes())
    source = source or video
    strip = source.with_name(STRIP_NAME) if source.name == FILM_NAME else None
    copied = None
    if strip is not None and os.path.lexists(strip):
        try:
            copied = atomic_write(out_dir / f"{name}-strip.png", read_bytes(strip, MAX_STRIP_BYTES))
        except (UnsafeFileError, OSError) as err:  # a link or a FIFO planted as the strip: its bytes stay out
            print(f"ecorl report: skipped a filmstrip: {err}", file=sys.stderr)
    return WebVideo(mp4, poster, caption, source, copied)


def video_tag(out: Path, video: WebVideo) -> str:
    """A captioned H.264 <video> whose poster is its middle frame, and its filmstrip if it has one."""
    src = html.escape(video.mp4.relative_to(out).as_posix())
    poster = html.escape(video.poster.relative_to(out).as_posix())
    codec = h264_codec(video.mp4)  # the encoder's profile and level (a browser skips a source it thinks it cannot play)
    kind = f"video/mp4; codecs=&quot;{codec}&quot;" if codec else "video/mp4"
    tag = (f"<figure><video controls loop muted preload='metadata' poster='{poster}'>"
           f"<source src='{src}' type='{kind}'></video>"
           f"<figcaption>{html.escape(video.caption)} (<a href='{src}'>mp4</a>)</figcaption></figure>")
    if video.strip is None:
        return tag
    strip = html.escape(video.strip.relative_to(out).as_posix())
    return (f"{tag}<figure class='strip'><img src='{strip}' alt='filmstrip'><figcaption>the first episode, "
            f"frame by frame</figcaption></figure>")
