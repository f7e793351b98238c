"""Scenario + seed -> Timeline: per-frame poses, velocities, attitude, rotor RPM and part temperatures.

The timeline is the shared clock of every sensor: the renderer draws it, the acoustic and RF
synthesisers sample it (``TargetTrack.position_at`` interpolates between frames).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from scenes.defaults import offset_for
from scenes.schema import HelicopterRotor, Scenario, Target
from simulator.physics import thermal
from simulator.physics.sky import ThermalSky
from simulator.physics.trajectory import GRAVITY_MPS2, positions_m
from simulator.seeding import rng_for

_DIFF_STEP_S = 1e-3
MULTIROTOR_DRAG_PER_M = 0.02


@dataclass
class TargetTrack:
    """One target over the sequence. Arrays are indexed by frame."""

    target_id: int
    name: str
    kind: str
    size_m: float
    position_m: np.ndarray          # (F, 3)
    velocity_mps: np.ndarray        # (F, 3)
    rotation: np.ndarray            # (F, 3, 3) object->world; columns forward, left, up
    rotor_rpm: np.ndarray           # (F, n_rotors)
    rotor_angle_rad: np.ndarray     # (F,) integrated blade angle, for prop animation
    flap_phase_rad: np.ndarray      # (F,) birds; zeros otherwise
    part_temperature_k: dict[str, np.ndarray] = field(default_factory=dict)  # role -> (F,)
    n_blades: int = 0
    hover_rpm: float | None = None  # rotors' hover speed when it differs from rotor_hover_rpm(kind, size_m)

    def position_at(self, times_s: np.ndarray, frame_times_s: np.ndarray) -> np.ndarray:
        """Linear interpolation of position at arbitrary times (for audio/RF sample clocks)."""
        return np.stack([np.interp(times_s, frame_times_s, self.position_m[:, k]) for k in range(3)], -1)


@dataclass
class CameraTrack:
    """A camera's pose per frame: origin, viewing direction and up vector (world frame)."""

    name: str
    origin_m: np.ndarray    # (F, 3)
    forward: np.ndarray     # (F, 3) unit
    up: np.ndarray          # (F, 3) unit, orthogonal to forward
    width_px: int
    height_px: int
    hfov_deg: float

    @property
    def focal_px(self) -> float:
        return (self.width_px / 2) / np.tan(np.radians(self.hfov_deg) / 2)

    def project(self, frame: int, points_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pinhole projection: pixel coordinates (x right, y down, pixel centres at +0.5) and depth."""
        fwd, up = self.forward[frame], self.up[frame]
        right = np.cross(fwd, up)
        rel = np.atleast_2d(points_m) - self.origin_m[frame]
        depth = rel @ fwd
        safe = np.where(np.abs(depth) < 1e-9, 1e-9, depth)
        x = self.width_px / 2 + self.focal_px * (rel @ right) / safe
        y = self.height_px / 2 - self.focal_px * (rel @ up) / safe
        return np.stack([x, y], -1), depth


@dataclass
class Timeline:
    scenario: Scenario
    seed: int
    times_s: np.ndarray             # (F,)
    targets: list[TargetTrack]
    cameras: dict[str, CameraTrack]  # "rgb", "thermal"
    microphone_position_m: np.ndarray  # (F, 3): at the camera rig

    @property
    def n_frames(self) -> int:
        return int(self.times_s.size)


def retuned_rotors(track: TargetTrack, hover_rpm: float, rpm_factor: np.ndarray | None = None) -> TargetTrack:
    """A copy of a rotorcraft ``track`` whose rotors hover at ``hover_rpm`` instead of
    :func:`rotor_hover_rpm` of its kind and size: every rotor speed (flight-state changes, detune and
    fluctuation included) and the blade angle scale by the same factor, and ``hover_rpm`` is recorded
    so the acoustic model's thrust reference follows (issue 24: the sim2real audio draws the blade-passing
    frequency of the benchmark's drones instead of the size law). ``rpm_factor`` (F,), e.g.
    :func:`manoeuvre_rpm_factor`, multiplies every rotor's speed per frame on top (the hover reference
    stays ``hover_rpm``: a faster rotor is a thrust change)."""
    import dataclasses

    if not hover_rpm > 0:
        raise ValueError(f"hover_rpm must be > 0, got {hover_rpm}")
    law = rotor_hover_rpm(track.kind, track.size_m)
    if not law > 0:
        raise ValueError(f"kind: {track.kind!r} has no rotor to retune")
    factor = float(hover_rpm) / law
    rpm = np.asarray(track.rotor_rpm) * factor
    if rpm_factor is not None:
        per_frame = np.asarray(rpm_factor, dtype=np.float64).reshape(-1)
        if per_frame.size != rpm.shape[0] or not np.all(per_frame > 0):
            raise ValueError(f"rpm_factor: need {rpm.shape[0]} positive per-frame factors, got {per_frame.size}")
        rpm = rpm * per_frame[:, None]
    return dataclasses.replace(track, rotor_rpm=rpm, rotor_angle_rad=np.asarray(track.rotor_angle_rad) * factor,
                               hover_rpm=float(hover_rpm))


def manoeuvre_rpm_factor(rng: np.random.Generator, n_frames: int, frame_rate_hz: float, std: float,
                         time_s: float) -> np.ndarray:
    """Per-frame factor (F,) on every rotor's speed at once: 1 + a stationary Gauss-Markov (AR(1)) series of
    relative std ``std`` and correlation time ``time_s``, floored at 0.5. A flying multirotor changes its
    collective rotor speed with every climb, acceleration and gust correction; the zero-sum
    :func:`rotor_rpm_fluctuation` (attitude) leaves the total thrust, hence the blade-passing line's mean, alone."""
    if not (std >= 0 and time_s > 0 and frame_rate_hz > 0):
        raise ValueError(f"need std >= 0, time_s > 0, frame_rate_hz > 0; got {std}, {time_s}, {frame_rate_hz}")
    from scipy.signal import lfilter

    a = float(np.exp(-1.0 / (frame_rate_hz * time_s)))
    drive = rng.standard_normal(n_frames)
    drive[0] /= np.sqrt(max(1.0 - a * a, 1e-12))                # start in the stationary distribution
    x = lfilter([np.sqrt(1.0 - a * a)], [1.0, -a], drive)
    return np.maximum(1.0 + std * x, 0.5)


def rotor_hover_rpm(kind: str, size_m: float) -> float:
    """Hover RPM scaled from a 0.45 m quad at 5500 rpm: rpm ~ size^-0.5 (larger props turn slower)."""
    if kind in ("quadcopter", "hexacopter"):
        return 5500.0 * (0.45 / size_m) ** 0.5
    if kind == "fixed_wing":
        return 7000.0 * (1.5 / size_m) ** 0.5
    if kind == "helicopter":
        return 400.0
    return 0.0


# Flight-controller RPM corrections of each rotor (attitude hold, gusts): relative std and correlation
# time drawn per target (domain randomisation; Heutschi et al. 2020 model drone pitch with random RPM
# jitter; the spread is an assumption, not a fit). Zero-sum across rotors: attitude corrections trade
# thrust between rotors and leave the total (the hover RPM of the flight state) unchanged.
RPM_FLUCTUATION_STD = (0.005, 0.03)
RPM_FLUCTUATION_TIME_S = (0.05, 0.5)


def rotor_rpm_fluctuation(rng: np.random.Generator, n_frames: int, n_rotors: int, frame_rate_hz: float) -> np.ndarray:
    """Multiplicative per-rotor RPM factors (F, R): 1 + a zero-sum Gauss-Markov (AR(1)) fluctuation with a
    drawn relative std and correlation time (``RPM_FLUCTUATION_STD``, ``RPM_FLUCTUATION_TIME_S``)."""
    if n_rotors < 2 or n_frames < 1:
        return np.ones((n_frames, n_rotors))
    std = rng.uniform(*RPM_FLUCTUATION_STD)
    tau = rng.uniform(*RPM_FLUCTUATION_TIME_S)
    a = float(np.exp(-1.0 / (frame_rate_hz * tau)))
    from scipy.signal import lfilter

    drive = rng.standard_normal((n_frames, n_rotors))
    drive[0] /= np.sqrt(max(1.0 - a * a, 1e-12))                # start in the stationary distribution
    x = lfilter([np.sqrt(1.0 - a * a)], [1.0, -a], drive, axis=0)
    x -= x.mean(axis=1, keepdims=True)
    x *= np.sqrt(n_rotors / (n_rotors - 1.0))                  # per-rotor std stays ``std`` after removing the mean
    return 1.0 + std * x


def _rotor_count(kind: str) -> int:
    return {"quadcopter": 4, "hexacopter": 6, "fixed_wing": 1, "helicopter": 1}.get(kind, 0)


def _normalise(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n < 1e-12, 1.0, n)


def _heading(velocity: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Unit horizontal heading per frame; keeps the last valid heading while hovering."""
    horiz = velocity.copy()
    horiz[:, 2] = 0
    out = np.empty_like(horiz)
    last = fallback
    for i, h in enumerate(horiz):
        n = np.linalg.norm(h)
        if n > 0.3:
            last = h / n
        out[i] = last
    return out


def _attitude(kind: str, vel: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (F,3,3) and thrust/g ratio (F,) following the motion."""
    z_world = np.array([0.0, 0.0, 1.0])
    heading = _heading(vel, np.array([1.0, 0.0, 0.0]))
    if kind in ("quadcopter", "hexacopter"):
        speed = np.linalg.norm(vel, axis=-1, keepdims=True)
        thrust = acc + GRAVITY_MPS2 * z_world + MULTIROTOR_DRAG_PER_M * vel * speed
        up = _normalise(thrust)
        forward = _normalise(heading - np.sum(heading * up, -1, keepdims=True) * up)
        ratio = np.linalg.norm(thrust, axis=-1) / GRAVITY_MPS2
    else:
        forward = np.where(np.linalg.norm(vel, axis=-1, keepdims=True) > 0.3, _normalise(vel), heading)
        left0 = _normalise(np.cross(z_world, forward))
        up0 = np.cross(forward, left0)
        horiz_speed = np.linalg.norm(vel[:, :2], axis=-1)
        yaw_rate = (vel[:, 0] * acc[:, 1] - vel[:, 1] * acc[:, 0]) / np.maximum(horiz_speed ** 2, 1e-6)
        bank = np.arctan2(horiz_speed * yaw_rate, GRAVITY_MPS2)
        bank = np.clip(bank, -np.radians(60), np.radians(60))[:, None]
        up = np.cos(bank) * up0 + np.sin(bank) * left0
        ratio = 1.0 / np.cos(bank[:, 0])
    left = np.cross(up, forward)
    rotation = np.stack([forward, left, up], axis=-1)
    return rotation, ratio


def _part_roles(kind: str) -> tuple[str, ...]:
    return {
        "quadcopter": ("body", "arm", "motor", "prop", "battery", "camera"),
        "hexacopter": ("body", "arm", "motor", "prop", "battery", "camera"),
        "fixed_wing": ("fuselage", "wing", "tail", "motor", "prop", "body"),
        "bird": ("body", "head", "wing", "feather"),
        "airliner": ("fuselage", "wing", "tail", "engine"),
        "helicopter": ("fuselage", "tail", "engine", "exhaust", "body", "prop"),
    }[kind]


def _air_at(scenario: Scenario, position: np.ndarray, rig_origin: np.ndarray, air_k: float) -> float | np.ndarray:
    """The air temperature at the target's altitude per frame (``atmosphere.lapse_rate_k_per_km`` over its
    height above the camera), or the air at the sensor when no lapse rate is set."""
    lapse = scenario.atmosphere.lapse_rate_k_per_km
    if lapse is None:
        return air_k
    return air_k - lapse * (position[:, 2] - rig_origin[2]) / 1000.0


def _part_temperatures(scenario: Scenario, target: Target, position: np.ndarray, rig_origin: np.ndarray,
                       sky: ThermalSky, times_s: np.ndarray) -> dict[str, np.ndarray]:
    from scenes.defaults import material_for

    air_k = scenario.atmosphere.air_temperature_k
    ramp = times_s / max(scenario.duration_s, 1e-9)
    out: dict[str, np.ndarray] = {}
    mode = target.thermal.mode
    if mode == "match_background":
        rel = position - rig_origin
        range_m = np.linalg.norm(rel, axis=-1)
        sight = rel / range_m[:, None]
        sight_elevation = np.arcsin(np.clip(sight[:, 2], -1.0, 1.0))
        background = sky.radiance(sight)
        bg_bright_k = thermal.brightness_temperature(background)
        end = target.thermal.contrast_end_k if target.thermal.contrast_end_k is not None else target.thermal.contrast_k
        wanted_k = bg_bright_k + target.thermal.contrast_k + (end - target.thermal.contrast_k) * ramp
        tau = sky.lwir.transmission(range_m, sight_elevation)
        surface_needed = (thermal.band_radiance(wanted_k) - sky.lwir.path_radiance(range_m, sight_elevation)) / tau
        reflected = sky.reflected_radiance()
        for role in _part_roles(target.kind):
            eps = material_for(target, role).emissivity
            out[role] = np.array([thermal.temperature_for_surface_radiance(r, eps, reflected) for r in surface_needed])
        return out
    local_air = _air_at(scenario, position, rig_origin, air_k)    # once per target, not per part
    for role in _part_roles(target.kind):
        if mode == "absolute":
            value = target.thermal.absolute_k.get(role, air_k)
            out[role] = np.full(times_s.size, float(value))
        else:
            start, end = offset_for(target, role), offset_for(target, role, end=True)
            out[role] = local_air + start + (end - start) * ramp
    return out


def _helicopter_rotor(target: Target) -> HelicopterRotor:
    """A helicopter's rotor record (the scene schema sets one for every helicopter)."""
    if target.rotor is None:
        raise ValueError(f"target {target.name!r}: a helicopter needs its rotor record")
    return target.rotor


def pan_tilt_pointing(aim_m: np.ndarray, origin_m: np.ndarray, tracking, frame_rate_hz: float,
                      rng_error: np.random.Generator, rng_loss: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(forward (F, 3) unit, lost (F,) bool) of a pan-tilt head tracking ``aim_m`` (see
    scenes.schema.Tracking): command = target direction + Ornstein-Uhlenbeck error per axis;
    during a loss the command holds the last pointing; the head follows through a first-order lag.
    Draws are per frame in order, so a truncated sequence is a prefix of the full one."""
    n = len(aim_m)
    rel = aim_m - origin_m
    az = np.unwrap(np.arctan2(rel[:, 0], rel[:, 1]))
    el = np.arctan2(rel[:, 2], np.hypot(rel[:, 0], rel[:, 1]))
    dt = 1.0 / frame_rate_hz
    sigma = np.radians(tracking.error_deg)
    rho = np.exp(-dt / tracking.error_period_s)
    noise = rng_error.standard_normal((n, 2))
    err = np.empty((n, 2))
    err[0] = sigma * noise[0]
    for i in range(1, n):
        err[i] = rho * err[i - 1] + sigma * np.sqrt(1 - rho * rho) * noise[i]
    lost = np.zeros(n, bool)
    if tracking.loss_rate_hz > 0:
        draws = rng_loss.random((n, 2))
        starts = draws[:, 0] < tracking.loss_rate_hz * dt
        lengths = tracking.loss_s[0] + (tracking.loss_s[1] - tracking.loss_s[0]) * draws[:, 1]
        for s0 in np.flatnonzero(starts):
            lost[s0:s0 + max(1, int(round(lengths[s0] * frame_rate_hz)))] = True
    alpha = 1.0 - np.exp(-dt / tracking.lag_s) if tracking.lag_s > 0 else 1.0
    head = np.empty((n, 2))
    head[0] = (az[0] + err[0, 0] / max(np.cos(el[0]), 0.1), el[0] + err[0, 1])
    for i in range(1, n):
        command = head[i - 1] if lost[i] else np.array([az[i] + err[i, 0] / max(np.cos(el[i]), 0.1), el[i] + err[i, 1]])
        head[i] = head[i - 1] + alpha * (command - head[i - 1])
    h_az, h_el = head[:, 0], np.clip(head[:, 1], -np.radians(89.0), np.radians(89.0))
    forward = np.stack([np.sin(h_az) * np.cos(h_el), np.cos(h_az) * np.cos(h_el), np.sin(h_el)], -1)
    return forward, lost


def _camera_tracks(scenario: Scenario, targets: list[TargetTrack], n_frames: int,
                   seed: int = 0) -> dict[str, CameraTrack]:
    rig = scenario.camera_rig
    origin = np.tile(np.asarray(rig.position_m, dtype=np.float64), (n_frames, 1))
    if rig.track_target is not None and rig.tracking is not None:
        track = next(t for t in targets if t.name == rig.track_target)
        forward, _ = pan_tilt_pointing(track.position_m, origin, rig.tracking, scenario.frame_rate_hz,
                                       rng_for(seed, "tracking", 0), rng_for(seed, "tracking", 1))
        aim = origin + forward
    elif rig.track_target is not None:
        track = next(t for t in targets if t.name == rig.track_target)
        aim = track.position_m
    else:
        aim = np.tile(np.asarray(rig.look_at_m, dtype=np.float64), (n_frames, 1))
    forward = _normalise(aim - origin)
    z_world = np.array([0.0, 0.0, 1.0])
    right = _normalise(np.cross(forward, z_world))
    up = np.cross(right, forward)
    cams = {"rgb": CameraTrack("rgb", origin, forward, up, rig.rgb.width_px, rig.rgb.height_px, rig.rgb.hfov_deg)}
    off = rig.thermal_offset
    yaw, pitch, roll = np.radians([off.yaw_deg, off.pitch_deg, off.roll_deg])
    # offset rotation in the camera frame (x right, y up, z back): yaw about y, pitch about x, roll about z
    ry = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
    rx = np.array([[1, 0, 0], [0, np.cos(pitch), -np.sin(pitch)], [0, np.sin(pitch), np.cos(pitch)]])
    rz = np.array([[np.cos(roll), -np.sin(roll), 0], [np.sin(roll), np.cos(roll), 0], [0, 0, 1]])
    r_off = ry @ rx @ rz
    cam_to_world = np.stack([right, up, -forward], axis=-1)  # (F,3,3) columns x, y, z of the camera frame
    t_origin = origin + cam_to_world @ np.asarray(off.translation_m)
    t_rot = cam_to_world @ r_off
    th = rig.thermal
    cams["thermal"] = CameraTrack("thermal", t_origin, -t_rot[:, :, 2], t_rot[:, :, 1], th.width_px, th.height_px,
                                  th.hfov_deg)
    return cams


def build_timeline(scenario: Scenario, seed: int, n_frames: int | None = None) -> Timeline:
    """Evaluate every target and camera at each frame time. ``n_frames`` truncates the sequence."""
    total = scenario.n_frames
    count = total if n_frames is None else int(n_frames)
    if count < 1:
        raise ValueError(f"n_frames must be >= 1, got {count}")
    count = min(count, total)
    times = np.arange(count) / scenario.frame_rate_hz
    rig_origin = np.asarray(scenario.camera_rig.position_m, dtype=np.float64)
    sky = ThermalSky(scenario.sky, scenario.atmosphere, seed)
    tracks: list[TargetTrack] = []
    h = _DIFF_STEP_S
    for index, target in enumerate(scenario.targets):
        rng = rng_for(seed, "trajectory", index)
        stacked = positions_m(target.trajectory, np.concatenate([times, times - h, times + h]), rng)
        pos, before, after = stacked[:count], stacked[count:2 * count], stacked[2 * count:]
        vel = (after - before) / (2 * h)
        acc = (after - 2 * pos + before) / h ** 2
        if count > 2:
            acc = np.stack([np.convolve(np.pad(acc[:, k], 2, mode="edge"), np.ones(5) / 5, mode="valid")
                            for k in range(3)], -1)
        rotation, thrust_ratio = _attitude(target.kind, vel, acc)
        n_rotors = _rotor_count(target.kind)
        hover = rotor_hover_rpm(target.kind, target.size_m)
        if target.kind == "helicopter":   # constant-speed rotor (governed); collective pitch varies instead
            base_rpm = np.full(count, float(_helicopter_rotor(target).main_rpm))
        elif target.kind == "fixed_wing":
            base_rpm = hover * np.sqrt(np.clip(np.linalg.norm(vel, axis=-1) / 15.0, 0.3, 3.0))
        else:
            base_rpm = hover * np.sqrt(np.clip(thrust_ratio, 0.2, 4.0))
        rotor_rng = rng_for(seed, "rotor_detune", index)
        detune = 1.0 + 0.01 * rotor_rng.standard_normal(n_rotors)
        rpm = base_rpm[:, None] * detune[None, :] * rotor_rpm_fluctuation(rotor_rng, count, n_rotors,
                                                                           scenario.frame_rate_hz)
        angle = np.concatenate([[0.0], np.cumsum(base_rpm[:-1] / 60.0 * 2 * np.pi / scenario.frame_rate_hz)])
        flap = 2 * np.pi * target.wingbeat_hz * times if target.kind == "bird" else np.zeros(count)
        track = TargetTrack(
            target_id=index + 1, name=target.name, kind=target.kind, size_m=target.size_m,
            position_m=pos, velocity_mps=vel, rotation=rotation, rotor_rpm=rpm, rotor_angle_rad=angle,
            flap_phase_rad=flap,
            n_blades=_helicopter_rotor(target).main_blades if target.kind == "helicopter" else (2 if n_rotors else 0),
        )
        track.part_temperature_k = _part_temperatures(scenario, target, pos, rig_origin, sky, times)
        tracks.append(track)
    cameras = _camera_tracks(scenario, tracks, count, seed)
    return Timeline(scenario=scenario, seed=seed, times_s=times, targets=tracks, cameras=cameras,
                    microphone_position_m=cameras["rgb"].origin_m.copy())
