"""Generation configs (scenes/generation/*.yaml): a weighted mixture of scenarios, randomisation
ranges, dataset size and splits; and the per-sequence randomised scenario they produce.

Every draw for sequence k comes from ``rng_for(seed, "generation", k, stream)`` so adding a
randomised parameter never shifts the others, and the split of sequence k depends only on
``split_seed`` and the number of sequences.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from scenes.kinds import DRONE_KINDS, DRONE_SIZE_M, MAX_BANK_DEG
from scenes.loader import GENERATION_DIR
from scenes.sampling import Span, at, direction, pick, pick_at, target_size
from scenes.schema import (
    Flyby,
    Hover,
    OmitWhenUnset,
    Orbit,
    Recording,
    RgbCamera,
    Scenario,
    Target,
    Terrain,
    ThermalCamera,
    Waypoints,
)
from simulator.physics.trajectory import min_orbit_radius_m
from simulator.seeding import rng_for

SPLITS = ("train", "val", "test")

# sub-streams of the "generation" stream per sequence (never renumber: it would change datasets)
_S_PRESET, _S_SEED, _S_TARGET, _S_TRAJ, _S_SUN, _S_AIR, _S_PARTS, _S_CAMERA, _S_DISTRACT = range(1, 10)
_S_BINS, _S_FOV, _S_MODE, _S_CLOUDS, _S_ELEV = range(10, 15)   # scene-realism fields (issue 23)
_S_FRAME_WARM = 15                                              # multirotor frame warming (issue 23)
_S_SENSOR = 16                                                  # camera-model settings (issue 23)
_S_PAINT = 17                                                   # the primary target's paint (issue 23)
_SPLIT_TAG = 1000


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Range(_Model):
    """Uniform range [min, max] (equal ends = a fixed value)."""

    min: float
    max: float

    @model_validator(mode="before")
    @classmethod
    def _from_pair(cls, data: Any) -> Any:
        if isinstance(data, (list, tuple)):
            if len(data) != 2:
                raise ValueError(f"a range is [min, max], got {list(data)}")
            return {"min": data[0], "max": data[1]}
        if isinstance(data, (int, float)) and not isinstance(data, bool):
            return {"min": data, "max": data}
        return data

    @model_validator(mode="after")
    def _ordered(self) -> "Range":
        if not (math.isfinite(self.min) and math.isfinite(self.max)) or self.min > self.max:
            raise ValueError(f"need finite min <= max, got [{self.min}, {self.max}]")
        return self

    def draw(self, rng: np.random.Generator) -> float:
        """A uniform value of the range (one draw)."""
        return at((self.min, self.max), rng.random())


class MixtureEntry(_Model):
    """One scenario source: a preset name or a scenario YAML path, with a relative weight."""

    scenario: str = Field(min_length=1)
    weight: float = Field(default=1.0, gt=0.0)


TrajectoryKind = Literal["hover", "flyby", "orbit", "waypoints"]


DistractorKind = Literal["bird", "airliner", "helicopter"]


def _default_distractor_kinds() -> list[DistractorKind]:
    return ["bird"]


class DistanceBin(_Model):
    """One distance bin of a per-class distance distribution: drawn with probability weight / sum."""

    weight: float = Field(gt=0.0)
    range_m: Range


#: randomise.sensor fields: the camera_rig entry and the field each one replaces; the bounds are the camera
#: models' own (read off their pydantic constraints by ``sensor_field_bounds``). The draws follow this
#: order: append new fields at the end, never reorder (it would change datasets)
SENSOR_FIELDS: dict[str, tuple[str, str]] = {
    "thermal_blur_sigma_px": ("thermal", "blur_sigma_px"),
    "thermal_netd_k": ("thermal", "netd_k"),
    "thermal_agc_plateau_fraction": ("thermal", "agc_plateau_fraction"),
    "thermal_agc_linear_fraction": ("thermal", "agc_linear_fraction"),
    "thermal_agc_gamma": ("thermal", "agc_gamma"),
    "thermal_agc_base_gain": ("thermal", "agc_base_gain"),
    "rgb_blur_sigma_px": ("rgb", "blur_sigma_px"),
    "rgb_read_noise_e": ("rgb", "read_noise_e"),
    "rgb_ae_key": ("rgb", "ae_key"),
    "recording_crf": ("recording", "crf"),
    "thermal_agc_min_span_k": ("thermal", "agc_min_span_k"),
}
_CAMERA_ENTRY_MODELS: dict[str, type[BaseModel]] = {"thermal": ThermalCamera, "rgb": RgbCamera,
                                                    "recording": Recording}
#: upper bounds where the camera field has none (a sanity cap, electrons)
_SENSOR_FIELD_CAPS = {"rgb_read_noise_e": 1000.0}


def sensor_field_bounds(name: str) -> tuple[float, bool, float, bool]:
    """(lowest, lowest excluded, highest, highest excluded) of ``randomise.sensor.<name>``: the camera
    field's own ge/gt/le/lt constraints, capped by ``_SENSOR_FIELD_CAPS``."""
    entry, field = SENSOR_FIELDS[name]
    lo, lo_open, hi, hi_open = -math.inf, False, _SENSOR_FIELD_CAPS.get(name, math.inf), False
    for c in _CAMERA_ENTRY_MODELS[entry].model_fields[field].metadata:
        if getattr(c, "ge", None) is not None:
            lo, lo_open = float(c.ge), False
        elif getattr(c, "gt", None) is not None:
            lo, lo_open = float(c.gt), True
        elif getattr(c, "le", None) is not None and float(c.le) <= hi:
            hi, hi_open = float(c.le), False
        elif getattr(c, "lt", None) is not None and float(c.lt) <= hi:
            hi, hi_open = float(c.lt), True
    return lo, lo_open, hi, hi_open


class SensorRandomisation(_Model):
    """Per-sequence draws of camera-model settings (domain randomisation where the real cameras' settings
    are unknown: focus, noise, gain stage, exposure, encoder quality). Each field replaces the scenario's
    value of the camera_rig field it names (``thermal_netd_k`` -> ``camera_rig.thermal.netd_k``);
    ``recording_crf`` replaces the recording's rate control and needs ``camera_rig.recording``. Null: the
    scenario's value. Units are the camera fields' own (K, pixels, electrons, fractions)."""

    thermal_blur_sigma_px: Range | None = None
    thermal_netd_k: Range | None = None
    thermal_agc_plateau_fraction: Range | None = None
    thermal_agc_linear_fraction: Range | None = None
    thermal_agc_gamma: Range | None = None
    thermal_agc_base_gain: Range | None = None
    rgb_blur_sigma_px: Range | None = None
    rgb_read_noise_e: Range | None = None
    rgb_ae_key: Range | None = None
    recording_crf: Range | None = None
    thermal_agc_min_span_k: Range | None = None

    @model_validator(mode="after")
    def _bounds(self) -> "SensorRandomisation":
        for name in SENSOR_FIELDS:
            value = getattr(self, name)
            if value is None:
                continue
            lo, lo_open, hi, hi_open = sensor_field_bounds(name)
            if value.min < lo or (lo_open and value.min <= lo) or value.max > hi or (hi_open and value.max >= hi):
                interval = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
                raise ValueError(f"sensor.{name} must lie in {interval}, got [{value.min}, {value.max}]")
        return self


#: randomisation ranges that must lie inside a closed interval: (low, high, unit in the message)
_CLOSED_BOUNDS: dict[str, tuple[float, float, str]] = {
    "time_of_day_h": (0.0, 24.0, ""), "relative_humidity": (0.0, 1.0, ""), "sun_elevation_deg": (-90.0, 90.0, ""),
    "cloud_cover": (0.0, 1.0, ""), "multirotor_frame_warming_k": (0.0, 60.0, " K"), "paint_reflectance": (0.0, 1.0, ""),
}


class Randomisation(_Model, OmitWhenUnset):
    """Ranges applied on top of each mixture scenario; a field left null keeps the preset's value.

    ``range_m``/``trajectory_kinds`` replace the primary drone's trajectory (the camera then tracks
    it and its field of view is set so the drone spans ``target_px`` pixels on the RGB camera).
    """

    target_kinds: list[Literal["quadcopter", "hexacopter", "fixed_wing"]] | None = Field(default=None, min_length=1)
    target_size_scale: Range | None = None
    range_m: Range | None = None
    trajectory_kinds: list[TrajectoryKind] | None = Field(default=None, min_length=1)
    speed_mps: Range = Field(default_factory=lambda: Range(min=3.0, max=12.0))
    target_px: Range = Field(default_factory=lambda: Range(min=8.0, max=20.0))
    elevation_deg: Range = Field(default_factory=lambda: Range(min=3.0, max=15.0),
                                 description="elevation of the drone above the horizon seen from the camera")
    sun_elevation_deg: Range | None = None
    sun_azimuth_deg: Range | None = None
    time_of_day_h: Range | None = Field(default=None, description="UTC hour at latitude_deg/longitude_deg")
    date: str = Field(default="2024-06-21", pattern=r"^\d{4}-\d{2}-\d{2}$")
    latitude_deg: float = Field(default=48.0, ge=-90.0, le=90.0)
    longitude_deg: float = Field(default=11.0, ge=-180.0, le=180.0)
    air_temperature_k: Range | None = None
    relative_humidity: Range | None = None
    visibility_m: Range | None = None
    part_temperature_offset_k: Range | None = Field(default=None, description="added to every part offset")
    multirotor_frame_warming_k: Range | None = Field(default=None, description=(
        "flying multirotors only (quadcopter, hexacopter): one draw per target (K, >= 0) added to the body and "
        "arm offsets, the heat the ESCs on the arms and the power board and battery in the centre plate give "
        "the frame in flight (docs/SIM2REAL.md); null: the kind's defaults"))
    paint_reflectance: Range | None = Field(default=None, description=(
        "grey visible reflectance (linear albedo, 0-1) of the primary target's painted parts "
        "(scenes.defaults.PAINTED_ROLES: a multirotor's body, arms and battery cover, a helicopter's fuselage "
        "and tail, ...), one draw per sequence; their LWIR emissivity is kept, so the thermal band is unchanged; "
        "null: the kind's default materials"))
    camera_yaw_deg: Range | None = Field(default=None, description="thermal-to-RGB yaw offset")
    camera_pitch_deg: Range | None = Field(default=None, description="thermal-to-RGB pitch offset")
    camera_translation_m: Range | None = Field(default=None, description="thermal-to-RGB baseline along x")
    distractors: tuple[Annotated[int, Field(ge=0, le=10)], Annotated[int, Field(ge=0, le=10)]] = (0, 0)
    distractor_kinds: list[DistractorKind] = Field(default_factory=_default_distractor_kinds, min_length=1)
    # scene realism (issue 23); every field left null keeps the draws and outputs of older configs
    distance_bins: list[DistanceBin] | None = Field(default=None, min_length=1,
                                                    description="replaces range_m: a weighted mixture of distance "
                                                                "ranges")
    hfov_deg: Range | None = Field(default=None, description="fixed RGB field of view (replaces target_px)")
    elevation_fov_fraction: Range | None = Field(
        default=None,
        description="replaces elevation_deg: the drone's elevation above the horizon as a fraction of the "
                                  "thermal camera's vertical field of view (0.35 puts the horizon 0.35 frame heights "
                                  "below a centred drone)")
    fixed_camera_fraction: float = Field(default=0.0, ge=0.0, le=1.0,
                                         description="share of sequences with a fixed camera (targets enter and leave)")
    fixed_camera_offset_deg: Range = Field(default_factory=lambda: Range(min=-8.0, max=8.0),
                                           description="fixed camera: azimuth offset of the optical axis from the "
                                                       "drone's centre")
    camera_elevation_deg: Range | None = Field(default=None,
                                               description="fixed camera: optical-axis elevation (null: the drone's)")
    tracking_lag_s: Range | None = None
    tracking_error_deg: Range | None = None
    tracking_error_fov_fraction: Range | None = Field(default=None, description="replaces tracking_error_deg: "
                                                      "rms pointing error as a fraction of the RGB horizontal FOV")
    tracking_loss_rate_hz: Range | None = None
    tracking_error_period_s: Range | None = Field(default=None, description=(
        "correlation time of the pointing error (scenes.schema.Tracking.error_period_s; null: its default)"))
    cloud_cover: Range | None = Field(default=None, description="sky.clouds.coverage, 0-1")
    terrain: Terrain | None = Field(default=None, description="the ground and horizon clutter of every sequence")
    sensor: SensorRandomisation | None = Field(default=None, description=(
        "per-sequence camera-model settings (blur, NETD, gain stage, exposure, H.264 CRF); null: the scenario's"))

    #: fields added after the dataset format froze, left out of the dump while unset: a config without
    #: them keeps its manifest bytes and ``dataset_id`` (an older dataset folder resumes)
    _OMIT_WHEN_UNSET: ClassVar[tuple[str, ...]] = ("multirotor_frame_warming_k", "sensor", "paint_reflectance")

    @model_validator(mode="after")
    def _checks(self) -> "Randomisation":
        if self.distractors[0] > self.distractors[1]:
            raise ValueError(f"distractors must be [min, max] with min <= max, got {list(self.distractors)}")
        if self.time_of_day_h is not None and (self.sun_elevation_deg is not None or self.sun_azimuth_deg is not None):
            raise ValueError("give either time_of_day_h or sun_elevation_deg/sun_azimuth_deg, not both")
        for name in ("range_m", "visibility_m"):
            value = getattr(self, name)
            if value is not None and value.min <= 0:
                raise ValueError(f"{name} must be > 0, got [{value.min}, {value.max}]")
        for name, (low, high, unit) in _CLOSED_BOUNDS.items():
            value = getattr(self, name)
            if value is not None and not (low <= value.min and value.max <= high):
                raise ValueError(f"{name} must lie in [{low:g}, {high:g}]{unit}, got [{value.min}, {value.max}]")
        for b in self.distance_bins or []:
            if b.range_m.min <= 0:
                raise ValueError(f"distance_bins range_m must be > 0, got [{b.range_m.min}, {b.range_m.max}]")
        for name in ("hfov_deg", "tracking_lag_s", "tracking_error_deg", "tracking_loss_rate_hz",
                     "tracking_error_period_s", "elevation_fov_fraction",
                     "tracking_error_fov_fraction"):
            value = getattr(self, name)
            if value is not None and (value.min < 0 or (name == "hfov_deg" and not 0 < value.min <= value.max < 170)):
                raise ValueError(f"{name} out of range, got [{value.min}, {value.max}]")
        for name in ("speed_mps", "target_px", "target_size_scale"):
            value = getattr(self, name)
            if value is not None and value.min <= 0:
                raise ValueError(f"{name} must be > 0, got [{value.min}, {value.max}]")
        return self


class Splits(_Model):
    train: float = Field(default=0.8, ge=0.0, le=1.0)
    val: float = Field(default=0.1, ge=0.0, le=1.0)
    test: float = Field(default=0.1, ge=0.0, le=1.0)
    seed: int = Field(default=0, ge=0, description="fixed split seed, independent of the render seed")

    @model_validator(mode="after")
    def _sum(self) -> "Splits":
        total = self.train + self.val + self.test
        if abs(total - 1.0) > 1e-6:
            raise ValueError(f"train + val + test must be 1, got {total:g}")
        return self


class GenerationConfig(_Model):
    """A dataset recipe (scenes/generation/<name>.yaml)."""

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.-]+$")
    description: str = ""
    mixture: list[MixtureEntry] = Field(min_length=1)
    randomise: Randomisation = Field(default_factory=Randomisation)
    sequences: int = Field(default=10, ge=1, le=1_000_000)
    frames: int = Field(default=25, ge=1, le=100_000, description="frames per sequence")
    frame_rate_hz: float | None = Field(default=None, gt=0.0, le=240.0, description="null keeps each scenario's")
    image_size: tuple[Annotated[int, Field(ge=16, le=4096)], Annotated[int, Field(ge=16, le=4096)]] = (320, 256)
    thermal_image_size: tuple[Annotated[int, Field(ge=16, le=4096)],
                              Annotated[int, Field(ge=16, le=4096)]] | None = None
    spp: int = Field(default=4, ge=1, le=1024,
                     description="both cameras' samples per pixel (CameraIntrinsics.spp: sub-pixel targets need 16-32)")
    splits: Splits = Field(default_factory=Splits)


def load_generation_config(config_or_name: str | Path | dict | GenerationConfig) -> GenerationConfig:
    """A config object, a mapping, a YAML path or a preset in scenes/generation/; a scene preset
    name (scenes/library/) gives that scenario with its default randomisation."""
    from scenes.errors import UserInputError
    from scenes.loader import LIBRARY_DIR, load_validated

    if isinstance(config_or_name, GenerationConfig):
        return config_or_name
    if isinstance(config_or_name, (str, Path)):
        text = str(config_or_name)
        plain = not Path(text).suffix and "/" not in text and not Path(text).exists()
        if plain and not (GENERATION_DIR / f"{text}.yaml").is_file() and (LIBRARY_DIR / f"{text}.yaml").is_file():
            return GenerationConfig(name=text, mixture=[MixtureEntry(scenario=text)], randomise=default_randomisation())
    if isinstance(config_or_name, (str, Path)):
        text = str(config_or_name)
        path = GENERATION_DIR / f"{text}.yaml" if not Path(text).suffix and "/" not in text else Path(text)
        if path.is_file():
            from scenes.yaml_safe import load_yaml_file

            data = load_yaml_file(path)  # bounded and strict (duplicate keys, alias bombs, depth)
            if isinstance(data, dict) and "clips" in data and "mixture" not in data:
                raise UserInputError(f"{text!r} is a TRIDENT clip config: use `evids generate {text} --format trident`")
    return load_validated(config_or_name, GenerationConfig, GENERATION_DIR, "generation config")


def default_randomisation() -> Randomisation:
    """What a bare scene preset gets: weather, light, part temperatures, camera offsets; the
    preset's own targets, trajectories and camera."""
    return Randomisation(
        sun_elevation_deg=Range(min=10.0, max=60.0), sun_azimuth_deg=Range(min=0.0, max=360.0),
        air_temperature_k=Range(min=275.0, max=303.0), relative_humidity=Range(min=0.3, max=0.8),
        visibility_m=Range(min=8000.0, max=30000.0), part_temperature_offset_k=Range(min=-2.0, max=2.0),
        camera_yaw_deg=Range(min=-0.05, max=0.05), camera_pitch_deg=Range(min=-0.05, max=0.05))


# --------------------------------------------------------------------------------------------
# Per-sequence plan
# --------------------------------------------------------------------------------------------

def split_assignment(splits: Splits, n: int) -> list[str]:
    """Split of each of n sequences: exact largest-remainder counts, order shuffled by splits.seed."""
    fractions = np.array([splits.train, splits.val, splits.test])
    raw = fractions * n
    counts = np.floor(raw).astype(int)
    remainder = n - int(counts.sum())
    order = sorted(range(3), key=lambda i: (-(raw[i] - counts[i]), i))
    for i in order[:remainder]:
        counts[i] += 1
    labels = [name for name, c in zip(SPLITS, counts) for _ in range(int(c))]
    perm = rng_for(splits.seed, "generation", _SPLIT_TAG, n).permutation(n)
    return [labels[int(j)] for j in np.argsort(perm)]


def sequence_name(index: int) -> str:
    return f"seq{index + 1:06d}"


def sequence_seed(seed: int, index: int) -> int:
    """Render seed of sequence ``index`` (independent per sequence)."""
    return int(rng_for(seed, "generation", index, _S_SEED).integers(0, 2 ** 31 - 1))


def choose_source(config: GenerationConfig, seed: int, index: int) -> str:
    weights = np.array([m.weight for m in config.mixture], dtype=np.float64)
    k = int(rng_for(seed, "generation", index, _S_PRESET).choice(len(weights), p=weights / weights.sum()))
    return config.mixture[k].scenario


def _load_source(source: str, base_dir: Path | None) -> Scenario:
    from scenes.loader import load_scenario

    path = Path(source)
    if base_dir is not None and path.suffix and not path.is_absolute() and not path.exists():
        candidate = base_dir / path
        if candidate.exists():
            return load_scenario(candidate)
    return load_scenario(source)


def _primary_index(targets: list[Target]) -> int:
    for i, t in enumerate(targets):
        if t.kind in DRONE_KINDS:
            return i
    return 0


def _xyz(v: np.ndarray) -> tuple[float, float, float]:
    """A 3-vector as a tuple of floats rounded to the millimetre."""
    x, y, z = (round(float(c), 3) for c in v)
    return x, y, z


def _orbit_radius(drawn_m: float, speed_mps: float, max_bank_deg: float) -> float:
    """The drawn orbit radius (rounded to the millimetre), raised to the smallest radius whose
    coordinated-turn bank stays within ``max_bank_deg`` (rounded up) where it is below it: a radius
    that was already physical is kept as drawn, and no random number is drawn for the raise."""
    radius = round(drawn_m, 3)  # a no-op on an already rounded draw
    smallest = math.ceil(min_orbit_radius_m(speed_mps, max_bank_deg) * 1000.0) / 1000.0
    return max(radius, smallest)


def _trajectory(kind: str, centre: np.ndarray, speed: float, duration_s: float,
                rng: np.random.Generator, max_bank_deg: float) -> Hover | Flyby | Orbit | Waypoints:
    """A drawn path of ``kind`` around ``centre``; an orbit's radius keeps its bank within
    ``max_bank_deg`` (the target kind's ``scenes.kinds.MAX_BANK_DEG``). A raised orbit's centre moves
    away from the start point by the raise, so the target starts at the drawn orbit's start point,
    on its heading, at the drawn range (a 600 m circle about the drawn point would take it hundreds of
    metres out of its distance bin)."""
    heading = rng.uniform(0.0, 2 * math.pi)
    horiz = np.array([math.cos(heading), math.sin(heading), 0.0])
    c = _xyz(centre)
    if kind == "hover":
        return Hover(center_m=c, drift_m=round(float(rng.uniform(0.2, 1.0)), 3))
    if kind == "flyby":
        climb = float(rng.uniform(-0.1, 0.1))
        velocity = speed * horiz + np.array([0.0, 0.0, climb * speed])
        start = centre - velocity * duration_s / 2
        return Flyby(start_m=_xyz(start), velocity_mps=_xyz(velocity))
    if kind == "orbit":
        drawn = round(float(rng.uniform(5.0, 25.0)), 3)
        clockwise = bool(rng.random() < 0.5)
        start = round(float(rng.uniform(0, 360)), 3)
        radius = _orbit_radius(drawn, round(speed, 3), max_bank_deg)
        if radius > drawn:   # the wider circle starts where the drawn one did, on the same heading
            outward = np.array([math.cos(math.radians(start)), math.sin(math.radians(start)), 0.0])
            c = _xyz(centre - (radius - drawn) * outward)
        return Orbit(center_m=c, radius_m=radius, speed_mps=round(speed, 3), clockwise=clockwise,
                     start_angle_deg=start)
    spread = max(2.0, speed * duration_s / 3)
    points = [_xyz(centre + rng.uniform(-1, 1, 3) * np.array([spread, spread, spread / 4])) for _ in range(4)]
    return Waypoints(points_m=points, speed_mps=round(speed, 3))


def randomised_scenario(config: GenerationConfig, seed: int, index: int,
                        base_dir: Path | None = None) -> tuple[str, Scenario]:
    """(mixture source, scenario) of sequence ``index``: the chosen scenario with every configured
    range drawn, resized to the config's image size and frame count, named ``seq<index+1>``.

    Each step draws from its own sub-stream ``rng_for(seed, "generation", index, _S_...)``, in this
    order: primary target (kind, size), track (range, path, camera), sun, clouds, air, part
    temperatures, multirotor frame warming, the primary target's paint, thermal-camera offset, distractors,
    camera-model settings."""
    source = choose_source(config, seed, index)
    base = _load_source(source, base_dir)
    r = config.randomise
    data = base.model_dump(mode="python")
    frame_rate = config.frame_rate_hz or base.frame_rate_hz
    duration = config.frames / frame_rate
    data.update(name=sequence_name(index), duration_s=duration, frame_rate_hz=frame_rate, seed=None)
    targets = data["targets"]
    p = _primary_index(base.targets)

    def stream(sub: int) -> np.random.Generator:
        return rng_for(seed, "generation", index, sub)

    _draw_primary_target(r, targets[p], stream(_S_TARGET))
    rig = data["camera_rig"]
    cam_pos = np.asarray(rig["position_m"], dtype=np.float64)
    if r.range_m is not None or r.trajectory_kinds is not None or r.distance_bins is not None:
        _draw_track(config, base, p, targets[p], rig, cam_pos, duration, stream)
    _draw_sun(r, data["sky"], stream(_S_SUN))
    if r.cloud_cover is not None:
        _draw_clouds(r.cloud_cover, data["sky"], stream(_S_CLOUDS))
    if r.terrain is not None:
        data["terrain"] = r.terrain.model_dump(mode="python")
    _draw_air(r, data["atmosphere"], stream(_S_AIR))
    if r.part_temperature_offset_k is not None:
        _draw_part_offsets(r.part_temperature_offset_k, targets, stream(_S_PARTS))
    if r.multirotor_frame_warming_k is not None:
        _draw_frame_warming(r.multirotor_frame_warming_k, targets, stream(_S_FRAME_WARM))
    if r.paint_reflectance is not None:
        _draw_paint(r.paint_reflectance, targets[p], stream(_S_PAINT))
    _draw_camera_offset(r, rig["thermal_offset"], stream(_S_CAMERA))
    _draw_distractors(r, targets, targets[p], rig, base, cam_pos, duration, stream(_S_DISTRACT))
    if r.sensor is not None:
        _draw_sensor(r.sensor, rig, stream(_S_SENSOR))

    w, h = config.image_size
    tw, th = config.thermal_image_size or config.image_size
    rig["rgb"].update(width_px=w, height_px=h, spp=config.spp)
    rig["thermal"].update(width_px=tw, height_px=th, spp=config.spp)
    from scenes.loader import scenario_from_dict

    return source, scenario_from_dict(data, source=f"{config.name}: sequence {index}")


def _draw_primary_target(r: Randomisation, target: dict, rng: np.random.Generator) -> None:
    """The primary drone's kind (``target_kinds``; a new kind takes its nominal size and default
    thermal offsets and materials) and size (``target_size_scale``). Always two draws."""
    kind_draw, size_draw = rng.random(), rng.random()
    if r.target_kinds is not None and target["kind"] in DRONE_KINDS:
        new_kind = pick_at(r.target_kinds, kind_draw)
        if new_kind != target["kind"]:
            target["kind"] = new_kind
            target["thermal"]["offsets_k"] = {}
            target["thermal"]["offsets_end_k"] = None
            target["materials"] = {}
            target["size_m"] = DRONE_SIZE_M[new_kind]
    if r.target_size_scale is not None:
        target["size_m"] = round(target["size_m"] * at(_span(r.target_size_scale), size_draw), 4)


def _draw_track(config: GenerationConfig, base: Scenario, p: int, target: dict, rig: dict, cam_pos: np.ndarray,
                duration: float, stream: Callable[[int], np.random.Generator]) -> None:
    """The primary drone's new trajectory (range, kind, bearing, elevation, speed, path) and the camera
    that tracks it: field of view from ``target_px`` (or ``hfov_deg``), elevation from
    ``elevation_fov_fraction``, then the camera mode (fixed or tracking). ``target`` is the primary
    target's dict, ``base.targets[p]`` the same target before this sequence's draws."""
    r = config.randomise
    rng = stream(_S_TRAJ)
    if r.distance_bins is not None:
        rng.random()   # keeps the later draws where a range_m config has them
        distance = _draw_bin(r.distance_bins, stream(_S_BINS))
    elif r.range_m is not None:
        distance = r.range_m.draw(rng)
    else:
        distance = float(np.linalg.norm(np.asarray(_trajectory_anchor(base.targets[p])) - cam_pos))
        rng.random()
    kind = pick(rng, r.trajectory_kinds or ["hover", "flyby", "orbit", "waypoints"])
    bearing = float(rng.uniform(-30.0, 30.0))
    elevation = r.elevation_deg.draw(rng)
    speed = r.speed_mps.draw(rng)
    centre = cam_pos + distance * direction(bearing, elevation)
    centre[2] = max(centre[2], cam_pos[2] + 5.0)
    target["trajectory"] = _trajectory(kind, centre, speed, duration, rng,
                                       MAX_BANK_DEG[target["kind"]]).model_dump(mode="python")
    width = config.image_size[0]
    hfov = math.degrees(target["size_m"] / distance * width / r.target_px.draw(rng))
    hfov = float(min(60.0, max(0.5, hfov)))
    if r.hfov_deg is not None:
        hfov = r.hfov_deg.draw(stream(_S_FOV))
    ratio = base.camera_rig.thermal.hfov_deg / base.camera_rig.rgb.hfov_deg
    rig["track_target"] = target["name"]
    rig["look_at_m"] = None
    rig["rgb"]["hfov_deg"] = round(hfov, 4)
    rig["thermal"]["hfov_deg"] = round(min(60.0, hfov * ratio), 4)
    if r.elevation_fov_fraction is not None:
        tw, th_px = config.thermal_image_size or config.image_size
        vfov = 2 * math.degrees(math.atan(math.tan(math.radians(rig["thermal"]["hfov_deg"]) / 2) * th_px / tw))
        new_el = r.elevation_fov_fraction.draw(stream(_S_ELEV)) * vfov
        anchor = np.asarray(_trajectory_anchor(Target.model_validate(target)), dtype=np.float64)
        wanted_z = max(cam_pos[2] + distance * math.sin(math.radians(new_el)), 3.0)
        target["trajectory"] = _shift_z(target["trajectory"], wanted_z - anchor[2])
        elevation = new_el
    _camera_mode(r, rig, target, cam_pos, bearing, elevation, stream(_S_MODE))


def _draw_sun(r: Randomisation, sky: dict, rng: np.random.Generator) -> None:
    """The sun: a drawn UTC hour at the config's place and date (``time_of_day_h``), or a drawn
    elevation and/or azimuth (a preset sun given by date keeps 35 / 135 deg for the other)."""
    if r.time_of_day_h is not None:
        hour = r.time_of_day_h.draw(rng)
        hh, mm = int(hour), int(round((hour - int(hour)) * 60))
        if mm == 60:
            hh, mm = hh + 1, 0
        stamp = f"{r.date}T{min(hh, 23):02d}:{mm if hh < 24 else 59:02d}:00+00:00"
        sky["sun"] = {"datetime_utc": stamp, "latitude_deg": r.latitude_deg, "longitude_deg": r.longitude_deg}
    elif r.sun_elevation_deg is not None or r.sun_azimuth_deg is not None:
        sun = sky["sun"]
        if sun.get("elevation_deg") is None:
            sun = {"elevation_deg": 35.0, "azimuth_deg": 135.0}
        if r.sun_elevation_deg is not None:
            sun["elevation_deg"] = round(r.sun_elevation_deg.draw(rng), 4)
        if r.sun_azimuth_deg is not None:
            sun["azimuth_deg"] = round(r.sun_azimuth_deg.draw(rng), 4)
        sky["sun"] = {"elevation_deg": sun["elevation_deg"], "azimuth_deg": sun["azimuth_deg"]}


def _draw_clouds(cover: Range, sky: dict, rng: np.random.Generator) -> None:
    """The cloud coverage (the preset's other cloud fields kept)."""
    clouds = dict(sky.get("clouds") or {})
    clouds["coverage"] = round(cover.draw(rng), 4)
    sky["clouds"] = clouds


def _draw_air(r: Randomisation, air: dict, rng: np.random.Generator) -> None:
    """Air temperature, humidity and visibility: one draw each, made whether or not it is configured."""
    for field, rounding in (("air_temperature_k", 3), ("relative_humidity", 4), ("visibility_m", 1)):
        value = getattr(r, field)
        draw = rng.random()
        if value is not None:
            air[field] = round(at(_span(value), draw), rounding)


def _draw_part_offsets(offset: Range, targets: list[dict], rng: np.random.Generator) -> None:
    """One drawn temperature offset per target, added to every part offset (or to the contrast of a
    target that matches its background)."""
    from scenes.assets import ROLES
    from scenes.defaults import offset_for

    for t_data in targets:
        delta = offset.draw(rng)
        thermal = t_data["thermal"]
        if thermal["mode"] == "offset":
            probe = Target.model_validate(t_data)
            thermal["offsets_k"] = {role: round(offset_for(probe, role) + delta, 4) for role in ROLES}
            if thermal.get("offsets_end_k") is not None:
                thermal["offsets_end_k"] = {role: round(offset_for(probe, role, end=True) + delta, 4)
                                            for role in ROLES}
        elif thermal["mode"] == "match_background":
            thermal["contrast_k"] = round(thermal["contrast_k"] + delta, 4)
            if thermal.get("contrast_end_k") is not None:
                thermal["contrast_end_k"] = round(thermal["contrast_end_k"] + delta, 4)


#: the part roles a flying multirotor's frame warming heats: the centre plate and shell (power board,
#: flight controller, battery bay) and the arms (ESCs strapped under them, motor heat conducted inward)
FRAME_WARMING_ROLES = ("body", "arm")


def _draw_frame_warming(warming: Range, targets: list[dict], rng: np.random.Generator) -> None:
    """One draw per target in order (multirotor or not, so adding a distractor never shifts the
    primary's draw), added to the body and arm offsets of quadcopters and hexacopters in offset mode."""
    from scenes.defaults import offset_for

    for t_data in targets:
        delta = warming.draw(rng)
        thermal = t_data["thermal"]
        if t_data["kind"] not in ("quadcopter", "hexacopter") or thermal["mode"] != "offset":
            continue
        probe = Target.model_validate(t_data)
        offsets = dict(thermal["offsets_k"])
        for role in FRAME_WARMING_ROLES:
            offsets[role] = round(offset_for(probe, role) + delta, 4)
        thermal["offsets_k"] = offsets
        if thermal.get("offsets_end_k") is not None:
            end = dict(thermal["offsets_end_k"])
            for role in FRAME_WARMING_ROLES:
                end[role] = round(offset_for(probe, role, end=True) + delta, 4)
            thermal["offsets_end_k"] = end


def _draw_paint(paint: Range, target: dict, rng: np.random.Generator) -> None:
    """One grey reflectance for the primary target's painted parts (``PAINTED_ROLES`` of its kind),
    each part keeping its emissivity (the kind's default or the scenario's override)."""
    from scenes.defaults import PAINTED_ROLES, material_for

    albedo = round(paint.draw(rng), 4)
    probe = Target.model_validate(target)
    materials = dict(target["materials"])
    for role in PAINTED_ROLES[target["kind"]]:
        materials[role] = {"rgb_reflectance": (albedo, albedo, albedo),
                           "emissivity": material_for(probe, role).emissivity}
    target["materials"] = materials


def _draw_camera_offset(r: Randomisation, off: dict, rng: np.random.Generator) -> None:
    """The thermal camera's yaw, pitch and baseline offsets from the RGB camera (always three draws)."""
    draws = rng.random(3)
    if r.camera_yaw_deg is not None:
        off["yaw_deg"] = round(off["yaw_deg"] + r.camera_yaw_deg.min + (r.camera_yaw_deg.max - r.camera_yaw_deg.min)
                               * draws[0], 5)
    if r.camera_pitch_deg is not None:
        off["pitch_deg"] = round(off["pitch_deg"] + r.camera_pitch_deg.min
                                 + (r.camera_pitch_deg.max - r.camera_pitch_deg.min) * draws[1], 5)
    if r.camera_translation_m is not None:
        tx = r.camera_translation_m.min + (r.camera_translation_m.max - r.camera_translation_m.min) * draws[2]
        off["translation_m"] = (round(tx, 5), off["translation_m"][1], off["translation_m"][2])


def _draw_sensor(sensor: SensorRandomisation, rig: dict, rng: np.random.Generator) -> None:
    """One draw per ``SENSOR_FIELDS`` entry in its fixed order, made whether or not it is configured (so
    switching one field on never moves another's value); each configured one replaces its camera field."""
    from scenes.errors import UserInputError

    draws = rng.random(len(SENSOR_FIELDS))
    for draw, (name, (entry, field)) in zip(draws, SENSOR_FIELDS.items()):
        value = getattr(sensor, name)
        if value is None:
            continue
        if rig.get(entry) is None:
            raise UserInputError(f"randomise.sensor.{name}: the scenario has no camera_rig.{entry}")
        rig[entry][field] = round(at(_span(value), float(draw)), 5)
        if name == "recording_crf":
            rig[entry]["bit_rate_bps"] = None


def _draw_distractors(r: Randomisation, targets: list[dict], primary: dict, rig: dict, base: Scenario,
                      cam_pos: np.ndarray, duration: float, rng: np.random.Generator) -> None:
    """``distractors`` extra targets (kinds from ``distractor_kinds``, sizes from
    ``scenes.kinds.TARGET_SIZE_RANGE_M``) flying by near the primary target's line of sight."""
    n_extra = int(rng.integers(r.distractors[0], r.distractors[1] + 1))
    if not n_extra:
        return
    anchor = np.asarray(_trajectory_anchor(Target.model_validate(primary)), dtype=np.float64)
    to_target = anchor - cam_pos
    dist = float(np.linalg.norm(to_target))
    bearing0 = math.degrees(math.atan2(to_target[0], to_target[1]))
    elev0 = math.degrees(math.asin(to_target[2] / max(dist, 1e-9)))
    half = 0.3 * (rig["rgb"]["hfov_deg"] if rig["look_at_m"] is None else base.camera_rig.rgb.hfov_deg)
    names = {t["name"] for t in targets}
    for j in range(n_extra):
        kind = pick(rng, r.distractor_kinds)
        b = bearing0 + float(rng.uniform(-half, half))
        e = elev0 + float(rng.uniform(-half, half) * 0.8)
        if kind == "bird":
            d = dist * float(rng.uniform(0.4, 0.9))
            size, speed = target_size(rng, kind), float(rng.uniform(4.0, 10.0))
        elif kind == "helicopter":
            d = float(rng.uniform(300.0, 2500.0))
            size, speed = target_size(rng, kind), float(rng.uniform(15.0, 60.0))
        else:
            d = float(rng.uniform(3000.0, 9000.0))
            size, speed = target_size(rng, kind), float(rng.uniform(100.0, 220.0))
        centre = cam_pos + d * direction(b, e)
        centre[2] = max(centre[2], cam_pos[2] + 3.0)
        traj = _trajectory("flyby", centre, speed, duration, rng, MAX_BANK_DEG[kind])
        name = f"distractor{j + 1}"
        while name in names:
            name += "_"
        names.add(name)
        targets.append({"name": name, "kind": kind, "size_m": round(size, 3),
                        "trajectory": traj.model_dump(mode="python"),
                        "wingbeat_hz": round(float(rng.uniform(2.5, 6.0)), 3) if kind == "bird" else 4.0})
        if kind == "helicopter":
            targets[-1]["rotor"] = {"main_blades": 4, "main_rpm": 400.0}


def _span(value: Range) -> Span:
    """A config range as a (low, high) span."""
    return (value.min, value.max)


def _shift_z(trajectory: dict, dz: float) -> dict:
    """The same trajectory moved up by dz metres."""
    t = dict(trajectory)
    for key in ("center_m", "start_m"):
        if t.get(key) is not None:
            x, y, z = t[key]
            t[key] = (x, y, round(z + dz, 3))
    if t.get("points_m") is not None:
        t["points_m"] = [(x, y, round(z + dz, 3)) for x, y, z in t["points_m"]]
    return t


def _draw_bin(bins: list[DistanceBin], rng: np.random.Generator) -> float:
    """A distance from a weighted mixture of uniform ranges."""
    weights = np.array([b.weight for b in bins], dtype=np.float64)
    k = int(np.searchsorted(np.cumsum(weights) / weights.sum(), rng.random(), side="right"))
    return bins[min(k, len(bins) - 1)].range_m.draw(rng)


def _camera_mode(r: Randomisation, rig: dict, target: dict, cam_pos: np.ndarray, bearing: float, elevation: float,
                 rng: np.random.Generator) -> None:
    """Fixed camera (a share of sequences) pointed near the drone's centre, or a tracking camera with
    drawn lag / error / losses. Draws a fixed number of values so each field keeps its stream."""
    u, off, el, lag, err, loss = rng.random(6)
    if u < r.fixed_camera_fraction:
        az = bearing + r.fixed_camera_offset_deg.min + (r.fixed_camera_offset_deg.max
                                                        - r.fixed_camera_offset_deg.min) * off
        axis_el = elevation if r.camera_elevation_deg is None else \
            r.camera_elevation_deg.min + (r.camera_elevation_deg.max - r.camera_elevation_deg.min) * el
        rig["look_at_m"] = tuple(round(float(v), 4) for v in cam_pos + 100.0 * direction(az, axis_el))
        rig["track_target"] = None
        rig["tracking"] = None
        return
    if r.tracking_lag_s is None and r.tracking_error_deg is None and r.tracking_loss_rate_hz is None \
            and r.tracking_error_fov_fraction is None:
        return

    def pick(value: Range | None, draw: float, default: float) -> float:
        return default if value is None else round(value.min + (value.max - value.min) * draw, 4)

    error = pick(r.tracking_error_deg, err, 0.0)
    if r.tracking_error_fov_fraction is not None:
        error = round(pick(r.tracking_error_fov_fraction, err, 0.0) * float(rig["rgb"]["hfov_deg"]), 4)
    rig["tracking"] = {"lag_s": pick(r.tracking_lag_s, lag, 0.0), "error_deg": error,
                       "loss_rate_hz": pick(r.tracking_loss_rate_hz, loss, 0.0)}
    if r.tracking_error_period_s is not None:       # one more draw, only where the field is set
        rig["tracking"]["error_period_s"] = pick(r.tracking_error_period_s, float(rng.random()), 1.5)


def _trajectory_anchor(target: Target) -> tuple[float, float, float]:
    traj = target.trajectory
    if isinstance(traj, (Hover, Orbit)):
        return traj.center_m
    if isinstance(traj, Flyby):
        return traj.start_m
    return tuple(np.mean(np.asarray(traj.points_m), axis=0).tolist())
