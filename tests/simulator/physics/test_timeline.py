import datetime as dt

import numpy as np
import pytest

from scenes import load_scenario
from scenes.schema import Flyby, Hover, Orbit, Waypoints
from simulator.physics.sky import (
    direction_from_elevation_azimuth,
    solar_elevation_azimuth_deg,
)
from simulator.physics.timeline import build_timeline, rotor_hover_rpm
from simulator.physics.trajectory import positions_m
from simulator.seeding import rng_for


def _with_trajectory(preset: str, trajectory, kind: str | None = None):
    scenario = load_scenario(preset)
    target = scenario.targets[0].model_copy(update={"trajectory": trajectory, **({"kind": kind} if kind else {})})
    return scenario.model_copy(update={"targets": [target]})


def test_waypoints_are_flown_at_the_declared_speed():
    traj = Waypoints(points_m=[(0, 100, 20), (30, 100, 20), (30, 140, 25)], speed_mps=7.5)
    t = np.linspace(0, 5, 501)
    pos = positions_m(traj, t, rng_for(0, "trajectory", 0))
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=1) / np.diff(t)
    assert np.allclose(speed, 7.5, rtol=0.02)
    assert np.allclose(pos[0], (0, 100, 20))


def test_orbit_and_flyby_geometry():
    t = np.array([0.0, 1.0])
    orbit = positions_m(Orbit(center_m=(0, 0, 50), radius_m=20, speed_mps=10), t, rng_for(0, "trajectory", 0))
    assert np.allclose(np.linalg.norm(orbit[:, :2], axis=1), 20)
    assert np.isclose(np.arctan2(orbit[1, 1], orbit[1, 0]), 0.5)  # 10 m/s on r = 20 m: 0.5 rad/s, counter-clockwise
    fly = positions_m(Flyby(start_m=(1, 2, 3), velocity_mps=(4, 0, -1)), t, rng_for(0, "trajectory", 0))
    assert np.allclose(fly[1], (5, 2, 2))


def test_hover_drift_is_seeded_and_bounded():
    traj = Hover(center_m=(0, 50, 10), drift_m=0.5)
    t = np.linspace(0, 20, 400)
    a = positions_m(traj, t, rng_for(1, "trajectory", 0))
    b = positions_m(traj, t, rng_for(1, "trajectory", 0))
    c = positions_m(traj, t, rng_for(2, "trajectory", 0))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.abs(a - (0, 50, 10)).max() <= 0.5 + 1e-9


def test_hovering_multirotor_turns_at_hover_rpm_and_stays_level():
    scenario = _with_trajectory("clear_day_quad", Hover(center_m=(0, 100, 20), drift_m=0.0))
    track = build_timeline(scenario, 0).targets[0]
    assert np.allclose(track.rotor_rpm.mean(axis=1), rotor_hover_rpm("quadcopter", 0.45), rtol=0.01)
    assert np.allclose(track.rotation[:, :, 2], (0, 0, 1), atol=1e-6)


def test_forward_flight_tilts_multirotor_forward_and_raises_rpm():
    scenario = _with_trajectory("clear_day_quad", Flyby(start_m=(0, 100, 20), velocity_mps=(12, 0, 0)))
    track = build_timeline(scenario, 0).targets[0]
    up = track.rotation[10, :, 2]
    assert up[0] > 0.05  # thrust tilts toward +x to balance drag
    assert track.rotor_rpm[10].mean() > rotor_hover_rpm("quadcopter", 0.45)


def test_fixed_wing_banks_into_a_counter_clockwise_turn():
    scenario = _with_trajectory("fixed_wing_pass", Orbit(center_m=(0, 300, 60), radius_m=60, speed_mps=20))
    track = build_timeline(scenario, 0).targets[0]
    forward, left, up = (track.rotation[20, :, k] for k in range(3))
    expected_bank = np.arctan2(20 ** 2 / 60, 9.81)
    toward_centre = (np.array([0, 300, 60]) - track.position_m[20])
    toward_centre /= np.linalg.norm(toward_centre)
    assert np.dot(up, toward_centre) > 0  # the lift vector leans into the turn
    assert np.isclose(np.arccos(np.clip(up[2], -1, 1)), expected_bank, atol=np.radians(3))
    assert np.allclose(np.cross(forward, left), up, atol=1e-9)


def test_solar_position_matches_almanac_values():
    el, az = solar_elevation_azimuth_deg(dt.datetime(2026, 6, 21, 12, 0), 0.0, 0.0)
    assert el == pytest.approx(90 - 23.44, abs=0.5)
    assert az == pytest.approx(0.0, abs=2.0) or az == pytest.approx(360.0, abs=2.0)
    el, _ = solar_elevation_azimuth_deg(dt.datetime(2026, 3, 20, 12, 0), 52.0, 0.0)
    assert el == pytest.approx(38.0, abs=1.0)
    assert np.allclose(direction_from_elevation_azimuth(0.0, 90.0), (1, 0, 0), atol=1e-12)


def test_thermal_camera_offset_moves_and_turns_it():
    scenario = load_scenario("swarm_3")
    timeline = build_timeline(scenario, 0, n_frames=2)
    rgb, th = timeline.cameras["rgb"], timeline.cameras["thermal"]
    right = np.cross(rgb.forward[0], rgb.up[0])
    assert np.allclose(th.origin_m[0] - rgb.origin_m[0], 0.12 * right, atol=1e-9)
    angle = np.degrees(np.arccos(np.clip(np.dot(th.forward[0], rgb.forward[0]), -1, 1)))
    assert angle == pytest.approx(0.3, abs=1e-6)


def test_retuned_rotors_scale_every_rotor_and_record_the_hover_rpm():
    from simulator.physics.timeline import retuned_rotors

    scenario = _with_trajectory("clear_day_quad", Hover(center_m=(0, 100, 20), drift_m=0.0))
    track = build_timeline(scenario, 0).targets[0]
    before = track.rotor_rpm.copy()
    law = rotor_hover_rpm("quadcopter", track.size_m)
    tuned = retuned_rotors(track, 4000.0)
    assert tuned.hover_rpm == 4000.0 and track.hover_rpm is None
    assert np.allclose(tuned.rotor_rpm.mean(axis=1), 4000.0, rtol=0.01)
    assert np.allclose(tuned.rotor_rpm / before, 4000.0 / law)             # detune and fluctuation kept, scaled
    assert np.allclose(tuned.rotor_angle_rad, track.rotor_angle_rad * 4000.0 / law)
    assert np.array_equal(track.rotor_rpm, before)                           # the original track is untouched
    with pytest.raises(ValueError, match="hover_rpm"):
        retuned_rotors(track, 0.0)
    bird = build_timeline(_with_trajectory("clear_day_quad", Hover(center_m=(0, 100, 20)), kind="bird"), 0).targets[0]
    with pytest.raises(ValueError, match="no rotor"):
        retuned_rotors(bird, 4000.0)


def test_manoeuvre_rpm_factor_has_the_drawn_std_and_correlation_time():
    from simulator.physics.timeline import manoeuvre_rpm_factor

    a = manoeuvre_rpm_factor(rng_for(1, "trajectory", 7), 20000, 25.0, 0.05, 1.0)
    assert np.array_equal(a, manoeuvre_rpm_factor(rng_for(1, "trajectory", 7), 20000, 25.0, 0.05, 1.0))
    assert np.std(a) == pytest.approx(0.05, rel=0.1) and np.mean(a) == pytest.approx(1.0, abs=0.01)
    x = a - a.mean()
    lag = 25                                                    # one correlation time: autocorrelation e^-1
    assert np.mean(x[:-lag] * x[lag:]) / np.var(x) == pytest.approx(np.exp(-1.0), abs=0.08)
    assert np.all(manoeuvre_rpm_factor(rng_for(2, "trajectory", 7), 2000, 25.0, 0.8, 1.0) >= 0.5)    # floored
    assert np.array_equal(manoeuvre_rpm_factor(rng_for(1, "trajectory", 7), 50, 25.0, 0.0, 1.0), np.ones(50))
    with pytest.raises(ValueError):
        manoeuvre_rpm_factor(rng_for(1, "trajectory", 7), 50, 25.0, 0.05, 0.0)


def test_retuned_rotors_take_a_per_frame_factor_on_every_rotor():
    from simulator.physics.timeline import retuned_rotors

    scenario = _with_trajectory("clear_day_quad", Hover(center_m=(0, 100, 20), drift_m=0.0))
    track = build_timeline(scenario, 0).targets[0]
    factor = np.linspace(0.9, 1.1, track.rotor_rpm.shape[0])
    plain, wandering = retuned_rotors(track, 4000.0), retuned_rotors(track, 4000.0, factor)
    assert np.allclose(wandering.rotor_rpm, plain.rotor_rpm * factor[:, None])
    assert wandering.hover_rpm == 4000.0                                   # the hover reference stays
    with pytest.raises(ValueError, match="rpm_factor"):
        retuned_rotors(track, 4000.0, factor[:-1])
    with pytest.raises(ValueError, match="rpm_factor"):
        retuned_rotors(track, 4000.0, -factor)


def test_rotor_rpm_fluctuation_is_zero_sum_and_correlated():
    from simulator.physics.timeline import RPM_FLUCTUATION_STD, rotor_rpm_fluctuation

    f = rotor_rpm_fluctuation(rng_for(1, "rotor_detune", 0), 20_000, 4, 30.0)
    assert np.allclose(f.mean(axis=1), 1.0)
    std = float(np.std(f - 1.0))
    assert RPM_FLUCTUATION_STD[0] * 0.8 <= std <= RPM_FLUCTUATION_STD[1] * 1.2
    x = f[:, 0] - 1.0
    lag1 = float(np.corrcoef(x[:-1], x[1:])[0, 1])
    assert lag1 > 0.5                                           # a Gauss-Markov process, not white jitter
    assert np.array_equal(rotor_rpm_fluctuation(rng_for(1, "rotor_detune", 0), 10, 1, 30.0), np.ones((10, 1)))


def test_lapse_rate_cools_a_target_by_its_height_above_the_camera_and_is_off_by_default():
    """ICAO 6.5 K/km: an airliner 1,000 m above the camera flies in air 6.5 K colder, every part by the same
    amount; a climbing one cools frame by frame; unset, the parts keep the sensor's air (the former model)."""
    base = _with_trajectory("clear_day_quad", Hover(center_m=(0, 3000, 1001.5), drift_m=0.0), kind="airliner")
    rig_z = base.camera_rig.position_m[2]
    assert rig_z == pytest.approx(1.5)
    cold = base.model_copy(update={"atmosphere": base.atmosphere.model_copy(update={"lapse_rate_k_per_km": 6.5})})
    plain, lapsed = (build_timeline(s, 0, 4).targets[0].part_temperature_k for s in (base, cold))
    for role in plain:
        assert np.allclose(plain[role] - lapsed[role], 6.5, atol=0.01), role
    assert np.allclose(plain["engine"], base.atmosphere.air_temperature_k + 80.0)   # the offsets stand on the air
    climb = _with_trajectory("clear_day_quad", Flyby(start_m=(0, 3000, 501.5), velocity_mps=(0, 0, 300)),
                             kind="airliner")
    climb = climb.model_copy(update={"atmosphere": climb.atmosphere.model_copy(update={"lapse_rate_k_per_km": 6.5})})
    wing = build_timeline(climb, 0, 4).targets[0].part_temperature_k["wing"]
    assert np.all(np.diff(wing) < 0)
    assert "lapse_rate_k_per_km" not in base.atmosphere.model_dump()    # unset: older scenes keep their bytes
