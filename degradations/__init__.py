"""Seeded, scheduled sensor degradations for RGB, thermal, audio and RF streams.

``REGISTRY`` maps names ("audio.white_noise", "thermal.crossover", ...) to classes;
``apply(name, x, *, seed, severity=None, meta=None, **params)`` is the one-line entry point.
Schedules live in :mod:`degradations.schedule`, spec files in :mod:`degradations.spec`.
"""
from __future__ import annotations

from degradations import audio, crossmodal, rf, thermal, video  # noqa: F401  (register classes)
from degradations.base import Degradation, make_rng
from degradations.errors import DegradationError, SpecError
from degradations.registry import REGISTRY, apply, get

__all__ = ["REGISTRY", "apply", "get", "Degradation", "DegradationError", "SpecError", "make_rng"]
