"""Geometry and timing: boxes follow misalignment, labels follow desync / frame drop / freeze."""
from __future__ import annotations

import numpy as np
import pytest

import degradations
from degradations.crossmodal import transform_boxes


def _square_clip(T=3, H=64, W=80, box=(30, 20, 12, 10)):
    x = np.zeros((T, H, W), np.float32) + 280.0
    bx, by, bw, bh = box
    x[:, by:by + bh, bx:bx + bw] = 300.0
    return x


def _bbox(img, thr):
    ys, xs = np.nonzero(img > thr)
    return np.array([xs.min(), ys.min(), xs.max() + 1 - xs.min(), ys.max() + 1 - ys.min()], float)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_misalignment_boxes_follow_pixels(seed):
    box = (30, 20, 12, 10)
    x = _square_clip(box=box)
    boxes = np.array([box] * 3, float)
    y, info = degradations.apply("crossmodal.misalignment", x, seed=seed, severity=4,
                                 meta={"boxes": boxes, "mask": x > 290}, return_info=True)
    nb = np.asarray(info["meta"]["boxes"])
    for t in range(3):
        px = _bbox(y[t], 290.0)
        assert np.all(np.abs(px - nb[t]) <= 2.5), (px, nb[t])  # rotated box hull vs pixels
        assert np.array_equal(_bbox(info["meta"]["mask"][t].astype(float), 0.5), _bbox(y[t], 290)) or \
            np.all(np.abs(_bbox(info["meta"]["mask"][t].astype(float), 0.5) - px) <= 1.5)
    assert not np.allclose(nb[0], box)


def test_transform_boxes_pure_translation():
    m = np.array([[1, 0, 5.0], [0, 1, -3.0]])
    np.testing.assert_allclose(transform_boxes(np.array([[10, 10, 4, 6]]), m), [[15, 7, 4, 6]])


def test_desync_shifts_frames_and_labels_together():
    T = 10
    x = np.stack([np.full((8, 8, 3), t * 20, np.uint8) for t in range(T)])
    boxes = np.array([[t, 0, 2, 2] for t in range(T)], float)
    y, info = degradations.apply("crossmodal.desync", x, seed=0, dt_s=0.1, direction=1,
                                 meta={"fps": 30.0, "boxes": boxes}, return_info=True)
    shown = (y[:, 0, 0, 0] // 20).astype(int)
    np.testing.assert_array_equal(shown, np.clip(np.arange(T) - 3, 0, T - 1))
    np.testing.assert_array_equal(np.asarray(info["meta"]["boxes"])[:, 0], shown)


def test_desync_audio_in_samples():
    x = np.arange(100, dtype=np.float32)
    y = degradations.apply("crossmodal.desync", x, seed=0, dt_s=0.01, direction=-1,
                           stream="audio", meta={"sample_rate_hz": 1000})
    np.testing.assert_array_equal(y[:90], x[10:])


@pytest.mark.parametrize("name", ["video.frame_drop", "video.frame_freeze", "crossmodal.frame_rate_mismatch"])
def test_retiming_labels_follow_shown_frame(name):
    T = 20
    x = np.stack([np.full((8, 8, 3), t * 10, np.uint8) for t in range(T)])
    boxes = np.array([[t, t, 2, 2] for t in range(T)], float)
    y, info = degradations.apply(name, x, seed=1, severity=4, meta={"boxes": boxes}, return_info=True)
    shown = (y[:, 0, 0, 0] // 10).astype(int)
    assert np.any(shown != np.arange(T))
    np.testing.assert_array_equal(info["meta"]["frame_index_shown"], shown)
    np.testing.assert_array_equal(np.asarray(info["meta"]["boxes"])[:, 0], shown)


def test_dropout_flags_missing():
    y, info = degradations.apply("crossmodal.dropout", np.ones(50, np.float32), seed=0, severity=1,
                                 stream="audio", return_info=True)
    assert np.all(y == 0) and info["meta"]["missing"] is True
