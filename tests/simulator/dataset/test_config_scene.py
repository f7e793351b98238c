"""Scene-realism fields of generation configs: distance bins, fixed field of view, fixed / tracking
camera modes, cloud cover, terrain; null fields leave older configs' scenarios unchanged."""
import math

import numpy as np
import pytest

from scenes.errors import UserInputError
from simulator.dataset.config import _draw_bin, load_generation_config, randomised_scenario

BASE = {"name": "t", "mixture": [{"scenario": "clear_day_quad"}], "frames": 5, "image_size": [96, 80], "spp": 1}
OLD = {"range_m": [100, 120], "trajectory_kinds": ["hover"], "air_temperature_k": [280, 281], "distractors": [1, 1]}


def _cfg(**randomise):
    return load_generation_config({**BASE, "randomise": {**OLD, **randomise}})


def _range(scene):
    return math.dist(scene.targets[0].trajectory.center_m, scene.camera_rig.position_m)


def test_new_fields_leave_every_other_draw_alone():
    plain, clouded = _cfg(), _cfg(cloud_cover=[0.2, 0.6])
    for i in range(4):
        a, b = randomised_scenario(plain, 3, i)[1], randomised_scenario(clouded, 3, i)[1]
        assert a.sky.clouds is None and 0.2 <= b.sky.clouds.coverage <= 0.6
        assert a.model_copy(update={"sky": b.sky}) == b
        assert a.terrain is None and a.camera_rig.tracking is None


def test_distance_bins_follow_their_weights_and_ranges():
    cfg = _cfg(distance_bins=[{"weight": 3, "range_m": [20, 40]}, {"weight": 1, "range_m": [150, 200]}])
    ranges = np.array([_range(randomised_scenario(cfg, 0, i)[1]) for i in range(60)])
    near, far = (ranges > 19) & (ranges < 41), (ranges > 149) & (ranges < 201)
    assert np.all(near | far) and near.any() and far.any()
    draws = np.array([_draw_bin(cfg.randomise.distance_bins, np.random.default_rng(7)) for _ in range(1)]
                     + [_draw_bin(cfg.randomise.distance_bins, rng) for rng in [np.random.default_rng(8)]
                        for _ in range(4000)])
    assert (draws < 100).mean() == pytest.approx(0.75, abs=0.02)   # binomial sd 0.007


def test_fixed_camera_fraction_and_tracking_ranges():
    cfg = _cfg(fixed_camera_fraction=0.5, camera_elevation_deg=[1, 2], hfov_deg=[20, 20],
               tracking_lag_s=[0.2, 0.4], tracking_error_deg=[0.1, 0.3], tracking_loss_rate_hz=[0.0, 0.2])
    fixed = tracked = 0
    for i in range(40):
        rig = randomised_scenario(cfg, 1, i)[1].camera_rig
        assert rig.rgb.hfov_deg == 20.0
        if rig.look_at_m is not None:
            fixed += 1
            d = np.subtract(rig.look_at_m, rig.position_m)
            assert 1.0 - 1e-3 <= math.degrees(math.asin(d[2] / np.linalg.norm(d))) <= 2.0 + 1e-3
            assert rig.tracking is None
        else:
            tracked += 1
            assert 0.2 <= rig.tracking.lag_s <= 0.4 and 0.1 <= rig.tracking.error_deg <= 0.3
    assert fixed > 8 and tracked > 8


def test_terrain_goes_into_every_sequence_and_bad_values_name_the_field():
    cfg = _cfg(terrain={"ground": "field", "procedural": {"tree_lines": [1, 2]}}, distractor_kinds=["helicopter"])
    scene = randomised_scenario(cfg, 0, 0)[1]
    assert scene.terrain.ground == "field" and scene.terrain.procedural.tree_lines == (1, 2)
    assert scene.targets[1].kind == "helicopter" and scene.targets[1].rotor.main_blades == 4
    with pytest.raises(UserInputError, match=r"randomise\.terrain\.ground"):
        _cfg(terrain={"ground": "moss"})
    with pytest.raises(UserInputError, match=r"randomise\.terrain\.emissivity\.asphalt"):
        _cfg(terrain={"emissivity": {"asphalt": -1}})
    with pytest.raises(UserInputError, match="cloud_cover"):
        _cfg(cloud_cover=[0.5, 1.5])


def test_elevation_as_a_fraction_of_the_vertical_field_of_view():
    cfg = _cfg(elevation_fov_fraction=[0.3, 0.3], trajectory_kinds=["hover"], range_m=[200, 200])
    for i in range(5):
        scene = randomised_scenario(cfg, 2, i)[1]
        th = scene.camera_rig.thermal
        vfov = 2 * math.degrees(math.atan(math.tan(math.radians(th.hfov_deg) / 2) * th.height_px / th.width_px))
        c = np.subtract(scene.targets[0].trajectory.center_m, scene.camera_rig.position_m)
        expected_z = max(200.0 * math.sin(math.radians(0.3 * vfov)), 3.0 - scene.camera_rig.position_m[2])
        assert c[2] == pytest.approx(expected_z, abs=2e-3)


def test_tracking_error_scales_with_the_field_of_view():
    cfg = _cfg(tracking_error_fov_fraction=[0.1, 0.1], tracking_lag_s=[0.2, 0.2])
    for i in range(3):
        rig = randomised_scenario(cfg, 4, i)[1].camera_rig
        assert rig.tracking.error_deg == pytest.approx(0.1 * rig.rgb.hfov_deg, abs=1e-3) and rig.tracking.lag_s == 0.2


def test_tracking_error_period_is_drawn_only_where_it_is_set():
    base = _cfg(tracking_error_fov_fraction=[0.1, 0.2], tracking_lag_s=[0.2, 0.4])
    slow = _cfg(tracking_error_fov_fraction=[0.1, 0.2], tracking_lag_s=[0.2, 0.4], tracking_error_period_s=[30, 60])
    for i in range(4):
        a, b = randomised_scenario(base, 4, i)[1], randomised_scenario(slow, 4, i)[1]
        assert a.camera_rig.tracking.error_period_s == 1.5            # the schema's default
        assert 30.0 <= b.camera_rig.tracking.error_period_s <= 60.0
        # the same offsets and lag: the period is one extra draw after the others
        assert (b.camera_rig.tracking.error_deg, b.camera_rig.tracking.lag_s) == \
            (a.camera_rig.tracking.error_deg, a.camera_rig.tracking.lag_s)
    with pytest.raises(UserInputError, match="tracking_error_period_s"):
        _cfg(tracking_error_period_s=[-1, 2])


def test_a_slow_pointing_error_keeps_the_camera_still_between_frames():
    """Pan-tilt head of the timeline: with a 30 s error correlation time the per-frame pointing step is a
    small fraction of the 1.5 s default's (the real platform is nearly still between frames)."""
    from scenes.schema import Tracking
    from simulator.physics.timeline import pan_tilt_pointing

    aim = np.tile([0.0, 100.0, 10.0], (60, 1))
    steps = {}
    for period in (1.5, 30.0):
        fwd, _ = pan_tilt_pointing(aim, np.zeros((60, 3)), Tracking(lag_s=0.3, error_deg=3.0, error_period_s=period),
                                   30.0, np.random.default_rng(0), np.random.default_rng(1))
        steps[period] = float(np.median(np.degrees(np.arccos(np.clip(np.sum(fwd[1:] * fwd[:-1], 1), -1, 1)))))
    assert steps[30.0] < 0.3 * steps[1.5]


def test_multirotor_frame_warming_heats_only_body_and_arms_and_leaves_every_other_draw_alone():
    from scenes.defaults import offset_for

    plain, warm = _cfg(), _cfg(multirotor_frame_warming_k=[4, 9])
    for i in range(4):
        a, b = randomised_scenario(plain, 3, i)[1], randomised_scenario(warm, 3, i)[1]
        drone_a, drone_b = a.targets[0], b.targets[0]
        assert drone_b.kind in ("quadcopter", "hexacopter")
        delta = offset_for(drone_b, "body") - offset_for(drone_a, "body")
        assert 4.0 <= delta <= 9.0
        assert offset_for(drone_b, "arm") - offset_for(drone_a, "arm") == pytest.approx(delta, abs=1e-3)
        for role in ("motor", "battery", "prop", "camera"):
            assert offset_for(drone_b, role) == offset_for(drone_a, role)
        # the distractor (a bird, a plane...) and everything else are untouched
        assert a.targets[1:] == b.targets[1:]
        assert a.model_copy(update={"targets": b.targets}) == b
    assert randomised_scenario(warm, 3, 0)[1] == randomised_scenario(warm, 3, 0)[1]   # deterministic per seed
    with pytest.raises(UserInputError, match="multirotor_frame_warming_k"):
        _cfg(multirotor_frame_warming_k=[-1, 2])
    with pytest.raises(UserInputError, match="multirotor_frame_warming_k"):
        _cfg(multirotor_frame_warming_k=[3, 2])


def test_an_unset_frame_warming_is_left_out_of_the_dump_and_a_set_one_round_trips():
    """The manifest and dataset_id of a config without the field keep their bytes (an older dataset
    folder still resumes); a set value is recorded and read back."""
    plain, warm = _cfg(), _cfg(multirotor_frame_warming_k=[0, 8])
    assert "multirotor_frame_warming_k" not in plain.model_dump(mode="json")["randomise"]
    dumped = warm.model_dump(mode="json")
    assert dumped["randomise"]["multirotor_frame_warming_k"] == {"min": 0.0, "max": 8.0}
    assert load_generation_config(dumped) == warm


SENSOR = {"thermal_blur_sigma_px": [0.2, 1.0], "thermal_netd_k": [0.02, 0.06], "thermal_agc_gamma": [1.1, 1.5],
          "rgb_ae_key": [0.2, 0.3]}


def test_sensor_draws_replace_only_their_camera_fields_and_leave_every_other_draw_alone():
    plain, varied = _cfg(), _cfg(sensor=SENSOR)
    netd = []
    for i in range(6):
        a, b = randomised_scenario(plain, 3, i)[1], randomised_scenario(varied, 3, i)[1]
        th, rgb = b.camera_rig.thermal, b.camera_rig.rgb
        assert 0.2 <= th.blur_sigma_px <= 1.0 and 0.02 <= th.netd_k <= 0.06 and 1.1 <= th.agc_gamma <= 1.5
        assert 0.2 <= rgb.ae_key <= 0.3
        netd.append(th.netd_k)
        # every other camera field and every other draw is the plain config's
        assert a.camera_rig.thermal.model_copy(update={"blur_sigma_px": th.blur_sigma_px, "netd_k": th.netd_k,
                                                       "agc_gamma": th.agc_gamma}) == th
        assert a.camera_rig.rgb.model_copy(update={"ae_key": rgb.ae_key}) == rgb
        assert a.model_copy(update={"camera_rig": b.camera_rig}) == b
    assert len(set(netd)) == 6                                                     # one draw per sequence
    assert randomised_scenario(varied, 3, 2)[1] == randomised_scenario(varied, 3, 2)[1]   # deterministic per seed
    # switching a field on never moves another field's value
    fewer = _cfg(sensor={"thermal_netd_k": [0.02, 0.06]})
    assert randomised_scenario(fewer, 3, 1)[1].camera_rig.thermal.netd_k == netd[1]


def test_sensor_fields_are_checked_against_the_camera_bounds_and_named():
    with pytest.raises(UserInputError, match="sensor.thermal_netd_k"):
        _cfg(sensor={"thermal_netd_k": [0.0, 0.05]})
    with pytest.raises(UserInputError, match="sensor.recording_crf"):
        _cfg(sensor={"recording_crf": [20, 60]})
    with pytest.raises(UserInputError, match="thermal_noise"):
        _cfg(sensor={"thermal_noise": [0.1, 0.2]})
    # a CRF draw needs a recording stage in the scenario
    with pytest.raises(UserInputError, match="randomise.sensor.recording_crf"):
        randomised_scenario(_cfg(sensor={"recording_crf": [24, 32]}), 3, 0)


def test_an_unset_sensor_randomiser_is_left_out_of_the_dump_and_a_set_one_round_trips():
    plain, varied = _cfg(), _cfg(sensor=SENSOR)
    assert "sensor" not in plain.model_dump(mode="json")["randomise"]
    dumped = varied.model_dump(mode="json")
    assert dumped["randomise"]["sensor"]["thermal_netd_k"] == {"min": 0.02, "max": 0.06}
    assert load_generation_config(dumped) == varied


def test_a_crf_draw_replaces_the_recordings_rate_control():
    from simulator.dataset.config import SensorRandomisation, _draw_sensor

    rig = {"recording": {"codec": "h264", "crf": None, "bit_rate_bps": 40000}}
    _draw_sensor(SensorRandomisation(recording_crf=[24, 32]), rig, np.random.default_rng(0))
    assert 24 <= rig["recording"]["crf"] <= 32 and rig["recording"]["bit_rate_bps"] is None


def test_sensor_bounds_are_the_camera_fields_own_so_every_value_a_camera_refuses_is_refused_here():
    """Each randomise.sensor field accepts exactly what its camera field accepts (plus the read-noise cap):
    a range touching an excluded end or crossing a bound is refused, naming the field; the bounds of a few
    fields are checked by hand against scenes.schema."""
    from simulator.dataset.config import SENSOR_FIELDS, sensor_field_bounds

    assert sensor_field_bounds("thermal_netd_k") == (0.0, True, 1.0, False)
    assert sensor_field_bounds("thermal_agc_gamma") == (0.25, False, 4.0, False)
    assert sensor_field_bounds("recording_crf") == (0.0, False, 51.0, False)
    assert sensor_field_bounds("rgb_read_noise_e") == (0.0, False, 1000.0, False)   # the cap: the camera has none
    for name in SENSOR_FIELDS:
        lo, lo_open, hi, hi_open = sensor_field_bounds(name)
        inner_lo = lo + 1e-3 if lo_open else lo
        inner_hi = hi - 1e-3 if hi_open else hi
        _cfg(sensor={name: [inner_lo, inner_hi]})                                   # the whole legal span
        with pytest.raises(UserInputError, match=f"sensor.{name}"):
            _cfg(sensor={name: [inner_lo, hi + 1.0]})
        with pytest.raises(UserInputError, match=f"sensor.{name}"):
            _cfg(sensor={name: [lo if lo_open else lo - 1.0, inner_hi]})


def test_omit_when_unset_drops_only_the_named_keys_that_are_none():
    from scenes.schema import omit_when_unset

    data = {"a": None, "b": None, "c": 1}
    assert omit_when_unset(data, ("a", "c", "missing")) == {"b": None, "c": 1}
    assert omit_when_unset([1, None], ("a",)) == [1, None]                         # not a dict: untouched


def test_paint_reflectance_recolours_only_the_primary_targets_painted_parts():
    from scenes.defaults import PAINTED_ROLES, material_for

    plain, painted = _cfg(), _cfg(paint_reflectance=[0.5, 0.8])
    for i in range(4):
        a, b = randomised_scenario(plain, 3, i)[1], randomised_scenario(painted, 3, i)[1]
        drone_a, drone_b = a.targets[0], b.targets[0]
        albedos = {material_for(drone_b, role).rgb_reflectance for role in PAINTED_ROLES[drone_b.kind]}
        assert len(albedos) == 1
        (grey,) = albedos
        assert grey[0] == grey[1] == grey[2] and 0.5 <= grey[0] <= 0.8
        for role in PAINTED_ROLES[drone_b.kind]:   # LWIR untouched
            assert material_for(drone_b, role).emissivity == material_for(drone_a, role).emissivity
        for role in ("motor", "prop", "camera"):
            assert material_for(drone_b, role) == material_for(drone_a, role)
        assert a.targets[1:] == b.targets[1:]          # distractors keep their colours
        assert a.model_copy(update={"targets": b.targets}) == b
        assert drone_a.model_copy(update={"materials": drone_b.materials}) == drone_b
    assert randomised_scenario(painted, 3, 1)[1] == randomised_scenario(painted, 3, 1)[1]
    assert "paint_reflectance" not in plain.model_dump(mode="json")["randomise"]
    assert load_generation_config(painted.model_dump(mode="json")) == painted
    for bad in ([-0.1, 0.5], [0.2, 1.5]):
        with pytest.raises(UserInputError, match="paint_reflectance"):
            _cfg(paint_reflectance=bad)
