"""Anti-UAV 410/600 layout from a native sequence: thermal `000001.jpg`... + `IR_label.json`, and the
RGB camera in a sibling folder `<name>_visible/` with `visible.json` (same fields)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from simulator.encode import agc_8bit
from simulator.native import atomic_folder, frame_name, load_labels, load_meta, load_rgb, load_thermal_kelvin, write_jpeg, write_json


def primary_target_id(labels: dict) -> int:
    """Anti-UAV is single-object: the first drone-class target (else the first target)."""
    for obj in labels["objects"]:
        if obj["class"] == "drone":
            return obj["id"]
    return labels["objects"][0]["id"]


def _label_file(labels: dict, camera: str, target_id: int) -> dict:
    exist, rects = [], []
    for frame in labels["frames"]:
        rec = next(r for r in frame[camera] if r["id"] == target_id)
        exist.append(int(rec["exist"]))
        rects.append(list(rec["box"]) if rec["exist"] else [])
    return {"exist": exist, "gt_rect": rects}


def export_antiuav(sequence_dir: Path, out_dir: Path, name: str | None = None) -> tuple[Path, Path]:
    """Write `<out>/<name>/` (thermal, IR_label.json) and `<out>/<name>_visible/` (RGB, visible.json)."""
    sequence_dir, out_dir = Path(sequence_dir), Path(out_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    name = name or meta["scenario_name"]
    target_id = primary_target_id(labels)
    n = meta["n_frames"]
    ir_dir, vis_dir = out_dir / name, out_dir / f"{name}_visible"
    with atomic_folder(ir_dir) as tmp:
        for i in range(n):
            image, _ = agc_8bit(load_thermal_kelvin(sequence_dir, i))
            write_jpeg(tmp / frame_name(i, "jpg"), image)
        write_json(tmp / "IR_label.json", _label_file(labels, "thermal", target_id))
    with atomic_folder(vis_dir) as tmp:
        for i in range(n):
            write_jpeg(tmp / frame_name(i, "jpg"), load_rgb(sequence_dir, i))
        write_json(tmp / "visible.json", _label_file(labels, "rgb", target_id))
    return ir_dir, vis_dir


def read_antiuav_labels(path: Path) -> tuple[np.ndarray, list[list[float] | None]]:
    """Read IR_label.json / visible.json: exist flags and boxes (None when absent; accepts [] and [0])."""
    import json

    data = json.loads(Path(path).read_text())
    exist = np.asarray(data["exist"], dtype=np.int64)
    rects = [list(map(float, r)) if isinstance(r, list) and len(r) == 4 else None for r in data["gt_rect"]]
    if len(rects) != len(exist):
        raise ValueError(f"{path}: {len(exist)} exist flags but {len(rects)} gt_rect entries")
    return exist, rects


def export_antiuav_rgbt(sequence_dir: Path, out_dir: Path, name: str | None = None) -> Path:
    """Anti-UAV (RGB-T, the 300-sequence release's layout): `<out>/<name>/visible/000001.jpg`,
    `infrared/000001.jpg`, `visible.json`, `infrared.json` (same fields as IR_label.json)."""
    sequence_dir, out_dir = Path(sequence_dir), Path(out_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    name = name or meta["scenario_name"]
    target_id = primary_target_id(labels)
    final = out_dir / name
    with atomic_folder(final) as tmp:
        for i in range(meta["n_frames"]):
            image, _ = agc_8bit(load_thermal_kelvin(sequence_dir, i))
            write_jpeg(tmp / "infrared" / frame_name(i, "jpg"), image)
            write_jpeg(tmp / "visible" / frame_name(i, "jpg"), load_rgb(sequence_dir, i))
        write_json(tmp / "infrared.json", _label_file(labels, "thermal", target_id))
        write_json(tmp / "visible.json", _label_file(labels, "rgb", target_id))
    return final
