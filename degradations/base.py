"""The degradation unit: a small class with ``sample_params`` (all randomness) and a pure ``apply``.

Conventions (documented once, see docs/DEGRADATIONS.md):

* ``sample_params(rng, meta) -> dict`` makes every random draw. Large random fields (noise images,
  noise waveforms) are not params: a small integer ``noise_seed`` is drawn and ``apply`` regenerates
  the field with ``np.random.default_rng(noise_seed)``. Params are small and JSON-serialisable.
* ``apply(x, params, meta) -> x`` is pure and deterministic. It never changes meta; geometry or
  timing changes to labels are returned by ``update_meta(params, meta) -> meta`` (a new dict).
* ``sample_params`` makes the same draws in the same order whatever the severity, so the same seed
  at two severities gives the same noise field scaled differently (severity sweeps are paired).
* Layout of one *item* per modality: ``rgb`` frame (H, W, 3) or clip (T, H, W, 3), uint8 or float
  in [0, 1]; ``thermal`` frame (H, W) or clip (T, H, W) in kelvin; ``audio`` (N,) float;
  ``rf_iq`` (N,) complex; ``rf_spec`` (F, T) float dB. One extra leading axis is a batch.
"""
from __future__ import annotations

import math
import zlib
from typing import Any, ClassVar

import numpy as np

from degradations.errors import DegradationError

MODALITIES = ("rgb", "thermal", "audio", "rf_iq", "rf_spec")
TEMPORAL_MODES = ("per_frame", "static")
#: Severity used when neither a severity nor a full set of params is given.
DEFAULT_LEVEL = 3.0


def stream_id(name: str) -> int:
    """Stable 32-bit id of a named random stream (independent of Python's hash seed)."""
    return zlib.crc32(name.encode("utf-8"))


def make_rng(seed: int, *keys: int | str) -> np.random.Generator:
    """Generator from ``SeedSequence([seed, *keys])``; string keys are mapped by :func:`stream_id`."""
    entropy = [int(seed)] + [stream_id(k) if isinstance(k, str) else int(k) for k in keys]
    if any(v < 0 for v in entropy):
        raise DegradationError(f"seed and stream keys must be non-negative integers, got {entropy}")
    return np.random.default_rng(np.random.SeedSequence(entropy))


def interpolate_level(table: tuple[float, ...], identity: float, severity: float) -> float:
    """Value of a 5-level table at a continuous severity in [0, 5] (0 = identity).

    Levels 1-5 are linearly interpolated. Between 0 and 1 the value moves linearly from
    ``identity`` to level 1, except for dB quantities whose identity is +inf (an SNR): there the
    *noise amplitude* 10^(-v/20) is interpolated linearly from 0, so severity 0.5 is 6 dB cleaner
    than level 1.
    """
    s = float(severity)
    if s <= 0.0:
        return float(identity)
    if s >= 1.0:
        lo = min(int(math.floor(s)), 5)
        if lo >= 5:
            return float(table[4])
        frac = s - lo
        return float(table[lo - 1] + frac * (table[lo] - table[lo - 1]))
    if math.isinf(identity):
        amp = s * 10.0 ** (-table[0] / 20.0)
        return float(-20.0 * math.log10(amp))
    return float(identity + s * (table[0] - identity))


#: Closed domain [lo, hi] of every numeric parameter a user may set explicitly (spec files, the
#: Python API, experiment configs). They bound physically meaningful values and the work a call can
#: cause (a 1e5-pixel blur radius would allocate hundreds of GiB); severity 0 is the identity, so
#: "no noise" is never spelled as an infinite SNR.
PARAM_DOMAINS: dict[str, tuple[float, float]] = {
    # audio
    "snr_db": (-60.0, 120.0), "min_snr_db": (-60.0, 120.0), "max_snr_db": (-60.0, 120.0), "p": (0.0, 1.0),
    "low_cut_hz": (0.0, 96000.0), "high_cut_hz": (1.0, 96000.0), "drop_fraction": (0.0, 1.0),
    "gap_ms": (0.1, 10000.0), "gain_db": (-60.0, 60.0), "clip_level": (1e-6, 1e6), "gust_hz": (0.0, 100.0),
    "cutoff_hz": (1.0, 96000.0),
    # cross-modal
    "dt_s": (0.0, 60.0), "direction": (-1.0, 1.0), "rate_ratio": (0.05, 20.0), "shift_px": (0.0, 4096.0),
    "rot_deg": (-180.0, 180.0), "scale_delta": (-0.5, 0.5),
    # rf
    "bits": (1.0, 24.0), "clip_rms": (0.01, 1000.0), "k_factor": (0.0, 1e12), "delay_spread": (0.0, 64.0),
    "n_taps": (1.0, 64.0), "offset_norm": (-0.5, 0.5), "drift_norm": (-0.5, 0.5), "amp_db": (-20.0, 20.0),
    "phase_deg": (-90.0, 90.0), "attenuation_db": (0.0, 200.0), "noise_floor_db": (-50.0, 200.0),
    "mask_fraction": (0.0, 1.0), "n_masks": (0.0, 100.0), "sir_db": (-60.0, 120.0), "n_carriers": (1.0, 100.0),
    "burst_fraction": (0.0, 1.0), "duty": (0.0, 1.0), "bandwidth_frac": (0.0, 1.0), "burst_frac": (0.0, 1.0),
    # thermal
    "hot_k": (0.0, 5000.0), "size_frac": (0.0, 1.0), "sigma_px": (0.0, 100.0), "halo": (0.0, 10.0),
    "strength": (0.0, 1.0), "ring_px": (0.0, 256.0), "fraction": (0.0, 1.0), "size_px": (0.0, 512.0),
    "contrast_k": (-200.0, 200.0), "gain_std": (0.0, 1.0), "offset_std_k": (0.0, 50.0), "ref_k": (1.0, 1000.0),
    "netd_k": (0.0, 10.0),
    # video
    "qscale": (0.0, 100.0), "gop": (1.0, 1000.0), "p_qscale_factor": (0.01, 100.0), "radius_px": (0.0, 256.0),
    "beta_per_m": (0.0, 10.0), "airlight": (0.0, 1.0), "default_range_m": (0.0, 1e6), "drop_prob": (0.0, 1.0),
    "freeze_fraction": (0.0, 1.0), "sigma": (0.0, 5.0), "amount": (0.0, 1.0), "quality": (1.0, 100.0),
    "n_spots": (0.0, 1000.0), "opacity": (0.0, 1.0), "exposure": (0.0, 100.0), "read_sigma": (0.0, 5.0),
    "gamma": (0.05, 20.0), "length_px": (1.0, 256.0), "density": (0.0, 1.0), "brightness": (0.0, 5.0),
    "factor": (1.0, 64.0), "photons": (1e-3, 1e9), "coverage": (0.0, 1.0), "colour": (0.0, 1.0),
    "intensity": (0.0, 10.0), "radius_frac": (1e-3, 10.0), "veil": (0.0, 1.0),
}


def _short(value: Any, limit: int = 60) -> str:
    text = repr(value) if isinstance(value, (int, float, str, bool, type(None))) else type(value).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _jsonable(v: Any) -> Any:
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.bool_,)):
        return bool(v)
    if isinstance(v, (list, tuple)):
        return [_jsonable(u) for u in v]
    if isinstance(v, dict):
        return {k: _jsonable(u) for k, u in v.items()}
    return v


class Degradation:
    """Base class. Subclasses set the class attributes and implement ``_apply`` on one item.

    ``_apply`` receives the item in the *work domain*: rgb float32 [0, 1] clip (T, H, W, 3),
    thermal float32 clip (T, H, W), audio/rf_iq 1-D, rf_spec 2-D.
    """

    name: ClassVar[str] = ""
    modality: ClassVar[str] = ""
    #: parameter -> values at severity levels 1..5
    table: ClassVar[dict[str, tuple[float, ...]]] = {}
    #: parameter -> value at severity 0 (the identity)
    identity: ClassVar[dict[str, float]] = {}
    #: extra (non-table) parameters accepted by the constructor, with defaults
    extra: ClassVar[dict[str, Any]] = {}
    #: per-class parameter domains [lo, hi] overriding :data:`PARAM_DOMAINS`
    domains: ClassVar[dict[str, tuple[float, float]]] = {}
    #: integer-valued table params (rounded after interpolation)
    integer_params: ClassVar[tuple[str, ...]] = ()
    #: does the transform draw random numbers at all?
    random: ClassVar[bool] = True
    #: default choice between one draw for the whole clip ("static") and a fresh draw per frame
    default_temporal: ClassVar[str] = "per_frame"
    #: report the realised SNR (signal power / power of y - x) in the info dict
    reports_snr: ClassVar[bool] = False
    #: changes labels (boxes, masks, frame indices) through ``update_meta``
    changes_meta: ClassVar[bool] = False
    #: needs a time axis (clip), e.g. frame drop; single frames are rejected
    needs_clip: ClassVar[bool] = False
    #: rgb only: ``_apply`` accepts uint8 clips directly (cv2 filters, JPEG) and returns uint8
    uint8_native: ClassVar[bool] = False
    #: a pure retime: output element t is input element ``frame_index(n, params)[t]``, nothing else
    #: changes (frame drop/freeze, desync, frame-rate mismatch); measured as ``retimed_fraction``
    retimes: ClassVar[bool] = False
    #: clip-level transforms (needs_clip / changes_meta) that are not retimes: ``apply`` on ONE frame
    #: of a run, with ``meta['run_offset']`` = that frame's position in the run, equals that frame
    #: of ``apply`` on the whole run (so `evids degrade` may stream the clip frame by frame)
    frame_separable: ClassVar[bool] = False
    #: report the realised change of a run (``changed_frame_fraction``, ``mean_abs_change``) from
    #: additive per-frame sums, so a run processed frame by frame reports exactly the same values
    reports_change: ClassVar[bool] = False

    def __init__(self, severity: float | None = None, *, temporal: str | None = None,
                 **params: Any) -> None:
        if severity is not None:
            if not isinstance(severity, (int, float)) or isinstance(severity, bool) \
                    or not (0.0 <= float(severity) <= 5.0) or math.isnan(float(severity)):
                raise DegradationError(f"{self.name}: severity must be a number in [0, 5], got {severity!r}")
        allowed = set(self.table) | set(self.extra)
        unknown = sorted(set(params) - allowed)
        if unknown:
            raise DegradationError(
                f"{self.name}: unknown parameter(s) {', '.join(_short(u) for u in unknown[:10])}; allowed: "
                f"{sorted(allowed)}")
        temporal = temporal or self.default_temporal
        if temporal not in TEMPORAL_MODES:
            raise DegradationError(f"{self.name}: temporal must be one of {TEMPORAL_MODES}, got {temporal!r}")
        self.severity = None if severity is None else float(severity)
        self.temporal = temporal
        self.overrides = dict(params)
        for key, value in params.items():
            self.check_param(key, value)

    # -- parameters -------------------------------------------------------------------------
    def check_param(self, key: str, value: Any) -> None:
        """Validate one explicit parameter against its domain (:data:`PARAM_DOMAINS`, or the class's
        ``domains``); subclasses extend. Raises DegradationError naming the parameter and range."""
        domain = self.domains.get(key, PARAM_DOMAINS.get(key))
        if key in self.table or domain is not None:
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(float(value)):
                raise DegradationError(f"{self.name}: parameter {key} must be a finite number, got {_short(value)}")
        if domain is not None:
            lo, hi = domain
            if not lo <= float(value) <= hi:
                raise DegradationError(f"{self.name}: parameter {key} must be in [{lo:g}, {hi:g}], got {_short(value)}")

    def level_params(self, severity: float) -> dict[str, Any]:
        """Table values at a continuous severity."""
        out: dict[str, Any] = {}
        for key, values in self.table.items():
            v = interpolate_level(values, self.identity[key], severity)
            out[key] = int(round(v)) if key in self.integer_params else v
        return out

    @property
    def nominal_severity(self) -> float:
        """Severity used for the table (explicit, else level 3)."""
        return DEFAULT_LEVEL if self.severity is None else self.severity

    def sample_params(self, rng: np.random.Generator, meta: dict | None = None) -> dict[str, Any]:
        """Resolve severity to parameter values and make every random draw (JSON-serialisable)."""
        meta = meta or {}
        p: dict[str, Any] = {"severity": self.nominal_severity, "temporal": self.temporal}
        p.update(self.level_params(self.nominal_severity))
        p.update({k: v for k, v in self.extra.items()})
        p.update(self.overrides)
        # Always the first draw, whatever the severity: keeps severity sweeps paired.
        p["noise_seed"] = int(rng.integers(0, 2**31 - 1)) if self.random else 0
        self._sample_extra(rng, meta, p)
        return _jsonable(p)

    def _sample_extra(self, rng: np.random.Generator, meta: dict, p: dict[str, Any]) -> None:
        """Subclass hook for additional small draws (angles, positions); fixed count per call."""

    def is_identity(self, params: dict[str, Any]) -> bool:
        """True when params mean "do nothing" (severity 0 with no explicit overrides)."""
        return float(params.get("severity", 1.0)) <= 0.0 and not any(
            k in self.table for k in self.overrides)

    # -- application ------------------------------------------------------------------------
    def apply(self, x: np.ndarray, params: dict[str, Any], meta: dict | None = None) -> np.ndarray:
        """Pure transform of ONE item (numpy, native dtype in, same dtype out)."""
        meta = meta or {}
        x = np.asarray(x)
        if self.is_identity(params):
            return x.copy()
        work, restore = self._to_work(x)
        out = self._apply(work, params, meta)
        return restore(out)

    def update_meta(self, params: dict[str, Any], meta: dict | None,
                    shape: tuple[int, ...] | None = None) -> dict:
        """Labels after the transform (new dict; ``shape`` is the item's shape); default: unchanged."""
        return dict(meta or {})

    def frame_index(self, n: int, params: dict[str, Any]) -> np.ndarray:
        """Retimes only: the input element shown at each of ``n`` output elements."""
        raise DegradationError(f"{self.name}: not a retime (no frame index)")

    def n_elements(self, x: np.ndarray) -> int:
        """Length of one item's time axis (1 for a single rgb/thermal frame)."""
        x = np.asarray(x)
        if self.modality in ("rgb", "thermal"):
            return 1 if x.ndim == self.item_ndims()[0] else int(x.shape[0])
        return int(x.shape[1 if self.modality == "rf_spec" else 0])

    def measure(self, x: np.ndarray, y: np.ndarray, params: dict[str, Any],
                meta: dict | None = None) -> dict[str, float]:
        """Realised quantities after apply (e.g. the realised SNR, measured from y - x)."""
        if self.retimes:
            return retime_measure(self.frame_index(self.n_elements(x), params))
        if self.reports_change:
            xs, ys = np.asarray(x), np.asarray(y)
            if xs.ndim == self.item_ndims()[0]:
                xs, ys = xs[None], ys[None]
            sums = None
            for t in range(xs.shape[0]):
                sums = add_sums(sums, change_sums(xs[t], ys[t]))
            return change_measure(sums)
        if not self.reports_snr:
            return {}
        xs = np.asarray(x).astype(np.complex128 if np.iscomplexobj(x) else np.float64)
        ys = np.asarray(y).astype(xs.dtype)
        ys -= xs                                                         # the noise that was added
        ps, pn = _mean_power(xs), _mean_power(ys)
        snr = math.inf if pn == 0.0 else (-math.inf if ps == 0.0 else 10.0 * math.log10(ps / pn))
        return {"realised_snr_db": snr, "signal_power": ps, "noise_power": pn}

    def _apply(self, x: np.ndarray, params: dict[str, Any], meta: dict) -> np.ndarray:
        raise DegradationError(f"{type(self).__name__} does not define _apply")

    # -- dtype / layout handling (one item) -----------------------------------------------------
    def item_ndims(self) -> tuple[int, ...]:
        """Accepted ndim of one item (first entry is the native single item)."""
        return {"rgb": (3, 4), "thermal": (2, 3), "audio": (1,), "rf_iq": (1,),
                "rf_spec": (2,)}[self.modality]

    def _to_work(self, x: np.ndarray):
        mod = self.modality
        dtype = x.dtype
        if mod == "rgb":
            if x.ndim not in (3, 4) or x.shape[-1] != 3:
                raise DegradationError(
                    f"{self.name}: rgb input must be (H, W, 3) or (T, H, W, 3), got shape {x.shape}")
            single = x.ndim == 3
            if self.needs_clip and single:
                raise DegradationError(f"{self.name}: needs a clip (T, H, W, 3), got a single frame")
            w = x[None] if single else x
            if dtype == np.uint8 and self.uint8_native:
                return w, lambda y: y[0] if single else y
            if dtype == np.uint8:
                w = w.astype(np.float32) * np.float32(1.0 / 255.0)
            elif np.issubdtype(dtype, np.floating):
                w = w.astype(np.float32)
            else:
                raise DegradationError(f"{self.name}: rgb dtype must be uint8 or float, got {dtype}")

            def restore(y: np.ndarray) -> np.ndarray:
                y = y[0] if single else y
                if dtype == np.uint8:
                    return np.clip(y * 255.0 + 0.5, 0, 255).astype(np.uint8)
                return np.clip(y, 0.0, 1.0).astype(dtype)
            return w, restore
        if mod == "thermal":
            if x.ndim not in (2, 3) or not np.issubdtype(dtype, np.floating):
                raise DegradationError(
                    f"{self.name}: thermal input must be float kelvin (H, W) or (T, H, W), got {dtype} {x.shape}")
            single = x.ndim == 2
            if self.needs_clip and single:
                raise DegradationError(f"{self.name}: needs a clip (T, H, W), got a single frame")
            w = (x[None] if single else x).astype(np.float32)
            return w, lambda y: (y[0] if single else y).astype(dtype)
        if mod in ("audio", "rf_iq"):
            if x.ndim != 1:
                raise DegradationError(f"{self.name}: {mod} item must be 1-D, got shape {x.shape}")
            if mod == "rf_iq":
                if not np.iscomplexobj(x):
                    raise DegradationError(f"{self.name}: rf_iq must be complex I/Q, got {dtype}")
                return x.astype(np.complex64), lambda y: y.astype(dtype)
            if not np.issubdtype(dtype, np.floating):
                raise DegradationError(f"{self.name}: audio must be float, got {dtype}")
            return x.astype(np.float32), lambda y: y.astype(dtype)
        if mod == "rf_spec":
            if x.ndim != 2 or not np.issubdtype(dtype, np.floating):
                raise DegradationError(f"{self.name}: rf_spec item must be float dB (F, T), got {dtype} {x.shape}")
            return x.astype(np.float32), lambda y: y.astype(dtype)
        raise DegradationError(f"{self.name}: unknown modality {mod!r}")

    # -- helpers for subclasses -----------------------------------------------------------------
    @staticmethod
    def noise_rng(params: dict[str, Any]) -> np.random.Generator:
        """The generator that regenerates this call's large random fields."""
        return np.random.default_rng(int(params["noise_seed"]))

    @staticmethod
    def field_shape(clip_shape: tuple[int, ...], params: dict[str, Any]) -> tuple[int, ...]:
        """Shape of a per-frame (T, ...) or static (1, ...) random field for a clip."""
        if params.get("temporal", "per_frame") == "static":
            return (1,) + tuple(clip_shape[1:])
        return tuple(clip_shape)


def retime_measure(index: np.ndarray) -> dict[str, float]:
    """``retimed_fraction``: share of a run's output elements showing another input element."""
    idx = np.asarray(index)
    return {"retimed_fraction": float(np.mean(idx != np.arange(idx.size))) if idx.size else 0.0}


def change_sums(x: np.ndarray, y: np.ndarray) -> dict[str, float]:
    """Additive sums of the change y - x of ONE frame (stream units: grey levels, kelvin)."""
    d = np.abs(np.asarray(y, np.float64) - np.asarray(x, np.float64))
    return {"frames": 1.0, "changed_frames": float(d.any()), "abs_change": float(d.sum()), "values": float(d.size)}


def add_sums(total: dict[str, float] | None, part: dict[str, float]) -> dict[str, float]:
    """``total`` + ``part`` key by key (None is the empty sum)."""
    return dict(part) if total is None else {k: total[k] + part[k] for k in total}


def change_measure(sums: dict[str, float] | None) -> dict[str, float]:
    """``changed_frame_fraction`` and ``mean_abs_change`` from the summed :func:`change_sums`."""
    if not sums or sums["frames"] == 0:
        return {}
    return {"changed_frame_fraction": sums["changed_frames"] / sums["frames"],
            "mean_abs_change": sums["abs_change"] / max(sums["values"], 1.0)}


#: meta keys holding one entry per frame (first axis = time); retimed by frame drop/freeze/desync
PER_FRAME_KEYS = ("boxes", "mask", "exist", "thermal_mask", "rgb_mask", "decoy_boxes", "range_m")


def reindex_frames(meta: dict, shown: np.ndarray) -> dict:
    """New meta whose per-frame labels follow the frame actually shown at each output index."""
    out = dict(meta)
    shown = np.asarray(shown, dtype=np.int64)
    for key in PER_FRAME_KEYS:
        v = meta.get(key)
        if v is None or np.ndim(v) == 0:
            continue
        arr = np.asarray(v)
        if arr.shape[0] != shown.size:
            continue
        out[key] = arr[shown]
    out["frame_index_shown"] = shown.tolist()
    return out


def _mean_power(a: np.ndarray) -> float:
    """mean(|a|^2) in float64 (one pass; a view as real pairs for complex)."""
    flat = np.ascontiguousarray(a).ravel()
    if np.iscomplexobj(flat):
        flat = flat.view(flat.real.dtype)
        return float(np.einsum("i,i->", flat, flat) / (flat.size // 2)) if flat.size else float("nan")
    return float(np.einsum("i,i->", flat, flat) / flat.size) if flat.size else float("nan")


def _normal_table() -> np.ndarray:
    from scipy.special import ndtri

    return ndtri((np.arange(65536, dtype=np.float64) + 0.5) / 65536.0).astype(np.float32)


#: inverse-CDF table of the standard normal at 65536 equiprobable points (|z| <= 4.33)
NORMAL_TABLE = _normal_table()


def fast_normal(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Standard-normal float32 field via a 16-bit inverse-CDF table (about 4x faster than
    ``standard_normal`` for image-sized fields; tails truncated at 4.33 sigma, 65536 levels).
    Used for image/thermal sensor noise, where that resolution is far below one grey level."""
    n = int(np.prod(shape))
    idx = np.frombuffer(rng.bytes(2 * n), dtype=np.uint16)
    return NORMAL_TABLE.take(idx).reshape(shape)                    # take: ~2x fancy indexing here
