"""RF on the scenario timeline: complex baseband I/Q of drone links and interferers, and spectrograms.

The receiver sits at the camera rig, tuned to ``center_frequency_hz`` (2.44 GHz) with complex
sampling at ``sample_rate_hz`` (20 MS/s; its filter passes ``passband_fraction`` x fs, +-9 MHz).
Simulating 10 s at 20 MS/s would be 200 M samples, so the receiver is duty-cycled like a scanning
SDR: at the start of every 0.25 s segment it captures ``capture_samples`` samples (default 50 400 =
2.52 ms), and each capture gives one spectrogram. Each drone emits the links named in
``RFConfig.links`` (presets in :mod:`simulator.physics.rf_links`: ExpressLRS/FrSky-like hopping
control, OcuSync-like or Wi-Fi video, DroneID-like broadcast); their transmission schedules run on
the absolute clock over the whole clip and a capture holds only the bursts that overlap it in time
and land inside its passband (most 2.5 ms captures hold 0 or 1 control burst).

Received power = conducted power x antenna gains x two-ray ground-reflection path gain x small-scale
fading (Rician, block fading per hop burst / per capture for OFDM), see
:mod:`simulator.physics.propagation`. Power units: |x|^2 is milliwatts at the receiver input (so
10 log10 mean |x|^2 is dBm). Receiver noise kTB with a noise figure. Draws come from
``rng_for(seed, "rf", *indices, emitter, part)``.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.fft as sfft
from pydantic import BaseModel, ConfigDict, Field, model_validator

from scenes.kinds import DRONE_KINDS
from simulator.physics import propagation as prop
from simulator.physics import rf_links
from simulator.physics.propagation import SPEED_OF_LIGHT_MPS, free_space_path_loss_db  # noqa: F401 (re-export)
from simulator.seeding import rng_for

BOLTZMANN_J_PER_K = 1.380649e-23
NOISE_TEMPERATURE_K = 290.0
OFDM_FFT = 256                     # legacy grid of ofdm_bursts: 78.125 kHz subcarrier spacing at 20 MS/s
OFDM_CP = 64
SPECTROGRAM_PX = 112
OFDM_TAPER = 32                    # sin^2 edge window of each OFDM symbol (1.6 us at 20 MS/s); 2 x 32 <= CP keeps
                                   # an FFT window starting 32 samples into the CP untouched
RAMP_S = 10e-6                     # burst power ramp-up/down time of the hopping transmitters
_EMITTER_WIFI, _EMITTER_BT, _EMITTER_NOISE = 2, 3, 4
_PART_SCHEDULE, _PART_WAVEFORM, _PART_FADING = 0, 1, 2
# fields of the first RF model (fixed 8-channel hopping, one video link); replaced by ``links``
_LEGACY_FIELDS = ("control_channels_hz", "control_bandwidth_hz", "control_slot_s", "control_burst_s",
                  "control_eirp_dbm", "video_offset_hz", "video_bandwidth_hz", "video_eirp_dbm", "video_duty")


class RFConfig(BaseModel):
    """Receiver, propagation and emitter parameters (drone links by preset name)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    sample_rate_hz: float = Field(default=20e6, gt=0.0)
    center_frequency_hz: float = Field(default=2.44e9, gt=0.0)
    capture_samples: int = Field(default=50_400, ge=SPECTROGRAM_PX * 16)
    noise_figure_db: float = Field(default=6.0, ge=0.0, le=30.0)
    passband_fraction: float = Field(default=0.9, gt=0.0, le=1.0, description="receiver filter width / fs")
    links: tuple[str | rf_links.LinkPreset, ...] = Field(
        default=("elrs_like_250hz", "ocusync_like_10mhz"),
        description="links every drone emits: preset names (simulator.physics.rf_links) or inline presets")
    propagation: Literal["two_ray", "free_space"] = "two_ray"
    ground_polarization: Literal["vertical", "horizontal"] = "vertical"
    ground_relative_permittivity: float = Field(default=15.0, gt=0.0)
    ground_conductivity_s_per_m: float = Field(default=0.005, ge=0.0)
    fading: Literal["rician", "rayleigh", "none"] = "rician"
    rician_k_db: float = Field(default=10.0, ge=-10.0, le=40.0, description="near line-of-sight K factor")
    rx_antenna: Literal["isotropic", "dipole", "patch"] = Field(
        default="dipole", description="dipole: vertical; patch: boresight along the RGB camera's view")
    wifi_rx_dbm: float | None = -68.0
    wifi_offset_hz: float = 13e6
    wifi_duty: float = Field(default=0.3, gt=0.0, le=1.0)
    bluetooth_rx_dbm: float | None = -72.0
    spectrogram_floor_db: float = Field(default=-10.0, description="image black level, dB re noise per bin")
    spectrogram_range_db: float = Field(default=80.0, gt=0.0)
    detect_snr_db: float = Field(default=0.0, description="in-band SNR at which a link counts as observable")

    @model_validator(mode="before")
    @classmethod
    def _drop_legacy(cls, data):
        if isinstance(data, dict) and any(k in data for k in _LEGACY_FIELDS):
            old = sorted(k for k in _LEGACY_FIELDS if k in data)
            warnings.warn(f"RF config fields {old} belong to the replaced fixed-channel model and are ignored; "
                          f"drone links are now chosen by preset name in 'links'", DeprecationWarning, stacklevel=2)
            data = {k: v for k, v in data.items() if k not in _LEGACY_FIELDS}
        return data

    @model_validator(mode="after")
    def _check_links(self) -> RFConfig:
        presets = [rf_links.link_preset(x) if isinstance(x, str) else x for x in self.links]
        names = [p.name for p in presets]
        if len(set(names)) != len(names):
            raise ValueError(f"links: each link must have its own name, got {names}")
        return self

    @property
    def link_presets(self) -> list[rf_links.LinkPreset]:
        """The drone links as preset objects (names resolved)."""
        return [rf_links.link_preset(x) if isinstance(x, str) else x for x in self.links]

    @property
    def noise_dbm(self) -> float:
        """Receiver noise power over the full complex band: kTB (B = sample rate) + noise figure."""
        return 10 * np.log10(BOLTZMANN_J_PER_K * NOISE_TEMPERATURE_K * self.sample_rate_hz * 1e3) + self.noise_figure_db

    @property
    def noise_per_bin_dbm(self) -> float:
        return self.noise_dbm - 10 * np.log10(SPECTROGRAM_PX)

    @property
    def bin_hz(self) -> float:
        return self.sample_rate_hz / SPECTROGRAM_PX

    @property
    def passband_hz(self) -> tuple[float, float]:
        """Absolute low and high edge of the receiver passband."""
        half = 0.5 * self.passband_fraction * self.sample_rate_hz
        return self.center_frequency_hz - half, self.center_frequency_hz + half

    @property
    def capture_s(self) -> float:
        return self.capture_samples / self.sample_rate_hz

    def fhss_visible_fraction(self, preset: rf_links.FhssPreset) -> float:
        """Share of a hopping link's channels whose centre lies inside the passband."""
        lo, hi = self.passband_hz
        ch = preset.channels_hz
        return float(np.mean((ch >= lo) & (ch <= hi)))


def _unit_phasor(phase: np.ndarray) -> np.ndarray:
    """exp(j phase) as complex64, reducing the (float64) phase first."""
    p = np.mod(phase, 2 * np.pi).astype(np.float32)
    out = np.empty(p.shape, dtype=np.complex64)
    out.real = np.cos(p)
    out.imag = np.sin(p)
    return out


def ofdm_bursts(rng: np.random.Generator, capture_start_s: np.ndarray, n_samples: int, sample_rate_hz: float,
                offset_hz: float, bandwidth_hz: float, duty: float, burst_range_s: tuple[float, float],
                subcarrier_step: int = 1, clip_duration_s: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """Unit-power (when on) QPSK-OFDM bursts of nominal ``bandwidth_hz`` centred at ``offset_hz``.

    Subcarriers on a 256-point grid (``subcarrier_step`` x 78.125 kHz at 20 MS/s, DC nulled, those
    beyond +-0.45 fs removed by the receiver filter). Bursts of random length in ``burst_range_s``
    separated by random gaps giving the mean ``duty``; gating is per OFDM symbol (256 + 64 CP).
    """
    spacing = sample_rate_hz / OFDM_FFT
    centre_bin = round(offset_hz / spacing)
    half = round(bandwidth_hz / spacing / 2 / subcarrier_step)
    bins = centre_bin + subcarrier_step * np.concatenate([np.arange(-half, 0), np.arange(1, half + 1)])
    n_nominal = max(bins.size, 1)                     # power is shared by all nominal subcarriers
    bins = bins[np.abs(bins) < 0.45 * OFDM_FFT]
    sym_len = OFDM_FFT + OFDM_CP
    n_seg = capture_start_s.size
    n_sym = int(np.ceil(n_samples / sym_len))
    # burst schedule on the absolute clock
    mean_burst = float(np.mean(burst_range_s))
    mean_gap = mean_burst * (1 - duty) / duty
    n_bursts = int(np.ceil((clip_duration_s + 1.0) / (mean_burst + mean_gap) * 2)) + 4
    lengths = rng.uniform(*burst_range_s, size=n_bursts)
    gaps = rng.exponential(mean_gap, size=n_bursts) if duty < 1 else np.zeros(n_bursts)
    starts = np.cumsum(np.concatenate([[-rng.uniform(0, mean_burst + mean_gap)], (lengths + gaps)[:-1]]))
    sym_t = capture_start_s[:, None] + (np.arange(n_sym)[None, :] + 0.5) * sym_len / sample_rate_hz
    k = np.clip(np.searchsorted(starts, sym_t, side="right") - 1, 0, n_bursts - 1)
    on = (sym_t - starts[k]) < lengths[k]
    out = np.zeros((n_seg, n_sym, sym_len), dtype=np.complex64)
    if bins.size:
        grid = np.zeros((n_seg, n_sym, OFDM_FFT), dtype=np.complex64)
        qpsk = np.exp(1j * (np.pi / 4 + np.pi / 2 * rng.integers(0, 4, size=(n_seg, n_sym, bins.size))))
        grid[:, :, bins % OFDM_FFT] = qpsk.astype(np.complex64) * np.float32(np.sqrt(OFDM_FFT / n_nominal))
        body = sfft.ifft(grid, axis=-1, norm="ortho")
        out[:, :, OFDM_CP:] = body
        out[:, :, :OFDM_CP] = body[:, :, -OFDM_CP:]
        out *= _symbol_taper(sym_len, OFDM_TAPER)
        out *= on[:, :, None]
    gate = np.repeat(on, sym_len, axis=1)[:, :n_samples]
    return out.reshape(n_seg, -1)[:, :n_samples], gate


@dataclass
class RFCapture:
    """I/Q captures (one per segment), their spectrograms and link ground truth."""

    config: RFConfig
    capture_start_s: np.ndarray                  # (S,)
    iq: np.ndarray                               # (S, N) complex64, |x|^2 in mW
    spectrogram_dbm: np.ndarray = field(default_factory=lambda: np.zeros(0))   # (S, 112, 112)
    link_active: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # (S,) a drone link emits
    link_rx_dbm: np.ndarray = field(default_factory=lambda: np.zeros(0))        # (S,) strongest drone link budget
    control_snr_db: np.ndarray = field(default_factory=lambda: np.zeros(0))     # (S,) best control burst in capture
    video_snr_db: np.ndarray = field(default_factory=lambda: np.zeros(0))       # (S,) best video burst in capture
    # (S,) link power while on / noise, full band
    realised_snr_db: np.ndarray = field(default_factory=lambda: np.zeros(0))
    drone_range_m: np.ndarray = field(default_factory=lambda: np.zeros(0))      # (S,)
    link_snr_db: dict[str, np.ndarray] = field(default_factory=dict)        # "<target>/<link>" -> (S,) best in-band SNR
    bursts_per_capture: dict[str, np.ndarray] = field(default_factory=dict)  # "<target>/<link>" -> (S,) int
    annotations: list[dict] = field(default_factory=list)   # one per received drone burst (see sigmf_metadata)

    @property
    def observable(self) -> np.ndarray:
        """A drone link is on and at least one burst in the capture reaches ``detect_snr_db`` in its band."""
        best = np.full(self.capture_start_s.size, -np.inf)
        for snr in self.link_snr_db.values():
            best = np.maximum(best, snr)
        best = np.maximum(best, np.maximum(self.control_snr_db, self.video_snr_db))
        return self.link_active & (best >= self.config.detect_snr_db)

    def sigmf_metadata(self) -> dict:
        """SigMF-style metadata for the captures written back to back (cf32_le, sample index s x N).

        ``global``: sample rate, datatype; ``captures``: one per capture with its sample start,
        centre frequency and start time on the clip clock (``evids:start_s``); ``annotations``:
        one per received drone burst (sample start/count, absolute frequency edges, link, SNR).
        Keys in the ``evids:`` namespace are declared as an optional extension. The formats layer
        adds ``core:version``, file names and datetimes.
        """
        cfg, n = self.config, self.iq.shape[-1] if self.iq.ndim else 0
        return {
            "global": {"core:datatype": "cf32_le", "core:sample_rate": cfg.sample_rate_hz,
                       "core:extensions": [{"name": "evids", "version": "1.0.0", "optional": True}],
                       "core:description": "evids synthetic drone RF captures (duty-cycled receiver)",
                       "evids:noise_dbm": round(cfg.noise_dbm, 3), "evids:links": [p.name for p in cfg.link_presets]},
            "captures": [{"core:sample_start": int(s * n), "core:frequency": cfg.center_frequency_hz,
                          "evids:start_s": float(t)} for s, t in enumerate(self.capture_start_s)],
            "annotations": [dict(a) for a in self.annotations],
        }


def spectrogram_dbm(iq: np.ndarray, sample_rate_hz: float, px: int = SPECTROGRAM_PX) -> np.ndarray:
    """(S, px, px) power per time-frequency cell in dBm; rows = frequency (row 0 = +fs/2), cols = time.

    Each capture is cut into ``px`` non-overlapping frames (Hann window), zero-padded to a multiple
    of ``px`` points, FFT-shifted, and adjacent bins summed into ``px`` bands of fs/px. Normalised
    by nfft * sum(w^2) so a cell holds the signal power in its band (white noise of power P reads
    P / px in every cell).
    """
    x = np.atleast_2d(iq)
    frame = x.shape[1] // px
    if frame < 16:
        raise ValueError(f"capture_samples must be >= {16 * px} for a {px}-column spectrogram, got {x.shape[1]}")
    nfft = px * int(np.ceil(frame / px))
    window = np.hanning(frame + 2)[1:-1].astype(np.float32)
    frames = x[:, : frame * px].reshape(x.shape[0], px, frame) * window
    spec = np.abs(sfft.fftshift(sfft.fft(frames, n=nfft, axis=-1), axes=-1)) ** 2
    pooled = spec.reshape(x.shape[0], px, px, nfft // px).sum(-1) / (nfft
                                                                     * float(np.sum(window.astype(np.float64) ** 2)))
    return 10 * np.log10(np.maximum(pooled, 1e-30)).transpose(0, 2, 1)[:, ::-1, :].astype(np.float32)


def spectrogram_image(spec_dbm: np.ndarray, config: RFConfig) -> np.ndarray:
    """uint8 image: 0 at noise-per-bin + floor_db, 255 at floor_db + range_db above that (clipped)."""
    lo = config.noise_per_bin_dbm + config.spectrogram_floor_db
    scaled = (np.asarray(spec_dbm, dtype=np.float64) - lo) / config.spectrogram_range_db
    return np.round(np.clip(scaled, 0.0, 1.0) * 255).astype(np.uint8)


# --------------------------------------------------------------------------------------------
# Burst waveforms (unit power while on)
# --------------------------------------------------------------------------------------------

def lora_chirps(rng: np.random.Generator, t_in_burst_s: np.ndarray, sample_rate_hz: float, offset_hz: float,
                bandwidth_hz: float, spreading_factor: int) -> np.ndarray:
    """LoRa-like chirp spread spectrum: up-chirps sweeping ``bandwidth_hz`` in 2^SF / BW, each
    cyclically shifted by a random symbol value; symbols aligned to the burst start."""
    symbol_s = 2 ** spreading_factor / bandwidth_hz
    pos = np.asarray(t_in_burst_s, dtype=np.float64) / symbol_s
    sym = np.floor(pos).astype(np.int64)
    first = int(sym.min()) if sym.size else 0
    values = rng.integers(0, 2 ** spreading_factor, size=int(sym.max()) - first + 1 if sym.size else 0)
    u = np.mod(pos - sym + values[sym - first] / 2 ** spreading_factor, 1.0)
    inst_hz = offset_hz + bandwidth_hz * (u - 0.5)
    phase = 2 * np.pi * np.cumsum(inst_hz) / sample_rate_hz + 2 * np.pi * rng.random()
    return _unit_phasor(phase)


def gfsk_burst(rng: np.random.Generator, n_samples: int, sample_rate_hz: float, offset_hz: float,
               symbol_rate_hz: float) -> np.ndarray:
    """Binary CPFSK (h = 0.5) with linear frequency transitions between symbols (GFSK-like)."""
    sps = sample_rate_hz / symbol_rate_hz
    n_sym = int(np.ceil(n_samples / sps)) + 2
    bits = rng.integers(0, 2, size=n_sym).astype(np.float64) * 2 - 1
    pos = np.arange(n_samples) / sps
    idx = pos.astype(np.int64)
    frac = pos - idx
    nrz = bits[idx] * (1 - frac) + bits[idx + 1] * frac
    inst_hz = offset_hz + 0.25 * symbol_rate_hz * nrz
    phase = 2 * np.pi * np.cumsum(inst_hz) / sample_rate_hz + 2 * np.pi * rng.random()
    return _unit_phasor(phase)


def ofdm_waveform(rng: np.random.Generator, n_rows: int, n_samples: int, sample_rate_hz: float, offset_hz: float,
                  bandwidth_hz: float, subcarrier_spacing_hz: float, cp_fraction: float,
                  passband_half_hz: float) -> tuple[np.ndarray, float]:
    """Continuous QPSK-OFDM rows (n_rows, n_samples) of nominal ``bandwidth_hz`` at ``offset_hz``.

    FFT size round(fs / spacing) (1333 at 20 MS/s for 15 kHz: 15.004 kHz), cyclic prefix
    ``cp_fraction`` of it, DC nulled. Unit power when the whole band is received; subcarriers
    outside the receiver passband are dropped, so the power is the received fraction (returned).
    """
    fft = max(round(sample_rate_hz / subcarrier_spacing_hz), 16)
    cp = round(cp_fraction * fft)
    spacing = sample_rate_hz / fft
    centre_bin = round(offset_hz / spacing)
    half = max(round(bandwidth_hz / spacing / 2), 1)
    bins = centre_bin + np.concatenate([np.arange(-half, 0), np.arange(1, half + 1)])
    n_nominal = bins.size
    bins = bins[np.abs(bins * spacing) < passband_half_hz]
    sym_len = fft + cp
    n_sym = int(np.ceil(n_samples / sym_len))
    out = np.zeros((n_rows, n_sym, sym_len), dtype=np.complex64)
    if bins.size and n_rows:
        grid = np.zeros((n_rows, n_sym, fft), dtype=np.complex64)
        qpsk = np.exp(1j * (np.pi / 4 + np.pi / 2 * rng.integers(0, 4, size=(n_rows, n_sym, bins.size))))
        grid[:, :, bins % fft] = qpsk.astype(np.complex64) * np.float32(np.sqrt(fft / n_nominal))
        body = sfft.ifft(grid, axis=-1, norm="ortho")
        out[:, :, cp:] = body
        out[:, :, :cp] = body[:, :, fft - cp:]
        # transmit windowing: sin^2 edges over part of the CP keep the symbol joins from splattering
        # out of band (as real OFDM transmitters shape to meet their spectral mask)
        taper = _symbol_taper(sym_len, min(OFDM_TAPER, cp // 2))
        out *= taper
    return out.reshape(n_rows, -1)[:, :n_samples], bins.size / n_nominal


def _symbol_taper(length: int, edge: int) -> np.ndarray:
    """Unit-mean-power window with sin^2 ramps of ``edge`` samples at both ends of an OFDM symbol."""
    w = np.ones(length)
    if edge > 0:
        ramp = np.sin(0.5 * np.pi * (np.arange(edge) + 0.5) / edge) ** 2
        w[:edge] = ramp
        w[length - edge:] = ramp[::-1]
    return (w / np.sqrt(np.mean(w ** 2))).astype(np.float32)


def _ramp(t_in_burst_s: np.ndarray, duration_s: float) -> np.ndarray:
    """sin^2 power ramp of RAMP_S at both burst edges (limits the splatter of hard keying)."""
    ramp = np.clip(np.minimum(t_in_burst_s, duration_s - t_in_burst_s) / RAMP_S, 0.0, 1.0)
    return (np.sin(0.5 * np.pi * ramp) ** 2).astype(np.float32)


# --------------------------------------------------------------------------------------------
# Geometry and channel
# --------------------------------------------------------------------------------------------

@dataclass
class _Geometry:
    tx_m: np.ndarray          # (S, 3) drone position at capture start
    rx_m: np.ndarray          # (S, 3) receiver (camera rig)
    tx_axis: np.ndarray       # (S, 3) drone body up (the dipole's element)
    rx_axis: np.ndarray       # (S, 3) receiver antenna axis (dipole: vertical; patch: camera view)

    @property
    def range_m(self) -> np.ndarray:
        return np.linalg.norm(self.tx_m - self.rx_m, axis=-1)


def _geometry(timeline, track, starts: np.ndarray, rx_antenna: str) -> _Geometry:
    times = np.asarray(timeline.times_s, dtype=np.float64)
    mic = np.asarray(timeline.microphone_position_m, dtype=np.float64)
    rx = np.stack([np.interp(starts, times, mic[:, k]) for k in range(3)], -1)
    frame = np.clip(np.round(np.interp(starts, times, np.arange(times.size))).astype(int), 0, times.size - 1)
    up = np.tile([0.0, 0.0, 1.0], (starts.size, 1))
    rotation = getattr(track, "rotation", None)
    tx_axis = np.asarray(rotation)[frame][:, :, 2] if rotation is not None else up
    rx_axis = up
    cameras = getattr(timeline, "cameras", None)
    if rx_antenna == "patch" and cameras and "rgb" in cameras:
        rx_axis = np.asarray(cameras["rgb"].forward)[frame]
    return _Geometry(track.position_at(starts, times), rx, tx_axis, rx_axis)


def _path_gain(cfg: RFConfig, geo: _Geometry, rows: np.ndarray, frequency_hz: np.ndarray,
               tx_antenna: str) -> np.ndarray:
    """Linear path gain incl. antenna patterns for captures ``rows`` at ``frequency_hz`` (same shape)."""
    reflection = cfg.ground_polarization if cfg.propagation == "two_ray" else "none"
    return prop.two_ray_path_gain(geo.tx_m[rows], geo.rx_m[rows], frequency_hz, tx_antenna=tx_antenna,
                                  tx_axis=geo.tx_axis[rows], rx_antenna=cfg.rx_antenna, rx_axis=geo.rx_axis[rows],
                                  reflection=reflection, relative_permittivity=cfg.ground_relative_permittivity,
                                  conductivity_s_per_m=cfg.ground_conductivity_s_per_m)


def _fading(cfg: RFConfig, rng: np.random.Generator, size: int) -> np.ndarray:
    if cfg.fading == "none":
        return np.ones(size, dtype=np.complex128)
    return prop.rician_gains(rng, size, None if cfg.fading == "rayleigh" else cfg.rician_k_db)


@dataclass
class _LinkResult:
    signal: np.ndarray         # (S, N) complex64
    on: np.ndarray             # (S, N) bool
    bursts: np.ndarray         # (S,) int, received bursts per capture
    snr_db: np.ndarray         # (S,) best in-band SNR of a received burst, -inf if none
    budget_dbm: np.ndarray     # (S,) mean received power (no fading) at the link's band centre
    annotations: list[dict]


def _annotation(cfg: RFConfig, label: str, role: str, sample_start: int, count: int, centre_hz: float,
                bandwidth_hz: float, snr_db: float) -> dict:
    lo, hi = cfg.passband_hz
    return {"core:sample_start": int(sample_start), "core:sample_count": int(count),
            "core:freq_lower_edge": float(max(centre_hz - bandwidth_hz / 2, lo)),
            "core:freq_upper_edge": float(min(centre_hz + bandwidth_hz / 2, hi)),
            "core:label": label, "evids:role": role, "evids:snr_db": round(float(snr_db), 2)}


def _write_burst(row: np.ndarray, cfg: RFConfig, preset: rf_links.FhssPreset, rng: np.random.Generator,
                 capture_start_s: float, start_s: float, duration_s: float, centre_hz: float,
                 amplitude: complex) -> tuple[int, int] | None:
    """Add one hop burst (its part inside the capture) to ``row``; returns its sample span or None."""
    fs, n = cfg.sample_rate_hz, row.size
    a = max(0, int(np.ceil((start_s - capture_start_s) * fs)))
    e = min(n, int(np.ceil((start_s + duration_s - capture_start_s) * fs)))
    if e <= a:
        return None
    t_in = (np.arange(a, e) / fs + capture_start_s) - start_s
    offset = centre_hz - cfg.center_frequency_hz
    if preset.modulation == "lora":
        wave = lora_chirps(rng, t_in, fs, offset, preset.occupied_bandwidth_hz, preset.spreading_factor)
    elif preset.modulation == "gfsk":
        wave = gfsk_burst(rng, e - a, fs, offset, preset.symbol_rate_hz)
    else:
        wave = ofdm_waveform(rng, 1, e - a, fs, offset, preset.occupied_bandwidth_hz, preset.subcarrier_spacing_hz,
                             144 / 2048, 0.5 * cfg.passband_fraction * fs)[0][0]
    row[a:e] += wave * _ramp(t_in, duration_s) * np.complex64(amplitude)
    return a, e


def _background_fhss(cfg: RFConfig, preset: rf_links.FhssPreset, rx_dbm: float, starts: np.ndarray,
                     duration_s: float, rng: np.random.Generator, iq: np.ndarray) -> None:
    """Add a hopping interferer received at a fixed power (e.g. Bluetooth) to ``iq`` in place."""
    sched = rf_links.fhss_schedule(preset, rng, duration_s)
    lo, hi = cfg.passband_hz
    visible = (sched.centre_hz >= lo) & (sched.centre_hz <= hi)
    amp = np.sqrt(10 ** (rx_dbm / 10))
    for s, idx in enumerate(rf_links.bursts_in_windows(sched, starts, cfg.capture_s)):
        for b in idx[visible[idx]]:
            _write_burst(iq[s], cfg, preset, rng, starts[s], sched.start_s[b], sched.duration_s[b], sched.centre_hz[b],
                         amp)


def _fhss_link(cfg: RFConfig, preset: rf_links.FhssPreset, geo: _Geometry, starts: np.ndarray, duration_s: float,
               rngs: tuple[np.random.Generator, ...], label: str) -> _LinkResult:
    g_sched, g_wave, g_fade = rngs
    n, fs, n_seg = cfg.capture_samples, cfg.sample_rate_hz, starts.size
    sched = rf_links.fhss_schedule(preset, g_sched, duration_s)
    lo, hi = cfg.passband_hz
    if preset.modulation == "ofdm":
        visible = rf_links.band_overlap_fraction(sched.centre_hz, sched.bandwidth_hz, lo, hi) > 0
    else:
        visible = (sched.centre_hz >= lo) & (sched.centre_hz <= hi)
    fades = _fading(cfg, g_fade, sched.start_s.size)          # one block-fading gain per burst (per hop)
    p_tx_mw = 10 ** (preset.tx_power_dbm / 10)
    noise_mw = 10 ** (cfg.noise_dbm / 10)
    sig = np.zeros((n_seg, n), dtype=np.complex64)
    on = np.zeros((n_seg, n), dtype=bool)
    bursts = np.zeros(n_seg, dtype=np.int64)
    snr = np.full(n_seg, -np.inf)
    notes: list[dict] = []
    budget = 10 * np.log10(p_tx_mw * _path_gain(cfg, geo, np.arange(n_seg), np.full(n_seg, cfg.center_frequency_hz),
                                                preset.tx_antenna))
    for s, idx in enumerate(rf_links.bursts_in_windows(sched, starts, cfg.capture_s)):
        idx = idx[visible[idx]]
        if not idx.size:
            continue
        p_rx = p_tx_mw * _path_gain(cfg, geo, np.full(idx.size, s), sched.centre_hz[idx], preset.tx_antenna)
        for j, b in enumerate(idx):
            span = _write_burst(sig[s], cfg, preset, g_wave, starts[s], sched.start_s[b], sched.duration_s[b],
                                sched.centre_hz[b], np.sqrt(p_rx[j]) * fades[b])
            if span is None:
                continue
            a, e = span
            bursts[s] += 1
            on[s, a:e] = True
            burst_snr = 10 * np.log10(max(p_rx[j] * abs(fades[b]) ** 2, 1e-300)
                                      / (noise_mw * preset.occupied_bandwidth_hz / fs))
            snr[s] = max(snr[s], burst_snr)
            notes.append(_annotation(cfg, label, preset.role, s * n + a, e - a, sched.centre_hz[b],
                                     preset.occupied_bandwidth_hz, burst_snr))
    return _LinkResult(sig, on, bursts, snr, budget, notes)


def _ofdm_link(cfg: RFConfig, preset: rf_links.OfdmPreset, geo: _Geometry, starts: np.ndarray, duration_s: float,
               rngs: tuple[np.random.Generator, ...], label: str) -> _LinkResult:
    g_sched, g_wave, g_fade = rngs
    n, fs, n_seg = cfg.capture_samples, cfg.sample_rate_hz, starts.size
    sched = rf_links.ofdm_schedule(preset, g_sched, duration_s)
    lo, hi = cfg.passband_hz
    centre = float(sched.centre_hz[0])
    band_frac = float(rf_links.band_overlap_fraction(centre, preset.bandwidth_hz, lo, hi))
    fades = _fading(cfg, g_fade, n_seg)                        # block fading per capture (2.5 ms < coherence time)
    p_tx_mw = 10 ** (preset.tx_power_dbm / 10)
    noise_mw = 10 ** (cfg.noise_dbm / 10)
    gain = _path_gain(cfg, geo, np.arange(n_seg), np.full(n_seg, centre), preset.tx_antenna)
    on = np.zeros((n_seg, n), dtype=bool)
    bursts = np.zeros(n_seg, dtype=np.int64)
    spans: list[tuple[int, int, int, float, float]] = []
    if band_frac > 0:
        for s, idx in enumerate(rf_links.bursts_in_windows(sched, starts, cfg.capture_s)):
            for b in idx:
                a = max(0, int(np.ceil((sched.start_s[b] - starts[s]) * fs)))
                e = min(n, int(np.ceil((sched.start_s[b] + sched.duration_s[b] - starts[s]) * fs)))
                if e > a:
                    on[s, a:e] = True
                    bursts[s] += 1
                    spans.append((s, a, e, float(sched.start_s[b]), float(sched.duration_s[b])))
    sig = np.zeros((n_seg, n), dtype=np.complex64)
    rows = np.nonzero(bursts)[0]
    if rows.size:
        wave, _ = ofdm_waveform(g_wave, rows.size, n, fs, centre - cfg.center_frequency_hz, preset.bandwidth_hz,
                                preset.subcarrier_spacing_hz, preset.cp_fraction, 0.5 * cfg.passband_fraction * fs)
        amp = (np.sqrt(p_tx_mw * gain[rows]) * fades[rows]).astype(np.complex64)
        envelope = np.zeros((n_seg, n), dtype=np.float32)
        for s, a, e, t0, dur in spans:
            t_in = (np.arange(a, e) / fs + starts[s]) - t0
            envelope[s, a:e] = np.maximum(envelope[s, a:e], _ramp(t_in, dur))
        sig[rows] = wave * envelope[rows] * amp[:, None]
    snr_all = 10 * np.log10(np.maximum(p_tx_mw * gain * np.abs(fades) ** 2, 1e-300)
                            / (noise_mw * preset.bandwidth_hz / fs))
    snr = np.where(bursts > 0, snr_all, -np.inf)
    notes = [_annotation(cfg, label, preset.role, s * n + a, e - a, centre, preset.bandwidth_hz, snr_all[s])
             for s, a, e, _, _ in spans]
    return _LinkResult(sig, on, bursts, snr, 10 * np.log10(p_tx_mw * gain), notes)


def synthesize_rf(timeline, seed: int, capture_start_s: np.ndarray, *, config: RFConfig | None = None,
                  rf_silent: bool = False, stream_indices: tuple[int, ...] = (),
                  clip_duration_s: float | None = None) -> RFCapture:
    """Capture I/Q at each ``capture_start_s`` from the timeline's drones and the background emitters.

    Every drone target (quad/hexa/fixed-wing) emits ``config.links`` unless ``rf_silent``
    (autonomous flight, radio off); birds and airliners emit nothing. Drone i, link k draws from
    ``rng_for(seed, "rf", *stream_indices, 100 (i + 1) + k, part)`` (part 0 schedule, 1 waveform,
    2 fading), so changing the channel model never moves a hop sequence.
    """
    cfg = config or RFConfig()
    starts = np.atleast_1d(np.asarray(capture_start_s, dtype=np.float64))
    if starts.size and np.min(starts) < 0:
        raise ValueError(f"capture_start_s must be >= 0, got min {np.min(starts)}")
    duration = float(clip_duration_s if clip_duration_s is not None else (starts.max() + 1.0 if starts.size else 1.0))
    n, fs, n_seg = cfg.capture_samples, cfg.sample_rate_hz, starts.size
    noise_mw = 10 ** (cfg.noise_dbm / 10)
    g = rng_for(seed, "rf", *stream_indices, _EMITTER_NOISE)
    iq = g.standard_normal((n_seg, n, 2), dtype=np.float32).view(np.complex64)[..., 0]
    iq *= np.float32(np.sqrt(noise_mw / 2))
    link_active = np.zeros(n_seg, bool)
    link_dbm = np.full(n_seg, -np.inf)
    ctrl_snr = np.full(n_seg, -np.inf)
    video_snr = np.full(n_seg, -np.inf)
    realised = np.full(n_seg, -np.inf)
    drone_range = np.full(n_seg, np.nan)
    per_link_snr: dict[str, np.ndarray] = {}
    per_link_bursts: dict[str, np.ndarray] = {}
    notes: list[dict] = []
    for index, track in enumerate(timeline.targets):
        if track.kind not in DRONE_KINDS:
            continue
        geo = _geometry(timeline, track, starts, cfg.rx_antenna)
        range_m = geo.range_m
        drone_range = np.where(np.isnan(drone_range), range_m, np.minimum(drone_range, range_m))
        if rf_silent:
            continue
        link = np.zeros((n_seg, n), dtype=np.complex64)
        on = np.zeros((n_seg, n), dtype=bool)
        for k, preset in enumerate(cfg.link_presets):
            name = preset.name
            rngs = tuple(rng_for(seed, "rf", *stream_indices, 100 * (index + 1) + k, part)
                         for part in (_PART_SCHEDULE, _PART_WAVEFORM, _PART_FADING))
            label = f"{track.name}/{name}"
            if isinstance(preset, rf_links.FhssPreset):
                res = _fhss_link(cfg, preset, geo, starts, duration, rngs, label)
            else:
                res = _ofdm_link(cfg, preset, geo, starts, duration, rngs, label)
            link += res.signal
            on |= res.on
            per_link_snr[label] = res.snr_db
            per_link_bursts[label] = res.bursts
            notes.extend(res.annotations)
            link_dbm = np.maximum(link_dbm, res.budget_dbm)
            if preset.role == "control":
                ctrl_snr = np.maximum(ctrl_snr, res.snr_db)
            elif preset.role == "video":
                video_snr = np.maximum(video_snr, res.snr_db)
        n_on = np.sum(on, axis=1)
        p_on = np.sum(np.abs(link.astype(np.complex128)) ** 2 * on, axis=1) / np.maximum(n_on, 1)
        realised = np.maximum(realised, np.where(n_on > 0, 10 * np.log10(np.maximum(p_on, 1e-300) / noise_mw), -np.inf))
        iq += link
        link_active[:] = True
    if cfg.wifi_rx_dbm is not None:
        wifi, _ = ofdm_bursts(rng_for(seed, "rf", *stream_indices, _EMITTER_WIFI), starts, n, fs, cfg.wifi_offset_hz,
                              16.6e6, cfg.wifi_duty, (0.2e-3, 2.0e-3), subcarrier_step=4, clip_duration_s=duration)
        # rx power refers to the whole 20 MHz channel; the receiver only passes the part in its window
        iq += wifi * np.float32(np.sqrt(10 ** (cfg.wifi_rx_dbm / 10)))
    if cfg.bluetooth_rx_dbm is not None:
        _background_fhss(cfg, rf_links.BLUETOOTH, cfg.bluetooth_rx_dbm, starts, duration,
                         rng_for(seed, "rf", *stream_indices, _EMITTER_BT), iq)
    notes.sort(key=lambda a: (a["core:sample_start"], a["core:label"]))
    return RFCapture(config=cfg, capture_start_s=starts, iq=iq, spectrogram_dbm=spectrogram_dbm(iq, fs),
                     link_active=link_active, link_rx_dbm=link_dbm, control_snr_db=ctrl_snr,
                     video_snr_db=video_snr, realised_snr_db=realised, drone_range_m=drone_range,
                     link_snr_db=per_link_snr, bursts_per_capture=per_link_bursts, annotations=notes)
