"""Tiny regression datasets for users' test suites (pytest plugin ``simulator.dataset.pytest_plugin`` and
``evids fixture NAME --out DIR``), cached on disk by content key.

A fixture is rendered from a scene preset and a seed at a fixed tiny size (FIXTURE_SPEC); its
bytes are stable for a given package version (evids, Mitsuba, NumPy, OpenCV, librosa: the key
includes them), so golden values can be pinned against it.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path
from typing import Any, Callable

import numpy as np

FIXTURE_SPEC: dict[str, Any] = {"frames": 4, "image_size": [96, 80], "spp": 1, "trident_clip_s": 1.0,
                                "trident_render_px": 32, "trident_rendered_frames": 4}
FIXTURES: dict[str, str] = {
    "native": "a one-sequence native dataset (manifest.json + sequences/seq000001/)",
    "antiuav": "an Anti-UAV thermal sequence (000001.jpg.., IR_label.json) with its <name>_visible sibling",
    "antiuav_rgbt": "an Anti-UAV RGB-T sequence (visible/, infrared/, visible.json, infrared.json)",
    "mmuav": "an MM-UAV sequence pair (0001/{rgb_frame,ir_frame}, gt_rgb/gt.txt, gt_ir/gt.txt, seqinfo-*.ini)",
    "coco": "a COCO-video file in the MM-UAV baseline style (returns annotations/train_rgb.json; images beside)",
    "trident": "a TRIDENT-layout folder with one 1 s clip (audio/, video/, rf/, labels/, manifest.json)",
}
_EXPORT_OF = {"antiuav": "antiuav", "antiuav_rgbt": "antiuav_rgbt", "mmuav": "mot", "coco": "coco"}


def fixture_key(name: str, preset: str, seed: int) -> str:
    """Content key: package versions + fixture name + preset + seed + the fixed tiny spec."""
    from simulator.files import package_versions

    versions = package_versions()
    for pkg in ("librosa", "soundfile", "scipy"):
        try:
            from importlib import metadata

            versions[pkg] = metadata.version(pkg)
        except Exception:  # a missing optional package is part of the key as "absent"
            versions[pkg] = "absent"
    blob = json.dumps({"name": name, "preset": preset, "seed": int(seed), "spec": FIXTURE_SPEC, "versions": versions},
                      sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()


def fixture_target(root: Path, name: str) -> Path:
    """The path a fixture of ``name`` returns inside its built folder ``root``."""
    if name == "native":
        return root
    if name == "antiuav":
        return root / "antiuav" / "train" / "seq000001"
    if name == "antiuav_rgbt":
        return root / "antiuav_rgbt" / "train" / "seq000001"
    if name == "mmuav":
        return root / "mot" / "train" / "0001"
    if name == "coco":
        return root / "coco" / "annotations" / "train_rgb.json"
    return root / "trident"


def _tiny_frames(scenario, seed: int, n_frames: int, width_px: int, height_px: int, layout=None) -> np.ndarray:
    """A few frames rendered at a tiny size, upscaled (nearest) and held over the clip."""
    import cv2

    from simulator.dataset.sequence import render_rgb_video

    px = FIXTURE_SPEC["trident_render_px"]
    small = render_rgb_video(scenario, seed, min(n_frames, FIXTURE_SPEC["trident_rendered_frames"]), px, px,
                             layout=layout)
    pick = (np.arange(n_frames) * len(small)) // n_frames
    return np.stack([cv2.resize(small[k], (width_px, height_px), interpolation=cv2.INTER_NEAREST) for k in pick])


def build_fixture(name: str, out_dir: str | Path, *, preset: str = "clear_day_quad", seed: int = 0) -> Path:
    """Build fixture ``name`` into ``out_dir`` (created; must not exist or be empty); returns the
    fixture's path (see :func:`fixture_target`)."""
    from scenes.errors import UserInputError

    if name not in FIXTURES:
        raise UserInputError(f"unknown fixture {name!r}; valid: {', '.join(FIXTURES)}")
    out = Path(out_dir)
    if out.exists() and any(out.iterdir()):
        raise UserInputError(f"fixture output folder {str(out)!r} is not empty")
    if name == "trident":
        from simulator.dataset.trident import generate_trident

        config = {"name": f"fixture_{preset}", "clip_duration_s": FIXTURE_SPEC["trident_clip_s"], "save_iq": False,
                  "clips": [{"scenario": preset}]}
        out.mkdir(parents=True, exist_ok=True)
        generate_trident(config, out / "trident", seed, progress=False, render_frames=_tiny_frames)
        return fixture_target(out, name)
    from simulator.dataset.generate import generate_dataset

    # the preset's sky, air and other targets; its primary drone 120 m away, tracked, ~12 px wide
    randomise = {"range_m": [120, 120], "trajectory_kinds": ["flyby"], "speed_mps": [6, 6], "target_px": [12, 12],
                 "elevation_deg": [8, 8]}
    config = {"name": f"fixture_{preset}", "mixture": [{"scenario": preset}], "randomise": randomise, "sequences": 1,
              "frames": FIXTURE_SPEC["frames"], "image_size": FIXTURE_SPEC["image_size"], "spp": FIXTURE_SPEC["spp"],
              "splits": {"train": 1.0, "val": 0.0, "test": 0.0}}
    formats = ("native",) + ((_EXPORT_OF[name],) if name in _EXPORT_OF else ())
    generate_dataset(config, out, seed, formats=formats, progress=False)
    return fixture_target(out, name)


def cached_fixture(name: str, cache_dir: str | Path, *, preset: str = "clear_day_quad", seed: int = 0,
                   build: Callable[..., Path] = build_fixture) -> Path:
    """``build_fixture`` once per content key under ``cache_dir``; later calls (and concurrent
    pytest-xdist workers) reuse the folder. Built in a temporary folder and renamed into place."""
    key = fixture_key(name, preset, seed)
    final = Path(cache_dir) / f"{name}-{preset}-{seed}-{key[:16]}"
    if (final / ".complete").is_file():
        return fixture_target(final, name)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = final.parent / f".tmp-{final.name}-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        build(name, tmp, preset=preset, seed=seed)
        (tmp / ".complete").write_text(key + "\n")
        try:
            tmp.rename(final)
        except OSError:
            if not (final / ".complete").is_file():
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return fixture_target(final, name)
