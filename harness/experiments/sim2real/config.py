"""The sim-to-real protocol file (examples/sim2real_svanstrom.yaml), validated at the boundary."""
from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator

from simulator.formats.svanstrom import SENSORS, VIDEO_CLASSES, Sensor

VISUAL_SENSORS: tuple[Sensor, ...] = ("ir", "visible")
#: what a run's classifiers were tested on, by its summary's ``test_half`` (printed by the run and by the comparison)
TEST_HALF_WORDS = {"evaluation": "the real evaluation half",
                   "calibration": "the real calibration half (--tune: cross-fitted)"}
DEFAULT_CONFIG = Path(__file__).resolve().parents[3] / "examples" / "sim2real_svanstrom.yaml"


def _reject_unknown(keys, known, nouns: str, expected: str) -> None:
    """A ``ValueError`` listing the ``keys`` not in ``known`` (pydantic names the field)."""
    bad = [k for k in keys if k not in known]
    if bad:
        raise ValueError(f"unknown {nouns} {bad}; {expected}")


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SyntheticClass(_Model):
    """How one real class is generated: a generation config (scenes/generation schema; scenario paths
    relative to the protocol file) and how many sequences."""

    generation: dict[str, Any]
    sequences: int = Field(ge=1, le=10_000)
    quick_sequences: int = Field(default=1, ge=1, le=100)
    sensor_generation: dict[str, dict[str, Any]] = Field(
        default_factory=dict,
        description="per visual sensor, changes to `generation` (mappings merged key by key, anything else "
                    "replaced) that give that sensor a synthetic set of its own, rendered apart with the same "
                    "seed: the benchmark's IR and visible clips of a class are separate recordings "
                    "(docs/SIM2REAL.md, \"One synthetic set per sensor\")")

    @field_validator("sensor_generation")
    @classmethod
    def _visual_sensors(cls, value: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
        _reject_unknown(value, VISUAL_SENSORS, "sensor(s)", f"expected {', '.join(VISUAL_SENSORS)}")
        return value

    def generation_for(self, sensor: str | None) -> dict[str, Any]:
        """The generation mapping of ``sensor``'s own set (``None``: the shared one), not yet validated."""
        if sensor is None or sensor not in self.sensor_generation:
            return json.loads(json.dumps(self.generation))
        changes = self.sensor_generation[sensor]
        merged = merge_mappings(self.generation, changes)
        if "name" not in changes and isinstance(merged.get("name"), str):
            merged["name"] = f"{merged['name']}_{sensor}"        # the set's own name in its manifest
        return merged

    def set_of(self, sensor: str) -> str | None:
        """Which of this class's synthetic sets ``sensor`` reads: its own (the sensor) or the shared one (None)."""
        return sensor if sensor in self.sensor_generation else None

    def sets_read_by(self, sensors: Sequence[str]) -> list[str | None]:
        """The sets ``sensors`` read: the shared one (None) if one of them reads it, then each sensor's own,
        in the given order."""
        return ([None] if any(self.set_of(s) is None for s in sensors) else []) + \
            [s for s in sensors if self.set_of(s) is not None]


def synthetic_set_folder(cls: str, own_sensor: str | None) -> str:
    """The folder under a run's ``synthetic/`` of a class's shared set (``own_sensor`` None) or of a sensor's own."""
    return cls if own_sensor is None else f"{cls}_{own_sensor}"


def merge_mappings(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """A deep copy of ``base`` with ``changes`` applied: mappings merged key by key, other values replaced."""
    out = json.loads(json.dumps(base))
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge_mappings(out[key], value)
        else:
            out[key] = json.loads(json.dumps(value))
    return out


class VisualProtocol(_Model):
    classes: dict[str, SyntheticClass] = Field(min_length=2)
    frames: int = Field(default=30, ge=2, le=10_000, description="frames per synthetic sequence")
    frames_per_real_clip: int = Field(default=12, ge=2, le=1000, description="sampled frames per real clip")
    crop_px: int = Field(default=32, ge=8, le=256)
    crop_context: float = Field(default=2.0, ge=1.0, le=8.0, description="crop side / largest box side")
    min_crop_px: int = Field(default=16, ge=4, le=256)
    detector_frames_per_clip: int = Field(default=4, ge=0, le=1000,
                                          description="whole frames kept per clip for the detector (0: no detector)")
    detector_steps: int = Field(default=3200, ge=1, le=100_000,
                                description="optimiser steps per detector (batches of 8 crops); the real-trained IR "
                                            "detector's calibration-fold AP50 is 0.35 / 0.64 / 0.65 at 400 / 1600 / "
                                            "3200 (docs/SIM2REAL.md)")
    detector_downscale: dict[str, int] = Field(
        default_factory=lambda: {"ir": 1, "visible": 2},
        description="per visual sensor, the integer factor its frames are shrunk by (area averaging) before the "
                    "detector: the backbone's ~35 px receptive field is made for 3-30 px targets, the benchmark's "
                    "visible ones are 27-118 px at 640x512 (docs/SIM2REAL.md); scores are against the recorded-size "
                    "labels")
    quick_detector_steps: int = Field(default=10, ge=1, le=10_000)
    quick_image_size: tuple[int, int] = (96, 80)
    quick_thermal_image_size: tuple[int, int] = (64, 48)
    quick_frames: int = Field(default=4, ge=2, le=100)
    workers: int = Field(default=2, ge=1, le=64)

    @field_validator("detector_downscale")
    @classmethod
    def _downscale(cls, value: dict[str, int]) -> dict[str, int]:
        _reject_unknown(value, VISUAL_SENSORS, "sensor(s)", f"expected {', '.join(VISUAL_SENSORS)}")
        low = {k: v for k, v in value.items() if not 1 <= v <= 8}
        if low:
            raise ValueError(f"factors must be 1-8, got {low}")
        return value

    @field_validator("classes")
    @classmethod
    def _known(cls, value: dict[str, SyntheticClass]) -> dict[str, SyntheticClass]:
        _reject_unknown(value, VIDEO_CLASSES, "class(es)", f"the benchmark's video classes are {list(VIDEO_CLASSES)}")
        return value


class Training(_Model):
    seeds: list[int] = Field(default_factory=lambda: [0, 1, 2], min_length=1)
    steps: int = Field(default=250, ge=1, le=1_000_000,
                       description="optimiser steps per crop classifier, the same for every condition")
    quick_steps: int = Field(default=15, ge=1, le=10_000)
    batch_size: int = Field(default=128, ge=1, le=65_536)
    learning_rate: float = Field(default=2e-3, gt=0.0, le=1.0)
    few_shot_fraction: float = Field(default=0.1, gt=0.0, le=1.0)
    bootstrap: int = Field(default=1000, ge=50, le=100_000)


class Sim2RealConfig(_Model):
    name: str = Field(min_length=1)
    description: str = ""
    seed: int = Field(default=0, ge=0)
    sensors: list[str] = Field(default_factory=lambda: ["ir", "visible", "audio"], min_length=1)
    visual: VisualProtocol
    audio: dict[str, Any] = Field(default_factory=dict)
    training: Training = Field(default_factory=Training)

    @field_validator("sensors")
    @classmethod
    def _sensors(cls, value: list[str]) -> list[str]:
        _reject_unknown(value, SENSORS, "sensor(s)", f"expected {', '.join(SENSORS)}")
        return value


def load_config(path: str | Path | None = None) -> tuple[Sim2RealConfig, Path]:
    """(config, the folder its relative paths are resolved against)."""
    from scenes.loader import load_validated

    path = Path(path) if path is not None else DEFAULT_CONFIG
    return load_validated(path, Sim2RealConfig, None, "sim2real config"), path.resolve().parent
