"""Sources, as pressure at 1 m evaluated on the microphone clock through tau(t): drone rotors (blade
lines, motor lines, broadband, ESC whine, drawn over documented ranges), birds, airliners and helicopters,
and :func:`synthesize_target`, which propagates one target track to the microphone."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenes.kinds import DRONE_KINDS
from scenes.kinds import DRONE_SIZE_M as _REFERENCE_SIZE_M
from simulator.physics.acoustics.levels import (
    AUDIO_BAND_HZ,
    SPHERE_DB,
    a_weighting_db,
    check_nonnegative,
    check_sample_rate,
    db_spl_to_pa,
    rotor_directivity,
    sound_power_dba,
    speed_of_sound_mps,
)
from simulator.physics.acoustics.propagation import Retarded, extrapolated, propagate, retarded_time
from simulator.physics.acoustics.signals import chirp_events, shaped_gain, shaped_noise, smooth_random

MOTOR_POLE_PAIRS = 7              # 12N14P outrunner: electrical frequency = 7 x shaft rate
N_BLADE_HARMONICS = 10
MAX_BLADE_HARMONICS = 30          # cap of the randomised line count (synthesis cost ~ lines)

# relative source levels at 1 m (dB SPL, unweighted) for the reference size: they fix the tonal /
# broadband balance; the absolute level comes from the sound power (sound_power_dba); docs/AUDIO_RF.md
_TONAL_DB_1M = {"quadcopter": 78.0, "hexacopter": 81.0, "fixed_wing": 80.0}
_BROADBAND_DB_1M = {"quadcopter": 72.0, "hexacopter": 75.0, "fixed_wing": 74.0}
BROADBAND_SHAPE = (300.0, 6000.0, -3.0)   # rotor broadband: band edges (Hz) and tilt (dB/octave)
BPF_MODULATION = 0.3                      # broadband amplitude modulation at the blade-passing frequency
GEOMETRY_STEP = 64                        # samples between evaluations of emission geometry (1.5 ms)
BIRD_CALL_DB_1M = 80.0
BIRD_WINGBEAT_DB_1M = 55.0
AIRLINER_DB_1M = 140.0


@dataclass(frozen=True)
class RotorNoise:
    """Rotor-noise parameters that physics leaves open. The defaults are the model before issue 24
    (clean coherent lines 6 dB over one stationary broadband); :func:`draw_rotor_noise` randomises them
    over documented ranges (docs/AUDIO_RF.md), which is what :func:`synthesize_target` uses by default."""

    harmonic_decay: float = 0.8             # blade-passing line amplitude ~ k^-decay
    harmonic_top_hz: float | None = None    # lines up to this frequency (None: N_BLADE_HARMONICS lines)
    broadband_offset_db: float | None = None  # broadband minus tonal at 1 m (None: the kind's 78/72 dB table)
    broadband_shape: tuple[float, float, float] = BROADBAND_SHAPE
    bpf_modulation: float = BPF_MODULATION
    imbalance: float = 0.18                 # shaft-rate line, re the first BPF line's amplitude
    motor_lines: tuple[float, float] = (0.25, 0.12)   # lines at 1x and 2x the electrical frequency
    pole_pairs: int = MOTOR_POLE_PAIRS
    pwm_hz: float | None = None             # ESC PWM switching frequency (a steady whine), None = off
    pwm_level: float = 0.0                  # its amplitude re the first BPF line
    amplitude_fluctuation_db: float = 0.0   # slow log-normal level fluctuation (turbulent propagation, manoeuvres)
    amplitude_fluctuation_hz: float = 1.0   # its corner frequency


LEGACY_ROTOR_NOISE = RotorNoise()
# ranges of draw_rotor_noise (uniform unless said): see docs/AUDIO_RF.md "Rotor noise (issue 24)"
ROTOR_NOISE_RANGES = {
    "harmonic_decay": (0.3, 1.2), "harmonic_top_hz": (3000.0, 10000.0), "broadband_offset_db": (10.0, 20.0),
    "broadband_low_hz": (100.0, 400.0), "broadband_high_hz": (15000.0, 20000.0), "broadband_tilt_db": (-4.0, -1.5),
    "bpf_modulation": (0.1, 0.6), "imbalance": (0.02, 0.15), "motor_line": (0.02, 0.15),
    "pwm_hz": (8000.0, 12000.0, 16000.0), "pwm_level": (0.0, 0.08), "amplitude_fluctuation_db": (1.0, 4.0),
    "amplitude_fluctuation_hz": (0.3, 3.0),
}


def merged_ranges(base: dict, overrides: dict | None, field_name: str) -> dict:
    """``base`` ranges with ``overrides`` applied: only (low, high) spans of existing keys can be
    replaced, low <= high; a bad entry raises a ValueError naming ``field_name.key``. The draws keep
    their order, so replacing a span moves only the values drawn from it."""
    if not overrides:
        return base
    out = dict(base)
    for key, span in overrides.items():
        if key not in base or len(base[key]) != 2 or isinstance(base[key][0], int) and isinstance(base[key][1], int):
            spans = sorted(k for k, v in base.items() if len(v) == 2 and not all(isinstance(x, int) for x in v))
            raise ValueError(f"{field_name}.{key}: not a drawn span; expected one of {spans}")
        lo, hi = (float(x) for x in span) if len(span) == 2 else (np.nan, np.nan)
        if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi:
            raise ValueError(f"{field_name}.{key}: need (low, high) with low <= high, got {tuple(span)}")
        out[key] = (lo, hi)
    return out


def draw_rotor_noise(rng: np.random.Generator, ranges: dict | None = None) -> RotorNoise:
    """Rotor-noise parameters drawn from ``ROTOR_NOISE_RANGES`` (domain randomisation, per drone);
    ``ranges`` replaces some of its spans (:func:`merged_ranges`; same draws in the same order)."""
    r = merged_ranges(ROTOR_NOISE_RANGES, ranges, "rotor_noise")

    def u(name: str) -> float:
        return float(rng.uniform(r[name][0], r[name][1]))

    decay, top, offset = u("harmonic_decay"), u("harmonic_top_hz"), u("broadband_offset_db")
    shape = (u("broadband_low_hz"), u("broadband_high_hz"), u("broadband_tilt_db"))
    bpf_mod, imbalance = u("bpf_modulation"), u("imbalance")
    motor = (u("motor_line"), u("motor_line"))
    pole_pairs = int(rng.choice([6, 7]))
    pwm = float(rng.choice(r["pwm_hz"])) if rng.random() < 0.5 else None
    pwm_level = u("pwm_level")
    fluct_db, fluct_hz = u("amplitude_fluctuation_db"), u("amplitude_fluctuation_hz")
    return RotorNoise(harmonic_decay=decay, harmonic_top_hz=top, broadband_offset_db=offset, broadband_shape=shape,
                      bpf_modulation=bpf_mod, imbalance=imbalance, motor_lines=motor, pole_pairs=pole_pairs,
                      pwm_hz=pwm, pwm_level=pwm_level if pwm else 0.0, amplitude_fluctuation_db=fluct_db,
                      amplitude_fluctuation_hz=fluct_hz)


def _source_noise(rng: np.random.Generator, retarded: Retarded, sample_rate_hz: float, low_hz: float,
                  high_hz: float, slope_db_per_octave: float = 0.0) -> np.ndarray:
    """Shaped noise generated on the emission clock and resampled along tau(t) (Doppler, delay)."""
    t0 = float(retarded.tau_s[0])
    m = int(np.ceil((float(retarded.tau_s[-1]) - t0) * sample_rate_hz)) + 3
    src = shaped_noise(rng, m, sample_rate_hz, low_hz, high_hz, slope_db_per_octave)
    return np.interp((retarded.tau_s - t0) * sample_rate_hz, np.arange(m), src)



def _harmonic_poly(z: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """Re(sum_p coeffs[..., p] z^p) by Horner's rule (z on the unit circle, complex64)."""
    acc = np.broadcast_to(coeffs[:, -1:], z.shape).astype(np.complex64)
    for p in range(coeffs.shape[1] - 2, -1, -1):
        np.multiply(acc, z, out=acc)
        if np.any(coeffs[:, p]):
            acc += coeffs[:, p:p + 1]
    return acc.real


def rotor_signature(rpm: np.ndarray, n_blades: int, retarded: Retarded, sample_rate_hz: float,
                    rng: np.random.Generator, tonal_db_1m: float, broadband_db_1m: float,
                    hover_rpm: float, *, sound_power_dba: float | None = None,
                    tonal_gain: np.ndarray | None = None, broadband_gain: np.ndarray | None = None,
                    noise: RotorNoise = LEGACY_ROTOR_NOISE) -> np.ndarray:
    """Pressure at 1 m of a set of rotors heard through ``retarded`` (microphone clock).

    ``rpm`` (R, N) is each rotor's speed at the emission time of every microphone sample. Each
    rotor gives blade-passing harmonics k x rpm/60 x n_blades (k = 1..10, amplitude ~ k^-0.8), a
    shaft-rate imbalance line and motor electrical lines at 7 and 14 x the shaft rate; rotors with
    slightly different RPM beat. Broadband turbulence is shaped noise modulated at the BPF.
    Tonal pressure scales with thrust (rpm^2), broadband with rpm^2.5 (acoustic power ~ rpm^4 / rpm^5).

    ``sound_power_dba`` (L_WA at hover) rescales both parts together (keeping their ratio) so the
    A-weighted level at 1 m, averaged over the sphere, is L_WA - 10 log10(4 pi) at ``hover_rpm``;
    ``tonal_gain``/``broadband_gain`` (N,) are the directivity amplitude factors per sample.
    ``noise`` sets what physics leaves open (line count and decay, broadband level and shape, BPF
    modulation, imbalance, motor lines, ESC PWM whine); the default is the pre-issue-24 model.
    """
    rpm = np.atleast_2d(np.asarray(rpm, dtype=np.float64))
    if rpm.size and np.min(rpm) < 0:
        raise ValueError(f"rotor_rpm must be >= 0, got min {np.min(rpm):.6g}")
    if n_blades < 1:
        raise ValueError(f"n_blades must be >= 1, got {n_blades}")
    n_rotors, n = rpm.shape
    shaft_hz_rx = rpm / 60.0 * retarded.dtau_dt[None, :]             # received shaft rate (Doppler)
    phase = 2 * np.pi * np.cumsum(shaft_hz_rx, axis=1) / sample_rate_hz
    phase += rng.uniform(0, 2 * np.pi, size=(n_rotors, 1))
    phase32 = np.mod(phase, 2 * np.pi).astype(np.float32)
    z = np.empty(phase32.shape, dtype=np.complex64)
    z.real = np.cos(phase32)
    z.imag = np.sin(phase32)
    if noise.harmonic_top_hz is None:
        n_harm = N_BLADE_HARMONICS
    else:
        n_harm = int(np.clip(noise.harmonic_top_hz / max(n_blades * hover_rpm / 60.0, 1.0), 1, MAX_BLADE_HARMONICS))
    pp = int(noise.pole_pairs)
    max_power = max(n_blades * n_harm, 2 * pp)
    coeffs = np.zeros((n_rotors, max_power + 1), dtype=np.complex128)
    k = np.arange(1, n_harm + 1)
    blade_amp = k ** -noise.harmonic_decay * 10 ** (rng.normal(0.0, 1.5, size=(n_rotors, k.size)) / 20)
    coeffs[:, n_blades * k] = blade_amp * np.exp(1j * rng.uniform(0, 2 * np.pi, size=(n_rotors, k.size)))
    coeffs[:, 1] += noise.imbalance * np.exp(1j * rng.uniform(0, 2 * np.pi, size=n_rotors))   # imbalance
    coeffs[:, pp] += noise.motor_lines[0] * np.exp(1j * rng.uniform(0, 2 * np.pi, size=n_rotors))
    coeffs[:, 2 * pp] += noise.motor_lines[1] * np.exp(1j * rng.uniform(0, 2 * np.pi, size=n_rotors))
    # rms of sum_p |c_p| cos(.) per rotor = sqrt(sum |c|^2 / 2); scale so all rotors together give tonal_db_1m
    per_rotor_rms = np.sqrt(np.sum(np.abs(coeffs) ** 2, axis=1) / 2)
    pwm_amp = noise.pwm_level / max(float(np.sqrt(np.sum(np.abs(coeffs[0]) ** 2) / 2)), 1e-30)
    coeffs *= db_spl_to_pa(tonal_db_1m) / np.sqrt(n_rotors) / per_rotor_rms[:, None]
    pwm_pa = pwm_amp * db_spl_to_pa(tonal_db_1m) / np.sqrt(n_rotors)
    if noise.broadband_offset_db is not None:
        broadband_db_1m = tonal_db_1m + noise.broadband_offset_db
    broadband_pa = db_spl_to_pa(broadband_db_1m)
    pwm_hz = noise.pwm_hz if noise.pwm_hz is not None else 0.0
    pwm_on = noise.pwm_hz is not None and pwm_pa > 0 and pwm_hz < 0.45 * sample_rate_hz
    if sound_power_dba is not None:
        extra = n_rotors * pwm_pa ** 2 / 2 * 10 ** (float(a_weighting_db(pwm_hz)) / 10) if pwm_on else 0.0
        scale = _sound_power_scale(coeffs, broadband_pa, n_blades, hover_rpm, sound_power_dba,
                                   noise.broadband_shape, noise.bpf_modulation, extra)
        coeffs *= scale
        broadband_pa *= scale
        pwm_pa *= scale
    # only powers of z that lie below Nyquist at the highest shaft rate are kept
    max_shaft_hz = float(np.max(shaft_hz_rx)) if n else 0.0
    if max_shaft_hz > 0:
        keep = np.arange(max_power + 1) * max_shaft_hz < 0.45 * sample_rate_hz
        coeffs[:, ~keep] = 0
    thrust = (rpm / max(hover_rpm, 1e-9)) ** 2
    tonal = np.sum(_harmonic_poly(z, coeffs.astype(np.complex64)) * thrust, axis=0, dtype=np.float64)
    hiss = _source_noise(rng, retarded, sample_rate_hz, *noise.broadband_shape)
    bpf_mod = 1.0 + noise.bpf_modulation * np.real(z[0] ** n_blades)
    broadband = hiss * bpf_mod * np.mean(thrust, axis=0) ** 1.25 * broadband_pa
    if pwm_on:                          # ESC switching whine: fixed frequency, every rotor, random phases
        phases = np.asarray(rng.uniform(0, 2 * np.pi, size=n_rotors))
        tonal = tonal + pwm_pa * np.sum(np.cos(2 * np.pi * pwm_hz * retarded.tau_s[None, :] + phases[:, None]),
                                        axis=0)
    if tonal_gain is not None:
        tonal = tonal * tonal_gain
    if broadband_gain is not None:
        broadband = broadband * broadband_gain
    return tonal + broadband


def _sound_power_scale(coeffs: np.ndarray, broadband_pa: float, n_blades: int, hover_rpm: float,
                       sound_power_dba: float, broadband_shape: tuple[float, float, float] = BROADBAND_SHAPE,
                       bpf_modulation: float = BPF_MODULATION, extra_tonal_ms: float = 0.0) -> float:
    """Amplitude factor that gives A-weighted mean square (L_WA - 10 lg 4 pi at 1 m) at hover.

    Tonal: sum over lines |c_p|^2 / 2 x A(p f_shaft)^2. Broadband: rms^2 x (1 + m^2 / 2) (BPF
    modulation) x the A-weighted share of its spectrum (evaluated on a 1 Hz grid).
    """
    shaft_hz = hover_rpm / 60.0
    powers = np.arange(coeffs.shape[1])
    a_lin = 10 ** (a_weighting_db(np.maximum(powers * shaft_hz, 1e-3)) / 10)
    tonal_ms = float(np.sum(np.abs(coeffs) ** 2 / 2 * a_lin[None, :])) + extra_tonal_ms
    f = np.arange(1.0, AUDIO_BAND_HZ)
    shape = shaped_gain(f, *broadband_shape) ** 2
    share = float(np.sum(shape * 10 ** (a_weighting_db(f) / 10)) / np.sum(shape))
    broad_ms = broadband_pa ** 2 * (1 + bpf_modulation ** 2 / 2) * share
    target_ms = db_spl_to_pa(sound_power_dba - SPHERE_DB) ** 2
    return float(np.sqrt(target_ms / max(tonal_ms + broad_ms, 1e-300)))



def bird_signature(wingbeat_hz: float, retarded: Retarded, sample_rate_hz: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Pressure at 1 m of a bird: low-frequency wing-beat thumps at wingbeat_hz plus sporadic calls."""
    if not wingbeat_hz > 0:
        raise ValueError(f"wingbeat_hz must be > 0, got {wingbeat_hz}")
    flap = 2 * np.pi * wingbeat_hz * retarded.tau_s
    thump = _source_noise(rng, retarded, sample_rate_hz, 40.0, 400.0) * np.maximum(np.sin(flap), 0.0) ** 4
    thump *= db_spl_to_pa(BIRD_WINGBEAT_DB_1M) / max(float(np.sqrt(np.mean(thump ** 2))), 1e-30)
    t0 = float(retarded.tau_s[0])
    m = int(np.ceil((float(retarded.tau_s[-1]) - t0) * sample_rate_hz)) + 3
    calls_src = chirp_events(rng, m, sample_rate_hz, 0.8, (2000.0, 5000.0), (0.08, 0.25))
    calls = np.interp((retarded.tau_s - t0) * sample_rate_hz, np.arange(m), calls_src)
    return thump + calls * db_spl_to_pa(BIRD_CALL_DB_1M) * np.sqrt(2)


def airliner_signature(retarded: Retarded, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
    """Pressure at 1 m of a jet airliner: low-frequency broadband jet noise (peak ~100-300 Hz)."""
    jet = _source_noise(rng, retarded, sample_rate_hz, 60.0, 400.0, -2.0)
    return jet * db_spl_to_pa(AIRLINER_DB_1M)


# Helicopter (light turbine helicopter). What is known, and used as such: the main rotor is governed
# (constant rpm), its blade-passing frequency BPF = blades x rpm / 60 is 12-30 Hz for light helicopters
# (2 blades at ~400 rpm: R44, Bell 206; 3 at ~390: AS350; 4 at ~395: EC135, A109, Bell 429); the tail
# rotor is geared to it (4.5-6.5 x the main shaft rate, 2-4 blades: BPF 50-170 Hz); thickness/loading
# noise is a low-frequency pulse train at the BPF, blade slap (blade-vortex interaction) sharp broadband
# pulses at the BPF, and the rotor's broadband self-noise is amplitude-modulated at the BPF ('swish');
# the turboshaft's compressor adds tones at several kHz. A ~300 m flyover is 80-90 dB(A). What is not
# known per helicopter (levels of the parts, pulse widths, modulation depth, turbine tones) is drawn from
# HELICOPTER_RANGES (domain randomisation; the envelope-modulation depth at the BPF, 15-24 dB over the
# modulation floor in every band up to 14 kHz, and the tones at 6-12 kHz were read off the calibration
# half of the Svanström recordings: docs/SIM2REAL_AUDIO.md).
HELICOPTER_DB_1M = 126.0          # overall unweighted level at 1 m of the sum of the parts below
HELICOPTER_MAIN_RPM = (330.0, 420.0)   # governed main-rotor speed when no track gives it
HELICOPTER_RANGES = {"main_blades": (2, 3, 3, 4, 4), "tail_ratio": (4.5, 6.5), "tail_blades": (2, 4),
                     "thump_ms": (2.0, 6.0), "thump_db": (-18.0, -2.0), "slap_ms": (0.15, 0.6),
                     "slap_db": (-22.0, -4.0), "swish_width": (0.08, 0.25), "swish_depth": (0.1, 1.3),
                     "broadband_low_hz": (200.0, 400.0), "broadband_tilt_db": (-8.0, -6.0),
                     "tip_noise_db": (-22.0, -10.0), "tail_db": (-20.0, -10.0),
                     "turbine_tones": (1, 3), "turbine_hz": (6000.0, 12000.0), "turbine_db": (-30.0, -16.0),
                     "turbine_noise_db": (-26.0, -14.0), "tail_peak_harmonic": (1.0, 1.0),
                     "level_fluctuation_db": (0.0, 0.0), "level_fluctuation_hz": (0.3, 1.0),
                     "band_high_hz": (AUDIO_BAND_HZ, AUDIO_BAND_HZ)}


def _periodic_pulses(phase: np.ndarray, width: float, jitter: np.ndarray | None = None) -> np.ndarray:
    """Gaussian pulses (std ``width`` periods) at every integer of ``phase`` (cycles), optionally each
    pass scaled by ``jitter[pass]``."""
    frac = phase - np.floor(phase + 0.5)                     # periods to the nearest pass
    pulses = np.exp(-0.5 * (frac / width) ** 2)
    if jitter is not None:
        passes = np.floor(phase + 0.5).astype(np.int64)
        pulses = pulses * jitter[passes - passes.min()]
    return pulses


def helicopter_signature(retarded: Retarded, sample_rate_hz: float, rng: np.random.Generator, *,
                         main_rpm: np.ndarray | float | None = None, main_blades: int | None = None,
                         ranges: dict | None = None) -> np.ndarray:
    """Pressure at 1 m of a helicopter (emission clock through ``retarded``), parts drawn from
    ``HELICOPTER_RANGES``.

    ``main_rpm`` (scalar or per microphone sample) and ``main_blades`` come from the target's rotor
    (scene schema) when given, else they are drawn (``HELICOPTER_MAIN_RPM``, 2-4 blades). Parts, each
    scaled re the rotor broadband: rotor broadband from 200-400 Hz to the upper edge ``band_high_hz`` (module:
    16 kHz; above it clamped to 0.45 fs) (tilt -8..-6 dB/octave) and blade-tip self-noise 2 kHz to that edge
    (-1 dB/octave, -22..-10 dB), both with an exponential 'swish'
    envelope at the BPF; thickness/loading thump (2-6 ms pulses at the BPF, per-pass
    jitter); blade slap (0.15-0.6 ms pulses); tail-rotor lines k x its BPF (k^-1); turbine: 1-3
    wandering compressor tones at 6-12 kHz and noise from 1 kHz to the same edge. The sum is scaled to HELICOPTER_DB_1M.
    ``ranges`` replaces some (low, high) spans of ``HELICOPTER_RANGES`` (:func:`merged_ranges`).
    """
    r = merged_ranges(HELICOPTER_RANGES, ranges, "helicopter")
    u = lambda name: float(rng.uniform(r[name][0], r[name][1]))  # noqa: E731
    drawn_rpm, drawn_blades = float(rng.uniform(*HELICOPTER_MAIN_RPM)), int(rng.choice(r["main_blades"]))
    blades = drawn_blades if main_blades is None else int(main_blades)   # drawn anyway: later draws stay put
    if blades < 1:
        raise ValueError(f"main_blades must be >= 1, got {blades}")
    rpm = np.broadcast_to(np.asarray(drawn_rpm if main_rpm is None else main_rpm, dtype=np.float64),
                          retarded.tau_s.shape)
    check_nonnegative("main_rpm", rpm)
    tau = retarded.tau_s - float(retarded.tau_s[0])
    dtau = np.diff(tau, prepend=tau[0])
    shaft_cycles = np.cumsum(rpm / 60.0 * dtau) + rng.uniform()          # main shaft revolutions (emission clock)
    phase = blades * shaft_cycles                                        # blade passes
    tail_phase = u("tail_ratio") * int(rng.choice(r["tail_blades"])) * shaft_cycles
    n_pass = int(np.ceil(phase.max() - phase.min())) + 3
    jitter = 10 ** (rng.normal(0.0, 2.0, size=n_pass) / 20)
    bpf = float(np.median(rpm)) / 60.0 * blades
    thump = _periodic_pulses(phase, u("thump_ms") / 1000.0 * bpf, jitter)
    slap = _periodic_pulses(phase, u("slap_ms") / 1000.0 * bpf, jitter[::-1])
    swish = np.exp(u("swish_depth") * _periodic_pulses(phase, u("swish_width")))
    # upper edge of the broadband parts (rotor, tip, turbine noise): nothing in the sources stops at 16 kHz; the
    # module's span (16, 16) kHz draws nothing and keeps every output; above 16 kHz it is clamped to 0.45 fs
    edge_lo, edge_hi = (float(x) for x in r["band_high_hz"])
    high = edge_lo if edge_lo == edge_hi else float(rng.uniform(edge_lo, edge_hi))
    if high > AUDIO_BAND_HZ:
        high = max(AUDIO_BAND_HZ, min(high, 0.45 * sample_rate_hz))
    broad = _source_noise(rng, retarded, sample_rate_hz, u("broadband_low_hz"), high, u("broadband_tilt_db")) * swish
    tip = _source_noise(rng, retarded, sample_rate_hz, 2000.0, high, -1.0) * swish
    k = np.arange(1, 16)
    tail_phases = rng.uniform(0, 2 * np.pi, size=(k.size, 1))
    turbine = np.zeros(tau.size)
    for _ in range(int(rng.integers(int(r["turbine_tones"][0]), int(r["turbine_tones"][1]) + 1))):
        f_t = u("turbine_hz") * (1 + 0.005 * smooth_random(rng, tau.size, sample_rate_hz, 0.3))
        turbine += np.cos(2 * np.pi * np.cumsum(f_t) / sample_rate_hz + rng.uniform(0, 2 * np.pi))
    turbine_noise = _source_noise(rng, retarded, sample_rate_hz, 1000.0, high, -2.0)
    levels = [u(name) for name in ("tip_noise_db", "thump_db", "slap_db", "tail_db", "turbine_db", "turbine_noise_db")]
    # tail-rotor lines ~ k^-1 above its strongest harmonic, rising as (k / peak)^2 below it (peak 1: k^-1 from
    # the first line); drawn last, so a span of (1, 1) leaves every other draw and the lines as before
    peak = u("tail_peak_harmonic")
    weights = k ** -1.0 * np.minimum(1.0, k / peak) ** 2
    tail = np.sum(weights[:, None] * np.cos(2 * np.pi * k[:, None] * tail_phase[None, :] + tail_phases), axis=0)
    parts = [(broad, 0.0), (tip, levels[0]), (thump - thump.mean(), levels[1]), (slap - slap.mean(), levels[2]),
             (tail, levels[3]), (turbine, levels[4]), (turbine_noise, levels[5])]
    total = np.zeros(tau.size)
    for x, db in parts:
        total += x / max(float(np.sqrt(np.mean(x ** 2))), 1e-30) * 10 ** (db / 20)
    return total * db_spl_to_pa(HELICOPTER_DB_1M) / max(float(np.sqrt(np.mean(total ** 2))), 1e-30)


def target_source_levels(kind: str, size_m: float) -> tuple[float, float]:
    """(tonal, broadband) unweighted dB SPL at 1 m of a drone kind, +20 log10 of size / reference size.

    Their difference sets the spectral balance; :func:`synthesize_target` rescales both to the
    drone's sound power (:func:`sound_power_dba`)."""
    gain = 20.0 * np.log10(size_m / _REFERENCE_SIZE_M[kind])
    return _TONAL_DB_1M[kind] + gain, _BROADBAND_DB_1M[kind] + gain


def _emission_geometry(track, frame_times_s: np.ndarray, tau_s: np.ndarray, mic_position_m: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample source position and body up axis at the emission time, and the microphone position."""
    frame_t = np.asarray(frame_times_s, dtype=np.float64)
    pos = extrapolated(tau_s, frame_t, np.asarray(track.position_m, dtype=np.float64),
                        np.asarray(track.velocity_mps, dtype=np.float64))
    mic = np.broadcast_to(np.asarray(mic_position_m, dtype=np.float64).reshape(-1, 3), (frame_t.size, 3))
    mic_at = np.stack([np.interp(tau_s, frame_t, mic[:, k]) for k in range(3)], -1)
    rotation = getattr(track, "rotation", None)
    if rotation is None:
        up = np.tile([0.0, 0.0, 1.0], (tau_s.size, 1))
    else:
        frame = np.clip(np.round(np.interp(tau_s, frame_t, np.arange(frame_t.size))).astype(int), 0, frame_t.size - 1)
        up = np.asarray(rotation, dtype=np.float64)[:, :, 2][frame]
    return pos, up, mic_at


def synthesize_target(track, frame_times_s: np.ndarray, mic_position_m: np.ndarray, n_samples: int,
                      sample_rate_hz: float, air_temperature_k: float, relative_humidity: float,
                      rng: np.random.Generator, wingbeat_hz: float = 4.0, *, ground_factor: float | None = None,
                      sound_power_db: float | None = None, directivity: bool = True,
                      rotor_noise: RotorNoise | None = None, rotor_noise_ranges: dict | None = None,
                      helicopter_ranges: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Received pressure (Pa) of one ``TargetTrack`` at the microphone, and its range per sample.

    Drones radiate their hover sound power ``sound_power_db`` (L_WA; default :func:`sound_power_dba`
    of kind and size) with the rotor directivity about the body's up axis; ``ground_factor`` (ISO
    9613-2 G, None = free field) adds the ground effect with heights above z = 0. ``rotor_noise``
    None draws the open rotor-noise parameters from ``rng`` (:func:`draw_rotor_noise`); pass
    ``LEGACY_ROTOR_NOISE`` for the clean pre-issue-24 rotor model; ``rotor_noise_ranges`` and
    ``helicopter_ranges`` replace spans of ``ROTOR_NOISE_RANGES`` / ``HELICOPTER_RANGES`` (None: the
    module's ranges, byte-identical to before they existed). A ``kind`` "helicopter" track
    (built by hand: the scenario schema has no helicopter target yet) uses :func:`helicopter_signature`.
    """
    from simulator.physics.timeline import rotor_hover_rpm

    check_sample_rate(sample_rate_hz)
    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples}")
    c = speed_of_sound_mps(air_temperature_k)
    rx_t = np.arange(n_samples) / sample_rate_hz + float(frame_times_s[0])
    ret = retarded_time(rx_t, frame_times_s, track.position_m, track.velocity_mps, mic_position_m, c)
    # geometry changes slowly: evaluate it every GEOMETRY_STEP samples and interpolate
    coarse = np.unique(np.append(np.arange(0, n_samples, GEOMETRY_STEP), n_samples - 1))
    pos_c, up_c, mic_c = _emission_geometry(track, frame_times_s, ret.tau_s[coarse], mic_position_m)
    samples = np.arange(n_samples)
    fluctuation = None
    if track.kind in DRONE_KINDS:
        noise = draw_rotor_noise(rng, rotor_noise_ranges) if rotor_noise is None else rotor_noise
        rpm_frames = np.asarray(track.rotor_rpm, dtype=np.float64)
        check_nonnegative("rotor_rpm", rpm_frames)
        rpm = np.stack([np.interp(ret.tau_s, frame_times_s, rpm_frames[:, r]) for r in range(rpm_frames.shape[1])])
        tonal_db, broad_db = target_source_levels(track.kind, track.size_m)
        power = sound_power_dba(track.kind, track.size_m) if sound_power_db is None else float(sound_power_db)
        gains = (None, None)
        if directivity:
            gains = tuple(np.interp(samples, coarse, g) for g in rotor_directivity(mic_c - pos_c, up_c))
        hover = getattr(track, "hover_rpm", None) or rotor_hover_rpm(track.kind, track.size_m)
        src = rotor_signature(rpm, max(int(track.n_blades), 1), ret, sample_rate_hz, rng, tonal_db, broad_db,
                              hover, sound_power_dba=power,
                              tonal_gain=gains[0], broadband_gain=gains[1], noise=noise)
        if noise.amplitude_fluctuation_db > 0:
            fluctuation = _level_fluctuation(rng, n_samples, sample_rate_hz, noise.amplitude_fluctuation_db,
                                             noise.amplitude_fluctuation_hz)
    elif track.kind == "bird":
        src = bird_signature(wingbeat_hz, ret, sample_rate_hz, rng)
    elif track.kind == "airliner":
        src = airliner_signature(ret, sample_rate_hz, rng)
    elif track.kind == "helicopter":
        rpm_frames = np.asarray(track.rotor_rpm, dtype=np.float64).reshape(len(frame_times_s), -1)
        main_rpm = np.interp(ret.tau_s, frame_times_s, rpm_frames[:, 0]) if rpm_frames.size else None
        src = helicopter_signature(ret, sample_rate_hz, rng, main_rpm=main_rpm,
                                   main_blades=getattr(track, "n_blades", None) if rpm_frames.size else None,
                                   ranges=helicopter_ranges)
        # turbulent propagation over 50-300 m (and the pilot's collective) make the received level wander; the
        # module's span (0, 0) draws nothing, so every helicopter output stays as it was without it
        spans = merged_ranges(HELICOPTER_RANGES, helicopter_ranges, "helicopter")
        if spans["level_fluctuation_db"][1] > 0:
            std_db = float(rng.uniform(*spans["level_fluctuation_db"]))
            corner_hz = float(rng.uniform(*spans["level_fluctuation_hz"]))
            fluctuation = _level_fluctuation(rng, n_samples, sample_rate_hz, std_db, corner_hz)
    else:
        raise ValueError(f"kind: unknown target kind {track.kind!r}")
    ground = {}
    if ground_factor is not None:
        ground = {"ground_factor": ground_factor, "source_height_m": np.interp(samples, coarse, pos_c[:, 2]),
                  "receiver_height_m": float(np.mean(mic_c[:, 2])),
                  "horizontal_range_m": np.interp(samples, coarse, np.linalg.norm((pos_c - mic_c)[:, :2], axis=-1))}
    received = propagate(src, ret.range_m, sample_rate_hz, air_temperature_k, relative_humidity, **ground)
    if fluctuation is not None:
        received = received * fluctuation
    return received, ret.range_m


def _level_fluctuation(rng: np.random.Generator, n: int, sample_rate_hz: float, std_db: float, corner_hz: float
                       ) -> np.ndarray:
    """Slow log-normal gain (std ``std_db`` of the level, low-passed at ``corner_hz``), unit mean square so the
    sound power stays calibrated: turbulent propagation and manoeuvres make real drone levels wander."""
    g = 10.0 ** (std_db * smooth_random(rng, n, sample_rate_hz, corner_hz) / 20.0)
    return g / max(float(np.sqrt(np.mean(g ** 2))), 1e-30)
