"""Recording chain: sound pressure at the microphone -> the samples a consumer recorder writes.

Stages (each switchable; parameters that the hardware leaves open are drawn per clip from
``RecorderConfig`` ranges, ``rng_for(seed, "acoustics", *indices, RECORDER_STREAM_INDEX)``):

1. microphone response: 2nd-order high-pass (small electret capsules and their wind-noise filters
   roll off below ~30-100 Hz), a broad presence lift (+0-5 dB around 2-6 kHz, typical of small
   cardioid/shotgun electrets) and a 2nd-order low-pass (12-20 kHz, at most 0.45 fs);
2. self-noise of capsule and preamplifier (a white floor, dB re full scale after the gain);
3. automatic gain control: the level (RMS in 50 ms blocks) is followed with a fast attack and a slow
   release and the gain steers it to a target level, between a minimum and maximum gain, as consumer
   recorders and laptop inputs do (the gain 'pumps' with loud events); opt-in (``agc_detector: mean``)
   the detector instead follows the mean of the block levels in dB with one time constant (the drawn
   release) both ways, as WebRTC's AGC2 speech-level estimator does (a leaky average of frame RMS levels
   in dBFS), so a governed recording sits at its target on average rather than under it;
3b. a downward expander (noise gate) on some recorders (laptop inputs and their noise suppression):
   below a threshold level the gain falls by (ratio - 1) dB per dB, within a range; in the calibration
   half quiet recordings (backgrounds, far drones) dip 15-20 dB under their median 100 ms level in 6
   of 15 background clips while loud ones (helicopters, near drones) do not, which a gate on a
   class-blind recorder gives;
4. clipping at full scale and quantisation to the recording's bit depth (16 bit by default);
5. the band limit of a lossy encoder (MP3/AAC encoders low-pass at ~15-17 kHz at consumer bit rates),
   drawn per clip: on with ``codec_probability``, cutoff in ``codec_cutoff_hz``, a brick-wall in the
   spectrum with a short raised-cosine edge. In the calibration half of the Svanström audio 26 of 45
   clips end at 15-17 kHz (the level at 18 kHz 40-81 dB under the 6-9 kHz level) and 19 run flat to
   18 kHz (-10..-18 dB), in every class alike, so the chain draws it class-blind.

The Svanström recordings were made with a small cardioid electret (thesis: Boya BY-MM1) into a
laptop; its response, gain and AGC are not published, hence the ranges.
"""
from __future__ import annotations

from typing import ClassVar, Literal

import numpy as np
from pydantic import ConfigDict, Field, model_validator

from scenes.schema import OmitWhenUnset
from simulator.seeding import rng_for

RECORDER_STREAM_INDEX = 3000
AGC_BLOCK_S = 0.05
Span = tuple[float, float]


class RecorderConfig(OmitWhenUnset):
    """The recording chain; spans (low, high) are drawn uniformly per clip."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    enabled: bool = True
    highpass_hz: Span = (30.0, 100.0)
    lowpass_hz: Span = Field(default=(17_000.0, 21_000.0), description=(
        "capsule roll-off (the Boya BY-MM1 is specified to 18 kHz); clamped to 0.45 fs"))
    presence_db: Span = (0.0, 5.0)
    presence_hz: Span = (2000.0, 6000.0)
    self_noise_dbfs: Span = (-80.0, -66.0)
    agc: bool = True
    agc_target_dbfs: Span = (-32.0, -22.0)
    agc_release_s: Span = (0.5, 3.0)
    agc_attack_s: float = Field(default=0.05, gt=0.0)
    agc_max_gain_db: float = Field(default=3.0, ge=0.0)
    agc_min_gain_db: float = Field(default=-26.0, le=0.0)
    agc_detector: Literal["peak", "mean"] | None = Field(default=None, description=(
        "the AGC's level detector: 'peak' (None, the default) follows the 50 ms block RMS with agc_attack_s "
        "rising and the drawn release falling, so a governed recording sits under its target by its level "
        "swings; 'mean' follows the mean of the block levels in dB with the drawn release both ways "
        "(WebRTC AGC2's speech-level estimator: a leaky average of frame RMS levels in dBFS), so a steady "
        "recording sits at its target"))
    input_gain_db: Span = Field(default=(-8.0, 4.0), description="gain before the AGC (or the fixed gain without it)")
    gate_probability: float = Field(default=0.5, ge=0.0, le=1.0, description="share of clips with a noise gate")
    gate_threshold_dbfs: Span = (-48.0, -36.0)
    gate_ratio: Span = (2.0, 4.0)
    gate_range_db: Span = (-30.0, -15.0)
    gate_release_s: Span = (0.05, 0.3)
    bit_depth: int = Field(default=16, ge=8, le=32)
    codec_probability: float = Field(default=0.58, ge=0.0, le=1.0, description="share of clips an encoder band-limits")
    codec_cutoff_hz: Span = (15_000.0, 17_000.0)
    codec_edge_hz: float = Field(default=300.0, gt=0.0, description="width of the encoder's raised-cosine edge")
    codec_floor_db: float = Field(default=-70.0, le=0.0, description="what the encoder leaves above its cutoff")
    clip: bool = True

    #: fields added after TRIDENT manifests froze, left out of dumps (and their hashes) while unset
    _OMIT_WHEN_UNSET: ClassVar[tuple[str, ...]] = ("agc_detector",)

    @model_validator(mode="after")
    def _spans(self) -> RecorderConfig:
        for name, value in self.model_dump().items():
            if isinstance(value, tuple) and value[0] > value[1]:
                raise ValueError(f"{name}: low {value[0]} exceeds high {value[1]}")
        if self.highpass_hz[0] <= 0 or self.lowpass_hz[0] <= self.highpass_hz[1]:
            raise ValueError("highpass_hz must be > 0 and below lowpass_hz")
        if self.codec_cutoff_hz[0] <= self.highpass_hz[1]:
            raise ValueError("codec_cutoff_hz must lie above highpass_hz")
        return self


def microphone_response_db(freqs_hz: np.ndarray, highpass_hz: float, lowpass_hz: float, presence_db: float,
                           presence_hz: float) -> np.ndarray:
    """Magnitude response (dB) of the capsule model: 2nd-order Butterworth high- and low-pass and a
    1-octave-wide (Gaussian in log f) presence lift."""
    f = np.maximum(np.asarray(freqs_hz, dtype=np.float64), 1e-3)
    hp = (f / highpass_hz) ** 4 / (1 + (f / highpass_hz) ** 4)
    lp = 1 / (1 + (f / lowpass_hz) ** 4)
    lift = presence_db * np.exp(-0.5 * (np.log2(f / presence_hz)) ** 2)
    return 10 * np.log10(np.maximum(hp * lp, 1e-30)) + lift


def codec_response_db(freqs_hz: np.ndarray, cutoff_hz: float, edge_hz: float, floor_db: float) -> np.ndarray:
    """Encoder band limit (dB): 0 below ``cutoff_hz - edge_hz``, ``floor_db`` above ``cutoff_hz``, a
    raised-cosine (in amplitude) edge between."""
    f = np.asarray(freqs_hz, dtype=np.float64)
    x = np.clip((f - (cutoff_hz - edge_hz)) / edge_hz, 0.0, 1.0)
    floor = 10 ** (floor_db / 20)
    amp = floor + (1 - floor) * 0.5 * (1 + np.cos(np.pi * x))
    return 20 * np.log10(amp)


def _apply_response(x: np.ndarray, sample_rate_hz: float, response_db_fn) -> np.ndarray:
    import scipy.fft as sfft

    n_fft = sfft.next_fast_len(x.size, real=True)
    f = np.fft.rfftfreq(n_fft, 1.0 / sample_rate_hz)
    return sfft.irfft(sfft.rfft(x, n_fft) * 10 ** (response_db_fn(f) / 20), n_fft)[: x.size]


def agc_gain(x: np.ndarray, sample_rate_hz: float, target_dbfs: float, attack_s: float, release_s: float,
             min_gain_db: float, max_gain_db: float, detector: str = "peak") -> np.ndarray:
    """Per-sample AGC gain: block RMS (50 ms) followed by a one-pole detector, gain = target / level within
    the gain limits. ``detector`` 'peak': on the RMS, level rising with the attack time constant, falling
    with the release; 'mean': on the block levels in dB, the release time constant both ways."""
    if detector not in ("peak", "mean"):
        raise ValueError(f"detector must be 'peak' or 'mean', got {detector!r}")
    block = max(1, round(AGC_BLOCK_S * sample_rate_hz))
    n_blocks = int(np.ceil(x.size / block))
    padded = np.pad(x, (0, n_blocks * block - x.size))
    level = np.sqrt(np.mean(padded.reshape(n_blocks, block) ** 2, axis=1) + 1e-20)
    a_att, a_rel = np.exp(-AGC_BLOCK_S / attack_s), np.exp(-AGC_BLOCK_S / release_s)
    if detector == "mean":
        a_att = a_rel                                  # one time constant both ways
        level = 20 * np.log10(level)
    env = np.empty(n_blocks)
    e = level[0]
    for i, v in enumerate(level):                      # a few hundred blocks: a plain loop is fine
        a = a_att if v > e else a_rel
        e = a * e + (1 - a) * v
        env[i] = e
    env_db = env if detector == "mean" else 20 * np.log10(env)
    gain_db = np.clip(target_dbfs - env_db, min_gain_db, max_gain_db)
    centres = (np.arange(n_blocks) + 0.5) * block
    return 10 ** (np.interp(np.arange(x.size), centres, gain_db) / 20)


def gate_gain(x: np.ndarray, sample_rate_hz: float, threshold_dbfs: float, ratio: float, range_db: float,
              release_s: float, attack_s: float = 0.005) -> np.ndarray:
    """Per-sample gain of a downward expander: 10 ms block levels L under ``threshold_dbfs`` get
    (ratio - 1)(L - threshold) dB (no less than ``range_db``); the gain opens with ``attack_s`` and
    closes with ``release_s`` (one-pole, per block)."""
    block = max(1, round(0.01 * sample_rate_hz))
    n_blocks = int(np.ceil(x.size / block))
    padded = np.pad(x, (0, n_blocks * block - x.size))
    level = 10 * np.log10(np.mean(padded.reshape(n_blocks, block) ** 2, axis=1) + 1e-20)
    want = np.clip((ratio - 1.0) * np.minimum(level - threshold_dbfs, 0.0), range_db, 0.0)
    a_att, a_rel = np.exp(-0.01 / attack_s), np.exp(-0.01 / release_s)
    gain = np.empty(n_blocks)
    g = 0.0
    for i, w in enumerate(want):                       # ~1000 blocks per 10 s: a plain loop is fine
        a = a_att if w > g else a_rel
        g = a * g + (1 - a) * w
        gain[i] = g
    centres = (np.arange(n_blocks) + 0.5) * block
    return 10 ** (np.interp(np.arange(x.size), centres, gain) / 20)


def record(pressure_pa: np.ndarray, sample_rate_hz: float, *, seed: int, index: int = 0, full_scale_pa: float = 0.1,
           config: RecorderConfig | None = None) -> np.ndarray:
    """Recorded samples (float32, full scale 1.0) of a pressure signal (Pa) through the chain above.

    ``full_scale_pa`` is the pressure that reaches full scale at 0 dB input gain. Disabled config:
    pressure / full_scale_pa. Deterministic per (seed, index).
    """
    cfg = config or RecorderConfig()
    x = np.asarray(pressure_pa, dtype=np.float64).reshape(-1) / float(full_scale_pa)
    if not full_scale_pa > 0:
        raise ValueError(f"full_scale_pa must be > 0, got {full_scale_pa}")
    if not cfg.enabled or x.size == 0:
        return x.astype(np.float32)
    rng = rng_for(seed, "acoustics", int(index), RECORDER_STREAM_INDEX)
    u = lambda span: float(rng.uniform(*span))  # noqa: E731
    hp, lp = u(cfg.highpass_hz), min(u(cfg.lowpass_hz), 0.45 * sample_rate_hz)
    pres_db, pres_hz = u(cfg.presence_db), u(cfg.presence_hz)
    noise_dbfs, target, release = u(cfg.self_noise_dbfs), u(cfg.agc_target_dbfs), u(cfg.agc_release_s)
    input_gain = 10 ** (u(cfg.input_gain_db) / 20)
    codec_on, cutoff = bool(rng.random() < cfg.codec_probability), min(u(cfg.codec_cutoff_hz), 0.45 * sample_rate_hz)
    gate_on = bool(rng.random() < cfg.gate_probability)
    gate = (u(cfg.gate_threshold_dbfs), u(cfg.gate_ratio), u(cfg.gate_range_db), u(cfg.gate_release_s))
    y = _apply_response(x, sample_rate_hz, lambda f: microphone_response_db(f, hp, lp, pres_db, pres_hz)) * input_gain
    if cfg.agc:
        y = y * agc_gain(y, sample_rate_hz, target, cfg.agc_attack_s, release, cfg.agc_min_gain_db, cfg.agc_max_gain_db,
                         detector=cfg.agc_detector or "peak")
    y = y + 10 ** (noise_dbfs / 20) * rng.standard_normal(y.size)
    if gate_on:                        # the gate follows the digitised signal, self-noise included
        y = y * gate_gain(y, sample_rate_hz, *gate)
    if cfg.clip:
        y = np.clip(y, -1.0, 1.0)
    if codec_on:                       # the encoder sees the clipped recording, self-noise included
        y = np.clip(_apply_response(y, sample_rate_hz, lambda f: codec_response_db(f, cutoff, cfg.codec_edge_hz,
                                                                                   cfg.codec_floor_db)), -1.0, 1.0)
    steps = 2 ** (cfg.bit_depth - 1) - 1
    return (np.round(y * steps) / steps).astype(np.float32)
