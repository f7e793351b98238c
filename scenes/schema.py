"""Declarative, renderer-free scene model (pydantic). YAML in, YAML out.

World frame: ENU metres, +z up; the camera rig usually stands near the origin. Angles in degrees in
the YAML (names end in _deg); temperatures in kelvin (names end in _k).
"""
from __future__ import annotations

import datetime as dt
import math
from typing import Annotated, ClassVar, Final, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_serializer, model_validator

from scenes.terrain_assets import check_asset

SCHEMA_VERSION: Final = 1

TargetKind = Literal["quadcopter", "hexacopter", "fixed_wing", "bird", "airliner", "helicopter"]
Vec3 = tuple[float, float, float]
RGB = tuple[
    Annotated[float, Field(ge=0.0, le=1.0)],
    Annotated[float, Field(ge=0.0, le=1.0)],
    Annotated[float, Field(ge=0.0, le=1.0)],
]


class _Model(BaseModel):
    # allow_inf_nan=False: NaN/inf in any float field is refused at validation (not in the renderer)
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def omit_when_unset(data: object, names: tuple[str, ...]) -> object:
    """A model dump without the named keys whose value is None: fields added after a file format froze
    stay out of the dump while unset, so older files keep their bytes and every hash taken of them (the
    one mechanism behind each model's ``_OMIT_WHEN_UNSET``)."""
    if isinstance(data, dict):
        for name in names:
            if name in data and data[name] is None:
                del data[name]
    return data


class OmitWhenUnset(BaseModel):
    """Mixin: a model that lists fields in ``_OMIT_WHEN_UNSET`` leaves them out of every dump while they are
    None (:func:`omit_when_unset`)."""

    _OMIT_WHEN_UNSET: ClassVar[tuple[str, ...]] = ()

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        return omit_when_unset(handler(self), self._OMIT_WHEN_UNSET)


#: a name used as one path component (scene names become output folder names)
PLAIN_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,127}$"
PlainName = Annotated[str, Field(pattern=PLAIN_NAME_PATTERN, min_length=1, max_length=128,
                                 description="letters, digits and ._+- (not starting with . or -): used as a folder "
                                             "name")]
#: the radiometric counts' ceiling must sit this far above the hottest planned temperature
THERMAL_HEADROOM_K = 20.0


class Material(_Model):
    """Surface of one part: visible reflectance (linear sRGB albedo) and LWIR emissivity."""

    rgb_reflectance: RGB
    emissivity: float = Field(ge=0.01, le=1.0)


class Thermal(_Model):
    """How part temperatures are set.

    - ``offset``: T = air temperature + offsets_k[role] (+ a linear ramp to offsets_end_k if given).
    - ``absolute``: T = absolute_k[role].
    - ``match_background``: solve each part's temperature so its apparent radiance equals the sky
      behind the target plus ``contrast_k`` (ramping linearly to ``contrast_end_k``); contrast 0 is
      a physical thermal crossover.
    """

    mode: Literal["offset", "absolute", "match_background"] = "offset"
    offsets_k: dict[str, float] = Field(default_factory=dict)
    offsets_end_k: dict[str, float] | None = None
    absolute_k: dict[str, Annotated[float, Field(gt=100.0, lt=1500.0)]] = Field(default_factory=dict)
    contrast_k: float = 0.0
    contrast_end_k: float | None = None

    @model_validator(mode="after")
    def _absolute_needs_values(self) -> "Thermal":
        if self.mode == "absolute" and not self.absolute_k:
            raise ValueError("mode 'absolute' needs absolute_k: {role: kelvin}")
        return self


class Waypoints(_Model):
    """Catmull-Rom spline through points_m, flown at constant speed_mps (loops if ``loop``)."""

    kind: Literal["waypoints"] = "waypoints"
    points_m: list[Vec3] = Field(min_length=2)
    speed_mps: float = Field(gt=0.0, le=300.0)
    loop: bool = False


class Hover(_Model):
    """Station keeping at center_m with smooth random drift of about drift_m (seeded)."""

    kind: Literal["hover"] = "hover"
    center_m: Vec3
    drift_m: float = Field(default=0.5, ge=0.0)
    drift_period_s: float = Field(default=4.0, gt=0.0)


class Orbit(_Model):
    """Circle of radius_m around center_m at constant speed; start_angle_deg from +x toward +y."""

    kind: Literal["orbit"] = "orbit"
    center_m: Vec3
    radius_m: float = Field(gt=0.0)
    speed_mps: float = Field(gt=0.0, le=300.0)
    clockwise: bool = False
    start_angle_deg: float = 0.0


class Flyby(_Model):
    """Straight line from start_m with constant velocity_mps."""

    kind: Literal["flyby"] = "flyby"
    start_m: Vec3
    velocity_mps: Vec3


Trajectory = Annotated[Union[Waypoints, Hover, Orbit, Flyby], Field(discriminator="kind")]


class HelicopterRotor(_Model):
    """A helicopter's main rotor (diameter = the target's size_m); the tail rotor is geared to it."""

    main_blades: int = Field(default=4, ge=2, le=8)
    main_rpm: float = Field(default=400.0, gt=0.0, le=1000.0, description="typical light helicopters: 350-550 rpm")


class Target(_Model):
    name: str = Field(min_length=1)
    kind: TargetKind
    size_m: float = Field(gt=0.0, le=100.0)
    trajectory: Trajectory
    materials: dict[str, Material] = Field(default_factory=dict, description="per-role overrides")
    thermal: Thermal = Field(default_factory=Thermal)
    wingbeat_hz: float = Field(default=4.0, gt=0.0, le=30.0, description="birds only")
    rotor: HelicopterRotor | None = Field(default=None, description="helicopters only (required for them)")

    @model_validator(mode="after")
    def _rotor(self) -> "Target":
        if self.kind == "helicopter" and self.rotor is None:
            raise ValueError("rotor: a helicopter needs a main rotor, e.g. rotor: {main_blades: 4, main_rpm: 400}")
        if self.kind != "helicopter" and self.rotor is not None:
            raise ValueError(f"rotor: only helicopters take a rotor block (kind is {self.kind!r})")
        return self


class Sun(_Model):
    """Either elevation_deg/azimuth_deg (azimuth clockwise from north = +y) or a time and place."""

    elevation_deg: float | None = Field(default=None, ge=-90.0, le=90.0)
    azimuth_deg: float | None = None
    datetime_utc: dt.datetime | None = None
    latitude_deg: float | None = Field(default=None, ge=-90.0, le=90.0)
    longitude_deg: float | None = Field(default=None, ge=-180.0, le=180.0)

    @model_validator(mode="after")
    def _one_way(self) -> "Sun":
        angles = self.elevation_deg is not None and self.azimuth_deg is not None
        place = self.datetime_utc is not None and self.latitude_deg is not None and self.longitude_deg is not None
        if angles == place:
            raise ValueError("give either elevation_deg + azimuth_deg, or datetime_utc + latitude_deg + longitude_deg")
        return self


class Clouds(_Model, OmitWhenUnset):
    coverage: float = Field(ge=0.0, le=1.0)
    altitude_m: float = Field(default=2000.0, gt=0.0)
    scale_deg: float = Field(default=20.0, gt=0.0, description="typical cloud size on the sky")
    edge_width_sd: float | None = Field(
        default=None, gt=0.0, le=20.0,
        description="width of a cloud's edge: the cover rises from 0 to 1 over this many standard deviations of "
                    "the fractal field above the coverage threshold (None = 1.2; wider = softer, thinner edges)")

    #: fields added after the scenario format froze, left out of scenario.yaml while unset
    _OMIT_WHEN_UNSET: ClassVar[tuple[str, ...]] = ("edge_width_sd",)


class Sky(_Model):
    sun: Sun = Field(default_factory=lambda: Sun(elevation_deg=40.0, azimuth_deg=135.0))
    turbidity: float = Field(default=3.0, ge=1.0, le=10.0)
    ground_albedo: float = Field(default=0.2, ge=0.0, le=1.0)
    clouds: Clouds | None = None


def saturation_vapour_density_g_m3(air_temperature_k: float) -> float:
    """Water-vapour density at saturation over water, g m^-3 (Magnus form, Alduchov & Eskridge 1996)."""
    t_c = float(air_temperature_k) - 273.15
    e_pa = 610.94 * math.exp(17.625 * t_c / (t_c + 243.04))
    return e_pa / (461.5 * float(air_temperature_k)) * 1000.0


AtmosphereModel = Literal["user", "tropical", "midlat_summer", "midlat_winter", "subarctic_summer",
                          "subarctic_winter", "us_standard"]


class Atmosphere(_Model, OmitWhenUnset):
    """Air at the sensor. LWIR sky and paths come from LOWTRAN7 tables (docs/PHYSICS.md):

    - ``model: user`` (default): the sky is interpolated between the AFGL model atmospheres by the
      absolute humidity of this air; horizontal paths use LOWTRAN7 for exactly this air.
    - a named AFGL model: that model's sky and path tables (air temperature still sets L(T_air)).
    Humidity: ``relative_humidity`` (0-1) or ``absolute_humidity_g_m3`` (water-vapour density; it
    then sets relative_humidity, and both given must agree). ``visibility_m`` (Koschmieder, 2 % contrast) drives the visible haze and the LWIR aerosol.
    """  # noqa: E501 (the model's JSON-schema description: kept as it is)

    air_temperature_k: float = Field(default=288.0, gt=200.0, lt=340.0)
    relative_humidity: float = Field(default=0.5, ge=0.0, le=1.0)
    absolute_humidity_g_m3: float | None = Field(default=None, ge=0.0, le=60.0)
    visibility_m: float = Field(default=20000.0, gt=10.0)
    model: AtmosphereModel = "user"
    lapse_rate_k_per_km: float | None = Field(
        default=None, ge=-10.0, le=10.0,
        description="fall of the air temperature with height above the camera (6.5: the ICAO standard atmosphere; "
                    "negative: an inversion): a target's parts take the air temperature at the target's altitude "
                    "before their offsets; None: the air at the sensor everywhere (docs/PHYSICS.md)")

    #: added after the scenario format froze: left out of scenario.yaml while unset (older scenes keep their bytes)
    _OMIT_WHEN_UNSET: ClassVar[tuple[str, ...]] = ("lapse_rate_k_per_km",)

    @model_validator(mode="before")
    @classmethod
    def _humidity_from_absolute(cls, data):
        """absolute_humidity_g_m3 sets relative_humidity (so every consumer sees one air); both
        given must agree within 0.01 (a resolved YAML carries both)."""
        if not isinstance(data, dict) or data.get("absolute_humidity_g_m3") is None:
            return data
        try:
            ah = float(data["absolute_humidity_g_m3"])
            t_k = float(data.get("air_temperature_k", 288.0))
        except (TypeError, ValueError):
            return data   # the field validators report the bad value
        if not 200.0 < t_k < 340.0 or ah < 0:
            return data
        rh = ah / saturation_vapour_density_g_m3(t_k)
        if rh > 1.0 + 1e-6:
            raise ValueError(f"absolute_humidity_g_m3 {ah} exceeds saturation at {t_k} K "
                             f"({saturation_vapour_density_g_m3(t_k):.2f} g m^-3)")
        given = data.get("relative_humidity")
        if given is not None:
            try:
                if abs(float(given) - rh) > 0.01:
                    raise ValueError(f"relative_humidity {given} and absolute_humidity_g_m3 {ah} disagree "
                                     f"(that is RH {rh:.3f} at {t_k} K): give one of them")
            except TypeError:
                return data
            return data
        return {**data, "relative_humidity": min(rh, 1.0)}


class CameraIntrinsics(_Model):
    width_px: int = Field(default=640, ge=16, le=4096)
    height_px: int = Field(default=512, ge=16, le=4096)
    hfov_deg: float = Field(default=30.0, gt=0.1, lt=170.0)
    spp: int = Field(default=4, ge=1, le=1024, description=(
        "samples per pixel of the radiance pass (with small targets only their tiles are sampled; the sky "
        "outside them is evaluated at pixel centres); a target covering less than a pixel needs 16-32, or it "
        "blinks from frame to frame as its few samples hit or miss it"))
    label_margin_px: tuple[Annotated[int, Field(ge=0, le=256)], Annotated[int, Field(ge=0, le=256)]] = Field(
        default=(0, 0), description="[x, y] pixels added on each side of every label box (clipped to the frame), as "
                                    "human annotators draw boxes; the exact box stays in box_tight. (0, 0) = exact")


class RgbCamera(CameraIntrinsics, OmitWhenUnset):
    """Visible camera model (simulator/sensors/camera.py). Defaults: a typical 1/2.3-inch CMOS
    (6.17 mm wide, 1.55 um native pixels) behind an f/2.8 lens; the output pixel averages the
    native pixels it covers. exposure_time_s None = auto exposure capped at one frame period."""

    sensor_width_mm: float = Field(default=6.17, gt=0.5, le=50.0)
    native_pixel_pitch_um: float = Field(default=1.55, gt=0.5, le=30.0)
    f_number: float = Field(default=2.8, ge=0.7, le=32.0)
    defocus_blur_um: float = Field(default=0.0, ge=0.0, le=500.0, description="blur-circle diameter")
    blur_sigma_px: float = Field(default=0.0, ge=0.0, le=10.0,
                                 description="extra Gaussian blur, rms in output pixels (aberrations, OLPF, rescaling)")
    full_well_e: float = Field(default=4600.0, gt=100.0, description="per native pixel")
    read_noise_e: float = Field(default=2.5, ge=0.0, description="per native pixel, rms")
    quantum_efficiency: float = Field(default=0.5, gt=0.0, le=1.0)
    exposure_time_s: float | None = Field(default=None, gt=0.0, le=1.0)
    max_gain: float = Field(default=16.0, ge=1.0, le=1024.0)
    adc_bits: Literal[8, 10, 12, 14, 16] = 12
    tone: Literal["srgb", "camcorder"] = Field(
        default="srgb", description="srgb: fixed exposure, sRGB curve; camcorder: whole-frame auto-exposure + "
                                    "BT.709 curve with a highlight knee (simulator/sensors/agc.py)")
    ae_key: float = Field(default=0.25, gt=0.0, le=1.0, description="camcorder: metered mean linear luminance target")
    ae_damping: float = Field(default=0.9, ge=0.0, lt=1.0,
                              description="camcorder: per-frame memory of the exposure (log)")
    knee_point: float = Field(default=0.85, gt=0.0, le=1.0, description="camcorder: output level where the knee starts")
    knee_slope: float = Field(default=0.25, gt=0.0, le=1.0, description="camcorder: slope factor above the knee")
    colour_gain: float | None = Field(
        default=None, gt=0.0, le=4.0,
        description="camcorder: gain on the chroma of the tone-mapped output about its BT.709 luma (the camera's "
                    "colour level / saturation setting, applied before the encoder; 1 = colorimetric); None = off")

    #: fields added after the scenario format froze, left out of scenario.yaml while unset
    _OMIT_WHEN_UNSET: ClassVar[tuple[str, ...]] = ("colour_gain",)

    @model_validator(mode="after")
    def _colour_gain_needs_camcorder(self) -> "RgbCamera":
        if self.colour_gain is not None and self.tone != "camcorder":
            raise ValueError(f"colour_gain is a camcorder setting: it needs tone: camcorder (got tone {self.tone!r})")
        return self


class ThermalCamera(CameraIntrinsics, OmitWhenUnset):
    """Uncooled LWIR microbolometer model. Defaults: a 640x512, 12 um pixel core behind an f/1.0
    lens, NETD 40 mK, time constant 10 ms, small residual column fixed-pattern noise after a
    shutter NUC; radiometric 16-bit counts T = counts * kelvin_per_count and an 8-bit AGC view."""

    netd_k: float = Field(default=0.04, gt=0.0, le=1.0)
    kelvin_per_count: float = Field(default=0.01, gt=0.0)
    pixel_pitch_um: float = Field(default=12.0, gt=1.0, le=100.0)
    f_number: float = Field(default=1.0, ge=0.5, le=8.0)
    wavelength_um: float = Field(default=10.0, ge=7.0, le=15.0, description="PSF wavelength")
    defocus_blur_um: float = Field(default=0.0, ge=0.0, le=1000.0, description="blur-circle diameter")
    blur_sigma_px: float = Field(default=0.0, ge=0.0, le=10.0,
                                 description="extra Gaussian blur, rms in pixels (aberrations, crosstalk)")
    time_constant_s: float = Field(default=0.010, ge=0.0, le=0.1)
    fpn_column_offset_k: float = Field(default=0.02, ge=0.0, le=10.0, description="rms per-column offset")
    fpn_column_gain: float = Field(default=0.005, ge=0.0, le=0.5, description="rms per-column gain error")
    fpn_pixel_gain: float | None = Field(
        default=None, ge=0.0, le=0.5,
        description="rms per-pixel gain residual after the shutter NUC: a scene this many kelvin from the shutter "
                    "shows a fixed grain of fpn_pixel_gain x that many kelvin (a cold clear sky: grain; near the "
                    "shutter: none); None = off")
    adc_bits: Literal[14, 16] = 16
    agc: Literal["minmax", "percentile", "histogram", "plateau"] = "minmax"
    agc_bin_k: float = Field(default=0.05, gt=0.0, le=5.0, description="plateau: histogram bin width")
    agc_plateau_fraction: float = Field(default=0.01, gt=0.0, le=1.0,
                                        description="plateau: per-bin cap, fraction of the frame's pixels")
    agc_linear_fraction: float = Field(default=0.2, ge=0.0, le=1.0, description="plateau: share of the linear map")
    agc_tail_fraction: float = Field(default=0.005, ge=0.0, lt=0.5, description="plateau: pixels ignored at each end")
    agc_min_span_k: float = Field(default=4.0, gt=0.0, le=200.0,
                                  description="plateau: a scene narrower than this is not stretched to full range (max "
                                              "gain)")
    agc_damping: float = Field(default=0.9, ge=0.0, lt=1.0, description="plateau: per-frame memory of the transfer")
    agc_base_sigma_px: float = Field(default=0.0, ge=0.0, le=200.0,
                                     description="plateau: local contrast, Gaussian base (0 = off)")
    agc_base_gain: float = Field(default=1.0, ge=0.0, le=1.0, description="plateau: gain of the base about its mean")
    agc_base_opening_px: int | None = Field(
        default=None, ge=3, le=401, description="plateau: the base is the Gaussian of the counts' grey opening over "
                                                "a disc this wide (px): hotter content narrower than it (the "
                                                "targets) stays detail, no dark ring round it; None = off")
    agc_gamma: float = Field(default=1.0, ge=0.25, le=4.0,
                             description="plateau: gamma on the transfer (FLIR ACE; > 1: more grey levels for hot "
                                         "content, darker sky; 1 = off)")
    agc_mean_level: float | None = Field(default=None, gt=0.0, lt=1.0,
                                         description="plateau: the frame's mean output pinned at this fraction of "
                                                     "the range (FLIR ITT mean / brightness; None = off)")

    #: fields added after the scenario format froze, left out of scenario.yaml while unset
    _OMIT_WHEN_UNSET: ClassVar[tuple[str, ...]] = ("agc_mean_level", "agc_base_opening_px", "fpn_pixel_gain")

    @model_validator(mode="after")
    def _counts_cover_scene(self) -> "ThermalCamera":
        full_scale_k = self.kelvin_per_count * (2 ** self.adc_bits - 1)
        if full_scale_k < 400.0:
            raise ValueError(f"kelvin_per_count x (2^adc_bits - 1) = {full_scale_k:.0f} K must reach 400 K "
                             f"(radiometric counts T = counts * kelvin_per_count)")
        if self.agc_base_opening_px is not None and (self.agc != "plateau" or self.agc_base_sigma_px <= 0):
            raise ValueError("agc_base_opening_px shapes the local-contrast base: it needs agc: plateau and "
                             f"agc_base_sigma_px > 0 (got agc {self.agc!r}, "
                             f"agc_base_sigma_px {self.agc_base_sigma_px})")
        return self


class CameraOffset(_Model):
    """Pose of the thermal camera relative to the RGB camera (camera frame: x right, y up, z back)."""

    translation_m: Vec3 = (0.0, 0.0, 0.0)
    yaw_deg: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0


class Recording(_Model):
    """H.264 recording chain after the camera model (simulator/sensors/recording.py): the 8-bit views
    (rgb, thermal_agc) pass through a libx264 encode + decode; counts and kelvin stay untouched.
    Rate control: ``crf`` (constant rate factor; 28 if neither is given) or ``bit_rate_bps``."""

    codec: Literal["h264"] = "h264"
    crf: float | None = Field(default=None, ge=0.0, le=51.0)
    bit_rate_bps: int | None = Field(default=None, ge=1, le=10 ** 9)
    gop_frames: int = Field(default=128, ge=1, le=100000, description="frames from one key frame to the next")
    preset: Literal["ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow"] = "veryfast"
    video_range: Literal["limited", "full"] = Field(
        default="limited", description="grey view on video levels (luma 16-235, as the benchmark's IR clips) or 0-255")

    @model_validator(mode="after")
    def _one_rate_control(self) -> "Recording":
        if self.crf is not None and self.bit_rate_bps is not None:
            raise ValueError("give crf or bit_rate_bps, not both")
        return self


class Tracking(_Model):
    """A pan-tilt tracker's imperfections (with ``track_target``; None = perfect centring).

    The commanded pointing is the target direction plus a smooth random error (rms error_deg per
    axis, correlation time error_period_s); the head follows the command through a first-order lag
    (lag_s). Track losses arrive at loss_rate_hz; during a loss (loss_s seconds, drawn in the range)
    the head holds its last pointing, then re-acquires through the lag. Seeded per scene."""

    lag_s: float = Field(default=0.3, ge=0.0, le=10.0)
    error_deg: float = Field(default=0.2, ge=0.0, le=20.0)
    error_period_s: float = Field(default=1.5, gt=0.0, le=60.0)
    loss_rate_hz: float = Field(default=0.0, ge=0.0, le=5.0)
    loss_s: tuple[Annotated[float, Field(gt=0.0, le=60.0)], Annotated[float, Field(gt=0.0, le=60.0)]] = (0.5, 2.0)

    @model_validator(mode="after")
    def _loss_order(self) -> "Tracking":
        if self.loss_s[0] > self.loss_s[1]:
            raise ValueError(f"loss_s must be [min, max] with min <= max, got {list(self.loss_s)}")
        return self


class CameraRig(_Model):
    position_m: Vec3 = (0.0, 0.0, 1.5)
    look_at_m: Vec3 | None = None
    track_target: str | None = None
    tracking: Tracking | None = Field(default=None, description="pan-tilt lag, error and losses (with track_target)")
    rgb: RgbCamera = Field(default_factory=RgbCamera)
    thermal: ThermalCamera = Field(default_factory=ThermalCamera)
    thermal_offset: CameraOffset = Field(default_factory=CameraOffset)
    sensor: Literal["camera", "ideal"] = Field(default="camera", description="ideal = no camera model")
    recording: Recording | None = Field(default=None, description="H.264 recording chain (None = lossless frames)")

    @model_validator(mode="after")
    def _pointing(self) -> "CameraRig":
        if (self.look_at_m is None) == (self.track_target is None):
            raise ValueError("give exactly one of look_at_m (fixed camera) or track_target (pan/tilt)")
        if self.tracking is not None and self.track_target is None:
            raise ValueError("tracking needs track_target (a fixed camera does not track)")
        if self.look_at_m is not None:
            d = [a - b for a, b in zip(self.look_at_m, self.position_m)]
            length = sum(v * v for v in d) ** 0.5
            if length < 1e-3:
                raise ValueError(f"look_at_m {list(self.look_at_m)} is the camera position: the camera would see "
                                 "nothing")
            if (d[0] ** 2 + d[1] ** 2) ** 0.5 < 1e-3 * length:
                raise ValueError(f"look_at_m {list(self.look_at_m)} is straight above/below position_m "
                                 f"{list(self.position_m)}: the camera's up direction is undefined (tilt it slightly)")
        return self


class TreeLine(_Model):
    """A tree line: a band of canopy at distance_m from the camera rig between two compass azimuths
    (clockwise from north = +y), height_m tall (crowns vary by +-height_jitter)."""

    asset: str = "deciduous"
    distance_m: float = Field(gt=5.0, le=20000.0)
    azimuth_deg: tuple[float, float]
    height_m: float | None = Field(default=None, gt=0.0, le=100.0, description="None = the asset's height")
    height_jitter: float = Field(default=0.3, ge=0.0, le=0.9)

    @field_validator("asset")
    @classmethod
    def _asset(cls, v: str) -> str:
        return check_asset(v, "trees")

    @model_validator(mode="after")
    def _span(self) -> "TreeLine":
        a, b = self.azimuth_deg
        if not 0.0 < b - a <= 360.0:
            raise ValueError(f"azimuth_deg must be [from, to] with 0 < to - from <= 360, got {[a, b]}")
        return self


class Structure(_Model):
    """A building or mast at distance_m and compass azimuth_deg from the rig (sizes None = the asset's)."""

    asset: str
    distance_m: float = Field(gt=5.0, le=20000.0)
    azimuth_deg: float
    width_m: float | None = Field(default=None, gt=0.0, le=500.0)
    depth_m: float | None = Field(default=None, gt=0.0, le=500.0)
    height_m: float | None = Field(default=None, gt=0.0, le=600.0)


class Building(Structure):
    asset: str = "house"

    @field_validator("asset")
    @classmethod
    def _asset(cls, v: str) -> str:
        return check_asset(v, "building")


class Mast(Structure):
    asset: str = "lattice_mast"

    @field_validator("asset")
    @classmethod
    def _asset(cls, v: str) -> str:
        return check_asset(v, "mast")


class ProceduralClutter(_Model):
    """Seeded horizon clutter added to the listed objects: counts are [min, max] per sequence;
    objects fall at random azimuths (all around) and distances in the given ranges."""

    tree_lines: tuple[Annotated[int, Field(ge=0, le=20)], Annotated[int, Field(ge=0, le=20)]] = (2, 5)
    tree_distance_m: tuple[Annotated[float, Field(gt=5.0)], Annotated[float, Field(gt=5.0)]] = (150.0, 2000.0)
    tree_span_deg: tuple[Annotated[float, Field(gt=0.0, le=360.0)],
                         Annotated[float, Field(gt=0.0, le=360.0)]] = (20.0, 120.0)
    tree_assets: list[str] = Field(default_factory=lambda: ["deciduous", "deciduous", "conifer"], min_length=1)
    buildings: tuple[Annotated[int, Field(ge=0, le=50)], Annotated[int, Field(ge=0, le=50)]] = (0, 4)
    building_distance_m: tuple[Annotated[float, Field(gt=5.0)], Annotated[float, Field(gt=5.0)]] = (100.0, 1500.0)
    building_assets: list[str] = Field(default_factory=lambda: ["house", "house", "barn", "block"], min_length=1)
    masts: tuple[Annotated[int, Field(ge=0, le=20)], Annotated[int, Field(ge=0, le=20)]] = (0, 2)
    mast_distance_m: tuple[Annotated[float, Field(gt=5.0)], Annotated[float, Field(gt=5.0)]] = (200.0, 2500.0)
    mast_assets: list[str] = Field(default_factory=lambda: ["lattice_mast", "pole"], min_length=1)

    @field_validator("tree_assets")
    @classmethod
    def _trees(cls, v: list[str]) -> list[str]:
        return [check_asset(a, "trees") for a in v]

    @field_validator("building_assets")
    @classmethod
    def _buildings(cls, v: list[str]) -> list[str]:
        return [check_asset(a, "building") for a in v]

    @field_validator("mast_assets")
    @classmethod
    def _masts(cls, v: list[str]) -> list[str]:
        return [check_asset(a, "mast") for a in v]

    @model_validator(mode="after")
    def _ordered(self) -> "ProceduralClutter":
        for name in ("tree_lines", "tree_distance_m", "tree_span_deg", "buildings", "building_distance_m",
                     "masts", "mast_distance_m"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ValueError(f"{name} must be [min, max] with min <= max, got {[lo, hi]}")
        return self


class Terrain(_Model):
    """The ground and the horizon clutter (off unless a scene gives ``terrain``). The ground is a
    disc of radius ground_radius_m around the rig, flat or gently rolling (relief_m: rms height of
    hills a few hundred metres across, zero under the rig); its surface and every object's
    temperature follow the energy balance of simulator.physics.terrain_thermal (sun, clouds, air);
    LWIR is emitted (eps L(T)) plus the reflected sky. ``emissivity`` overrides an asset's LWIR
    emissivity by asset name."""

    ground: str = "grass"
    ground_radius_m: float = Field(default=3000.0, ge=50.0, le=20000.0)
    relief_m: float = Field(default=0.0, ge=0.0, le=50.0)
    tree_lines: list[TreeLine] = Field(default_factory=list)
    buildings: list[Building] = Field(default_factory=list)
    masts: list[Mast] = Field(default_factory=list)
    procedural: ProceduralClutter | None = None
    emissivity: dict[str, Annotated[float, Field(gt=0.0, le=1.0)]] = Field(default_factory=dict)

    @field_validator("ground")
    @classmethod
    def _ground(cls, v: str) -> str:
        return check_asset(v, "ground")

    @field_validator("emissivity")
    @classmethod
    def _known(cls, v: dict[str, float]) -> dict[str, float]:
        from scenes.terrain_assets import TERRAIN_ASSETS

        for name in v:
            if name not in TERRAIN_ASSETS:
                raise ValueError(f"unknown terrain asset {name!r}; known: {', '.join(sorted(TERRAIN_ASSETS))}")
        return v


class Scenario(_Model):
    schema_version: Literal[1] = SCHEMA_VERSION
    name: PlainName
    description: str = ""
    duration_s: float = Field(gt=0.0, le=3600.0)
    frame_rate_hz: float = Field(default=30.0, gt=0.0, le=240.0)
    seed: int | None = Field(default=None, ge=0)
    targets: list[Target] = Field(min_length=1)
    sky: Sky = Field(default_factory=Sky)
    atmosphere: Atmosphere = Field(default_factory=Atmosphere)
    camera_rig: CameraRig
    terrain: Terrain | None = Field(default=None, description="ground and horizon clutter; None = sky only")

    @model_validator(mode="after")
    def _names(self) -> "Scenario":
        names = [t.name for t in self.targets]
        if len(set(names)) != len(names):
            raise ValueError(f"target names must be unique, got {names}")
        track = self.camera_rig.track_target
        if track is not None and track not in names:
            raise ValueError(f"camera_rig.track_target {track!r} is not a target name; targets: {names}")
        return self

    @model_validator(mode="after")
    def _thermal_range(self) -> "Scenario":
        """Refuse a thermal scale whose ceiling ((2^adc_bits - 1) x kelvin_per_count) would clip the hottest
        planned temperature: clipped counts would erase the target and fake a thermal crossover."""
        kpc = self.camera_rig.thermal.kelvin_per_count
        counts_max = 2 ** getattr(self.camera_rig.thermal, "adc_bits", 16) - 1
        hottest, where = self.atmosphere.air_temperature_k, "atmosphere.air_temperature_k"
        for t in self.targets:
            th = t.thermal
            candidates: dict[str, float] = {}
            if th.mode == "absolute":
                candidates.update({f"targets[{t.name}].thermal.absolute_k.{r}": v for r, v in th.absolute_k.items()})
            elif th.mode == "offset":
                for label, offsets in (("offsets_k", th.offsets_k), ("offsets_end_k", th.offsets_end_k or {})):
                    candidates.update({f"targets[{t.name}].thermal.{label}.{r}": self.atmosphere.air_temperature_k + v
                                       for r, v in offsets.items()})
            else:
                top = max(th.contrast_k, th.contrast_end_k if th.contrast_end_k is not None else th.contrast_k)
                candidates[f"targets[{t.name}].thermal.contrast_k"] = self.atmosphere.air_temperature_k + top
            for label, value in candidates.items():
                if value > hottest:
                    hottest, where = value, label
        ceiling = counts_max * kpc
        if ceiling < hottest + THERMAL_HEADROOM_K:
            need = (hottest + THERMAL_HEADROOM_K) / counts_max
            raise ValueError(
                f"camera_rig.thermal.kelvin_per_count {kpc:g} puts the counts' ceiling ({counts_max}) at {ceiling:.1f} "
                "K, below the "
                f"hottest planned temperature {hottest:.1f} K ({where}) + {THERMAL_HEADROOM_K:g} K headroom: every "
                f"hot pixel would clip; use kelvin_per_count >= {need:.3g}")
        return self

    @property
    def n_frames(self) -> int:
        return max(1, int(round(self.duration_s * self.frame_rate_hz)))
