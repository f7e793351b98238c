"""Drawn orbits keep the bank of their target kind physical: the radius is at least v^2 / (g tan(bank))
(scenes.kinds.MAX_BANK_DEG), a radius that was already physical is kept as drawn, and the bank the
timeline poses a generated orbit at stays within the kind's limit."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scenes.kinds import MAX_BANK_DEG, TARGET_KINDS
from scenes.loader import validate_mapping
from scenes.schema import Orbit
from simulator.dataset.config import GenerationConfig, _orbit_radius, _trajectory, randomised_scenario
from simulator.physics.timeline import build_timeline
from simulator.physics.trajectory import GRAVITY_MPS2, min_orbit_radius_m, positions_m

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "sim2real"


def _bank_deg(orbit: Orbit) -> float:
    return math.degrees(math.atan(orbit.speed_mps ** 2 / (GRAVITY_MPS2 * orbit.radius_m)))


def test_minimum_radius_by_hand():
    # 40 m/s at 30 deg: 1600 / (9.81 x 0.577350) = 282.4955 m; 12 m/s at 35 deg: 144 / (9.81 x 0.700208)
    assert min_orbit_radius_m(40.0, 30.0) == pytest.approx(282.4955, abs=1e-3)
    assert min_orbit_radius_m(12.0, 35.0) == pytest.approx(20.9637, abs=1e-3)
    assert min_orbit_radius_m(20.0, 45.0) == pytest.approx(400.0 / 9.81, rel=1e-12)
    with pytest.raises(ValueError, match="max_bank_deg"):
        min_orbit_radius_m(10.0, 90.0)


def test_a_physical_radius_is_kept_as_drawn_and_a_tight_one_raised():
    assert _orbit_radius(17.12345, 3.0, 35.0) == 17.123          # 3 m/s needs 1.3 m: kept, as before
    assert _orbit_radius(10.0, 40.0, 30.0) == 282.496            # raised, rounded up to the millimetre


def test_the_table_covers_every_kind_and_turns_level_flight_no_steeper_than_the_renderer_clip():
    assert set(MAX_BANK_DEG) == set(TARGET_KINDS)
    assert all(0.0 < b <= 60.0 for b in MAX_BANK_DEG.values())
    assert MAX_BANK_DEG["helicopter"] == MAX_BANK_DEG["airliner"] == 30.0


def test_a_raised_orbit_starts_where_the_drawn_one_did_and_an_unraised_one_is_unchanged():
    centre = np.array([0.0, 500.0, 100.0])
    loose = _trajectory("orbit", centre, 40.0, 2.0, np.random.default_rng(3), 89.999)   # the old draw
    raised = _trajectory("orbit", centre, 40.0, 2.0, np.random.default_rng(3), 30.0)
    assert isinstance(loose, Orbit) and isinstance(raised, Orbit)
    assert loose.center_m == (0.0, 500.0, 100.0) and raised.radius_m == 282.496 > loose.radius_m
    assert (raised.clockwise, raised.start_angle_deg) == (loose.clockwise, loose.start_angle_deg)
    start = [positions_m(o, np.zeros(1), np.random.default_rng(0))[0] for o in (loose, raised)]
    assert np.allclose(start[0], start[1], atol=2e-3)
    slow = [_trajectory("orbit", centre, 3.0, 2.0, np.random.default_rng(3), b) for b in (89.999, 35.0)]
    assert slow[0] == slow[1]


@settings(max_examples=60, deadline=None)
@given(kind=st.sampled_from(TARGET_KINDS), speed=st.floats(0.5, 250.0), seed=st.integers(0, 2 ** 32 - 1))
def test_every_drawn_orbit_banks_within_its_kind_limit(kind: str, speed: float, seed: int):
    rng = np.random.default_rng(seed)
    orbit = _trajectory("orbit", np.array([0.0, 500.0, 100.0]), speed, 2.0, rng, MAX_BANK_DEG[kind])
    assert isinstance(orbit, Orbit)
    assert orbit.radius_m >= 5.0
    assert _bank_deg(orbit) <= MAX_BANK_DEG[kind] + 1e-9


@pytest.mark.parametrize("scenario, kinds, speed", [
    ("realism_helicopter.yaml", None, [20, 60]),
    ("realism_drone.yaml", ["quadcopter", "hexacopter", "fixed_wing"], [3, 12]),
    ("realism_bird.yaml", None, [4, 14]),
])
def test_generated_orbits_bank_within_the_limit_in_the_timeline(scenario: str, kinds, speed):
    randomise = {"distance_bins": [{"weight": 1, "range_m": [300, 900]}], "trajectory_kinds": ["orbit"],
                 "speed_mps": speed, "hfov_deg": [24, 24]}
    if kinds:
        randomise["target_kinds"] = kinds
    config = validate_mapping(GenerationConfig, {"name": "t", "mixture": [{"scenario": str(EXAMPLES / scenario)}],
                                                 "randomise": randomise, "frames": 8, "image_size": [96, 80],
                                                 "spp": 1}, "test")
    for index in range(6):
        _, scene = randomised_scenario(config, 5, index)
        target = scene.targets[0]
        orbit = target.trajectory
        assert isinstance(orbit, Orbit)
        assert _bank_deg(orbit) <= MAX_BANK_DEG[target.kind] + 1e-9
        if target.kind in ("fixed_wing", "bird", "airliner", "helicopter"):
            up = build_timeline(scene, 0).targets[0].rotation[:, :, 2]     # body up axis per frame
            bank = np.degrees(np.arccos(np.clip(up[:, 2], -1.0, 1.0)))
            assert bank.max() <= MAX_BANK_DEG[target.kind] + 0.5
