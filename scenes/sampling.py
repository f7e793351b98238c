"""The draws every scene sampler makes: a value of a span, a choice among options, a coin, a target's
kind and size. The generation-config sampler (``simulator.dataset.config.randomised_scenario``), the
TRIDENT scene distribution (``simulator.dataset.trident.draw_scene``) and the sim2real synthetic audio
clips all draw through these, with kinds and sizes from ``scenes.kinds`` only.

Each function consumes a fixed number of values from the generator it is given (named per function),
so a sampler's draw order is the order of its calls. Pure numpy; nothing here knows about datasets.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TypeVar

import numpy as np

from scenes.kinds import DRONE_KINDS, TARGET_KINDS, TARGET_SIZE_RANGE_M

T = TypeVar("T")
Span = tuple[float, float]


def at(span: Span, u: float) -> float:
    """The point a unit draw ``u`` in [0, 1) picks on ``span`` = (low, high): low + (high - low) u."""
    return float(span[0] + (span[1] - span[0]) * u)


def uniform(rng: np.random.Generator, span: Span) -> float:
    """A uniform value of ``span`` (one draw; bit-identical to ``at(span, rng.random())``)."""
    return float(rng.uniform(span[0], span[1]))


def log_uniform(rng: np.random.Generator, span: Span) -> float:
    """A log-uniform value of ``span`` (both ends > 0; one draw)."""
    if span[0] <= 0:
        raise ValueError(f"a log-uniform span needs a low end > 0, got {span}")
    return float(np.exp(rng.uniform(np.log(span[0]), np.log(span[1]))))


def pick(rng: np.random.Generator, options: Sequence[T]) -> T:
    """One of ``options``, each equally likely (one integer draw)."""
    if not options:
        raise ValueError("nothing to pick from")
    return options[int(rng.integers(len(options)))]


def pick_at(options: Sequence[T], u: float) -> T:
    """The option a unit draw ``u`` in [0, 1) picks, each equally likely."""
    if not options:
        raise ValueError("nothing to pick from")
    return options[min(int(u * len(options)), len(options) - 1)]


def chance(rng: np.random.Generator, probability: float) -> bool:
    """True with ``probability`` (one draw, made whatever the probability)."""
    return bool(rng.random() < probability)


def sign(rng: np.random.Generator) -> float:
    """+1.0 or -1.0, each with probability 1/2 (one draw)."""
    return 1.0 if rng.random() < 0.5 else -1.0


def drone_kind(rng: np.random.Generator, kinds: Sequence[str] = DRONE_KINDS) -> str:
    """A drone kind among ``kinds`` (every one a ``scenes.kinds.DRONE_KINDS`` entry; one draw)."""
    unknown = [k for k in kinds if k not in DRONE_KINDS]
    if unknown:
        raise ValueError(f"not drone kinds: {unknown} (scenes.kinds.DRONE_KINDS: {list(DRONE_KINDS)})")
    return pick(rng, kinds)


def size_range(kind: str, table: Mapping[str, Span] = TARGET_SIZE_RANGE_M) -> Span:
    """The size span (m) of ``kind`` in ``table`` (default ``scenes.kinds.TARGET_SIZE_RANGE_M``)."""
    if kind not in TARGET_KINDS:
        raise ValueError(f"unknown target kind {kind!r} (scenes.kinds.TARGET_KINDS: {list(TARGET_KINDS)})")
    if kind not in table:
        raise ValueError(f"no size span for {kind!r}")
    return table[kind]


def target_size(rng: np.random.Generator, kind: str, table: Mapping[str, Span] = TARGET_SIZE_RANGE_M) -> float:
    """A target's overall size (m), uniform on its kind's span in ``table`` (one draw)."""
    return uniform(rng, size_range(kind, table))


def direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit vector, azimuth clockwise from +y (north) toward +x (east), elevation above the horizon."""
    b, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.sin(b) * math.cos(e), math.cos(b) * math.cos(e), math.sin(e)])
