"""Test-time degradation of loaded clips: audio noise on the waveform (MFCC recomputed), video
noise per 7-frame segment, RF noise on the spectrogram image (via dB) or on the I/Q before the STFT,
and conflict programs through :func:`degradations.spec.apply_spec`. Every draw is seeded from
``SeedSequence([noise_seed, clip_index, stream])``."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

import degradations
from evids.modalities import MODALITY_TABLE, OBSERVABILITY_KEY
from harness.experiments.config import NoiseEntry
from harness.experiments.data import ClipArrays

STREAM_CODE = {"audio": 1, "video": 2, "rf_spec": 3, "rf_iq": 4, "program": 5}
SEGMENT_S = 0.25
FPS = 28


def item_seed(noise_seed: int, clip_index: int, stream: str, k: int = 0) -> int:
    """An independent integer seed per (noise seed, clip, stream, entry)."""
    ss = np.random.SeedSequence([int(noise_seed), int(clip_index), STREAM_CODE[stream], int(k)])
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def _apply(entry: NoiseEntry, x: np.ndarray, seed: int) -> np.ndarray:
    if entry.severity is not None and entry.severity == 0.0 and not entry.params:
        return x
    kwargs = dict(entry.params)
    if entry.severity is not None:
        kwargs["severity"] = entry.severity
    return degradations.apply(entry.name, x, seed=seed, **kwargs)


def image_to_db(img: np.ndarray, range_db: float) -> np.ndarray:
    """(S, 112, 112) image in [0, 1] (row 0 = highest frequency) -> (S, F, T) dB, row 0 = lowest."""
    return (img[:, ::-1, :].astype(np.float64) * range_db).astype(np.float32)


def db_to_image(db: np.ndarray, range_db: float) -> np.ndarray:
    return np.clip(np.asarray(db, np.float64)[:, ::-1, :] / range_db, 0.0, 1.0).astype(np.float32)


@dataclass
class Degraded:
    """Model inputs of one clip after degradation."""

    mfcc: np.ndarray
    video: np.ndarray
    rf: np.ndarray


def degrade_clip(clip: ClipArrays, clip_index: int, noise_seed: int, *, audio: Sequence[NoiseEntry] = (),
                 video: Sequence[NoiseEntry] = (), rf_spec: Sequence[NoiseEntry] = (),
                 rf_iq: Sequence[NoiseEntry] = (),
                 rf_range_db: float = 60.0, rf_config: dict | None = None) -> Degraded:
    """The clip's (mfcc, video, rf) with the listed degradations; untouched streams are the clean arrays."""
    from simulator.formats.trident import mfcc_segments

    mfcc, vid, rf = clip.mfcc, clip.video, clip.rf
    if audio:
        wav = clip.audio
        for k, e in enumerate(audio):
            wav = _apply(e, wav, item_seed(noise_seed, clip_index, "audio", k))
        mfcc = mfcc_segments(wav, clip.sample_rate_hz, clip.n_segments)
    if video:
        for k, e in enumerate(video):
            vid = _apply(e, vid, item_seed(noise_seed, clip_index, "video", k))
    if rf_iq:
        if clip.iq is None or rf_config is None:
            raise ValueError(f"clip {clip.clip_id} has no I/Q capture (rf_iq/ folder); I/Q-level RF noise is "
                             "impossible")
        from simulator.physics.rf import RFConfig, spectrogram_dbm, spectrogram_image

        iq = clip.iq
        for k, e in enumerate(rf_iq):
            iq = _apply(e, iq, item_seed(noise_seed, clip_index, "rf_iq", k))
        conf = RFConfig.model_validate(rf_config)
        rf = spectrogram_image(spectrogram_dbm(iq, conf.sample_rate_hz), conf).astype(np.float32) / 255.0
    if rf_spec:
        db = image_to_db(rf, rf_range_db)
        for k, e in enumerate(rf_spec):
            db = _apply(e, db, item_seed(noise_seed, clip_index, "rf_spec", k))
        rf = db_to_image(db, rf_range_db)
    return Degraded(mfcc, vid, rf)


def conflict_clip(clip: ClipArrays, clip_index: int, noise_seed: int, program: str, onset_s: float,
                  duration_s: float, severity: float, rf_range_db: float = 60.0) -> tuple[Degraded, dict]:
    """Apply one conflict program to a clip; returns the inputs and per-segment flags
    ``{"compromised": {audio, video, rf}: (S,) bool, "conflict": (S,) bool}``."""
    from degradations.spec import apply_spec, parse_spec
    from simulator.formats.trident import mfcc_segments

    s = clip.n_segments
    rf_db = image_to_db(clip.rf, rf_range_db)                       # (S, F, T)
    streams = {"rgb": clip.video.reshape(-1, *clip.video.shape[2:]), "audio": clip.audio,
               "rf_spec": np.concatenate(list(rf_db), axis=1)}      # (F, S*T)
    meta = {"rgb_fps": float(FPS), "audio_sample_rate_hz": clip.sample_rate_hz,
            "rf_spec_frame_rate_hz": clip.rf.shape[2] / SEGMENT_S}
    spec = parse_spec({"programs": [{"name": program, "onset_s": onset_s, "duration_s": duration_s,
                                     "severity": severity}]})
    t_s = np.arange(s) * SEGMENT_S
    out, record = apply_spec(spec, streams, meta, item_seed(noise_seed, clip_index, "program"), t_s)
    video = np.asarray(out["rgb"]).reshape(clip.video.shape)
    mfcc = mfcc_segments(np.asarray(out["audio"]), clip.sample_rate_hz, s)
    spec_out = np.asarray(out["rf_spec"])
    rf = db_to_image(np.stack(np.split(spec_out, s, axis=1)), rf_range_db)
    comp = record["compromised"]
    flags = {"compromised": {m: np.asarray(comp.get(spec.compromised_key, [False] * s), bool)
                             for m, spec in MODALITY_TABLE.items()},
             "conflict": np.asarray(record["conflict"], bool)}
    return Degraded(mfcc, video, rf), flags


def program_window(n_segments: int, onset_fraction: float, duration_fraction: float) -> np.ndarray:
    """(S,) bool: segments inside [onset, onset + duration) of the clip."""
    t = np.arange(n_segments) * SEGMENT_S
    dur = n_segments * SEGMENT_S
    a, b = onset_fraction * dur, (onset_fraction + duration_fraction) * dur
    return (t >= a - 1e-9) & (t < b - 1e-9)


def swap_clip(clip: ClipArrays, donor: ClipArrays, modalities: tuple[str, ...], strength: float,
              window: np.ndarray, rf_range_db: float = 60.0) -> Degraded:
    """The clip with each listed modality's stream moved to its twin's (``donor``) inside ``window``.

    Audio is blended on the waveform (MFCC recomputed), video per frame, RF on the spectrogram in
    power; outside the window every stream is the clip's own.
    """
    from degradations.crossmodal import blend_signature
    from simulator.formats.trident import mfcc_segments

    if donor.n_segments != clip.n_segments:
        raise ValueError(f"twin {donor.clip_id} has {donor.n_segments} segments, {clip.clip_id} {clip.n_segments}")
    mfcc, vid, rf = clip.mfcc, clip.video, clip.rf
    w = np.asarray(window, bool)
    if "video" in modalities:
        vid = vid.copy()
        vid[w] = blend_signature(clip.video[w], donor.video[w], strength, "rgb")
    if "audio" in modalities:
        seg = int(round(SEGMENT_S * clip.sample_rate_hz))
        mask = np.repeat(w, seg)[: clip.audio.size]
        mask = np.pad(mask, (0, clip.audio.size - mask.size))
        n = min(clip.audio.size, donor.audio.size)
        wav = clip.audio.copy()
        sel = mask[:n]
        wav[:n][sel] = blend_signature(clip.audio[:n][sel], donor.audio[:n][sel], strength, "audio")
        mfcc = mfcc_segments(wav, clip.sample_rate_hz, clip.n_segments)
        mfcc = np.where(w[:, None, None, None], mfcc, clip.mfcc)     # untouched segments bit-identical
    if "rf" in modalities:
        rf = clip.rf.copy()
        own, don = image_to_db(clip.rf[w], rf_range_db), image_to_db(donor.rf[w], rf_range_db)
        rf[w] = db_to_image(blend_signature(own, don, strength, "rf_spec"), rf_range_db)
    return Degraded(mfcc.astype(np.float32), vid, rf.astype(np.float32))


def targeted_segments(clip: ClipArrays, donor: ClipArrays, kind: str, modalities: tuple[str, ...],
                      window: np.ndarray) -> np.ndarray:
    """Segments a program really targets: inside the window where the drone clip (the clip itself
    when blinding, the donor twin for a decoy) carries evidence in every compromised modality
    (simulator observability truth); without truth, the whole window."""
    drone = clip if kind == "blind" else donor
    mask = np.asarray(window, bool).copy()
    for m in modalities:
        obs = drone.observability.get(OBSERVABILITY_KEY[m])
        if obs is not None and len(obs) == len(mask):
            mask &= np.asarray(obs, bool)
    return mask
