"""Cross-modal faults: one stream (``stream`` param: rgb, thermal, audio, rf_iq, rf_spec) is
missing, late, misaligned or mistimed relative to the others; its labels move with it.

Rates come from meta: ``fps`` (rgb/thermal frames), ``sample_rate_hz`` (audio/rf_iq samples),
``frame_rate_hz`` (rf_spec columns per second).
"""
from __future__ import annotations

import cv2
import numpy as np

from degradations.base import MODALITIES, Degradation, reindex_frames
from degradations.errors import DegradationError
from degradations.registry import register


class _Cross(Degradation):
    """Base: the modality is chosen per instance with the ``stream`` parameter."""
    modality = "rgb"
    streams: tuple[str, ...] = MODALITIES
    #: the stream a spec entry without a ``stream`` (field or parameter) applies it to
    spec_stream: str = "rgb"
    uint8_native = True  # index/warp operations work on uint8 frames directly

    def __init__(self, severity=None, *, temporal=None, **params):
        stream = params.pop("stream", "rgb")
        if stream not in self.streams:
            raise DegradationError(f"{self.name}: stream must be one of {self.streams}, got {stream!r}")
        self.modality = stream  # type: ignore[misc]  # per instance by design: the stream parameter picks it
        super().__init__(severity, temporal=temporal, **params)
        self.overrides["stream"] = stream

    def rate(self, meta: dict) -> float:
        """Samples (frames, columns) per second of this stream, from meta."""
        key = {"rgb": "fps", "thermal": "fps", "audio": "sample_rate_hz", "rf_iq": "sample_rate_hz",
               "rf_spec": "frame_rate_hz"}[self.modality]
        r = meta.get(key)
        if r is None or not float(r) > 0:
            raise DegradationError(f"{self.name}: meta[{key!r}] must be a positive rate for stream {self.modality!r}, "
                                   f"got {r!r}")
        return float(r)

    def time_axis(self) -> int:
        return 1 if self.modality == "rf_spec" else 0


@register
class SensorDropout(_Cross):
    """The stream is missing: all samples are replaced by ``fill`` (0, or NaN for float streams)
    and meta['missing'] is set True (the flag the fusion model is told about, or not)."""
    name = "crossmodal.dropout"
    table = {}
    identity = {}
    extra = {"fill": 0.0}
    random = False
    changes_meta = True
    frame_separable = True
    reports_change = True

    def _apply(self, x, params, meta):
        fill = float(params["fill"])
        if np.isnan(fill) and self.modality == "rgb":
            return np.zeros_like(x)
        return np.full_like(x, fill)

    def update_meta(self, params, meta, shape=None):
        out = dict(meta or {})
        if not self.is_identity(params):
            out["missing"] = True
        return out


@register
class Desync(_Cross):
    """Temporal desync: the stream is delayed by ``dt_s`` (sign drawn unless ``direction`` is +1/-1),
    y[t] = x[t - n] with edge hold, n = round(dt * rate). Per-frame labels are shifted the same way."""
    name = "crossmodal.desync"
    table = {"dt_s": (0.02, 0.05, 0.1, 0.2, 0.5)}
    identity = {"dt_s": 0.0}
    extra = {"direction": 0}
    changes_meta = True
    retimes = True

    def _sample_extra(self, rng, meta, p):
        drawn = 1 if rng.random() < 0.5 else -1
        if p["direction"] not in (0, 1, -1):
            raise DegradationError(f"{self.name}: direction must be -1, 0 (draw) or 1, got {p['direction']!r}")
        p["direction"] = p["direction"] or drawn
        p["shift"] = int(round(p["direction"] * p["dt_s"] * self.rate(meta)))

    def index(self, n: int, params) -> np.ndarray:
        return np.clip(np.arange(n) - int(params["shift"]), 0, n - 1)

    def frame_index(self, n: int, params) -> np.ndarray:
        return self.index(n, params)

    def _apply(self, x, params, meta):
        ax = self.time_axis()
        return np.take(x, self.index(x.shape[ax], params), axis=ax)

    def update_meta(self, params, meta, shape=None):
        out = dict(meta or {})
        if shape is None or self.is_identity(params):
            return out
        ax = self.time_axis()
        if self.modality in ("rgb", "thermal") and len(shape) == self.item_ndims()[0]:
            return out
        out = reindex_frames(out, self.index(shape[ax], params))
        out["shift_samples"] = int(params["shift"])
        return out


def affine_matrix(params: dict, H: int, W: int) -> np.ndarray:
    """2x3 affine: rotation ``rot_deg`` and scale about the centre, then translation."""
    m = cv2.getRotationMatrix2D((W / 2.0, H / 2.0), params["rot_sign"] * params["rot_deg"],
                                1.0 + params["scale_sign"] * params["scale_delta"])
    a = params["shift_angle_rad"]
    m[0, 2] += params["shift_px"] * np.cos(a)
    m[1, 2] += params["shift_px"] * np.sin(a)
    return m


def transform_boxes(boxes: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Axis-aligned boxes (..., 4) xywh mapped through a 2x3 affine (bounding box of the corners)."""
    b = np.asarray(boxes, np.float64)
    if b.size == 0:
        return b
    x, y, w, h = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    cx = np.stack([x, x + w, x, x + w], -1)
    cy = np.stack([y, y, y + h, y + h], -1)
    px = m[0, 0] * cx + m[0, 1] * cy + m[0, 2]
    py = m[1, 0] * cx + m[1, 1] * cy + m[1, 2]
    x0, y0 = px.min(-1), py.min(-1)
    return np.stack([x0, y0, px.max(-1) - x0, py.max(-1) - y0], -1)


@register
class Misalignment(_Cross):
    """RGB-thermal misalignment: affine warp (translation ``shift_px`` in a drawn direction, rotation
    ``rot_deg`` and scale 1 +- ``scale_delta`` about the centre) of one imaging stream; meta boxes
    (xywh, any leading shape) and masks are transformed with the same matrix."""
    name = "crossmodal.misalignment"
    streams = ("rgb", "thermal")
    spec_stream = "thermal"      # the thermal camera is the one misregistered against the RGB reference
    table = {"shift_px": (2.0, 4.0, 8.0, 12.0, 20.0), "rot_deg": (0.5, 1.0, 2.0, 3.0, 5.0),
             "scale_delta": (0.01, 0.02, 0.04, 0.06, 0.1)}
    identity = {"shift_px": 0.0, "rot_deg": 0.0, "scale_delta": 0.0}
    changes_meta = True
    frame_separable = True
    reports_change = True
    default_temporal = "static"

    def __init__(self, severity=None, *, temporal=None, **params):
        params.setdefault("stream", "thermal")
        super().__init__(severity, temporal=temporal, **params)

    def _sample_extra(self, rng, meta, p):
        v = rng.random(3)
        p["shift_angle_rad"] = float(v[0] * 2 * np.pi)
        p["rot_sign"] = 1 if v[1] < 0.5 else -1
        p["scale_sign"] = 1 if v[2] < 0.5 else -1

    def _apply(self, x, params, meta):
        H, W = x.shape[1:3]
        m = affine_matrix(params, H, W)
        return np.stack([cv2.warpAffine(f, m, (W, H), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
                         for f in x])

    def update_meta(self, params, meta, shape=None):
        out = dict(meta or {})
        if shape is None or self.is_identity(params):
            return out
        single = len(shape) == self.item_ndims()[0]
        H, W = (shape[0:2] if single else shape[1:3])
        m = affine_matrix(params, H, W)
        if out.get("boxes") is not None:
            out["boxes"] = transform_boxes(np.asarray(out["boxes"]), m)
        for key in ("mask", "thermal_mask", "rgb_mask"):
            if out.get(key) is not None:
                mk = np.asarray(out[key]).astype(np.uint8)
                frames = mk[None] if mk.ndim == 2 else mk
                warped = np.stack([cv2.warpAffine(f, m, (W, H), flags=cv2.INTER_NEAREST) for f in frames]).astype(bool)
                out[key] = warped[0] if mk.ndim == 2 else warped
        out["affine"] = m.tolist()
        return out


@register
class FrameRateMismatch(_Cross):
    """The camera actually runs at ``rate_ratio`` x the nominal rate while frames are stamped at the
    nominal rate: output frame t shows source frame floor((t + phase) * ratio), phase in [0, 1)
    drawn (where the slow camera's frame grid starts); labels follow."""
    name = "crossmodal.frame_rate_mismatch"
    streams = ("rgb", "thermal")
    table = {"rate_ratio": (0.95, 0.9, 0.8, 0.67, 0.5)}
    identity = {"rate_ratio": 1.0}
    changes_meta = True
    needs_clip = True
    retimes = True

    def _sample_extra(self, rng, meta, p):
        p["phase"] = float(rng.random())

    def frame_index(self, n: int, params) -> np.ndarray:
        return self.index(n, params)

    def index(self, n: int, params) -> np.ndarray:
        r = float(params["rate_ratio"])
        if not 0 < r <= 1:
            raise DegradationError(f"{self.name}: rate_ratio must be in (0, 1], got {r}")
        return np.clip(np.floor((np.arange(n) + params["phase"]) * r).astype(np.int64), 0, n - 1)

    def _apply(self, x, params, meta):
        return x[self.index(x.shape[0], params)]

    def update_meta(self, params, meta, shape=None):
        if shape is None or self.is_identity(params) or len(shape) == self.item_ndims()[0]:
            return dict(meta or {})
        return reindex_frames(dict(meta or {}), self.index(shape[0], params))


# ----------------------------------------------------------------------------- signature swaps
def blend_signature(x: np.ndarray, donor: np.ndarray, strength: float, stream: str) -> np.ndarray:
    """Move a stream towards a donor recording of the SAME scene (its counterfactual twin).

    The twin differs only in the drone's own signature, so ``strength`` 1 removes the drone's
    evidence from a drone clip (target-blinding) or adds a drone's evidence to a background clip
    (a decoy that is drone-like to this one sensor); 0 < strength < 1 is the weak variant: the
    signature at (1 - strength) / strength of its amplitude (rgb, audio, rf_iq) or power (rf_spec).
    Pure: rgb uint8 frames blend in [0, 255] (rounded), audio and I/Q blend linearly, RF
    spectrograms (dB) blend in power.
    """
    if not 0.0 <= float(strength) <= 1.0:
        raise DegradationError(f"signature swap: strength must be in [0, 1], got {strength!r}")
    x, donor = np.asarray(x), np.asarray(donor)
    if x.shape != donor.shape:
        raise DegradationError(f"signature swap: donor shape {donor.shape} differs from the stream's {x.shape}")
    s = float(strength)
    if stream == "rgb":
        y = (1.0 - s) * x.astype(np.float64) + s * donor.astype(np.float64)
        return np.clip(np.round(y), 0, 255).astype(x.dtype) if x.dtype == np.uint8 else y.astype(x.dtype)
    if stream in ("audio", "rf_iq"):
        return ((1.0 - s) * x + s * donor).astype(x.dtype)
    if stream == "rf_spec":
        p = ((1.0 - s) * np.power(10.0, x.astype(np.float64) / 10.0) + s
             * np.power(10.0, donor.astype(np.float64) / 10.0))
        return (10.0 * np.log10(np.maximum(p, 1e-30))).astype(x.dtype)
    raise DegradationError(f"signature swap: stream must be rgb, audio, rf_iq or rf_spec, got {stream!r}")
