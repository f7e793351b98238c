"""Named random streams: every draw comes from SeedSequence([seed, stream_id, *indices]).

Every stream id lives in :data:`STREAMS` (unique values; ``tests/simulator/test_seeding.py`` fails
on a duplicate, on an ``rng_for`` name that is not registered, and on a ``SeedSequence([seed, 123, ...])``
with a literal id anywhere in the packages). The last three were literals at their call sites
before and keep their values, so every seeded output is unchanged."""
from __future__ import annotations

import numpy as np

STREAMS = {
    "trajectory": 1,
    "clouds": 2,
    "render": 3,
    "rotor_detune": 4,
    "acoustics": 5,
    "rf": 6,
    "generation": 7,
    "camera": 8,
    "sim2real": 9,
    "terrain": 10,
    "tracking": 11,
    "fusion_init": 99,          # E2 fusion heads' initialisation (harness.experiments.pipeline)
    "detection": 1600,          # the detection experiment (harness.experiments.detection.data)
    "clip_split": 0x5B117,      # E2 train/val/test split of clips (harness.experiments.data)
}


def rng_for(seed: int, stream: str, *indices: int) -> np.random.Generator:
    """An independent generator for (seed, stream, indices); adding a stream never shifts another."""
    if stream not in STREAMS:
        raise ValueError(f"unknown random stream {stream!r}; known: {sorted(STREAMS)}")
    return np.random.default_rng(np.random.SeedSequence([int(seed), STREAMS[stream], *map(int, indices)]))


def render_seed(seed: int, frame_index: int, pass_index: int) -> int:
    """A 32-bit Mitsuba sampler seed per (scenario seed, frame, pass)."""
    state = np.random.SeedSequence([int(seed), STREAMS["render"], int(frame_index), int(pass_index)])
    return int(state.generate_state(1, dtype=np.uint32)[0])
