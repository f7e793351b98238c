"""TRIDENT-style tri-modal clips: 10 s of RGB video + audio + RF on one timeline, 40 segments of 0.25 s.

Per clip: 280 video frames at 28 fps (112x112), a 44.1 kHz mono WAV, one RF I/Q capture and one
RF spectrogram per segment, an MFCC 1x40x40 per audio segment, and per-segment ground truth
(class and per-modality observability). :func:`generate_trident` writes a dataset in the TRIDENT
folder layout (``audio/``, ``video/``, ``rf/`` roots, each ``{Drone,Background}/<scenario>/``),
plus ``rf_iq/`` (complex64 I/Q), ``labels/`` (ground truth JSON) and ``manifest.json``, through the
dataset driver shared with the native kind (simulator.dataset.driver: lock, resume, per-clip
hashes in the manifest, ``evids verify``).

MFCC: librosa, per 0.25 s segment (11 025 samples at 44.1 kHz) with n_fft = 1024 (23 ms),
hop_length = 282 (= 11025 // 39), centred frames -> 1 + 11025 // 282 = 40 frames; 128 mel bands,
40 coefficients; log-power floor at 80 dB below each segment's own maximum (segments are
independent). The input is the WAV sample value: the recorded samples (``TridentConfig.recorder``,
simulator.sensors.microphone), or pressure / full_scale_pa with the recorder disabled.
"""
from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from scenes.kinds import DRONE_KINDS
from scenes.loader import GENERATION_DIR
from scenes.sampling import chance, drone_kind, log_uniform, sign, target_size, uniform
from scenes.schema import Scenario
from simulator.dataset.driver import Unit, VerifyReport
from simulator.formats.trident import (
    FRAMES_PER_SEGMENT,
    LABELS,
    MFCC_N_FFT,
    MFCC_N_MELS,
    MFCC_N_MFCC,
    MFCC_TOP_DB,
    SEGMENT_S,
    VIDEO_FPS,
    VIDEO_PX,
    SegmentTruth,
    TridentClip,
    clip_files,
    mfcc_hop_length,
    mfcc_segments,
    write_clip,
)
from simulator.jobs import JobError, Start, iter_jobs
from simulator.physics.acoustics.ambience import Ambience, AmbienceDistribution, draw_ambience
from simulator.physics.acoustics.levels import AUDIO_SAMPLE_RATE_HZ, band_level_db
from simulator.physics.acoustics.mix import synthesize_audio
from simulator.physics.rf import RFConfig, spectrogram_image, synthesize_rf
from simulator.seeding import rng_for
from simulator.sensors.microphone import RecorderConfig, record

AUDIBLE_BAND_HZ = (200.0, 8000.0)     # band in which drone and background levels are compared
VISIBLE_MIN_PX = 1.0                  # projected size below which a target is not "in view"
_TRIDENT_SEED_TAG = 6                  # separates clip seeds from other users of the "generation" stream
_RECORDER_INDEX = 0                    # recorder draws: rng_for(clip seed, "acoustics", 0, RECORDER_STREAM_INDEX)

FramesFn = Callable[..., np.ndarray]  # (scenario, seed, n_frames, width_px, height_px[, layout=Scenario])



# --------------------------------------------------------------------------------------------
# Configuration (YAML boundary)
# --------------------------------------------------------------------------------------------

class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ClipSpec(_Model):
    """A group of clips from one scenario (a preset name or an inline scenario mapping)."""

    scenario: str | dict[str, Any]
    group: str | None = Field(default=None, description="the <scenario> folder name; default the scenario name")
    count: int = Field(default=1, ge=1, le=1000)
    rf_silent: bool = Field(default=False, description="autonomous flight: drone radios off")
    ambience: Ambience = Field(default_factory=Ambience)

    @model_validator(mode="after")
    def _group_name(self) -> ClipSpec:
        name = self.group or (self.scenario if isinstance(self.scenario, str) else None)
        if name is not None and (not name or "/" in name or name.startswith(".")):
            raise ValueError(f"group must be a plain folder name, got {name!r}")
        return self


Span = tuple[float, float]
# TRIDENT scenes' ambience (the values of the scene distribution before the one AmbienceDistribution):
# wind and three optional beds; residual, rustle and distant aircraft off (probability 0: no draws)
TRIDENT_AMBIENCE = AmbienceDistribution(
    wind_db=(32.0, 50.0), gust_depth=(0.2, 0.9), traffic_probability=0.4, traffic_db=(36.0, 52.0),
    rain_probability=0.15, rain_db=(38.0, 52.0), birdsong_probability=0.4, birdsong_db=(32.0, 48.0),
    residual_probability=0.0, rustle_probability=0.0, aircraft_probability=0.0)
_LEGACY_AMBIENCE_KEYS = ("wind_db", "traffic_probability", "traffic_db", "rain_probability", "rain_db",
                         "birdsong_probability", "birdsong_db")


class SceneDistribution(_Model):
    """Scene conditions drawn from ONE distribution shared by both classes (no class shortcut).

    Scene j draws sky, sun, atmosphere, ambience beds, confusers (birds, airliner), RF interferers
    (Wi-Fi, Bluetooth) and a drone (kind, size, range, apparent size in the 112 px frame, path);
    with ``twins`` the generator writes the drone-present clip AND its drone-absent twin with the
    same seeds, so the two differ only in the drone's own signatures (pixels, rotor sound, links).
    The drone is the LAST target, so every other source keeps its random-stream index.
    Scenes are assigned to splits here (the split unit is the scene: both twins share a split).
    """

    n_scenes: int = Field(ge=3, le=5000)
    twins: bool = True
    n_test_scenes: int = Field(default=1, ge=1)
    n_val_scenes: int = Field(default=1, ge=1)
    split_seed: int = Field(default=0, ge=0)
    drone_kinds: list[Literal["quadcopter", "hexacopter", "fixed_wing"]] = Field(
        default=["quadcopter", "hexacopter", "fixed_wing"], min_length=1)
    drone_px: Span = Field(default=(3.0, 30.0), description="apparent drone size in the frame (px), log-uniform")
    range_m: Span = Field(default=(60.0, 400.0), description="drone range, log-uniform")
    elevation_deg: Span = (4.0, 35.0)
    path_fraction: Span = Field(default=(0.05, 0.45), description="path length / frame width")
    rf_silent_probability: float = Field(default=0.2, ge=0.0, le=1.0)
    sun_elevation_deg: Span = (8.0, 70.0)
    turbidity: Span = (2.0, 7.0)
    cloud_probability: float = Field(default=0.4, ge=0.0, le=1.0)
    cloud_coverage: Span = (0.15, 0.7)
    air_temperature_k: Span = (273.0, 305.0)
    relative_humidity: Span = (0.25, 0.95)
    visibility_m: Span = (4000.0, 40000.0)
    ambience: AmbienceDistribution = Field(default_factory=lambda: TRIDENT_AMBIENCE, description=(
        "ambient beds per scene (simulator.physics.acoustics.ambience.AmbienceDistribution)"))
    max_birds: int = Field(default=2, ge=0, le=6)
    airliner_probability: float = Field(default=0.35, ge=0.0, le=1.0)
    wifi_probability: float = Field(default=0.6, ge=0.0, le=1.0)
    wifi_rx_dbm: Span = (-80.0, -58.0)
    bluetooth_probability: float = Field(default=0.5, ge=0.0, le=1.0)
    bluetooth_rx_dbm: Span = (-84.0, -64.0)

    @model_validator(mode="before")
    @classmethod
    def _ambience_defaults(cls, data: Any) -> Any:
        """An ``ambience`` mapping is completed from TRIDENT_AMBIENCE (not from the sim2real defaults of
        AmbienceDistribution); the flat keys of older presets (wind_db, traffic_db, ...) are accepted."""
        if not isinstance(data, dict):
            return data
        flat = {k: data[k] for k in _LEGACY_AMBIENCE_KEYS if k in data}
        given = data.get("ambience")
        if flat and given is not None:
            raise ValueError("give the ambience spans either flat (older presets) or under ambience, not both")
        if isinstance(given, dict) or flat:
            data = {k: v for k, v in data.items() if k not in _LEGACY_AMBIENCE_KEYS}
            data["ambience"] = {**TRIDENT_AMBIENCE.model_dump(), **(given or {}), **flat}
        return data

    @model_validator(mode="after")
    def _splits(self) -> SceneDistribution:
        if self.n_test_scenes + self.n_val_scenes >= self.n_scenes:
            raise ValueError(f"n_test_scenes + n_val_scenes ({self.n_test_scenes} + {self.n_val_scenes}) must leave "
                             f"at least one of the {self.n_scenes} scenes for training (splits are scene-disjoint)")
        for name, v in self.model_dump().items():
            if isinstance(v, tuple) and len(v) == 2 and v[0] > v[1]:
                raise ValueError(f"{name}: low {v[0]} exceeds high {v[1]}")
        return self


class TridentConfig(_Model):
    """A TRIDENT-style generation preset (scenes/generation/*.yaml): ``clips`` (listed scenarios)
    and/or ``scenes`` (scene-balanced drawn scenes with counterfactual twins)."""

    name: str = Field(min_length=1)
    description: str = ""
    clip_duration_s: float = Field(default=10.0, gt=0.0, le=600.0)
    video_fps: int = Field(default=VIDEO_FPS, ge=1, le=240)
    frames_per_segment: int = Field(default=FRAMES_PER_SEGMENT, ge=1)
    video_px: int = Field(default=VIDEO_PX, ge=16, le=1024)
    full_scale_pa: float = Field(default=0.1, gt=0.0, description=(
        "the pressure that reaches WAV 1.0 at 0 dB recorder input gain (0.1 Pa = 74 dB SPL)"))
    recorder: RecorderConfig = Field(default_factory=RecorderConfig, description=(
        "the recording chain (simulator.sensors.microphone); enabled: false writes pressure / full_scale_pa"))
    save_iq: bool = True
    jpeg_quality: int = Field(default=95, ge=10, le=100)
    rf: RFConfig = Field(default_factory=RFConfig)
    video_render_stride: int = Field(default=1, ge=1, le=28, description=(
        "render every k-th video frame and hold it k frames (1 = every frame); a budget knob"))
    clips: list[ClipSpec] = Field(default_factory=list)
    scenes: SceneDistribution | None = None

    @model_validator(mode="after")
    def _segments(self) -> TridentConfig:
        if not self.clips and self.scenes is None:
            raise ValueError("give clips (listed scenarios) or scenes (a scene distribution), or both")
        if self.frames_per_segment % self.video_render_stride:
            raise ValueError(f"video_render_stride ({self.video_render_stride}) must divide frames_per_segment "
                             f"({self.frames_per_segment})")
        n_seg = self.clip_duration_s / SEGMENT_S
        if abs(n_seg - round(n_seg)) > 1e-9:
            raise ValueError(f"clip_duration_s must be a multiple of {SEGMENT_S} s, got {self.clip_duration_s}")
        if abs(self.video_fps * SEGMENT_S - self.frames_per_segment) > 1e-9:
            raise ValueError(f"frames_per_segment ({self.frames_per_segment}) must equal video_fps x {SEGMENT_S} s")
        return self

    @property
    def n_segments(self) -> int:
        return int(round(self.clip_duration_s / SEGMENT_S))


def load_trident_config(config_or_name: str | Path | dict | TridentConfig) -> TridentConfig:
    """A config object, a mapping, a YAML path, or a preset name in scenes/generation/."""
    from scenes.loader import load_validated

    if isinstance(config_or_name, TridentConfig):
        return config_or_name
    return load_validated(config_or_name, TridentConfig, GENERATION_DIR, "trident generation config")


def resolve_scenario(spec: ClipSpec, source: str = "<clip>") -> Scenario:
    from scenes.loader import load_scenario, scenario_from_dict

    if isinstance(spec.scenario, str):
        return load_scenario(spec.scenario)
    return scenario_from_dict(spec.scenario, source=source)


def clip_scenario(scenario: Scenario, config: TridentConfig) -> Scenario:
    """The scenario re-timed to the clip (duration, 28 fps) with the RGB camera at the clip size."""
    data = scenario.model_dump(mode="python")
    data["duration_s"] = config.clip_duration_s
    data["frame_rate_hz"] = float(config.video_fps)
    data["camera_rig"]["rgb"]["width_px"] = config.video_px
    data["camera_rig"]["rgb"]["height_px"] = config.video_px
    return Scenario.model_validate(data)


def clip_label(scenario: Scenario) -> str:
    """Drone if any target is a drone (multirotor or fixed-wing), else Background."""
    return LABELS[0] if any(t.kind in DRONE_KINDS for t in scenario.targets) else LABELS[1]


def clip_seed(seed: int, clip_index: int) -> int:
    """Seed of clip ``clip_index`` of a dataset generated with ``seed`` (independent per clip)."""
    return int(rng_for(seed, "generation", _TRIDENT_SEED_TAG, clip_index).integers(0, 2 ** 31 - 1))


# --------------------------------------------------------------------------------------------
# Scene-balanced generation: one scene distribution, drone clip + drone-absent twin
# --------------------------------------------------------------------------------------------

_SCENE_TAG = 11            # "generation" sub-stream of scene draws (independent of clip seeds)


class DrawnScene(BaseModel):
    """One drawn scene: the drone clip's scenario, its twin's, and the per-clip settings."""

    model_config = ConfigDict(frozen=True, arbitrary_types_allowed=True)
    index: int
    name: str
    drone: Scenario
    twin: Scenario
    ambience: Ambience
    rf_silent: bool
    rf: RFConfig
    conditions: dict[str, Any]


@dataclass(frozen=True)
class _View:
    """The drawn drone and the fixed camera looking at it (what the confusers are placed around)."""

    kind: str
    size_m: float
    range_m: float
    px: float
    focal_px: float
    hfov_deg: float
    az_deg: float
    el_deg: float
    cam: np.ndarray
    view: np.ndarray
    centre: np.ndarray
    lateral: np.ndarray
    frame_w_m: float


def _direction(az_deg: float, el_deg: float) -> np.ndarray:
    """scenes.sampling.direction in numpy arithmetic (kept: numpy's and math's sin/cos may differ in
    the last bit on some machines, and the drawn scenes must not)."""
    a, e = np.radians(az_deg), np.radians(el_deg)
    return np.array([np.cos(e) * np.sin(a), np.cos(e) * np.cos(a), np.sin(e)])


def draw_scene(dist: SceneDistribution, config: TridentConfig, seed: int, index: int) -> DrawnScene:
    """Scene ``index`` of a dataset generated with ``seed``: every condition drawn from ``dist``.

    Camera: fixed (not tracking, so the twin's camera is the drone clip's), pointed at the middle of
    the drone's path, field of view chosen so the drone spans a drawn 3-30 px; the path stays inside
    the frame (``path_fraction`` of its width). Confusers (birds near drone size, an airliner far
    behind) are placed in the view and appear in BOTH clips. One stream, drawn in this order: drone
    and view, drone path, confusers, sky, atmosphere, ambience, RF interferers, RF silence.
    """
    rng = rng_for(seed, "generation", _TRIDENT_SEED_TAG, _SCENE_TAG, index)
    v = _draw_view(rng, dist, config)
    drone = _draw_drone_path(rng, dist, config, v)
    confusers = _draw_birds(rng, dist, v)
    airliner = chance(rng, dist.airliner_probability) or not confusers
    if airliner:                       # every scene keeps >= 1 confuser (a scenario needs a target)
        confusers.append(_draw_airliner(rng, v))
    sky, cloudy = _draw_sky(rng, dist)
    atmosphere = _draw_atmosphere(rng, dist)
    ambience = draw_ambience(rng, dist.ambience)
    rf, wifi_on, bt_on = _draw_interferers(rng, dist, config.rf)
    rf_silent = chance(rng, dist.rf_silent_probability)
    name = f"scene_{index:04d}"
    base = {"name": name, "duration_s": config.clip_duration_s, "frame_rate_hz": float(config.video_fps),
            "sky": sky, "atmosphere": atmosphere,
            "camera_rig": {"position_m": v.cam.tolist(), "look_at_m": np.round(v.centre, 3).tolist(),
                           "rgb": {"width_px": config.video_px, "height_px": config.video_px,
                                   "hfov_deg": round(v.hfov_deg, 4)},
                           "thermal": {"width_px": 16, "height_px": 16, "hfov_deg": round(v.hfov_deg, 4)}}}
    drone_s = Scenario.model_validate({**base, "targets": [*confusers, drone]})
    twin_s = Scenario.model_validate({**base, "targets": confusers})
    conditions = {"drone_kind": v.kind, "drone_size_m": round(v.size_m, 3), "range_m": round(v.range_m, 1),
                  "drone_px_drawn": round(v.px, 2), "hfov_deg": round(v.hfov_deg, 3),
                  "elevation_deg": round(v.el_deg, 2),
                  "sun_elevation_deg": sky["sun"]["elevation_deg"], "cloudy": bool(cloudy),
                  "n_birds": sum(c["kind"] == "bird" for c in confusers), "airliner": bool(airliner),
                  "rain": ambience.rain_db is not None, "traffic": ambience.traffic_db is not None,
                  "wifi": bool(wifi_on), "bluetooth": bool(bt_on), "rf_silent": rf_silent}
    return DrawnScene(index=index, name=name, drone=drone_s, twin=twin_s, ambience=ambience,
                      rf_silent=rf_silent, rf=rf, conditions=conditions)


def _draw_view(rng: np.random.Generator, dist: SceneDistribution, config: TridentConfig) -> _View:
    """The drone (kind, size from scenes.kinds.TARGET_SIZE_RANGE_M, range, apparent px) and the
    camera's view of it (field of view, azimuth, elevation). Six draws."""
    kind = drone_kind(rng, dist.drone_kinds)
    size_m = target_size(rng, kind)
    range_m = log_uniform(rng, dist.range_m)
    px = log_uniform(rng, dist.drone_px)
    focal_px = px * range_m / size_m
    half = config.video_px / 2.0
    hfov = float(np.degrees(2 * np.arctan(half / focal_px)))
    az, el = uniform(rng, (-60.0, 60.0)), uniform(rng, dist.elevation_deg)
    cam = np.array([0.0, 0.0, 1.5])
    view = _direction(az, el)
    lateral = np.array([np.cos(np.radians(az)), -np.sin(np.radians(az)), 0.0])
    return _View(kind=kind, size_m=size_m, range_m=range_m, px=px, focal_px=focal_px, hfov_deg=hfov, az_deg=az,
                 el_deg=el, cam=cam, view=view, centre=cam + range_m * view, lateral=lateral,
                 frame_w_m=config.video_px * size_m / px)


def _draw_drone_path(rng: np.random.Generator, dist: SceneDistribution, config: TridentConfig, v: _View) -> dict:
    """The drone target: a two-point path across the view centre (length ``path_fraction`` of the
    frame width, drawn direction and climb), flown in the clip's duration. Three draws."""
    path_m = uniform(rng, dist.path_fraction) * v.frame_w_m
    way = sign(rng)
    climb = uniform(rng, (-0.15, 0.15)) * path_m
    p0 = v.centre - way * v.lateral * path_m / 2 - np.array([0, 0, climb / 2])
    p1 = v.centre + way * v.lateral * path_m / 2 + np.array([0, 0, climb / 2])
    speed = max(float(np.linalg.norm(p1 - p0)) / config.clip_duration_s, 0.02)
    return {"name": "drone", "kind": v.kind, "size_m": round(v.size_m, 4),
            "trajectory": {"kind": "waypoints", "speed_mps": round(speed, 4),
                           "points_m": [np.round(p0, 3).tolist(), np.round(p1, 3).tolist()]}}


def _draw_birds(rng: np.random.Generator, dist: SceneDistribution, v: _View) -> list[dict]:
    """0..max_birds birds near the drone's range, sized to span 2-24 px, flying across the view."""
    birds: list[dict] = []
    for b in range(int(rng.integers(0, dist.max_birds + 1))):
        r_b = v.range_m * uniform(rng, (0.4, 1.6))
        b_size = float(np.clip(log_uniform(rng, (2.0, 24.0)) * r_b / v.focal_px, 0.15, 1.6))
        off = uniform(rng, (-0.45, 0.45)) * v.frame_w_m * r_b / v.range_m
        up = uniform(rng, (-0.35, 0.35)) * v.frame_w_m * r_b / v.range_m
        start = v.cam + r_b * v.view + v.lateral * off + np.array([0, 0, up])
        vel = v.lateral * (uniform(rng, (2.0, 9.0)) * sign(rng)) + np.array([0, 0, uniform(rng, (-0.5, 0.5))])
        birds.append({"name": f"bird{b}", "kind": "bird", "size_m": round(b_size, 3),
                      "wingbeat_hz": round(uniform(rng, (2.5, 6.0)), 2),
                      "trajectory": {"kind": "flyby", "start_m": np.round(start, 2).tolist(),
                                     "velocity_mps": np.round(vel, 3).tolist()}})
    return birds


def _draw_airliner(rng: np.random.Generator, v: _View) -> dict:
    """An airliner 5-11 km behind the drone, near its elevation, crossing the view (size from
    scenes.kinds.TARGET_SIZE_RANGE_M). Six draws."""
    r_a = uniform(rng, (5000.0, 11000.0))
    a_el = float(np.clip(v.el_deg + uniform(rng, (-1.0, 1.0)) * v.hfov_deg * 0.4, 2.0, 60.0))
    start = (v.cam + r_a * _direction(v.az_deg, a_el)
             - v.lateral * uniform(rng, (0.3, 0.6)) * r_a * np.radians(v.hfov_deg))
    vel = v.lateral * uniform(rng, (120.0, 220.0))
    return {"name": "jet", "kind": "airliner", "size_m": round(target_size(rng, "airliner"), 1),
            "trajectory": {"kind": "flyby", "start_m": np.round(start, 1).tolist(),
                           "velocity_mps": np.round(vel, 2).tolist()}}


def _draw_sky(rng: np.random.Generator, dist: SceneDistribution) -> tuple[dict[str, Any], bool]:
    """Sun elevation and azimuth, turbidity, and clouds with ``cloud_probability`` (sky, cloudy)."""
    sky: dict[str, Any] = {"sun": {"elevation_deg": round(uniform(rng, dist.sun_elevation_deg), 2),
                                   "azimuth_deg": round(uniform(rng, (0.0, 360.0)), 2)},
                           "turbidity": round(uniform(rng, dist.turbidity), 2)}
    cloudy = chance(rng, dist.cloud_probability)
    if cloudy:
        sky["clouds"] = {"coverage": round(uniform(rng, dist.cloud_coverage), 3)}
    return sky, cloudy


def _draw_atmosphere(rng: np.random.Generator, dist: SceneDistribution) -> dict[str, float]:
    """Air temperature, relative humidity and visibility (log-uniform). Three draws."""
    return {"air_temperature_k": round(uniform(rng, dist.air_temperature_k), 2),
            "relative_humidity": round(uniform(rng, dist.relative_humidity), 3),
            "visibility_m": round(log_uniform(rng, dist.visibility_m), 1)}


def _draw_interferers(rng: np.random.Generator, dist: SceneDistribution, rf: RFConfig) -> tuple[RFConfig, bool, bool]:
    """Wi-Fi and Bluetooth interferers, each on with its probability at a drawn received level
    (rf config, wifi on, bluetooth on). Four draws."""
    wifi_on, wifi_db = chance(rng, dist.wifi_probability), uniform(rng, dist.wifi_rx_dbm)
    bt_on, bt_db = chance(rng, dist.bluetooth_probability), uniform(rng, dist.bluetooth_rx_dbm)
    rf = rf.model_copy(update={"wifi_rx_dbm": round(wifi_db, 1) if wifi_on else None,
                               "bluetooth_rx_dbm": round(bt_db, 1) if bt_on else None})
    return rf, wifi_on, bt_on


def scene_splits(dist: SceneDistribution) -> list[str]:
    """Split of every scene (train / val / test), seeded; the split unit is the scene."""
    rng = rng_for(dist.split_seed, "generation", _TRIDENT_SEED_TAG, _SCENE_TAG, 10 ** 6)
    order = rng.permutation(dist.n_scenes)
    out = ["train"] * dist.n_scenes
    for k, j in enumerate(order):
        if k < dist.n_test_scenes:
            out[j] = "test"
        elif k < dist.n_test_scenes + dist.n_val_scenes:
            out[j] = "val"
    return out


# --------------------------------------------------------------------------------------------

def drone_px_per_frame(timeline) -> np.ndarray:
    """Largest apparent size (px) of a drone inside the RGB frame per frame (0 where none is in view)."""
    cam = timeline.cameras["rgb"]
    out = np.zeros(timeline.n_frames)
    for track in timeline.targets:
        if track.kind not in DRONE_KINDS:
            continue
        for i in range(timeline.n_frames):
            xy, depth = cam.project(i, track.position_m[i])
            d = float(depth[0])
            if d <= 0:
                continue
            inside = 0 <= xy[0, 0] < cam.width_px and 0 <= xy[0, 1] < cam.height_px
            if inside:
                out[i] = max(out[i], track.size_m * cam.focal_px / d)
    return out


def _per_segment(values: np.ndarray, n_segments: int, frames_per_segment: int) -> np.ndarray:
    need = n_segments * frames_per_segment
    return np.pad(values, (0, max(0, need - values.size)))[:need].reshape(n_segments, frames_per_segment)


def _video_visibility(timeline, n_segments: int, frames_per_segment: int) -> np.ndarray:
    visible = drone_px_per_frame(timeline) >= VISIBLE_MIN_PX
    return _per_segment(visible, n_segments, frames_per_segment).sum(axis=1) * 2 > frames_per_segment


def synthesize_clip(scenario: Scenario, seed: int, config: TridentConfig, *, rf_silent: bool = False,
                    ambience: Ambience | None = None, frames: np.ndarray | None = None,
                    rf_config: RFConfig | None = None) -> TridentClip:
    """Audio, MFCC, RF and ground truth of one clip; ``scenario`` is already re-timed (clip_scenario).

    ``frames`` (rendered elsewhere) are checked for shape and kept; None leaves the clip without video.
    """
    from simulator.physics.timeline import build_timeline

    n_seg = config.n_segments
    timeline = build_timeline(scenario, seed)
    fs = AUDIO_SAMPLE_RATE_HZ
    audio = synthesize_audio(timeline, seed, ambience=ambience, duration_s=config.clip_duration_s, sample_rate_hz=fs)
    samples = record(audio.mix_pa, fs, seed=seed, index=_RECORDER_INDEX, full_scale_pa=config.full_scale_pa,
                     config=config.recorder)
    mfcc = mfcc_segments(samples, fs, n_seg)
    starts = np.arange(n_seg) * SEGMENT_S
    rf_cfg = rf_config or config.rf
    rf = synthesize_rf(timeline, seed, starts, config=rf_cfg, rf_silent=rf_silent,
                       clip_duration_s=config.clip_duration_s)
    images = spectrogram_image(rf.spectrogram_dbm, rf_cfg)
    label = clip_label(scenario)
    seg_len = int(round(SEGMENT_S * fs))
    drone_names = [t.name for t in timeline.targets if t.kind in DRONE_KINDS]
    if drone_names:
        drone = np.sum([audio.targets_pa[n].astype(np.float64) for n in drone_names], axis=0)
        other = audio.mix_pa.astype(np.float64) - drone
        snr = band_level_db(drone, fs, *AUDIBLE_BAND_HZ, seg_len) - band_level_db(other, fs, *AUDIBLE_BAND_HZ, seg_len)
    else:
        snr = np.full(n_seg, -np.inf)
    snr = np.pad(snr, (0, max(0, n_seg - snr.size)), constant_values=-np.inf)[:n_seg]
    present = np.full(n_seg, label == LABELS[0])
    truth = SegmentTruth(
        label=label, drone_present=present,
        video_visible=_video_visibility(timeline, n_seg, config.frames_per_segment) & present,
        audio_audible=(snr >= 0.0) & present, rf_observable=rf.observable & present, rf_silent=rf_silent,
        drone_range_m=rf.drone_range_m, audio_snr_db=snr, rf_link_snr_db=np.maximum(rf.control_snr_db, rf.video_snr_db),
    )
    if frames is not None:
        frames = np.asarray(frames)
        want = (n_seg * config.frames_per_segment, config.video_px, config.video_px, 3)
        if frames.shape != want or frames.dtype != np.uint8:
            raise ValueError(f"frames must be uint8 {want}, got {frames.dtype} {frames.shape}")
    return TridentClip(audio=samples, sample_rate_hz=fs, mfcc=mfcc, rf=rf, rf_images=images, frames=frames, truth=truth)


# --------------------------------------------------------------------------------------------
# Writing the TRIDENT layout


def _default_frames(scenario: Scenario, seed: int, n_frames: int, width_px: int, height_px: int,
                    layout: Scenario | None = None) -> np.ndarray:
    from simulator.dataset.sequence import render_rgb_video

    return render_rgb_video(scenario, seed, n_frames, width_px, height_px, layout=layout)


def _versions() -> dict[str, str]:
    from simulator.files import package_versions

    return package_versions(("evids", "numpy", "scipy", "librosa", "soundfile", "opencv-python-headless", "mitsuba"))


def _content_hash(root: Path) -> str:
    """sha256 over every file of the dataset but its manifest and the driver's bookkeeping (lock, lease)."""
    from simulator.files import BOOKKEEPING

    files = sorted(p for p in root.rglob("*") if p.is_file() and p.name != "manifest.json"
                   and not (p.parent == root and p.name in BOOKKEEPING))     # Path order (recorded hashes)
    return _digest(root, [str(p.relative_to(root)) for p in files])


class PlanItem(BaseModel):
    """One clip to write: its folder group, scenario, seed and per-clip settings."""

    model_config = ConfigDict(frozen=True, arbitrary_types_allowed=True)
    group: str
    scenario: Scenario
    seed: int
    rf_silent: bool = False
    ambience: Ambience | None = None
    rf: RFConfig | None = None
    layout: Scenario | None = None  # a twin: its drone clip's scene (renders with the same launch layout)
    meta: dict[str, Any] = Field(default_factory=dict)


def build_plan(config: TridentConfig, seed: int) -> list[PlanItem]:
    """Listed clips first (clip k: seed clip_seed(seed, k)), then each drawn scene's drone clip and
    twin (both with seed clip_seed(seed, 10**6 + j): every stream shares its draws)."""
    plan: list[PlanItem] = []
    for i, spec in enumerate(config.clips):
        scenario = clip_scenario(resolve_scenario(spec, source=f"clips.{i}.scenario"), config)
        group = spec.group or scenario.name
        for _ in range(spec.count):
            plan.append(PlanItem(group=group, scenario=scenario, seed=clip_seed(seed, len(plan)),
                                 rf_silent=spec.rf_silent, ambience=spec.ambience))
    if config.scenes is not None:
        splits = scene_splits(config.scenes)
        for j in range(config.scenes.n_scenes):
            sc = draw_scene(config.scenes, config, seed, j)
            s_seed = clip_seed(seed, 10 ** 6 + j)
            first = len(plan) + 1
            common = {"scene": sc.name, "split": splits[j], "conditions": sc.conditions}
            plan.append(PlanItem(group=sc.name, scenario=sc.drone, seed=s_seed, rf_silent=sc.rf_silent,
                                 ambience=sc.ambience, rf=sc.rf,
                                 meta={**common, "twin": first + 1 if config.scenes.twins else None}))
            if config.scenes.twins:
                plan.append(PlanItem(group=sc.name, scenario=sc.twin, seed=s_seed, rf_silent=sc.rf_silent,
                                     ambience=sc.ambience, rf=sc.rf, layout=sc.drone, meta={**common, "twin": first}))
    return plan


def render_clip_frames(scenario: Scenario, seed: int, config: TridentConfig, frames_fn: FramesFn,
                       n_frames: int, layout: Scenario | None = None) -> np.ndarray:
    """Video frames of a clip; with ``video_render_stride`` k every k-th frame is rendered and held.
    ``layout`` (a twin's drone scene) is passed on to ``frames_fn`` as a keyword when given."""
    k = config.video_render_stride
    px = config.video_px
    if k > 1:
        scenario = scenario.model_copy(update={"frame_rate_hz": scenario.frame_rate_hz / k})
        if layout is not None:
            layout = layout.model_copy(update={"frame_rate_hz": layout.frame_rate_hz / k})
    extra = {} if layout is None else {"layout": layout}
    frames = np.asarray(frames_fn(scenario, seed, n_frames // k, px, px, **extra), dtype=np.uint8)
    return frames if k == 1 else np.repeat(frames, k, axis=0)


def segment_drone_px(scenario: Scenario, seed: int, config: TridentConfig) -> np.ndarray:
    """Mean apparent drone size (px) per segment over the frames where it is in view (0: none)."""
    from simulator.physics.timeline import build_timeline

    px = _per_segment(drone_px_per_frame(build_timeline(scenario, seed)), config.n_segments,
                      config.frames_per_segment)
    seen = px > 0
    return np.where(seen.any(1), px.sum(1) / np.maximum(seen.sum(1), 1), 0.0)


def clip_unit_name(k: int) -> str:
    """The driver's name of clip ``k`` (0-based): ``clip000001`` for the clip numbered 1 in file names."""
    return f"clip{k + 1:06d}"


def _write_one_clip(root: Path, k: int, item: PlanItem, config: TridentConfig, frames_fn: FramesFn,
                    n_frames: int) -> dict[str, Any]:
    """Render, synthesise and write clip ``k`` (0-based) into ``root``; its driver result."""
    frames = render_clip_frames(item.scenario, item.seed, config, frames_fn, n_frames, layout=item.layout)
    clip = synthesize_clip(item.scenario, item.seed, config, rf_silent=item.rf_silent,
                           ambience=item.ambience, frames=frames, rf_config=item.rf)
    meta = {"scenario": item.scenario.name, "seed": item.seed, "label": clip.truth.label, **item.meta,
            "drone_px": [round(float(v), 2) for v in segment_drone_px(item.scenario, item.seed, config)]}
    write_clip(root, item.group, k + 1, clip, config, meta)
    return {"name": clip_unit_name(k)}


def _clip_worker_init() -> None:
    import drjit as dr

    dr.set_thread_count(1)  # one process per core: Dr.Jit's own pool would oversubscribe


def _callable_id(fn: Any) -> str:
    """A stable name of a frames function (module.qualname; a partial's arguments included)."""
    import functools

    if isinstance(fn, functools.partial):
        return f"{_callable_id(fn.func)}{fn.args!r}{sorted(fn.keywords.items())!r}"
    return f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', type(fn).__qualname__)}"


LAYOUT_ROOTS = ("audio", "video", "rf", "rf_iq", "labels")


def _clip_files(config: TridentConfig, label: str, group: str, number: int) -> list[str]:
    return clip_files(label, group, number, n_frames=config.n_segments * config.frames_per_segment,
                      n_segments=config.n_segments, save_iq=config.save_iq)


def _digest(root: Path, ordered: list[str]) -> str:
    """sha256 over each file's relative path and the sha256 of its bytes, in the given order."""
    digest = hashlib.sha256()
    for rel in ordered:
        digest.update(rel.encode())
        digest.update(hashlib.sha256((root / rel).read_bytes()).digest())
    return digest.hexdigest()


def _files_hash(root: Path, files: list[str]) -> str:
    """A clip's content hash: :func:`_digest` of its files in sorted string order."""
    return _digest(root, sorted(files))


@dataclass
class TridentDataset:
    """The TRIDENT clip dataset kind (simulator.dataset.driver): one unit per clip, its files spread
    over the layout's audio/, video/, rf/, rf_iq/ and labels/ folders."""

    config: TridentConfig
    seed: int
    plan: list[PlanItem]
    frames_fn: FramesFn
    noun: str = "clip"

    @property
    def label(self) -> str:
        return f"trident {self.config.name}"

    @property
    def n_frames(self) -> int:
        return self.config.n_segments * self.config.frames_per_segment

    def identity(self) -> str:
        from simulator.dataset.driver import canonical_sha256

        return canonical_sha256({"config": self.config.model_dump(mode="json"), "seed": int(self.seed),
                                 "clips": len(self.plan), "frames": _callable_id(self.frames_fn)})

    def units(self) -> list[Unit]:
        return [Unit(clip_unit_name(k), k) for k in range(len(self.plan))]

    def files(self, k: int) -> list[str]:
        """Files of clip ``k`` relative to the root (simulator.formats.trident.clip_files)."""
        item = self.plan[k]
        return _clip_files(self.config, clip_label(item.scenario), item.group, k + 1)

    def prepare(self, out: Path) -> None:
        planned = {f for k in range(len(self.plan)) for f in self.files(k)}
        for root in LAYOUT_ROOTS:
            for path in sorted((out / root).rglob("*")) if (out / root).is_dir() else []:
                if path.is_symlink() or (path.is_file() and path.relative_to(out).as_posix() not in planned):
                    path.unlink()  # a link is never followed; a file no planned clip writes is a leftover

    def unit_hash(self, out: Path, unit: Unit) -> str:
        return _files_hash(out, self.files(unit.payload))

    def unit_ok(self, out: Path, unit: Unit, recorded_hash: str | None) -> bool:
        if recorded_hash is None or not all((out / rel).is_file() for rel in self.files(unit.payload)):
            return False  # clips are not self-verifying: only a recorded, matching hash certifies one
        return self.unit_hash(out, unit) == recorded_hash

    def run(self, out: Path, todo: list[Unit], *, workers: int, progress: bool) -> Iterator[dict[str, Any]]:
        calls = [(out, u.payload, self.plan[u.payload], self.config, self.frames_fn, self.n_frames) for u in todo]
        start: Start = "inline" if workers <= 1 or len(calls) <= 1 else "forkserver"
        for i, result in iter_jobs(_write_one_clip, calls, workers=workers, start=start, on_error="collect",
                                   progress=self.label if progress else None, initializer=_clip_worker_init):
            if isinstance(result, JobError):
                why = f"worker process died ({result.error})" if result.died else result.message
                result = {"name": todo[i].name, "error": why}
            yield result

    def manifest(self, units: list[Unit], hashes: dict[str, str], complete: bool, out: Path) -> dict[str, Any]:
        clips = []
        for k, item in enumerate(self.plan):
            clips.append({"clip": k + 1, "name": clip_unit_name(k), "group": item.group,
                          "scenario": item.scenario.name, "seed": item.seed, "label": clip_label(item.scenario),
                          **item.meta, "content_sha256": hashes.get(clip_unit_name(k))})
        return {
            "format": "trident", "generator": "simulator.dataset.trident.generate_trident",
            "dataset_id": self.identity(), "complete": complete, "seed": int(self.seed),
            "config": self.config.model_dump(mode="json"), "clips": clips, "versions": _versions(),
            "segment_s": SEGMENT_S, "audio_sample_rate_hz": AUDIO_SAMPLE_RATE_HZ,
            "mfcc": {"n_fft": MFCC_N_FFT, "hop_length": mfcc_hop_length(int(SEGMENT_S * AUDIO_SAMPLE_RATE_HZ)),
                     "n_mels": MFCC_N_MELS, "n_mfcc": MFCC_N_MFCC, "top_db": MFCC_TOP_DB},
            "content_sha256": _content_hash(out) if complete else None,
        }


def generate_trident(config_or_name: str | Path | dict | TridentConfig, out_dir: str | Path, seed: int, *,
                     n_clips: int | None = None, progress: bool = True,
                     render_frames: FramesFn | None = None, workers: int = 1, overwrite: bool = False) -> Path:
    """Generate (or finish) a TRIDENT-layout dataset in ``out_dir``; returns it.

    Clip k (0-based over the expanded clip list, first ``n_clips`` only) uses seed
    ``clip_seed(seed, k)`` and is numbered k + 1 in file names. ``render_frames(scenario, seed,
    n_frames, width_px, height_px)`` supplies video frames (default: the Mitsuba renderer).
    The dataset driver (simulator.dataset.driver) owns the rest: a folder holding this same dataset
    is resumed (clips recorded intact are kept), another one is refused unless ``overwrite``; a
    failed clip leaves the others recorded and raises GenerationFailed naming it.
    ``workers`` > 1 writes clips in that many processes (each clip depends only on its own seed, so
    the files are byte-identical for any worker count; ``render_frames`` must then be picklable).
    """
    from scenes.errors import UserInputError
    from simulator.dataset.driver import drive

    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise UserInputError(f"workers must be an integer >= 1, got {workers!r}")
    config = load_trident_config(config_or_name)
    if n_clips is not None and n_clips < 1:
        raise UserInputError(f"n_clips must be >= 1, got {n_clips}")
    plan = build_plan(config, seed)
    if n_clips is not None:
        plan = plan[:n_clips]
    kind = TridentDataset(config, seed, plan, render_frames or _default_frames)
    inputs = ([Path(config_or_name)] if isinstance(config_or_name, (str, Path)) and Path(config_or_name).is_file()
              else [])
    drive(kind, out_dir, inputs=inputs, overwrite=overwrite, workers=workers, progress=progress)
    return Path(out_dir)


def verify_trident(dataset_dir: str | Path) -> VerifyReport:
    """Re-hash every clip of a generated TRIDENT dataset against its manifest (``evids verify``)."""
    from scenes.errors import UserInputError
    from simulator.files import check_plain_name
    from simulator.formats.trident import read_manifest

    root = Path(dataset_dir)
    manifest = read_manifest(root) or {}
    where = root / "manifest.json"
    try:
        config = load_trident_config(manifest.get("config") or {})
    except (UserInputError, ValueError) as exc:
        raise UserInputError(f"{where}: 'config' is not a TRIDENT generation config: {exc}") from None
    clips = manifest.get("clips")
    if not isinstance(clips, list):
        raise UserInputError(f"{where}: key 'clips' is missing or not a list")
    complete = manifest.get("complete", True) is True   # manifests before the driver had no flag
    report = VerifyReport(incomplete=not complete, noun="clip")
    for k, entry in enumerate(clips):
        if not isinstance(entry, dict) or entry.get("label") not in LABELS or not isinstance(entry.get("clip"), int):
            raise UserInputError(f"{where}: clips[{k}] needs a label ({'/'.join(LABELS)}) and an integer clip number")
        group = check_plain_name(str(entry.get("group")), f"clips[{k}].group")
        name = str(entry.get("name") or clip_unit_name(entry["clip"] - 1))
        files = _clip_files(config, entry["label"], group, entry["clip"])
        report.checked += 1
        absent = [f for f in files if not (root / f).is_file()]
        if len(absent) == len(files):
            report.missing.append(name)
        elif absent:
            report.corrupt[name] = [f"{f} (absent)" for f in absent]
        elif isinstance(entry.get("content_sha256"), str) and _files_hash(root, files) != entry["content_sha256"]:
            report.corrupt[name] = ["content differs from manifest.json"]
        elif complete and "name" in entry and not entry.get("content_sha256"):
            report.corrupt[name] = ["manifest.json (no content hash recorded for a complete dataset)"]
    if complete and not report.missing and not report.corrupt and manifest.get("content_sha256") != _content_hash(root):
        report.corrupt["(dataset)"] = ["a file no clip lists was added, or a clip's file changed"]
    return report
