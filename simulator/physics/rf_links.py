"""Drone radio-link presets and their transmission schedules on the absolute clock.

A link is either frequency-hopping (FHSS control links: ExpressLRS-like LoRa, FrSky-like GFSK, and
the DroneID-like broadcast hopping over ~15 frequencies) or OFDM (DJI-OcuSync-like video at 10/20/40
MHz with LTE-like 15 kHz subcarriers, Wi-Fi video on a 20 MHz channel). Presets are "-like": the
numbers are from public descriptions (docs/AUDIO_RF.md lists each with its source), not any vendor's
specification. A schedule is the list of bursts (start, duration, absolute centre frequency) that a
link transmits over a clip; the receiver sees only the bursts that overlap its capture windows in
time and frequency (:func:`bursts_in_windows`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

ISM_LOW_HZ, ISM_HIGH_HZ = 2400.0e6, 2483.5e6


def lora_time_on_air_s(spreading_factor: int, bandwidth_hz: float, payload_bytes: int, preamble_symbols: int,
                       coding_rate: int, implicit_header: bool = True, crc: bool = False) -> float:
    """LoRa packet duration (Semtech SX127x/SX128x time-on-air formula; SF5/SF6 add 2 preamble symbols).

    n_payload = 8 + max(ceil((8 PL - 4 SF + 28 + 16 CRC - 20 IH) / (4 SF)) (CR + 4), 0) with coding
    rate 4/(4+CR); T = (n_preamble + 4.25 [+2 for SF < 7] + n_payload) 2^SF / BW.
    """
    if not 5 <= spreading_factor <= 12:
        raise ValueError(f"spreading_factor must be in 5..12, got {spreading_factor}")
    symbol_s = 2 ** spreading_factor / bandwidth_hz
    numerator = 8 * payload_bytes - 4 * spreading_factor + 28 + 16 * int(crc) - 20 * int(implicit_header)
    n_payload = 8 + max(int(np.ceil(numerator / (4 * spreading_factor))) * (coding_rate + 4), 0)
    extra = 6.25 if spreading_factor < 7 else 4.25
    return (preamble_symbols + extra + n_payload) * symbol_s


class _Preset(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(min_length=1)
    role: Literal["control", "video", "broadcast"]
    tx_power_dbm: float = Field(description="conducted power; the antenna pattern adds its gain")
    tx_antenna: Literal["isotropic", "dipole", "patch"] = "dipole"


class FhssPreset(_Preset):
    """Periodic packets hopping over a channel plan (hop every ``packets_per_hop`` packets)."""

    kind: Literal["fhss"] = "fhss"
    first_channel_hz: float = Field(gt=0)
    channel_spacing_hz: float = Field(gt=0)
    n_channels: int = Field(ge=1)
    packet_rate_hz: float = Field(gt=0)
    packet_s: float = Field(gt=0)
    packets_per_hop: int = Field(default=1, ge=1)
    occupancy: float = Field(default=1.0, gt=0.0, le=1.0, description="share of packet slots used")
    modulation: Literal["lora", "gfsk", "ofdm"]
    occupied_bandwidth_hz: float = Field(gt=0)
    spreading_factor: int = 6                 # lora
    symbol_rate_hz: float = 250e3              # gfsk
    subcarrier_spacing_hz: float = 15e3        # ofdm bursts (DroneID-like)

    @property
    def channels_hz(self) -> np.ndarray:
        return self.first_channel_hz + self.channel_spacing_hz * np.arange(self.n_channels)


class OfdmPreset(_Preset):
    """Bursty OFDM on one channel picked per clip from ``channel_centres_hz``."""

    kind: Literal["ofdm"] = "ofdm"
    bandwidth_hz: float = Field(gt=0, description="occupied bandwidth (used subcarriers x spacing)")
    subcarrier_spacing_hz: float = Field(gt=0)
    cp_fraction: float = Field(default=144 / 2048, ge=0, lt=1)
    channel_centres_hz: tuple[float, ...] = Field(min_length=1)
    duty: float = Field(gt=0, le=1)
    burst_range_s: tuple[float, float]


LinkPreset = Annotated[FhssPreset | OfdmPreset, Field(discriminator="kind")]


def _centres(bandwidth_hz: float, step_hz: float) -> tuple[float, ...]:
    """Channel centres on a ``step_hz`` grid whose band fits inside 2400-2483.5 MHz (1.5 MHz guard)."""
    lo, hi = ISM_LOW_HZ + 1.5e6 + bandwidth_hz / 2, ISM_HIGH_HZ - 1.5e6 - bandwidth_hz / 2
    return tuple(float(c) for c in np.arange(lo, hi + 1.0, step_hz))


_ELRS: dict[str, Any] = {"role": "control", "first_channel_hz": 2400.4e6, "channel_spacing_hz": 1e6, "n_channels": 80,
         "modulation": "lora",
             "occupied_bandwidth_hz": 812.5e3, "packets_per_hop": 4, "tx_power_dbm": 20.0}

LINK_PRESETS: dict[str, LinkPreset] = {
    # ExpressLRS 2.4 GHz-like: LoRa BW 812.5 kHz, 80 x 1 MHz channels from 2400.4 MHz, hop every 4 packets,
    # 8-byte packets (implicit header, no radio CRC); 500 Hz: SF5 CR 4/6 preamble 12; 250 Hz: SF6 CR 4/7 preamble 14
    "elrs_like_500hz": FhssPreset(name="elrs_like_500hz", packet_rate_hz=500.0, spreading_factor=5,
                                  packet_s=lora_time_on_air_s(5, 812.5e3, 8, 12, 2), **_ELRS),
    "elrs_like_250hz": FhssPreset(name="elrs_like_250hz", packet_rate_hz=250.0, spreading_factor=6,
                                  packet_s=lora_time_on_air_s(6, 812.5e3, 8, 14, 3), **_ELRS),
    "elrs_like_50hz": FhssPreset(name="elrs_like_50hz", packet_rate_hz=50.0, spreading_factor=8,
                                 packet_s=lora_time_on_air_s(8, 812.5e3, 8, 12, 3), **_ELRS),
    # FrSky ACCST-like: a 9 ms frame, one GFSK packet per frame (~38 bytes at 250 kbit/s = 1.2 ms), hop per packet
    "frsky_like": FhssPreset(name="frsky_like", role="control", first_channel_hz=2404e6, channel_spacing_hz=1.5e6,
                             n_channels=47, packet_rate_hz=1 / 9e-3, packet_s=38 * 8 / 250e3, modulation="gfsk",
                             symbol_rate_hz=250e3, occupied_bandwidth_hz=500e3, tx_power_dbm=20.0),
    # DJI-OcuSync-like video downlink: LTE-like OFDM, 15 kHz subcarriers, 600/1200/2400 used (9/18/36 MHz)
    "ocusync_like_10mhz": OfdmPreset(name="ocusync_like_10mhz", role="video", bandwidth_hz=9e6,
                                     subcarrier_spacing_hz=15e3, channel_centres_hz=_centres(10e6, 10e6), duty=0.7,
                                     burst_range_s=(1e-3, 4e-3), tx_power_dbm=23.0),
    "ocusync_like_20mhz": OfdmPreset(name="ocusync_like_20mhz", role="video", bandwidth_hz=18e6,
                                     subcarrier_spacing_hz=15e3, channel_centres_hz=_centres(20e6, 20e6), duty=0.7,
                                     burst_range_s=(1e-3, 4e-3), tx_power_dbm=23.0),
    "ocusync_like_40mhz": OfdmPreset(name="ocusync_like_40mhz", role="video", bandwidth_hz=36e6,
                                     subcarrier_spacing_hz=15e3, channel_centres_hz=_centres(40e6, 40e6), duty=0.7,
                                     burst_range_s=(1e-3, 4e-3), tx_power_dbm=23.0),
    # Wi-Fi (802.11g/n-like) video: 52 x 312.5 kHz subcarriers (16.6 MHz) on channel 1, 6 or 11
    "wifi_video": OfdmPreset(name="wifi_video", role="video", bandwidth_hz=16.25e6, subcarrier_spacing_hz=312.5e3,
                             cp_fraction=0.25, channel_centres_hz=(2412e6, 2437e6, 2462e6), duty=0.5,
                             burst_range_s=(0.2e-3, 1.5e-3), tx_power_dbm=18.0),
    # DroneID-like broadcast: one ~0.64 ms 10 MHz OFDM burst every 600 ms, cycling over 15 frequencies
    "droneid_like": FhssPreset(name="droneid_like", role="broadcast", first_channel_hz=2406.5e6,
                               channel_spacing_hz=5e6, n_channels=15, packet_rate_hz=1 / 0.6, packet_s=0.64e-3,
                               modulation="ofdm", occupied_bandwidth_hz=9e6, tx_power_dbm=20.0),
}


# background Bluetooth (not a drone link): 79 x 1 MHz from 2402 MHz, 1600 slots/s, 366 us packets, 30 % used
BLUETOOTH = FhssPreset(name="bluetooth", role="control", first_channel_hz=2402e6, channel_spacing_hz=1e6, n_channels=79,
                       packet_rate_hz=1600.0, packet_s=366e-6, modulation="gfsk", symbol_rate_hz=1e6,
                       occupied_bandwidth_hz=1e6, tx_power_dbm=0.0, occupancy=0.3)


def link_preset(name: str) -> LinkPreset:
    if name not in LINK_PRESETS:
        raise ValueError(f"links: unknown link preset {name!r}; choose from {sorted(LINK_PRESETS)}")
    return LINK_PRESETS[name]


@dataclass
class Schedule:
    """Bursts of one link over a clip (sorted by start)."""

    start_s: np.ndarray          # (B,)
    duration_s: np.ndarray       # (B,)
    centre_hz: np.ndarray        # (B,) absolute centre frequency
    bandwidth_hz: float


def fhss_schedule(preset: FhssPreset, rng: np.random.Generator, duration_s: float) -> Schedule:
    """Periodic packets with a random clock phase; hop channels = concatenated random permutations
    of the channel plan (every channel once per cycle, as hop tables do), one hop per
    ``packets_per_hop`` packets. Covers [-1 period, duration_s + 1 s)."""
    period = 1.0 / preset.packet_rate_hz
    phase = rng.uniform(0.0, period)
    n_packets = int(np.ceil((duration_s + 1.0) / period)) + 2
    starts = phase - period + period * np.arange(n_packets)
    # hop boundaries are aligned to a random packet so the hop phase is random too
    offset = int(rng.integers(0, preset.packets_per_hop))
    hop = (np.arange(n_packets) + offset) // preset.packets_per_hop
    n_hops = int(hop[-1]) + 1
    cycles = int(np.ceil(n_hops / preset.n_channels))
    order = np.concatenate([rng.permutation(preset.n_channels) for _ in range(cycles)])[:n_hops]
    sched = Schedule(start_s=starts, duration_s=np.full(n_packets, preset.packet_s),
                     centre_hz=preset.channels_hz[order[hop]], bandwidth_hz=preset.occupied_bandwidth_hz)
    if preset.occupancy < 1.0:
        used = rng.random(n_packets) < preset.occupancy
        sched = Schedule(sched.start_s[used], sched.duration_s[used], sched.centre_hz[used], sched.bandwidth_hz)
    return sched


def ofdm_schedule(preset: OfdmPreset, rng: np.random.Generator, duration_s: float) -> Schedule:
    """One channel per clip; burst lengths uniform in ``burst_range_s`` with exponential gaps for ``duty``."""
    centre = float(preset.channel_centres_hz[int(rng.integers(0, len(preset.channel_centres_hz)))])
    mean_burst = float(np.mean(preset.burst_range_s))
    mean_gap = mean_burst * (1 - preset.duty) / preset.duty
    n = int(np.ceil((duration_s + 1.0) / (mean_burst + mean_gap) * 2)) + 4
    lengths = rng.uniform(*preset.burst_range_s, size=n)
    gaps = rng.exponential(mean_gap, size=n) if preset.duty < 1 else np.zeros(n)
    starts = np.cumsum(np.concatenate([[-rng.uniform(0, mean_burst + mean_gap)], (lengths + gaps)[:-1]]))
    return Schedule(start_s=starts, duration_s=lengths, centre_hz=np.full(n, centre), bandwidth_hz=preset.bandwidth_hz)


def band_overlap_fraction(centre_hz: np.ndarray | float, bandwidth_hz: float, window_low_hz: float,
                          window_high_hz: float) -> np.ndarray:
    """Fraction of each burst's band [c - B/2, c + B/2] inside the receiver passband."""
    lo = np.maximum(np.asarray(centre_hz) - bandwidth_hz / 2, window_low_hz)
    hi = np.minimum(np.asarray(centre_hz) + bandwidth_hz / 2, window_high_hz)
    return np.clip((hi - lo) / bandwidth_hz, 0.0, 1.0)


def bursts_in_windows(schedule: Schedule, window_start_s: np.ndarray, window_s: float) -> list[np.ndarray]:
    """Indices of the bursts overlapping each time window [start, start + window_s) (any overlap)."""
    end = schedule.start_s + schedule.duration_s
    longest = float(np.max(schedule.duration_s)) if schedule.duration_s.size else 0.0
    out = []
    for w in np.asarray(window_start_s, dtype=np.float64):
        lo = np.searchsorted(schedule.start_s, w - longest, side="left")
        hi = np.searchsorted(schedule.start_s, w + window_s, side="left")
        idx = np.arange(lo, hi)
        out.append(idx[end[idx] > w])
    return out


def expected_fhss_counts(preset: FhssPreset, window_s: float, visible_fraction: float) -> dict[str, float]:
    """Analytic per-capture burst statistics of a hop-per-packet link with a uniformly random clock phase.

    M packets overlap a window of T: M = m or m + 1 with m = floor((T + L) R) and P(m + 1) =
    frac((T + L) R); each is visible with probability p (independent hops). Returns the mean and
    P(0), P(1), P(>=2). Valid for ``packets_per_hop == 1`` (the mean holds for any hop interval).
    """
    x = (window_s + preset.packet_s) * preset.packet_rate_hz
    m, frac = int(np.floor(x)), x - np.floor(x)
    p = visible_fraction
    from math import comb

    def dist(count: int) -> np.ndarray:
        return np.array([comb(count, j) * p ** j * (1 - p) ** (count - j) for j in range(count + 1)])

    probs = np.zeros(m + 2)
    probs[: m + 1] += (1 - frac) * dist(m)
    probs[: m + 2] += frac * dist(m + 1)
    return {"mean": x * p, "p0": float(probs[0]), "p1": float(probs[1]) if probs.size > 1 else 0.0,
            "p2plus": float(probs[2:].sum())}
