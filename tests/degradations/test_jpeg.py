"""video.jpeg: RGB chroma stays in its channels (a BGR/RGB mix-up would turn red into blue) and the
error grows as the quality falls."""
import numpy as np

import degradations


def _patches() -> np.ndarray:
    frame = np.zeros((64, 96, 3), np.uint8)
    frame[:, :32, 0] = 220   # red
    frame[:, 32:64, 1] = 220  # green
    frame[:, 64:, 2] = 220   # blue
    return frame[None]


def test_jpeg_keeps_each_colour_in_its_channel():
    out = degradations.apply("video.jpeg", _patches(), seed=0, quality=90)[0]
    for col, channel in ((16, 0), (48, 1), (80, 2)):
        pixel = out[32, col].astype(int)
        assert pixel[channel] > 180
        assert all(pixel[c] < 60 for c in range(3) if c != channel)


def test_jpeg_error_grows_as_quality_falls():
    rng = np.random.default_rng(0)
    clip = np.clip(rng.normal(128, 40, (1, 64, 64, 3)), 0, 255).astype(np.uint8)
    errors = [np.mean((degradations.apply("video.jpeg", clip, seed=0, quality=q).astype(float) - clip) ** 2)
              for q in (95, 50, 10)]
    assert errors[0] < errors[1] < errors[2]
    same = degradations.apply("video.jpeg", clip, seed=1, quality=50)
    assert np.array_equal(same, degradations.apply("video.jpeg", clip, seed=1, quality=50))


def test_trimmed_motion_blur_kernel_filters_exactly_like_the_full_kernel():
    import cv2

    from degradations.video import line_kernel, trim_kernel

    rng = np.random.default_rng(3)
    frame = (rng.random((40, 50, 3)) * 255).astype(np.uint8)
    for angle in (0.0, 17.0, 45.0, 100.0, 170.0):
        full = line_kernel(15, angle)
        small = trim_kernel(full)
        assert small.shape[0] % 2 == 1 and small.shape[1] % 2 == 1 and small.size <= full.size
        assert np.isclose(small.sum(), 1.0)
        a = cv2.filter2D(frame, -1, full, borderType=cv2.BORDER_REFLECT)
        b = cv2.filter2D(frame, -1, small, borderType=cv2.BORDER_REFLECT)
        assert np.abs(a.astype(int) - b).max() <= 1
