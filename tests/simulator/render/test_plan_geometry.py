"""Launch layout (pure function of the scene) and posed assets (equal to rebuilding them)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scenes.assets import build_asset
from simulator.render.geometry import AnimatedAsset
from simulator.render.plan import (
    BATCH_PIXEL_BUDGET,
    CameraPlan,
    pixel_box,
    place_tile,
    plan_camera,
    projected_boxes,
    tile_contains,
)


@pytest.mark.parametrize("kind", ["quadcopter", "hexacopter", "fixed_wing", "bird", "airliner"])
@settings(max_examples=15, deadline=None)
@given(rotor=st.floats(-50.0, 50.0), flap=st.floats(-10.0, 10.0))
def test_posed_asset_equals_a_rebuilt_asset(kind, rotor, flap):
    asset = AnimatedAsset(kind, 0.7)
    assert asset.exact
    posed = asset.local_by_role(rotor, flap)
    built = build_asset(kind, 0.7, rotor_angle_rad=rotor, flap_phase_rad=flap)
    for role in asset.roles:
        expected = np.vstack([p.vertices for p in built if p.role == role])
        assert np.max(np.abs(posed[role] - expected)) < 1e-9


def test_small_targets_get_roi_tiles_that_contain_their_boxes():
    boxes = [[(100.2, 50.5, 109.9, 58.1), None], [(630.0, 500.0, 640.0, 512.0), (0.0, 0.0, 3.5, 2.0)]]
    plan = plan_camera(boxes, 640, 512, max_range_m=300.0)
    assert plan.mode == "roi" and plan.tiles_per_frame == 2
    assert plan.tile_width % 8 == 0 and plan.tile_height % 8 == 0
    for frame in boxes:
        for box in frame:
            if box is None:
                continue
            tile = place_tile(plan, box, 640, 512)
            assert 0 <= tile.x0 and tile.x0 + tile.width <= 640 and 0 <= tile.y0 and tile.y0 + tile.height <= 512
            assert tile_contains(tile, pixel_box(box, 640, 512, pad_px=1))


def test_large_targets_or_small_frames_render_whole_frames_within_the_pixel_budget():
    big = plan_camera([[(0.0, 0.0, 400.0, 300.0)]], 640, 512, max_range_m=50.0)
    assert big.mode == "full" and big.tile_width == 640 and big.tile_height == 512
    assert big.batch_frames * 640 * 512 <= BATCH_PIXEL_BUDGET
    assert plan_camera([[(0.0, 0.0, 400.0, 300.0)]], 640, 512, 50.0, roi=False).mode == "full"


def test_slot_copies_are_farther_apart_than_a_primary_ray_reaches():
    plan = plan_camera([[(10.0, 10.0, 20.0, 20.0)]], 640, 512, max_range_m=3000.0, batch_frames=16)
    offsets = np.array([plan.slot_offset_m(s) for s in range(plan.batch_frames)])
    gaps = np.linalg.norm(offsets[:, None] - offsets[None], axis=-1)[~np.eye(plan.batch_frames, dtype=bool)]
    # a copy's geometry lies within max_range of its camera; rays stop at far_clip
    assert gaps.min() > plan.far_clip_m + 3000.0
    assert len({tuple(o) for o in offsets}) == plan.batch_frames


def test_projected_boxes_handle_behind_and_outside():
    pts = np.array([[10.0, 20.0], [30.0, 40.0]])
    assert projected_boxes(pts, np.array([5.0, 5.0]), 64, 64) == (10.0, 20.0, 30.0, 40.0)
    assert projected_boxes(pts, np.array([-1.0, -1.0]), 64, 64) is None
    assert projected_boxes(pts + 100, np.array([5.0, 5.0]), 64, 64) is None
    assert projected_boxes(pts, np.array([5.0, -1.0]), 64, 64) == (0.0, 0.0, 64.0, 64.0)
    assert CameraPlan("roi", 16, 16, 1, 4, 10.0, 100.0).record()["batch_frames"] == 4
