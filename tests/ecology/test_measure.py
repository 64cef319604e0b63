"""Env-agnostic measurements: hitting time, marginal entropy, visitation counts, video."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ecology import count_entropy, hitting_time, marginal_entropy, visitation_counts, write_video


def test_hitting_time_counts_steps_to_first_reward():
    assert hitting_time([0, 0, 0, 100, 0, 100]) == 4
    assert hitting_time([1, 0, 100], threshold=99) == 3
    assert hitting_time([0, -100, 0]) is None
    assert hitting_time([]) is None


def test_marginal_entropy_of_known_distributions():
    a, b = np.zeros(3), np.ones(3)
    assert marginal_entropy([a, a, a, a]) == 0.0
    assert marginal_entropy([a, b, a, b]) == pytest.approx(math.log(2))
    views = [np.eye(8)[i] for i in range(8)]
    assert marginal_entropy(views) == pytest.approx(math.log(8))
    with pytest.raises(ValueError, match="at least one"):
        marginal_entropy([])


def test_count_entropy_ignores_zero_counts_and_works_along_the_last_axis():
    h = count_entropy(np.array([[2, 2, 0, 0], [1, 1, 1, 1], [5, 0, 0, 0], [0, 0, 0, 0]]))
    assert h == pytest.approx([math.log(2), math.log(4), 0.0, 0.0])


def test_visitation_counts_are_indexed_row_then_column():
    counts = visitation_counts([(1, 2), (1, 2), (3, 0)], shape=(4, 5))
    assert counts[2, 1] == 2 and counts[0, 3] == 1 and counts.sum() == 3
    with pytest.raises(ValueError, match="outside"):
        visitation_counts([(5, 0)], shape=(4, 5))


def test_write_video_produces_a_readable_mp4(tmp_path):
    import cv2

    frames = [np.full((32, 48, 3), i * 20, np.uint8) for i in range(10)]
    path = write_video(frames, tmp_path / "clip.mp4", fps=5)
    capture = cv2.VideoCapture(str(path))
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == 10
    assert (int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)), int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT))) == (48, 32)
    assert not list(tmp_path.glob("*.partial*"))


def test_write_video_refuses_bad_frames(tmp_path):
    with pytest.raises(ValueError, match="uint8 RGB"):
        write_video([np.zeros((8, 8), np.uint8)], tmp_path / "x.mp4")
    with pytest.raises(ValueError, match="no frames"):
        write_video([], tmp_path / "y.mp4")


def test_write_video_that_fails_midway_leaves_no_file(tmp_path):
    frames = [np.zeros((16, 16, 3), np.uint8), np.zeros((16, 24, 3), np.uint8)]
    with pytest.raises(ValueError, match="frame 1 has size"):
        write_video(frames, tmp_path / "clip.mp4")
    assert list(tmp_path.iterdir()) == []


def test_corner_cells_lie_inside_the_wall_and_the_share_counts_them():
    from ecology import VisitGrid, corner_cells, corner_share

    rows, cols = corner_cells((6, 8), wall=1)
    assert list(zip(rows.tolist(), cols.tolist())) == [(1, 1), (1, 6), (4, 1), (4, 6)]
    rows, cols = corner_cells((4, 4), wall=0)
    assert list(zip(rows.tolist(), cols.tolist())) == [(0, 0), (0, 3), (3, 0), (3, 3)]
    assert VisitGrid((6, 8), wall=1).corners()[1].tolist() == [1, 6, 1, 6]
    visits = np.zeros((2, 6, 8), np.int64)
    visits[0, 1, 1], visits[0, 4, 6], visits[0, 2, 3] = 2, 1, 1  # three of four visits in corners
    assert corner_share(visits, wall=1).tolist() == [0.75, 0.0]  # no visits at all reads as 0
    with pytest.raises(ValueError, match="no four inner corners"):
        corner_cells((3, 3), wall=1)
