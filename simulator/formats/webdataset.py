"""WebDataset shards (the ``webdataset`` package) for streaming generated data into training loops:
writer, reader and spec (docs/FORMATS.md, "WebDataset").

``<out>/<split>/<split>-000000.tar``, ``-000001.tar``, ... (a new shard once one passes
``shard_bytes``, ~500 MB by default); every member has mtime 0, owner ``evids`` and mode 0444, so
the same dataset gives byte-identical shards.

* native datasets, one sample per frame pair, key ``<sequence>_<NNNNNN>`` (1-based frame):
  ``rgb.png`` (8-bit RGB), ``thermal.png`` (16-bit counts, kelvin = counts x ``kelvin_per_count``),
  ``json`` (sequence, split, frame index and time, ``kelvin_per_count``, the frame's label records
  per camera: id, class, exist, box [x, y, w, h], range and thermal contrast as in labels.json);
* TRIDENT clip datasets, one sample per 0.25 s segment, key ``<Label>_<scenario>_<n>_<SS>``:
  ``mfcc.npy`` (1, 40, 40) float32 (pipeline named in the JSON), ``frame0.jpg`` .. ``frame6.jpg``,
  ``rf.png``, ``json`` (label, label_id, clip_id, segment, mfcc pipeline, observability when known).
"""
from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any, Iterable, Iterator

import numpy as np

SHARD_BYTES = 500_000_000
TAR_OPTIONS = {"mtime": 0.0, "user": "evids", "group": "evids", "mode": 0o444, "encoder": False}


def _writer(folder: Path, split: str, shard_bytes: int):
    try:
        import webdataset as wds
    except ImportError:
        from scenes.errors import UserInputError

        raise UserInputError("the webdataset export needs the 'webdataset' package: pip install "
                             "'evids[formats]'") from None

    folder.mkdir(parents=True, exist_ok=True)
    pattern = str(folder / split).replace("%", "%%") + "/" + split.replace("%", "%%") + "-%06d.tar"
    (folder / split).mkdir(parents=True, exist_ok=True)
    return wds.ShardWriter(pattern, maxsize=shard_bytes, verbose=0, **TAR_OPTIONS)


def _json_bytes(data: dict[str, Any]) -> bytes:
    return (json.dumps(data, sort_keys=True, allow_nan=False) + "\n").encode()


def export_native_webdataset(entries: Iterable[dict[str, Any]], out: Path, *, shard_bytes: int = SHARD_BYTES,
                             progress: bool = False) -> Path:
    """Shards of frame samples for native manifest entries (name, split, path), per split."""
    from simulator.formats.native import frame_name, load_labels, load_meta

    out = Path(out)
    if shard_bytes <= 0:
        raise ValueError(f"shard_bytes must be > 0, got {shard_bytes}")
    by_split: dict[str, list[dict[str, Any]]] = {}
    for e in entries:
        by_split.setdefault(e["split"], []).append(e)
    for split, items in sorted(by_split.items()):
        if progress:
            from rich.progress import track

            items = list(track(items, description=f"export webdataset {split}"))
        writer = _writer(out, split, shard_bytes)
        try:
            for e in items:
                seq = Path(e["path"])
                meta, labels = load_meta(seq), load_labels(seq)
                for frame in labels["frames"]:
                    i = frame["index"]
                    info = {"sequence": e["name"], "split": split, "frame_index": i, "frame_number": i + 1,
                            "time_s": i / meta["frame_rate_hz"],
                            "kelvin_per_count": meta["cameras"]["thermal"]["kelvin_per_count"],
                            "objects": labels["objects"], "rgb": frame["rgb"], "thermal": frame["thermal"]}
                    writer.write({"__key__": f"{e['name']}_{i + 1:06d}",
                                  "rgb.png": (seq / "rgb" / frame_name(i, "png")).read_bytes(),
                                  "thermal.png": (seq / "thermal" / frame_name(i, "png")).read_bytes(),
                                  "json": _json_bytes(info)})
        finally:
            writer.close()
    return out


def export_trident_webdataset(src_root: str | Path, out: str | Path, *, shard_bytes: int = SHARD_BYTES,
                              mfcc: str | None = None, progress: bool = False) -> Path:
    """Shards of segment samples for a TRIDENT clip dataset (one split, ``all``)."""
    import cv2

    from simulator.formats.trident import TridentDataset

    out = Path(out)
    ds = TridentDataset(src_root, mfcc=mfcc)
    clips = ds.clips
    if progress:
        from rich.progress import track

        clips = list(track(clips, description="export webdataset"))
    writer = _writer(out, "all", shard_bytes)
    try:
        for clip in clips:
            for seg in ds.iter_clip(clip):
                s = seg.segment_index
                sample: dict[str, Any] = {"__key__": f"{clip.clip_id.replace('/', '_')}_{s:02d}"}
                buf = io.BytesIO()
                np.save(buf, seg.audio_mfcc.astype(np.float32))
                sample["mfcc.npy"] = buf.getvalue()
                for k, path in enumerate(clip.frames[s * 7:(s + 1) * 7]):
                    sample[f"frame{k}.jpg"] = path.read_bytes()
                ok, png = cv2.imencode(".png", np.clip(np.rint(seg.rf * 255), 0, 255).astype(np.uint8)[..., ::-1]
                                       if seg.rf.ndim == 3 else np.clip(np.rint(seg.rf * 255), 0, 255).astype(np.uint8))
                if not ok:
                    raise RuntimeError(f"cannot encode the RF image of {clip.clip_id} segment {s}")
                sample["rf.png"] = png.tobytes()
                sample["json"] = _json_bytes({"label": clip.label, "label_id": seg.label, "clip_id": seg.clip_id,
                                              "segment": s, "mfcc": ds.mfcc_pipeline,
                                              "observability": seg.observability})
                writer.write(sample)
    finally:
        writer.close()
    return out


def shards(root: Path, split: str) -> list[Path]:
    """The shard files of one split, in order."""
    return sorted((Path(root) / split).glob(f"{split}-*.tar"))


def iter_samples(paths: Iterable[Path]) -> Iterator[dict[str, Any]]:
    """Raw samples (``__key__`` + bytes per extension, ``json`` parsed) of shards, in order."""
    import webdataset as wds

    urls = [str(p) for p in paths]
    if not urls:
        return
    for sample in wds.WebDataset(urls, shardshuffle=False, empty_check=False):
        out = {k: v for k, v in sample.items() if not k.startswith("__") or k == "__key__"}
        if "json" in out:
            out["json"] = json.loads(out["json"])
        yield out
