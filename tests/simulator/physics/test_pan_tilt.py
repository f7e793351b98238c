"""Pan-tilt tracking controller: lag, pointing error, losses (hold), prefix determinism."""
import numpy as np
import pytest

from scenes import load_scenario
from scenes.errors import UserInputError
from scenes.loader import scenario_from_dict
from scenes.schema import Tracking
from simulator.physics.timeline import build_timeline, pan_tilt_pointing


def _circle(n, rate_deg_s, fps, r=300.0):
    t = np.arange(n) / fps
    az = np.radians(rate_deg_s) * t
    return np.stack([r * np.sin(az), r * np.cos(az), np.zeros(n)], -1), np.zeros((n, 3))


def _azimuth(forward):
    return np.degrees(np.unwrap(np.arctan2(forward[:, 0], forward[:, 1])))


def test_first_order_lag_trails_a_constant_rate_target_by_rate_times_lag():
    fps, rate, lag = 100.0, 5.0, 0.4
    aim, origin = _circle(800, rate, fps)
    fwd, lost = pan_tilt_pointing(aim, origin, Tracking(lag_s=lag, error_deg=0.0), fps,
                                  np.random.default_rng(0), np.random.default_rng(1))
    trail = rate * np.arange(800) / fps - _azimuth(fwd)
    # discrete first-order filter: steady trail = rate dt (1 - a) / a with a = 1 - exp(-dt/lag) ~ rate lag
    a = 1 - np.exp(-1 / fps / lag)
    assert trail[-1] == pytest.approx(rate / fps * (1 - a) / a, rel=1e-3)
    assert trail[-1] == pytest.approx(rate * lag, rel=0.02)
    assert not lost.any()


def test_pointing_error_has_the_asked_rms_and_zero_lag_follows_the_command():
    fps = 30.0
    aim, origin = _circle(20000, 0.0, fps)
    fwd, _ = pan_tilt_pointing(aim, origin, Tracking(lag_s=0.0, error_deg=0.5, error_period_s=0.5), fps,
                               np.random.default_rng(2), np.random.default_rng(3))
    az, el = _azimuth(fwd), np.degrees(np.arcsin(fwd[:, 2]))
    assert np.std(az) == pytest.approx(0.5, rel=0.1) and np.std(el) == pytest.approx(0.5, rel=0.1)
    # correlated over error_period_s: lag-1 autocorrelation = exp(-dt / period)
    r1 = np.corrcoef(az[:-1], az[1:])[0, 1]
    assert r1 == pytest.approx(np.exp(-1 / fps / 0.5), abs=0.01)


def test_a_track_loss_holds_the_head_then_reacquires():
    fps = 30.0
    aim, origin = _circle(600, 4.0, fps)
    fwd, lost = pan_tilt_pointing(aim, origin, Tracking(lag_s=0.2, error_deg=0.0, loss_rate_hz=0.3, loss_s=(1.0, 1.0)),
                                  fps,
                                  np.random.default_rng(0), np.random.default_rng(7))
    assert lost.any() and not lost.all()
    i = np.flatnonzero(lost)
    held = fwd[i[0]:i[0] + 30]
    assert np.allclose(held, held[0])   # first loss: 1 s held
    end = np.flatnonzero(~lost[i[0]:])[0] + i[0]
    trail = 4.0 * np.arange(600) / fps - _azimuth(fwd)
    assert trail[end - 1] > 3.5                  # ~1 s x 4 deg/s behind when the loss ends
    assert np.min(trail[end:end + 60]) < 0.85  # re-acquired within 2 s: back to the steady 4 x 0.2 deg


def test_timeline_with_tracking_is_seeded_and_a_prefix_of_the_full_sequence():
    data = load_scenario("clear_day_quad").model_dump(mode="json")
    data["camera_rig"]["tracking"] = {"lag_s": 0.3, "error_deg": 0.5, "loss_rate_hz": 0.5}
    scene = scenario_from_dict(data)
    full, part, other = build_timeline(scene, 4), build_timeline(scene, 4, 40), build_timeline(scene, 5)
    assert np.array_equal(full.cameras["rgb"].forward[:40], part.cameras["rgb"].forward)
    assert not np.array_equal(full.cameras["rgb"].forward, other.cameras["rgb"].forward)
    # the drone is off centre (pointing error), not on the optical axis
    cam = full.cameras["rgb"]
    px = np.array([cam.project(i, full.targets[0].position_m[i])[0][0] for i in range(full.n_frames)])
    off = np.hypot(px[:, 0] - cam.width_px / 2, px[:, 1] - cam.height_px / 2)
    assert np.median(off) > 5.0
    perfect = build_timeline(load_scenario("clear_day_quad"), 4)
    c = perfect.cameras["rgb"]
    px0 = c.project(10, perfect.targets[0].position_m[10])[0][0]
    assert np.allclose(px0, [c.width_px / 2, c.height_px / 2], atol=1e-6)


def test_tracking_on_a_fixed_camera_is_refused_naming_the_field():
    data = load_scenario("out_of_view").model_dump(mode="json")
    data["camera_rig"]["tracking"] = {"lag_s": 0.3}
    with pytest.raises(UserInputError, match="camera_rig: .*tracking needs track_target"):
        scenario_from_dict(data)
