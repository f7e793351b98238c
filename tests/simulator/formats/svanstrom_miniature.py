"""A miniature of the Svanström benchmark layout, written from the format facts (docs/FORMATS.md):
tiny H.264 mp4 clips, label files whose ``__function_workspace__`` holds the per-frame cells that
mcos-decoder reads, 16-bit stereo WAVs and the description sheet. Shared by the reader tests and
the ``evids sim2real --quick`` test; nothing here comes from the real release.

The label file is the smallest MAT-5 file that carries a groundTruth-like element tree: a MATLAB 7
"function workspace" variable (empty name, uint8) whose stream nests miMATRIX elements five deep and
holds one cell per frame at depth 5: 80 payload bytes with a length-4 double for a box, 112 bytes for
"absent" (the sizes mcos-decoder documents). MATLAB itself would not open it as a groundTruth.
"""
from __future__ import annotations

import io
import struct
import subprocess
from pathlib import Path

import numpy as np

MI_INT8, MI_UINT8, MI_INT32, MI_UINT32, MI_DOUBLE, MI_MATRIX = 1, 2, 5, 6, 9, 14


def _element(kind: int, payload: bytes) -> bytes:
    pad = (8 - len(payload) % 8) % 8
    return struct.pack("<II", kind, len(payload)) + payload + b"\0" * pad


def _cell(box: tuple[float, float, float, float] | None) -> bytes:
    flags = _element(MI_UINT32, struct.pack("<II", 6, 0))          # 16 bytes
    dims = _element(MI_INT32, struct.pack("<ii", 1, 4))             # 16 bytes
    if box is None:
        body = flags + dims + _element(MI_UINT8, bytes(72))          # 16 + 16 + 80 = 112
    else:
        body = flags + dims + _element(MI_INT8, b"") + _element(MI_DOUBLE, struct.pack("<4d", *box))  # 80
    return _element(MI_MATRIX, body)


def label_mat_bytes(boxes: list[tuple[float, float, float, float] | None]) -> bytes:
    """A MAT-5 file whose function workspace mcos-decoder decodes to ``boxes``."""
    tree = b"".join(_cell(b) for b in boxes)
    for _ in range(5):                   # depths 4 .. 0 wrap the frame cells
        tree = _element(MI_MATRIX, tree)
    workspace = b"\0" * 8 + tree          # the 8-byte preamble mcos-decoder skips
    var = (_element(MI_UINT32, struct.pack("<II", 9, 0))               # mxUINT8_CLASS
           + _element(MI_INT32, struct.pack("<ii", 1, len(workspace)))
           + _element(MI_INT8, b"")                                      # empty name: the workspace
           + _element(MI_UINT8, workspace))
    header = b"MATLAB 5.0 MAT-file, miniature written by the evids tests".ljust(116, b" ")
    header += struct.pack("<Q", 128) + struct.pack("<H", 0x0100) + b"IM"
    return header + _element(MI_MATRIX, var)


def video_bytes(frames: list[np.ndarray], fps: int = 30) -> bytes:
    """H.264 mp4 of uint8 frames (H, W) grey or (H, W, 3) RGB."""
    import av

    buf = io.BytesIO()
    with av.open(buf, "w", format="mp4") as out:
        stream = out.add_stream("libx264", rate=fps)
        stream.height, stream.width = frames[0].shape[:2]
        stream.pix_fmt = "yuv420p"
        stream.options = {"crf": "18", "preset": "ultrafast"}
        stream.thread_count = 1
        for f in frames:
            rgb = np.repeat(f[..., None], 3, axis=2) if f.ndim == 2 else f
            for packet in stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    return buf.getvalue()


def wav_bytes(x: np.ndarray, rate: int = 44_100) -> bytes:
    import scipy.io.wavfile

    buf = io.BytesIO()
    pcm = np.clip(x * 32767.0, -32768, 32767).astype(np.int16)
    scipy.io.wavfile.write(buf, rate, np.stack([pcm, pcm], axis=1))
    return buf.getvalue()


def description_bytes(rows: list[tuple[str, str, int, str, int, str | None]]) -> bytes:
    import openpyxl

    wb = openpyxl.Workbook()
    ws = wb.active
    ws.append(["SENSOR", "CLASS", "NUMBER", "DISTANCE  BIN", "INTER BIN NUMBER", "DRONE TYPE / INTERNET SOURCE"])
    for r in rows:
        ws.append(list(r))
    buf = io.BytesIO()
    wb.save(buf)
    return buf.getvalue()


def _clip_frames(rng: np.random.Generator, n: int, w: int, h: int, rgb: bool, cls: str
                 ) -> tuple[list[np.ndarray], list[tuple[float, float, float, float] | None]]:
    """A sky with a warm ground band, and a blob target moving across (absent in the last frame)."""
    size = {"DRONE": 4, "BIRD": 3, "AIRPLANE": 6, "HELICOPTER": 5}[cls]
    frames, boxes = [], []
    yy, xx = np.mgrid[0:h, 0:w]
    for i in range(n):
        img = np.full((h, w), 90.0) + rng.normal(0, 2.0, (h, w))
        img[int(h * 0.75):] += 40
        box = None
        if i < n - 1:
            cx, cy = 6 + i * (w - 12) / n, h * 0.35
            img += 60 * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * (size / 2) ** 2))
            box = (cx - size, cy - size, 2.0 * size, 2.0 * size)
        img = np.clip(img, 0, 255).astype(np.uint8)
        frames.append(np.stack([img, img, (img * 0.9).astype(np.uint8)], axis=2) if rgb else img)
        boxes.append(box)
    return frames, boxes


def write_miniature(root: Path, *, seed: int = 0, numbers: tuple[int, ...] = (1, 2, 3, 4), n_frames: int = 6,
                    ir_size: tuple[int, int] = (64, 48), visible_size: tuple[int, int] = (64, 48),
                    audio_s: float = 1.0) -> Path:
    """Write ``root/Data/...`` with every video class x ``numbers`` for IR and visible, and every
    audio class x ``numbers``; returns ``root``."""
    rng = np.random.default_rng(seed)
    data = root / "Data"
    rows = []
    for sensor, folder, prefix, (w, h) in (("IR", "Video_IR", "IR_", ir_size), ("V", "Video_V", "V_", visible_size)):
        (data / folder).mkdir(parents=True, exist_ok=True)
        for cls in ("AIRPLANE", "BIRD", "DRONE", "HELICOPTER"):
            for k in numbers:
                frames, boxes = _clip_frames(rng, n_frames, w, h, sensor == "V", cls)
                stem = f"{prefix}{cls}_{k:03d}"
                (data / folder / f"{stem}.mp4").write_bytes(video_bytes(frames))
                (data / folder / f"{stem}_LABELS.mat").write_bytes(label_mat_bytes(boxes))
                rows.append((sensor, cls, k, ("CLOSE", "MEDIUM", "DISTANT")[k % 3], k, "F450" if cls == "DRONE"
                             else None))
    (data / "Audio").mkdir(parents=True, exist_ok=True)
    t = np.arange(int(44_100 * audio_s)) / 44_100
    for cls in ("BACKGROUND", "DRONE", "HELICOPTER"):
        for k in numbers:
            noise = rng.normal(0, 0.05, t.size)
            if cls == "DRONE":
                x = noise + sum(0.05 / h_ * np.sin(2 * np.pi * 400 * h_ * t) for h_ in range(1, 6))
            elif cls == "HELICOPTER":
                x = noise * (1 + 0.8 * np.sin(2 * np.pi * 18 * t))
            else:
                x = noise * 0.5
            (data / "Audio" / f"{cls}_{k:03d}.wav").write_bytes(wav_bytes(x))
    (data / "Video_dataset_description.xlsx").write_bytes(description_bytes(rows))
    return root


def mirror_of(folder: Path, mirror: Path) -> Path:
    """A bare git mirror of ``folder`` (as `fetch` brings the real repository here)."""
    git = ["git", "-c", "user.name=evids", "-c", "user.email=evids@example.invalid", "-c", "init.defaultBranch=main"]
    subprocess.run([*git, "init", "-q", str(folder)], check=True)
    subprocess.run([*git, "-C", str(folder), "add", "-A"], check=True)
    subprocess.run([*git, "-C", str(folder), "commit", "-q", "-m", "miniature"], check=True)
    subprocess.run([*git, "clone", "-q", "--bare", str(folder), str(mirror)], check=True)
    return mirror
