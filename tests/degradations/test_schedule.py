"""Schedules give exactly the declared intervals; random events are seeded."""
from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from degradations.schedule import (
    PROGRAMS,
    ConstantSchedule,
    Event,
    RampSchedule,
    RandomSchedule,
    StepSchedule,
    conflict_program,
)


def test_step_events_exact_half_open_intervals():
    t = np.arange(300) / 30.0  # 10 s at 30 fps
    s = StepSchedule(events=[Event(onset_s=1.0, duration_s=2.0, severity=4.0),
                             Event(onset_s=2.5, duration_s=1.0, severity=5.0)])
    sev = s.severity_at(t)
    np.testing.assert_array_equal(np.flatnonzero(sev > 0), np.arange(30, 105))  # [1.0, 3.5)
    assert np.all(sev[30:75] == 4.0) and np.all(sev[75:105] == 5.0)  # overlap takes the max
    assert sev[29] == 0 and sev[105] == 0


def test_constant_and_ramp():
    t = np.linspace(0, 10, 101)
    assert np.all(ConstantSchedule(severity=2.5).severity_at(t) == 2.5)
    r = RampSchedule(start_s=2.0, end_s=6.0, from_severity=1.0, to_severity=5.0)
    sev = r.severity_at(t)
    assert sev[0] == 1.0 and sev[40] == pytest.approx(3.0) and sev[60] == 5.0 and sev[100] == 5.0
    assert np.all(np.diff(sev) >= 0)
    r2 = RampSchedule(start_s=2.0, end_s=6.0, to_severity=5.0, hold=False)
    assert r2.severity_at(np.array([7.0]))[0] == 0.0
    with pytest.raises(ValidationError, match="end_s"):
        RampSchedule(start_s=3.0, end_s=2.0)


def test_random_events_seeded_and_exact():
    r = RandomSchedule(rate_hz=0.5, duration_s=(0.5, 1.5), severity=(3.0, 5.0), seed=7, horizon_s=60.0)
    ev = r.events()
    assert ev == RandomSchedule(**{**r.model_dump(), "seed": 7}).events()
    assert ev != RandomSchedule(**{**r.model_dump(), "seed": 8}).events()
    assert 10 <= len(ev) <= 50  # Poisson(30)
    assert all(0.5 <= e.duration_s <= 1.5 and 3.0 <= e.severity <= 5.0 for e in ev)
    t = np.arange(0, 60, 0.01)
    sev = r.severity_at(t)
    inside = np.zeros(t.size, bool)
    for e in ev:
        inside |= (t >= e.onset_s) & (t < e.onset_s + e.duration_s)
    np.testing.assert_array_equal(sev > 0, inside)


def test_programs_and_causes():
    sched = StepSchedule(events=[Event(onset_s=0, duration_s=1)])
    assert set(PROGRAMS) == {"ir_blind", "rgb_blind", "audio_masked", "rf_silent", "decoy"}
    assert [e["name"] for e in conflict_program("rgb_blind", sched, "fog")] == ["video.fog"]
    with pytest.raises(ValueError, match="cause"):
        conflict_program("rgb_blind", sched, "rain")
    with pytest.raises(ValueError, match="unknown conflict program"):
        conflict_program("nope", sched)
