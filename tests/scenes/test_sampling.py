"""scenes.sampling, the draws every scene sampler makes: hand-checked values, kinds only from
scenes.kinds, sizes inside the scenes table, one draw per call, same seed -> same draw."""
from __future__ import annotations

import numpy as np
import pytest

from scenes import sampling
from scenes.kinds import DRONE_KINDS, DRONE_SIZE_M, TARGET_KINDS, TARGET_SIZE_RANGE_M


def test_at_is_the_point_of_the_span():
    assert sampling.at((2.0, 4.0), 0.0) == 2.0
    assert sampling.at((2.0, 4.0), 0.25) == 2.5
    assert sampling.at((-1.0, 1.0), 0.5) == 0.0
    assert sampling.at((3.0, 3.0), 0.9) == 3.0


def test_uniform_is_bit_identical_to_a_unit_draw_on_the_span():
    """The generation sampler scales rng.random(), TRIDENT calls rng.uniform: the same numbers."""
    a, b = np.random.default_rng(5), np.random.default_rng(5)
    for span in [(0.0, 1.0), (-60.0, 60.0), (0.3, 0.6), (5000.0, 11000.0), (273.0, 305.0)] * 200:
        assert sampling.uniform(a, span) == sampling.at(span, b.random())


def test_log_uniform_stays_in_its_span_and_is_uniform_in_the_log():
    rng = np.random.default_rng(0)
    x = np.array([sampling.log_uniform(rng, (10.0, 1000.0)) for _ in range(4000)])
    assert x.min() >= 10.0 and x.max() <= 1000.0
    assert abs(np.median(x) - 100.0) < 10.0          # geometric mean of the ends, not 505
    with pytest.raises(ValueError, match="low end > 0"):
        sampling.log_uniform(rng, (0.0, 10.0))


def test_pick_at_splits_the_unit_interval_evenly():
    options = ["a", "b", "c"]
    assert sampling.pick_at(options, 0.0) == "a"
    assert sampling.pick_at(options, 0.34) == "b"
    assert sampling.pick_at(options, 0.67) == "c"
    assert sampling.pick_at(options, 1.0) == "c"     # clamped
    with pytest.raises(ValueError):
        sampling.pick_at([], 0.5)


def test_every_draw_consumes_a_fixed_number_of_values():
    """chance draws even at probability 0 or 1, so what follows keeps its place in the stream."""
    for draw in (lambda r: sampling.chance(r, 0.0), lambda r: sampling.chance(r, 1.0), sampling.sign,
                 lambda r: sampling.uniform(r, (1.0, 2.0)), lambda r: sampling.log_uniform(r, (1.0, 2.0))):
        a, b = np.random.default_rng(3), np.random.default_rng(3)
        draw(a)
        b.random()
        assert a.random() == b.random()
    rng = np.random.default_rng(1)
    assert not any(sampling.chance(rng, 0.0) for _ in range(100))
    assert all(sampling.chance(rng, 1.0) for _ in range(100))
    assert {sampling.sign(rng) for _ in range(100)} == {1.0, -1.0}


def test_drone_kinds_come_from_the_scenes_table_only():
    rng = np.random.default_rng(0)
    drawn = {sampling.drone_kind(rng) for _ in range(300)}
    assert drawn == set(DRONE_KINDS) and drawn <= set(TARGET_KINDS)
    assert {sampling.drone_kind(rng, ["hexacopter", "fixed_wing"]) for _ in range(100)} == {"hexacopter", "fixed_wing"}
    for bad in (["bird"], ["quadcopter", "octocopter"]):
        with pytest.raises(ValueError, match="not drone kinds"):
            sampling.drone_kind(rng, bad)


@pytest.mark.parametrize("kind", TARGET_KINDS)
def test_sizes_stay_inside_the_scenes_table(kind):
    lo, hi = TARGET_SIZE_RANGE_M[kind]
    rng = np.random.default_rng(7)
    sizes = np.array([sampling.target_size(rng, kind) for _ in range(500)])
    assert sizes.min() >= lo and sizes.max() <= hi
    assert sizes.min() < lo + 0.05 * (hi - lo) and sizes.max() > hi - 0.05 * (hi - lo)   # the whole span


def test_a_size_table_is_checked_against_the_kinds():
    with pytest.raises(ValueError, match="unknown target kind"):
        sampling.size_range("octocopter")
    with pytest.raises(ValueError, match="no size span"):
        sampling.size_range("hexacopter", {"quadcopter": (0.1, 0.2)})
    assert sampling.size_range("quadcopter", {"quadcopter": (0.1, 0.2)}) == (0.1, 0.2)


def test_the_size_table_covers_every_kind_and_holds_the_nominal_sizes():
    assert set(TARGET_SIZE_RANGE_M) == set(TARGET_KINDS)
    for kind, size in DRONE_SIZE_M.items():
        lo, hi = TARGET_SIZE_RANGE_M[kind]
        assert 0 < lo <= size <= hi


def test_same_seed_same_draw():
    def draws(seed):
        rng = np.random.default_rng(seed)
        kind = sampling.drone_kind(rng)
        return (kind, sampling.target_size(rng, kind), sampling.log_uniform(rng, (60.0, 400.0)),
                sampling.pick(rng, ["hover", "flyby"]), sampling.chance(rng, 0.5))

    assert draws(11) == draws(11)
    assert draws(11) != draws(12)


def test_direction_hand_checked():
    assert np.allclose(sampling.direction(0.0, 0.0), [0.0, 1.0, 0.0])     # north
    assert np.allclose(sampling.direction(90.0, 0.0), [1.0, 0.0, 0.0])    # east
    assert np.allclose(sampling.direction(0.0, 90.0), [0.0, 0.0, 1.0])    # up
    assert np.isclose(np.linalg.norm(sampling.direction(37.0, 12.0)), 1.0)
