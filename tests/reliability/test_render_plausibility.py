"""Plausibility around a render (simulator.dataset.plausibility via render_sequence): camera poses
that can see nothing are refused before rendering; a target never in view is rendered but reported."""
from __future__ import annotations

import copy

import pytest

from scenes.errors import UserInputError
from scenes.loader import load_scenario, scenario_from_dict
from simulator.dataset.plausibility import check_camera_poses, targets_never_seen
from simulator.physics.timeline import build_timeline
from tests.conftest import shrink

BASE = load_scenario("clear_day_quad").model_dump(mode="json")


def _scene(trajectory: dict, camera: dict | None = None):
    data = copy.deepcopy(BASE)
    data["targets"] = [{**data["targets"][0], "trajectory": trajectory}]
    if camera:
        data["camera_rig"].update(camera)
    data["duration_s"] = 0.2
    return scenario_from_dict(data)


REFUSED = [
    ("tracking a target straight overhead", {"kind": "hover", "center_m": [0, 0, 120], "drift_m": 0.0}, None,
     "straight up/down"),
    ("camera inside the target", {"kind": "hover", "center_m": [0, 0, 1.6], "drift_m": 0.0},
     {"track_target": None, "look_at_m": [0, 100, 10]}, "inside target"),
    ("target flying through the camera", {"kind": "flyby", "start_m": [-1, 0, 1.5], "velocity_mps": [5, 0, 0]},
     {"track_target": None, "look_at_m": [0, 100, 10]}, "inside target"),
]


@pytest.mark.parametrize("case,trajectory,camera,reason", REFUSED, ids=[r[0] for r in REFUSED])
def test_camera_poses_that_see_nothing_are_refused(case, trajectory, camera, reason):
    timeline = build_timeline(_scene(trajectory, camera), 0)
    with pytest.raises(UserInputError, match=reason):
        check_camera_poses(timeline)


def test_a_normal_pose_passes():
    check_camera_poses(build_timeline(load_scenario("clear_day_quad"), 0, 3))


def test_targets_never_seen_from_labels():
    frames = [{"rgb": [{"name": "a", "exist": 0}, {"name": "b", "exist": 1}], "thermal": [{"name": "a", "exist": 0}]},
              {"rgb": [{"name": "a", "exist": 0}, {"name": "b", "exist": 0}], "thermal": [{"name": "a", "exist": 0}]}]
    assert targets_never_seen(frames) == ["a"]


def test_a_render_of_a_camera_looking_away_reports_the_unseen_target(tmp_path):
    from simulator.dataset.sequence import render_sequence

    scenario = _scene({"kind": "hover", "center_m": [0, 200, 40], "drift_m": 0.0},
                      {"track_target": None, "look_at_m": [0, -100, 10]})
    scenario = shrink(scenario, 32, 24, spp=1).model_copy(update={"duration_s": 1 / 30})
    notes: list[str] = []
    written = render_sequence(scenario, 0, tmp_path, progress=False, notes=notes)
    assert (written["native"] / "meta.json").is_file()
    assert notes == ["target 'drone' is never in view of any camera (all frames exist: 0)"]
