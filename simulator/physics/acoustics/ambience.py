"""Ambient beds synthesised at the microphone: the :class:`Ambience` of a clip and the
:class:`AmbienceDistribution` it is drawn from, the broadband beds (wind, traffic, rain, birdsong,
residual, rustle, aircraft, drifting broadband, calls), the tonal machinery bed, and the rng stream
indices of every bed (``rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX + k)``)."""
from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from simulator.physics.acoustics.levels import check_sample_rate, db_spl_to_pa
from simulator.physics.acoustics.signals import chirp_events, shaped_noise, smooth_random
from simulator.seeding import rng_for

AMBIENT_SOURCE_INDEX = 1000       # rng index base of ambient beds (targets use 0, 1, ...)


class Ambience(BaseModel):
    """Ambient sound beds at the microphone; levels are dB SPL (RMS over the clip), None = off."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    wind_db: float | None = Field(default=45.0, ge=0.0, le=110.0)
    gust_depth: float = Field(default=0.6, ge=0.0, le=1.0, description="0 steady, 1 strongly gusty")
    traffic_db: float | None = Field(default=None, ge=0.0, le=110.0)
    rain_db: float | None = Field(default=None, ge=0.0, le=110.0)
    birdsong_db: float | None = Field(default=None, ge=0.0, le=110.0)
    residual_db: float | None = Field(default=None, ge=0.0, le=110.0, description=(
        "distant mixed outdoor sound (far traffic, industry, people): broadband 50 Hz-10 kHz"))
    rustle_db: float | None = Field(default=None, ge=0.0, le=110.0, description="leaves and grass moved by the wind")
    aircraft_db: float | None = Field(default=None, ge=0.0, le=110.0, description="a distant aircraft passing")


OPTIONAL_BEDS = ("traffic", "rain", "birdsong", "residual", "rustle", "aircraft")
_Span = tuple[float, float]


class AmbienceDistribution(BaseModel):
    """Where each clip's :class:`Ambience` is drawn from (domain randomisation): spans (low, high) of
    dB SPL drawn uniformly, and for every optional bed the probability that it is on. The one home of
    the ambience mix: TRIDENT scene distributions and the sim2real audio clips both draw through
    :func:`draw_ambience`. The defaults are the sim2real fit (levels read off the calibration half of
    the Svanström recordings, docs/SIM2REAL_AUDIO.md); a bed with probability 0 takes no draws."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    wind_db: _Span = (16.0, 34.0)          # 24-42 until 2026-12-03: backgrounds 7-10 dB too loud at 50-160 Hz
    gust_depth: _Span = (0.5, 1.0)
    traffic_probability: float = Field(default=0.4, ge=0.0, le=1.0)
    traffic_db: _Span = (30.0, 46.0)
    rain_probability: float = Field(default=0.15, ge=0.0, le=1.0)
    rain_db: _Span = (32.0, 46.0)
    birdsong_probability: float = Field(default=0.4, ge=0.0, le=1.0)
    birdsong_db: _Span = (22.0, 36.0)
    residual_probability: float = Field(default=1.0, ge=0.0, le=1.0)
    residual_db: _Span = (20.0, 34.0)
    rustle_probability: float = Field(default=0.5, ge=0.0, le=1.0)
    rustle_db: _Span = (18.0, 32.0)
    aircraft_probability: float = Field(default=0.2, ge=0.0, le=1.0)
    aircraft_db: _Span = (35.0, 52.0)

    @model_validator(mode="after")
    def _spans(self) -> AmbienceDistribution:
        for name, value in self.model_dump().items():
            if isinstance(value, tuple) and value[0] > value[1]:
                raise ValueError(f"{name}: low {value[0]} exceeds high {value[1]}")
        return self


class BedShapes(BaseModel):
    """Spectral shapes of two broadband beds, for callers that fit them (the sim2real audio clips); the
    defaults are the module's own shapes, so ``BedShapes()`` and None synthesise the same samples. Not part
    of :class:`Ambience` / :class:`AmbienceDistribution` (whose dumps are hashed into TRIDENT manifests), and
    no draw depends on it: the beds take the same random numbers whatever the shapes."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    traffic_band_hz: _Span = Field(default=(40.0, 2500.0), description="traffic bed band (Hz; the top clamped to "
                                                                         "0.45 fs)")
    traffic_tilt_db: float = Field(default=-1.5, ge=-12.0, le=3.0, description="traffic bed tilt (dB/octave)")
    residual_low_hz: float = Field(default=50.0, gt=0.0, lt=10000.0, description="residual bed lower edge (Hz)")
    residual_tilt_db: _Span = Field(default=(-9.0, -6.0), description="residual bed tilt span (dB/octave)")

    @model_validator(mode="after")
    def _spans(self) -> BedShapes:
        for name in ("traffic_band_hz", "residual_tilt_db"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ValueError(f"{name}: low {lo} exceeds high {hi}")
        if self.traffic_band_hz[0] <= 0:
            raise ValueError(f"traffic_band_hz: must be > 0, got {self.traffic_band_hz[0]}")
        return self


def draw_ambience(rng: np.random.Generator, dist: AmbienceDistribution) -> Ambience:
    """One clip's beds from ``dist``: wind level and gust depth, then per optional bed (in OPTIONAL_BEDS
    order) on/off and a level (both drawn whenever its probability is > 0, so the draws do not depend
    on the outcome). Levels rounded to 0.1 dB."""
    amb: dict[str, float | None] = {"wind_db": round(float(rng.uniform(*dist.wind_db)), 1),
                                    "gust_depth": round(float(rng.uniform(*dist.gust_depth)), 2)}
    for bed in OPTIONAL_BEDS:
        p = getattr(dist, f"{bed}_probability")
        if p <= 0:
            continue
        on = rng.random() < p
        level = float(rng.uniform(*getattr(dist, f"{bed}_db")))
        amb[f"{bed}_db"] = round(level, 1) if on else None
    return Ambience.model_validate(amb)


def _scale_to(x: np.ndarray, level_db: float) -> np.ndarray:
    return x * db_spl_to_pa(level_db) / max(float(np.sqrt(np.mean(x ** 2))), 1e-30)


def wind_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float, gust_depth: float, *,
             high_hz: float = 500.0, tilt_db_per_octave: float = -6.0) -> np.ndarray:
    """Wind on the microphone: red-tilted low-frequency noise (15 Hz-``high_hz``, ``tilt_db_per_octave``)
    with slow gust envelope (~0.3 Hz)."""
    base = shaped_noise(rng, n, sample_rate_hz, 15.0, high_hz, tilt_db_per_octave)
    gust = np.exp(gust_depth * 1.2 * smooth_random(rng, n, sample_rate_hz, 0.3))
    return _scale_to(base * gust, level_db)


def drifting_broadband_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float,
                           band_hz: tuple[float, float], tilt_db_per_octave: float) -> np.ndarray:
    """A flat, line-free broadband bed (distant road traffic, wind in foliage): noise over ``band_hz`` (the
    top clamped to 0.45 fs) with ``tilt_db_per_octave``, under a slow 3 dB level drift (~0.2 Hz)."""
    base = shaped_noise(rng, n, sample_rate_hz, band_hz[0], min(band_hz[1], 0.45 * sample_rate_hz), tilt_db_per_octave)
    drift = 10 ** (3.0 * smooth_random(rng, n, sample_rate_hz, 0.2) / 20)
    return _scale_to(base * drift, level_db)


def calls_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float,
              start_hz: tuple[float, float]) -> np.ndarray:
    """High-frequency calls (insects, small birds): Poisson chirps at 6 per second, 0.05-0.4 s long, starting
    in ``start_hz`` (the top clamped to 0.4 fs), at ``level_db`` dB SPL; zeros when no call falls in the clip."""
    calls = chirp_events(rng, n, sample_rate_hz, 6.0, (start_hz[0], min(start_hz[1], 0.4 * sample_rate_hz)),
                          (0.05, 0.4))
    return _scale_to(calls, level_db) if np.any(calls) else calls


def traffic_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float, *,
                band_hz: tuple[float, float] = (40.0, 2500.0), tilt_db_per_octave: float = -1.5) -> np.ndarray:
    """Road traffic at 50-500 m: tyre/road and engine noise over ``band_hz`` (default 40 Hz-2.5 kHz, the
    top clamped to 0.45 fs) with a spectral tilt ``tilt_db_per_octave`` (default -1.5: the EN 1793-3
    normalised traffic spectrum peaks near 1 kHz A-weighted; :class:`BedShapes` carries the unweighted
    reading of it), with vehicles passing (bell-shaped swells)."""
    base = shaped_noise(rng, n, sample_rate_hz, band_hz[0], min(band_hz[1], 0.45 * sample_rate_hz), tilt_db_per_octave)
    t = np.arange(n) / sample_rate_hz
    duration = n / sample_rate_hz
    passes = rng.uniform(-2.0, duration + 2.0, size=max(1, rng.poisson(0.5 * duration)))
    widths = rng.uniform(1.5, 4.0, size=passes.size)
    swell = 0.4 + np.sum(np.exp(-0.5 * ((t[None, :] - passes[:, None]) / widths[:, None]) ** 2), axis=0) \
        if passes.size < 64 else np.ones(n)
    return _scale_to(base * swell, level_db)


def rain_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """Rain: Poisson drop impacts (~1500 /s), each a 1-4 ms decaying high-passed noise burst."""
    from scipy.signal import fftconvolve

    count = rng.poisson(1500.0 * n / sample_rate_hz)
    impulses = np.zeros(n)
    np.add.at(impulses, rng.integers(0, n, size=count), rng.exponential(1.0, size=count))
    k = int(0.004 * sample_rate_hz)
    kernel = shaped_noise(rng, k, sample_rate_hz, 1500.0, 12000.0) * np.exp(-np.arange(k) / (0.0015 * sample_rate_hz))
    hiss = 0.3 * shaped_noise(rng, n, sample_rate_hz, 2000.0, 10000.0)
    return _scale_to(fftconvolve(impulses, kernel)[:n] + hiss * np.std(impulses) * np.sqrt(k) * 0.05, level_db)


def birdsong_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """Background birdsong: several birds' Poisson-timed chirps and trills, 2-7 kHz."""
    calls = chirp_events(rng, n, sample_rate_hz, 4.0, (2000.0, 7000.0), (0.05, 0.4))
    if not np.any(calls):
        return np.zeros(n)
    return _scale_to(calls, level_db)


def residual_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float, *,
                 low_hz: float = 50.0, tilt_db: tuple[float, float] = (-9.0, -6.0)) -> np.ndarray:
    """Residual outdoor sound (ISO 1996-2 'residual sound': what remains without specific sources):
    broadband ``low_hz`` (default 50 Hz)-10 kHz with a tilt drawn from ``tilt_db`` (dB/octave, default -9..-6)
    and a slow drift (4 dB std, 0.3 Hz). The same draws whatever ``low_hz`` and ``tilt_db``."""
    tilt = float(rng.uniform(*tilt_db))
    base = shaped_noise(rng, n, sample_rate_hz, low_hz, 10000.0, tilt)
    drift = 10 ** (4.0 * smooth_random(rng, n, sample_rate_hz, 0.3) / 20)
    return _scale_to(base * drift, level_db)


def rustle_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """Vegetation moved by the wind: 400 Hz-10 kHz noise, -6..-3 dB/octave, in gust-driven bursts
    (the envelope of low-passed noise at ~0.5 Hz) with fast leaf flutter (~8 Hz)."""
    base = shaped_noise(rng, n, sample_rate_hz, 400.0, 10000.0, float(rng.uniform(-6.0, -3.0)))
    gust = np.exp(1.2 * smooth_random(rng, n, sample_rate_hz, 0.5)) ** 1.5
    flutter = 1.0 + 0.4 * smooth_random(rng, n, sample_rate_hz, 8.0)
    return _scale_to(base * gust * np.abs(flutter), level_db)


def aircraft_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """A distant aircraft: broadband 50 Hz-2 kHz (high frequencies absorbed over kilometres) with a slow
    bell-shaped swell centred somewhere in (or near) the clip."""
    base = shaped_noise(rng, n, sample_rate_hz, 50.0, float(rng.uniform(800.0, 2500.0)), -2.0)
    t = np.arange(n) / sample_rate_hz
    duration = n / sample_rate_hz
    centre, width = rng.uniform(-0.3, 1.3) * duration, rng.uniform(4.0, 15.0)
    return _scale_to(base * (0.3 + np.exp(-0.5 * ((t - centre) / width) ** 2)), level_db)


# Tonal machinery (issue 24, sixth pass): the Ambience beds above are all broadband, but outdoor
# backgrounds often hold steady tones: mains-powered machinery hums at the mains frequency and its
# harmonics (50 Hz in Europe; transformers radiate mostly at twice it, 100 Hz, from magnetostriction),
# fans and pumps at their blade-passing frequency, idling or cruising engines at their firing frequency
# (4-stroke: rpm / 60 x cylinders / 2, e.g. 4 cylinders at 2000-3000 rpm: 67-100 Hz) and harmonics.
# Not part of Ambience / AmbienceDistribution (whose dumps are hashed into TRIDENT manifests); the
# sim2real audio clips draw it through MachineryDistribution (docs/SIM2REAL_AUDIO.md, sixth pass).
MACHINERY_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 7   # rng index of the machinery bed (after the other beds)
MAX_MACHINERY_HARMONICS = 8
# the sim2real audio clips' own beds (harness/experiments/sim2real/audio.py), after the machinery bed
MIC_WIND_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 8    # flow noise on the microphone (seventh pass)
BROADBAND_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 9   # flat, line-free broadband background bed (ninth pass)
CALLS_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 10      # high-frequency calls (insects, small birds; ninth pass)
RESONANCE_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 11  # per-clip spectral resonances (recorder, mount; tenth pass)


class Machinery(BaseModel):
    """One clip's tonal machinery bed: harmonics k x ``fundamental_hz`` (k = 1..len(harmonic_db)) at
    ``harmonic_db`` re the strongest, the sum at ``level_db`` dB SPL; the speed wanders slowly
    (relative std ``wander``, ~5 s correlation)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    level_db: float = Field(ge=0.0, le=110.0)
    fundamental_hz: float = Field(gt=0.0, le=2000.0)
    harmonic_db: tuple[float, ...] = Field(min_length=1, max_length=MAX_MACHINERY_HARMONICS)
    wander: float = Field(default=0.0, ge=0.0, le=0.1)


class MachineryDistribution(BaseModel):
    """Where a clip's :class:`Machinery` bed is drawn from: on with ``probability``; then with
    ``mains_probability`` a hum at exactly ``mains_hz`` with ``mains_harmonics`` harmonics and no wander,
    else a machine at a fundamental drawn log-uniformly from ``fundamental_hz`` with ``harmonics``
    harmonics and a drawn ``wander``. Per-harmonic levels: -``harmonic_slope_db`` x log2(k) plus a
    Gaussian of std ``harmonic_spread_db`` (then re the strongest). Spans are (low, high)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    probability: float = Field(default=0.5, ge=0.0, le=1.0)
    level_db: _Span = (20.0, 34.0)
    mains_probability: float = Field(default=0.3, ge=0.0, le=1.0)
    mains_hz: float = Field(default=50.0, gt=0.0)
    mains_harmonics: tuple[int, int] = (4, 8)
    fundamental_hz: _Span = (60.0, 260.0)
    harmonics: tuple[int, int] = (1, 4)
    harmonic_slope_db: float = Field(default=3.0, ge=0.0)
    harmonic_spread_db: float = Field(default=5.0, ge=0.0)
    wander: _Span = (0.0, 0.01)

    @model_validator(mode="after")
    def _spans(self) -> MachineryDistribution:
        for name in ("level_db", "mains_harmonics", "fundamental_hz", "harmonics", "wander"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ValueError(f"{name}: low {lo} exceeds high {hi}")
        for name in ("mains_harmonics", "harmonics"):
            lo, hi = getattr(self, name)
            if lo < 1 or hi > MAX_MACHINERY_HARMONICS:
                raise ValueError(f"{name}: need 1 <= low <= high <= {MAX_MACHINERY_HARMONICS}, got {(lo, hi)}")
        if self.fundamental_hz[0] <= 0:
            raise ValueError(f"fundamental_hz: must be > 0, got {self.fundamental_hz[0]}")
        return self


def draw_machinery(rng: np.random.Generator, dist: MachineryDistribution) -> Machinery | None:
    """One clip's machinery bed from ``dist`` (None: off). Nothing is drawn when ``dist.probability`` is 0;
    otherwise always the same number of draws (on/off, kind, level, fundamental, count, wander and
    MAX_MACHINERY_HARMONICS harmonic levels), so the outcome never shifts later draws."""
    if dist.probability <= 0:
        return None
    on, mains = rng.random() < dist.probability, rng.random() < dist.mains_probability
    level = float(rng.uniform(*dist.level_db))
    f0 = float(np.exp(rng.uniform(np.log(dist.fundamental_hz[0]), np.log(dist.fundamental_hz[1]))))
    count = int(rng.integers(*(dist.mains_harmonics if mains else dist.harmonics), endpoint=True))
    wander = float(rng.uniform(*dist.wander))
    k = np.arange(1, MAX_MACHINERY_HARMONICS + 1)
    rel = -dist.harmonic_slope_db * np.log2(k) + rng.normal(0.0, dist.harmonic_spread_db, size=k.size)
    if not on:
        return None
    rel = rel[:count] - rel[:count].max()
    return Machinery(level_db=round(level, 1), fundamental_hz=dist.mains_hz if mains else round(f0, 2),
                     harmonic_db=tuple(round(float(x), 1) for x in rel), wander=0.0 if mains else round(wander, 4))


def machinery_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, machinery: Machinery) -> np.ndarray:
    """The tonal bed of ``machinery`` at the microphone (Pa): harmonics with random phases on one slowly
    wandering speed (low-passed at 0.2 Hz), a slow level drift (1 dB std, 0.3 Hz); harmonics above the
    Nyquist frequency are dropped."""
    check_sample_rate(sample_rate_hz)
    speed = 1.0 + machinery.wander * smooth_random(rng, n, sample_rate_hz, 0.2)
    cycles = np.cumsum(machinery.fundamental_hz * speed) / sample_rate_hz
    phases = rng.uniform(0.0, 2 * np.pi, size=len(machinery.harmonic_db))
    x = np.zeros(n)
    for k, (db, phi) in enumerate(zip(machinery.harmonic_db, phases), start=1):
        if k * machinery.fundamental_hz * (1.0 + 4.0 * machinery.wander) < 0.5 * sample_rate_hz:
            x += 10 ** (db / 20) * np.cos(2 * np.pi * k * cycles + phi)
    drift = 10 ** (1.0 * smooth_random(rng, n, sample_rate_hz, 0.3) / 20)
    return _scale_to(x * drift, machinery.level_db)


def synthesize_ambience(ambience: Ambience, n_samples: int, sample_rate_hz: float, seed: int,
                        *indices: int, shapes: BedShapes | None = None) -> dict[str, np.ndarray]:
    """Each enabled bed (Pa at the microphone), from its own rng stream (seed, acoustics, *indices, 1000+k);
    ``shapes`` sets the traffic and residual beds' spectra (None: the module's, as ``BedShapes()``)."""
    check_sample_rate(sample_rate_hz)
    shapes = shapes or BedShapes()
    beds: dict[str, np.ndarray] = {}
    if ambience.wind_db is not None:
        beds["wind"] = wind_bed(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX), n_samples,
                                sample_rate_hz, ambience.wind_db, ambience.gust_depth)
    if ambience.traffic_db is not None:
        beds["traffic"] = traffic_bed(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX + 1), n_samples,
                                      sample_rate_hz, ambience.traffic_db, band_hz=shapes.traffic_band_hz,
                                      tilt_db_per_octave=shapes.traffic_tilt_db)
    if ambience.rain_db is not None:
        beds["rain"] = rain_bed(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX + 2), n_samples,
                                sample_rate_hz, ambience.rain_db)
    if ambience.birdsong_db is not None:
        beds["birdsong"] = birdsong_bed(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX + 3), n_samples,
                                        sample_rate_hz, ambience.birdsong_db)
    residual = functools.partial(residual_bed, low_hz=shapes.residual_low_hz, tilt_db=shapes.residual_tilt_db)
    makers: tuple[tuple[str, Callable[..., np.ndarray]], ...] = (("residual", residual), ("rustle", rustle_bed),
                                                                 ("aircraft", aircraft_bed))
    for k, (name, maker) in enumerate(makers):
        level = getattr(ambience, f"{name}_db")
        if level is not None:
            beds[name] = maker(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX + 4 + k), n_samples,
                               sample_rate_hz, level)
    return beds

