"""The camera model between the renderer and the files: what a real RGB camera and an uncooled LWIR
microbolometer record of the rendered radiance (on by default; ``camera_rig.sensor: ideal`` skips it).

Per frame and camera, in this order (all linear stages commute; noise comes last):
1. motion blur of each target over the integration window (RGB: box over the exposure time;
   thermal: the bolometer's exponential response exp(-s/tau) over one frame period), applied in a
   window around the target's projection, from its image motion between frames;
2. optics: diffraction (Airy, circular pupil) x defocus (uniform blur circle) x pixel aperture,
   as one transfer function, applied by FFT (``psf_kernel`` gives the discrete kernel);
3. thermal: first-order bolometer lag y_n = a x_n + (1 - a) y_(n-1), a = 1 - exp(-dt/tau)
   (the in-frame part is step 1); brightness temperature; per-column fixed-pattern gain/offset
   about the NUC reference (air temperature); temporal NETD noise; 14/16-bit radiometric counts;
   8-bit AGC view (``agc: plateau`` = the FLIR cores' plateau equalisation over the whole frame,
   damped over frames: simulator/sensors/agc.py);
4. RGB: photo-electrons from the physical radiance (auto exposure capped at one frame period, then
   gain up to max_gain), shot (Poisson) and read noise, ADC quantisation, sRGB 8-bit
   (``tone: camcorder`` = whole-frame metered auto-exposure + BT.709 curve with a highlight knee, and an
   optional colour level ``colour_gain`` on the output's chroma).
Noise is seeded per (scenario seed, camera, frame) through ``rng_for``; fixed-pattern noise per
(seed, camera). Labels are computed from the renderer's exact buffers, never from these frames.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from scenes.schema import RgbCamera, ThermalCamera
from simulator.physics import thermal as radiometry
from simulator.physics.timeline import Timeline
from simulator.seeding import rng_for
from simulator.sensors.agc import CamcorderExposure, PlateauAgc
from simulator.sensors.encode import agc_8bit, kelvin_to_counts, rgb_to_srgb8

PLANCK_H = 6.62607015e-34
LIGHT_C = 2.99792458e8
RGB_WAVELENGTHS_UM = (0.61, 0.55, 0.465)   # effective centres of the R, G, B channels
RGB_CHANNEL_WIDTH_NM = 100.0               # Mitsuba radiance is per nm; each channel integrates ~100 nm
OPTICS_TRANSMISSION = 0.9
AUTO_EXPOSURE_KEY = 0.45                   # the renderer maps the sky in view to this fraction of white
CAMERA_INDEX = {"rgb": 0, "thermal": 1}
FPN_STREAM = 1
NOISE_STREAM = 2
AGC_PERCENTILE = 0.5
POISSON_EXACT_BELOW_E = 1000.0


# --- optics ---------------------------------------------------------------------------------------
def optics_transfer(fx_per_um: np.ndarray, fy_per_um: np.ndarray, f_number: float, wavelength_um: float,
                    defocus_blur_um: float) -> np.ndarray:
    """Continuous transfer function of diffraction-limited optics with a circular pupil and a
    uniform defocus blur circle (diameter defocus_blur_um), at spatial frequencies in cycles/um."""
    from scipy.special import j1

    rho = np.hypot(fx_per_um, fy_per_um)
    s = np.clip(rho * wavelength_um * f_number, 0.0, 1.0)
    diffraction = (2 / np.pi) * (np.arccos(s) - s * np.sqrt(1 - s ** 2))
    if defocus_blur_um <= 0:
        return diffraction
    x = np.pi * defocus_blur_um * rho
    defocus = np.where(x > 1e-9, 2 * j1(x) / np.where(x > 1e-9, x, 1.0), 1.0)
    return diffraction * defocus


@lru_cache(maxsize=16)
def psf_kernel(pixel_pitch_um: float, f_number: float, wavelength_um: float, defocus_blur_um: float,
               blur_sigma_um: float = 0.0) -> np.ndarray:
    """Discrete PSF: K[i, j] = energy of a point imaged at the centre of pixel (0, 0) that lands in
    pixel (i, j) (optics PSF integrated over the pixel aperture). Odd square, sums to 1.
    ``blur_sigma_um``: an extra Gaussian (rms per axis) for what is not diffraction or defocus: lens
    aberrations, an optical low-pass filter, detector crosstalk, the video path's resampling."""
    radius_px = int(max(2, np.ceil(20 * wavelength_um * f_number / pixel_pitch_um),
                        np.ceil(defocus_blur_um / pixel_pitch_um) + 2,
                        np.ceil(4 * blur_sigma_um / pixel_pitch_um) + 1))
    size_px = 2 * radius_px + 1
    cutoff = 1.0 / (wavelength_um * f_number)                        # cycles/um
    sub = int(max(8, np.ceil(4 * pixel_pitch_um * cutoff)))          # fine samples per pixel (> Nyquist)
    sub = min(sub, max(8, 2048 // size_px))                           # bound the one-off FFT size
    n = size_px * sub
    f = np.fft.fftfreq(n, d=pixel_pitch_um / sub)
    fx, fy = np.meshgrid(f, f)
    h = optics_transfer(fx, fy, f_number, wavelength_um, defocus_blur_um)
    if blur_sigma_um > 0:                                             # Gaussian MTF exp(-2 pi^2 s^2 f^2)
        h = h * np.exp(-2.0 * np.pi ** 2 * blur_sigma_um ** 2 * (fx ** 2 + fy ** 2))
    h = h * np.sinc(fx * pixel_pitch_um) * np.sinc(fy * pixel_pitch_um)   # pixel aperture (box)
    fine = np.real(np.fft.ifft2(h))                                   # (PSF * box)(x) on the fine grid, periodic
    fine = np.fft.fftshift(fine) * sub * sub                          # density per pixel area
    centre = n // 2
    idx = centre + (np.arange(size_px) - radius_px) * sub
    kernel = fine[np.ix_(idx, idx)]
    return kernel / kernel.sum()


class KernelFilter:
    """Convolution of (H, W) images with a centred odd kernel, edges mirrored (numpy ``reflect``,
    scipy.ndimage ``mirror``, OpenCV ``BORDER_REFLECT_101``), in float32: small kernels (the RGB
    PSFs) by direct summation (OpenCV filter2D), large ones (the 35x35 LWIR PSF) by FFT (scipy.fft,
    single-threaded; the kernel's spectrum is computed once per image shape), whichever measured
    faster. Equal to ``scipy.ndimage.convolve(mode='mirror')`` to float32 rounding (tested)."""

    DIRECT_MAX_TAPS = 129                              # OpenCV itself switches to a DFT at 130 taps

    def __init__(self, kernel: np.ndarray):
        self.kernel = kernel
        self.radius = kernel.shape[0] // 2
        self._taps = np.ascontiguousarray(kernel[::-1, ::-1], dtype=np.float32)   # filter2D correlates
        self._spectra: dict[tuple[int, int], np.ndarray] = {}

    def __call__(self, image: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The filtered image (float32), written into ``out`` (contiguous float32, image's shape) if given."""
        import cv2

        image = np.ascontiguousarray(image, dtype=np.float32)
        if self.kernel.size <= self.DIRECT_MAX_TAPS:
            return cv2.filter2D(image, -1, self._taps, dst=out,
                                borderType=cv2.BORDER_REFLECT_101 | cv2.BORDER_ISOLATED)
        filtered = self._by_fft(image)
        if out is None:
            return filtered
        np.copyto(out, filtered)
        return out

    def _by_fft(self, image: np.ndarray) -> np.ndarray:
        """Linear convolution by a real FFT of the mirrored-padded image (no wrap-around)."""
        import cv2
        from scipy import fft

        r = self.radius
        h, w = image.shape
        shape = (fft.next_fast_len(h + 2 * r, real=True), fft.next_fast_len(w + 2 * r, real=True))
        padded = cv2.copyMakeBorder(image, r, shape[0] - h - r, r, shape[1] - w - r, cv2.BORDER_REFLECT_101)
        if shape not in self._spectra:
            self._spectra[shape] = fft.rfft2(self.kernel.astype(np.float32), s=shape)
        spectrum = fft.rfft2(padded)
        spectrum *= self._spectra[shape]
        return fft.irfft2(spectrum, s=shape)[2 * r:2 * r + h, 2 * r:2 * r + w]


class Scratch:
    """Work arrays reused from frame to frame (one sensor, one thread): on this class of VM every
    fresh multi-MB temporary costs a page fault per 4 KiB page (~1 ms per 640x512x3 float32
    array), more than the arithmetic on it. Never hand one of these arrays out."""

    def __init__(self) -> None:
        self._arrays: dict[str, np.ndarray] = {}

    def __call__(self, name: str, shape: tuple[int, ...], dtype=np.float32) -> np.ndarray:
        a = self._arrays.get(name)
        if a is None or a.shape != tuple(shape) or a.dtype != dtype:
            a = self._arrays[name] = np.empty(shape, dtype)
        return a


# --- motion ---------------------------------------------------------------------------------------
def trail_weights(length_samples: int, kind: str, time_constant_s: float,
                  window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample times (fraction of the window back in time, 0..1) and normalised weights of the
    integration window: 'box' (shutter) or 'exponential' (bolometer, exp(-s/tau) over window_s)."""
    frac = (np.arange(length_samples) + 0.5) / length_samples
    if kind == "box" or time_constant_s <= 0:
        w = np.ones(length_samples)
    else:
        w = np.exp(-frac * window_s / time_constant_s)
    return frac, w / w.sum()


def trail_kernel(displacement_px: np.ndarray, frac: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The motion trail as one correlation kernel K (odd in both axes, centred, float32):
    sum_s weights[s] x the bilinear-interpolation stencil of the offset displacement_px x frac[s]
    (x, y), so that correlating with K (out[p] = sum_o K[o] in[p + o]) equals summing the weighted
    bilinear shifts of ``blur_along``'s definition. Its weights sum to sum(weights)."""
    offsets = displacement_px[None, :] * frac[:, None]                 # (S, 2) as (x, y), px
    whole = np.floor(offsets)
    t = offsets - whole                                                # bilinear fractions
    rx, ry = (int(np.max(np.abs(whole[:, i]))) + 1 for i in (0, 1))
    kernel = np.zeros((2 * ry + 1, 2 * rx + 1))
    ix, iy = whole[:, 0].astype(int) + rx, whole[:, 1].astype(int) + ry
    for dy, wy in ((0, 1 - t[:, 1]), (1, t[:, 1])):
        for dx, wx in ((0, 1 - t[:, 0]), (1, t[:, 0])):
            np.add.at(kernel, (iy + dy, ix + dx), weights * wy * wx)
    return kernel.astype(np.float32)


def blur_along(window: np.ndarray, displacement_px: np.ndarray, frac: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Sum of the window shifted back along its motion (displacement over the integration window):
    sum_s weights[s] x (window bilinearly shifted by -displacement_px x frac[s], edges replicated),
    i.e. scipy.ndimage.shift(order=1, mode='nearest') per sample. Computed in float32 as one
    correlation with ``trail_kernel`` (OpenCV filter2D, the window's own edges replicated), equal to
    the per-sample shifts to float32 rounding (tested). (H, W) or (H, W, C) windows."""
    import cv2

    kernel = trail_kernel(np.asarray(displacement_px, dtype=np.float64), frac, weights)
    return cv2.filter2D(np.ascontiguousarray(window, dtype=np.float32), -1, kernel,
                        borderType=cv2.BORDER_REPLICATE | cv2.BORDER_ISOLATED)


@dataclass
class _Motion:
    """Image-plane position (px) and displacement per frame period of every target, per camera."""

    centre_px: np.ndarray      # (T, F, 2)
    step_px: np.ndarray        # (T, F, 2): position(frame) - position(frame - 1)
    half_size_px: np.ndarray   # (T, F)
    in_front: np.ndarray       # (T, F) bool


def _motion(timeline: Timeline, which: str) -> _Motion:
    cam = timeline.cameras[which]
    n = timeline.n_frames
    centres, steps, sizes, front = [], [], [], []
    for track in timeline.targets:
        c = np.zeros((n, 2))
        d = np.zeros(n)
        for i in range(n):
            xy, depth = cam.project(i, track.position_m[i])
            c[i], d[i] = xy[0], depth[0]
        step = np.zeros_like(c)
        if n > 1:
            step[1:] = c[1:] - c[:-1]
            step[0] = step[1]
        centres.append(c)
        steps.append(step)
        sizes.append(0.6 * track.size_m * cam.focal_px / np.maximum(d, 1e-6))
        front.append(d > 0.5)
    return _Motion(np.array(centres).reshape(-1, n, 2), np.array(steps).reshape(-1, n, 2),
                   np.array(sizes).reshape(-1, n), np.array(front).reshape(-1, n))


def motion_blur(image: np.ndarray, motion: _Motion, frame: int, fraction_of_frame: float, kind: str,
                time_constant_s: float, frame_period_s: float, margin_px: int, in_place: bool = False) -> np.ndarray:
    """Blur each target's neighbourhood along its image motion over the integration window (into
    ``image`` itself with in_place, else into a copy made only if some target moves)."""
    out = image
    h, w = image.shape[:2]
    for t in range(motion.centre_px.shape[0]):
        if not motion.in_front[t, frame]:
            continue
        disp = motion.step_px[t, frame] * fraction_of_frame
        length = float(np.hypot(*disp))
        if length < 0.25:
            continue
        cx, cy = motion.centre_px[t, frame]
        reach = motion.half_size_px[t, frame] + length + margin_px
        x0, x1 = int(max(0, np.floor(cx - reach))), int(min(w, np.ceil(cx + reach)))
        y0, y1 = int(max(0, np.floor(cy - reach))), int(min(h, np.ceil(cy + reach)))
        if x1 - x0 < 2 or y1 - y0 < 2:
            continue
        frac, weights = trail_weights(int(np.ceil(2 * length)) + 2, kind, time_constant_s,
                                      fraction_of_frame * frame_period_s)
        if out is image and not in_place:
            out = image.copy()
        out[y0:y1, x0:x1] = blur_along(out[y0:y1, x0:x1], disp, frac, weights)
    return out


# --- AGC ------------------------------------------------------------------------------------------
def agc(kelvin: np.ndarray, mode: str) -> np.ndarray:
    """8-bit display view: linear min/max, linear between the 0.5/99.5 percentiles, or histogram
    equalisation (the usual camera choices)."""
    if mode == "minmax":
        return agc_8bit(kelvin)[0]
    if mode == "percentile":
        lo, hi = np.percentile(kelvin, [AGC_PERCENTILE, 100 - AGC_PERCENTILE])
        mid, span = 0.5 * (lo + hi), max(hi - lo, 0.5)
        return np.clip(np.rint((kelvin - (mid - span / 2)) / span * 255.0), 0, 255).astype(np.uint8)
    _, inverse, counts = np.unique(kelvin.ravel(), return_inverse=True, return_counts=True)
    below = np.cumsum(counts) - counts                       # pixels colder than each level
    scale = 255.0 / max(int(below[-1]), 1)
    return np.rint(below[inverse] * scale).astype(np.uint8).reshape(kelvin.shape)


def equalise_counts(counts: np.ndarray) -> np.ndarray:
    """``agc(counts x kelvin_per_count, 'histogram')`` from the integer counts: a histogram of the
    levels instead of np.unique's sort. Identical, because counts -> kelvin is strictly increasing
    in float32 (counts < 2^16 differ by more than float32's 2^-24 relative spacing)."""
    flat = counts.ravel()
    per_level = np.bincount(flat)
    below = np.cumsum(per_level) - per_level                 # pixels colder than each level
    scale = 255.0 / max(int(below[-1]), 1)                   # the hottest level present is the last bin
    return np.rint(below * scale).astype(np.uint8)[flat].reshape(counts.shape)


def agc_counts(counts: np.ndarray, kelvin_per_count: float, mode: str) -> np.ndarray:
    """``agc(counts x kelvin_per_count, mode)`` computed once per occupied count level and looked up
    per pixel (the percentiles from the levels' histogram instead of a sort). Equal to it (tested)."""
    if mode == "histogram":
        return equalise_counts(counts)
    lo_count, hi_count = int(counts.min()), int(counts.max())
    levels = np.arange(lo_count, hi_count + 1, dtype=np.uint16)
    shown = np.multiply(levels, np.float32(kelvin_per_count), dtype=np.float32)   # the pixels' kelvin values
    if mode == "minmax":
        lut = agc_8bit(shown)[0]
    else:
        per_level = np.bincount((counts.ravel() - np.uint16(lo_count)), minlength=levels.size)
        lo, hi = map(np.float64, _percentiles_of_levels(shown, per_level, (AGC_PERCENTILE, 100 - AGC_PERCENTILE)))
        mid, span = 0.5 * (lo + hi), max(hi - lo, 0.5)                # float64, as np.percentile's are
        lut = np.clip(np.rint((shown - (mid - span / 2)) / span * 255.0), 0, 255).astype(np.uint8)
    return lut[counts - np.uint16(lo_count)]


def _percentiles_of_levels(values: np.ndarray, per_level: np.ndarray, q: tuple[float, ...]) -> list[float]:
    """np.percentile (method 'linear') of the pixels, from the sorted distinct values and their counts."""
    cum = np.cumsum(per_level)
    n = int(cum[-1])
    out = []
    for qi in q:
        rank = qi / 100.0 * (n - 1)
        below = int(np.floor(rank))
        a = float(values[np.searchsorted(cum, below, side="right")])
        b = float(values[np.searchsorted(cum, min(below + 1, n - 1), side="right")])
        t = rank - below                                             # numpy's _lerp, in float64
        out.append(b - (b - a) * (1 - t) if t >= 0.5 else a + (b - a) * t)
    return out


def standard_normal_f32(rng: np.random.Generator, out: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Fill ``out`` (contiguous float32) with normal values of mean 0 and standard deviation ``scale``
    (applied to the Box-Muller radius, so it costs no pass of its own) from ``rng``'s bit stream.

    Box-Muller in float32 on 24-bit uniforms: ceil(n/2) 64-bit raw draws of the generator, read as
    2 ceil(n/2) 32-bit words; u = (top 24 bits + 0.5) / 2^24 in (0, 1), u1 from the first half of
    the words, u2 from the second; z = sqrt(-2 ln u1) x (cos | sin)(2 pi u2): the first half of
    ``out`` takes the cosines, the second the sines of the same pairs. About 3x faster here than
    ``Generator.standard_normal(dtype=float32)`` (ziggurat), whose draws were the largest stage of the
    camera model. Byte-identical for the same generator state on the same platform (numpy's float32
    log/sin/cos are vectorised per CPU feature set). Tails end at sqrt(2 ln 2^25) = 5.9 sigma (the
    normal distribution has 4e-9 of its mass beyond)."""
    if not (out.dtype == np.float32 and out.flags.c_contiguous):
        raise ValueError("standard_normal_f32: out must be a contiguous float32 array")
    flat = out.reshape(-1)
    n = flat.size
    half = (n + 1) // 2
    bits = rng.bit_generator.random_raw(half).view(np.uint32)        # 2 x 32 bits per pair
    np.right_shift(bits, np.uint32(8), out=bits)
    u = bits.astype(np.float32)                                      # exact: < 2^24
    u += np.float32(0.5)
    u *= np.float32(2.0 ** -24)
    u1, u2 = u[:half], u[half:]
    radius = np.log(u1)
    radius *= np.float32(-2.0 * scale * scale)
    np.sqrt(radius, out=radius)
    u2 *= np.float32(2.0 * np.pi)
    first, second = flat[:half], flat[half:]
    np.cos(u2, out=first)
    first *= radius
    np.sin(u2[:n - half], out=second)
    second *= radius[:n - half]
    return out


def shot_noise(electrons: np.ndarray, rng: np.random.Generator, read_noise_e: float = 0.0,
               out: np.ndarray | None = None, work: np.ndarray | None = None) -> np.ndarray:
    """Photo-electron counts with shot (Poisson) and read (Gaussian, rms read_noise_e) noise.

    One standard normal value z per pixel (``standard_normal_f32``). Pixels at or above
    POISSON_EXACT_BELOW_E electrons: n + z sqrt(n + read^2), the normal approximation of the Poisson
    term (skewness 1/sqrt(n) < 3 %) plus the independent Gaussian read noise. Pixels below it (dark
    ones, usually few): an exact Poisson draw (after all the normal values, in raster order) plus
    read_noise_e x z. ``out`` and ``work`` (float32, electrons' shape) are optional buffers.
    """
    lam = np.asarray(electrons, dtype=np.float32)
    if out is None:
        out = np.empty(lam.shape, np.float32)
    z = standard_normal_f32(rng, out)
    dark = lam < np.float32(POISSON_EXACT_BELOW_E) if float(lam.min()) < POISSON_EXACT_BELOW_E else None
    dark_z = z[dark] if dark is not None else None
    sigma = np.add(lam, np.float32(read_noise_e ** 2), out=work)
    z *= np.sqrt(sigma, out=sigma)
    z += lam
    if dark_z is not None:
        dark_lam = np.maximum(lam[dark], np.float32(0.0)).astype(np.float64)
        z[dark] = rng.poisson(dark_lam).astype(np.float32) + np.float32(read_noise_e) * dark_z
    return z


# --- the cameras ----------------------------------------------------------------------------------
@dataclass
class RecordedFrame:
    """What the cameras write for one frame."""

    rgb8: np.ndarray            # (H, W, 3) uint8 sRGB
    thermal_counts: np.ndarray  # (H, W) uint16 radiometric counts, T = counts * kelvin_per_count
    thermal_agc8: np.ndarray    # (H, W) uint8
    thermal_kelvin: np.ndarray  # (H, W) float32 recorded temperature (before quantisation)


@dataclass
class ThermalSensor:
    """One uncooled LWIR camera over a sequence (keeps the bolometer state between frames)."""

    params: ThermalCamera
    timeline: Timeline
    frame_period_s: float
    nuc_reference_k: float
    _state: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        p = self.params
        self.kernel = psf_kernel(p.pixel_pitch_um, p.f_number, p.wavelength_um, p.defocus_blur_um,
                                 p.blur_sigma_px * p.pixel_pitch_um)
        self.optics = KernelFilter(self.kernel)
        self.lag_alpha = 1.0 - float(np.exp(-self.frame_period_s / p.time_constant_s)) if p.time_constant_s > 0 else 1.0
        self.motion = _motion(self.timeline, "thermal")
        rng = rng_for(self.timeline.seed, "camera", CAMERA_INDEX["thermal"], FPN_STREAM)
        self.column_gain = (p.fpn_column_gain * rng.standard_normal(p.width_px)).astype(np.float64)
        self.column_offset_k = (p.fpn_column_offset_k * rng.standard_normal(p.width_px)).astype(np.float64)
        gain = self.column_gain[None, :]               # a row, or a full map with the per-pixel residual
        if p.fpn_pixel_gain:                           # drawn after the column terms: those stay as they were
            gain = gain + p.fpn_pixel_gain * rng.standard_normal((p.height_px, p.width_px))
        self._fpn_gain = (1.0 + gain).astype(np.float32)
        self._fpn_add = (self.nuc_reference_k * -gain + self.column_offset_k[None, :]).astype(np.float32)
        self._scratch = Scratch()
        self._plateau = PlateauAgc(p.kelvin_per_count, p.agc_bin_k, p.agc_plateau_fraction, p.agc_linear_fraction,
                                   p.agc_tail_fraction, p.agc_min_span_k, p.agc_damping, p.agc_base_sigma_px,
                                   p.agc_base_gain, p.agc_gamma, p.agc_mean_level,
                                   p.agc_base_opening_px or 0) if p.agc == "plateau" else None

    def detector_radiance(self, frame: int, radiance: np.ndarray) -> np.ndarray:
        """Optics + in-frame motion + bolometer lag, in W sr^-1 m^-2 (no noise)."""
        x = self.optics(radiance)
        if self.params.time_constant_s > 0:
            motion_blur(x, self.motion, frame, 1.0, "exponential", self.params.time_constant_s,
                        self.frame_period_s, self.kernel.shape[0] // 2, in_place=True)
        if self._state is not None:  # a x + (1 - a) state, into x (ours; the old state stays as returned)
            x *= np.float32(self.lag_alpha)
            x += np.multiply(self._state, np.float32(1.0 - self.lag_alpha), out=self._scratch("lag", x.shape))
        self._state = x
        return self._state

    def record(self, frame: int, radiance: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Radiance -> (recorded kelvin float32, counts uint16, AGC uint8)."""
        p = self.params
        kelvin = radiometry.brightness_temperature_f32(self.detector_radiance(frame, radiance))
        kelvin *= self._fpn_gain                      # (T - ref) gain + ref + offset
        kelvin += self._fpn_add
        rng = rng_for(self.timeline.seed, "camera", CAMERA_INDEX["thermal"], NOISE_STREAM, frame)
        kelvin += standard_normal_f32(rng, self._scratch("noise", kelvin.shape), scale=p.netd_k)
        level = np.divide(kelvin, p.kelvin_per_count, out=self._scratch("level", kelvin.shape))
        np.rint(level, out=level)
        counts = np.clip(level, 0, 2 ** p.adc_bits - 1, out=level).astype(np.uint16)
        if self._plateau is not None:                 # stateful: the transfer is damped over frames
            return kelvin, counts, self._plateau(counts)
        return kelvin, counts, agc_counts(counts, p.kelvin_per_count, p.agc)   # = agc(counts x kelvin_per_count)

    def metadata(self) -> dict:
        p = self.params
        return {"model": "uncooled microbolometer", **p.model_dump(mode="json"),
                "psf_centre_pixel_fraction": round(float(self.kernel[self.kernel.shape[0] // 2, self.kernel.shape[1]
                                                                     // 2]), 6),
                "psf_kernel_px": int(self.kernel.shape[0]), "lag_alpha_per_frame": round(self.lag_alpha, 6),
                "nuc_reference_k": self.nuc_reference_k,
                "focal_length_mm": round(self.timeline.cameras["thermal"].focal_px * p.pixel_pitch_um / 1000, 6)}


@dataclass
class RgbSensor:
    """One visible CMOS camera over a sequence."""

    params: RgbCamera
    timeline: Timeline
    frame_period_s: float
    render_exposure: float   # the renderer's scale: rgb_linear = radiance * render_exposure

    def __post_init__(self) -> None:
        p = self.params
        self.pixel_pitch_um = p.sensor_width_mm * 1000.0 / p.width_px
        self.kernels = [psf_kernel(self.pixel_pitch_um, p.f_number, wl, p.defocus_blur_um,
                                   p.blur_sigma_px * self.pixel_pitch_um) for wl in RGB_WAVELENGTHS_UM]
        self.optics = [KernelFilter(k) for k in self.kernels]
        self.bin_area = (self.pixel_pitch_um / p.native_pixel_pitch_um) ** 2
        self.full_well_e = p.full_well_e * self.bin_area
        self.read_noise_e = p.read_noise_e * np.sqrt(self.bin_area)
        rate_key = self.electrons_per_s_per_native_pixel(AUTO_EXPOSURE_KEY / max(self.render_exposure, 1e-30))
        needed_s = AUTO_EXPOSURE_KEY * p.full_well_e / max(rate_key, 1e-30)   # key -> 45 % of full well
        if p.exposure_time_s is None:
            self.exposure_time_s = min(needed_s, self.frame_period_s)
            self.gain = float(min(needed_s / self.exposure_time_s, p.max_gain))
        else:
            self.exposure_time_s, self.gain = float(p.exposure_time_s), 1.0
        # photo-electrons in one output pixel per unit of the renderer's exposed linear value
        self.electrons_per_unit = (self.electrons_per_s_per_native_pixel(1.0 / max(self.render_exposure, 1e-30))
                                   * self.exposure_time_s * self.bin_area)
        self.needed_exposure_s = float(needed_s)
        self.motion = _motion(self.timeline, "rgb")
        self._scratch = Scratch()
        levels = 2 ** p.adc_bits - 1
        self._camcorder = CamcorderExposure(self.gain / levels, levels, p.ae_key, p.ae_damping, p.knee_point,
                                            p.knee_slope, colour_gain=p.colour_gain) if p.tone == "camcorder" else None

    def electrons_per_s_per_native_pixel(self, radiance_per_nm: float) -> float:
        """Photo-electron rate of a native pixel looking at a scene of this spectral radiance
        (W m^-2 sr^-1 nm^-1, Mitsuba's unit) through the lens: E = L pi / (4 N^2) at the focal plane."""
        p = self.params
        band = radiance_per_nm * RGB_CHANNEL_WIDTH_NM
        irradiance = band * np.pi / (4 * p.f_number ** 2) * OPTICS_TRANSMISSION
        power = irradiance * (p.native_pixel_pitch_um * 1e-6) ** 2
        photon_j = PLANCK_H * LIGHT_C / (RGB_WAVELENGTHS_UM[1] * 1e-6)
        return float(power / photon_j * p.quantum_efficiency)

    def focal_plane(self, frame: int, rgb_linear: np.ndarray) -> np.ndarray:
        """Optics (per channel) then motion blur: the exposed linear image on the sensor, (H, W, 3)
        float32 in a work array (valid until the next call)."""
        import cv2

        h, w, n = rgb_linear.shape
        planes = self._scratch("planes", (n, h, w))                    # channel planes: filter2D input
        np.copyto(planes, np.moveaxis(rgb_linear, -1, 0), casting="unsafe")
        blurred = self._scratch("optics", (n, h, w))
        for c in range(n):
            self.optics[c](planes[c], out=blurred[c])
        x = cv2.merge(list(blurred), dst=self._scratch("focal", (h, w, n)))   # interleave again
        return motion_blur(x, self.motion, frame, self.exposure_time_s / self.frame_period_s, "box", 0.0,
                           self.frame_period_s, self.kernels[0].shape[0] // 2, in_place=True)

    def record(self, frame: int, rgb_linear: np.ndarray) -> np.ndarray:
        """Exposed linear RGB (the renderer's units) -> recorded sRGB 8-bit (H, W, 3)."""
        p = self.params
        electrons = self.focal_plane(frame, rgb_linear)
        np.maximum(electrons, np.float32(0.0), out=electrons)
        electrons *= np.float32(self.electrons_per_unit)
        rng = rng_for(self.timeline.seed, "camera", CAMERA_INDEX["rgb"], NOISE_STREAM, frame)
        h, w, n = electrons.shape
        work = self._scratch("planes", (n, h, w)).reshape(h, w, n)     # the planes are consumed by now
        noisy = shot_noise(electrons, rng, self.read_noise_e, out=self._scratch("noise", electrons.shape), work=work)
        levels = 2 ** p.adc_bits - 1
        noisy *= np.float32(levels / self.full_well_e)
        np.clip(noisy, 0.0, levels, out=noisy)
        noisy += np.float32(0.5)
        level = self._scratch("level", noisy.shape, np.uint16)        # ADC level, rounded (adc_bits <= 16)
        np.copyto(level, noisy, casting="unsafe")
        if self._camcorder is not None:               # whole-frame auto-exposure + BT.709 knee curve
            return self._camcorder(level)
        return self.srgb_lut.take(level.ravel()).reshape(level.shape)   # -> sRGB 8-bit

    @property
    def srgb_lut(self) -> np.ndarray:
        """sRGB 8-bit value of every ADC level (value = DN / levels x gain, 1.0 = white)."""
        if getattr(self, "_lut", None) is None:
            levels = 2 ** self.params.adc_bits - 1
            self._lut = rgb_to_srgb8((np.arange(levels + 1) * (self.gain / levels)).astype(np.float32))
        return self._lut

    def metadata(self) -> dict:
        p = self.params
        return {"model": "CMOS, output pixel = mean of native pixels", **p.model_dump(mode="json"),
                "output_pixel_pitch_um": round(self.pixel_pitch_um, 6),
                "focal_length_mm": round(self.timeline.cameras["rgb"].focal_px * self.pixel_pitch_um / 1000, 6),
                "exposure_time_s_used": round(self.exposure_time_s, 9), "gain": round(self.gain, 6),
                "auto_exposure_needed_s": round(self.needed_exposure_s, 9),
                "full_well_e_output_pixel": round(self.full_well_e, 3),
                "read_noise_e_output_pixel": round(self.read_noise_e, 4),
                "electrons_at_white": round(self.electrons_per_unit, 3),
                "psf_centre_pixel_fraction": [round(float(k[k.shape[0] // 2, k.shape[1] // 2]), 6)
                                              for k in self.kernels]}


class CameraModel:
    """Both cameras of a rig over one sequence: ``record(frame, buffers)`` -> RecordedFrame.

    With ``camera_rig.sensor == 'ideal'`` it reproduces the plain encodings of the rendered buffers."""

    def __init__(self, timeline: Timeline, render_exposure: float):
        scenario = timeline.scenario
        rig = scenario.camera_rig
        self.ideal = rig.sensor == "ideal"
        self.rig = rig
        period = 1.0 / scenario.frame_rate_hz
        if not self.ideal:
            self.rgb = RgbSensor(rig.rgb, timeline, period, render_exposure)
            self.thermal = ThermalSensor(rig.thermal, timeline, period, scenario.atmosphere.air_temperature_k)
        self.recording = None
        if rig.recording is not None:                 # opened now: a refused rate fails before any frame
            from simulator.sensors.recording import RecordingChain

            self.recording = RecordingChain(rig.recording, (rig.rgb.width_px, rig.rgb.height_px),
                                            (rig.thermal.width_px, rig.thermal.height_px), scenario.frame_rate_hz)

    def record(self, frame: int, rgb_linear: np.ndarray, thermal_radiance: np.ndarray,
               thermal_kelvin: np.ndarray | None = None) -> RecordedFrame:
        """The recorded frames of one rendered frame (radiance in, file-ready arrays out); frames in order.
        ``thermal_kelvin`` (the radiance's brightness temperature) is read by the ideal sensor only."""
        kpc = self.rig.thermal.kelvin_per_count
        if self.ideal:
            if thermal_kelvin is None:
                thermal_kelvin = radiometry.brightness_temperature(thermal_radiance).astype(np.float32)
            counts = kelvin_to_counts(thermal_kelvin, kpc)
            out = RecordedFrame(rgb_to_srgb8(rgb_linear), counts, agc_8bit(thermal_kelvin)[0], thermal_kelvin)
        else:
            kelvin, counts, shown = self.thermal.record(frame, thermal_radiance)
            out = RecordedFrame(self.rgb.record(frame, rgb_linear), counts, shown, kelvin)
        if self.recording is not None:                # the recorder: H.264 on the 8-bit views
            out.rgb8 = self.recording.rgb(out.rgb8)
            out.thermal_agc8 = self.recording.thermal(out.thermal_agc8)
        return out

    def record_buffers(self, frame: int, buffers) -> RecordedFrame:
        """``record`` for any object with rgb_linear, thermal_radiance and thermal_kelvin (FrameBuffers);
        thermal_kelvin is only read (FrameBuffers: computed) for the ideal sensor."""
        return self.record(frame, buffers.rgb_linear, buffers.thermal_radiance,
                           buffers.thermal_kelvin if self.ideal else None)

    def metadata(self) -> dict:
        meta: dict[str, Any] = {"sensor": "ideal"} if self.ideal else \
            {"sensor": "camera", "rgb": self.rgb.metadata(), "thermal": self.thermal.metadata()}
        if self.recording is not None:
            meta["recording"] = self.recording.metadata()
        return meta
