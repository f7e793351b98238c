"""Shared helpers for the dataset-generation tests: a tiny config and a whole-tree digest."""
from __future__ import annotations

import hashlib
from pathlib import Path

import yaml

TINY = {
    "name": "tiny",
    "mixture": [{"scenario": "clear_day_quad", "weight": 2}, {"scenario": "bird_confuser"}],
    "randomise": {"target_kinds": ["quadcopter", "hexacopter"], "range_m": [80, 160],
                  "trajectory_kinds": ["hover", "flyby"],
                  "distractors": [1, 2], "sun_elevation_deg": [15, 50], "air_temperature_k": [280, 300],
                  "part_temperature_offset_k": [-2, 2], "camera_yaw_deg": [-0.2, 0.2]},
    "sequences": 4, "frames": 3, "image_size": [96, 80], "spp": 1,
    "splits": {"train": 0.5, "val": 0.25, "test": 0.25, "seed": 0},
}


def write_tiny(folder: Path, **updates) -> Path:
    path = Path(folder) / "tiny.yaml"
    path.write_text(yaml.safe_dump({**TINY, **updates}))
    return path


def tree_digest(folder: Path) -> dict[str, str]:
    """sha256 of every file (hidden ones included) by relative path."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(Path(folder).rglob("*")) if p.is_file()}
