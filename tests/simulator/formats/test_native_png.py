"""The native PNG writer: lossless for every frame kind, and the row filter it declares is the one in
the file (a parameter OpenCV ignored, or read in the wrong order, would leave libpng's own choice)."""
import struct
import zlib

import numpy as np
import pytest

from simulator.formats.native import (
    PNG_FILTER_COLOUR,
    PNG_FILTER_SINGLE_CHANNEL,
    read_image,
    write_png,
)

# PNG row filter type bytes (PNG specification, section 9.2) of OpenCV's filter flags
FILTER_TYPE = {8: 0, 16: 1, 32: 2, 64: 3, 128: 4}


def _row_filters(path, row_bytes: int) -> set[int]:
    data = path.read_bytes()
    pos, idat = 8, b""
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if kind == b"IDAT":
            idat += data[pos + 8:pos + 8 + length]
        pos += 12 + length
    raw = zlib.decompress(idat)
    stride = row_bytes + 1
    assert len(raw) % stride == 0
    return {raw[i] for i in range(0, len(raw), stride)}


def _frame(kind: str) -> np.ndarray:
    rng = np.random.default_rng(3)
    yy = np.arange(48)[:, None] * np.ones((1, 64))
    if kind == "rgb":
        return np.clip(yy[..., None] * 2 + rng.normal(0, 3, (48, 64, 3)), 0, 255).astype(np.uint8)
    if kind == "counts":
        return (27000 + 10 * yy + rng.normal(0, 5, yy.shape)).astype(np.uint16)
    mask = np.zeros((48, 64), np.uint8)
    mask[10:20, 30:41] = 1
    return mask


@pytest.mark.parametrize("kind, bytes_per_pixel, filter_flag", [
    ("rgb", 3, PNG_FILTER_COLOUR), ("counts", 2, PNG_FILTER_SINGLE_CHANNEL), ("mask", 1, PNG_FILTER_SINGLE_CHANNEL)])
def test_png_is_lossless_and_uses_the_declared_row_filter(tmp_path, kind, bytes_per_pixel, filter_flag):
    image = _frame(kind)
    path = tmp_path / f"{kind}.png"
    write_png(path, image)
    back = read_image(path)
    assert back.dtype == image.dtype and np.array_equal(back, image)
    assert _row_filters(path, image.shape[1] * bytes_per_pixel) == {FILTER_TYPE[filter_flag]}
