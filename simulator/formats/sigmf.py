"""SigMF recordings of saved RF I/Q (the ``sigmf`` package): writer, reader and spec (docs/FORMATS.md, "SigMF").

A clip's I/Q is ``S`` captures of ``n`` complex64 samples each (one per 0.25 s segment, not
contiguous in time). Two ways to describe it, both SigMF 1.x and both read by :func:`read_sigmf`:

* **beside the .npy** (:func:`write_npy_meta`): ``<n>.sigmf-meta`` next to ``<n>.npy`` as a
  Non-Conforming Dataset (``core:dataset`` = the .npy file name, ``core:header_bytes`` = its NumPy
  header), so nothing is stored twice;
* **conforming** (:func:`write_recording`): ``<base>.sigmf-data`` (raw ``cf32_le``, captures back to
  back) + ``<base>.sigmf-meta``, what GNU Radio, inspectrum and TorchSig open directly.

Metadata: global ``core:datatype`` cf32_le, ``core:sample_rate``, ``core:version``, ``core:recorder``
``evids``, ``core:description``; one capture per segment (``core:sample_start`` = s * n,
``core:frequency`` = centre frequency, ``core:header_bytes`` on the first for the .npy form); one
annotation per segment (``core:label`` = the clip class, ``core:comment`` = the capture start on the
clip timeline). No ``core:datetime`` (synthetic data; keeps files byte-identical per seed) and no
checksum (``core:sha512`` is optional).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from simulator.files import write_atomic
from simulator.formats.validation import FormatError

META_EXT = ".sigmf-meta"
DATA_EXT = ".sigmf-data"
DATATYPE = "cf32_le"


def npy_header_bytes(path: Path) -> int:
    """Byte offset of the array data in a .npy file."""
    with open(path, "rb") as f:
        major, _ = np.lib.format.read_magic(f)
        if major == 1:
            np.lib.format.read_array_header_1_0(f)
        else:
            np.lib.format.read_array_header_2_0(f)
        return f.tell()


def _metadata(n_captures: int, capture_samples: int, sample_rate_hz: float, center_frequency_hz: float,
              capture_start_s: list[float], label: str, description: str, header_bytes: int | None,
              dataset: str | None) -> dict[str, Any]:
    glob: dict[str, Any] = {
        "core:datatype": DATATYPE, "core:sample_rate": float(sample_rate_hz), "core:version": _sigmf_version(),
        "core:recorder": "evids", "core:description": description, "core:num_channels": 1,
    }
    if dataset is not None:
        glob["core:dataset"] = dataset
    captures, annotations = [], []
    for s in range(n_captures):
        cap: dict[str, Any] = {"core:sample_start": s * capture_samples, "core:frequency": float(center_frequency_hz)}
        if s == 0 and header_bytes is not None:
            cap["core:header_bytes"] = int(header_bytes)
        captures.append(cap)
        annotations.append({"core:sample_start": s * capture_samples, "core:sample_count": capture_samples,
                            "core:label": label,
                            "core:comment": f"segment {s}: capture starts at {capture_start_s[s]:.6f} s of the clip"})
    return {"global": glob, "captures": captures, "annotations": annotations}


def _sigmf_version() -> str:
    from sigmf import __specification__

    return __specification__


def _write_meta(meta_path: Path, metadata: dict[str, Any], data_path: Path) -> None:
    """Validate through the sigmf package, then write the JSON atomically (sorted keys)."""
    from sigmf import SigMFFile

    f = SigMFFile(metadata=metadata, data_file=str(data_path), skip_checksum=True)
    f.validate()
    write_atomic(meta_path, f.dumps(pretty=True) + "\n")


def _check(iq: np.ndarray, capture_start_s) -> tuple[np.ndarray, list[float]]:
    iq = np.asarray(iq)
    if iq.ndim != 2 or iq.dtype != np.complex64:
        raise ValueError(f"iq must be complex64 (captures, samples), got {iq.dtype} {iq.shape}")
    starts = [float(v) for v in np.asarray(capture_start_s, dtype=np.float64).ravel()]
    if len(starts) != iq.shape[0]:
        raise ValueError(f"capture_start_s has {len(starts)} entries for {iq.shape[0]} captures")
    return iq, starts


def write_npy_meta(npy_path: Path, *, sample_rate_hz: float, center_frequency_hz: float, capture_start_s,
                   label: str, description: str = "evids synthetic RF capture") -> Path:
    """``<stem>.sigmf-meta`` describing an existing complex64 (S, n) .npy as a Non-Conforming Dataset."""
    npy_path = Path(npy_path)
    iq = np.load(npy_path, mmap_mode="r")
    iq, starts = _check(iq, capture_start_s)
    meta = _metadata(iq.shape[0], iq.shape[1], sample_rate_hz, center_frequency_hz, starts, label, description,
                     npy_header_bytes(npy_path), npy_path.name)
    out = npy_path.with_suffix(META_EXT)
    _write_meta(out, meta, npy_path)
    return out


def write_recording(base: Path, iq: np.ndarray, *, sample_rate_hz: float, center_frequency_hz: float,
                    capture_start_s, label: str, description: str = "evids synthetic RF capture") -> tuple[Path, Path]:
    """Conforming ``<base>.sigmf-data`` (raw cf32_le) + ``<base>.sigmf-meta``; returns both paths."""
    base = Path(base)
    iq, starts = _check(iq, capture_start_s)
    data = base.with_name(base.name + DATA_EXT)
    write_atomic(data, np.ascontiguousarray(iq, dtype="<c8").tobytes())
    meta = _metadata(iq.shape[0], iq.shape[1], sample_rate_hz, center_frequency_hz, starts, label, description,
                     None, None)
    meta_path = base.with_name(base.name + META_EXT)
    _write_meta(meta_path, meta, data)
    return data, meta_path


def read_sigmf(meta_path: Path) -> tuple[np.ndarray, dict[str, Any]]:
    """(I/Q as complex64 (captures, samples), metadata dict) of a recording written by either function."""
    from sigmf import sigmffile
    from sigmf.error import SigMFError

    meta_path = Path(meta_path)
    try:
        f = sigmffile.fromfile(str(meta_path), skip_checksum=True)
        samples = np.asarray(f.read_samples(), dtype=np.complex64)
    except (SigMFError, ValueError, KeyError, OSError) as exc:
        raise FormatError(meta_path, "", f"not a readable SigMF recording ({exc})") from None
    captures = f.get_captures()
    starts = [c["core:sample_start"] for c in captures]
    n = starts[1] - starts[0] if len(starts) > 1 else samples.size
    if n <= 0 or samples.size != n * len(starts):
        raise FormatError(meta_path, "captures",
                          f"{samples.size} samples do not split into {len(starts)} captures of {n}")
    return samples.reshape(len(starts), n), f._metadata
