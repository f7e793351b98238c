"""Scene-balanced generation: one scene distribution for both classes, counterfactual twins that
differ only in the drone's own signatures (pixels, rotor source, links), scene-disjoint splits
recorded per clip, a drone of the drawn 3-30 px, and field-named errors."""
from __future__ import annotations

import json

import numpy as np
import pytest

from scenes.errors import UserInputError
from simulator.dataset import trident as tr


def _cfg(**scenes):
    base = {"n_scenes": 6, "n_test_scenes": 2, "n_val_scenes": 1, **scenes}
    return tr.load_trident_config({"name": "tw", "clip_duration_s": 0.5, "save_iq": False, "video_render_stride": 7,
                                   "rf": {"capture_samples": 112 * 40}, "scenes": base})


def test_plan_pairs_every_scene_with_its_twin_and_splits_by_scene():
    cfg = _cfg(n_scenes=12, n_test_scenes=4, n_val_scenes=2)
    plan = tr.build_plan(cfg, seed=3)
    assert len(plan) == 24
    for d, t in zip(plan[0::2], plan[1::2]):
        assert tr.clip_label(d.scenario) == "Drone" and tr.clip_label(t.scenario) == "Background"
        assert d.seed == t.seed and d.group == t.group and d.meta["split"] == t.meta["split"]
        assert d.ambience == t.ambience and d.rf == t.rf and d.rf_silent == t.rf_silent
        assert d.scenario.targets[:-1] == t.scenario.targets          # the drone is last; confusers shared
        assert d.scenario.model_dump(exclude={"targets"}) == t.scenario.model_dump(exclude={"targets"})
    splits = [p.meta["split"] for p in plan[0::2]]
    assert splits.count("test") == 4 and splits.count("val") == 2 and splits.count("train") == 6
    assert tr.build_plan(cfg, seed=3) == plan and tr.build_plan(cfg, seed=4) != plan


def test_drawn_drone_size_spans_3_to_30_px():
    cfg = _cfg(n_scenes=40, n_test_scenes=1, n_val_scenes=1)
    px = []
    for p in tr.build_plan(cfg, seed=1)[0::2]:
        s = tr.segment_drone_px(p.scenario, p.seed, cfg)
        assert (s > 0).all()                                         # in view in every segment
        px.append(float(np.median(s)))
    assert 2.9 <= min(px) and max(px) <= 31.0 and max(px) / min(px) > 4


def test_twins_are_identical_outside_the_drones_own_signatures():
    from simulator.physics.acoustics import synthesize_audio
    from simulator.physics.rf import synthesize_rf
    from simulator.physics.timeline import build_timeline

    cfg = _cfg()
    drone, twin = tr.build_plan(cfg, seed=5)[:2]
    fd = tr.render_clip_frames(drone.scenario, drone.seed, cfg, tr._default_frames, 14)
    assert twin.layout == drone.scenario and drone.layout is None     # the twin renders with its drone clip's layout
    ft = tr.render_clip_frames(twin.scenario, twin.seed, cfg, tr._default_frames, 14, layout=twin.layout)
    delta = np.abs(fd.astype(np.int16) - ft.astype(np.int16)).max(-1)
    diff = delta > 2             # <= 2/255 elsewhere: light the drone itself reflects onto a nearby bird
    assert diff.any()                                                # the drone is visible
    assert (delta > 0).mean() < 0.01                                 # > 99 % of pixels byte-identical
    tl = build_timeline(drone.scenario, drone.seed)
    cam = tl.cameras["rgb"]
    yy, xx = np.mgrid[:112, :112]
    for i in range(0, 14, 7):                                        # rendered frames (stride 7)
        xy, depth = cam.project(i, tl.targets[-1].position_m[i])
        r = tl.targets[-1].size_m * cam.focal_px / float(depth[0]) + 3.0
        outside = np.hypot(xx - xy[0, 0], yy - xy[0, 1]) > r
        assert not diff[i][outside].any(), f"frame {i}: pixels away from the drone differ"
    ad = synthesize_audio(tl, drone.seed, ambience=drone.ambience, duration_s=0.5)
    at = synthesize_audio(build_timeline(twin.scenario, twin.seed), twin.seed, ambience=twin.ambience, duration_s=0.5)
    for name, wave in at.targets_pa.items():                         # every confuser source byte-identical
        assert ad.targets_pa[name].tobytes() == wave.tobytes()
    assert set(ad.targets_pa) - set(at.targets_pa) == {"drone"}
    starts = np.arange(2) * 0.25
    rd = synthesize_rf(tl, drone.seed, starts, config=drone.rf, rf_silent=True, clip_duration_s=0.5)
    rt = synthesize_rf(build_timeline(twin.scenario, twin.seed), twin.seed, starts, config=twin.rf, clip_duration_s=0.5)
    assert rd.iq.tobytes() == rt.iq.tobytes()                        # without its links, the drone adds no RF


def test_generated_clips_record_scene_split_and_twin(tmp_path):
    cfg = _cfg(n_scenes=3, n_test_scenes=1, n_val_scenes=1)

    def frames(s, seed, n, w, h, layout=None):
        return np.full((n, h, w, 3), 120, np.uint8)

    out = tr.generate_trident(cfg, tmp_path / "d", seed=2, progress=False, render_frames=frames)
    man = json.loads((out / "manifest.json").read_text())
    by_clip = {c["clip"]: c for c in man["clips"]}
    assert len(by_clip) == 6
    for c in man["clips"]:
        twin = by_clip[c["twin"]]
        assert twin["twin"] == c["clip"] and twin["scene"] == c["scene"] and twin["split"] == c["split"]
        assert {c["label"], twin["label"]} == {"Drone", "Background"}
    lab = json.loads((out / "labels" / "Drone" / man["clips"][0]["group"] / "1.json").read_text())
    assert lab["split"] == man["clips"][0]["split"] and len(lab["drone_px"]) == 2


def test_scene_config_errors_name_the_field():
    with pytest.raises(UserInputError, match="n_test_scenes.*at least one"):
        _cfg(n_scenes=3, n_test_scenes=2, n_val_scenes=1)
    with pytest.raises(UserInputError, match="drone_px: low 30.0 exceeds high 3.0"):
        _cfg(drone_px=[30.0, 3.0])
    with pytest.raises(UserInputError, match="video_render_stride"):
        tr.load_trident_config({"name": "x", "video_render_stride": 3, "scenes": {"n_scenes": 5}})


def test_ambience_distribution_has_one_home_and_older_flat_keys_still_load():
    from simulator.physics.acoustics import AmbienceDistribution

    nested = _cfg(ambience={"wind_db": [25.0, 42.0], "rain_probability": 0.0}).scenes
    flat = _cfg(wind_db=[25.0, 42.0], rain_probability=0.0).scenes
    assert isinstance(nested.ambience, AmbienceDistribution) and nested.ambience == flat.ambience
    assert nested.ambience.wind_db == (25.0, 42.0) and nested.ambience.traffic_db == tr.TRIDENT_AMBIENCE.traffic_db
    assert nested.ambience.residual_probability == 0.0      # unset fields come from TRIDENT_AMBIENCE
    cfg = tr.load_trident_config({"name": "x", "video_render_stride": 7, "scenes": {"n_scenes": 5}})
    drawn = [tr.draw_scene(cfg.scenes, cfg, 4, j).ambience for j in range(8)]
    assert all(a.residual_db is None and a.rustle_db is None and a.aircraft_db is None for a in drawn)
    assert all(32.0 <= a.wind_db <= 50.0 for a in drawn) and any(a.traffic_db is not None for a in drawn)
    with pytest.raises(UserInputError, match="either flat"):
        _cfg(wind_db=[25.0, 42.0], ambience={"rain_db": [30.0, 40.0]})
    with pytest.raises(UserInputError, match="ambience.*wind_db: low 50.0 exceeds high 40.0"):
        _cfg(ambience={"wind_db": [50.0, 40.0]})
