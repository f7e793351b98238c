"""A spec applied to frame streams (rgb, thermal) one output frame at a time, in constant memory.

Two steps, as ``apply_spec`` would do on the whole clip but without holding it:

1. :func:`plan_frames` (no pixels): every entry's schedule on the row clock, its runs, and, for
   clip-level entries (``needs_clip`` / ``changes_meta``: frame drop/freeze, desync, frame-rate
   mismatch, misalignment, dropout, decoys), the params of every run drawn with apply_spec's keys
   (static: 0, else run start + 1) and the output -> input frame map of each stage (identity except
   for retimes). Params depend on the clip's metadata (size, fps, times) and the seed, never on pixels.
2. :meth:`FramePlan.frames`: per stream, a chain of generators, one per stage, each yielding its
   output frames 0..n-1 in order: frame(s, i) = op_s(frame(s-1, map_s[i])). Retimes apply no pixel
   op (they pick the input frame); a separable clip-level op is applied to the single frame with its
   run's params and ``meta['run_offset']`` = the frame's position in its run (a decoy's track and
   flap phase). Maps are monotone, so each stage holds one input frame: a frozen frame is kept one
   deep, dropped frames still pass through the earlier stages (their measures stay complete).
   Per-frame labels (masks, boxes) flow along the chain with the frame, as apply_spec's meta does.

Frame-local entries keep the per-frame keying of the frame-by-frame path (``apply_spec(...,
frame_offset=i)`` on one frame: per-frame draws keyed by the output index i + 1), so a frame-local
spec gives the same bytes as before; clip-level entries give exactly apply_spec's in-memory result.
Realised-effect measures of clip-level runs are additive per-frame sums (see ``Degradation.measure``)
accumulated while streaming; a measure that needs the whole run is reported as not computed.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from degradations.base import (
    MODALITIES,
    PER_FRAME_KEYS,
    Degradation,
    add_sums,
    change_measure,
    change_sums,
    make_rng,
    retime_measure,
)
from degradations.errors import DegradationError, SpecError
from degradations.registry import get
from degradations.spec import (
    DegradationSpec,
    _runs,
    _slice_meta,
    checked_clock,
    count_rows,
    entries_on,
    entry_severity,
    stream_times,
    stream_view,
    summary_record,
)

#: streams whose time axis is frames (the ones a frame stream can carry)
FRAME_STREAMS = ("rgb", "thermal")
#: record note of a clip-level run whose measure needs the whole run at once
UNMEASURED = "measure needs the whole run; not computed when streaming"

#: (stream, output frame index) -> that frame as a 1-frame clip (1, H, W, 3) or (1, H, W)
ReadFrame = Callable[[str, int], np.ndarray]
#: (stream, frame index) -> per-frame meta of that input frame, 1-frame arrays ("thermal_mask": (1, H, W))
ReadMeta = Callable[[str, int], dict]


@dataclass
class _Run:
    """One planned run of a clip-level stage."""
    start: int
    stop: int
    deg: Degradation
    params: dict
    record: dict
    sums: dict | None = None


@dataclass
class _Stage:
    """One non-skipped entry: its schedule on the frames and, if clip-level, its planned runs."""
    index: int
    entry: dict
    key: str
    cls: type[Degradation]
    static: bool
    clip_level: bool
    sevq: np.ndarray
    source: np.ndarray
    run_of: np.ndarray
    runs: list[_Run] = field(default_factory=list)
    record_runs: list[dict] = field(default_factory=list)


def _measure_kind(cls: type[Degradation]) -> str:
    """How a clip-level class's run measure is obtained when streaming: none, index, sums or clip."""
    if cls.retimes:
        return "index"
    if cls.reports_change:
        return "sums"
    if cls.measure is Degradation.measure and not cls.reports_snr:
        return "none"
    return "clip"


def _plan_stage(spec: DegradationSpec, i: int, e: dict, key: str, sevq: np.ndarray, view: dict,
                shape: tuple[int, ...], seed: int) -> _Stage:
    """A stage's runs, params and frame map (clip-level) from metadata alone."""
    cls = get(e["name"])
    n = sevq.size
    static = (e["temporal"] or cls.default_temporal) == "static"
    clip_level = bool(cls.needs_clip or cls.changes_meta)
    stage = _Stage(i, e, key, cls, static, clip_level, sevq, np.arange(n), np.full(n, -1))
    if not clip_level:
        return stage
    if not (cls.retimes or cls.frame_separable):
        raise DegradationError(f"{e['name']}: a clip-level transform that is neither a retime nor frame-separable "
                               "cannot be applied to a frame stream")
    kind = _measure_kind(cls)
    for a, b, s in _runs(sevq):
        deg = cls(s, temporal=e["temporal"], **e["params"])
        params = deg.sample_params(make_rng(seed, key, 0 if static else a + 1), dict(view))
        record: dict[str, Any] = {"start": a, "stop": b, "severity": s, "params": params}
        if kind == "index":
            idx = np.asarray(deg.frame_index(b - a, params), dtype=np.int64)
            if np.any(np.diff(idx) < 0) or np.any((idx < 0) | (idx >= b - a)):
                raise DegradationError(f"{e['name']}: frame index is not monotone inside its run; cannot stream")
            stage.source[a:b] = a + idx
            record.update(retime_measure(idx))
        elif kind == "clip":
            record["unmeasured"] = UNMEASURED
        new = deg.update_meta(params, dict(view), (b - a,) + tuple(shape))
        record.update({k: new[k] for k in ("missing", "affine", "shift_samples") if k in new})
        stage.run_of[a:b] = len(stage.runs)
        stage.runs.append(_Run(a, b, deg, params, record))
        stage.record_runs.append(record)
    return stage


def _own_keys(meta: dict, stream: str) -> dict:
    """The keys of one stream's chain: its own prefixed keys and unprefixed (shared) ones."""
    others = tuple(m + "_" for m in MODALITIES if m != stream)
    return {k: v for k, v in meta.items() if not k.startswith(others)}


@dataclass
class FramePlan:
    """A spec planned on n frames of the given streams (see the module docstring)."""
    spec: DegradationSpec
    seed: int
    t_s: np.ndarray
    meta: dict
    shapes: dict[str, tuple[int, ...]]
    stages: list[_Stage]
    skipped: list[dict]
    sev_rows: dict[str, np.ndarray]
    missing_rows: dict[str, np.ndarray]

    @property
    def n(self) -> int:
        return int(self.t_s.size)

    def frames(self, read: ReadFrame, frame_meta: ReadMeta) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        """Yield (i, {stream: output frame i as a 1-frame clip}) for i = 0..n-1, in order."""
        chains = {}
        for stream in self.shapes:
            gen = self._source(stream, read, frame_meta)
            for stage in self.stages:
                if stage.entry["stream"] == stream:
                    gen = self._stage(stage, gen)
            chains[stream] = gen
        for i in range(self.n):
            yield i, {m: next(g)[0] for m, g in chains.items()}
        for g in chains.values():  # each chain finishes its stages (drains frames no output shows)
            for _ in g:
                pass

    def record(self) -> dict:
        """The record (as apply_spec's, without meta); complete once :meth:`frames` is exhausted."""
        applied = [{"index": s.index, "name": s.entry["name"], "stream": s.entry["stream"],
                    "program": s.entry["program"], "runs": s.record_runs} for s in self.stages]
        return summary_record(self.spec, self.t_s, self.seed, list(self.shapes), self.sev_rows,
                              self.missing_rows, applied, self.skipped)

    # -- the chain ------------------------------------------------------------------------------
    def _source(self, stream: str, read: ReadFrame, frame_meta: ReadMeta) -> Iterator[tuple[np.ndarray, dict]]:
        want = (1,) + self.shapes[stream]
        for j in range(self.n):
            x = np.asarray(read(stream, j))
            if x.shape != want:
                raise DegradationError(f"{stream} frame {j}: shape {x.shape}, expected {want} (the first frame's)")
            yield x, _own_keys(dict(frame_meta(stream, j)), stream)

    def _stage(self, stage: _Stage, upstream: Iterator) -> Iterator[tuple[np.ndarray, dict]]:
        held: Any = None
        held_j = -1
        for j in range(self.n):
            src = int(stage.source[j])
            while held_j < src:
                held, held_j = next(upstream), held_j + 1
            if held_j != src:
                raise DegradationError(f"{stage.entry['name']}: frame map goes backwards at frame {j}; cannot stream")
            yield self._op(stage, j, *held)
        for _ in upstream:
            pass

    def _op(self, stage: _Stage, j: int, x: np.ndarray, fmeta: dict) -> tuple[np.ndarray, dict]:
        """Stage ``stage`` at output frame j on its input frame x (with that frame's meta)."""
        stream = stage.entry["stream"]
        view = stream_view({**self.meta, **fmeta}, stream)
        sub = _slice_meta(view, 0, 1, 1, stream)
        if not stage.clip_level:
            s = float(stage.sevq[j])
            if s <= 0:
                return x, fmeta
            deg = stage.cls(s, temporal=stage.entry["temporal"], **stage.entry["params"])
            params = deg.sample_params(make_rng(self.seed, stage.key, 0 if stage.static else j + 1), sub)
            y = deg.apply(x, params, sub)
            stage.record_runs.append({"start": j, "stop": j + 1, "severity": s, "params": params,
                                      **deg.measure(x, y, params, sub)})
            return y, fmeta
        r = int(stage.run_of[j])
        if r < 0:
            return x, fmeta
        run = stage.runs[r]
        if stage.cls.retimes:  # the pixels are the input frame's (as apply's dtype round trip leaves them)
            work, restore = run.deg._to_work(x)
            return restore(work), fmeta
        sub["run_offset"] = j - run.start
        y = run.deg.apply(x, run.params, sub)
        new = run.deg.update_meta(run.params, sub, tuple(x.shape))
        fmeta = {**fmeta, **{f"{stream}_{k}": new[k] for k in PER_FRAME_KEYS
                             if k in new and new[k] is not None and np.ndim(new[k]) > 0 and len(new[k]) == 1}}
        if stage.cls.reports_change:
            run.sums = add_sums(run.sums, change_sums(x[0], y[0]))
            if j == run.stop - 1:
                run.record.update(change_measure(run.sums))
        return y, fmeta


def plan_frames(spec: DegradationSpec, seed: int, t_s: Any, meta: dict,
                shapes: dict[str, tuple[int, ...]]) -> FramePlan:
    """Plan ``spec`` on frame streams of one frame per row time ``t_s``.

    meta: the clip's shared keys (``fps``, ``thermal_netd_k``, ...; no per-frame arrays, those come
    per frame to :meth:`FramePlan.frames`); shapes: stream -> shape of one frame ((H, W, 3) rgb,
    (H, W) thermal). Entries on other streams are skipped ("stream absent"), as in apply_spec."""
    t_s = checked_clock(spec, t_s)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SpecError(f"seed must be a non-negative int, got {seed!r}")
    unknown = sorted(set(shapes) - set(FRAME_STREAMS))
    if unknown:
        raise SpecError(f"frame streams: {unknown} are not frame streams; expected keys among {list(FRAME_STREAMS)}")
    present = [m for m in MODALITIES if m in shapes]
    shapes = {m: tuple(int(v) for v in shapes[m]) for m in present}
    sev_rows = {m: np.zeros(t_s.size) for m in present}
    missing_rows = {m: np.zeros(t_s.size, bool) for m in present}
    stages: list[Any] = []
    skipped: list[dict] = []
    for i, e, key in entries_on(spec, present, skipped):
        stream = e["stream"]
        view = stream_view(meta, stream)
        times = stream_times(stream, t_s.size, view, t_s)
        sevq = entry_severity(spec, e, times)
        count_rows(e, stream, times, sevq, t_s, sev_rows, missing_rows)
        stages.append(_plan_stage(spec, i, e, key, sevq, view, shapes[stream], int(seed)))
    return FramePlan(spec, int(seed), t_s, dict(meta), shapes, stages, skipped, sev_rows, missing_rows)
