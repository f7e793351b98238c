"""RF on the scenario timeline: complex baseband I/Q of drone links and interferers, and spectrograms.

The receiver sits at the camera rig, tuned to ``center_frequency_hz`` (2.44 GHz) with complex
sampling at ``sample_rate_hz`` (20 MS/s, so the window spans +-10 MHz). Simulating 10 s at
20 MS/s would be 200 M samples, so the receiver is duty-cycled like a scanning SDR: at the start
of every 0.25 s segment it captures ``capture_samples`` samples (default 50 400 = 2.52 ms), and
each capture gives one spectrogram. Signals are generated on the absolute clock, so burst
schedules and hop sequences are continuous across captures.

Power units: |x|^2 is milliwatts at the receiver input (so 10 log10 mean |x|^2 is dBm).
Emitters: drone control link (frequency-hopping GFSK-like bursts on declared channels), drone
video downlink (bursty OFDM of nominal bandwidth), Wi-Fi (OFDM 20 MHz channel, CSMA-like packets)
and Bluetooth (79-channel hopping, 1600 hops/s). Free-space path loss from range; receiver noise
kTB with a noise figure. Draws come from ``rng_for(seed, "rf", *indices, emitter)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.fft as sfft
from pydantic import BaseModel, ConfigDict, Field, model_validator

from simulator.seeding import rng_for

BOLTZMANN_J_PER_K = 1.380649e-23
NOISE_TEMPERATURE_K = 290.0
SPEED_OF_LIGHT_MPS = 299_792_458.0
OFDM_FFT = 256                     # 78.125 kHz subcarrier spacing at 20 MS/s
OFDM_CP = 64
SPECTROGRAM_PX = 112
RAMP_S = 10e-6                     # burst power ramp-up/down time of the hopping transmitters
DRONE_KINDS = ("quadcopter", "hexacopter", "fixed_wing")
_EMITTER_CONTROL, _EMITTER_VIDEO, _EMITTER_WIFI, _EMITTER_BT, _EMITTER_NOISE = 0, 1, 2, 3, 4
BT_CHANNELS_HZ = tuple(2402e6 + 1e6 * k for k in range(79))


class RFConfig(BaseModel):
    """Receiver and emitter parameters; frequencies of channels are offsets from the centre (Hz)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    sample_rate_hz: float = Field(default=20e6, gt=0.0)
    center_frequency_hz: float = Field(default=2.44e9, gt=0.0)
    capture_samples: int = Field(default=50_400, ge=SPECTROGRAM_PX * 16)
    noise_figure_db: float = Field(default=6.0, ge=0.0, le=30.0)
    control_channels_hz: tuple[float, ...] = (-7e6, -5e6, -3e6, -1e6, 1e6, 3e6, 5e6, 7e6)
    control_bandwidth_hz: float = Field(default=1e6, gt=0.0)
    control_slot_s: float = Field(default=0.5e-3, gt=0.0)
    control_burst_s: float = Field(default=0.25e-3, gt=0.0)
    control_eirp_dbm: float = 20.0
    video_offset_hz: float = 0.0
    video_bandwidth_hz: float = Field(default=10e6, gt=0.0)
    video_eirp_dbm: float = 23.0
    video_duty: float = Field(default=0.7, gt=0.0, le=1.0)
    wifi_rx_dbm: float | None = -68.0
    wifi_offset_hz: float = 13e6
    wifi_duty: float = Field(default=0.3, gt=0.0, le=1.0)
    bluetooth_rx_dbm: float | None = -72.0
    spectrogram_floor_db: float = Field(default=-10.0, description="image black level, dB re noise per bin")
    spectrogram_range_db: float = Field(default=80.0, gt=0.0)
    detect_snr_db: float = Field(default=0.0, description="in-band SNR at which a link counts as observable")

    @model_validator(mode="after")
    def _nyquist(self) -> "RFConfig":
        if self.control_burst_s > self.control_slot_s:
            raise ValueError(f"control_burst_s ({self.control_burst_s}) must be <= control_slot_s ({self.control_slot_s})")
        edges = [abs(c) + self.control_bandwidth_hz / 2 for c in self.control_channels_hz]
        edges.append(abs(self.video_offset_hz) + self.video_bandwidth_hz / 2)
        if self.sample_rate_hz < 2 * max(edges):
            raise ValueError(f"sample_rate_hz {self.sample_rate_hz:.6g} is below twice the highest band edge "
                             f"{max(edges):.6g} Hz of the declared drone channels")
        if not self.control_channels_hz:
            raise ValueError("control_channels_hz must declare at least one channel")
        return self

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


def free_space_path_loss_db(range_m: np.ndarray | float, frequency_hz: float) -> np.ndarray:
    """Friis free-space loss 20 log10(4 pi d f / c), isotropic antennas; range clamped to >= 1 m."""
    r = np.asarray(range_m, dtype=np.float64)
    if r.size and (not np.all(np.isfinite(r)) or np.min(r) < 0):
        raise ValueError(f"range_m must be finite and >= 0, got min {np.nanmin(r):.6g}")
    if not frequency_hz > 0:
        raise ValueError(f"frequency_hz must be > 0, got {frequency_hz}")
    return 20 * np.log10(4 * np.pi * np.maximum(r, 1.0) * frequency_hz / SPEED_OF_LIGHT_MPS)


def _unit_phasor(phase: np.ndarray) -> np.ndarray:
    """exp(j phase) as complex64, reducing the (float64) phase first."""
    p = np.mod(phase, 2 * np.pi).astype(np.float32)
    out = np.empty(p.shape, dtype=np.complex64)
    out.real = np.cos(p)
    out.imag = np.sin(p)
    return out


def fhss_bursts(rng: np.random.Generator, capture_start_s: np.ndarray, n_samples: int, sample_rate_hz: float,
                channels_hz: np.ndarray, slot_s: float, burst_s: float, symbol_rate_hz: float,
                occupancy: float = 1.0, clip_duration_s: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """Unit-power frequency-hopping CPFSK bursts (h = 0.5, linear frequency transitions, 10 us ramps).

    One burst of ``burst_s`` at the start of every ``slot_s`` slot, on a channel drawn per slot
    (a slot is used with probability ``occupancy``). Returns the (S, N) complex64 signal and the
    (S, N) bool burst gate. Channels outside the sampled band are not received (gate off).
    """
    n_slots = int(np.ceil((clip_duration_s + 1.0) / slot_s))
    hop = rng.integers(0, len(channels_hz), size=n_slots)
    used = rng.random(n_slots) < occupancy
    t = capture_start_s[:, None] + np.arange(n_samples)[None, :] / sample_rate_hz
    slot = np.minimum((t / slot_s).astype(np.int64), n_slots - 1)
    channel = np.asarray(channels_hz, dtype=np.float64)[hop[slot]]
    in_band = np.abs(channel) < 0.5 * sample_rate_hz - symbol_rate_hz
    in_slot = t - slot * slot_s
    gate = (in_slot < burst_s) & used[slot] & in_band
    # raised-cosine power ramp at each burst edge (as transmitters do) limits spectral splatter
    ramp = np.clip(np.minimum(in_slot, burst_s - in_slot) / RAMP_S, 0.0, 1.0)
    envelope = np.sin(0.5 * np.pi * ramp).astype(np.float32) ** 2
    sps = sample_rate_hz / symbol_rate_hz
    n_sym = int(np.ceil(n_samples / sps)) + 2
    bits = rng.integers(0, 2, size=(capture_start_s.size, n_sym)).astype(np.float32) * 2 - 1
    # linear transitions between symbol values = NRZ convolved with a one-symbol boxcar
    sym_pos = np.arange(n_samples) / sps
    idx = sym_pos.astype(np.int64)
    frac = (sym_pos - idx).astype(np.float32)
    nrz = bits[:, idx] * (1 - frac) + bits[:, idx + 1] * frac
    deviation_hz = 0.25 * symbol_rate_hz                      # modulation index 0.5
    inst_hz = channel + deviation_hz * nrz
    phase = 2 * np.pi * np.cumsum(inst_hz, axis=1) / sample_rate_hz
    phase += 2 * np.pi * rng.random((capture_start_s.size, 1))
    sig = np.zeros(gate.shape, dtype=np.complex64)
    sig[gate] = _unit_phasor(phase[gate]) * envelope[gate]      # only burst samples need a phasor
    return sig, gate


def ofdm_bursts(rng: np.random.Generator, capture_start_s: np.ndarray, n_samples: int, sample_rate_hz: float,
                offset_hz: float, bandwidth_hz: float, duty: float, burst_range_s: tuple[float, float],
                subcarrier_step: int = 1, clip_duration_s: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """Unit-power (when on) QPSK-OFDM bursts of nominal ``bandwidth_hz`` centred at ``offset_hz``.

    Subcarriers on a 256-point grid (``subcarrier_step`` x 78.125 kHz at 20 MS/s, DC nulled, those
    beyond +-0.45 fs removed by the receiver filter). Bursts of random length in ``burst_range_s``
    separated by random gaps giving the mean ``duty``; gating is per OFDM symbol (256 + 64 CP).
    """
    spacing = sample_rate_hz / OFDM_FFT
    centre_bin = int(round(offset_hz / spacing))
    half = int(round(bandwidth_hz / spacing / 2 / subcarrier_step))
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
    link_rx_dbm: np.ndarray = field(default_factory=lambda: np.zeros(0))        # (S,) strongest drone, video link
    control_snr_db: np.ndarray = field(default_factory=lambda: np.zeros(0))     # (S,) in-band (control bw)
    video_snr_db: np.ndarray = field(default_factory=lambda: np.zeros(0))       # (S,) in-band (video bw)
    realised_snr_db: np.ndarray = field(default_factory=lambda: np.zeros(0))    # (S,) link power while on / noise, full band
    drone_range_m: np.ndarray = field(default_factory=lambda: np.zeros(0))      # (S,)

    @property
    def observable(self) -> np.ndarray:
        """A drone link is on and at least one of its links reaches ``detect_snr_db`` in its own band."""
        best = np.maximum(self.control_snr_db, self.video_snr_db)
        return self.link_active & (best >= self.config.detect_snr_db)


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
    pooled = spec.reshape(x.shape[0], px, px, nfft // px).sum(-1) / (nfft * float(np.sum(window.astype(np.float64) ** 2)))
    return 10 * np.log10(np.maximum(pooled, 1e-30)).transpose(0, 2, 1)[:, ::-1, :].astype(np.float32)


def spectrogram_image(spec_dbm: np.ndarray, config: RFConfig) -> np.ndarray:
    """uint8 image: 0 at noise-per-bin + floor_db, 255 at floor_db + range_db above that (clipped)."""
    lo = config.noise_per_bin_dbm + config.spectrogram_floor_db
    scaled = (np.asarray(spec_dbm, dtype=np.float64) - lo) / config.spectrogram_range_db
    return np.round(np.clip(scaled, 0.0, 1.0) * 255).astype(np.uint8)


def synthesize_rf(timeline, seed: int, capture_start_s: np.ndarray, *, config: RFConfig | None = None,
                  rf_silent: bool = False, stream_indices: tuple[int, ...] = (),
                  clip_duration_s: float | None = None) -> RFCapture:
    """Capture I/Q at each ``capture_start_s`` from the timeline's drones and the background emitters.

    Every drone target (quad/hexa/fixed-wing) emits the control and video links unless
    ``rf_silent`` (autonomous flight, radio off); birds and airliners emit nothing. Received power
    = EIRP - free-space path loss at the range at capture start (the receiver is at the camera rig).
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
    times = np.asarray(timeline.times_s, dtype=np.float64)
    mic = np.asarray(timeline.microphone_position_m, dtype=np.float64)
    link_active = np.zeros(n_seg, bool)
    link_dbm = np.full(n_seg, -np.inf)
    ctrl_snr = np.full(n_seg, -np.inf)
    video_snr = np.full(n_seg, -np.inf)
    realised = np.full(n_seg, -np.inf)
    drone_range = np.full(n_seg, np.nan)
    channels = np.asarray(cfg.control_channels_hz)
    for index, track in enumerate(timeline.targets):
        if track.kind not in DRONE_KINDS:
            continue
        pos = track.position_at(starts, times)
        mic_at = np.stack([np.interp(starts, times, mic[:, k]) for k in range(3)], -1)
        range_m = np.linalg.norm(pos - mic_at, axis=-1)
        drone_range = np.where(np.isnan(drone_range), range_m, np.minimum(drone_range, range_m))
        if rf_silent:
            continue
        loss = free_space_path_loss_db(range_m, cfg.center_frequency_hz)
        ctrl_dbm, vid_dbm = cfg.control_eirp_dbm - loss, cfg.video_eirp_dbm - loss
        ctrl, ctrl_on = fhss_bursts(rng_for(seed, "rf", *stream_indices, 10 * (index + 1) + _EMITTER_CONTROL), starts, n,
                                    fs, channels, cfg.control_slot_s, cfg.control_burst_s, cfg.control_bandwidth_hz,
                                    clip_duration_s=duration)
        vid, vid_on = ofdm_bursts(rng_for(seed, "rf", *stream_indices, 10 * (index + 1) + _EMITTER_VIDEO), starts, n, fs,
                                  cfg.video_offset_hz, cfg.video_bandwidth_hz, cfg.video_duty, (0.3e-3, 0.8e-3),
                                  clip_duration_s=duration)
        ctrl *= np.sqrt(10 ** (ctrl_dbm / 10)).astype(np.float32)[:, None]
        vid *= np.sqrt(10 ** (vid_dbm / 10)).astype(np.float32)[:, None]
        link = ctrl + vid
        on = ctrl_on | vid_on
        p_on = np.sum(link.view(np.float32) ** 2, axis=1, dtype=np.float64) / np.maximum(np.sum(on, axis=1), 1)
        realised = np.maximum(realised, 10 * np.log10(np.maximum(p_on, 1e-30) / noise_mw))
        iq += link
        link_active[:] = True
        link_dbm = np.maximum(link_dbm, vid_dbm)
        ctrl_snr = np.maximum(ctrl_snr, ctrl_dbm - cfg.noise_dbm - 10 * np.log10(cfg.control_bandwidth_hz / fs))
        video_snr = np.maximum(video_snr, vid_dbm - cfg.noise_dbm - 10 * np.log10(cfg.video_bandwidth_hz / fs))
    if cfg.wifi_rx_dbm is not None:
        wifi, _ = ofdm_bursts(rng_for(seed, "rf", *stream_indices, _EMITTER_WIFI), starts, n, fs, cfg.wifi_offset_hz,
                              16.6e6, cfg.wifi_duty, (0.2e-3, 2.0e-3), subcarrier_step=4, clip_duration_s=duration)
        # rx power refers to the whole 20 MHz channel; the receiver only passes the part in its window
        iq += wifi * np.float32(np.sqrt(10 ** (cfg.wifi_rx_dbm / 10)))
    if cfg.bluetooth_rx_dbm is not None:
        bt_offsets = np.asarray(BT_CHANNELS_HZ) - cfg.center_frequency_hz
        bt, _ = fhss_bursts(rng_for(seed, "rf", *stream_indices, _EMITTER_BT), starts, n, fs, bt_offsets, 625e-6,
                            366e-6, 1e6, occupancy=0.3, clip_duration_s=duration)
        iq += bt * np.float32(np.sqrt(10 ** (cfg.bluetooth_rx_dbm / 10)))
    return RFCapture(config=cfg, capture_start_s=starts, iq=iq, spectrogram_dbm=spectrogram_dbm(iq, fs),
                     link_active=link_active, link_rx_dbm=link_dbm, control_snr_db=ctrl_snr,
                     video_snr_db=video_snr, realised_snr_db=realised, drone_range_m=drone_range)
