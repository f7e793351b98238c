"""Svanström multi-sensor drone benchmark (Svanström, Alonso-Fernandez, Englund 2021): reader, split
rule and spec (docs/FORMATS.md, "Svanström"; docs/SIM2REAL.md).

Layout of the public release (GitHub DroneDetectionThesis/Drone-detection-dataset), under ``Data/``:

* ``Video_IR/IR_<CLASS>_<NNN>.mp4`` (320x256, 30 fps H.264) + ``IR_<CLASS>_<NNN>_LABELS.mat``;
* ``Video_V/V_<CLASS>_<NNN>.mp4`` (640x512) + ``V_<CLASS>_<NNN>_LABELS.mat``; video classes
  AIRPLANE, BIRD, DRONE, HELICOPTER;
* ``Audio/<CLASS>_<NNN>.wav`` (10 s, 44.1 kHz, 16-bit stereo); audio classes BACKGROUND, DRONE,
  HELICOPTER;
* ``Video_dataset_description.xlsx``: one row per video clip, columns SENSOR (IR | V), CLASS,
  NUMBER, DISTANCE BIN (CLOSE | MEDIUM | DISTANT), INTER BIN NUMBER, DRONE TYPE / INTERNET SOURCE.

Labels are MATLAB ``groundTruth`` objects (MCOS) that ``scipy.io.loadmat`` returns only as an opaque
``__function_workspace__``; the PyPI package ``mcos-decoder`` (the ``svanstrom`` extra) walks it into
one ``(x, y, w, h)`` (pixels, top-left + size) or ``None`` (target absent) per frame. IR and visible
clips with the same number are different recordings: never pair them.

**Split rule** (fixed, published): a clip with an odd NUMBER belongs to the *calibration* half, an
even NUMBER to the *evaluation* half, per sensor and class. Anything that tunes the simulator to the
real data (statistics matching, parameter fits, choice of randomisation ranges, thresholds,
temperatures, early stopping) may look at the calibration half only; the evaluation half is for the
numbers that are reported.

The root may be a downloaded folder (the one holding ``Data/``, or ``Data/`` itself) **or a bare git
mirror of the repository**, read in place through one ``git cat-file --batch`` process: nothing is
checked out or copied.

Reading validates each clip: its label file exists, decodes, and has as many entries as the video has
frames (one more or one fewer is tolerated: the release has clips whose label list carries one extra
leading entry), the class is known, and the video decodes to the end. :meth:`SvanstromBenchmark.check`
raises :class:`FormatError` naming the file (``strict=True``) or records the clip in ``skipped``.
"""
from __future__ import annotations

import io
import os
import re
import subprocess
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator, Literal, cast

import numpy as np

from simulator.formats.validation import FormatError, Skipped

Sensor = Literal["ir", "visible", "audio"]
Half = Literal["calibration", "evaluation"]

SENSORS: tuple[Sensor, ...] = ("ir", "visible", "audio")
VIDEO_CLASSES = ("AIRPLANE", "BIRD", "DRONE", "HELICOPTER")
AUDIO_CLASSES = ("BACKGROUND", "DRONE", "HELICOPTER")
DISTANCE_BINS = ("CLOSE", "MEDIUM", "DISTANT")
FRAME_SIZE_PX = {"ir": (320, 256), "visible": (640, 512)}      # (width, height)
VIDEO_FPS = 30
AUDIO_SAMPLE_RATE_HZ = 44_100
LABEL_COUNT_TOLERANCE = 1
DESCRIPTION = "Video_dataset_description.xlsx"

_FOLDER: dict[Sensor, str] = {"ir": "Video_IR", "visible": "Video_V", "audio": "Audio"}
_PREFIX = {"ir": "IR_", "visible": "V_", "audio": ""}
_SHEET_SENSOR = {"IR": "ir", "V": "visible"}
_NAME_RE = re.compile(r"^(?:(IR|V)_)?([A-Z]+)_(\d+)(_LABELS)?\.(mp4|mat|wav)$")


def split_of(number: int) -> Half:
    """The fixed split: odd clip numbers calibrate, even numbers evaluate."""
    return "calibration" if number % 2 == 1 else "evaluation"


TUNING_BLOCK_CLIPS = 5


def tuning_fold(number: int) -> int:
    """The fold (0 or 1) of a calibration clip when the calibration half is split in two to tune on it
    (``evids sim2real --tune``): runs of ``TUNING_BLOCK_CLIPS`` consecutive odd numbers alternate (1-9
    fold 0, 11-19 fold 1, ...), so neighbouring clips, often one recording session, stay on one side."""
    if number % 2 != 1:
        raise ValueError(f"number: {number} is an evaluation clip (even); only calibration clips have a tuning fold")
    return ((number - 1) // 2 // TUNING_BLOCK_CLIPS) % 2


@dataclass(frozen=True)
class Clip:
    """One clip of the benchmark; paths are relative to the ``Data/`` folder."""

    sensor: Sensor
    cls: str
    number: int
    media: str                  # e.g. "Video_IR/IR_DRONE_001.mp4"
    labels: str | None          # e.g. "Video_IR/IR_DRONE_001_LABELS.mat"; None for audio
    distance_bin: str | None = None
    drone_type: str | None = None

    @property
    def name(self) -> str:
        return f"{_PREFIX[self.sensor]}{self.cls}_{self.number:03d}"

    @property
    def half(self) -> Half:
        return split_of(self.number)


# ------------------------------------------------------------------------------------------------
# Where the bytes come from: a folder or a bare git mirror


class _FolderSource:
    def __init__(self, data_dir: Path):
        self.data_dir = data_dir
        self.where = str(data_dir)

    def list(self) -> list[str]:
        return sorted(p.relative_to(self.data_dir).as_posix() for p in self.data_dir.rglob("*") if p.is_file())

    def identity(self) -> str:
        """Changes when any file is added, removed, resized or touched."""
        import hashlib

        h = hashlib.sha256()
        for rel in self.list():
            st = (self.data_dir / rel).stat()
            h.update(f"{rel}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
        return "folder:" + h.hexdigest()

    def read(self, rel: str) -> bytes:
        try:
            return (self.data_dir / rel).read_bytes()
        except FileNotFoundError:
            raise FormatError(self.data_dir / rel, "", "file not found") from None


class _GitMirrorSource:
    """Blobs of ``<rev>:Data/...`` from a bare repository through one ``git cat-file --batch``."""

    def __init__(self, git_dir: Path, rev: str = "HEAD", prefix: str = "Data/"):
        self.git_dir, self.rev, self.prefix = git_dir, rev, prefix
        self.where = f"{git_dir} ({rev})"
        self._proc: subprocess.Popen | None = None
        self._pid = -1
        self._lock = threading.Lock()

    def _git(self, *args: str) -> bytes:
        try:
            return subprocess.run(["git", "--git-dir", str(self.git_dir), *args], capture_output=True,
                                  check=True).stdout
        except FileNotFoundError:
            raise FormatError(self.git_dir, "", "reading a git mirror needs the `git` command") from None
        except subprocess.CalledProcessError as exc:
            raise FormatError(self.git_dir, "", f"git failed: {exc.stderr.decode(errors='replace').strip()}") from None

    def identity(self) -> str:
        """The commit the mirror's ``rev`` points to."""
        return "git:" + self._git("rev-parse", self.rev).decode().strip()

    def list(self) -> list[str]:
        out = self._git("ls-tree", "-r", "--name-only", "-z", self.rev, "--", self.prefix.rstrip("/"))
        names = [n.decode() for n in out.split(b"\0") if n]
        return sorted(n[len(self.prefix):] for n in names if n.startswith(self.prefix))

    def _batch(self) -> subprocess.Popen:
        if self._proc is None or self._pid != os.getpid() or self._proc.poll() is not None:
            # a forked worker gets its own process (pipes are not shared across a fork safely)
            self._proc = subprocess.Popen(["git", "--git-dir", str(self.git_dir), "cat-file", "--batch"],
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE)
            self._pid = os.getpid()
        return self._proc

    def read(self, rel: str) -> bytes:
        with self._lock:
            proc = self._batch()
            if proc.stdin is None or proc.stdout is None:
                raise RuntimeError("git cat-file --batch started without pipes")
            proc.stdin.write(f"{self.rev}:{self.prefix}{rel}\n".encode())
            proc.stdin.flush()
            header = proc.stdout.readline().decode().split()
            if len(header) != 3 or header[1] != "blob":
                raise FormatError(f"{self.where}:{self.prefix}{rel}", "", "file not found in the mirror")
            size = int(header[2])
            data = proc.stdout.read(size)
            proc.stdout.read(1)  # the newline after each object
            return data

    def close(self) -> None:
        if self._proc is not None and self._pid == os.getpid():
            if self._proc.stdin:
                self._proc.stdin.close()
            self._proc.wait(timeout=10)
        self._proc = None


def _is_bare_git(path: Path) -> bool:
    return (path / "HEAD").is_file() and (path / "objects").is_dir() and (path / "refs").is_dir()


def _source(root: Path) -> _FolderSource | _GitMirrorSource:
    root = Path(root)
    if not root.exists():
        raise FormatError(root, "", "no such folder (give the dataset folder or a git mirror of it)")
    if _is_bare_git(root):
        return _GitMirrorSource(root)
    if (root / ".git").is_dir() and not (root / "Data").is_dir():
        return _GitMirrorSource(root / ".git")
    for data in (root / "Data", root):
        if (data / "Video_IR").is_dir() or (data / "Audio").is_dir() or (data / "Video_V").is_dir():
            return _FolderSource(data)
    raise FormatError(root, "", "not the Svanström layout: no Data/Video_IR, Data/Video_V or Data/Audio folder, "
                                "and not a git mirror")


# ------------------------------------------------------------------------------------------------
# The benchmark


class SvanstromBenchmark:
    """Clips, labels, frames and audio of one copy of the benchmark (folder or git mirror)."""

    def __init__(self, root: Path | str):
        self.root = Path(root)
        self._src = _source(self.root)
        self.where = self._src.where
        self._files = self._src.list()
        self._description: dict[tuple[str, str, int], dict] | None = None
        self.unrecognised: list[str] = []
        self._clips = self._index()

    # -- listing ---------------------------------------------------------------------------------
    def _index(self) -> list[Clip]:
        files = set(self._files)
        clips: list[Clip] = []
        for rel in self._files:
            folder, _, name = rel.rpartition("/")
            sensor = next((s for s, f in _FOLDER.items() if f == folder), None)
            if sensor is None:
                continue
            m = _NAME_RE.match(name)
            if m is None or m.group(4) or m.group(5) == "mat":
                if m is None:
                    self.unrecognised.append(rel)
                continue
            prefix, cls, number = m.group(1), m.group(2), int(m.group(3))
            if (sensor == "audio") != (prefix is None) or (sensor != "audio" and _PREFIX[sensor] != prefix + "_"):
                self.unrecognised.append(rel)
                continue
            label_rel = None
            if sensor != "audio":
                label_rel = f"{folder}/{_PREFIX[sensor]}{cls}_{number:03d}_LABELS.mat"
                if label_rel not in files:
                    label_rel = f"{folder}/{name[:-4]}_LABELS.mat"  # same stem, other zero padding
            clips.append(Clip(sensor=sensor, cls=cls, number=number, media=rel, labels=label_rel))
        return clips

    def description(self) -> dict[tuple[str, str, int], dict]:
        """``(sensor, CLASS, number) -> {"distance_bin", "inter_bin_number", "drone_type"}`` from the
        xlsx sheet (empty when the file is missing)."""
        if self._description is None:
            self._description = {}
            if DESCRIPTION in self._files:
                self._description = _read_description(self._src.read(DESCRIPTION), f"{self.where}/{DESCRIPTION}")
        return self._description

    def clips(self, sensor: Sensor, half: Half | None = None, classes: Iterable[str] | None = None) -> list[Clip]:
        """Clips of one sensor, optionally one half and some classes, sorted by class and number;
        distance bin and drone type filled in from the description sheet."""
        if sensor not in SENSORS:
            raise FormatError(self.where, "sensor", f"unknown sensor {sensor!r}; expected one of {SENSORS}")
        wanted = None if classes is None else {c.upper() for c in classes}
        desc = self.description() if sensor != "audio" else {}
        out = []
        for c in self._clips:
            if c.sensor != sensor or (half is not None and c.half != half) or (wanted and c.cls not in wanted):
                continue
            row = desc.get((sensor, c.cls, c.number))
            if row:
                c = Clip(c.sensor, c.cls, c.number, c.media, c.labels, row.get("distance_bin"), row.get("drone_type"))
            out.append(c)
        return sorted(out, key=lambda c: (c.cls, c.number))

    def identity(self) -> str:
        """A string that changes when the copy's content may have changed (git commit, or the folder's
        file names, sizes and modification times): the key of caches derived from it."""
        return self._src.identity()

    # -- reading ---------------------------------------------------------------------------------
    def read_bytes(self, rel: str) -> bytes:
        return self._src.read(rel)

    def labels(self, clip: Clip) -> list[tuple[float, float, float, float] | None]:
        """Per-frame ``(x, y, w, h)`` in pixels or ``None`` (absent), as stored (not aligned to frames)."""
        if clip.labels is None:
            raise FormatError(self.where, clip.name, "audio clips have no labels")
        path = f"{self.where}/{clip.labels}"
        if clip.labels not in set(self._files):
            raise FormatError(path, "", f"label file of {clip.media} is missing")
        return decode_labels(self._src.read(clip.labels), path)

    def video_frame_count(self, clip: Clip) -> int:
        """Frames in the clip's video (decodes packets only, not pixels)."""
        return _count_frames(self._src.read(clip.media), f"{self.where}/{clip.media}")

    def frames(self, clip: Clip, indices: Iterable[int] | None = None) -> Iterator[tuple[int, np.ndarray]]:
        """``(index, frame)`` for the requested 0-based frame indices (all when None), in order:
        IR as (256, 320) uint8 luma, visible as (512, 640, 3) uint8 RGB. Only requested frames are
        converted to arrays (decoding itself must run through every frame of an H.264 stream)."""
        if clip.sensor == "audio":
            raise FormatError(self.where, clip.name, "audio clips have no frames")
        yield from _decode_frames(self._src.read(clip.media), f"{self.where}/{clip.media}",
                                  gray=clip.sensor == "ir", indices=indices)

    def audio(self, clip: Clip) -> tuple[np.ndarray, int]:
        """``(samples, sample_rate_hz)``: float32 in [-1, 1], shape (n,) mono (channels averaged)."""
        if clip.sensor != "audio":
            raise FormatError(self.where, clip.name, "not an audio clip")
        return decode_wav(self._src.read(clip.media), f"{self.where}/{clip.media}")

    def aligned_labels(self, clip: Clip, n_frames: int | None = None) -> list[tuple[float, float, float, float] | None]:
        """Labels aligned to the video's frames: a list one longer than the video drops its first
        entry (the release's extra leading slot), one shorter is padded with ``None`` at the end."""
        labels = self.labels(clip)
        n = self.video_frame_count(clip) if n_frames is None else n_frames
        return align_labels(labels, n, f"{self.where}/{clip.labels}")

    def check(self, clip: Clip, *, strict: bool = True, skipped: Skipped | None = None) -> bool:
        """Validate one clip (labels present and decodable, counts agree, class known, video or audio
        decodes to the end). Returns True when good; a bad clip raises (strict) or is recorded."""
        try:
            known = AUDIO_CLASSES if clip.sensor == "audio" else VIDEO_CLASSES
            if clip.cls not in known:
                raise FormatError(f"{self.where}/{clip.media}", "class",
                                  f"unknown class {clip.cls!r}; expected one of {known}")
            if clip.sensor == "audio":
                self.audio(clip)
            else:
                self.aligned_labels(clip, self.video_frame_count(clip))
            return True
        except FormatError as err:
            if strict:
                raise
            (skipped if skipped is not None else Skipped()).add(err)
            return False

    def close(self) -> None:
        if isinstance(self._src, _GitMirrorSource):
            self._src.close()


# ------------------------------------------------------------------------------------------------
# Decoders (bytes in, arrays out): labels, video, audio, description sheet


def decode_labels(data: bytes, path: str) -> list[tuple[float, float, float, float] | None]:
    """Per-frame boxes of a ``groundTruth`` label file via mcos-decoder."""
    import scipy.io

    try:
        from mcos_decoder import extract_bboxes
    except ImportError:
        raise FormatError(path, "", "reading Svanström labels needs the `svanstrom` extra "
                                    "(pip install 'evids[svanstrom]', which brings mcos-decoder)") from None
    try:
        workspace = scipy.io.loadmat(io.BytesIO(data)).get("__function_workspace__")
    except Exception as exc:  # scipy raises several types on corrupt files
        raise FormatError(path, "", f"not a readable MATLAB file ({type(exc).__name__}: {exc})") from None
    if workspace is None:
        raise FormatError(path, "", "no __function_workspace__: not a MATLAB groundTruth label file")
    boxes = extract_bboxes(np.asarray(workspace).tobytes())
    if not boxes:
        raise FormatError(path, "", "no per-frame label cells found")
    out: list[tuple[float, float, float, float] | None] = []
    for i, box in enumerate(boxes):
        if box is not None and not (all(np.isfinite(box)) and box[2] > 0 and box[3] > 0):
            raise FormatError(path, f"frame {i + 1}", f"bad box {box}")
        out.append(None if box is None else cast(tuple[float, float, float, float], tuple(float(v) for v in box)))
    return out


def align_labels(labels: list, n_frames: int, path: str) -> list:
    """Match a label list to ``n_frames`` (tolerance one entry, see :meth:`SvanstromBenchmark.aligned_labels`)."""
    diff = len(labels) - n_frames
    if abs(diff) > LABEL_COUNT_TOLERANCE:
        raise FormatError(path, "", f"{len(labels)} label entries for {n_frames} video frames "
                                    f"(more than {LABEL_COUNT_TOLERANCE} apart)")
    if diff == 1:
        return labels[1:] if labels[0] is None else labels[:-1]
    if diff == -1:
        return labels + [None]
    return labels


def _open_video(data: bytes, path: str):
    import av

    try:
        container = av.open(io.BytesIO(data))
    except av.FFmpegError as exc:
        raise FormatError(path, "", f"not a readable video ({exc})") from None
    if not container.streams.video:
        container.close()
        raise FormatError(path, "", "no video stream")
    return container


def _av_frames(data: bytes, path: str) -> Iterator:
    """Every decoded frame of the first video stream; a truncated or corrupt stream raises FormatError."""
    import av

    container = _open_video(data, path)
    n = 0
    try:
        for frame in container.decode(container.streams.video[0]):
            n += 1
            yield frame
    except av.FFmpegError as exc:
        raise FormatError(path, f"frame {n + 1}", f"video does not decode ({exc})") from None
    finally:
        container.close()
    if n == 0:
        raise FormatError(path, "", "video has no decodable frame (truncated?)")


def _count_frames(data: bytes, path: str) -> int:
    return sum(1 for _ in _av_frames(data, path))


def _decode_frames(data: bytes, path: str, *, gray: bool, indices: Iterable[int] | None
                   ) -> Iterator[tuple[int, np.ndarray]]:
    """Decode every frame; yield the wanted ones as arrays (IR: the luma plane as stored, no range
    conversion, one copy instead of a swscale pass)."""
    wanted = None if indices is None else {int(i) for i in indices}
    for i, frame in enumerate(_av_frames(data, path)):
        if wanted is not None and i not in wanted:
            continue
        if gray and frame.format.name in ("yuv420p", "yuvj420p", "gray"):
            plane = frame.planes[0]
            buf = np.frombuffer(memoryview(plane), np.uint8).reshape(frame.height, plane.line_size)
            yield i, buf[:, : frame.width].copy()
        else:
            yield i, frame.to_ndarray(format="gray" if gray else "rgb24")


def decode_wav(data: bytes, path: str) -> tuple[np.ndarray, int]:
    """16/32-bit PCM or float WAV bytes -> (mono float32 in [-1, 1], sample rate)."""
    import scipy.io.wavfile

    try:
        rate, x = scipy.io.wavfile.read(io.BytesIO(data))
    except (ValueError, EOFError) as exc:
        raise FormatError(path, "", f"not a readable WAV file ({exc})") from None
    if x.size == 0:
        raise FormatError(path, "", "WAV file has no samples")
    if x.dtype.kind == "i":
        x = x.astype(np.float32) / float(2 ** (8 * x.dtype.itemsize - 1))
    elif x.dtype == np.uint8:
        x = (x.astype(np.float32) - 128.0) / 128.0
    x = x.astype(np.float32)
    if x.ndim == 2:
        x = x.mean(axis=1, dtype=np.float32)
    return x, int(rate)


def _read_description(data: bytes, path: str) -> dict[tuple[str, str, int], dict]:
    try:
        import openpyxl
    except ImportError:
        raise FormatError(path, "", "reading the description sheet needs the `svanstrom` extra (openpyxl)") from None
    try:
        sheet = openpyxl.load_workbook(io.BytesIO(data), read_only=True, data_only=True).worksheets[0]
    except Exception as exc:  # openpyxl raises several types on corrupt files
        raise FormatError(path, "", f"not a readable xlsx file ({type(exc).__name__})") from None
    rows = sheet.iter_rows(values_only=True)
    header = [str(h or "").strip().upper() for h in next(rows, ())]

    def col(*starts: str) -> int | None:
        return next((k for k, h in enumerate(header) if any(h.startswith(s) for s in starts)), None)

    c_sensor, c_class, c_number = col("SENSOR"), col("CLASS"), col("NUMBER")
    c_bin, c_inter, c_type = col("DISTANCE"), col("INTER BIN"), col("DRONE TYPE")
    if c_sensor is None or c_class is None or c_number is None:
        raise FormatError(path, "row 1", f"expected columns SENSOR, CLASS, NUMBER; found {header}")
    out: dict[tuple[str, str, int], dict] = {}
    for r, row in enumerate(rows, start=2):
        if not row or row[c_sensor] is None:
            continue
        sensor = _SHEET_SENSOR.get(str(row[c_sensor]).strip().upper())
        if sensor is None:
            raise FormatError(path, f"row {r}", f"unknown SENSOR {row[c_sensor]!r} (expected IR or V)")
        try:
            number = int(row[c_number])
        except (TypeError, ValueError):
            raise FormatError(path, f"row {r}", f"NUMBER is not a whole number: {row[c_number]!r}") from None
        bin_ = str(row[c_bin]).strip().upper() if c_bin is not None and row[c_bin] is not None else None
        if bin_ is not None and bin_ not in DISTANCE_BINS:
            raise FormatError(path, f"row {r}", f"unknown DISTANCE BIN {bin_!r}; expected one of {DISTANCE_BINS}")
        out[(sensor, str(row[c_class]).strip().upper(), number)] = {
            "distance_bin": bin_,
            "inter_bin_number": row[c_inter] if c_inter is not None else None,
            "drone_type": (str(row[c_type]).strip() or None) if c_type is not None and row[c_type] else None,
        }
    return out


def open_benchmark(root: Path | str | None = None) -> SvanstromBenchmark:
    """Open the benchmark at ``root``, or at ``$EVIDS_SVANSTROM`` when root is None."""
    if root is None:
        env = os.environ.get("EVIDS_SVANSTROM")
        if not env:
            raise FormatError("EVIDS_SVANSTROM", "", "no dataset path given and EVIDS_SVANSTROM is not set")
        root = env
    return SvanstromBenchmark(Path(root))
