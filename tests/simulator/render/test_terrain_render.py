"""Terrain in the renderer: ground and tree line in both bands, occlusion labels (exist 0 behind a
building), seamless ROI compositing, byte identity per seed."""
import numpy as np
import pytest

from scenes import load_scenario
from simulator.physics.timeline import build_timeline
from simulator.render.labels import coverage_labels
from simulator.render.renderer import SequenceRenderer
from tests.conftest import shrink


@pytest.fixture(scope="module")
def rendered():
    scenario = shrink(load_scenario("horizon_treeline"), 160, 128, spp=1)
    timeline = build_timeline(scenario, 3)
    renderer = SequenceRenderer(timeline)
    frames = {i: renderer.render_frame(i) for i in (0, 25, 66, 99)}
    return scenario, timeline, renderer, frames


def _exist(timeline, frame, fb, camera="thermal"):
    cam = timeline.cameras[camera]
    return coverage_labels(timeline, frame, camera, fb.coverage[camera], cam.width_px, cam.height_px,
                           0.05 if camera == "thermal" else None)[0]["exist"]


def test_out_of_view_visible_occluded_and_visible_again(rendered):
    _, timeline, _, frames = rendered
    assert [_exist(timeline, i, frames[i]) for i in (0, 25, 66, 99)] == [0, 1, 0, 1]
    assert [_exist(timeline, i, frames[i], "rgb") for i in (0, 25, 66, 99)] == [0, 1, 0, 1]
    # the occluded drone is in the field of view: the barn, not the frame edge, hides it
    px, depth = timeline.cameras["thermal"].project(66, timeline.targets[0].position_m[66])
    assert depth[0] > 0 and 0 < px[0, 0] < 160 and 0 < px[0, 1] < 128


def test_ground_below_the_horizon_sky_above_in_both_bands(rendered):
    scenario, _, _, frames = rendered
    fb = frames[25]
    kelvin = fb.thermal_kelvin
    air = scenario.atmosphere.air_temperature_k
    ground = kelvin[-20:]                        # bottom rows: grass a few K above air at 35 deg sun
    assert air - 2 < float(np.median(ground)) < air + 8
    assert float(np.median(kelvin[:10])) < air - 10   # clear sky a few degrees up is colder than air
    rgb = fb.rgb_linear[-20:].reshape(-1, 3).mean(axis=0)
    assert rgb[1] > rgb[0] and rgb[1] > rgb[2]   # green grass
    sky = fb.rgb_linear[:10].reshape(-1, 3).mean(axis=0)
    assert sky[2] > sky[0]                       # blue sky


def test_roi_compositing_matches_a_full_frame_render(rendered):
    scenario, timeline, _, frames = rendered
    dense = shrink(load_scenario("horizon_treeline"), 160, 128, spp=16)   # a full render that averages each pixel
    full = SequenceRenderer(build_timeline(dense, 3, 32), roi=False).render_frame(25)
    a, b = frames[25].thermal_kelvin, full.thermal_kelvin
    target = (frames[25].mask_thermal > 0) | (full.mask_thermal > 0)
    # the ROI background is sampled at pixel centres, the full render averages 16 jittered samples:
    # away from terrain edges (smooth per-vertex emission) they agree to below a grey level
    pad = np.pad(b, 1, mode="edge")
    local = np.max([np.abs(pad[1 + dy:pad.shape[0] - 1 + dy, 1 + dx:pad.shape[1] - 1 + dx] - b)
                    for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0)
    smooth = (local < 0.5) & ~target
    assert smooth.mean() > 0.5
    diff = np.abs(a - b)
    assert np.percentile(diff[smooth], 99) < 0.1   # an 8-bit step of a 30 K display range is 0.12 K
    assert np.median(diff[~target]) < 0.02


def test_same_seed_same_bytes():
    scenario = shrink(load_scenario("horizon_treeline"), 96, 80, spp=1)
    a = SequenceRenderer(build_timeline(scenario, 5, 4)).render_frame(2)
    b = SequenceRenderer(build_timeline(scenario, 5, 4)).render_frame(2)
    c = SequenceRenderer(build_timeline(scenario, 6, 4)).render_frame(2)
    assert a.thermal_radiance.tobytes() == b.thermal_radiance.tobytes()
    assert a.rgb_linear.tobytes() == b.rgb_linear.tobytes()
    assert a.thermal_radiance.tobytes() != c.thermal_radiance.tobytes()   # another seed: other terrain
