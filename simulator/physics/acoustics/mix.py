"""A scenario's audio: every timeline target through :func:`synthesize_target` plus the ambient beds,
mixed at the microphone (:class:`AudioScene`), and the byte-reproducible float WAV writer."""
from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from scenes.kinds import DRONE_KINDS
from simulator.physics.acoustics.ambience import Ambience, BedShapes, synthesize_ambience
from simulator.physics.acoustics.levels import (
    AUDIO_SAMPLE_RATE_HZ,
    DEFAULT_GROUND_FACTOR,
    FULL_SCALE_PA,
    check_sample_rate,
    sound_power_dba,
)
from simulator.physics.acoustics.sources import synthesize_target
from simulator.seeding import rng_for


@dataclass
class AudioScene:
    """Microphone pressure (Pa) of a scenario: the mix and every component kept separately."""

    sample_rate_hz: float
    mix_pa: np.ndarray                                   # (N,) float32
    targets_pa: dict[str, np.ndarray] = field(default_factory=dict)   # target name -> (N,) float32
    target_range_m: dict[str, np.ndarray] = field(default_factory=dict)
    ambience_pa: dict[str, np.ndarray] = field(default_factory=dict)  # bed name -> (N,) float32
    sound_power_dba: dict[str, float] = field(default_factory=dict)   # drone name -> L_WA at hover used

    @property
    def n_samples(self) -> int:
        return int(self.mix_pa.size)


def synthesize_audio(timeline, seed: int, *, ambience: Ambience | None = None, duration_s: float | None = None,
                     sample_rate_hz: float = AUDIO_SAMPLE_RATE_HZ, stream_indices: tuple[int, ...] = (),
                     ground_factor: float | None = DEFAULT_GROUND_FACTOR,
                     sound_power_db: dict[str, float] | None = None, rotor_noise_ranges: dict | None = None,
                     helicopter_ranges: dict | None = None, ambience_shapes: BedShapes | None = None) -> AudioScene:
    """Audio of every timeline target plus ambient beds at the microphone (the camera rig).

    Target i draws from ``rng_for(seed, "acoustics", *stream_indices, i)``; beds from index 1000+k.
    ``duration_s`` defaults to the timeline span plus one frame. ``ground_factor`` is the ISO 9613-2
    G of the ground (0 hard, 1 porous, None = free field); ``sound_power_db`` overrides the L_WA
    of drones by target name; ``rotor_noise_ranges`` / ``helicopter_ranges`` replace spans of the
    drawn source parameters (:func:`merged_ranges`; None keeps the module's ranges); ``ambience_shapes`` sets
    the traffic and residual beds' spectra (:class:`BedShapes`; None: the module's).
    """
    check_sample_rate(sample_rate_hz)
    times = np.asarray(timeline.times_s, dtype=np.float64)
    if duration_s is None:
        step = float(times[1] - times[0]) if times.size > 1 else 1.0 / timeline.scenario.frame_rate_hz
        duration_s = float(times[-1] - times[0]) + step
    if not duration_s > 0:
        raise ValueError(f"duration_s must be > 0, got {duration_s}")
    n = round(duration_s * sample_rate_hz)
    atm = timeline.scenario.atmosphere
    wingbeats = {t.name: t.wingbeat_hz for t in timeline.scenario.targets}
    mic = np.asarray(timeline.microphone_position_m, dtype=np.float64)
    mix = np.zeros(n)
    scene = AudioScene(sample_rate_hz=float(sample_rate_hz), mix_pa=np.zeros(0, np.float32))
    for index, track in enumerate(timeline.targets):
        rng = rng_for(seed, "acoustics", *stream_indices, index)
        power = (sound_power_db or {}).get(track.name)
        received, range_m = synthesize_target(track, times, mic, n, sample_rate_hz, atm.air_temperature_k,
                                              atm.relative_humidity, rng, wingbeats.get(track.name, 4.0),
                                              ground_factor=ground_factor, sound_power_db=power,
                                              rotor_noise_ranges=rotor_noise_ranges,
                                              helicopter_ranges=helicopter_ranges)
        if track.kind in DRONE_KINDS:
            scene.sound_power_dba[track.name] = (power if power is not None
                                                 else sound_power_dba(track.kind, track.size_m))
        mix += received
        scene.targets_pa[track.name] = received.astype(np.float32)
        scene.target_range_m[track.name] = range_m.astype(np.float32)
    for name, bed in synthesize_ambience(ambience or Ambience(), n, sample_rate_hz, seed, *stream_indices,
                                         shapes=ambience_shapes).items():
        mix += bed
        scene.ambience_pa[name] = bed.astype(np.float32)
    scene.mix_pa = mix.astype(np.float32)
    return scene


def write_wav(path: str | Path, pressure_pa: np.ndarray, sample_rate_hz: float = AUDIO_SAMPLE_RATE_HZ,
              full_scale_pa: float = FULL_SCALE_PA) -> Path:
    """Mono 32-bit float WAV with sample = pressure / full_scale_pa (1.0 == 1 Pa by default)."""
    import soundfile

    check_sample_rate(sample_rate_hz)
    if not full_scale_pa > 0:
        raise ValueError(f"full_scale_pa must be > 0, got {full_scale_pa}")
    path = Path(path)
    data = (np.asarray(pressure_pa, dtype=np.float64) / full_scale_pa).astype(np.float32)
    buffer = io.BytesIO()
    soundfile.write(buffer, data, int(sample_rate_hz), subtype="FLOAT", format="WAV")
    path.write_bytes(_zero_peak_timestamp(buffer.getvalue()))
    return path


def _zero_peak_timestamp(wav: bytes) -> bytes:
    """libsndfile stamps float WAVs' PEAK chunk with the wall-clock time; zero it for byte-identical files."""
    out = bytearray(wav)
    pos = 12                                              # after 'RIFF' <size> 'WAVE'
    while pos + 8 <= len(out):
        chunk_id, size = bytes(out[pos:pos + 4]), int.from_bytes(out[pos + 4:pos + 8], "little")
        if chunk_id == b"PEAK" and size >= 8:
            out[pos + 12:pos + 16] = b"\0\0\0\0"          # version (4 bytes), then timestamp (4 bytes)
            break
        pos += 8 + size + (size & 1)
    return bytes(out)
