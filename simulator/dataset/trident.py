"""TRIDENT-style tri-modal clips: 10 s of RGB video + audio + RF on one timeline, 40 segments of 0.25 s.

Per clip: 280 video frames at 28 fps (112x112), a 44.1 kHz mono WAV, one RF I/Q capture and one
RF spectrogram per segment, an MFCC 1x40x40 per audio segment, and per-segment ground truth
(class and per-modality observability). :func:`generate_trident` writes a dataset in the TRIDENT
folder layout (``audio/``, ``video/``, ``rf/`` roots, each ``{Drone,Background}/<scenario>/``),
plus ``rf_iq/`` (complex64 I/Q), ``labels/`` (ground truth JSON) and ``manifest.json``; the whole
tree is written to a temporary sibling directory and renamed into place at the end.

MFCC: librosa, per 0.25 s segment (11 025 samples at 44.1 kHz) with n_fft = 1024 (23 ms),
hop_length = 282 (= 11025 // 39), centred frames -> 1 + 11025 // 282 = 40 frames; 128 mel bands,
40 coefficients; log-power floor at 80 dB below each segment's own maximum (segments are
independent). The input is the WAV sample value (pressure / full_scale_pa).
"""
from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path
from typing import Any, Callable

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from scenes.loader import GENERATION_DIR
from scenes.schema import Scenario
from simulator.formats.trident import (
    FRAMES_PER_SEGMENT,
    LABELS,
    MFCC_N_FFT,
    MFCC_N_MELS,
    MFCC_N_MFCC,
    MFCC_TOP_DB,
    SEGMENT_S,
    VIDEO_FPS,
    VIDEO_PX,
    SegmentTruth,
    TridentClip,
    mfcc_hop_length,
    mfcc_segments,
    write_clip,
)
from simulator.physics.acoustics import (
    AUDIO_SAMPLE_RATE_HZ,
    DRONE_KINDS,
    Ambience,
    band_level_db,
    synthesize_audio,
)
from simulator.physics.rf import RFConfig, spectrogram_image, synthesize_rf
from simulator.seeding import rng_for

AUDIBLE_BAND_HZ = (200.0, 8000.0)     # band in which drone and background levels are compared
VISIBLE_MIN_PX = 1.0                  # projected size below which a target is not "in view"
_TRIDENT_SEED_TAG = 6                  # separates clip seeds from other users of the "generation" stream

FramesFn = Callable[[Scenario, int, int, int, int], np.ndarray]



# --------------------------------------------------------------------------------------------
# Configuration (YAML boundary)
# --------------------------------------------------------------------------------------------

class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ClipSpec(_Model):
    """A group of clips from one scenario (a preset name or an inline scenario mapping)."""

    scenario: str | dict[str, Any]
    group: str | None = Field(default=None, description="the <scenario> folder name; default the scenario name")
    count: int = Field(default=1, ge=1, le=1000)
    rf_silent: bool = Field(default=False, description="autonomous flight: drone radios off")
    ambience: Ambience = Field(default_factory=Ambience)

    @model_validator(mode="after")
    def _group_name(self) -> "ClipSpec":
        name = self.group or (self.scenario if isinstance(self.scenario, str) else None)
        if name is not None and (not name or "/" in name or name.startswith(".")):
            raise ValueError(f"group must be a plain folder name, got {name!r}")
        return self


class TridentConfig(_Model):
    """A TRIDENT-style generation preset (scenes/generation/*.yaml)."""

    name: str = Field(min_length=1)
    description: str = ""
    clip_duration_s: float = Field(default=10.0, gt=0.0, le=600.0)
    video_fps: int = Field(default=VIDEO_FPS, ge=1, le=240)
    frames_per_segment: int = Field(default=FRAMES_PER_SEGMENT, ge=1)
    video_px: int = Field(default=VIDEO_PX, ge=16, le=1024)
    full_scale_pa: float = Field(default=0.1, gt=0.0, description="WAV 1.0 == this pressure (0.1 Pa = 74 dB SPL)")
    save_iq: bool = True
    jpeg_quality: int = Field(default=95, ge=10, le=100)
    rf: RFConfig = Field(default_factory=RFConfig)
    clips: list[ClipSpec] = Field(min_length=1)

    @model_validator(mode="after")
    def _segments(self) -> "TridentConfig":
        n_seg = self.clip_duration_s / SEGMENT_S
        if abs(n_seg - round(n_seg)) > 1e-9:
            raise ValueError(f"clip_duration_s must be a multiple of {SEGMENT_S} s, got {self.clip_duration_s}")
        if abs(self.video_fps * SEGMENT_S - self.frames_per_segment) > 1e-9:
            raise ValueError(f"frames_per_segment ({self.frames_per_segment}) must equal video_fps x {SEGMENT_S} s")
        return self

    @property
    def n_segments(self) -> int:
        return int(round(self.clip_duration_s / SEGMENT_S))


def load_trident_config(config_or_name: str | Path | dict | TridentConfig) -> TridentConfig:
    """A config object, a mapping, a YAML path, or a preset name in scenes/generation/."""
    from scenes.loader import load_validated

    if isinstance(config_or_name, TridentConfig):
        return config_or_name
    return load_validated(config_or_name, TridentConfig, GENERATION_DIR, "trident generation preset")


def resolve_scenario(spec: ClipSpec, source: str = "<clip>") -> Scenario:
    from scenes.loader import load_scenario, scenario_from_dict

    if isinstance(spec.scenario, str):
        return load_scenario(spec.scenario)
    return scenario_from_dict(spec.scenario, source=source)


def clip_scenario(scenario: Scenario, config: TridentConfig) -> Scenario:
    """The scenario re-timed to the clip (duration, 28 fps) with the RGB camera at the clip size."""
    data = scenario.model_dump(mode="python")
    data["duration_s"] = config.clip_duration_s
    data["frame_rate_hz"] = float(config.video_fps)
    data["camera_rig"]["rgb"]["width_px"] = config.video_px
    data["camera_rig"]["rgb"]["height_px"] = config.video_px
    return Scenario.model_validate(data)


def clip_label(scenario: Scenario) -> str:
    """Drone if any target is a drone (multirotor or fixed-wing), else Background."""
    return LABELS[0] if any(t.kind in DRONE_KINDS for t in scenario.targets) else LABELS[1]


def clip_seed(seed: int, clip_index: int) -> int:
    """Seed of clip ``clip_index`` of a dataset generated with ``seed`` (independent per clip)."""
    return int(rng_for(seed, "generation", _TRIDENT_SEED_TAG, clip_index).integers(0, 2 ** 31 - 1))


# --------------------------------------------------------------------------------------------

def _video_visibility(timeline, n_segments: int, frames_per_segment: int) -> np.ndarray:
    cam = timeline.cameras["rgb"]
    n_frames = timeline.n_frames
    visible = np.zeros(n_frames, bool)
    for track in timeline.targets:
        if track.kind not in DRONE_KINDS:
            continue
        for i in range(n_frames):
            xy, depth = cam.project(i, track.position_m[i])
            d = float(depth[0])
            if d <= 0:
                continue
            size_px = track.size_m * cam.focal_px / d
            inside = 0 <= xy[0, 0] < cam.width_px and 0 <= xy[0, 1] < cam.height_px
            visible[i] |= inside and size_px >= VISIBLE_MIN_PX
    need = n_segments * frames_per_segment
    visible = np.pad(visible, (0, max(0, need - n_frames)))[:need].reshape(n_segments, frames_per_segment)
    return visible.sum(axis=1) * 2 > frames_per_segment


def synthesize_clip(scenario: Scenario, seed: int, config: TridentConfig, *, rf_silent: bool = False,
                    ambience: Ambience | None = None, frames: np.ndarray | None = None) -> TridentClip:
    """Audio, MFCC, RF and ground truth of one clip; ``scenario`` is already re-timed (clip_scenario).

    ``frames`` (rendered elsewhere) are checked for shape and kept; None leaves the clip without video.
    """
    from simulator.physics.timeline import build_timeline

    n_seg = config.n_segments
    timeline = build_timeline(scenario, seed)
    fs = AUDIO_SAMPLE_RATE_HZ
    audio = synthesize_audio(timeline, seed, ambience=ambience, duration_s=config.clip_duration_s, sample_rate_hz=fs)
    samples = (audio.mix_pa.astype(np.float64) / config.full_scale_pa).astype(np.float32)
    mfcc = mfcc_segments(samples, fs, n_seg)
    starts = np.arange(n_seg) * SEGMENT_S
    rf = synthesize_rf(timeline, seed, starts, config=config.rf, rf_silent=rf_silent,
                       clip_duration_s=config.clip_duration_s)
    images = spectrogram_image(rf.spectrogram_dbm, config.rf)
    label = clip_label(scenario)
    seg_len = int(round(SEGMENT_S * fs))
    drone_names = [t.name for t in timeline.targets if t.kind in DRONE_KINDS]
    if drone_names:
        drone = np.sum([audio.targets_pa[n].astype(np.float64) for n in drone_names], axis=0)
        other = audio.mix_pa.astype(np.float64) - drone
        snr = band_level_db(drone, fs, *AUDIBLE_BAND_HZ, seg_len) - band_level_db(other, fs, *AUDIBLE_BAND_HZ, seg_len)
    else:
        snr = np.full(n_seg, -np.inf)
    snr = np.pad(snr, (0, max(0, n_seg - snr.size)), constant_values=-np.inf)[:n_seg]
    present = np.full(n_seg, label == LABELS[0])
    truth = SegmentTruth(
        label=label, drone_present=present,
        video_visible=_video_visibility(timeline, n_seg, config.frames_per_segment) & present,
        audio_audible=(snr >= 0.0) & present, rf_observable=rf.observable & present, rf_silent=rf_silent,
        drone_range_m=rf.drone_range_m, audio_snr_db=snr, rf_link_snr_db=np.maximum(rf.control_snr_db, rf.video_snr_db),
    )
    if frames is not None:
        frames = np.asarray(frames)
        want = (n_seg * config.frames_per_segment, config.video_px, config.video_px, 3)
        if frames.shape != want or frames.dtype != np.uint8:
            raise ValueError(f"frames must be uint8 {want}, got {frames.dtype} {frames.shape}")
    return TridentClip(audio=samples, sample_rate_hz=fs, mfcc=mfcc, rf=rf, rf_images=images, frames=frames, truth=truth)


# --------------------------------------------------------------------------------------------
# Writing the TRIDENT layout


def _default_frames(scenario: Scenario, seed: int, n_frames: int, width_px: int, height_px: int) -> np.ndarray:
    from simulator.dataset.sequence import render_rgb_video

    return render_rgb_video(scenario, seed, n_frames, width_px, height_px)


def _versions() -> dict[str, str]:
    from simulator.files import package_versions

    return package_versions(("evids", "numpy", "scipy", "librosa", "soundfile", "opencv-python-headless", "mitsuba"))


def _content_hash(root: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(p for p in root.rglob("*") if p.is_file() and p.name != "manifest.json"):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def generate_trident(config_or_name: str | Path | dict | TridentConfig, out_dir: str | Path, seed: int, *,
                     n_clips: int | None = None, progress: bool = True,
                     render_frames: FramesFn | None = None) -> Path:
    """Generate a TRIDENT-layout dataset into ``out_dir`` (must not exist or be empty); returns it.

    Clip k (0-based over the expanded clip list, first ``n_clips`` only) uses seed
    ``clip_seed(seed, k)`` and is numbered k + 1 in file names. ``render_frames(scenario, seed,
    n_frames, width_px, height_px)`` supplies video frames (default: the Mitsuba renderer).
    Written to a temporary sibling directory first and renamed, so a failed run leaves nothing.
    """
    from scenes.errors import UserInputError

    config = load_trident_config(config_or_name)
    out = Path(out_dir)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise UserInputError(f"output directory {str(out)!r} exists and is not empty; choose a new --out")
    if n_clips is not None and n_clips < 1:
        raise UserInputError(f"n_clips must be >= 1, got {n_clips}")
    plan: list[tuple[ClipSpec, Scenario, str]] = []
    for i, spec in enumerate(config.clips):
        scenario = clip_scenario(resolve_scenario(spec, source=f"clips.{i}.scenario"), config)
        group = spec.group or scenario.name
        plan.extend((spec, scenario, group) for _ in range(spec.count))
    if n_clips is not None:
        plan = plan[:n_clips]
    frames_fn = render_frames or _default_frames
    n_frames = config.n_segments * config.frames_per_segment
    out.parent.mkdir(parents=True, exist_ok=True)
    from simulator.files import clean_dead_temps, temp_sibling

    clean_dead_temps(out.parent, out.name)  # left by killed runs (never a live run's)
    tmp = temp_sibling(out)
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    clips_meta = []
    try:
        steps = range(len(plan))
        if progress:
            from rich.progress import track

            steps = track(steps, description=f"trident {config.name}", total=len(plan))
        for k in steps:
            spec, scenario, group = plan[k]
            seed_k = clip_seed(seed, k)
            frames = np.asarray(frames_fn(scenario, seed_k, n_frames, config.video_px, config.video_px), dtype=np.uint8)
            clip = synthesize_clip(scenario, seed_k, config, rf_silent=spec.rf_silent, ambience=spec.ambience,
                                   frames=frames)
            meta = {"scenario": scenario.name, "seed": seed_k, "label": clip.truth.label}
            write_clip(tmp, group, k + 1, clip, config, meta)
            clips_meta.append({"clip": k + 1, "group": group, **meta})
        manifest = {
            "format": "trident", "generator": "simulator.dataset.trident.generate_trident", "seed": int(seed),
            "config": config.model_dump(mode="json"), "clips": clips_meta, "versions": _versions(),
            "segment_s": SEGMENT_S, "audio_sample_rate_hz": AUDIO_SAMPLE_RATE_HZ,
            "mfcc": {"n_fft": MFCC_N_FFT, "hop_length": mfcc_hop_length(int(SEGMENT_S * AUDIO_SAMPLE_RATE_HZ)),
                     "n_mels": MFCC_N_MELS, "n_mfcc": MFCC_N_MFCC, "top_db": MFCC_TOP_DB},
            "content_sha256": _content_hash(tmp),
        }
        (tmp / "manifest.json").write_text(json.dumps(manifest, indent=1))
        if out.exists():
            out.rmdir()
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out
