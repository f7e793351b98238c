"""Shared test helpers: shrink scenarios so renders stay fast on a 2-core CPU."""
from __future__ import annotations

import pytest

from scenes.schema import Scenario


def shrink(scenario: Scenario, width_px: int = 160, height_px: int = 128, spp: int = 2,
           thermal_width_px: int | None = None, thermal_height_px: int | None = None) -> Scenario:
    """Same scene, smaller images (same field of view)."""
    rig = scenario.camera_rig
    rgb = rig.rgb.model_copy(update={"width_px": width_px, "height_px": height_px, "spp": spp})
    th = rig.thermal.model_copy(update={"width_px": thermal_width_px or width_px,
                                        "height_px": thermal_height_px or height_px, "spp": spp})
    return scenario.model_copy(update={"camera_rig": rig.model_copy(update={"rgb": rgb, "thermal": th})})


@pytest.fixture
def shrink_scenario():
    return shrink


def _hypothesis_profile() -> None:
    """CI runs property tests derandomized (a fixed example sequence) so a run can only fail for a
    reason that reproduces; locally hypothesis explores new examples each run."""
    import os

    from hypothesis import settings

    settings.register_profile("ci", derandomize=True, deadline=None)
    if os.environ.get("CI"):
        settings.load_profile("ci")


_hypothesis_profile()
