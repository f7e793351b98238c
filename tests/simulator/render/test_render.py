"""Renderer properties on small images: contrast sign, crossover, tight boxes, exist flags,
RGB/thermal registration, projection agreement, determinism and the Anti-UAV output."""
import hashlib
import json

import numpy as np

from scenes import load_scenario
from scenes.schema import Hover
from simulator.dataset.sequence import render_sequence
from simulator.formats.antiuav import read_label_file
from simulator.physics.timeline import build_timeline
from simulator.render.labels import coverage_labels, tight_box
from simulator.render.renderer import SequenceRenderer
from tests.conftest import shrink


def _render_frames(scenario, seed, frames, n_frames=None):
    timeline = build_timeline(scenario, seed, n_frames)
    renderer = SequenceRenderer(timeline)
    return timeline, {i: renderer.render_frame(i) for i in frames}


def _labels(timeline, frame, camera, fb, netd_k=None):
    cam = timeline.cameras[camera]
    return coverage_labels(timeline, frame, camera, fb.coverage[camera], cam.width_px, cam.height_px, netd_k)


def test_hot_drone_is_brighter_than_sky_in_thermal():
    scenario = shrink(load_scenario("clear_day_quad"), 256, 208)
    timeline, out = _render_frames(scenario, 7, [0])
    fb = out[0]
    labels = _labels(timeline, 0, "thermal", fb, 0.05)
    assert labels[0]["exist"] == 1
    assert labels[0]["contrast_k"] > 1.0
    target = fb.thermal_kelvin[fb.mask_thermal == 1]
    assert target.max() > np.percentile(fb.thermal_kelvin[fb.mask_thermal == 0], 99.9)


def test_dusk_crossover_contrast_passes_below_netd():
    scenario = shrink(load_scenario("dusk_crossover"), 640, 512)
    netd = scenario.camera_rig.thermal.netd_k
    crossing = int(round(0.6 * (scenario.n_frames - 1)))
    timeline, out = _render_frames(scenario, 11, [0, crossing, scenario.n_frames - 1])
    contrast = {i: _labels(timeline, i, "thermal", fb, netd)[0] for i, fb in out.items()}
    assert contrast[0]["contrast_k"] > 0.5
    assert abs(contrast[crossing]["contrast_k"]) < netd
    assert contrast[crossing]["crossover"] is True
    assert contrast[scenario.n_frames - 1]["contrast_k"] < -0.3


def test_box_is_the_tight_box_of_the_mask():
    mask = np.zeros((20, 30), bool)
    mask[5:9, 10:17] = True
    mask[12, 3] = True
    assert tight_box(mask) == [3, 5, 14, 8]
    assert tight_box(np.zeros((4, 4), bool)) is None


def test_rendered_box_matches_coverage_mask_and_projection():
    scenario = shrink(load_scenario("swarm_3"), 320, 256)
    timeline, out = _render_frames(scenario, 17, [0])
    fb = out[0]
    cam = timeline.cameras["rgb"]
    coverage = {c.target_id: c for c in fb.coverage["rgb"]}
    for rec in _labels(timeline, 0, "rgb", fb):
        cov = coverage[rec["id"]]
        ys, xs = np.nonzero(cov.coverage > 0)
        x0, y0 = cov.region[:2]
        assert rec["box"] == [x0 + xs.min(), y0 + ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1]
        assert rec["visible_px"] == round(float(cov.coverage.sum()), 4) > 0
        # the written mask (pixels at least half covered) lies inside the box
        my, mx = np.nonzero(fb.mask_rgb == rec["id"])
        x, y, w, h = rec["box"]
        assert np.all((mx >= x) & (mx < x + w) & (my >= y) & (my < y + h))
        track = timeline.targets[rec["id"] - 1]
        projected, _ = cam.project(0, track.position_m[0])
        weights = cov.coverage[ys, xs]
        centre = np.array([np.average(xs + x0 + 0.5, weights=weights), np.average(ys + y0 + 0.5, weights=weights)])
        assert np.linalg.norm(centre - projected[0]) < 2.0  # mirrored axes would put it far away


def test_out_of_view_has_absent_frames_with_empty_boxes():
    scenario = shrink(load_scenario("out_of_view"), 320, 256, spp=1)
    timeline = build_timeline(scenario, 19)
    renderer = SequenceRenderer(timeline)
    exist = []
    for i in range(0, timeline.n_frames, 3):
        fb = renderer.render_frame(i)
        rec = _labels(timeline, i, "rgb", fb)[0]
        exist.append(rec["exist"])
        if not rec["exist"]:
            assert rec["box"] == [] and rec["visible_px"] == 0
    assert exist[0] == 1 and exist[-1] == 1 and 0 in exist
    first_gap = exist.index(0)
    assert 1 in exist[first_gap:]  # it comes back


def test_registered_cameras_agree_within_one_pixel_after_scaling():
    scenario = load_scenario("clear_day_quad")
    rig = scenario.camera_rig
    near = scenario.targets[0].model_copy(update={"trajectory": Hover(center_m=(0.8, 40, 11.6), drift_m=0.1)})
    scenario = scenario.model_copy(update={"targets": [near],
                                           "camera_rig": rig.model_copy(update={"track_target": None,
                                                                                "look_at_m": (0, 40, 11)})})
    scenario = shrink(scenario, 320, 256, spp=2, thermal_width_px=160, thermal_height_px=128)
    _, out = _render_frames(scenario, 1, [0])
    fb = out[0]
    ys, xs = np.nonzero(fb.mask_rgb == 1)
    yt, xt = np.nonzero(fb.mask_thermal == 1)
    rgb_centre = np.array([xs.mean() + 0.5, ys.mean() + 0.5]) / 2.0
    th_centre = np.array([xt.mean() + 0.5, yt.mean() + 0.5])
    assert np.linalg.norm(rgb_centre - th_centre) < 1.0


def _digest(folder):
    h = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        h.update(path.relative_to(folder).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def test_same_seed_is_byte_identical_and_different_seed_differs(tmp_path):
    scenario = shrink(load_scenario("bird_confuser"), 96, 80)
    a = render_sequence(scenario, 5, tmp_path / "a", n_frames=3, progress=False)["native"]
    b = render_sequence(scenario, 5, tmp_path / "b", n_frames=3, progress=False)["native"]
    c = render_sequence(scenario, 6, tmp_path / "c", n_frames=3, progress=False)["native"]
    assert _digest(a) == _digest(b)
    assert _digest(a) != _digest(c)


def test_antiuav_output_has_the_benchmark_field_semantics(tmp_path):
    scenario = shrink(load_scenario("out_of_view"), 320, 256, spp=1)
    written = render_sequence(scenario, 19, tmp_path, formats=("native", "antiuav"), progress=False)
    ir = written["antiuav"]
    frames = sorted(ir.glob("*.jpg"))
    assert frames[0].name == "000001.jpg" and len(frames) == scenario.n_frames
    data = json.loads((ir / "IR_label.json").read_text())
    assert len(data["exist"]) == len(data["gt_rect"]) == len(frames)
    for flag, rect in zip(data["exist"], data["gt_rect"]):
        assert (flag == 1 and len(rect) == 4 and rect[2] > 0 and rect[3] > 0) or (flag == 0 and rect == [])
    assert 0 in data["exist"] and 1 in data["exist"]
    exist, rects = read_label_file(written["antiuav_visible"] / "visible.json")
    assert len(exist) == len(rects) == len(frames)
    native = json.loads((written["native"] / "labels.json").read_text())
    assert [f["thermal"][0]["exist"] for f in native["frames"]] == data["exist"]


def test_a_cached_sky_bake_renders_the_same_bytes_as_a_fresh_one(tmp_path):
    from simulator.render import renderer as rr

    scenario = shrink(load_scenario("bird_confuser"), 96, 80)   # has clouds: the bake depends on the seed
    assert scenario.sky.clouds is not None and scenario.sky.clouds.coverage > 0
    rr._SKY_BAKES.clear()
    a = render_sequence(scenario, 5, tmp_path / "a", n_frames=2, progress=False)["native"]
    assert len(rr._SKY_BAKES) == 1
    bake = next(iter(rr._SKY_BAKES.values()))
    assert bake.thermal is not None and not bake.rgb.flags.writeable
    b = render_sequence(scenario, 5, tmp_path / "b", n_frames=2, progress=False)["native"]   # a hit
    assert len(rr._SKY_BAKES) == 1 and next(iter(rr._SKY_BAKES.values())) is bake
    assert _digest(a) == _digest(b)
    render_sequence(scenario, 6, tmp_path / "c", n_frames=1, progress=False)      # other cloud seed: new bake
    clear = scenario.model_copy(update={"sky": scenario.sky.model_copy(update={"clouds": None})})
    from simulator.render.mitsuba_setup import load_mitsuba

    keys = {rr._sky_key(load_mitsuba(), build_timeline(clear, seed, 1)) for seed in (5, 6)}
    assert len(rr._SKY_BAKES) == 2 and len(keys) == 1                         # no clouds: the seed does not count


def _benchmark_quad_frame(range_m, randomise_extra):
    """Frame 0 of a hovering quadcopter ``range_m`` away on the benchmark's 24-deg, 320 x 256 cameras, drawn by a
    generation config with ``randomise_extra`` on top of fixed range, air temperature and size."""
    from simulator.dataset.config import load_generation_config, randomised_scenario

    randomise = {"range_m": [range_m, range_m], "trajectory_kinds": ["hover"], "hfov_deg": [24, 24],
                 "air_temperature_k": [285, 285], "target_size_scale": [1.5, 1.5], **randomise_extra}
    cfg = load_generation_config({"name": "t", "mixture": [{"scenario": "clear_day_quad"}], "frames": 2,
                                  "image_size": [320, 256], "spp": 2, "randomise": randomise})
    _, out = _render_frames(randomised_scenario(cfg, 0, 0)[1], 0, [0], 2)
    return out[0]


def test_multirotor_frame_warming_grows_the_drones_hot_area():
    """A quadcopter 40 m away on a 24-deg, 320-px thermal camera (the benchmark's geometry): with
    ``multirotor_frame_warming_k`` the body and arms join the motors and battery far above the sky, so
    more pixels stand out and the summed excess grows; a zero warming renders the same image as none."""
    def hot_pixels(warming):
        extra = {} if warming is None else {"multirotor_frame_warming_k": [warming, warming]}
        out = _benchmark_quad_frame(40.0, extra)
        kelvin, mask = out.thermal_kelvin, out.mask_thermal
        ys, xs = np.nonzero(mask == 1)
        y0, x0 = max(0, ys.min() - 8), max(0, xs.min() - 8)
        window, inside = kelvin[y0:ys.max() + 9, x0:xs.max() + 9], mask[y0:ys.max() + 9, x0:xs.max() + 9] == 1
        excess = window - np.median(window[~inside])
        # pixels far above the sky (a part's own temperature, not a grazing hit) and the summed excess
        return (int((excess > 22.0).sum()), float(excess[excess > 1.0].sum())), kelvin

    base, plain = hot_pixels(None)
    zero, unwarmed = hot_pixels(0.0)
    warm, _ = hot_pixels(10.0)
    assert np.array_equal(unwarmed, plain) and zero == base        # a zero offset renders the same image
    assert base[0] >= 2 and warm[0] >= base[0] + 2 and warm[1] >= base[1] + 20.0


def test_paint_reflectance_brightens_the_drone_in_rgb_and_leaves_the_thermal_frame_alone():
    """A white-painted quadcopter (``paint_reflectance`` 0.8) against the default near-black one: the
    drone's RGB pixels get brighter, the radiometric thermal frame is the same array (emissivity kept)."""
    dark = _benchmark_quad_frame(25.0, {})
    white = _benchmark_quad_frame(25.0, {"paint_reflectance": [0.8, 0.8]})
    assert np.array_equal(dark.thermal_kelvin, white.thermal_kelvin)
    drone = (dark.mask_rgb == 1) & (white.mask_rgb == 1)
    assert drone.sum() >= 10
    def luminance(f):
        return (f.rgb_linear[drone] @ np.array([0.2126, 0.7152, 0.0722])).mean()

    assert luminance(white) > 3.0 * luminance(dark)
