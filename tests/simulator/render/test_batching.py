"""Batched and ROI rendering against per-frame and full renders, and exact labels.

Tolerances: thermal radiance and sky pixels use the same primary samples in every layout (the
sub-pixel positions are a hash of camera seed, pixel and sample only), so they are compared
exactly, except the ROI mode's sky outside the tiles, which is evaluated at pixel centres and must
agree with the full render's jittered samples within 2e-3 relative (well below one 8-bit step).
RGB pixels on the target are path traced with a sampler whose streams depend on the launch layout,
so ROI and full mode agree there only statistically: the target's mean RGB within 10 %.
"""
import numpy as np
import pytest

from scenes import load_scenario
from scenes.schema import Hover
from simulator.physics.timeline import build_timeline
from simulator.render.labels import coverage_labels
from simulator.render.renderer import SequenceRenderer
from tests.conftest import shrink


def _tiles_mask(renderer, which, frame):
    view = renderer.views[which]
    cam = view.camera
    inside = np.zeros((cam.height_px, cam.width_px), bool)
    slot = frame % renderer.batch_frames
    tiles = view.place(renderer.batch_frames_of(frame // renderer.batch_frames) + [frame] * renderer.batch_frames)
    for ti in range(view.plan.tiles_per_frame):
        if renderer.boxes[which][frame][ti] is None:
            continue
        t = tiles[(slot, ti)]
        inside[t.y0:t.y0 + t.height, t.x0:t.x0 + t.width] = True
    return inside


@pytest.fixture(scope="module")
def swarm():
    scenario = shrink(load_scenario("swarm_3"), 320, 256, spp=8)
    return build_timeline(scenario, 3, 20)


def test_a_frame_rendered_alone_equals_the_same_frame_in_its_batch(swarm):
    batched = SequenceRenderer(swarm).render_frame(5)
    alone = SequenceRenderer(swarm).render_batch(0, only=[5])[5]
    for name in ("rgb_linear", "thermal_radiance", "thermal_kelvin", "mask_rgb", "mask_thermal"):
        assert np.array_equal(getattr(batched, name), getattr(alone, name)), name
    for which in ("rgb", "thermal"):
        for a, b in zip(batched.coverage[which], alone.coverage[which]):
            assert a.region == b.region and np.array_equal(a.coverage, b.coverage)


def test_roi_render_equals_full_render_inside_and_outside_the_tiles(swarm):
    roi = SequenceRenderer(swarm)
    full = SequenceRenderer(swarm, roi=False)
    assert roi.plans["thermal"].mode == "roi" and full.plans["thermal"].mode == "full"
    frame = 7
    a, b = roi.render_frame(frame), full.render_frame(frame)
    inside = _tiles_mask(roi, "thermal", frame)
    assert inside.any() and not inside.all()
    # thermal inside the tiles: the same rays, the same emission -> identical
    assert np.array_equal(a.thermal_radiance[inside], b.thermal_radiance[inside])
    # outside: sky at pixel centres vs the mean of the jittered samples
    rel = np.abs(a.thermal_radiance[~inside] - b.thermal_radiance[~inside]) / b.thermal_radiance[~inside]
    assert rel.max() < 2e-3
    inside_rgb = _tiles_mask(roi, "rgb", frame)
    target = a.mask_rgb > 0
    sky_in_tiles = inside_rgb & ~target
    cover = np.zeros(target.shape, bool)
    for c in a.coverage["rgb"]:
        x0, y0, x1, y1 = c.region
        cover[y0:y1, x0:x1] |= c.coverage > 0
    sky_in_tiles &= ~cover
    assert np.array_equal(a.rgb_linear[sky_in_tiles], b.rgb_linear[sky_in_tiles])
    rgb_rel = np.abs(a.rgb_linear[~inside_rgb]
                     - b.rgb_linear[~inside_rgb]) / np.maximum(b.rgb_linear[~inside_rgb], 1e-3)
    assert rgb_rel.max() < 2e-3
    for c in a.coverage["rgb"]:
        x0, y0, x1, y1 = c.region
        wa = a.rgb_linear[y0:y1, x0:x1][c.coverage > 0].mean(axis=0)
        wb = b.rgb_linear[y0:y1, x0:x1][c.coverage > 0].mean(axis=0)
        assert np.all(np.abs(wa - wb) <= 0.1 * np.abs(wb) + 1e-4)
    # labels do not depend on the layout at all
    assert np.array_equal(a.mask_rgb, b.mask_rgb) and np.array_equal(a.mask_thermal, b.mask_thermal)


def _twin_cameras(scenario):
    """The thermal camera made identical to the RGB one (same intrinsics, no offset)."""
    rig = scenario.camera_rig
    rgb = rig.rgb
    thermal = rig.thermal.model_copy(update={"width_px": rgb.width_px, "height_px": rgb.height_px,
                                             "hfov_deg": rgb.hfov_deg, "spp": rgb.spp})
    offset = rig.thermal_offset.model_copy(update={"translation_m": (0.0, 0.0, 0.0), "yaw_deg": 0.0,
                                                   "pitch_deg": 0.0, "roll_deg": 0.0})
    return scenario.model_copy(update={"camera_rig": rig.model_copy(update={"thermal": thermal,
                                                                            "thermal_offset": offset})})


def test_identically_placed_rgb_and_thermal_cameras_get_identical_boxes():
    scenario = _twin_cameras(shrink(load_scenario("swarm_3"), 240, 192, spp=1))
    timeline = build_timeline(scenario, 2, 12)
    renderer = SequenceRenderer(timeline)
    cam = timeline.cameras["rgb"]
    seen = 0
    for i, fb in renderer.iter_frames():
        rgb = coverage_labels(timeline, i, "rgb", fb.coverage["rgb"], cam.width_px, cam.height_px)
        th = coverage_labels(timeline, i, "thermal", fb.coverage["thermal"], cam.width_px, cam.height_px, 0.05)
        assert [r["box"] for r in rgb] == [r["box"] for r in th]
        assert [r["visible_px"] for r in rgb] == [r["visible_px"] for r in th]
        assert np.array_equal(fb.mask_rgb, fb.mask_thermal)
        seen += sum(r["exist"] for r in rgb)
    assert seen > 0


def _single_target(distance_m: float, size_m: float = 0.5):
    scenario = load_scenario("clear_day_quad")
    target = scenario.targets[0].model_copy(update={"size_m": size_m,
                                                    "trajectory": Hover(center_m=(0.3, distance_m, 12.0),
                                                                        drift_m=0.05)})
    rig = scenario.camera_rig.model_copy(update={"track_target": None, "look_at_m": (0.0, distance_m, 12.0)})
    return shrink(scenario.model_copy(update={"targets": [target], "camera_rig": rig}), 320, 256, spp=1)


def test_box_is_the_tight_box_of_the_projected_silhouette_within_one_pixel():
    timeline = build_timeline(_single_target(60.0), 4, 6)
    renderer = SequenceRenderer(timeline)
    cam = timeline.cameras["rgb"]
    for i, fb in renderer.iter_frames():
        verts = renderer.geometry[0].all_vertices(i)
        px, _ = cam.project(i, verts)
        x0, y0 = np.floor(px.min(axis=0))
        x1, y1 = np.ceil(px.max(axis=0))
        rec = coverage_labels(timeline, i, "rgb", fb.coverage["rgb"], cam.width_px, cam.height_px)[0]
        bx, by, bw, bh = rec["box"]
        assert bw > 5 and bh > 3  # a resolved target, so the comparison means something
        assert abs(bx - x0) <= 1 and abs(by - y0) <= 1
        assert abs(bx + bw - x1) <= 1 and abs(by + bh - y1) <= 1


def test_sub_pixel_target_is_labelled_by_its_coverage():
    timeline = build_timeline(_single_target(1500.0, size_m=0.3), 4, 3)
    renderer = SequenceRenderer(timeline)
    cam = timeline.cameras["rgb"]
    fb = renderer.render_frame(0)
    rec = coverage_labels(timeline, 0, "rgb", fb.coverage["rgb"], cam.width_px, cam.height_px)[0]
    footprint_px = (0.3 * cam.focal_px / 1500.0) ** 2
    assert footprint_px < 0.5
    assert rec["exist"] == 1 and 0 < rec["visible_px"] < 1.0
    assert rec["box"][2] <= 2 and rec["box"][3] <= 2


def test_thermal_contrast_label_is_the_target_radiance_against_the_sky_behind_it():
    from simulator.physics import thermal

    timeline = build_timeline(_single_target(200.0), 4, 3)
    renderer = SequenceRenderer(timeline)
    fb = renderer.render_frame(0)
    (cov,) = fb.coverage["thermal"]
    cam = timeline.cameras["thermal"]
    rec = coverage_labels(timeline, 0, "thermal", fb.coverage["thermal"], cam.width_px, cam.height_px, 0.05)[0]
    roles = cov.role_px
    radiance = sum(roles[r] * renderer.thermal_radiance(0, r, 0, "thermal") for r in roles) / sum(roles.values())
    expected = thermal.brightness_temperature(radiance) - thermal.brightness_temperature(cov.sky_radiance)
    assert rec["contrast_k"] == pytest.approx(float(expected), abs=1e-5)
    # partially covered edge pixels dilute the pixel-mean contrast; the label does not
    x0, y0, x1, y1 = cov.region
    pix = fb.thermal_kelvin[y0:y1, x0:x1][cov.coverage > 0].mean()
    sky = thermal.brightness_temperature(cov.sky_radiance)
    assert abs(rec["contrast_k"]) > abs(pix - sky)


def test_turning_camera_roi_and_full_modes_give_identical_labels():
    timeline = build_timeline(shrink(load_scenario("clear_day_quad"), 320, 256, spp=1), 0, 18)
    roi, full = SequenceRenderer(timeline), SequenceRenderer(timeline, roi=False)
    assert not roi.views["thermal"].static and roi.plans["thermal"].mode == "roi"
    cam = timeline.cameras["thermal"]
    for frame in (2, 17):
        a, b = roi.render_frame(frame), full.render_frame(frame)
        la = coverage_labels(timeline, frame, "thermal", a.coverage["thermal"], cam.width_px, cam.height_px, 0.05)
        lb = coverage_labels(timeline, frame, "thermal", b.coverage["thermal"], cam.width_px, cam.height_px, 0.05)
        assert la == lb and la[0]["exist"] == 1


def test_layout_from_a_superset_scene_keeps_shared_pixels_and_refuses_a_foreign_one(swarm):
    """A scene rendered with the layout of the same scene plus one more target (a twin and its
    drone clip) gets byte-identical pixels wherever the extra target does not reach; a layout
    whose targets do not start with the scene's own is refused."""
    scenario = swarm.scenario
    fewer = scenario.model_copy(update={"targets": scenario.targets[:-1]})
    own = build_timeline(fewer, 3, 20)
    full = SequenceRenderer(swarm, cameras=("rgb",), labels=False).render_frame(4).rgb_linear
    twin = SequenceRenderer(own, cameras=("rgb",), labels=False, layout=swarm).render_frame(4).rgb_linear
    cam = swarm.cameras["rgb"]
    xy, depth = cam.project(4, swarm.targets[-1].position_m[4])
    r = 3 * swarm.targets[-1].size_m * cam.focal_px / float(depth[0]) + 6.0
    yy, xx = np.mgrid[:cam.height_px, :cam.width_px]
    away = np.hypot(xx - xy[0, 0], yy - xy[0, 1]) > r
    assert np.array_equal(full[away], twin[away])          # same lanes, same random numbers
    assert not np.array_equal(full[~away], twin[~away])    # the extra target is really there
    reversed_targets = scenario.model_copy(update={"targets": scenario.targets[::-1]})
    with pytest.raises(ValueError, match="layout timeline differs"):
        SequenceRenderer(own, cameras=("rgb",), labels=False, layout=build_timeline(reversed_targets, 3, 20))


@pytest.mark.parametrize("name", ["low_elevation_haze", "pan_tilt_horizon"])   # turning camera: sky; sky and terrain
def test_a_turning_cameras_backgrounds_of_a_batch_equal_each_frame_evaluated_alone(name):
    scenario = shrink(load_scenario(name), 96, 80)
    renderer = SequenceRenderer(build_timeline(scenario, 2, 6), cameras=("rgb",), labels=False)
    view = renderer.views["rgb"]
    assert not view.static and view.plan.mode == "roi"
    together = view.backgrounds(list(range(6)))             # one launch
    for frame, image in enumerate(together):
        alone = view._background([frame], 0, 0, view.camera.height_px, view.camera.width_px)[0]
        assert image.tobytes() == alone.tobytes()
    renderer.close()


def test_the_animated_asset_is_shared_between_sequences_and_read_only(swarm):
    from simulator.render.geometry import TrackGeometry

    a, b = TrackGeometry(swarm.targets[0]), TrackGeometry(swarm.targets[0])
    assert a.asset is b.asset
    faces = a.faces(a.roles[0])
    with pytest.raises(ValueError):
        faces[0, 0] = 0


def test_rendering_one_batch_ahead_gives_the_same_frames_in_order_and_leaves_no_thread(swarm):
    import threading

    plain = [(i, fb) for i, fb in SequenceRenderer(swarm).iter_frames()]
    ahead = [(i, fb) for i, fb in SequenceRenderer(swarm).iter_frames(ahead=True)]
    assert [i for i, _ in ahead] == list(range(swarm.n_frames)) == [i for i, _ in plain]
    for (_, a), (_, b) in zip(plain, ahead):
        for name in ("rgb_linear", "thermal_radiance", "mask_rgb", "mask_thermal"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
    renderer = SequenceRenderer(swarm)
    frames = renderer.iter_frames(ahead=True)
    next(frames)          # batch 1 is now rendering on the worker
    frames.close()        # waits for it and joins the worker
    renderer.close()
    assert not [t for t in threading.enumerate() if t.name.startswith("evids-render")]


def test_a_render_error_one_batch_ahead_reaches_the_caller_at_that_batch(swarm, monkeypatch):
    import threading

    renderer = SequenceRenderer(swarm)
    render_batch = renderer.render_batch

    def failing(batch, only=None):
        if batch == 1:
            raise RuntimeError("launch failed")
        return render_batch(batch, only)

    monkeypatch.setattr(renderer, "render_batch", failing)
    seen = []
    with pytest.raises(RuntimeError, match="launch failed"):
        for i, _ in renderer.iter_frames(ahead=True):
            seen.append(i)
    assert seen == list(range(renderer.batch_frames))   # every frame of batch 0, then the error
    assert not [t for t in threading.enumerate() if t.name.startswith("evids-render")]
