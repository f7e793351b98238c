"""Dataset preparation for experiments: generate (or take) a TRIDENT-layout folder, load it through
:class:`simulator.formats.trident.TridentDataset` (the same path for generated, exported and real data),
keep each clip's waveform (for audio noise before the MFCC) and I/Q (for RF noise before the STFT)
when present, and split clips (stratified by label, seeded) into train/val/test."""
from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evids.modalities import OBSERVABILITY_KEY
from harness.experiments.config import DatasetConfig, SplitConfig
from scenes.errors import UserInputError
from simulator.seeding import STREAMS

if TYPE_CHECKING:
    from simulator.formats.trident import TridentSegment

SPLITS = ("train", "val", "test")


@dataclass
class ClipArrays:
    """One clip, all segments in time order."""

    clip_id: str
    label: int                       # 0 Drone, 1 Background
    mfcc: np.ndarray                 # (S, 1, 40, 40) float32 (clean, as the loader computes it)
    video: np.ndarray                # (S, 7, 112, 112, 3) uint8
    rf: np.ndarray                   # (S, 112, 112) float32 in [0, 1]
    audio: np.ndarray                # (N,) float32 waveform (mono)
    sample_rate_hz: float
    iq: np.ndarray | None = None     # (S, n) complex64 or None
    observability: dict[str, np.ndarray] = field(default_factory=dict)
    scene: str = ""                  # split unit: the drawn scene (generated) or the scenario folder
    split: str | None = None         # the dataset's own split assignment, when it carries one
    twin: str | None = None          # clip_id of the counterfactual twin (same scene, drone swapped)
    drone_px: np.ndarray | None = None   # (S,) apparent drone size per segment (px), generated data only
    conditions: dict = field(default_factory=dict)
    snr_db: dict[str, np.ndarray] = field(default_factory=dict)   # per-segment truth: audio, rf link (NaN: none)

    def __post_init__(self) -> None:
        if not self.scene:
            self.scene = self.clip_id

    @property
    def n_segments(self) -> int:
        return int(self.mfcc.shape[0])


@dataclass
class Prepared:
    """The loaded clips, the split and the RF image scaling (for spectrogram-domain noise)."""

    root: Path
    clips: list[ClipArrays]
    split: dict[str, list[int]]
    rf_range_db: float
    rf_config: dict | None
    generated: bool


def _render_at(render_px: int, scenario, seed, n_frames, width_px, height_px, layout=None):
    """Video frames rendered at ``render_px`` and resized to the clip's size."""
    import cv2

    from simulator.dataset.sequence import render_rgb_video

    small = render_rgb_video(scenario, seed, n_frames, render_px, render_px, layout=layout)
    if render_px == width_px and render_px == height_px:
        return small
    return np.stack([cv2.resize(f, (width_px, height_px), interpolation=cv2.INTER_LINEAR) for f in small])


def _frames_fn(render_px: int):
    import functools

    return functools.partial(_render_at, render_px)  # picklable: clips are written in worker processes


def ensure_dataset(cfg: DatasetConfig, run_dir: Path, progress: bool = True) -> tuple[Path, bool]:
    """The dataset folder: ``cfg.path``, or ``run_dir/data`` generated once (reused when complete)."""
    if cfg.path is not None:
        root = Path(cfg.path)
        if not root.is_dir():
            raise UserInputError(f"dataset.path: {str(root)!r} is not a folder")
        return root, False
    root = run_dir / "data"
    from simulator.dataset.driver import read_old_manifest

    if read_old_manifest(root).get("complete", True) is True and (root / "manifest.json").is_file():
        return root, True  # complete (or written before manifests said so); an unfinished one is resumed
    from simulator.dataset.trident import generate_trident, load_trident_config

    if cfg.generate is None:       # DatasetConfig holds exactly one of path and generate
        raise UserInputError("dataset: give dataset.generate (a generation config) or dataset.path (a folder)")
    gen = load_trident_config(cfg.generate)
    if cfg.clip_duration_s is not None:
        gen = gen.model_copy(update={"clip_duration_s": cfg.clip_duration_s})
        gen = type(gen).model_validate(gen.model_dump())
    frames = _frames_fn(cfg.render_px) if cfg.render_px is not None else None
    generate_trident(gen, root, cfg.seed, n_clips=cfg.n_clips, progress=progress, render_frames=frames,
                     workers=cfg.workers)
    return root, True


def _observability(seg: TridentSegment) -> dict[str, bool]:
    """A segment's observability record (a clip's segments have one each, or none has)."""
    if seg.observability is None:
        raise UserInputError(f"clip {seg.clip_id}: segment {seg.segment_index} has no observability record "
                             "while the clip's first segment has one")
    return seg.observability


def load_clips(root: Path, progress: bool = True) -> list[ClipArrays]:
    """Every clip under a TRIDENT-layout root, through the shared loader."""
    import soundfile

    from simulator.formats.trident import ClipFiles, TridentDataset, load_iq

    root = Path(root)
    try:
        ds = TridentDataset(root)
    except ValueError as exc:
        raise UserInputError(str(exc)) from None
    if not ds.clips:
        raise UserInputError(f"dataset {str(root)!r} holds no complete clips (audio + video + rf)")
    items: Iterable[ClipFiles] = ds.clips
    if progress:
        from rich.progress import track

        items = track(items, description="loading clips", total=len(ds.clips))
    out = []
    for clip in items:
        segs = list(ds.iter_clip(clip))
        if not segs:
            continue
        audio, rate = soundfile.read(str(clip.audio), dtype="float32", always_2d=True)
        iq = load_iq(clip)             # generated rf_iq/<n>.npy or the public export's RF_IQ SigMF
        iq = None if iq is None else iq[: len(segs)]
        obs = {}
        if segs[0].observability is not None:
            truth = [_observability(s) for s in segs]
            obs = {k: np.array([t[k] for t in truth]) for k in OBSERVABILITY_KEY.values()}
        info = _clip_info(clip, len(segs))
        out.append(ClipArrays(
            clip_id=clip.clip_id, label=int(segs[0].label),
            mfcc=np.stack([s.audio_mfcc for s in segs]).astype(np.float32),
            video=np.stack([s.video for s in segs]).astype(np.uint8),
            rf=np.stack([s.rf if s.rf.ndim == 2 else s.rf.mean(-1) for s in segs]).astype(np.float32),
            audio=audio.mean(axis=1), sample_rate_hz=float(rate), iq=iq, observability=obs, **info))
    return out


def _clip_info(clip, n_segments: int) -> dict:
    """Scene, split, twin and drone size of a clip from its labels JSON (generated data), else the
    scenario folder as the scene (a TRIDENT scenario folder is one recording session)."""
    public = {"Train": "train", "Test": "test"}.get(getattr(clip, "split", None) or "")
    info: dict = {"scene": f"{clip.label}/{clip.scenario}", "split": public, "twin": None, "drone_px": None,
                  "conditions": {}, "snr_db": {}}
    if clip.labels_json is None or not Path(clip.labels_json).is_file():
        return info
    try:
        meta = json.loads(Path(clip.labels_json).read_text())
    except (OSError, json.JSONDecodeError):
        return info
    if meta.get("scene"):
        info["scene"] = str(meta["scene"])
    if meta.get("split") in SPLITS:
        info["split"] = meta["split"]
    if meta.get("twin") is not None:
        other = "Background" if clip.label == "Drone" else "Drone"
        info["twin"] = f"{other}/{clip.scenario}/{meta['twin']}"
    if meta.get("drone_px") is not None:
        info["drone_px"] = np.asarray(meta["drone_px"], np.float64)[:n_segments]
    info["conditions"] = dict(meta.get("conditions") or {})
    seg = meta.get("segments") or {}
    snr = {}
    for key, name in (("audio_snr_db", "audio"), ("rf_link_snr_db", "rf")):
        if isinstance(seg.get(key), list):
            snr[name] = np.array([np.nan if v is None else float(v) for v in seg[key]], np.float64)[:n_segments]
    info["snr_db"] = snr
    return info


def split_clips(clips: list[ClipArrays], cfg: SplitConfig) -> dict[str, list[int]]:
    """Scene-disjoint split: every clip of one scene (a drone clip and its twin, or one scenario
    folder) lands in the same split. ``cfg.source == "dataset"`` keeps the dataset's own assignment
    when every clip carries one; otherwise scenes are shuffled (seeded) and assigned by fraction,
    stratified by the scene's label set. Too few scenes for three disjoint splits -> UserInputError.
    """
    if cfg.source == "dataset" and clips and all(c.split is not None for c in clips) and \
            all(any(c.split == s for c in clips) for s in SPLITS):
        out = {s: sorted(i for i, c in enumerate(clips) if c.split == s) for s in SPLITS}
    else:              # no recorded split, or one without validation clips (the public Train/Test)
        out = _split_by_scene(clips, cfg)
    for s in SPLITS:
        if not out[s]:
            raise UserInputError(f"split: the {s} split is empty with {len(clips)} clips in "
                                 f"{len({c.scene for c in clips})} scenes; use more scenes")
    check_scene_disjoint(clips, out)
    return out


def _split_by_scene(clips: list[ClipArrays], cfg: SplitConfig) -> dict[str, list[int]]:
    groups: dict[str, list[int]] = {}
    for i, c in enumerate(clips):
        groups.setdefault(c.scene if cfg.unit == "scene" else c.clip_id, []).append(i)
    strata: dict[tuple, list[str]] = {}
    for name in sorted(groups):
        strata.setdefault(tuple(sorted({clips[i].label for i in groups[name]})), []).append(name)
    if len(groups) < len(SPLITS):
        raise UserInputError(f"split.unit: {cfg.unit!r} splits need >= {len(SPLITS)} {cfg.unit} groups to keep "
                             f"train/val/test disjoint, the dataset has {len(groups)}")
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, STREAMS["clip_split"]]))
    out: dict[str, list[int]] = {s: [] for s in SPLITS}
    for key in sorted(strata):
        names = strata[key]
        names = [names[j] for j in rng.permutation(len(names))]
        n = len(names)
        n_test, n_val = int(round(cfg.test_fraction * n)), int(round(cfg.val_fraction * n))
        if n >= 3:
            n_test, n_val = max(1, n_test), max(1, n_val)
            n_test = min(n_test, n - 2)
            n_val = min(n_val, n - n_test - 1)
        for j, name in enumerate(names):
            s = "test" if j < n_test else "val" if j < n_test + n_val else "train"
            out[s] += groups[name]
    return {s: sorted(v) for s, v in out.items()}


def check_scene_disjoint(clips: list[ClipArrays], split: dict[str, list[int]]) -> None:
    """Raise UserInputError when one scene appears in two splits (the split unit is recorded)."""
    seen: dict[str, str] = {}
    for s, idx in split.items():
        for i in idx:
            prev = seen.setdefault(clips[i].scene, s)
            if prev != s:
                raise UserInputError(f"split: scene {clips[i].scene!r} appears in both {prev} and {s}; "
                                     "splits must be scene-disjoint")


def prepare(cfg_dataset: DatasetConfig, cfg_split: SplitConfig, run_dir: Path, progress: bool = True) -> Prepared:
    """Generate/locate, load and split the dataset."""
    root, generated = ensure_dataset(cfg_dataset, run_dir, progress)
    clips = load_clips(root, progress)
    rf_range, rf_cfg = 60.0, None
    manifest = root / "manifest.json"
    if manifest.is_file():
        try:
            rf_cfg = json.loads(manifest.read_text()).get("config", {}).get("rf")
            if rf_cfg and "spectrogram_range_db" in rf_cfg:
                rf_range = float(rf_cfg["spectrogram_range_db"])
        except (json.JSONDecodeError, AttributeError):
            rf_cfg = None
    return Prepared(root, clips, split_clips(clips, cfg_split), rf_range, rf_cfg, generated)


def stack(clips: list[ClipArrays], idx: list[int], key: str) -> np.ndarray:
    """Concatenate one array over the given clips' segments."""
    return np.concatenate([getattr(clips[i], key) for i in idx])


def labels_of(clips: list[ClipArrays], idx: list[int]) -> np.ndarray:
    return np.concatenate([np.full(clips[i].n_segments, clips[i].label, np.int64) for i in idx])


def scene_ids_of(clips: list[ClipArrays], idx: list[int]) -> np.ndarray:
    """Per-segment scene id: the cluster unit of every test statistic (twins share a scene)."""
    return np.concatenate([np.full(clips[i].n_segments, clips[i].scene, dtype=object) for i in idx])


def clip_ids_of(clips: list[ClipArrays], idx: list[int]) -> np.ndarray:
    return np.concatenate([np.full(clips[i].n_segments, clips[i].clip_id, dtype=object) for i in idx])
