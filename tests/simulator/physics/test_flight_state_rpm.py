"""RPM per flight state: thrust (acceleration, drag) and axial inflow (climb/descent) of fixed-pitch props."""
from __future__ import annotations

import numpy as np
import pytest

from scenes import load_scenario
from scenes.schema import Hover, Waypoints
from simulator.physics.timeline import axial_inflow_rpm, build_timeline, rotor_hover_rpm


def test_axial_inflow_rpm_by_hand():
    # 0.18 m prop at 5500 rpm (91.67 rev/s), climb 3 m/s: V / (2 D J0) = 3 / 0.216 = 13.89 rev/s
    # n = 13.89 + sqrt(13.89^2 + 91.67^2) = 106.60 rev/s = 6396 rpm; descent: 92.72 - 13.89 = 78.83 rev/s
    assert float(axial_inflow_rpm(5500.0, 3.0, 0.18)) == pytest.approx(6396.0, abs=1.0)
    assert float(axial_inflow_rpm(5500.0, -3.0, 0.18)) == pytest.approx(4730.0, abs=1.0)
    assert float(axial_inflow_rpm(5500.0, 0.0, 0.18)) == 5500.0


def _vertical(points, speed):
    scenario = load_scenario("clear_day_quad")
    target = scenario.targets[0].model_copy(update={"trajectory": Waypoints(points_m=points, speed_mps=speed)})
    return scenario.model_copy(update={"targets": [target], "duration_s": 4.0})


def test_climb_spins_faster_and_descent_slower_than_hover():
    hover = rotor_hover_rpm("quadcopter", load_scenario("clear_day_quad").targets[0].size_m)
    up = build_timeline(_vertical([(0, 100, 10), (0, 100, 40)], 3.0), 0).targets[0].rotor_rpm.mean(axis=1)
    down = build_timeline(_vertical([(0, 100, 40), (0, 100, 10)], 3.0), 0).targets[0].rotor_rpm.mean(axis=1)
    mid = slice(30, 80)                                        # steady vertical speed, away from the start
    assert np.all(up[mid] > 1.05 * hover) and np.all(down[mid] < 0.95 * hover)
    scenario = load_scenario("clear_day_quad")
    still = scenario.model_copy(update={"targets": [scenario.targets[0].model_copy(
        update={"trajectory": Hover(center_m=(0, 100, 20), drift_m=0.0)})], "duration_s": 2.0})
    level = build_timeline(still, 0).targets[0].rotor_rpm.mean(axis=1)
    assert np.allclose(level, hover, rtol=0.01)
