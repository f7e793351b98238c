"""The audio track of ``evids sim2real``: how far synthetic drone / helicopter / background audio is
from real recordings, measured two ways.

1. Spectral statistics per 5 s segment (:func:`audio_statistics`): spectral centroid, pitchedness and
   fundamental (YIN), harmonics above the local spectral floor, 1/3-octave band levels
   (IEC 61260-1 base-10 centres 50 Hz-16 kHz, dB re full scale) and level fluctuation (std of
   100 ms levels). Per class: real median and IQR against the synthetic median.
2. Drone vs not-drone on 1 s log-mel windows (:func:`run_audio_track`) with a small CNN (torch, CPU)
   and a log-mel logistic regression (scikit-learn), trained on real calibration clips, synthetic
   clips, both, few-shot real and few-shot + synthetic, tested on the real EVALUATION half with
   clip-bootstrap 95 % intervals.

The synthetic clips come from the project's own synthesiser (:func:`synthetic_audio_clips`: a
scenario per clip through ``build_timeline`` and ``synthesize_audio``), drawn from a config and a
seed only (``rng_for(seed, "generation", ...)`` streams).
"""
from __future__ import annotations

import functools
import json
import operator
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from harness.experiments.sim2real.classify import domain_balanced_weights
from scenes.sampling import drone_kind, log_uniform, pick, target_size, uniform
from simulator.seeding import rng_for

CLASSES = ("DRONE", "HELICOPTER", "BACKGROUND")
HALVES = ("calibration", "evaluation", "synthetic")
SEGMENT_S = 5.0
WINDOW_S = 1.0
LEVEL_FRAME_S = 0.1
# IEC 61260-1 base-10 1/3-octave mid-band frequencies: 1000 x 10^(n/10), n = -13 (50 Hz) .. 12 (16 kHz)
THIRD_OCTAVE_CENTRES_HZ = tuple(float(1000.0 * 10.0 ** (n / 10.0)) for n in range(-13, 13))
NOMINAL_CENTRES_HZ = (50, 63, 80, 100, 125, 160, 200, 250, 315, 400, 500, 630, 800, 1000, 1250, 1600, 2000,
                      2500, 3150, 4000, 5000, 6300, 8000, 10000, 12500, 16000)
PYIN_SAMPLE_RATE_HZ = 8000          # YIN runs on a resampled copy (fundamentals 60-1600 Hz)
YIN_FRAME = 1024
YIN_THRESHOLD = 0.3  # CMNDF dip that counts as periodic (YIN paper: 0.1 for clean speech; outdoor noise needs more)
PYIN_FMIN_HZ, PYIN_FMAX_HZ = 60.0, 1600.0
PITCHED_VOICED_FRACTION = 0.5       # a segment is pitched when YIN voices >= half of its frames
HARMONIC_FLOOR_DB = 10.0            # a harmonic counts when its peak is this far above the local median
MAX_HARMONICS = 30
N_MELS = 40
MEL_HOP = 1024
MEL_FFT = 2048
SCALAR_STATS = ("spectral_centroid_hz", "pitched_fraction", "f0_hz", "n_harmonics", "level_fluctuation_db",
                "level_dbfs")
NOT_DRONE = ("HELICOPTER", "BACKGROUND")


@dataclass
class AudioClip:
    """One mono clip: class, clip number, samples (float32, full scale 1.0) and which half it is."""

    name: str
    cls: str
    number: int
    samples: np.ndarray
    sample_rate: int
    half: str

    def __post_init__(self) -> None:
        if self.cls not in CLASSES:
            raise ValueError(f"cls must be one of {CLASSES}, got {self.cls!r}")
        if self.half not in HALVES:
            raise ValueError(f"half must be one of {HALVES}, got {self.half!r}")
        self.samples = np.asarray(self.samples, dtype=np.float32).reshape(-1)


def real_audio_clips(bench, half: str | None = None) -> list[AudioClip]:
    """Every audio clip of a ``simulator.formats.svanstrom.SvanstromBenchmark`` (or only those of
    ``half``: the others are not read) as an AudioClip (mono float32, the benchmark's odd/even split as
    the half)."""
    clips = []
    for clip in bench.clips("audio"):
        if half is not None and clip.half != half:
            continue
        samples, sr = bench.audio(clip)
        clips.append(AudioClip(clip.name, clip.cls, clip.number, samples, int(sr), clip.half))
    return clips


def read_wav_clips(folder: Path) -> list[AudioClip]:
    """Real clips from a folder of Svanström-style ``<CLASS>_<NNN>.wav`` files (stereo mixed to mono):
    odd NNN = calibration half, even NNN = evaluation half. A stand-in until the dataset reader of
    ``simulator.formats.svanstrom`` is used by the harness."""
    import soundfile

    clips = []
    for path in sorted(Path(folder).glob("*.wav")):
        cls, _, number = path.stem.rpartition("_")
        if cls not in CLASSES or not number.isdigit():
            continue
        data, sr = soundfile.read(str(path), dtype="float32", always_2d=True)
        n = int(number)
        clips.append(AudioClip(path.stem, cls, n, data.mean(axis=1), int(sr), "calibration" if n % 2 else "evaluation"))
    if not clips:
        raise ValueError(f"folder: no <CLASS>_<NNN>.wav clips in {folder}")
    return clips


# --------------------------------------------------------------------------------------------
# Spectral statistics
# --------------------------------------------------------------------------------------------

def _psd(x: np.ndarray, sr: int, n_fft: int = 8192) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Welch power spectral density (Hann, 50 % overlap), full-scale^2 / Hz."""
    from scipy.signal import welch

    n = min(n_fft, x.size)
    return welch(x, fs=sr, window="hann", nperseg=n, noverlap=n // 2, detrend=False, scaling="density")


def third_octave_levels_db(freqs_hz: np.ndarray, psd: np.ndarray) -> np.ndarray:
    """Band levels (dB re full-scale RMS 1.0) of the IEC 61260 base-10 1/3-octave bands, from a PSD."""
    df = float(freqs_hz[1] - freqs_hz[0])
    out = np.empty(len(THIRD_OCTAVE_CENTRES_HZ))
    for i, fm in enumerate(THIRD_OCTAVE_CENTRES_HZ):
        lo, hi = fm * 10 ** (-0.05), fm * 10 ** 0.05
        band = (freqs_hz >= lo) & (freqs_hz < hi)
        out[i] = 10 * np.log10(max(float(np.sum(psd[band])) * df, 1e-20))
    return out


def yin_f0(x: np.ndarray, sr: int) -> tuple[np.ndarray, np.ndarray]:
    """YIN fundamental (de Cheveigne & Kawahara 2002, steps 1-5) per frame of an 8 kHz copy of ``x``:
    the best period candidate's f0 (Hz; the first dip below the threshold, else the global minimum) and
    voiced flags (the cumulative-mean-normalised difference dips below YIN_THRESHOLD somewhere in the
    60-1600 Hz lag range). Frames 128 ms, hop 64 ms.

    Own vectorised code rather than librosa.pyin: pyin took 4.6 s per 10 s clip here (the track has
    ~150 clips to describe) and its cached numba kernels crashed in the shared venv.
    """
    from scipy.signal import resample_poly

    g = np.gcd(int(sr), PYIN_SAMPLE_RATE_HZ)
    y = resample_poly(np.asarray(x, dtype=np.float64), PYIN_SAMPLE_RATE_HZ // g, int(sr) // g) \
        if sr != PYIN_SAMPLE_RATE_HZ else np.asarray(x, dtype=np.float64)
    fs = PYIN_SAMPLE_RATE_HZ
    width, hop = YIN_FRAME, YIN_FRAME // 2
    tau_min, tau_max = int(fs // PYIN_FMAX_HZ), int(np.ceil(fs / PYIN_FMIN_HZ)) + 1
    span = width + tau_max
    if y.size < span:
        return np.full(0, np.nan), np.zeros(0, dtype=bool)
    from numpy.lib.stride_tricks import sliding_window_view

    frames = sliding_window_view(y, span)[::hop]
    n_fft = 1 << int(np.ceil(np.log2(2 * span)))
    head = np.fft.rfft(frames[:, :width], n_fft)
    full = np.fft.rfft(frames, n_fft)
    cross = np.fft.irfft(np.conj(head) * full, n_fft)[:, :tau_max + 1]       # sum_j x_j x_{j+tau}
    sq = np.concatenate([np.zeros((frames.shape[0], 1)), np.cumsum(frames ** 2, axis=1)], axis=1)
    taus = np.arange(tau_max + 1)
    energy0 = sq[:, width][:, None]
    energy_tau = sq[:, taus + width] - sq[:, taus]
    diff = np.maximum(energy0 + energy_tau - 2 * cross, 0.0)
    cum = np.cumsum(diff[:, 1:], axis=1)
    cmndf = np.ones_like(diff)
    cmndf[:, 1:] = diff[:, 1:] * taus[1:] / np.maximum(cum, 1e-30)
    region = cmndf[:, tau_min:tau_max]
    below = region < YIN_THRESHOLD
    voiced = below.any(axis=1)
    first = np.where(voiced, np.argmax(below, axis=1), np.argmin(region, axis=1))   # step 3 / global minimum
    f0 = np.empty(frames.shape[0])
    for i, t in enumerate(first):
        while t + 1 < region.shape[1] and region[i, t + 1] < region[i, t]:
            t += 1                                            # step 4: walk to the dip's minimum
        tau = t + tau_min
        shift = 0.0
        if tau_min < tau < tau_max:                           # step 5: parabolic interpolation
            a, b, c = cmndf[i, tau - 1], cmndf[i, tau], cmndf[i, tau + 1]
            denom = a - 2 * b + c
            shift = float(np.clip(0.5 * (a - c) / denom, -1, 1)) if abs(denom) > 1e-12 else 0.0
        f0[i] = fs / (tau + shift)
    return f0, voiced


def harmonic_count(freqs_hz: np.ndarray, psd: np.ndarray, f0_hz: float) -> int:
    """Harmonics k f0 (k = 1..30, below Nyquist) whose spectral peak (within +-2 % of k f0 and
    +-1 bin) stands >= 10 dB above the median of the band k f0 +- f0/2 (the local floor)."""
    if not np.isfinite(f0_hz) or f0_hz <= 0:
        return 0
    df = float(freqs_hz[1] - freqs_hz[0])
    count = 0
    for k in range(1, MAX_HARMONICS + 1):
        fk = k * f0_hz
        if fk + f0_hz / 2 >= freqs_hz[-1]:
            break
        half = max(0.02 * fk, 1.5 * df)
        peak = psd[(freqs_hz >= fk - half) & (freqs_hz <= fk + half)]
        floor = psd[(freqs_hz >= fk - f0_hz / 2) & (freqs_hz <= fk + f0_hz / 2)]
        if peak.size and floor.size and 10 * np.log10(peak.max() / max(np.median(floor), 1e-30)) >= HARMONIC_FLOOR_DB:
            count += 1
    return count


def _segment_statistics(x: np.ndarray, sr: int) -> dict[str, Any]:
    freqs, psd = _psd(x, sr)
    total = float(np.sum(psd))
    centroid = float(np.sum(freqs * psd) / total) if total > 0 else 0.0
    f0, voiced = yin_f0(x, sr)
    voiced_fraction = float(np.mean(voiced)) if voiced.size else 0.0
    pitched = voiced_fraction >= PITCHED_VOICED_FRACTION
    f0_hz = float(np.median(f0[voiced] if np.any(voiced) else f0)) if f0.size else float("nan")
    frame = round(LEVEL_FRAME_S * sr)
    n_frames = x.size // frame
    ms = np.mean(x[: n_frames * frame].astype(np.float64).reshape(n_frames, frame) ** 2, axis=1)
    levels = 10 * np.log10(np.maximum(ms, 1e-20))
    return {
        "spectral_centroid_hz": centroid,
        "pitched": bool(pitched),
        "pitched_fraction": float(pitched),
        "voiced_fraction": voiced_fraction,
        "f0_hz": f0_hz,
        "n_harmonics": harmonic_count(freqs, psd, f0_hz),
        "third_octave_dbfs": third_octave_levels_db(freqs, psd).tolist(),
        "level_fluctuation_db": float(np.std(levels)) if levels.size > 1 else 0.0,
        "level_dbfs": float(10 * np.log10(max(float(np.mean(x.astype(np.float64) ** 2)), 1e-20))),
    }


def audio_statistics(x: np.ndarray, sr: int) -> dict[str, Any]:
    """Spectral statistics of each 5 s segment of a mono clip (a shorter clip is one segment).

    Returns ``{"segments": [per-segment dict], "third_octave_centres_hz": [...]}``; a segment dict has
    spectral_centroid_hz, pitched (YIN voiced in >= 50 % of frames), voiced_fraction, f0_hz (median
    voiced YIN f0, NaN when nothing is voiced), n_harmonics (0 when unpitched), third_octave_dbfs (26
    bands, dB re full-scale RMS), level_fluctuation_db (std of 100 ms levels), level_dbfs.
    """
    x = np.asarray(x, dtype=np.float64).reshape(-1)
    if not sr > 0:
        raise ValueError(f"sr must be > 0, got {sr}")
    if x.size < int(0.5 * sr):
        raise ValueError(f"x: need at least 0.5 s of audio, got {x.size} samples at {sr} Hz")
    seg = round(SEGMENT_S * sr)
    n_seg = max(1, x.size // seg)
    parts = [x] if x.size < seg else [x[i * seg:(i + 1) * seg] for i in range(n_seg)]
    return {"segments": [_segment_statistics(p, sr) for p in parts],
            "third_octave_centres_hz": list(NOMINAL_CENTRES_HZ)}


def _pooled(stats: Iterable[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Segment statistics of many clips pooled per statistic (1/3-octave bands one column each)."""
    segs = [s for st in stats for s in st["segments"]]
    out: dict[str, np.ndarray] = {k: np.array([s[k] for s in segs], dtype=np.float64)
                                  for k in ("spectral_centroid_hz", "pitched", "voiced_fraction", "f0_hz",
                                            "n_harmonics", "level_fluctuation_db", "level_dbfs")}
    bands = np.array([s["third_octave_dbfs"] for s in segs],
                     dtype=np.float64).reshape(len(segs), len(NOMINAL_CENTRES_HZ))
    rel = bands - 10 * np.log10(np.maximum(np.sum(10 ** (bands / 10), axis=1, keepdims=True), 1e-30))
    for i, fc in enumerate(NOMINAL_CENTRES_HZ):
        out[f"band_{fc}hz_dbfs"] = bands[:, i] if bands.size else np.zeros(0)
        out[f"band_{fc}hz_rel_db"] = rel[:, i] if rel.size else np.zeros(0)
    return out


def compare_statistics(real: dict[str, np.ndarray], synthetic: dict[str, np.ndarray]) -> dict[str, dict[str, Any]]:
    """Per statistic: real median and IQR, synthetic median, and whether it lies inside the real IQR."""
    out: dict[str, dict[str, Any]] = {}
    for name, values in real.items():
        r = values[np.isfinite(values)]
        s = synthetic.get(name, np.zeros(0))
        s = s[np.isfinite(s)]
        if not r.size:
            continue
        q25, med, q75 = (float(v) for v in np.percentile(r, [25, 50, 75]))
        sm = float(np.median(s)) if s.size else None
        out[name] = {"real_median": med, "real_q25": q25, "real_q75": q75, "synthetic_median": sm,
                     "inside_real_iqr": bool(sm is not None and q25 <= sm <= q75), "n_real": int(r.size),
                     "n_synthetic": int(s.size)}
    return out


# --------------------------------------------------------------------------------------------
# Synthetic clips from the project's synthesiser
# --------------------------------------------------------------------------------------------

def _config_model():
    from pydantic import BaseModel, ConfigDict, Field, model_validator

    from scenes.kinds import BENCHMARK_DRONE_SIZE_RANGE_M, DRONE_KINDS
    from simulator.physics.acoustics.ambience import AmbienceDistribution, BedShapes, MachineryDistribution
    from simulator.sensors.microphone import RecorderConfig

    Span = tuple[float, float]

    class SyntheticAudioConfig(BaseModel):
        """What the synthetic clips draw from (every span is (low, high); ranges log-uniform)."""

        model_config = ConfigDict(extra="forbid", frozen=True)
        duration_s: float = Field(default=10.0, gt=0.0, le=60.0)
        sample_rate_hz: int = Field(default=44_100, ge=32_000, le=96_000)
        full_scale_pa: float = Field(default=0.1, gt=0.0, description="sample 1.0 == this pressure")
        drone_kinds: list[str] = Field(default=["quadcopter"], min_length=1)
        drone_size_m: dict[str, Span] = Field(default_factory=lambda: dict(BENCHMARK_DRONE_SIZE_RANGE_M),
                                              description="size span per drone kind (default: scenes.kinds)")
        drone_range_m: list[Span] = Field(default=[(2.0, 12.0), (8.0, 50.0)], min_length=1,
                                          description="range spans, one picked uniformly per clip")
        drone_speed_mps: Span = (0.0, 10.0)
        drone_bpf_hz: Span | None = Field(
            default=(150.0, 190.0),
            description="hover blade-passing frequency (Hz) drawn per drone clip, the rotors retuned to it "
                        "(timeline.retuned_rotors); None: the simulator's size law (rotor_hover_rpm: 174-225 Hz "
                        "at 0.3-0.5 m). The fit: the calibration half's drone line sits at 180 Hz [170, 183] "
                        "(docs/SIM2REAL_AUDIO.md, fifth pass)")
        drone_rpm_wander: Span | None = Field(
            default=(0.04, 0.10),
            description="relative std of a slow change of all rotors' speed at once (manoeuvres, gust "
                        "corrections; timeline.manoeuvre_rpm_factor), drawn per drone clip; None: off. The fit: "
                        "the calibration half's drone line stands 5.4 dB [4.3, 6.7] over its 60 Hz neighbourhood "
                        "in a 10 s average, which the drawn tones reach at this wander (fifth pass)")
        drone_rpm_wander_time_s: Span = Field(default=(0.5, 2.0), description="its correlation time")
        elevation_deg: Span = (3.0, 45.0)
        helicopter_range_m: Span = (50.0, 300.0)
        helicopter_height_m: Span = (30.0, 250.0)
        helicopter_speed_mps: Span = Field(
            default=(0.0, 20.0),
            description="0-60 m/s until the sixth pass: a fast pass sweeps the tail-rotor lines by up to +-15 % "
                        "(Doppler) and smears them into the broadband, while the calibration half's helicopter lines "
                        "hold still (frame-to-frame peak std 3.0 Hz [2.2, 3.6], like the synthetic ones below 20 m/s; "
                        "docs/SIM2REAL_AUDIO.md, sixth pass)")
        helicopter_blades: list[int] = Field(default=[2, 3, 3, 4, 4], min_length=1)
        helicopter_rpm: Span = (330.0, 420.0)
        helicopter_diameter_m: Span = (10.0, 16.0)
        rotor_noise: dict[str, Span] = Field(
            default_factory=lambda: {"broadband_offset_db": (-2.0, 6.0), "harmonic_top_hz": (1000.0, 2500.0)},
            description="drone rotor-noise spans replacing those of acoustics.ROTOR_NOISE_RANGES (the sim2real fit: "
                        "blade-passing lines up to 1-2.5 kHz with the broadband -2..+6 dB re the tones instead of "
                        "+10..+20, so the YIN fundamental and the 250 Hz dip between the first two lines of the real "
                        "drones appear; docs/SIM2REAL_AUDIO.md, fifth pass)")
        helicopter: dict[str, Span] = Field(
            default_factory=lambda: {"turbine_hz": (7500.0, 11500.0), "broadband_tilt_db": (-9.0, -7.0),
                                     "tip_noise_db": (-16.0, -6.0), "tail_db": (-14.0, -4.0),
                                     "tail_peak_harmonic": (1.5, 3.5), "level_fluctuation_db": (1.0, 3.0),
                                     "band_high_hz": (20_000.0, 20_000.0)},
            description="helicopter source spans replacing those of acoustics.HELICOPTER_RANGES (the sim2real fit; "
                        "docs/SIM2REAL_AUDIO.md, fourth pass; sixth pass: tail-rotor lines 6 dB stronger, the "
                        "strongest at the 2nd-3rd harmonic as in the calibration half's helicopters; seventh pass: "
                        "the received level wanders by 1-3 dB (turbulent propagation; the calibration half's "
                        "helicopters' 100 ms level std 1.8 dB [1.2, 2.5], the steady synthetic ones' 0.7); eighth "
                        "pass: the broadband parts (rotor, blade tip, turbine) run to 20 kHz (clamped to 0.45 fs) "
                        "instead of stopping at the module's 16 kHz, which cut the 14.1-17.8 kHz third octave in half; "
                        "air absorption, the capsule and the encoder set the upper limit)")
        ambience: AmbienceDistribution = Field(default_factory=AmbienceDistribution)
        ambience_shapes: BedShapes = Field(
            default_factory=lambda: BedShapes(traffic_band_hz=(100.0, 5000.0), traffic_tilt_db=-5.5),
            description="spectra of the traffic and residual beds (every clip of every class; acoustics.BedShapes, "
                        "whose defaults are the module's: traffic 40 Hz-2.5 kHz at -1.5 dB/octave, residual from 50 "
                        "Hz). Traffic here: the EN 1793-3 normalised road-traffic spectrum (100 Hz-5 kHz) is tabled "
                        "A-weighted; unweighted its 1/3-octave levels fall by about 2.5 dB per octave from 100 Hz to 5 "
                        "kHz, i.e. a PSD tilt of about -5.5 dB/octave, where the module's -1.5 makes the band levels "
                        "rise to 1 kHz. The calibration half's four loud broadband backgrounds fall 1.5-2.5 dB per "
                        "octave per band from 250 Hz to 3.15 kHz and sit 20-25 dB under their 125 Hz level at 50 Hz. "
                        "Twelfth pass, docs/SIM2REAL_AUDIO.md: calibration-half statistics 149 / 134 / 137 -> 152 / "
                        "141 / 139 of 177 on the seed-0 / 1 / 2 sets")
        machinery: MachineryDistribution | None = Field(
            default=None,
            description="a tonal machinery bed (mains hum, fans, engines: acoustics.machinery_bed) drawn for every "
                        "clip of every class (one distribution, no class cue); None: off. Off by default: probed in "
                        "the sixth pass (docs/SIM2REAL_AUDIO.md), it raised the log-mel LR's false alarms")
        background_ambience: AmbienceDistribution | None = Field(
            default=None,
            description="the BACKGROUND clips' ambience distribution (None: ``ambience``, as for the drones and "
                        "helicopters); the same draws are made whenever every bed probability is > 0 in both "
                        "(acoustics.draw_ambience), so the other classes' clips stay put (ninth pass)")
        background_broadband_probability: float = Field(
            default=0.0, ge=0.0, le=1.0,
            description="BACKGROUND clips only: the share carrying a flat, line-free broadband bed (distant road "
                        "traffic, wind in foliage; acoustics.drifting_broadband_bed); 0: off, nothing drawn "
                        "(ninth pass, docs/SIM2REAL_AUDIO.md)")
        background_broadband_db: Span = Field(default=(30.0, 44.0), description="its level (dB SPL)")
        background_broadband_band_hz: Span = Field(default=(100.0, 6000.0), description="its band (Hz)")
        background_broadband_tilt_db: Span = Field(default=(-3.0, 0.0), description="its tilt (dB/octave)")
        background_insect_probability: float = Field(
            default=0.0, ge=0.0, le=1.0,
            description="BACKGROUND clips only: the share carrying high-frequency calls (insects, small birds: "
                        "Poisson chirps at 4-10 kHz by default); 0: off, nothing drawn (ninth pass)")
        background_insect_db: Span = Field(default=(20.0, 34.0), description="its level (dB SPL)")
        background_insect_band_hz: Span = Field(default=(4000.0, 10000.0),
                                                description="its calls' start-frequency span (Hz)")
        mic_wind_probability: dict[str, float] = Field(
            default_factory=lambda: {"DRONE": 0.6},
            description="per class (DRONE / HELICOPTER / BACKGROUND), the share of clips with flow noise on the "
                        "microphone (the wind of the recording day, and near a drone its downwash and outwash: "
                        "acoustics.wind_bed, gusty red noise) at a level drawn re the clip's mix at the microphone; a "
                        "class not named (or 0): off, nothing drawn. The fit (seventh pass, docs/SIM2REAL_AUDIO.md): "
                        "7 of the calibration half's 15 drone clips carry gusty red noise with their 20-40 Hz "
                        "band within 16.5 dB of the total, 3 of 15 backgrounds and 1 of 15 helicopters; the "
                        "synthetic backgrounds and helicopters already carry the ambience's wind bed, so only the "
                        "drones draw it")
        mic_wind_db: Span = Field(default=(-3.0, 7.0), description=(
            "its level (dB re the RMS level of the clip's mix at the microphone); -6..+4 until the fourteenth session, "
            "3 dB more with the mean-level AGC (docs/SIM2REAL_AUDIO.md, thirteenth pass, candidate C3)"))
        mic_wind_gust_depth: Span = Field(default=(0.5, 1.0), description="its gust depth (acoustics.wind_bed)")
        mic_wind_high_hz: float = Field(
            default=100.0, gt=15.0, le=2000.0,
            description="its upper band edge (Hz); 200 Hz put wind energy into the log-mel bands of the real "
                        "backgrounds' 127 Hz lines and raised the LR's false alarms (seventh pass)")
        mic_wind_tilt_db: float = Field(default=-9.0, ge=-24.0, le=0.0, description=(
            "its spectral tilt (dB/octave; 5 of the calibration half's 7 windy drone clips fall 6-16 dB from the "
            "20-40 Hz to the 60-90 Hz band)"))
        resonance_count: dict[str, tuple[int, int]] = Field(
            default_factory=dict,
            description="per class (DRONE / HELICOPTER / BACKGROUND), the span of the number of spectral resonances "
                        "drawn per clip (recorder, housing and microphone-mount resonances, the site: each real clip "
                        "puts energy in a few bands of its own; acoustics.peaking_filter), the clip's RMS kept; a "
                        "class not listed gets none and nothing is drawn for it; {} (default): off. Off by default: "
                        "probed on DRONE + BACKGROUND in the tenth pass (docs/SIM2REAL_AUDIO.md), it moved the "
                        "statistics -2 / +10 / -2 on three synthetic sets and lowered the CNN's AUC on all three")
        resonance_hz: Span = Field(default=(150.0, 8000.0), description="their centre (Hz, log-uniform; clamped "
                                                                          "to 0.45 fs)")
        resonance_db: Span = Field(default=(6.0, 14.0), description="their gain at the centre (dB)")
        resonance_q: Span = Field(default=(1.5, 5.0), description="their quality factor (centre / -3 dB bandwidth)")
        recorder: bool = Field(default=True, description="pass the mix through the recording chain")
        microphone: RecorderConfig = Field(
            default_factory=lambda: RecorderConfig(agc_target_dbfs=(-28.0, -20.0), presence_hz=(4000.0, 10000.0),
                                                   agc_detector="mean", agc_min_gain_db=-28.0),
            description="the recording chain of the Svanström laptop recorder: the generic RecorderConfig with the "
                        "AGC target fitted to the calibration half (drones -24.8, helicopters -20.7 dBFS median) "
                        "and the capsule's 0-5 dB presence lift centred at 4-10 kHz instead of 2-6 kHz (all three "
                        "classes' 1-5 kHz shares sat 0.4-4 dB over the calibration IQR with the generic lift); "
                        "since the fourteenth session the AGC follows the mean level (as WebRTC's AGC2 level "
                        "estimator does) with a floor of -28 dB instead of the loud blocks with -26 dB: a fluctuating "
                        "drone recording left the peak detector 1.5-4.8 dB under its target (docs/SIM2REAL_AUDIO.md, "
                        "thirteenth pass, C3)")
        n_per_class: int = Field(default=20, ge=1, le=1000)
        quick_n_per_class: int = Field(default=2, ge=1, le=1000)

        @model_validator(mode="after")
        def _check(self):
            for kind in self.drone_kinds:
                if kind not in DRONE_KINDS:
                    raise ValueError(f"drone_kinds: unknown drone kind {kind!r}")
                if kind not in self.drone_size_m:
                    raise ValueError(f"drone_size_m: no size span for {kind!r}")
            spans = {"drone_speed_mps": self.drone_speed_mps, "elevation_deg": self.elevation_deg,
                     "mic_wind_db": self.mic_wind_db, "mic_wind_gust_depth": self.mic_wind_gust_depth,
                     "helicopter_range_m": self.helicopter_range_m, "helicopter_height_m": self.helicopter_height_m,
                     "helicopter_rpm": self.helicopter_rpm, "helicopter_diameter_m": self.helicopter_diameter_m,
                     "background_broadband_db": self.background_broadband_db,
                     "background_broadband_band_hz": self.background_broadband_band_hz,
                     "background_broadband_tilt_db": self.background_broadband_tilt_db,
                     "background_insect_db": self.background_insect_db,
                     "background_insect_band_hz": self.background_insect_band_hz,
                     "resonance_hz": self.resonance_hz, "resonance_db": self.resonance_db,
                     "resonance_q": self.resonance_q,
                     **{f"resonance_count.{k}": v for k, v in self.resonance_count.items()},
                     **{f"drone_size_m.{k}": v for k, v in self.drone_size_m.items()},
                     **{f"drone_range_m[{i}]": v for i, v in enumerate(self.drone_range_m)}}
            floors = (("drone_bpf_hz", "> 0"), ("drone_rpm_wander", ">= 0"), ("drone_rpm_wander_time_s", "> 0"))
            for name, floor in floors:
                span = getattr(self, name)
                if span is not None:
                    spans[name] = span
                    if span[0] < 0 or (span[0] == 0 and floor == "> 0"):
                        raise ValueError(f"{name}: must be {floor}, got {span[0]}")
            for name, (lo, hi) in spans.items():
                if lo > hi:
                    raise ValueError(f"{name}: low {lo} exceeds high {hi}")
            from simulator.physics.acoustics.sources import HELICOPTER_RANGES, ROTOR_NOISE_RANGES, merged_ranges

            merged_ranges(ROTOR_NOISE_RANGES, self.rotor_noise, "rotor_noise")     # raises naming the bad key
            merged_ranges(HELICOPTER_RANGES, self.helicopter, "helicopter")
            for i, (lo, _) in enumerate(self.drone_range_m):
                if lo <= 0:
                    raise ValueError(f"drone_range_m[{i}]: ranges must be > 0, got {lo}")
            lo, hi = self.mic_wind_gust_depth
            if lo < 0 or hi > 1:
                raise ValueError(f"mic_wind_gust_depth: must lie in [0, 1], got {(lo, hi)}")
            for name, low in (("resonance_hz", self.resonance_hz[0]), ("resonance_q", self.resonance_q[0])):
                if low <= 0:
                    raise ValueError(f"{name}: must be > 0, got {low}")
            for cls, (lo_count, _) in self.resonance_count.items():
                if cls not in CLASSES:
                    raise ValueError(f"resonance_count: unknown class {cls!r}; expected one of {list(CLASSES)}")
                if lo_count < 0:
                    raise ValueError(f"resonance_count.{cls}: counts must be >= 0, got {lo_count}")
            for cls, p in self.mic_wind_probability.items():
                if cls not in CLASSES:
                    raise ValueError(f"mic_wind_probability: unknown class {cls!r}; expected one of {list(CLASSES)}")
                if not 0.0 <= p <= 1.0:
                    raise ValueError(f"mic_wind_probability.{cls}: must lie in [0, 1], got {p}")
            return self

    return SyntheticAudioConfig


def synthetic_audio_config(config: dict | None = None):
    """The validated synthetic-audio config (pydantic; a bad field raises a UserInputError naming it)."""
    from pydantic import ValidationError

    from scenes.errors import UserInputError

    model = _config_model()
    try:
        return model.model_validate(dict(config or {}))
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "config"
        raise UserInputError(f"synthetic audio config: {where}: {first['msg']}") from exc


def _drone_scenario(cfg, rng: np.random.Generator, name: str):
    from scenes.schema import Scenario

    kind = drone_kind(rng, cfg.drone_kinds)
    size_m = target_size(rng, kind, cfg.drone_size_m)
    span = pick(rng, cfg.drone_range_m)
    range_m = log_uniform(rng, span)
    az, el = np.radians(uniform(rng, (-180.0, 180.0))), np.radians(uniform(rng, cfg.elevation_deg))
    mic = np.array([0.0, 0.0, 1.5])
    centre = mic + range_m * np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
    centre[2] = max(centre[2], 2.0)
    speed = uniform(rng, cfg.drone_speed_mps)
    heading = uniform(rng, (0.0, 2 * np.pi))
    if kind == "fixed_wing":
        speed = max(speed, 12.0)
    if speed < 0.5:
        trajectory = {"kind": "hover", "center_m": np.round(centre, 3).tolist(),
                      "drift_m": round(uniform(rng, (0.2, 1.5)), 2)}
    else:
        half = 0.5 * speed * cfg.duration_s * np.array([np.cos(heading), np.sin(heading), 0.0])
        trajectory = {"kind": "waypoints", "speed_mps": round(speed, 3),
                      "points_m": [np.round(centre - half, 3).tolist(), np.round(centre + half, 3).tolist()]}
    look = (centre + [5.0, 5.0, 0.0]) if np.linalg.norm(centre[:2]) < 1.0 else centre
    scenario = Scenario.model_validate({
        "name": name, "duration_s": cfg.duration_s, "frame_rate_hz": 25.0,
        "targets": [{"name": "drone", "kind": kind, "size_m": round(size_m, 4), "trajectory": trajectory}],
        "camera_rig": {"position_m": mic.tolist(), "look_at_m": np.round(look, 3).tolist(),
                       "rgb": {"width_px": 16, "height_px": 16, "hfov_deg": 30.0},
                       "thermal": {"width_px": 16, "height_px": 16, "hfov_deg": 30.0}}})
    return scenario, {"kind": kind, "size_m": size_m, "range_m": range_m, "speed_mps": speed}


def _record(cfg, mix_pa: np.ndarray, seed: int, index: int) -> np.ndarray:
    """Pressure -> recorded samples through ``cfg.microphone`` (``cfg.recorder`` False: mix / full scale)."""
    from simulator.sensors import microphone

    if cfg.recorder:
        return microphone.record(mix_pa, cfg.sample_rate_hz, seed=seed, index=index, full_scale_pa=cfg.full_scale_pa,
                                 config=cfg.microphone).astype(np.float32)
    return (np.asarray(mix_pa, dtype=np.float64) / cfg.full_scale_pa).astype(np.float32)


def _helicopter_scenario(cfg, rng: np.random.Generator, name: str):
    """A light helicopter (scene-schema target: main rotor blades and governed rpm drawn, diameter 10-16 m)
    passing or hovering at a drawn range (log-uniform), height and speed, with drawn air."""
    from scenes.schema import Scenario

    range_m = log_uniform(rng, cfg.helicopter_range_m)
    speed = uniform(rng, cfg.helicopter_speed_mps)
    height = min(uniform(rng, cfg.helicopter_height_m), 0.9 * range_m)
    heading, az = uniform(rng, (0.0, 2 * np.pi)), uniform(rng, (0.0, 2 * np.pi))
    horiz = np.sqrt(max(range_m ** 2 - height ** 2, 1.0))
    centre = np.array([horiz * np.cos(az), horiz * np.sin(az), height])
    blades = int(rng.choice(cfg.helicopter_blades))
    rotor = {"main_blades": blades, "main_rpm": round(uniform(rng, cfg.helicopter_rpm), 1)}
    size_m = round(uniform(rng, cfg.helicopter_diameter_m), 2)
    air = {"air_temperature_k": round(uniform(rng, (273.0, 303.0)), 2),
           "relative_humidity": round(uniform(rng, (0.3, 0.95)), 3)}
    if speed < 1.0:
        trajectory = {"kind": "hover", "center_m": np.round(centre, 2).tolist(), "drift_m": 2.0}
    else:
        half = 0.5 * speed * cfg.duration_s * np.array([np.cos(heading), np.sin(heading), 0.0])
        trajectory = {"kind": "waypoints", "speed_mps": round(speed, 3),
                      "points_m": [np.round(centre - half, 2).tolist(), np.round(centre + half, 2).tolist()]}
    scenario = Scenario.model_validate({
        "name": name, "duration_s": cfg.duration_s, "frame_rate_hz": 25.0, "atmosphere": air,
        "targets": [{"name": "helicopter", "kind": "helicopter", "size_m": size_m, "rotor": rotor,
                     "trajectory": trajectory}],
        "camera_rig": {"position_m": [0.0, 0.0, 1.5], "look_at_m": np.round(centre, 2).tolist(),
                       "rgb": {"width_px": 16, "height_px": 16, "hfov_deg": 30.0},
                       "thermal": {"width_px": 16, "height_px": 16, "hfov_deg": 30.0}}})
    return scenario, {"range_m": range_m, "speed_mps": speed, **rotor}


def _retuned(cfg, timeline, rng: np.random.Generator):
    """``timeline`` with every rotorcraft drone's rotors retuned (:func:`timeline.retuned_rotors`) to a hover
    blade-passing frequency (blades x hover rpm / 60) drawn from ``cfg.drone_bpf_hz`` (None: the size law)
    and, when ``cfg.drone_rpm_wander`` is set, a drawn manoeuvre wander of all rotors' speed
    (:func:`timeline.manoeuvre_rpm_factor`). Both None: ``timeline`` unchanged, nothing drawn."""
    import dataclasses

    from scenes.kinds import DRONE_KINDS
    from simulator.physics.timeline import manoeuvre_rpm_factor, retuned_rotors, rotor_hover_rpm

    if cfg.drone_bpf_hz is None and cfg.drone_rpm_wander is None:
        return timeline
    targets = []
    for t in timeline.targets:
        if t.kind not in DRONE_KINDS or not t.n_blades:
            targets.append(t)
            continue
        hover = (60.0 * uniform(rng, cfg.drone_bpf_hz) / int(t.n_blades) if cfg.drone_bpf_hz is not None
                 else rotor_hover_rpm(t.kind, t.size_m))
        factor = None
        if cfg.drone_rpm_wander is not None:
            std, time_s = uniform(rng, cfg.drone_rpm_wander), uniform(rng, cfg.drone_rpm_wander_time_s)
            factor = manoeuvre_rpm_factor(rng, len(timeline.times_s), timeline.scenario.frame_rate_hz, std, time_s)
        targets.append(retuned_rotors(t, hover, factor))
    return dataclasses.replace(timeline, targets=targets)


def _mic_wind(cfg, cls: str, rng: np.random.Generator, mix_pa: np.ndarray, clip_seed: int, n: int,
              sample_rate_hz: float) -> np.ndarray:
    """Flow noise on the microphone of one clip of class ``cls`` (Pa; zeros when the drawn switch is off):
    with ``cfg.mic_wind_probability[cls]`` the gusty wind-on-microphone bed (:func:`acoustics.wind_bed`, band
    edge ``cfg.mic_wind_high_hz``, tilt ``cfg.mic_wind_tilt_db``) at the RMS level of ``mix_pa`` (dB SPL) plus
    a level drawn from ``cfg.mic_wind_db``, gust depth from ``cfg.mic_wind_gust_depth``. Always three draws
    from ``rng`` (on/off, level, gust depth); the noise comes from the clip's acoustics stream
    ``acoustics.MIC_WIND_SOURCE_INDEX``."""
    from simulator.physics import acoustics as ac

    on = bool(rng.random() < cfg.mic_wind_probability.get(cls, 0.0))
    offset_db, gust = uniform(rng, cfg.mic_wind_db), uniform(rng, cfg.mic_wind_gust_depth)
    if not on:
        return np.zeros(n)
    mix_db = float(ac.pa_to_db_spl(float(np.sqrt(np.mean(np.asarray(mix_pa, dtype=np.float64) ** 2)))))
    return ac.wind_bed(rng_for(clip_seed, "acoustics", ac.MIC_WIND_SOURCE_INDEX), n, sample_rate_hz, mix_db + offset_db,
                       gust, high_hz=cfg.mic_wind_high_hz, tilt_db_per_octave=cfg.mic_wind_tilt_db)


def _background_beds(cfg, rng: np.random.Generator, clip_seed: int, n: int, sample_rate_hz: float) -> np.ndarray:
    """The BACKGROUND-only beds of one clip (Pa; zeros when both are off or not drawn): a flat broadband bed
    with ``cfg.background_broadband_probability`` (level and tilt drawn from their spans over the configured
    band; acoustics.drifting_broadband_bed) and high-frequency calls with ``cfg.background_insect_probability``
    (acoustics.calls_bed). A bed whose probability is 0 draws nothing; otherwise always on/off, level and
    (broadband) tilt, so the draws do not depend on the outcome. Noise from the clip's acoustics streams
    ``acoustics.BROADBAND_SOURCE_INDEX`` / ``acoustics.CALLS_SOURCE_INDEX``."""
    from simulator.physics import acoustics as ac

    out = np.zeros(n)
    if cfg.background_broadband_probability > 0:
        on = bool(rng.random() < cfg.background_broadband_probability)
        level = uniform(rng, cfg.background_broadband_db)
        tilt = uniform(rng, cfg.background_broadband_tilt_db)
        if on:
            out = out + ac.drifting_broadband_bed(rng_for(clip_seed, "acoustics", ac.BROADBAND_SOURCE_INDEX), n,
                                                  sample_rate_hz, level, cfg.background_broadband_band_hz, tilt)
    if cfg.background_insect_probability > 0:
        on = bool(rng.random() < cfg.background_insect_probability)
        level = uniform(rng, cfg.background_insect_db)
        if on:
            out = out + ac.calls_bed(rng_for(clip_seed, "acoustics", ac.CALLS_SOURCE_INDEX), n, sample_rate_hz,
                                     level, cfg.background_insect_band_hz)
    return out


def _resonances(cfg, cls: str, mix_pa: np.ndarray, clip_seed: int, sample_rate_hz: float) -> np.ndarray:
    """``mix_pa`` through the clip's spectral resonances (acoustics.resonances: peaking filters, RMS kept):
    a count drawn from ``cfg.resonance_count[cls]`` (integers, both ends included), then per resonance a
    centre (log-uniform in ``cfg.resonance_hz``, clamped to 0.45 fs), a gain (``cfg.resonance_db``) and a
    Q (``cfg.resonance_q``), all from the clip's own acoustics stream ``acoustics.RESONANCE_SOURCE_INDEX``.
    A class not in ``cfg.resonance_count``: ``mix_pa`` unchanged and nothing drawn."""
    from simulator.physics import acoustics as ac

    if cls not in cfg.resonance_count:
        return mix_pa
    rng = rng_for(clip_seed, "acoustics", ac.RESONANCE_SOURCE_INDEX)
    lo, hi = cfg.resonance_count[cls]
    peaks = [(min(log_uniform(rng, cfg.resonance_hz), 0.45 * sample_rate_hz), uniform(rng, cfg.resonance_db),
              uniform(rng, cfg.resonance_q)) for _ in range(int(rng.integers(lo, hi + 1)))]
    return ac.resonances(mix_pa, sample_rate_hz, peaks)


def helicopter_available() -> bool:
    """True when the acoustic model has a helicopter source."""
    from simulator.physics.acoustics import sources

    return hasattr(sources, "helicopter_signature")


def synthetic_audio_clips(config: dict | None, seed: int, n_per_class: int | None = None, *,
                          quick: bool = False) -> list[AudioClip]:
    """``n_per_class`` DRONE, HELICOPTER (when the source exists) and BACKGROUND clips from the
    project's synthesiser, every parameter drawn from ``config`` and ``seed`` (deterministic).
    ``n_per_class`` None takes the config's ``n_per_class`` (``quick_n_per_class`` when ``quick``).

    Clip j of class c draws its scene from ``rng_for(seed, "generation", 24, c, j)`` and its audio
    from the acoustics streams of seed ``clip_seed``; every clip carries the drawn ambience.
    """
    from simulator.physics import acoustics as ac
    from simulator.physics.timeline import build_timeline

    cfg = synthetic_audio_config(config)
    if n_per_class is None:
        n_per_class = cfg.quick_n_per_class if quick else cfg.n_per_class
    if n_per_class < 1:
        raise ValueError(f"n_per_class must be >= 1, got {n_per_class}")
    sr, n = cfg.sample_rate_hz, round(cfg.duration_s * cfg.sample_rate_hz)
    classes = ["DRONE"] + (["HELICOPTER"] if helicopter_available() else []) + ["BACKGROUND"]
    clips: list[AudioClip] = []
    for cls in classes:
        for j in range(n_per_class):
            rng = rng_for(seed, "generation", _SYNTH_TAG, CLASSES.index(cls), j)
            clip_seed = int(rng.integers(0, 2 ** 31 - 1))
            dist = cfg.background_ambience if cls == "BACKGROUND" and cfg.background_ambience else cfg.ambience
            ambience = ac.draw_ambience(rng, dist)
            if cls == "DRONE":
                scenario, _ = _drone_scenario(cfg, rng, f"synthetic_drone_{j:04d}")
                timeline = build_timeline(scenario, clip_seed)
                timeline = _retuned(cfg, timeline, rng)            # draws last: the draws before it stay put
                mix = ac.synthesize_audio(timeline, clip_seed, ambience=ambience, duration_s=cfg.duration_s,
                                          sample_rate_hz=sr, rotor_noise_ranges=cfg.rotor_noise,
                                          ambience_shapes=cfg.ambience_shapes).mix_pa
            elif cls == "HELICOPTER":
                scenario, _ = _helicopter_scenario(cfg, rng, f"synthetic_helicopter_{j:04d}")
                mix = ac.synthesize_audio(build_timeline(scenario, clip_seed), clip_seed, ambience=ambience,
                                          duration_s=cfg.duration_s, sample_rate_hz=sr,
                                          helicopter_ranges=cfg.helicopter, ambience_shapes=cfg.ambience_shapes).mix_pa
            else:
                mix = functools.reduce(operator.add, ac.synthesize_ambience(ambience, n, sr, clip_seed,
                                                                            shapes=cfg.ambience_shapes).values())
            if cfg.machinery is not None:                          # draws last: the draws before it stay put
                machinery = ac.draw_machinery(rng, cfg.machinery)
                if machinery is not None:
                    mix = mix + ac.machinery_bed(rng_for(clip_seed, "acoustics", ac.MACHINERY_SOURCE_INDEX), n, sr,
                                                 machinery)
            if cfg.mic_wind_probability.get(cls, 0.0) > 0:          # draws last: the draws before it stay put
                mix = mix + _mic_wind(cfg, cls, rng, mix, clip_seed, n, sr)
            if cls == "BACKGROUND":                                  # draws last: the draws before it stay put
                mix = mix + _background_beds(cfg, rng, clip_seed, n, sr)
            mix = _resonances(cfg, cls, mix, clip_seed, sr)              # own stream: the draws above stay put
            samples = _record(cfg, np.asarray(mix, dtype=np.float64), clip_seed, CLASSES.index(cls))
            clips.append(AudioClip(name=f"SYN_{cls}_{j + 1:03d}", cls=cls, number=j + 1, samples=samples,
                                   sample_rate=sr, half="synthetic"))
    return clips


_SYNTH_TAG = 24          # "generation" sub-stream of the sim2real audio clips (issue 24)


# --------------------------------------------------------------------------------------------
# Drone vs not-drone on 1 s log-mel windows
# --------------------------------------------------------------------------------------------

def _mel_basis(sr: int) -> np.ndarray:
    import librosa

    key = int(sr)
    if key not in _MEL_CACHE:
        _MEL_CACHE[key] = librosa.filters.mel(sr=key, n_fft=MEL_FFT, n_mels=N_MELS, fmin=50.0,
                                              fmax=min(16000.0, key / 2)).astype(np.float32)
    return _MEL_CACHE[key]


_MEL_CACHE: dict[int, np.ndarray] = {}


def logmel_windows(clip: AudioClip) -> np.ndarray:
    """(W, N_MELS, frames) log-mel (dB) windows of 1 s (non-overlapping; Hann STFT 2048 / hop 1024,
    librosa's Slaney mel filters 50 Hz-16 kHz), each window's mean log level removed (a recorder's
    gain is not a class cue)."""
    from numpy.lib.stride_tricks import sliding_window_view

    x = clip.samples.astype(np.float32)
    sr = int(clip.sample_rate)
    if x.size < MEL_FFT:
        raise ValueError(f"clip {clip.name}: shorter than one STFT frame")
    frames = sliding_window_view(x, MEL_FFT)[::MEL_HOP] * np.hanning(MEL_FFT + 1)[:-1].astype(np.float32)
    power = np.abs(np.fft.rfft(frames, axis=1)) ** 2
    logmel = 10.0 * np.log10(_mel_basis(sr) @ power.T.astype(np.float32) + 1e-10)
    per = round(WINDOW_S * sr / MEL_HOP)
    n_win = logmel.shape[1] // per
    if n_win < 1:
        raise ValueError(f"clip {clip.name}: shorter than one {WINDOW_S} s window")
    w = logmel[:, : n_win * per].reshape(N_MELS, n_win, per).transpose(1, 0, 2)
    return (w - w.mean(axis=(1, 2), keepdims=True)).astype(np.float32)


@dataclass
class _Windows:
    x: np.ndarray          # (N, N_MELS, T) float32
    y: np.ndarray          # (N,) 1 = drone
    cls: np.ndarray        # (N,) class name
    clip: np.ndarray       # (N,) clip index into the set's clip list


def _windows(clips: list[AudioClip], feats: dict[str, np.ndarray]) -> _Windows:
    xs, ys, cs, ids = [], [], [], []
    for i, c in enumerate(clips):
        f = feats[c.name + "/" + c.half]
        xs.append(f)
        ys += [int(c.cls == "DRONE")] * len(f)
        cs += [c.cls] * len(f)
        ids += [i] * len(f)
    return _Windows(np.concatenate(xs).astype(np.float32), np.array(ys), np.array(cs), np.array(ids))


def _lr_features(x: np.ndarray) -> np.ndarray:
    return np.concatenate([x.mean(axis=2), x.std(axis=2)], axis=1)


def _fit_predict_lr(train: _Windows, w: np.ndarray, test: _Windows, seed: int) -> np.ndarray:
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    model = make_pipeline(StandardScaler(), LogisticRegression(C=0.1, max_iter=3000, random_state=seed))
    model.fit(_lr_features(train.x), train.y, logisticregression__sample_weight=w)
    return model.predict_proba(_lr_features(test.x))[:, 1]


def _fit_predict_cnn(train: _Windows, w: np.ndarray, test: _Windows, seed: int, epochs: int) -> np.ndarray:
    import torch
    from torch import nn

    torch.manual_seed(seed)
    gen = np.random.default_rng(seed)
    mean = train.x.mean(axis=(0, 2), keepdims=True)
    std = train.x.std(axis=(0, 2), keepdims=True) + 1e-3
    xt = torch.from_numpy(((train.x - mean) / std)[:, None].astype(np.float32))
    yt = torch.from_numpy(train.y.astype(np.float32))
    wt = torch.from_numpy(w.astype(np.float32))
    net = nn.Sequential(
        nn.Conv2d(1, 16, 3, padding=1), nn.BatchNorm2d(16), nn.ReLU(), nn.MaxPool2d(2),
        nn.Conv2d(16, 32, 3, padding=1), nn.BatchNorm2d(32), nn.ReLU(), nn.MaxPool2d(2),
        nn.Conv2d(32, 32, 3, padding=1), nn.BatchNorm2d(32), nn.ReLU(), nn.AdaptiveAvgPool2d(1),
        nn.Flatten(), nn.Dropout(0.3), nn.Linear(32, 1))
    opt = torch.optim.Adam(net.parameters(), lr=2e-3, weight_decay=1e-4)
    batch = 64
    net.train()
    for _ in range(epochs):
        order = gen.permutation(len(yt))
        for s in range(0, len(order), batch):
            idx = torch.from_numpy(order[s:s + batch])
            if idx.numel() < 2:
                continue
            logits = net(xt[idx]).squeeze(1)
            loss = (nn.functional.binary_cross_entropy_with_logits(logits, yt[idx], reduction="none") * wt[idx]).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    net.eval()
    with torch.no_grad():
        xe = torch.from_numpy(((test.x - mean) / std)[:, None].astype(np.float32))
        return torch.sigmoid(net(xe).squeeze(1)).numpy().astype(np.float64)


def roc_auc(y: np.ndarray, score: np.ndarray) -> float:
    """Mann-Whitney ROC-AUC (ties count 1/2); NaN when a label is missing."""
    from scipy.stats import rankdata

    pos, n = int(np.sum(y == 1)), y.size
    if pos == 0 or pos == n:
        return float("nan")
    r = rankdata(score)
    return float((np.sum(r[y == 1]) - pos * (pos + 1) / 2) / (pos * (n - pos)))


def balanced_accuracy(y: np.ndarray, score: np.ndarray, threshold: float = 0.5) -> float:
    pred = score > threshold
    parts = [np.mean(pred[y == lab] == bool(lab)) for lab in (0, 1) if np.any(y == lab)]
    return float(np.mean(parts)) if parts else float("nan")


def _bootstrap_indices(test: _Windows, clips: list[AudioClip], rng: np.random.Generator,
                       n_boot: int) -> list[np.ndarray]:
    """Window indices of ``n_boot`` clip-bootstrap resamples (clips drawn with replacement per class)."""
    by_clip = {i: np.flatnonzero(test.clip == i) for i in np.unique(test.clip)}
    per_class: dict[str, list[int]] = {}
    for i in by_clip:
        per_class.setdefault(clips[i].cls, []).append(i)
    out = []
    for _ in range(n_boot):
        chosen = [c for ids in per_class.values() for c in rng.choice(ids, size=len(ids), replace=True)]
        out.append(np.concatenate([by_clip[c] for c in chosen]))
    return out


def _ci(values: Sequence[float] | np.ndarray) -> list[float]:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return [float(np.percentile(v, 2.5)), float(np.percentile(v, 97.5))] if v.size else [float("nan")] * 2


def _mde(boot_diff: np.ndarray) -> float:
    """Minimum detectable difference of a paired bootstrap difference: (z_0.975 + z_0.8) x its std
    (a 5 % two-sided test with 80 % power)."""
    v = np.asarray(boot_diff, np.float64)
    v = v[np.isfinite(v)]
    return float(2.801585 * v.std(ddof=1)) if v.size > 2 else float("nan")


CONDITIONS = {"a_real": "real calibration half", "b_synthetic": "synthetic only",
              "c_synthetic_plus_real": "synthetic + real calibration half (domain-balanced)",
              "d_few_shot": "few-shot real (10 % of calibration clips, >= 1 per class)",
              "d_plus_few_shot_synthetic": "few-shot real + synthetic (domain-balanced)"}
MODELS = ("cnn", "logreg")


def _few_shot(cal: list[AudioClip], rng: np.random.Generator) -> list[AudioClip]:
    out = []
    for cls in CLASSES:
        members = [c for c in cal if c.cls == cls]
        if members:
            k = max(1, round(0.1 * len(members)))
            out += [members[i] for i in sorted(rng.choice(len(members), size=k, replace=False))]
    return out


def _concat(a: _Windows, b: _Windows) -> _Windows:
    return _Windows(np.concatenate([a.x, b.x]), np.concatenate([a.y, b.y]), np.concatenate([a.cls, b.cls]),
                    np.concatenate([a.clip, b.clip + 10 ** 6]))


def spectrogram_figure(real: list[AudioClip], synthetic: list[AudioClip], path: Path) -> Path:
    """Real | synthetic spectrogram (0-8 kHz, dB) of the first clip of each class, one row per class."""
    import io

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.signal import spectrogram

    from simulator.files import write_atomic

    fig, axes = plt.subplots(len(CLASSES), 2, figsize=(10, 8), sharex=True, sharey=True)
    for r, cls in enumerate(CLASSES):
        for c, (label, pool) in enumerate((("real", real), ("synthetic", synthetic))):
            ax = axes[r, c]
            clip = next((k for k in pool if k.cls == cls), None)
            if clip is None:
                ax.text(0.5, 0.5, "no source", ha="center", va="center", transform=ax.transAxes)
            else:
                f, t, s = spectrogram(clip.samples.astype(np.float64), fs=clip.sample_rate, nperseg=2048, noverlap=1024)
                keep = f <= 8000
                ax.pcolormesh(t, f[keep] / 1000, 10 * np.log10(s[keep] + 1e-14), shading="auto", cmap="magma",
                              vmin=None, vmax=None, rasterized=True)
                ax.set_title(f"{label}: {clip.name}", fontsize=9)
            if c == 0:
                ax.set_ylabel(f"{cls}\nkHz")
            if r == len(CLASSES) - 1:
                ax.set_xlabel("s")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80, metadata={"Software": None})
    plt.close(fig)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, buf.getvalue())
    return path


def run_audio_track(real_clips: list[AudioClip], synthetic_clips: list[AudioClip], seeds: list[int], quick: bool,
                    out_dir: Path, progress: bool = False, predictions: Path | None = None) -> dict[str, Any]:
    """The audio track: per-class statistics (real IQR vs synthetic median), drone-vs-not-drone
    conditions (a)-(d+) for a CNN and a log-mel logistic regression tested on the real evaluation
    half with clip-bootstrap 95 % CIs, and ``out_dir/audio_spectrograms.png``. JSON-able summary.
    ``predictions``: also keep every evaluation window's scores there (``evids sim2real-compare``)."""
    import torch

    t_start = time.perf_counter()

    def say(msg: str) -> None:
        if progress:
            print(f"[audio {time.perf_counter() - t_start:6.1f} s] {msg}", flush=True)

    if len(seeds) < 1:
        raise ValueError("seeds: need at least one training seed")
    cal = [c for c in real_clips if c.half == "calibration"]
    ev = [c for c in real_clips if c.half == "evaluation"]
    syn = [c for c in synthetic_clips if c.half == "synthetic"]
    for name, part in (("calibration", cal), ("evaluation", ev), ("synthetic", syn)):
        if not part:
            raise ValueError(f"real_clips/synthetic_clips: no {name} clips")
        if not any(c.cls == "DRONE" for c in part) or all(c.cls == "DRONE" for c in part):
            raise ValueError(f"{name} clips need both DRONE and not-drone clips")
    out_dir = Path(out_dir)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        say(f"statistics of {len(real_clips) + len(syn)} clips")
        stats = {c.name + "/" + c.half: audio_statistics(c.samples, c.sample_rate) for c in [*cal, *ev, *syn]}
        per_class: dict[str, Any] = {}
        real_vs_real: dict[str, Any] = {}
        for cls in CLASSES:
            pools = {h: _pooled(stats[c.name + "/" + c.half] for c in part if c.cls == cls)
                     for h, part in (("calibration", cal), ("evaluation", ev), ("synthetic", syn))}
            real_vs_real[cls] = compare_statistics(pools["evaluation"], pools["calibration"])
            if not any(c.cls == cls for c in syn):
                per_class[cls] = {"synthetic": "no source"}
                continue
            per_class[cls] = {half: compare_statistics(pools[half], pools["synthetic"])
                              for half in ("evaluation", "calibration")
                              if any(c.cls == cls for c in (ev if half == "evaluation" else cal))}
        say("log-mel windows")
        feats = {c.name + "/" + c.half: logmel_windows(c) for c in [*cal, *ev, *syn]}
        w_cal, w_ev, w_syn = _windows(cal, feats), _windows(ev, feats), _windows(syn, feats)
        epochs = 2 if quick else 10
        n_boot = 100 if quick else 1000
        scores: dict[str, dict[str, list[np.ndarray]]] = {k: {m: [] for m in MODELS} for k in CONDITIONS}
        for seed in seeds:
            few_rng = rng_for(seed, "generation", _SYNTH_TAG, 99)
            few = _few_shot(cal, few_rng)
            w_few = _windows(few, feats)
            sets = {"a_real": (w_cal, np.zeros(len(w_cal.y))), "b_synthetic": (w_syn, np.ones(len(w_syn.y))),
                    "c_synthetic_plus_real": (_concat(w_syn, w_cal),
                                              np.r_[np.ones(len(w_syn.y)), np.zeros(len(w_cal.y))]),
                    "d_few_shot": (w_few, np.zeros(len(w_few.y))),
                    "d_plus_few_shot_synthetic": (_concat(w_syn, w_few),
                                                  np.r_[np.ones(len(w_syn.y)), np.zeros(len(w_few.y))])}
            for cond, (train, domain) in sets.items():
                w = domain_balanced_weights(train.y, domain)
                scores[cond]["logreg"].append(_fit_predict_lr(train, w, w_ev, seed))
                scores[cond]["cnn"].append(_fit_predict_cnn(train, w, w_ev, seed, epochs))
                say(f"seed {seed} {cond} done")
        if predictions is not None:
            from harness.experiments.sim2real.compare import write_audio_scores

            write_audio_scores(predictions, w_ev.y, [ev[i].name for i in w_ev.clip], w_ev.cls, MODELS,
                               list(CONDITIONS), seeds, [[scores[c][m] for c in CONDITIONS] for m in MODELS])
        boot = _bootstrap_indices(w_ev, ev, np.random.default_rng(0), n_boot)
        classifier: dict[str, Any] = {}
        heli = w_ev.cls == "HELICOPTER"
        back = w_ev.cls == "BACKGROUND"
        for model in MODELS:
            res: dict[str, Any] = {}
            boot_auc: dict[str, np.ndarray] = {}
            for cond in CONDITIONS:
                runs = scores[cond][model]
                aucs = [roc_auc(w_ev.y, s) for s in runs]
                baccs = [balanced_accuracy(w_ev.y, s) for s in runs]
                b_auc = np.array([np.mean([roc_auc(w_ev.y[i], s[i]) for s in runs]) for i in boot])
                b_bacc = [float(np.mean([balanced_accuracy(w_ev.y[i], s[i]) for s in runs])) for i in boot]
                boot_auc[cond] = b_auc
                res[cond] = {"description": CONDITIONS[cond], "roc_auc": float(np.mean(aucs)),
                             "roc_auc_ci95": _ci(b_auc),
                             "roc_auc_per_seed": [float(a) for a in aucs], "balanced_accuracy": float(np.mean(baccs)),
                             "balanced_accuracy_ci95": _ci(b_bacc),
                             "helicopter_called_drone": float(np.mean([np.mean(s[heli] > 0.5) for s in runs]))
                             if heli.any() else None,
                             "background_called_drone": float(np.mean([np.mean(s[back] > 0.5) for s in runs]))
                             if back.any() else None}
            ratio = boot_auc["b_synthetic"] / boot_auc["a_real"]
            res["ratio_synthetic_over_real_auc"] = res["b_synthetic"]["roc_auc"] / res["a_real"]["roc_auc"]
            res["ratio_ci95"] = _ci(list(ratio))
            res["few_shot_gain_auc"] = res["d_plus_few_shot_synthetic"]["roc_auc"] - res["d_few_shot"]["roc_auc"]
            res["few_shot_gain_ci95"] = _ci(list(boot_auc["d_plus_few_shot_synthetic"] - boot_auc["d_few_shot"]))
            res["few_shot_gain_mde"] = _mde(boot_auc["d_plus_few_shot_synthetic"] - boot_auc["d_few_shot"])
            res["synthetic_plus_real_gain_auc"] = res["c_synthetic_plus_real"]["roc_auc"] - res["a_real"]["roc_auc"]
            res["synthetic_plus_real_gain_ci95"] = _ci(list(boot_auc["c_synthetic_plus_real"] - boot_auc["a_real"]))
            res["synthetic_plus_real_gain_mde"] = _mde(boot_auc["c_synthetic_plus_real"] - boot_auc["a_real"])
            classifier[model] = res
        say("spectrogram figure")
        figure = spectrogram_figure(cal, syn, out_dir / "audio_spectrograms.png")
    finally:
        torch.set_num_threads(threads)
    # the null reference of the count: the real calibration half's medians against the same IQRs (a second
    # set of real recordings; it does not reach every statistic either)
    inside = {cls: {"inside": sum(v["inside_real_iqr"] for v in d["evaluation"].values()), "of": len(d["evaluation"]),
                    "calibration_inside": sum(v["inside_real_iqr"] for v in real_vs_real[cls].values())}
              for cls, d in per_class.items() if isinstance(d, dict) and "evaluation" in d}
    summary = {
        "n_clips": {"calibration": len(cal), "evaluation": len(ev), "synthetic": len(syn)},
        "n_windows": {"calibration": len(w_cal.y), "evaluation": len(w_ev.y), "synthetic": len(w_syn.y)},
        "seeds": list(map(int, seeds)), "quick": bool(quick), "cnn_epochs": epochs, "bootstrap": n_boot,
        "statistics": per_class, "statistics_inside_real_iqr": inside, "classifier": classifier,
        "figure": figure.name, "seconds": round(time.perf_counter() - t_start, 1),
    }
    return json.loads(json.dumps(summary, allow_nan=True, default=float))
