"""Both scene samplers (generation configs, TRIDENT scene distributions) and the sim2real synthetic
audio clips take kinds and sizes from scenes.kinds, and draw what they drew before the samplers were
made of scenes.sampling's steps (pinned values of seed 0: a changed draw order fails here)."""
from __future__ import annotations

import pytest
from pydantic import ValidationError

from scenes.kinds import BENCHMARK_DRONE_SIZE_RANGE_M, DISTRACTOR_KINDS, DRONE_KINDS, TARGET_SIZE_RANGE_M
from simulator.dataset import trident as tr
from simulator.dataset.config import Randomisation, load_generation_config, randomised_scenario
from simulator.seeding import rng_for


def _inside(value: float, span: tuple[float, float], digits: int) -> bool:
    tol = 0.5 * 10 ** -digits        # the samplers round what they write
    return span[0] - tol <= value <= span[1] + tol


def test_config_kind_fields_accept_the_scenes_kinds_only():
    for kind in DRONE_KINDS:
        assert Randomisation(target_kinds=[kind]).target_kinds == [kind]
    for kind in DISTRACTOR_KINDS:
        assert Randomisation(distractor_kinds=[kind]).distractor_kinds == [kind]
    for field, bad in (("target_kinds", "bird"), ("distractor_kinds", "quadcopter")):
        with pytest.raises(ValidationError):
            Randomisation(**{field: [bad]})
    for kind in DRONE_KINDS:
        assert tr.SceneDistribution(n_scenes=3, drone_kinds=[kind]).drone_kinds == [kind]
    with pytest.raises(ValidationError):
        tr.SceneDistribution(n_scenes=3, drone_kinds=["helicopter"])


def test_trident_drones_and_airliners_take_their_sizes_from_the_scenes_table():
    cfg = tr.load_trident_config("trident_scenes")
    dist = cfg.scenes.model_copy(update={"airliner_probability": 1.0})
    seen = set()
    for j in range(40):
        scene = tr.draw_scene(dist, cfg, 3, j)
        kind = scene.conditions["drone_kind"]
        seen.add(kind)
        drone = scene.drone.targets[-1]
        assert drone.kind == kind and _inside(drone.size_m, TARGET_SIZE_RANGE_M[kind], 4)
        jets = [t for t in scene.drone.targets if t.kind == "airliner"]
        assert len(jets) == 1 and _inside(jets[0].size_m, TARGET_SIZE_RANGE_M["airliner"], 1)
    assert seen == set(dist.drone_kinds) and seen <= set(DRONE_KINDS)


def test_generation_distractors_take_their_sizes_from_the_scenes_table():
    cfg = load_generation_config({"name": "d", "mixture": [{"scenario": "clear_day_quad"}],
                                  "randomise": {"distractors": [3, 3],
                                                "distractor_kinds": ["bird", "airliner", "helicopter"]}})
    seen = set()
    for i in range(12):
        extra = [t for t in randomised_scenario(cfg, 5, i)[1].targets if t.name.startswith("distractor")]
        assert len(extra) == 3
        for t in extra:
            seen.add(t.kind)
            assert t.kind in DISTRACTOR_KINDS and _inside(t.size_m, TARGET_SIZE_RANGE_M[t.kind], 3)
    assert seen == set(DISTRACTOR_KINDS)


def test_the_sim2real_audio_default_spans_come_from_scenes():
    from harness.experiments.sim2real import audio

    cfg = audio.synthetic_audio_config({"drone_kinds": list(DRONE_KINDS)})
    assert cfg.drone_size_m == BENCHMARK_DRONE_SIZE_RANGE_M
    for j in range(30):
        _, info = audio._drone_scenario(cfg, rng_for(1, "generation", 9, j), f"c{j}")
        assert info["kind"] in DRONE_KINDS and _inside(info["size_m"], cfg.drone_size_m[info["kind"]], 12)
    with pytest.raises(Exception, match="unknown drone kind"):
        audio.synthetic_audio_config({"drone_kinds": ["bird"]})


def test_pinned_draws_of_seed_0():
    """Values written by the samplers before they were split into scenes.sampling's steps."""
    cfg = tr.load_trident_config("trident_scenes")
    c = tr.draw_scene(cfg.scenes, cfg, 0, 0).conditions
    assert (c["drone_kind"], c["drone_size_m"], c["range_m"], c["drone_px_drawn"], c["n_birds"], c["airliner"]) \
        == ("hexacopter", 0.885, 51.2, 19.22, 2, False)
    c = tr.draw_scene(cfg.scenes, cfg, 0, 1).conditions
    assert (c["drone_kind"], c["drone_size_m"], c["range_m"], c["sun_elevation_deg"], c["airliner"]) \
        == ("fixed_wing", 1.755, 137.4, 20.87, True)

    gen = load_generation_config("mixed_small")
    source, s = randomised_scenario(gen, 0, 1)
    assert source == "dusk_crossover"
    assert [(t.kind, t.size_m) for t in s.targets] == [("quadcopter", 0.5068), ("airliner", 50.835)]
    assert (s.sky.sun.elevation_deg, s.atmosphere.air_temperature_k, s.camera_rig.rgb.hfov_deg) \
        == (58.8474, 294.374, 4.7763)

    from harness.experiments.sim2real import audio

    acfg = audio.synthetic_audio_config({"drone_kinds": list(DRONE_KINDS)})
    info = audio._drone_scenario(acfg, rng_for(0, "generation", audio._SYNTH_TAG, 0, 2), "x")[1]
    assert info["kind"] == "hexacopter" and round(info["size_m"], 6) == 0.711179
