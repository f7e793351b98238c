"""Scene statistics of real and synthetic frames (not a speed benchmark): background level, row
gradient, ground in view, target absent, target position, on the Svanström benchmark's
CALIBRATION half (odd clip numbers) only, plus PNG contact sheets.

    python benchmarks/scene_realism.py --real <benchmark folder or git mirror> --out <dir> [--frames 8]
    python benchmarks/scene_realism.py --synthetic <native dataset> --out <dir>

The dataset path comes from --real or EVIDS_SVANSTROM. Results: <out>/scene_stats.json and
<out>/contact_<sensor>.png. docs/SIM2REAL_VISUAL_SCENE.md quotes the figures.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

TEXTURE_RATIO = 2.0      # ground in view: bottom-band texture > this x top-band texture ...
TEXTURE_FLOOR = 1.0      # ... and > this many grey levels of mean |horizontal difference|
BANDS = 8


def luma(frame: np.ndarray) -> np.ndarray:
    if frame.ndim == 2:
        return frame.astype(np.float64)
    return frame[..., :3].astype(np.float64) @ np.array([0.299, 0.587, 0.114])


def frame_stats(frame: np.ndarray) -> dict:
    """Per-frame scene statistics of an 8-bit frame (grey or RGB)."""
    g = luma(frame)
    h = g.shape[0]
    rows = g.mean(axis=1)
    y = (np.arange(h) + 0.5) / h
    slope = float(np.polyfit(y, rows, 1)[0])    # grey levels from top to bottom of the frame
    texture = np.abs(np.diff(g, axis=1)).mean(axis=1)
    bands = np.array([b.mean() for b in np.array_split(texture, BANDS)])
    threshold = max(TEXTURE_FLOOR, TEXTURE_RATIO * bands[0])
    ground = bool(bands[-1] > threshold)
    horizon = None
    if ground:   # the highest row below which the texture (mean over h/16 rows) stays above the threshold
        k = max(1, h // 16)
        run = np.convolve(texture, np.ones(k) / k, mode="valid")
        below = run > threshold
        r = len(below) - 1
        while r >= 0 and below[r]:
            r -= 1
        horizon = (r + 1 + k / 2) / h
    return {"median": float(np.median(g)), "row_gradient": slope, "ground": ground, "horizon_y": horizon,
            "texture_top": float(bands[0]), "texture_bottom": float(bands[-1])}


def summarise(values: list[float]) -> dict:
    a = np.asarray(values, dtype=np.float64)
    if a.size == 0:
        return {"n": 0}
    q = np.percentile(a, [25, 50, 75])
    return {"n": int(a.size), "q25": round(float(q[0]), 3), "median": round(float(q[1]), 3),
            "q75": round(float(q[2]), 3)}


def real_stats(root: str, sensor: str, frames_per_clip: int, sheet: Path | None) -> dict:
    from simulator.formats.svanstrom import open_benchmark
    from simulator.formats.validation import FormatError

    bench = open_benchmark(root)
    clips = bench.clips(sensor, half="calibration")
    assert all(c.number % 2 == 1 for c in clips)
    per_frame, absent, centres, sheet_frames, above = [], [], [], [], []
    by_class: dict[str, dict] = {}
    skipped = []
    for clip in clips:
        try:
            n = bench.video_frame_count(clip)
            labels = bench.aligned_labels(clip, n)
        except FormatError as err:   # a missing video or labels that do not fit it: left out, named
            skipped.append(f"{clip.media}: {err}")
            continue
        absent.append(sum(b is None for b in labels) / max(len(labels), 1))
        idx = np.linspace(0, n - 1, frames_per_clip).round().astype(int)
        for i, frame in bench.frames(clip, idx):
            s = frame_stats(frame)
            s["cls"] = clip.cls
            per_frame.append(s)
            box = labels[i]
            if box is not None:
                x, yb, w, hb = box
                centres.append(((x + w / 2) / frame.shape[1], (yb + hb / 2) / frame.shape[0]))
                if s["horizon_y"] is not None:
                    above.append(s["horizon_y"] - centres[-1][1])
            if sheet is not None and i == idx[len(idx) // 2] and len(sheet_frames) < 48:
                sheet_frames.append(frame if frame.ndim == 3 else np.repeat(frame[..., None], 3, -1))
        c = by_class.setdefault(clip.cls, {"absent": []})
        c["absent"].append(absent[-1])
    bench.close()
    if sheet is not None:
        write_sheet(sheet_frames, sheet)
    cx, cy = (np.array(centres)[:, 0], np.array(centres)[:, 1]) if centres else ([], [])
    return {
        "clips": len(clips) - len(skipped), "skipped": skipped, "frames": len(per_frame),
        "median_level": summarise([s["median"] for s in per_frame]),
        "row_gradient": summarise([s["row_gradient"] for s in per_frame]),
        "ground_fraction": round(float(np.mean([s["ground"] for s in per_frame])), 3),
        "ground_fraction_by_class": {k: round(float(np.mean([s["ground"] for s in per_frame if s["cls"] == k])), 3)
                                     for k in sorted({s["cls"] for s in per_frame})},
        "absent_fraction_per_clip": summarise(absent),
        "absent_fraction_all": round(float(np.mean(absent)), 4),
        "absent_by_class": {k: summarise(v["absent"]) for k, v in sorted(by_class.items())},
        "target_centre_x": summarise(list(cx)), "target_centre_y": summarise(list(cy)),
        "horizon_y": summarise([s["horizon_y"] for s in per_frame if s["horizon_y"] is not None]),
        "horizon_minus_target_y": summarise(above),
    }


def synthetic_stats(dataset: Path, sensor: str, sheet: Path | None) -> dict:
    """The same statistics on a native dataset (evids generate): thermal_agc (IR) or rgb (visible)
    8-bit frames as the camera model recorded them, labels of the primary target (id 1)."""
    from PIL import Image

    folder, camera = ("thermal_agc", "thermal") if sensor == "ir" else ("rgb", "rgb")
    per_frame, absent, centres, above, sheet_frames = [], [], [], [], []
    for seq in sorted((dataset / "sequences").iterdir()):
        labels = json.loads((seq / "labels.json").read_text())["frames"]
        files = sorted((seq / folder).glob("*.png"))
        flags = []
        for f, lab in zip(files, labels):
            frame = np.asarray(Image.open(f))
            st = frame_stats(frame)
            per_frame.append(st)
            rec = next((r for r in lab[camera] if r["id"] == 1), None)
            present = rec is not None and rec["exist"] == 1
            flags.append(not present)
            if present:
                x, y, w, h = rec["box"]
                centres.append(((x + w / 2) / frame.shape[1], (y + h / 2) / frame.shape[0]))
                if st["horizon_y"] is not None:
                    above.append(st["horizon_y"] - centres[-1][1])
            if sheet is not None and f == files[len(files) // 2] and len(sheet_frames) < 48:
                sheet_frames.append(frame if frame.ndim == 3 else np.repeat(frame[..., None], 3, -1))
        absent.append(float(np.mean(flags)))
    if sheet is not None:
        write_sheet(sheet_frames, sheet)
    cx, cy = (np.array(centres)[:, 0], np.array(centres)[:, 1]) if centres else ([], [])
    return {
        "sequences": len(absent), "frames": len(per_frame),
        "median_level": summarise([s["median"] for s in per_frame]),
        "row_gradient": summarise([s["row_gradient"] for s in per_frame]),
        "ground_fraction": round(float(np.mean([s["ground"] for s in per_frame])), 3),
        "absent_fraction_per_clip": summarise(absent), "absent_fraction_all": round(float(np.mean(absent)), 4),
        "target_centre_x": summarise(list(cx)), "target_centre_y": summarise(list(cy)),
        "horizon_y": summarise([s["horizon_y"] for s in per_frame if s["horizon_y"] is not None]),
        "horizon_minus_target_y": summarise(above),
    }


def write_sheet(frames: list[np.ndarray], path: Path, cols: int = 8, width: int = 160) -> None:
    from PIL import Image

    tiles = []
    for f in frames:
        im = Image.fromarray(np.asarray(f, np.uint8))
        tiles.append(np.asarray(im.resize((width, int(round(width * im.height / im.width))))))
    h = max(t.shape[0] for t in tiles)
    rows = []
    for r in range(0, len(tiles), cols):
        row = tiles[r:r + cols] + [np.zeros_like(tiles[0])] * (cols - len(tiles[r:r + cols]))
        rows.append(np.hstack([np.pad(t, ((0, h - t.shape[0]), (0, 0), (0, 0))) for t in row]))
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.vstack(rows)).save(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--real", default=os.environ.get("EVIDS_SVANSTROM"))
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--frames", type=int, default=8, help="frames sampled per clip")
    ap.add_argument("--synthetic", type=Path, help="a native dataset (evids generate) to measure the same way")
    args = ap.parse_args()
    if args.synthetic is not None:
        out = {s: synthetic_stats(args.synthetic, s, args.out / f"contact_synthetic_{s}.png")
               for s in ("ir", "visible")}
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "scene_stats_synthetic.json").write_text(json.dumps(out, indent=1))
        print(json.dumps(out, indent=1))
        return
    if not args.real:
        ap.error("give --real or set EVIDS_SVANSTROM")
    out = {s: real_stats(args.real, s, args.frames, args.out / f"contact_real_{s}.png") for s in ("ir", "visible")}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "scene_stats.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
