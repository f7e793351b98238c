"""Severity over time, per modality, and the named conflict programs.

A schedule maps times (s) to a continuous severity in [0, 5]. Event intervals are half-open,
[onset_s, onset_s + duration_s), with a 1e-9 s tolerance for float clocks; overlapping events take
the maximum. Random events come from an explicit ``seed`` (Poisson onsets at ``rate_hz`` with
uniform durations and severities), so the same spec always yields the same events.
"""
from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from degradations.base import make_rng

_EPS_S = 1e-9
Severity = Annotated[float, Field(ge=0.0, le=5.0)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Event(_Model):
    """One interval [onset_s, onset_s + duration_s) at ``severity``."""
    onset_s: Annotated[float, Field(ge=0.0)]
    duration_s: Annotated[float, Field(gt=0.0)]
    severity: Severity = 5.0


class ConstantSchedule(_Model):
    """The same severity at all times."""
    kind: Literal["constant"] = "constant"
    severity: Severity

    def severity_at(self, t_s: np.ndarray) -> np.ndarray:
        return np.full(np.shape(t_s), self.severity, dtype=np.float64)


def _events_at(events: list[Event], t_s: np.ndarray, baseline: float) -> np.ndarray:
    t = np.asarray(t_s, dtype=np.float64)
    out = np.full(t.shape, baseline, dtype=np.float64)
    for e in events:
        inside = (t >= e.onset_s - _EPS_S) & (t < e.onset_s + e.duration_s - _EPS_S)
        out = np.where(inside, np.maximum(out, e.severity), out)
    return out


class StepSchedule(_Model):
    """Step events on a ``baseline`` severity (default 0)."""
    kind: Literal["step"] = "step"
    events: list[Event]
    baseline: Severity = 0.0

    def severity_at(self, t_s: np.ndarray) -> np.ndarray:
        return _events_at(self.events, t_s, self.baseline)


class RampSchedule(_Model):
    """Linear ramp from ``from_severity`` at start_s to ``to_severity`` at end_s; holds the end
    value afterwards when ``hold`` (else returns to from_severity), from_severity before start."""
    kind: Literal["ramp"] = "ramp"
    start_s: Annotated[float, Field(ge=0.0)]
    end_s: float
    from_severity: Severity = 0.0
    to_severity: Severity = 5.0
    hold: bool = True

    @model_validator(mode="after")
    def _order(self):
        if not self.end_s > self.start_s:
            raise ValueError(f"end_s ({self.end_s}) must be greater than start_s ({self.start_s})")
        return self

    def severity_at(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=np.float64)
        frac = np.clip((t - self.start_s) / (self.end_s - self.start_s), 0.0, 1.0)
        out = self.from_severity + frac * (self.to_severity - self.from_severity)
        if not self.hold:
            out = np.where(t >= self.end_s, self.from_severity, out)
        return out


class RandomSchedule(_Model):
    """Random events: Poisson onsets (``rate_hz``) on [start_s, horizon_s), durations and
    severities uniform in the given [min, max] ranges, all drawn from ``seed``."""
    kind: Literal["random"] = "random"
    rate_hz: Annotated[float, Field(gt=0.0)]
    duration_s: tuple[Annotated[float, Field(gt=0.0)], Annotated[float, Field(gt=0.0)]] = (0.5, 2.0)
    severity: tuple[Severity, Severity] = (3.0, 5.0)
    seed: Annotated[int, Field(ge=0)]
    horizon_s: Annotated[float, Field(gt=0.0)]
    start_s: Annotated[float, Field(ge=0.0)] = 0.0

    @model_validator(mode="after")
    def _ranges(self):
        if self.duration_s[0] > self.duration_s[1]:
            raise ValueError(f"duration_s min {self.duration_s[0]} exceeds max {self.duration_s[1]}")
        if self.severity[0] > self.severity[1]:
            raise ValueError(f"severity min {self.severity[0]} exceeds max {self.severity[1]}")
        return self

    def events(self) -> list[Event]:
        """The materialised events (deterministic in ``seed``)."""
        rng = make_rng(self.seed, "schedule.random")
        out: list[Event] = []
        t = self.start_s
        while True:
            t += float(rng.exponential(1.0 / self.rate_hz))
            if t >= self.horizon_s:
                return out
            d = float(rng.uniform(*self.duration_s))
            s = float(rng.uniform(*self.severity))
            out.append(Event(onset_s=t, duration_s=d, severity=s))

    def severity_at(self, t_s: np.ndarray) -> np.ndarray:
        return _events_at(self.events(), t_s, 0.0)


Schedule = Annotated[ConstantSchedule | StepSchedule | RampSchedule | RandomSchedule,
                     Field(discriminator="kind")]


def severity_at(schedule: Schedule, t_s: np.ndarray) -> np.ndarray:
    """Severity of ``schedule`` at times ``t_s`` (float64 array of the same shape)."""
    return schedule.severity_at(np.asarray(t_s, dtype=np.float64))


# ----------------------------------------------------------------------------- conflict programs
#: program -> (description, cause -> [(degradation, stream)], default cause). Only the listed
#: streams are degraded; the others keep seeing the target, which is the conflict.
PROGRAMS: dict[str, tuple[str, dict[str, list[tuple[str, str]]], str]] = {
    "ir_blind": ("thermal crossover while RGB still sees",
                 {"crossover": [("thermal.crossover", "thermal")]}, "crossover"),
    "rgb_blind": ("glare, fog or night blinds RGB while thermal sees",
                  {"glare": [("video.sun_glare", "rgb")], "fog": [("video.fog", "rgb")],
                   "night": [("video.low_light", "rgb")]}, "glare"),
    "audio_masked": ("wind masks audio while RF still sees", {"wind": [("audio.wind", "audio")]}, "wind"),
    "rf_silent": ("autonomous flight: no RF link while the other sensors see",
                  {"autonomous": [("rf.link_silence", "rf_iq"), ("rf.spec_link_silence", "rf_spec")]},
                  "autonomous"),
    "decoy": ("a bird looks like a target to RGB/thermal while audio and RF show nothing",
              {"bird": [("video.decoy_bird", "rgb"), ("thermal.decoy_bird", "thermal")]}, "bird"),
}


def conflict_program(name: str, schedule: Schedule, cause: str | None = None) -> list[dict]:
    """Degradation entries (name, stream, schedule) that realise a named conflict program."""
    if name not in PROGRAMS:
        raise ValueError(f"unknown conflict program {name!r}; known: {sorted(PROGRAMS)}")
    _, causes, default = PROGRAMS[name]
    cause = cause or default
    if cause not in causes:
        raise ValueError(f"program {name}: cause must be one of {sorted(causes)}, got {cause!r}")
    return [{"name": deg, "stream": stream, "schedule": schedule, "program": name}
            for deg, stream in causes[cause]]


# ------------------------------------------------------------------ twin-swap conflict programs
#: program -> (description, kind, compromised modalities). ``blind`` programs act on drone clips
#: (the modality loses the drone: its stream moves to the drone-absent twin's), ``decoy`` programs
#: on background clips (the modality gains a drone-like signature from the drone twin's stream).
#: Modalities: video (RGB frames), audio (waveform), rf (spectrogram). Strength knob: 1 strong,
#: < 1 weak (see degradations.crossmodal.blend_signature).
SWAP_PROGRAMS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "video_occluded": ("cloud occlusion / glare hides the drone from the camera", "blind", ("video",)),
    "audio_drowned": ("loud ambience drowns the rotor sound", "blind", ("audio",)),
    "rf_autonomous": ("autonomous flight: the drone's control and video links go silent", "blind", ("rf",)),
    "video_decoy": ("a drone-sized look-alike (bird, balloon, model) in view; nothing to hear or receive",
                    "decoy", ("video",)),
    "audio_decoy": ("rotor-like sound (model aircraft, lawnmower, distant helicopter); nothing to see",
                    "decoy", ("audio",)),
    "rf_decoy": ("a drone-like emitter on the ground (hopping RC link, FPV video link)", "decoy", ("rf",)),
    "audio_rf_blind": ("autonomous flight in loud wind: audio and RF lose the drone, video still sees it",
                       "blind", ("audio", "rf")),
    "audio_rf_decoy": ("a ground RC transmitter next to a running model engine: audio and RF say drone, "
                       "video sees sky", "decoy", ("audio", "rf")),
    "video_rf_decoy": ("a flying look-alike carrying a radio (model aircraft): video and RF say drone, "
                       "audio hears nothing", "decoy", ("video", "rf")),
}


def swap_program(name: str) -> tuple[str, str, tuple[str, ...]]:
    """(description, kind, modalities) of a twin-swap conflict program."""
    if name not in SWAP_PROGRAMS:
        raise ValueError(f"unknown twin-swap conflict program {name!r}; known: {sorted(SWAP_PROGRAMS)}")
    return SWAP_PROGRAMS[name]
