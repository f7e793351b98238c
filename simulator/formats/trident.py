"""Loader for TRIDENT-layout tri-modal data: generated folders and the public TRIDENT release.

Layout: ``<root>/{audio,video,rf}/{Drone,Background}/<scenario>/...`` with, per clip number n,
``audio/.../<n>.wav``, ``video/.../<n>_frame_<i>.jpg`` (28 fps) and one RF spectrogram image per
0.25 s segment whose name starts with ``<n>_`` and ends with the segment index (``<n>_rf_<s>.png``
here). Clips are matched across modalities by (label, scenario folder, n). Generated folders also
carry ``labels/.../<n>.json`` with per-segment observability ground truth, returned when present.

A clip yields min(audio segments, video frames // 7, RF images) segments, each as a
:class:`TridentSegment`: MFCC (1, 40, 40) float32 computed from the WAV exactly as the generator
does (:func:`mfcc_segments`), video (7, 112, 112, 3) uint8 RGB, RF spectrogram
(112, 112) float32 in [0, 1] (or (112, 112, 3) for colour images), label (Drone -> 0, as the
TRIDENT reference code), clip id and segment index.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Literal, Protocol

import numpy as np

from simulator.physics.acoustics import AUDIO_SAMPLE_RATE_HZ, write_wav
from simulator.physics.rf import RFCapture, RFConfig

SEGMENT_S = 0.25
VIDEO_FPS = 28
FRAMES_PER_SEGMENT = 7
VIDEO_PX = 112
MFCC_N_FFT = 1024
MFCC_N_MFCC = 40
MFCC_N_MELS = 128
MFCC_FRAMES = 40
MFCC_TOP_DB = 80.0
LABELS = ("Drone", "Background")      # TRIDENT reference code maps Drone -> 0
IMAGE_PX = VIDEO_PX
_VIDEO_RE = re.compile(r"^(\d+)_frame_(\d+)\.jpe?g$", re.IGNORECASE)
_RF_RE = re.compile(r"^(\d+)_(?:.*?)(\d+)\.(?:png|jpe?g)$", re.IGNORECASE)
_AUDIO_RE = re.compile(r"^(\d+)(?:_.*)?\.wav$", re.IGNORECASE)



# --------------------------------------------------------------------------------------------
# Features: MFCC per segment
# --------------------------------------------------------------------------------------------

def mfcc_hop_length(segment_samples: int) -> int:
    """Hop giving exactly 40 centred frames per segment: 1 + L // hop == 40 (L // 39 works for L >= 1560)."""
    hop = segment_samples // (MFCC_FRAMES - 1)
    if hop < 1 or 1 + segment_samples // hop != MFCC_FRAMES:
        raise ValueError(f"segment of {segment_samples} samples cannot give {MFCC_FRAMES} MFCC frames")
    return hop


def mfcc_segments(audio: np.ndarray, sample_rate_hz: float, n_segments: int | None = None) -> np.ndarray:
    """(S, 1, 40, 40) float32 MFCCs (coefficient x frame) of consecutive 0.25 s segments (zero-padded)."""
    import librosa

    if not sample_rate_hz > 0:
        raise ValueError(f"sample_rate_hz must be > 0, got {sample_rate_hz}")
    seg = int(round(SEGMENT_S * sample_rate_hz))
    x = np.asarray(audio, dtype=np.float32).ravel()
    count = int(np.ceil(x.size / seg)) if n_segments is None else int(n_segments)
    x = np.pad(x, (0, max(0, count * seg - x.size)))[: count * seg].reshape(count, seg)
    n_fft = MFCC_N_FFT if abs(sample_rate_hz - AUDIO_SAMPLE_RATE_HZ) < 1 else int(2 ** np.ceil(np.log2(0.0232 * sample_rate_hz)))
    power = librosa.feature.melspectrogram(y=x, sr=sample_rate_hz, n_fft=n_fft, hop_length=mfcc_hop_length(seg),
                                           n_mels=MFCC_N_MELS, center=True)
    log_power = 10.0 * np.log10(np.maximum(power, 1e-10))
    log_power = np.maximum(log_power, log_power.max(axis=(1, 2), keepdims=True) - MFCC_TOP_DB)
    mfcc = librosa.feature.mfcc(S=log_power, n_mfcc=MFCC_N_MFCC)
    return mfcc[:, None].astype(np.float32)



# --------------------------------------------------------------------------------------------
# One clip in memory
# --------------------------------------------------------------------------------------------

# One clip in memory
# --------------------------------------------------------------------------------------------

@dataclass
class SegmentTruth:
    """Per-segment ground truth; every array has one entry per segment."""

    label: str
    drone_present: np.ndarray          # (S,) bool: the segment's class is Drone
    video_visible: np.ndarray          # (S,) bool: a drone is in the camera view (>= 4 of 7 frames, >= 1 px)
    audio_audible: np.ndarray          # (S,) bool: drone band level >= everything else in the band
    rf_observable: np.ndarray          # (S,) bool: a drone link is on and above detect_snr_db in its band
    rf_silent: bool = False
    drone_range_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    audio_snr_db: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rf_link_snr_db: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def to_json(self) -> dict[str, Any]:
        def clean(a: np.ndarray) -> list:
            return [None if not np.isfinite(v) else round(float(v), 3) for v in np.asarray(a, dtype=np.float64)]

        return {
            "label": self.label, "rf_silent": self.rf_silent,
            "drone_present": self.drone_present.astype(int).tolist(),
            "video_visible": self.video_visible.astype(int).tolist(),
            "audio_audible": self.audio_audible.astype(int).tolist(),
            "rf_observable": self.rf_observable.astype(int).tolist(),
            "drone_range_m": clean(self.drone_range_m), "audio_snr_db": clean(self.audio_snr_db),
            "rf_link_snr_db": clean(self.rf_link_snr_db),
        }


@dataclass
class TridentClip:
    """Everything of one clip before writing."""

    audio: np.ndarray            # (N,) float32 WAV samples (pressure / full_scale_pa)
    sample_rate_hz: float
    mfcc: np.ndarray             # (S, 1, 40, 40) float32
    rf: RFCapture                # I/Q (S, n) complex64 and spectrogram_dbm (S, 112, 112)
    rf_images: np.ndarray        # (S, 112, 112) uint8
    frames: np.ndarray | None    # (S * 7, H, W, 3) uint8
    truth: SegmentTruth


class ClipWriteSettings(Protocol):
    """What :func:`write_clip` needs of a generation config (``simulator.dataset.trident.TridentConfig``)."""

    save_iq: bool
    jpeg_quality: int
    rf: RFConfig


# --------------------------------------------------------------------------------------------
# Writing the TRIDENT layout
# --------------------------------------------------------------------------------------------

# --------------------------------------------------------------------------------------------

def _encode_image(image: np.ndarray, ext: Literal[".jpg", ".png"], jpeg_quality: int = 95) -> bytes:
    import cv2

    img = image[..., ::-1] if image.ndim == 3 else image          # RGB -> BGR for OpenCV
    params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)] if ext == ".jpg" else [cv2.IMWRITE_PNG_COMPRESSION, 6]
    ok, buf = cv2.imencode(ext, np.ascontiguousarray(img), params)
    if not ok:
        raise RuntimeError(f"OpenCV could not encode a {ext} image of shape {image.shape}")
    return buf.tobytes()


def write_clip(root: Path, group: str, number: int, clip: TridentClip, config: ClipWriteSettings,
               meta: dict[str, Any] | None = None) -> list[Path]:
    """Write one clip under ``root`` (audio/, video/, rf/, rf_iq/, labels/); returns the paths written."""
    label = clip.truth.label
    dirs = {m: root / m / label / group for m in ("audio", "video", "rf", "labels")}
    if config.save_iq:
        dirs["rf_iq"] = root / "rf_iq" / label / group
    for d in dirs.values():
        d.mkdir(parents=True, exist_ok=True)
    written = [write_wav(dirs["audio"] / f"{number}.wav", clip.audio, clip.sample_rate_hz, full_scale_pa=1.0)]
    if clip.frames is not None:
        for i, frame in enumerate(clip.frames):
            path = dirs["video"] / f"{number}_frame_{i}.jpg"
            path.write_bytes(_encode_image(frame, ".jpg", config.jpeg_quality))
            written.append(path)
    for s, image in enumerate(clip.rf_images):
        path = dirs["rf"] / f"{number}_rf_{s}.png"
        path.write_bytes(_encode_image(image, ".png"))
        written.append(path)
    if config.save_iq:
        path = dirs["rf_iq"] / f"{number}.npy"
        np.save(path, clip.rf.iq.astype(np.complex64))
        written.append(path)
    info = {"clip": number, "group": group, **(meta or {}), "segments": clip.truth.to_json(),
            "rf": {"sample_rate_hz": config.rf.sample_rate_hz, "center_frequency_hz": config.rf.center_frequency_hz,
                   "capture_samples": config.rf.capture_samples, "noise_dbm": round(config.rf.noise_dbm, 3),
                   "capture_start_s": clip.rf.capture_start_s.tolist()}}
    path = dirs["labels"] / f"{number}.json"
    path.write_text(json.dumps(info, indent=1))
    written.append(path)
    return written


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------

@dataclass
class TridentSegment:
    """One aligned 0.25 s decision unit."""

    audio_mfcc: np.ndarray          # (1, 40, 40) float32
    video: np.ndarray               # (7, 112, 112, 3) uint8 RGB
    rf: np.ndarray                  # (112, 112) float32 in [0, 1]
    label: int                      # 0 Drone, 1 Background
    clip_id: str                    # "<Label>/<scenario>/<n>"
    segment_index: int
    observability: dict[str, bool] | None = None   # video/audio/rf ground truth (generated data only)


@dataclass
class ClipFiles:
    """Paths of one clip across modalities."""

    label: str
    scenario: str
    number: str
    audio: Path
    frames: list[Path]              # sorted by frame index
    rf: list[Path]                  # sorted by segment index
    labels_json: Path | None

    @property
    def clip_id(self) -> str:
        return f"{self.label}/{self.scenario}/{self.number}"

    @property
    def n_segments(self) -> int:
        return min(len(self.rf), len(self.frames) // FRAMES_PER_SEGMENT, _audio_segments(self.audio))


def _audio_segments(path: Path) -> int:
    import soundfile

    info = soundfile.info(str(path))
    return int(info.frames // int(round(0.25 * info.samplerate)))


def _indexed(folder: Path, pattern: re.Pattern) -> dict[str, list[tuple[int, Path]]]:
    out: dict[str, list[tuple[int, Path]]] = {}
    if folder.is_dir():
        for p in folder.iterdir():
            m = pattern.match(p.name)
            if m:
                out.setdefault(m.group(1), []).append((int(m.group(2)), p))
    return {k: [p for _, p in sorted(v)] for k, v in out.items()}


def discover_clips(root: str | Path) -> list[ClipFiles]:
    """All clips present in all three modalities, sorted by clip id."""
    root = Path(root)
    for modality in ("audio", "video", "rf"):
        if not (root / modality).is_dir():
            raise ValueError(f"root: {str(root)!r} has no {modality}/ folder (expected the TRIDENT layout)")
    clips = []
    for label in LABELS:
        audio_label = root / "audio" / label
        if not audio_label.is_dir():
            continue
        for scen_dir in sorted(p for p in audio_label.iterdir() if p.is_dir()):
            scenario = scen_dir.name
            audio = {m.group(1): p for p in scen_dir.iterdir() if (m := _AUDIO_RE.match(p.name))}
            frames = _indexed(root / "video" / label / scenario, _VIDEO_RE)
            rf = _indexed(root / "rf" / label / scenario, _RF_RE)
            for number in sorted(audio, key=int):
                if number not in frames or number not in rf:
                    continue
                labels_json = root / "labels" / label / scenario / f"{number}.json"
                clips.append(ClipFiles(label, scenario, number, audio[number], frames[number], rf[number],
                                       labels_json if labels_json.is_file() else None))
    return clips


def _read_image(path: Path, grayscale_ok: bool) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"cannot read image {path}")
    if img.ndim == 3:
        img = cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2RGB)
    elif not grayscale_ok:
        img = np.repeat(img[..., None], 3, axis=-1)
    if img.shape[:2] != (IMAGE_PX, IMAGE_PX):
        img = cv2.resize(img, (IMAGE_PX, IMAGE_PX), interpolation=cv2.INTER_AREA)
    return img


class TridentDataset:
    """Aligned (audio MFCC, video segment, RF spectrogram, label, clip id, segment index) from a root."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self.clips = discover_clips(self.root)
        self._index = [(c, s) for c, clip in enumerate(self.clips) for s in range(clip.n_segments)]
        self._cached: tuple[int, np.ndarray, dict | None] | None = None   # last clip's MFCC + truth

    def __len__(self) -> int:
        return len(self._index)

    def __getitem__(self, i: int) -> TridentSegment:
        c, s = self._index[i]
        if self._cached is None or self._cached[0] != c:
            self._cached = (c, self._mfcc(self.clips[c]), self._truth(self.clips[c]))
        return self._segment(self.clips[c], s, self._cached[1], self._cached[2])

    def __iter__(self) -> Iterator[TridentSegment]:
        for clip in self.clips:
            yield from self.iter_clip(clip)

    def iter_clip(self, clip: ClipFiles) -> Iterator[TridentSegment]:
        """The clip's segments in order (the WAV is read and featurised once)."""
        mfcc, truth = self._mfcc(clip), self._truth(clip)
        for s in range(clip.n_segments):
            yield self._segment(clip, s, mfcc, truth)

    @staticmethod
    def _mfcc(clip: ClipFiles) -> np.ndarray:
        import soundfile


        audio, rate = soundfile.read(str(clip.audio), dtype="float32", always_2d=True)
        return mfcc_segments(audio.mean(axis=1), float(rate), clip.n_segments)

    @staticmethod
    def _truth(clip: ClipFiles) -> dict | None:
        if clip.labels_json is None:
            return None
        return json.loads(clip.labels_json.read_text())["segments"]

    @staticmethod
    def _segment(clip: ClipFiles, s: int, mfcc: np.ndarray, truth: dict | None) -> TridentSegment:
        frames = clip.frames[s * FRAMES_PER_SEGMENT:(s + 1) * FRAMES_PER_SEGMENT]
        video = np.stack([_read_image(p, grayscale_ok=False) for p in frames])
        rf = _read_image(clip.rf[s], grayscale_ok=True).astype(np.float32) / 255.0
        obs = None
        if truth is not None:
            obs = {m: bool(truth[k][s]) for m, k in
                   (("video", "video_visible"), ("audio", "audio_audible"), ("rf", "rf_observable"))}
        return TridentSegment(audio_mfcc=mfcc[s], video=video, rf=rf, label=LABELS.index(clip.label),
                              clip_id=clip.clip_id, segment_index=s, observability=obs)


def iter_trident(root: str | Path) -> Iterator[TridentSegment]:
    """Every aligned segment under ``root`` in clip order."""
    yield from TridentDataset(root)
