"""Degradation spec files (YAML/JSON, pydantic-validated) and ``apply_spec`` for the CLI/loaders.

``load_spec(path) -> DegradationSpec`` raises :class:`SpecError` (a ValueError) whose message names
the field path and the bad value. ``apply_spec(spec, streams, meta, seed, t_s)`` degrades a dict of
streams on a shared clock and returns ``(degraded_streams, record)``; the record holds per-row
per-modality severity and ``compromised`` flags (the ground-truth conflict label). See
docs/DEGRADATIONS.md for the formats.
"""
from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any, Literal, cast

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from degradations.base import DEFAULT_LEVEL, MODALITIES, PER_FRAME_KEYS, make_rng
from degradations.errors import DegradationError, SpecError
from degradations.registry import REGISTRY, _to_numpy, get
from degradations.schedule import (
    PROGRAMS,
    Event,
    Schedule,
    StepSchedule,
    conflict_program,
)

Severity = Annotated[float, Field(ge=0.0, le=5.0)]
Stream = Literal["rgb", "thermal", "audio", "rf_iq", "rf_spec"]


def default_stream(name: str, params: dict | None = None) -> str:
    """Stream a registered degradation acts on: its own ``modality``; a cross-modal one (a
    ``spec_stream`` attribute) acts on ``params['stream']``, else on its ``spec_stream``."""
    cls = REGISTRY.get(name)
    if cls is None:
        raise DegradationError(f"unknown degradation {name!r}")
    spec_stream = getattr(cls, "spec_stream", None)
    if spec_stream is not None:
        return str((params or {}).get("stream", spec_stream))
    return str(cls.modality)


def stream_is_a_parameter(name: str) -> bool:
    """True for a cross-modal degradation: the stream it acts on is chosen per entry."""
    return getattr(REGISTRY[name], "spec_stream", None) is not None


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class DegradationEntry(_Model):
    """One degradation: registered ``name``, optional severity/params/temporal and schedule."""
    name: str
    stream: Stream | None = None
    severity: Severity | None = None
    params: dict[str, Any] = Field(default_factory=dict)
    temporal: Literal["per_frame", "static"] | None = None
    schedule: Schedule | None = None

    @model_validator(mode="after")
    def _check(self):
        if self.name not in REGISTRY:
            raise ValueError(f"unknown degradation {self.name!r}")
        params = dict(self.params)
        if stream_is_a_parameter(self.name):
            if self.stream is not None:
                params["stream"] = self.stream
        elif self.stream is not None and self.stream != default_stream(self.name):
            raise ValueError(f"{self.name} acts on stream {default_stream(self.name)!r}, not {self.stream!r}")
        try:
            REGISTRY[self.name](self.severity, temporal=self.temporal, **params)
        except DegradationError as exc:
            raise ValueError(str(exc)) from None
        self.params = params
        if self.stream is None:
            self.stream = cast(Stream, default_stream(self.name, params))
        return self


class ProgramEntry(_Model):
    """A named conflict program on a step event (onset_s, duration_s, severity) or any schedule."""
    name: Literal["ir_blind", "rgb_blind", "audio_masked", "rf_silent", "decoy"]
    onset_s: Annotated[float, Field(ge=0.0)] | None = None
    duration_s: Annotated[float, Field(gt=0.0)] | None = None
    severity: Severity = 5.0
    cause: str | None = None
    schedule: Schedule | None = None

    @model_validator(mode="after")
    def _check(self):
        if self.schedule is None and (self.onset_s is None or self.duration_s is None):
            raise ValueError("give onset_s and duration_s, or a schedule")
        causes = PROGRAMS[self.name][1]
        if self.cause is not None and self.cause not in causes:
            raise ValueError(f"cause must be one of {sorted(causes)}, got {self.cause!r}")
        return self

    def resolved_schedule(self) -> Schedule:
        if self.schedule is not None:
            return self.schedule
        onset_s, duration_s = self.onset_s, self.duration_s
        if onset_s is None or duration_s is None:       # excluded by _check; narrows the types
            raise ValueError("give onset_s and duration_s, or a schedule")
        return StepSchedule(events=[Event(onset_s=onset_s, duration_s=duration_s, severity=self.severity)])


class DegradationSpec(_Model):
    """A whole spec: degradations and conflict programs applied in order (degradations first)."""
    version: Literal[1] = 1
    compromised_at: Annotated[float, Field(gt=0.0, le=5.0)] = 3.0
    severity_quantum: Annotated[float, Field(gt=0.0, le=5.0)] = 0.1
    degradations: list[DegradationEntry] = Field(default_factory=list)
    programs: list[ProgramEntry] = Field(default_factory=list)

    def entries(self) -> list[dict]:
        """Flat list of {name, stream, severity, params, temporal, schedule, program}."""
        out = [{"name": d.name, "stream": d.stream, "severity": d.severity, "params": d.params,
                "temporal": d.temporal, "schedule": d.schedule, "program": None} for d in self.degradations]
        for p in self.programs:
            for e in conflict_program(p.name, p.resolved_schedule(), p.cause):
                params = {"stream": e["stream"]} if stream_is_a_parameter(e["name"]) else {}
                out.append({**e, "severity": None, "params": params, "temporal": None})
        return out


def _loc(loc: tuple) -> str:
    s = ""
    for part in loc:
        s += f"[{part}]" if isinstance(part, int) else (f".{part}" if s else str(part))
    return s or "<root>"


def parse_spec(data: Any) -> DegradationSpec:
    """Validate a spec given as a dict; SpecError lists each bad field path and value."""
    try:
        return DegradationSpec.model_validate(data)
    except ValidationError as exc:
        from scenes.errors import short_repr

        lines = []
        errors = exc.errors(include_url=False)
        for err in errors[:20]:
            loc = tuple(p for p in err["loc"] if p not in ("constant", "step", "ramp", "random"))
            lines.append(f"{_loc(loc)}: {err['msg'].removeprefix('Value error, ')} (got "
                         f"{short_repr(err.get('input'))})")
        if len(errors) > 20:
            lines.append(f"... and {len(errors) - 20} more problem(s)")
        raise SpecError("invalid degradation spec: " + "; ".join(lines)) from None


def load_spec(path: str | Path) -> DegradationSpec:
    """Read and validate a YAML or JSON spec file."""
    from scenes.errors import UserInputError
    from scenes.yaml_safe import MAX_BYTES, load_yaml

    p = Path(path)
    try:
        if p.stat().st_size > MAX_BYTES:
            raise SpecError(f"spec {str(p)!r} is larger than {MAX_BYTES} bytes; not a degradation spec")
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise SpecError(f"cannot read spec {str(p)!r}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise SpecError(f"spec {str(p)!r} is not UTF-8 text (byte {exc.start})") from None
    try:
        data = json.loads(text) if p.suffix.lower() == ".json" else load_yaml(text, f"spec {str(p)!r}")
    except json.JSONDecodeError as exc:
        raise SpecError(f"spec {str(p)!r} is not valid JSON: {exc}") from None
    except RecursionError:
        raise SpecError(f"spec {str(p)!r} is nested too deeply to read") from None
    except UserInputError as exc:
        raise SpecError(str(exc)) from None
    if not isinstance(data, dict):
        raise SpecError(f"spec {str(p)!r}: top level must be a mapping, got {type(data).__name__}")
    return parse_spec(data)


# ----------------------------------------------------------------------------- application
def _time_axis(stream: str) -> int:
    return 1 if stream == "rf_spec" else 0


def stream_view(meta: dict, stream: str) -> dict:
    """Meta as one stream sees it: keys prefixed ``<stream>_`` override the unprefixed ones."""
    view = dict(meta)
    pre = stream + "_"
    for k, v in meta.items():
        if k.startswith(pre):
            view[k[len(pre):]] = v
    return view


def stream_times(stream: str, n: int, view: dict, t_s: np.ndarray) -> np.ndarray:
    """Time (s) of each element along the stream's time axis."""
    if view.get("t_s") is not None and np.size(view["t_s"]) == n:
        return np.asarray(view["t_s"], dtype=np.float64)
    t0 = float(t_s[0]) if t_s.size else 0.0
    if stream in ("audio", "rf_iq"):
        sr = view.get("sample_rate_hz")
        if sr is None or not float(sr) > 0:
            raise SpecError(f"meta: {stream} needs a positive '{stream}_sample_rate_hz' or 'sample_rate_hz', got "
                            f"{sr!r}")
        return t0 + np.arange(n) / float(sr)
    if n == t_s.size:
        return t_s.astype(np.float64)
    rate = view.get("fps") if stream in ("rgb", "thermal") else view.get("frame_rate_hz")
    if rate is None or not float(rate) > 0:
        key = "fps" if stream in ("rgb", "thermal") else "frame_rate_hz"
        raise SpecError(f"meta: {stream} has {n} frames but t_s has {t_s.size}; give '{stream}_{key}' or "
                        f"'{stream}_t_s'")
    return t0 + np.arange(n) / float(rate)


def _runs(sev: np.ndarray) -> list[tuple[int, int, float]]:
    """Contiguous (start, stop, severity) runs of equal severity > 0."""
    if sev.size == 0:
        return []
    cuts = np.concatenate([[0], np.flatnonzero(np.diff(sev)) + 1, [sev.size]])
    return [(int(a), int(b), float(sev[a])) for a, b in zip(cuts[:-1], cuts[1:]) if sev[a] > 0]


def _row_max(times: np.ndarray, values: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Max of per-element values over record rows [t_s[k], t_s[k+1]) (last row open-ended)."""
    rows = np.zeros(t_s.size, dtype=np.float64)
    idx = np.searchsorted(t_s, times + 1e-9, side="right") - 1
    ok = idx >= 0
    np.maximum.at(rows, idx[ok], values[ok])
    return rows


def _slice_meta(view: dict, a: int, b: int, n: int, stream: str) -> dict:
    sub = dict(view)
    for k in PER_FRAME_KEYS + ("t_s",):
        v = view.get(k)
        if v is not None and np.ndim(v) > 0 and len(v) == n:
            sub[k] = np.asarray(v)[a:b]
    return sub


def checked_clock(spec: DegradationSpec, t_s: Any) -> np.ndarray:
    """``t_s`` as float64 row times after checking it and the spec (SpecError otherwise)."""
    if not isinstance(spec, DegradationSpec):
        raise SpecError(f"spec must be a DegradationSpec (use load_spec/parse_spec), got {type(spec).__name__}")
    t_s = np.asarray(t_s, dtype=np.float64).ravel()
    if t_s.size == 0 or np.any(np.diff(t_s) <= 0):
        raise SpecError("t_s must be a non-empty, strictly increasing array of row times (s)")
    return t_s


def entry_keys(entries: list[dict]) -> list[str]:
    """Random-stream key of each entry: name + occurrence number ('<name>#<k>'), so inserting other
    stages does not shift an entry's draws."""
    seen: dict[str, int] = {}
    keys = []
    for e in entries:
        keys.append(f"{e['name']}#{seen.get(e['name'], 0)}")
        seen[e["name"]] = seen.get(e["name"], 0) + 1
    return keys


def entries_on(spec: DegradationSpec, streams: list[str], skipped: list[dict]) -> Iterator[tuple[int, dict, str]]:
    """(index, entry, random-stream key) of the entries acting on ``streams``; the others are
    appended to ``skipped`` ("stream absent")."""
    entries = spec.entries()
    for i, (e, key) in enumerate(zip(entries, entry_keys(entries))):
        if e["stream"] in streams:
            yield i, e, key
        else:
            skipped.append({"index": i, "name": e["name"], "stream": e["stream"], "reason": "stream absent"})


def entry_severity(spec: DegradationSpec, e: dict, times: np.ndarray) -> np.ndarray:
    """An entry's severity at element ``times``, clipped to [0, 5] and quantised to the spec's quantum."""
    if e["schedule"] is not None:
        sev = np.clip(e["schedule"].severity_at(times), 0.0, 5.0)
    else:
        sev = np.full(times.size, DEFAULT_LEVEL if e["severity"] is None else e["severity"])
    q = spec.severity_quantum
    return np.clip(np.round(sev / q) * q, 0.0, 5.0)


def count_rows(e: dict, stream: str, times: np.ndarray, sevq: np.ndarray, t_s: np.ndarray,
               sev_rows: dict, missing_rows: dict) -> None:
    """Add one entry's severity (row max) and dropout flags to the per-row record arrays (in place)."""
    rows = _row_max(times, sevq, t_s)
    sev_rows[stream] = np.maximum(sev_rows[stream], rows)
    if e["name"] == "crossmodal.dropout":
        missing_rows[stream] |= rows > 0


def summary_record(spec: DegradationSpec, t_s: np.ndarray, seed: int, present: list[str], sev_rows: dict,
                   missing_rows: dict, applied: list[dict], skipped: list[dict]) -> dict:
    """The record's per-row part (severity, compromised, missing, conflict) plus applied/skipped."""
    K = t_s.size
    compromised = {m: (sev_rows[m] >= spec.compromised_at) | missing_rows[m] for m in present}
    comp = np.stack([compromised[m] for m in present]) if present else np.zeros((0, K), bool)
    return {
        "t_s": t_s.tolist(),
        "seed": int(seed),
        "modalities": present,
        "compromised_at": spec.compromised_at,
        "severity": {m: sev_rows[m].round(6).tolist() for m in present},
        "compromised": {m: compromised[m].tolist() for m in present},
        "missing": {m: missing_rows[m].tolist() for m in present},
        "conflict": (comp.any(axis=0) & ~comp.all(axis=0)).tolist(),
        "applied": applied,
        "skipped": skipped,
    }


def frame_local(spec: DegradationSpec) -> bool:
    """True if every entry acts on each frame alone (no retiming, no clip-long tracks), so the spec
    may be applied frame by frame (``apply_spec(..., frame_offset=i)``) in constant memory."""
    return all(not get(e["name"]).needs_clip and not get(e["name"]).changes_meta for e in spec.entries())


def apply_spec(spec: DegradationSpec, streams: dict[str, Any], meta: dict, seed: int,
               t_s: Any, frame_offset: int = 0) -> tuple[dict[str, Any], dict]:
    """Apply a spec to one sample's streams on the record clock ``t_s`` (K row times, s).

    streams: "rgb" (T, H, W, 3), "thermal" (T, H, W) K, "audio" (N,), "rf_iq" (N,) complex,
    "rf_spec" (F, T) dB; numpy or torch. meta: shared keys plus ``<stream>_``-prefixed ones
    (``thermal_mask``, ``rgb_boxes``, ``audio_sample_rate_hz``, ``rgb_fps`` ...). Each entry's
    schedule is evaluated per element, quantised to ``spec.severity_quantum`` and applied on runs
    of equal severity. Randomness: static entries use SeedSequence([seed, crc('<name>#<k>'), 0]) (k-th use of that name)
    for every run, per-frame entries add the run start + 1 (+ ``frame_offset``: the index of the
    first element in a longer stream processed in pieces). Returns (streams, record).
    """
    if isinstance(frame_offset, bool) or not isinstance(frame_offset, (int, np.integer)) or frame_offset < 0:
        raise SpecError(f"frame_offset must be a non-negative int, got {frame_offset!r}")
    t_s = checked_clock(spec, t_s)
    unknown = sorted(set(streams) - set(MODALITIES))
    if unknown:
        raise SpecError(f"streams: unknown modality {unknown}; expected keys among {list(MODALITIES)}")
    arrays, restores = {}, {}
    for k, v in streams.items():
        arrays[k], restores[k] = _to_numpy(v)
    meta_out = dict(meta)
    K = t_s.size
    present = [m for m in MODALITIES if m in arrays]
    sev_rows = {m: np.zeros(K) for m in present}
    missing_rows = {m: np.zeros(K, bool) for m in present}
    applied: list[dict] = []
    skipped: list[dict] = []
    for i, e, key in entries_on(spec, present, skipped):
        stream = e["stream"]
        x = arrays[stream]
        ax = _time_axis(stream)
        n = x.shape[ax]
        view = stream_view(meta_out, stream)
        if stream == "audio" and view.get("signal_rms") is None:
            view["signal_rms"] = float(np.sqrt(np.mean(x.astype(np.float64) ** 2)))
        if stream == "rf_iq" and view.get("signal_power") is None:
            view["signal_power"] = float(np.mean(np.abs(x.astype(np.complex128)) ** 2))
        times = stream_times(stream, n, view, t_s)
        sevq = entry_severity(spec, e, times)
        count_rows(e, stream, times, sevq, t_s, sev_rows, missing_rows)
        cls = get(e["name"])
        y = x.copy()
        runs_out = []
        static = (e["temporal"] or cls.default_temporal) == "static"
        shown = None
        for a, b, s in _runs(sevq):
            deg = cls(s, temporal=e["temporal"], **e["params"])
            rng = make_rng(seed, key, 0 if static else a + 1 + int(frame_offset))
            sub = _slice_meta(view, a, b, n, stream)
            part = np.take(x, np.arange(a, b), axis=ax)
            params = deg.sample_params(rng, sub)
            out = deg.apply(part, params, sub)
            if ax == 0:
                y[a:b] = out
            else:
                y[:, a:b] = out
            run = {"start": a, "stop": b, "severity": s, "params": params}
            run.update({k: v for k, v in deg.measure(part, out, params, sub).items()})
            if cls.changes_meta:
                new = deg.update_meta(params, sub, tuple(part.shape))
                for k in PER_FRAME_KEYS:
                    if k in new and new[k] is not None and np.ndim(new[k]) > 0 and len(new[k]) == b - a:
                        full = view.get(k)
                        if full is None or np.ndim(full) == 0 or len(full) != n:
                            full = np.full((n,) + np.shape(new[k])[1:], np.nan)
                        full = np.array(full, dtype=np.result_type(np.asarray(full).dtype, np.asarray(new[k]).dtype))
                        full[a:b] = np.asarray(new[k])
                        view[k] = full
                        meta_out[f"{stream}_{k}"] = full
                if cls.retimes and "frame_index_shown" in new:  # others only copy the key along
                    shown = np.arange(n) if shown is None else shown
                    shown[a:b] = shown[a + np.asarray(new["frame_index_shown"])]
                for k in ("missing", "affine", "shift_samples"):
                    if k in new:
                        run[k] = new[k]
            runs_out.append(run)
        if shown is not None:
            meta_out[f"{stream}_frame_index_shown"] = shown.tolist()
        arrays[stream] = y
        applied.append({"index": i, "name": e["name"], "stream": stream, "program": e["program"],
                        "runs": runs_out})
    record = {**summary_record(spec, t_s, seed, present, sev_rows, missing_rows, applied, skipped),
              "meta": meta_out}
    return {k: restores[k](arrays[k]) for k in arrays}, record
