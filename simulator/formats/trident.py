"""TRIDENT tri-modal clips: writer, reader and spec (docs/FORMATS.md, "TRIDENT").

Two layouts, both read by :class:`TridentDataset` / :func:`discover_clips`:

* **generated** (what ``evids generate --format trident`` writes): ``<root>/{audio,video,rf}/
  {Drone,Background}/<scenario>/`` with ``<n>.wav``, ``<n>_frame_<i>.jpg`` (0-based, 28 fps),
  ``<n>_rf_<s>.png`` (0-based, one per 0.25 s segment), plus ``rf_iq/.../<n>.npy`` (+ its SigMF
  ``<n>.sigmf-meta``), ``labels/.../<n>.json`` (per-segment observability) and ``manifest.json``;
* **public** (the TRIDENT release, and :func:`export_public`): ``<root>/Audio/<Split>/<Label>/<scenario>/<n>.wav``,
  ``Video/<Split>/<Label>/<scenario>/{Images_Extracted|Images}/<n>_frame_<i>.jpg`` (i = 1..280),
  ``RF_Spectrograms/<Split>/<Label>/<scenario>/{Images_Spectrograms|Images}/<n>_frame_<j>.jpg``
  (j = 1..40); ``<Split>`` is ``Train`` (``Images_Extracted``, ``Images_Spectrograms``) or ``Test``
  (``Images``). Our export adds ``Labels/``, ``RF_IQ/`` (SigMF) and ``manifest.json``, which the
  public code ignores.

A clip yields S segments of 0.25 s: S from its labels JSON, else from the manifest's clip
duration, else 40 in the public layout (the public code's fixed 10 s), else the WAV's length. Each
segment is a :class:`TridentSegment`: MFCC (1, 40, 40) float32, video (7, 112, 112, 3) uint8 RGB,
RF spectrogram (112, 112) float32 in [0, 1] (or (112, 112, 3) for colour images), label (Drone -> 0,
as the TRIDENT code), clip id and segment index.

MFCC pipelines (``mfcc=``): ``evids`` (default, physically correct: :func:`mfcc_segments`) or
``trident`` (the public code's, bit for bit: :func:`mfcc_trident`). ``None`` takes the one recorded
in the dataset's manifest (``evids`` when there is none).

Reading validates each clip: the WAV opens and covers S segments (a truncated WAV is an error),
frame and RF indices are consecutive from their first (0 or 1) with no gap, and there are at least
7 S frames and S RF images. ``strict=False`` skips a bad clip and records it in ``skipped``.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator, Literal, Protocol

import numpy as np

from simulator.formats.validation import FormatError, Skipped, SkippedRowsWarning, read_json
from simulator.physics.acoustics.levels import AUDIO_SAMPLE_RATE_HZ
from simulator.physics.acoustics.mix import write_wav
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
    segments = np.pad(x, (0, max(0, count * seg - x.size)))[: count * seg].reshape(count, seg)
    n_fft = (MFCC_N_FFT if abs(sample_rate_hz - AUDIO_SAMPLE_RATE_HZ) < 1
             else int(2 ** np.ceil(np.log2(0.0232 * sample_rate_hz))))
    power = librosa.feature.melspectrogram(y=segments, sr=sample_rate_hz, n_fft=n_fft, hop_length=mfcc_hop_length(seg),
                                           n_mels=MFCC_N_MELS, center=True)
    log_power = 10.0 * np.log10(np.maximum(power, 1e-10))
    log_power = np.maximum(log_power, log_power.max(axis=(1, 2), keepdims=True) - MFCC_TOP_DB)
    mfcc = librosa.feature.mfcc(S=log_power, n_mfcc=MFCC_N_MFCC)
    return mfcc[:, None].astype(np.float32)


# The public TRIDENT code's feature pipeline (dataset/get_dataset.py, DroneFusionDataset.__getitem__)
TRIDENT_SAMPLE_RATE_HZ = 44100
TRIDENT_DECIMATION = 3
TRIDENT_N_FFT = 2048
TRIDENT_HOP = 512
MFCC_PIPELINES = ("evids", "trident")


def mfcc_trident(wav_path: str | Path, n_segments: int) -> np.ndarray:
    """(S, 1, 40, 40) float32 MFCCs exactly as the public TRIDENT code computes them.

    Per segment k: ``librosa.load(path, sr=44100, offset=0.25 k, duration=0.25)``, then
    ``waveform[::3]`` with sr still 44100 (so mel bands are shifted by 3x and only 8 frames are real),
    ``librosa.feature.mfcc(n_mfcc=40, n_fft=2048, hop_length=512)``, zero-padded to 40 columns.
    Kept for compatibility with models trained on the public code; :func:`mfcc_segments` is correct."""
    import librosa

    out = np.zeros((n_segments, 1, MFCC_N_MFCC, MFCC_FRAMES), dtype=np.float32)
    for k in range(n_segments):
        waveform, sr = librosa.load(str(wav_path), sr=TRIDENT_SAMPLE_RATE_HZ, offset=k * SEGMENT_S, duration=SEGMENT_S)
        waveform = np.asfortranarray(waveform[::TRIDENT_DECIMATION])
        mfcc = librosa.feature.mfcc(y=waveform, sr=sr, n_mfcc=MFCC_N_MFCC, n_fft=TRIDENT_N_FFT, hop_length=TRIDENT_HOP)
        mfcc = np.pad(mfcc, ((0, 0), (0, max(0, MFCC_FRAMES - mfcc.shape[1]))), mode="constant")
        out[k, 0] = mfcc[:, :MFCC_FRAMES].astype(np.float32)
    return out



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

    audio: np.ndarray            # (N,) float32 WAV samples (recorded, full scale 1.0)
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

def _encode_image(image: np.ndarray, ext: Literal[".jpg", ".png"], jpeg_quality: int = 95) -> bytes:
    import cv2

    img = image[..., ::-1] if image.ndim == 3 else image          # RGB -> BGR for OpenCV
    params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)] if ext == ".jpg" else [cv2.IMWRITE_PNG_COMPRESSION, 6]
    ok, buf = cv2.imencode(ext, np.ascontiguousarray(img), params)
    if not ok:
        raise RuntimeError(f"OpenCV could not encode a {ext} image of shape {image.shape}")
    return buf.tobytes()


def clip_files(label: str, group: str, number: int, *, n_frames: int, n_segments: int, save_iq: bool) -> list[str]:
    """Paths (relative to the root, POSIX) that :func:`write_clip` writes for one clip with ``n_frames``
    video frames and ``n_segments`` RF images, in the order it writes them."""
    names = [f"audio/{label}/{group}/{number}.wav"]
    names += [f"video/{label}/{group}/{number}_frame_{i}.jpg" for i in range(n_frames)]
    names += [f"rf/{label}/{group}/{number}_rf_{s}.png" for s in range(n_segments)]
    if save_iq:
        names += [f"rf_iq/{label}/{group}/{number}.npy", f"rf_iq/{label}/{group}/{number}.sigmf-meta"]
    return names + [f"labels/{label}/{group}/{number}.json"]


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
        from simulator.formats.sigmf import write_npy_meta

        path = dirs["rf_iq"] / f"{number}.npy"
        np.save(path, clip.rf.iq.astype(np.complex64))
        written.append(path)
        written.append(write_npy_meta(path, sample_rate_hz=config.rf.sample_rate_hz,
                                      center_frequency_hz=config.rf.center_frequency_hz,
                                      capture_start_s=clip.rf.capture_start_s, label=label,
                                      description=f"evids synthetic RF capture, clip {number} ({group})"))
    info = {"clip": number, "group": group, **(meta or {}), "segments": clip.truth.to_json(),
            "rf": {"sample_rate_hz": config.rf.sample_rate_hz, "center_frequency_hz": config.rf.center_frequency_hz,
                   "capture_samples": config.rf.capture_samples, "noise_dbm": round(config.rf.noise_dbm, 3),
                   "capture_start_s": clip.rf.capture_start_s.tolist()}}
    path = dirs["labels"] / f"{number}.json"
    path.write_text(json.dumps(info, indent=1))
    written.append(path)
    return written



# --------------------------------------------------------------------------------------------
# Reader (both layouts)
# --------------------------------------------------------------------------------------------

PUBLIC_ROOTS = {"audio": "Audio", "video": "Video", "rf": "RF_Spectrograms"}
PUBLIC_SPLITS = ("Train", "Test")
PUBLIC_SUBFOLDERS = {"Train": {"video": "Images_Extracted", "rf": "Images_Spectrograms"},
                     "Test": {"video": "Images", "rf": "Images"}}
PUBLIC_SEGMENTS = 40                  # the public loader's fixed duration=10 s / segment_length=0.25 s
PUBLIC_EXTRAS = {"labels": "Labels", "rf_iq": "RF_IQ"}
MANIFEST = "manifest.json"


@dataclass
class TridentSegment:
    """One aligned 0.25 s decision unit."""

    audio_mfcc: np.ndarray          # (1, 40, 40) float32
    video: np.ndarray               # (7, 112, 112, 3) uint8 RGB
    rf: np.ndarray                  # (112, 112) float32 in [0, 1]
    label: int                      # 0 Drone, 1 Background
    clip_id: str                    # "<Label>/<scenario>/<n>" ("<Split>/<Label>/<scenario>/<n>" in the public layout)
    segment_index: int
    observability: dict[str, bool] | None = None   # video/audio/rf ground truth (generated data only)


@dataclass
class ClipFiles:
    """Paths of one clip across modalities; ``segments`` = S, checked when the clip was discovered."""

    label: str
    scenario: str
    number: str
    audio: Path
    frames: list[Path]              # sorted by frame index
    rf: list[Path]                  # sorted by segment index
    labels_json: Path | None
    split: str | None = None        # "Train"/"Test" in the public layout
    segments: int = 0
    iq: Path | None = None

    @property
    def clip_id(self) -> str:
        base = f"{self.label}/{self.scenario}/{self.number}"
        return f"{self.split}/{base}" if self.split else base

    @property
    def n_segments(self) -> int:
        return self.segments


def is_public_layout(root: Path) -> bool:
    return all((Path(root) / d).is_dir() for d in PUBLIC_ROOTS.values())


def read_manifest(root: Path) -> dict[str, Any] | None:
    path = Path(root) / MANIFEST
    if not path.is_file():
        return None
    data = read_json(path)
    if not isinstance(data, dict):
        raise FormatError(path, "top level", "expected an object")
    return data


def manifest_segments(manifest: dict[str, Any] | None) -> int | None:
    """Segments per clip recorded in a generated or exported manifest."""
    if not manifest:
        return None
    if isinstance(manifest.get("segments_per_clip"), int):
        return manifest["segments_per_clip"]
    duration = (manifest.get("config") or {}).get("clip_duration_s")
    return int(round(duration / SEGMENT_S)) if isinstance(duration, (int, float)) and duration > 0 else None


def manifest_mfcc(manifest: dict[str, Any] | None) -> str:
    """The MFCC pipeline a manifest records (``evids`` when none)."""
    value = (manifest or {}).get("mfcc")
    pipeline = value.get("pipeline", "evids") if isinstance(value, dict) else value or "evids"
    return pipeline if pipeline in MFCC_PIPELINES else "evids"


def _indexed(folder: Path, pattern: re.Pattern) -> dict[str, list[tuple[int, Path]]]:
    out: dict[str, list[tuple[int, Path]]] = {}
    if folder.is_dir():
        for p in folder.iterdir():
            m = pattern.match(p.name)
            if m:
                out.setdefault(m.group(1), []).append((int(m.group(2)), p))
    return {k: sorted(v) for k, v in out.items()}


def _audio_files(folder: Path) -> dict[str, Path]:
    """WAVs by clip number (the first digit run of the name, as the public code takes it)."""
    out = {}
    for p in folder.iterdir() if folder.is_dir() else []:
        if p.suffix.lower() == ".wav" and (m := re.search(r"\d+", p.stem)):
            out[m.group(0)] = p
    return out


def _audio_segments(path: Path) -> int:
    import soundfile

    try:
        info = soundfile.info(str(path))
    except (RuntimeError, soundfile.LibsndfileError) as exc:
        raise FormatError(path, "", f"not a readable WAV ({exc})") from None
    return int(info.frames // int(round(SEGMENT_S * info.samplerate)))


def _consecutive(items: list[tuple[int, Path]], what: str, folder: Path, need: int) -> list[Path]:
    if not items:
        raise FormatError(folder, what, "no files")
    start = items[0][0]
    if start not in (0, 1):
        raise FormatError(folder, what, f"indices must start at 0 or 1, first file is {items[0][1].name}")
    for expected, (i, path) in enumerate(items, start=start):
        if i != expected:
            raise FormatError(folder, what, f"index {expected} is missing (next file is {path.name}); "
                              "every later segment would shift")
    if len(items) < need:
        raise FormatError(folder, what, f"{len(items)} files but the clip needs {need}")
    return [p for _, p in items]


def _clip(label: str, scenario: str, number: str, audio: Path, frames: list[tuple[int, Path]] | None,
          rf: list[tuple[int, Path]] | None, video_dir: Path, rf_dir: Path, labels_json: Path | None,
          expected: int | None, split: str | None, iq: Path | None) -> ClipFiles:
    """One clip with its segment count S and every modality checked against S."""

    if labels_json is not None:
        truth = read_json(labels_json)
        try:
            present = truth["segments"]["drone_present"]
            if not isinstance(present, list):
                raise TypeError
            expected = len(present)
        except (KeyError, TypeError):
            raise FormatError(labels_json, "key 'segments.drone_present'",
                              "missing (per-segment ground truth)") from None
    have = _audio_segments(audio)
    s = expected if expected is not None else have
    if have < s:
        raise FormatError(audio, "length", f"holds {have} segments of {SEGMENT_S} s but the clip has {s} "
                          "(truncated WAV?)")
    if s < 1:
        raise FormatError(audio, "length", f"shorter than one {SEGMENT_S} s segment")
    if frames is None:
        raise FormatError(video_dir, f"clip {number}", "no video frames (<n>_frame_<i>.jpg)")
    if rf is None:
        raise FormatError(rf_dir, f"clip {number}", "no RF spectrogram images")
    frame_paths = _consecutive(frames, f"clip {number} video frames", video_dir, FRAMES_PER_SEGMENT * s)
    rf_paths = _consecutive(rf, f"clip {number} RF images", rf_dir, s)
    return ClipFiles(label, scenario, number, audio, frame_paths, rf_paths, labels_json, split, s, iq)


def _add(clips: list[ClipFiles], skipped, strict: bool, make) -> None:
    try:
        clips.append(make())
    except FormatError as err:
        if strict:
            raise
        skipped.add(err)


def _discover_generated(root: Path, manifest, strict: bool, skipped) -> list[ClipFiles]:
    expected = manifest_segments(manifest)
    clips: list[ClipFiles] = []
    for label in LABELS:
        audio_label = root / "audio" / label
        if not audio_label.is_dir():
            continue
        for scen_dir in sorted(p for p in audio_label.iterdir() if p.is_dir()):
            scenario = scen_dir.name
            video_dir, rf_dir = root / "video" / label / scenario, root / "rf" / label / scenario
            audio = _audio_files(scen_dir)
            frames, rf = _indexed(video_dir, _VIDEO_RE), _indexed(rf_dir, _RF_RE)
            for number in sorted(audio, key=int):
                if manifest is None and (number not in frames or number not in rf):
                    continue          # a bare folder: clips without every modality are not clips
                lj = root / "labels" / label / scenario / f"{number}.json"
                iq = root / "rf_iq" / label / scenario / f"{number}.npy"
                _add(clips, skipped, strict, lambda: _clip(
                    label, scenario, number, audio[number], frames.get(number), rf.get(number), video_dir, rf_dir,
                    lj if lj.is_file() else None, expected, None, iq if iq.is_file() else None))
    return clips


def _discover_public(root: Path, manifest, strict: bool, skipped) -> list[ClipFiles]:
    expected = manifest_segments(manifest) or PUBLIC_SEGMENTS
    clips: list[ClipFiles] = []
    for split in PUBLIC_SPLITS:
        sub = PUBLIC_SUBFOLDERS[split]
        for label in LABELS:
            audio_label = root / PUBLIC_ROOTS["audio"] / split / label
            if not audio_label.is_dir():
                continue
            for scen_dir in sorted((p for p in audio_label.iterdir() if p.is_dir()), key=lambda p: _natural(p.name)):
                scenario = scen_dir.name
                video_dir = root / PUBLIC_ROOTS["video"] / split / label / scenario / sub["video"]
                rf_dir = root / PUBLIC_ROOTS["rf"] / split / label / scenario / sub["rf"]
                audio = _audio_files(scen_dir)
                frames, rf = _indexed(video_dir, _VIDEO_RE), _indexed(rf_dir, _RF_RE)
                for number in sorted(audio, key=int):
                    lj = root / PUBLIC_EXTRAS["labels"] / split / label / scenario / f"{number}.json"
                    iq = root / PUBLIC_EXTRAS["rf_iq"] / split / label / scenario / f"{number}.sigmf-meta"
                    _add(clips, skipped, strict, lambda: _clip(
                        label, scenario, number, audio[number], frames.get(number), rf.get(number), video_dir, rf_dir,
                        lj if lj.is_file() else None, expected, split, iq if iq.is_file() else None))
    return clips


def _natural(name: str) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]


def discover_clips(root: str | Path, *, strict: bool = True, skipped=None) -> list[ClipFiles]:
    """All clips under ``root`` (generated or public layout), each checked; sorted by layout order."""
    root = Path(root)
    skipped = skipped if skipped is not None else Skipped()
    manifest = read_manifest(root)
    if manifest is not None and manifest.get("complete") is False:
        raise ValueError(f"root: {str(root)!r} is an unfinished generated dataset (its manifest says complete: "
                         "false); re-run the same `evids generate` command to finish it")
    if is_public_layout(root):
        return _discover_public(root, manifest, strict, skipped)
    for modality in ("audio", "video", "rf"):
        if not (root / modality).is_dir():
            raise ValueError(f"root: {str(root)!r} has no {modality}/ folder (expected the generated TRIDENT layout "
                             "audio/, video/, rf/ or the public one "
                             f"{', '.join(p + '/' for p in PUBLIC_ROOTS.values())})")
    return _discover_generated(root, manifest, strict, skipped)


def _read_image(path: Path, grayscale_ok: bool) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise FormatError(path, "", "not a readable image")
    if img.ndim == 3:
        img = cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2RGB)
    elif not grayscale_ok:
        img = np.repeat(img[..., None], 3, axis=-1)
    if img.shape[:2] != (IMAGE_PX, IMAGE_PX):
        img = cv2.resize(img, (IMAGE_PX, IMAGE_PX), interpolation=cv2.INTER_AREA)
    return img


class TridentDataset:
    """Aligned (audio MFCC, video segment, RF spectrogram, label, clip id, segment index) from a root.

    ``mfcc``: ``evids`` / ``trident`` / None (the manifest's). ``strict=False`` skips bad clips and
    lists them in ``skipped``."""

    def __init__(self, root: str | Path, *, mfcc: str | None = None, strict: bool = True):
        self.root = Path(root)
        if mfcc is not None and mfcc not in MFCC_PIPELINES:
            raise ValueError(f"mfcc must be one of {', '.join(MFCC_PIPELINES)}, got {mfcc!r}")
        self.skipped = Skipped()
        self.clips = discover_clips(self.root, strict=strict, skipped=self.skipped)
        if self.skipped:
            import warnings

            warnings.warn(f"{self.root}: skipped {len(self.skipped)} bad clip(s) (strict=False); first: "
                          f"{self.skipped.reasons[0]}", SkippedRowsWarning, stacklevel=2)
        self.mfcc_pipeline = mfcc or manifest_mfcc(read_manifest(self.root))
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

    def _mfcc(self, clip: ClipFiles) -> np.ndarray:
        import soundfile

        try:
            if self.mfcc_pipeline == "trident":
                return mfcc_trident(clip.audio, clip.n_segments)
            audio, rate = soundfile.read(str(clip.audio), dtype="float32", always_2d=True)
        except (RuntimeError, soundfile.LibsndfileError, EOFError) as exc:
            raise FormatError(clip.audio, "", f"not a readable WAV ({exc})") from None
        return mfcc_segments(audio.mean(axis=1), float(rate), clip.n_segments)

    @staticmethod
    def _truth(clip: ClipFiles) -> dict | None:
        if clip.labels_json is None:
            return None
        data = read_json(clip.labels_json)
        segments = data.get("segments") if isinstance(data, dict) else None
        keys = ("video_visible", "audio_audible", "rf_observable")
        if not isinstance(segments, dict) or any(not isinstance(segments.get(k), list)
                                                 or len(segments[k]) < clip.n_segments
                                                 for k in keys):
            raise FormatError(clip.labels_json, "key 'segments'",
                              f"needs {', '.join(keys)} with {clip.n_segments} entries")
        return segments

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


def load_iq(clip: ClipFiles) -> np.ndarray | None:
    """The clip's saved I/Q, complex64 (segments, samples): the generated ``.npy`` or the public
    export's SigMF recording; None when the dataset has none."""
    if clip.iq is None:
        return None
    if clip.iq.suffix == ".npy":
        return np.load(clip.iq)[: clip.n_segments]
    from simulator.formats.sigmf import read_sigmf

    return read_sigmf(clip.iq)[0][: clip.n_segments]


def iter_trident(root: str | Path) -> Iterator[TridentSegment]:
    """Every aligned segment under ``root`` in clip order."""
    yield from TridentDataset(root)


# --------------------------------------------------------------------------------------------
# Export: generated layout -> the public TRIDENT layout
# --------------------------------------------------------------------------------------------

def assign_splits(clips: list[ClipFiles], test_fraction: float) -> dict[str, str]:
    """Clip id -> "Train"/"Test": per label, in clip order, clip j is Test when
    floor((j + 1) f + 1/2) > floor(j f + 1/2), so round(n f) of a label's n clips, evenly spread.

    With f > 0 every split holds every label (the public loader opens Train/<label> and Test/<label>
    and raises FileNotFoundError on a missing one): a label the rule left without Test clips gets
    its last clip in Test, one left without Train clips its first in Train; a label with a single
    clip cannot be in both, which is refused (UserInputError naming the label and the fraction)."""
    import math

    from scenes.errors import UserInputError

    if not 0.0 <= test_fraction < 1.0:
        raise ValueError(f"test_fraction must be in [0, 1), got {test_fraction}")
    out: dict[str, str] = {}
    for label in LABELS:
        mine = [c for c in clips if c.label == label]
        for j, c in enumerate(mine):
            test = math.floor((j + 1) * test_fraction + 0.5) > math.floor(j * test_fraction + 0.5)
            out[c.clip_id] = "Test" if test else "Train"
        if test_fraction == 0.0 or not mine:
            continue
        if len(mine) < 2:
            raise UserInputError(f"--test-fraction {test_fraction}: label {label!r} has {len(mine)} clip, so Train and "
                                 "Test cannot both hold it (the TRIDENT loader needs every label in every split); "
                                 "generate more clips or export with --test-fraction 0")
        if all(out[c.clip_id] == "Train" for c in mine):
            out[mine[-1].clip_id] = "Test"
        if all(out[c.clip_id] == "Test" for c in mine):
            out[mine[0].clip_id] = "Train"
    return out


def _jpeg(image: np.ndarray, quality: int = 95) -> bytes:
    return _encode_image(image, ".jpg", quality)


def export_public(src_root: str | Path, out: str | Path, *, mfcc: str = "evids", test_fraction: float = 0.2,
                  jpeg_quality: int = 95, progress: bool = False) -> Path:
    """Write a generated TRIDENT dataset in the public layout under ``out`` (an empty folder).

    WAVs and video JPEGs are copied byte for byte (frames renamed 1-based); RF spectrograms are
    re-encoded as JPEG (1-based); ``Labels/`` and ``RF_IQ/`` (conforming SigMF) are extras; the
    manifest records the MFCC pipeline readers should use (``mfcc``), the split and the source."""
    import hashlib

    from simulator.formats.sigmf import write_recording

    if mfcc not in MFCC_PIPELINES:
        raise ValueError(f"mfcc must be one of {', '.join(MFCC_PIPELINES)}, got {mfcc!r}")
    src_root, out = Path(src_root), Path(out)
    source_manifest = read_manifest(src_root) or {}
    clips = discover_clips(src_root)
    splits = assign_splits(clips, test_fraction)
    rf_cfg = (source_manifest.get("config") or {}).get("rf") or {}
    items: Iterable[ClipFiles] = clips
    if progress:
        from rich.progress import track

        items = track(clips, description="export trident")
    entries = []
    for clip in items:
        split = splits[clip.clip_id]
        sub = PUBLIC_SUBFOLDERS[split]
        rel = Path(split) / clip.label / clip.scenario
        audio_dir = out / PUBLIC_ROOTS["audio"] / rel
        video_dir = out / PUBLIC_ROOTS["video"] / rel / sub["video"]
        rf_dir = out / PUBLIC_ROOTS["rf"] / rel / sub["rf"]
        for d in (audio_dir, video_dir, rf_dir):
            d.mkdir(parents=True, exist_ok=True)
        (audio_dir / f"{clip.number}.wav").write_bytes(clip.audio.read_bytes())
        for i, frame in enumerate(clip.frames[: FRAMES_PER_SEGMENT * clip.n_segments], start=1):
            (video_dir / f"{clip.number}_frame_{i}.jpg").write_bytes(frame.read_bytes())
        for j, image in enumerate(clip.rf[: clip.n_segments], start=1):
            (rf_dir / f"{clip.number}_frame_{j}.jpg").write_bytes(_jpeg(_read_image(image, grayscale_ok=True),
                                                                        jpeg_quality))
        if clip.labels_json is not None:
            dest = out / PUBLIC_EXTRAS["labels"] / rel / f"{clip.number}.json"
            dest.parent.mkdir(parents=True, exist_ok=True)
            dest.write_bytes(clip.labels_json.read_bytes())
        saved_iq = load_iq(clip) if clip.iq is not None and rf_cfg else None
        if saved_iq is not None:
            info = json.loads(clip.labels_json.read_text()).get("rf", {}) if clip.labels_json else {}
            iq = saved_iq.astype(np.complex64)
            starts = info.get("capture_start_s") or [s * SEGMENT_S for s in range(iq.shape[0])]
            base = out / PUBLIC_EXTRAS["rf_iq"] / rel / clip.number
            base.parent.mkdir(parents=True, exist_ok=True)
            write_recording(base, iq, sample_rate_hz=rf_cfg["sample_rate_hz"],
                            center_frequency_hz=rf_cfg["center_frequency_hz"], capture_start_s=starts[: iq.shape[0]],
                            label=clip.label)
        entries.append({"clip": clip.clip_id, "split": split, "segments": clip.n_segments})
    durations = sorted({c.n_segments * SEGMENT_S for c in clips})
    manifest = {
        "format": "trident-public", "generator": "simulator.formats.trident.export_public",
        "mfcc": {"pipeline": mfcc, **({"sample_rate_hz": TRIDENT_SAMPLE_RATE_HZ, "decimation": TRIDENT_DECIMATION,
                                       "n_fft": TRIDENT_N_FFT, "hop_length": TRIDENT_HOP, "n_mfcc": MFCC_N_MFCC}
                                      if mfcc == "trident" else
                                      {"n_fft": MFCC_N_FFT, "n_mels": MFCC_N_MELS, "n_mfcc": MFCC_N_MFCC,
                                       "top_db": MFCC_TOP_DB})},
        "segments_per_clip": clips[0].n_segments if len({c.n_segments for c in clips}) == 1 else None,
        "clip_duration_s": durations[0] if len(durations) == 1 else durations,
        "test_fraction": test_fraction, "clips": entries,
        "source": {"seed": source_manifest.get("seed"), "content_sha256": source_manifest.get("content_sha256"),
                   "manifest_sha256": hashlib.sha256((src_root / MANIFEST).read_bytes()).hexdigest()
                   if (src_root / MANIFEST).is_file() else None},
    }
    (out / MANIFEST).write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n")
    return out
