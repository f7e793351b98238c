"""Fixtures of the reliability tests: one tiny two-sequence native dataset, rendered once per session."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

TINY2 = {
    "name": "tiny2", "mixture": [{"scenario": "clear_day_quad"}],
    "randomise": {"range_m": [120, 120], "trajectory_kinds": ["flyby"], "speed_mps": [6, 6], "target_px": [12, 12],
                  "elevation_deg": [8, 8]},
    "sequences": 2, "frames": 3, "image_size": [64, 48], "spp": 1,
    "splits": {"train": 0.5, "val": 0.5, "test": 0.0, "seed": 0},
}


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory) -> Path:
    from simulator.dataset.generate import generate_dataset

    out = tmp_path_factory.mktemp("reliability") / "ds"
    generate_dataset(TINY2, out, 3, progress=False)
    return out


@pytest.fixture
def dataset(tiny_dataset, tmp_path) -> Path:
    """A private copy of the tiny dataset (tests may damage it)."""
    copy = tmp_path / "ds"
    shutil.copytree(tiny_dataset, copy, symlinks=True)
    return copy
