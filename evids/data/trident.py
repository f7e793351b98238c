"""Loader for TRIDENT-layout tri-modal data: generated folders and the public TRIDENT release.

Layout: ``<root>/{audio,video,rf}/{Drone,Background}/<scenario>/...`` with, per clip number n,
``audio/.../<n>.wav``, ``video/.../<n>_frame_<i>.jpg`` (28 fps) and one RF spectrogram image per
0.25 s segment whose name starts with ``<n>_`` and ends with the segment index (``<n>_rf_<s>.png``
here). Clips are matched across modalities by (label, scenario folder, n). Generated folders also
carry ``labels/.../<n>.json`` with per-segment observability ground truth, returned when present.

A clip yields min(audio segments, video frames // 7, RF images) segments, each as a
:class:`TridentSegment`: MFCC (1, 40, 40) float32 computed from the WAV exactly as the generator
does (``simulator.trident.mfcc_segments``), video (7, 112, 112, 3) uint8 RGB, RF spectrogram
(112, 112) float32 in [0, 1] (or (112, 112, 3) for colour images), label (Drone -> 0, as the
TRIDENT reference code), clip id and segment index.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

LABELS = ("Drone", "Background")
FRAMES_PER_SEGMENT = 7
IMAGE_PX = 112
_VIDEO_RE = re.compile(r"^(\d+)_frame_(\d+)\.jpe?g$", re.IGNORECASE)
_RF_RE = re.compile(r"^(\d+)_(?:.*?)(\d+)\.(?:png|jpe?g)$", re.IGNORECASE)
_AUDIO_RE = re.compile(r"^(\d+)(?:_.*)?\.wav$", re.IGNORECASE)


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

        from simulator.trident import mfcc_segments

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
