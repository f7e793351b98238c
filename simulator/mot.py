"""MM-UAV (MOT-style) layout from a native sequence.

``<out>/<NNNN>/rgb_frame/0001.jpg``, ``ir_frame/0001.jpg`` (4 digits, 1-based), ``gt_rgb/gt.txt``
and ``gt_ir/gt.txt`` with rows ``frame,id,left,top,w,h,consider,class,visibility`` (drones:
``...,1,0,1``), ``seqinfo-rgb.ini`` and ``seqinfo-ir.ini``. Distractors (birds, aircraft), when
kept, are rows with consider 0 and class 1 (bird) / 2 (aircraft), which MM-UAV tools ignore.
"""
from __future__ import annotations

from pathlib import Path

from simulator.native import atomic_folder, frame_name, load_labels, load_meta, read_image, write_jpeg

MOT_CLASS_IDS = {"drone": 0, "bird": 1, "aircraft": 2}
MODALITIES = {"rgb": ("rgb_frame", "gt_rgb", "seqinfo-rgb.ini"), "thermal": ("ir_frame", "gt_ir", "seqinfo-ir.ini")}


def mot_frame_name(index0: int) -> str:
    return f"{index0 + 1:04d}.jpg"


def gt_rows(labels: dict, camera: str, *, annotate_every: int = 1, distractors: bool = False) -> list[str]:
    """gt.txt lines (sorted by frame, then id) for frames f with (f - 1) % annotate_every == 0."""
    rows = []
    for frame in labels["frames"]:
        number = frame["index"] + 1
        if (number - 1) % annotate_every:
            continue
        for rec in sorted(frame[camera], key=lambda r: r["id"]):
            if not rec["exist"]:
                continue
            is_drone = rec["class"] == "drone"
            if not is_drone and not distractors:
                continue
            x, y, w, h = rec["box"]
            rows.append(f"{number},{rec['id']},{x},{y},{w},{h},{1 if is_drone else 0},{MOT_CLASS_IDS[rec['class']]},1")
    return rows


def seqinfo_text(name: str, im_dir: str, frame_rate_hz: float, length: int, width: int, height: int) -> str:
    return (f"[Sequence]\nname={name}\nimDir={im_dir}\nframeRate={int(round(frame_rate_hz))}\nseqLength={length}\n"
            f"imWidth={width}\nimHeight={height}\nimExt=.jpg\n")


def export_mmuav(sequence_dir: Path, out_dir: Path, name: str, *, annotate_every: int = 1,
                 distractors: bool = False) -> Path:
    """Write ``<out_dir>/<name>/`` in the MM-UAV layout (atomically); returns it."""
    if annotate_every < 1:
        raise ValueError(f"annotate_every must be >= 1, got {annotate_every}")
    sequence_dir = Path(sequence_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    n = meta["n_frames"]
    final = Path(out_dir) / name
    with atomic_folder(final) as tmp:
        for camera, (im_dir, gt_dir, ini) in MODALITIES.items():
            source = "rgb" if camera == "rgb" else "thermal_agc"
            for i in range(n):
                write_jpeg(tmp / im_dir / mot_frame_name(i), read_image(sequence_dir / source / frame_name(i, "png")))
            rows = gt_rows(labels, camera, annotate_every=annotate_every, distractors=distractors)
            (tmp / gt_dir).mkdir(parents=True, exist_ok=True)
            (tmp / gt_dir / "gt.txt").write_text("".join(r + "\n" for r in rows))
            cam = meta["cameras"][camera]
            (tmp / ini).write_text(seqinfo_text(name, im_dir, meta["frame_rate_hz"], n, cam["width_px"], cam["height_px"]))
    return final
