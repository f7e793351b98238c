"""RGB video degradations (frames (H, W, 3) or clips (T, H, W, 3), uint8 or float in [0, 1]).

Work domain: float32 in [0, 1] (uint8 is converted at the boundary and rounded back), except the
cv2-filter/JPEG transforms marked ``uint8_native`` that run on uint8 directly for speed. Severity
tables follow ImageNet-C where it has the corruption (noise, blur, JPEG).
"""
from __future__ import annotations

import cv2
import numpy as np

from degradations.base import NORMAL_TABLE, Degradation, fast_normal, reindex_frames
from degradations.errors import DegradationError
from degradations.registry import register


def _frames(fn, clip: np.ndarray) -> np.ndarray:
    """Apply a per-frame function (cv2 op) over a clip (T, H, W, C)."""
    if clip.shape[0] == 1:
        return fn(clip[0])[None]
    return np.stack([fn(f) for f in clip])


def line_kernel(length_px: int, angle_deg: float) -> np.ndarray:
    """Normalised motion-blur line kernel of odd size ``length_px`` at ``angle_deg``."""
    k = max(1, int(length_px)) | 1
    ker = np.zeros((k, k), np.float32)
    c = k // 2
    dx, dy = np.cos(np.deg2rad(angle_deg)) * c, np.sin(np.deg2rad(angle_deg)) * c
    cv2.line(ker, (int(round(c - dx)), int(round(c - dy))), (int(round(c + dx)), int(round(c + dy))), 1.0, 1,
             lineType=cv2.LINE_AA)
    return ker / ker.sum()


def trim_kernel(ker: np.ndarray) -> np.ndarray:
    """Drop all-zero outer rows/columns symmetrically (the centre, i.e. the anchor, stays put):
    the filter result is unchanged, but OpenCV filters a thin kernel directly instead of by DFT
    (a 15 x 15 line kernel: about 10-25x faster)."""
    rows, cols = np.flatnonzero(ker.any(axis=1)), np.flatnonzero(ker.any(axis=0))
    cy, cx = ker.shape[0] // 2, ker.shape[1] // 2
    ry = max(cy - rows[0], rows[-1] - cy)
    rx = max(cx - cols[0], cols[-1] - cx)
    return ker[cy - ry:cy + ry + 1, cx - rx:cx + rx + 1]


def disk_kernel(radius_px: float) -> np.ndarray:
    """Normalised defocus disk kernel (anti-aliased edge)."""
    r = max(float(radius_px), 0.5)
    k = int(np.ceil(r)) * 2 + 1
    yy, xx = np.mgrid[:k, :k] - k // 2
    ker = np.clip(r + 0.5 - np.sqrt(xx**2 + yy**2), 0, 1).astype(np.float32)
    return ker / ker.sum()


def smooth_field(rng: np.random.Generator, n: int, h: int, w: int, cells: tuple[int, int] = (6, 8)) -> np.ndarray:
    """n smooth random fields in [0, 1] (coarse grid upsampled with bicubic), float32 (n, h, w)."""
    grids = rng.random((n, cells[0], cells[1])).astype(np.float32)
    out = np.stack([cv2.resize(g, (w, h), interpolation=cv2.INTER_CUBIC) for g in grids])
    lo, hi = out.min(axis=(1, 2), keepdims=True), out.max(axis=(1, 2), keepdims=True)
    return (out - lo) / np.maximum(hi - lo, 1e-6)


@register
class GaussianNoise(Degradation):
    """Additive Gaussian noise, ImageNet-C sigmas on [0, 1] images; fresh per frame by default.

    uint8 input is processed in the integer domain: y = clip(x + round(255 sigma n)), which equals
    round(clip(x/255 + sigma n) * 255) for integer x. Normal draws use ``fast_normal``."""
    name = "video.gaussian_noise"
    modality = "rgb"
    table = {"sigma": (0.08, 0.12, 0.18, 0.26, 0.38)}
    identity = {"sigma": 0.0}
    uint8_native = True

    def _apply(self, x, params, meta):
        shape = self.field_shape(x.shape, params)
        if x.dtype == np.uint8:  # same bytes as fast_normal, looked up in a pre-scaled integer table
            idx = np.frombuffer(self.noise_rng(params).bytes(2 * int(np.prod(shape))), np.uint16).reshape(shape)
            lut = np.round(NORMAL_TABLE * np.float32(255.0 * params["sigma"])).astype(np.int16)
            y = lut[idx] + x.astype(np.int16)
            np.clip(y, 0, 255, out=y)
            return y.astype(np.uint8)
        n = fast_normal(self.noise_rng(params), shape)
        n *= np.float32(params["sigma"])
        return np.clip(x + n, 0.0, 1.0)


@register
class ShotNoise(Degradation):
    """Poisson (photon) noise: y = Poisson(x * photons) / photons (ImageNet-C photons 60..3)."""
    name = "video.shot_noise"
    modality = "rgb"
    table = {"photons": (60.0, 25.0, 12.0, 5.0, 3.0)}
    identity = {"photons": 1000.0}

    def _apply(self, x, params, meta):
        lam = float(params["photons"])
        if params.get("temporal") == "static":
            raise DegradationError(f"{self.name}: shot noise is signal-dependent; temporal must be 'per_frame'")
        y = self.noise_rng(params).poisson(x * lam).astype(np.float32) / np.float32(lam)
        return np.clip(y, 0.0, 1.0)


@register
class ImpulseNoise(Degradation):
    """Salt-and-pepper noise on a fraction ``amount`` of pixel values (ImageNet-C amounts)."""
    name = "video.impulse_noise"
    modality = "rgb"
    table = {"amount": (0.03, 0.06, 0.09, 0.17, 0.27)}
    identity = {"amount": 0.0}

    def _apply(self, x, params, meta):
        rng = self.noise_rng(params)
        u = rng.random(self.field_shape(x.shape, params), dtype=np.float32)
        a = np.float32(params["amount"])
        y = np.where(u < a / 2, np.float32(0.0), x)
        return np.where(u > 1 - a / 2, np.float32(1.0), y)


@register
class MotionBlur(Degradation):
    """Linear motion blur of ``length_px`` at a random angle (drawn once per item)."""
    name = "video.motion_blur"
    modality = "rgb"
    table = {"length_px": (7.0, 11.0, 15.0, 21.0, 29.0)}
    identity = {"length_px": 1.0}
    integer_params = ("length_px",)
    uint8_native = True

    def _sample_extra(self, rng, meta, p):
        p["angle_deg"] = float(rng.uniform(0.0, 180.0))

    def _apply(self, x, params, meta):
        ker = trim_kernel(line_kernel(params["length_px"], params["angle_deg"]))
        return _frames(lambda f: cv2.filter2D(f, -1, ker, borderType=cv2.BORDER_REFLECT), x)


@register
class DefocusBlur(Degradation):
    """Defocus: disk kernel of ``radius_px`` (ImageNet-C radii)."""
    name = "video.defocus_blur"
    modality = "rgb"
    table = {"radius_px": (3.0, 4.0, 6.0, 8.0, 10.0)}
    identity = {"radius_px": 0.0}
    random = False
    uint8_native = True

    def _apply(self, x, params, meta):
        ker = disk_kernel(params["radius_px"])
        return _frames(lambda f: cv2.filter2D(f, -1, ker, borderType=cv2.BORDER_REFLECT), x)


@register
class LowLight(Degradation):
    """Night/dusk: exposure drop, then read noise (sigma ``read_sigma``), then gamma (>1 darkens)."""
    name = "video.low_light"
    modality = "rgb"
    table = {"exposure": (0.6, 0.4, 0.25, 0.15, 0.08), "read_sigma": (0.01, 0.015, 0.02, 0.03, 0.04),
             "gamma": (1.1, 1.2, 1.3, 1.4, 1.5)}
    identity = {"exposure": 1.0, "read_sigma": 0.0, "gamma": 1.0}

    def _apply(self, x, params, meta):
        n = fast_normal(self.noise_rng(params), self.field_shape(x.shape, params))
        y = np.clip(x * np.float32(params["exposure"]) + n * np.float32(params["read_sigma"]), 0.0, 1.0)
        return np.power(y, np.float32(params["gamma"]))


@register
class Fog(Degradation):
    """Fog/haze, Koschmieder: I = J t + A (1 - t), t = exp(-beta d).

    d comes from meta['depth_m'] ((H, W) or (T, H, W)), else meta['range_m'] (scalar or per frame),
    else ``default_range_m`` (300 m). beta = 3.912 / visibility: the table is visibility
    3000/1500/800/400/200 m. ``airlight`` is A on [0, 1].
    """
    name = "video.fog"
    modality = "rgb"
    table = {"beta_per_m": (3.912 / 3000, 3.912 / 1500, 3.912 / 800, 3.912 / 400, 3.912 / 200)}
    identity = {"beta_per_m": 0.0}
    extra = {"airlight": 0.85, "default_range_m": 300.0}
    random = False

    def _apply(self, x, params, meta):
        T, H, W = x.shape[:3]
        if meta.get("depth_m") is not None:
            d = np.asarray(meta["depth_m"], dtype=np.float32)
            if d.shape not in ((H, W), (T, H, W)):
                raise DegradationError(f"{self.name}: meta['depth_m'] shape {d.shape} must be (H, W) or (T, H, W)")
            d = d.reshape((-1, H, W, 1))
        elif meta.get("range_m") is not None:
            d = np.asarray(meta["range_m"], dtype=np.float32).reshape(-1, 1, 1, 1)
            if d.shape[0] not in (1, T):
                raise DegradationError(f"{self.name}: meta['range_m'] must be a scalar or have T={T} entries")
        else:
            d = np.full((1, 1, 1, 1), params["default_range_m"], np.float32)
        if np.any(d < 0):
            raise DegradationError(f"{self.name}: ranges must be >= 0 m")
        t = np.exp(-np.float32(params["beta_per_m"]) * d)
        a = np.float32(params["airlight"])
        return x * t + a * (1.0 - t)


@register
class Smoke(Degradation):
    """Smoke / occluding patches: smooth random blobs covering ``coverage`` of the frame, grey."""
    name = "video.smoke"
    modality = "rgb"
    table = {"coverage": (0.1, 0.2, 0.3, 0.45, 0.6), "opacity": (0.5, 0.6, 0.7, 0.85, 0.95)}
    identity = {"coverage": 0.0, "opacity": 0.0}
    extra = {"colour": 0.55}
    default_temporal = "static"

    def _apply(self, x, params, meta):
        T, H, W = x.shape[:3]
        n = 1 if params["temporal"] == "static" else T
        f = smooth_field(self.noise_rng(params), n, H, W)
        q = np.quantile(f, 1.0 - params["coverage"], axis=(1, 2), keepdims=True)
        alpha = np.clip((f - q) / 0.08, 0.0, 1.0) * np.float32(params["opacity"])
        alpha = alpha[..., None].astype(np.float32)
        return x * (1.0 - alpha) + np.float32(params["colour"]) * alpha


@register
class Rain(Degradation):
    """Rain streaks: sparse drops smeared by a line kernel (``length_px``, shared angle), screen-blended."""
    name = "video.rain"
    modality = "rgb"
    table = {"density": (0.002, 0.004, 0.007, 0.01, 0.015), "length_px": (10.0, 14.0, 18.0, 22.0, 26.0)}
    identity = {"density": 0.0, "length_px": 1.0}
    extra = {"brightness": 0.7}
    integer_params = ("length_px",)

    def _sample_extra(self, rng, meta, p):
        p["angle_deg"] = float(rng.uniform(70.0, 110.0))

    def _apply(self, x, params, meta):
        shape = self.field_shape(x.shape, params)[:3]
        u = self.noise_rng(params).random(shape, dtype=np.float32)
        drops = (u < np.float32(params["density"])).astype(np.float32)
        ker = line_kernel(params["length_px"], params["angle_deg"])
        ker = ker / ker.max()
        streak = np.clip(_frames(lambda f: cv2.filter2D(f, -1, ker), drops) * np.float32(params["brightness"]), 0, 1)
        s = streak[..., None]
        return 1.0 - (1.0 - x * np.float32(0.9)) * (1.0 - s)


@register
class JPEG(Degradation):
    """JPEG re-encoding per frame at ``quality`` (ImageNet-C 25/18/15/10/7) with libjpeg-turbo via
    simplejpeg: it takes RGB directly (correct chroma without a colour conversion), 4:2:0 chroma
    subsampling as in common JPEG writers, libjpeg-turbo's fast integer DCT and (decoding) plain
    chroma upsampling: libjpeg's standard speed options, about 1.2x OpenCV's encode + decode."""
    name = "video.jpeg"
    modality = "rgb"
    table = {"quality": (25.0, 18.0, 15.0, 10.0, 7.0)}
    identity = {"quality": 100.0}
    integer_params = ("quality",)
    random = False
    uint8_native = True

    def _apply(self, x, params, meta):
        q = int(params["quality"])
        if not 1 <= q <= 100:
            raise DegradationError(f"{self.name}: quality must be in 1..100, got {q}")
        is_float = x.dtype != np.uint8
        u8 = np.clip(x * 255.0 + 0.5, 0, 255).astype(np.uint8) if is_float else x

        import simplejpeg

        def enc(f):
            buf = simplejpeg.encode_jpeg(np.ascontiguousarray(f), quality=q, colorspace="RGB",
                                         colorsubsampling="420", fastdct=True)
            return simplejpeg.decode_jpeg(buf, colorspace="RGB", fastdct=True, fastupsample=True)
        y = _frames(enc, u8)
        return y.astype(np.float32) / 255.0 if is_float else y


_JPEG_LUMA = np.array([
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
    14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113, 92,
    49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99], np.float32).reshape(8, 8) / 255.0


def _dct_matrix(n: int = 8) -> np.ndarray:
    k = np.arange(n)
    m = np.cos(np.pi * (2 * k[None, :] + 1) * k[:, None] / (2 * n)) * np.sqrt(2.0 / n)
    m[0] /= np.sqrt(2.0)
    return m.astype(np.float32)


_D8 = _dct_matrix()


@register
class BlockCompression(Degradation):
    """MPEG-like block coding: 8x8 DCT quantisation (JPEG luma table x ``qscale``) with a GOP of
    ``gop`` frames; P-frames code the residual to the previous reconstruction and skip blocks whose
    quantised residual is zero (frozen blocks, drift). Deterministic; per channel in YCrCb."""
    name = "video.block_compression"
    modality = "rgb"
    table = {"qscale": (1.0, 2.0, 3.0, 5.0, 8.0)}
    identity = {"qscale": 0.0}
    extra = {"gop": 12, "p_qscale_factor": 1.5}
    random = False

    def _code(self, img: np.ndarray, q: np.ndarray) -> np.ndarray:
        H, W, C = img.shape
        b = img.reshape(H // 8, 8, W // 8, 8, C)
        coef = np.einsum("ij,ajbkc,lk->aiblc", _D8, b, _D8, optimize=True)
        qc = np.round(coef / q[None, :, None, :, None]) * q[None, :, None, :, None]
        return np.einsum("ji,ajblc,lk->aibkc", _D8, qc, _D8, optimize=True).reshape(H, W, C)

    def _apply(self, x, params, meta):
        T, H, W, _ = x.shape
        ph, pw = (-H) % 8, (-W) % 8
        gop = int(params["gop"])
        if gop < 1:
            raise DegradationError(f"{self.name}: gop must be >= 1, got {params['gop']}")
        q = _JPEG_LUMA * np.float32(max(params["qscale"], 1e-3))
        out = np.empty_like(x)
        prev = None
        for t in range(T):
            f = cv2.cvtColor(x[t], cv2.COLOR_RGB2YCrCb)
            if ph or pw:
                f = cv2.copyMakeBorder(f, 0, ph, 0, pw, cv2.BORDER_REPLICATE)
            if prev is None or t % gop == 0:
                rec = self._code(f - 0.5, q) + 0.5
            else:
                rec = prev + self._code(f - prev, q * np.float32(params["p_qscale_factor"]))
            prev = rec
            out[t] = cv2.cvtColor(np.clip(rec[:H, :W], 0, 1).astype(np.float32), cv2.COLOR_YCrCb2RGB)
        return out


@register
class ResolutionDrop(Degradation):
    """Resolution drop: downsample by ``factor`` (area) and upsample back (bilinear); size kept."""
    name = "video.resolution_drop"
    modality = "rgb"
    table = {"factor": (1.5, 2.0, 3.0, 4.0, 6.0)}
    identity = {"factor": 1.0}
    random = False
    uint8_native = True

    def _apply(self, x, params, meta):
        T, H, W = x.shape[:3]
        f = float(params["factor"])
        if f < 1.0:
            raise DegradationError(f"{self.name}: factor must be >= 1, got {f}")
        h, w = max(1, int(round(H / f))), max(1, int(round(W / f)))
        return _frames(lambda im: cv2.resize(cv2.resize(im, (w, h), interpolation=cv2.INTER_AREA), (W, H),
                                             interpolation=cv2.INTER_LINEAR), x)


def _drop_index(T: int, params: dict) -> np.ndarray:
    u = np.random.default_rng(int(params["noise_seed"])).random(T)
    shown = np.arange(T)
    for t in range(1, T):
        if u[t] < params["drop_prob"]:
            shown[t] = shown[t - 1]
    return shown


def _freeze_index(T: int, params: dict) -> np.ndarray:
    n = min(max(1, int(round(params["freeze_fraction"] * T))), T - 1)
    shown = np.arange(T)
    if n <= 0:
        return shown
    start = int(params["onset_frac"] * (T - n))  # frames start+1 .. start+n repeat frame start
    shown[start + 1:start + 1 + n] = start
    return shown


class _Retime(Degradation):
    """Base for transforms that show a different source frame at some output indices."""
    modality = "rgb"
    changes_meta = True
    needs_clip = True
    uint8_native = True
    retimes = True

    def shown_index(self, T: int, params: dict) -> np.ndarray:
        raise DegradationError(f"{self.name}: no frame index rule")

    def frame_index(self, n: int, params: dict) -> np.ndarray:
        return self.shown_index(n, params)

    def _apply(self, x, params, meta):
        return x[self.shown_index(x.shape[0], params)]

    def update_meta(self, params, meta, shape=None):
        if shape is None or len(shape) < 4 or self.is_identity(params):
            return dict(meta or {})
        return reindex_frames(dict(meta or {}), self.shown_index(shape[0], params))


@register
class FrameDrop(_Retime):
    """Each frame is lost with ``drop_prob``; a lost frame repeats the last delivered one (labels too)."""
    name = "video.frame_drop"
    table = {"drop_prob": (0.1, 0.2, 0.3, 0.45, 0.6)}
    identity = {"drop_prob": 0.0}

    def shown_index(self, T, params):
        return _drop_index(T, params)


@register
class FrameFreeze(_Retime):
    """One freeze: from a random onset, ``freeze_fraction`` of the clip repeats the onset frame."""
    name = "video.frame_freeze"
    table = {"freeze_fraction": (0.1, 0.2, 0.3, 0.45, 0.6)}
    identity = {"freeze_fraction": 0.0}

    def _sample_extra(self, rng, meta, p):
        p["onset_frac"] = float(rng.random())

    def shown_index(self, T, params):
        return _freeze_index(T, params)


@register
class SunGlare(Degradation):
    """Sun glare: Gaussian flare of ``intensity`` and ``radius_frac`` plus veiling glare ``veil``,
    screen-blended. Centre from meta['sun_xy'] (pixels) if given, else drawn."""
    name = "video.sun_glare"
    modality = "rgb"
    table = {"intensity": (0.3, 0.45, 0.6, 0.75, 0.9), "radius_frac": (0.15, 0.2, 0.25, 0.3, 0.4),
             "veil": (0.05, 0.1, 0.15, 0.2, 0.3)}
    identity = {"intensity": 0.0, "radius_frac": 0.15, "veil": 0.0}
    default_temporal = "static"

    def _sample_extra(self, rng, meta, p):
        p["cx_frac"], p["cy_frac"] = (float(v) for v in rng.random(2))

    def _apply(self, x, params, meta):
        T, H, W = x.shape[:3]
        if meta.get("sun_xy") is not None:
            cx, cy = (float(v) for v in meta["sun_xy"])
        else:
            cx, cy = params["cx_frac"] * W, params["cy_frac"] * H
        r = params["radius_frac"] * max(H, W)
        yy, xx = np.ogrid[:H, :W]
        d2 = ((xx - cx) ** 2 + (yy - cy) ** 2).astype(np.float32)
        g = np.float32(params["intensity"]) * np.exp(-d2 / np.float32(r * r)) + np.float32(params["veil"])
        g = np.clip(g, 0, 1)[None, :, :, None].astype(np.float32)
        tint = np.array([1.0, 0.97, 0.9], np.float32)
        return 1.0 - (1.0 - x) * (1.0 - g * tint)


@register
class LensDirt(Degradation):
    """Static lens dirt: ``n_spots`` soft spots that darken and locally blur (same on every frame)."""
    name = "video.lens_dirt"
    modality = "rgb"
    table = {"n_spots": (4.0, 8.0, 12.0, 18.0, 25.0), "opacity": (0.3, 0.4, 0.5, 0.6, 0.7)}
    identity = {"n_spots": 0.0, "opacity": 0.0}
    integer_params = ("n_spots",)
    default_temporal = "static"

    def _apply(self, x, params, meta):
        T, H, W = x.shape[:3]
        rng = self.noise_rng(params)
        n_fields = 1 if params["temporal"] == "static" else T
        # fixed number of candidate spots (25) so lower severities are subsets of higher ones
        spots = rng.random((n_fields, 25, 3))
        out = np.empty_like(x)
        m = min(H, W)
        for t in range(T):
            s = spots[0 if n_fields == 1 else t][: int(params["n_spots"])]
            a = np.zeros((H, W), np.float32)
            for cx, cy, rr in s:
                cv2.circle(a, (int(cx * W), int(cy * H)), max(1, int((0.03 + 0.06 * rr) * m)), 1.0, -1)
            a = cv2.GaussianBlur(a, (0, 0), 0.02 * m + 0.5)
            a = (np.clip(a, 0, 1) * np.float32(params["opacity"]))[..., None]
            blurred = cv2.GaussianBlur(x[t], (0, 0), 0.01 * m + 0.5)
            out[t] = x[t] * (1.0 - a) + blurred * a * np.float32(0.4)
        return out


def decoy_track(T: int, H: int, W: int, params: dict, offset: int = 0) -> np.ndarray:
    """Decoy boxes (T, 4) xywh: a straight track from the drawn start with the drawn velocity, for
    the run's frames ``offset`` .. ``offset + T - 1``."""
    s = float(params["size_px"])
    x0, y0 = params["x0_frac"] * (W - s), params["y0_frac"] * (H - s) * 0.7
    vx, vy = params["vx_frac"] * W, params["vy_frac"] * H
    t = int(offset) + np.arange(T)
    xs = np.clip(x0 + vx * t, 0, W - s)
    ys = np.clip(y0 + vy * t, 0, H - s)
    return np.stack([xs, ys, np.full(T, s), np.full(T, s)], axis=1).astype(np.float32)


def bird_mask(T: int, H: int, W: int, boxes: np.ndarray, flap_seed: int, offset: int = 0) -> np.ndarray:
    """Soft bird silhouettes (body + flapping wings) inside each box, float32 (T, H, W) in [0, 1];
    the flap phase is that of the run's frames ``offset`` .. ``offset + T - 1``."""
    out = np.zeros((T, H, W), np.float32)
    phase = np.random.default_rng(flap_seed).uniform(0, 2 * np.pi)
    for t in range(T):
        x, y, w, h = boxes[t]
        cx, cy = int(x + w / 2), int(y + h / 2)
        flap = np.sin(phase + 0.9 * (int(offset) + t))
        cv2.ellipse(out[t], (cx, cy), (max(1, int(w / 5)), max(1, int(h / 6))), 0, 0, 360, 1.0, -1)
        for sgn in (-1, 1):
            tip = (int(cx + sgn * w / 2), int(cy - flap * h / 3))
            cv2.line(out[t], (cx, cy), tip, 1.0, max(1, int(h / 8)))
    return out


def run_offset(meta: dict | None, name: str) -> int:
    """meta['run_offset']: position of an item's first frame inside its run (0 for a whole run)."""
    v = (meta or {}).get("run_offset", 0)
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
        raise DegradationError(f"{name}: meta['run_offset'] must be a non-negative int, got {v!r}")
    return int(v)


class _Decoy(Degradation):
    """Base: a bird-like decoy crossing the frame; its boxes go to meta['decoy_boxes']. The track
    and flap phase of frame k of a run are those at ``meta['run_offset'] + k``."""
    changes_meta = True
    frame_separable = True
    reports_change = True
    table = {"size_px": (4.0, 6.0, 8.0, 11.0, 14.0)}
    identity = {"size_px": 0.0}

    def track(self, T: int, H: int, W: int, params: dict, meta: dict | None) -> np.ndarray:
        """Decoy boxes of this item's T frames."""
        return decoy_track(T, H, W, params, run_offset(meta, self.name))

    def mask(self, T: int, H: int, W: int, params: dict, meta: dict | None) -> np.ndarray:
        """Bird silhouettes of this item's T frames, float32 (T, H, W)."""
        off = run_offset(meta, self.name)
        return bird_mask(T, H, W, decoy_track(T, H, W, params, off), params["noise_seed"], off)

    def _sample_extra(self, rng, meta, p):
        v = rng.random(4)
        p["x0_frac"], p["y0_frac"] = float(v[0]), float(v[1])
        p["vx_frac"], p["vy_frac"] = float((v[2] - 0.5) * 0.02), float((v[3] - 0.5) * 0.006)

    def update_meta(self, params, meta, shape=None):
        out = dict(meta or {})
        if shape is None or self.is_identity(params):
            return out
        T, H, W = (1,) + tuple(shape[:2]) if len(shape) == self.item_ndims()[0] else tuple(shape[:3])
        out["decoy_boxes"] = self.track(T, H, W, params, meta).tolist()
        return out


@register
class VideoDecoy(_Decoy):
    """Decoy bird in RGB: a dark flapping silhouette (for the ``decoy`` conflict program)."""
    name = "video.decoy_bird"
    modality = "rgb"

    def _apply(self, x, params, meta):
        T, H, W = x.shape[:3]
        m = self.mask(T, H, W, params, meta)[..., None]
        return x * (1.0 - 0.8 * m) + np.float32(0.08) * m
