"""The camera model: optics, bolometer, noise, quantisation, determinism (no renderer needed)."""
import numpy as np
import pytest
from pydantic import ValidationError
from scipy.integrate import dblquad
from scipy.special import j1

from scenes import load_scenario
from scenes.schema import ThermalCamera
from simulator.physics import thermal
from simulator.physics.timeline import build_timeline
from simulator.sensors import camera as cam
from simulator.sensors.encode import agc_8bit, kelvin_to_counts, rgb_to_srgb8


def _timeline(w=64, h=48, frames=4, seed=5, **thermal_updates):
    s = load_scenario("clear_day_quad")
    rig = s.camera_rig
    rig = rig.model_copy(update={
        "rgb": rig.rgb.model_copy(update={"width_px": w, "height_px": h}),
        "thermal": rig.thermal.model_copy(update={"width_px": w, "height_px": h, **thermal_updates})})
    s = s.model_copy(update={"camera_rig": rig, "duration_s": frames / s.frame_rate_hz})
    return build_timeline(s, seed)


def _airy_square_fraction(pitch_um, f_number, wavelength_um):
    """Energy of an Airy pattern (point at a pixel centre) inside that square pixel."""
    scale = wavelength_um * f_number

    def airy(y, x):
        v = np.pi * np.hypot(x, y) / scale
        return (2 * j1(v) / v) ** 2 if v > 1e-12 else 1.0

    total = 4.0 * scale ** 2 / np.pi
    half = pitch_um / 2
    return dblquad(airy, -half, half, -half, half, epsabs=1e-9)[0] / total


@pytest.mark.parametrize("pitch,f_number,wavelength", [(12.0, 1.0, 10.0), (17.0, 1.2, 10.0), (12.0, 1.0, 8.0)])
def test_psf_pixel_energy_matches_the_airy_integral(pitch, f_number, wavelength):
    kernel = cam.psf_kernel(pitch, f_number, wavelength, 0.0)
    centre = kernel[kernel.shape[0] // 2, kernel.shape[1] // 2]
    assert centre == pytest.approx(_airy_square_fraction(pitch, f_number, wavelength), abs=0.004)
    assert kernel.sum() == pytest.approx(1.0)
    assert np.allclose(kernel, kernel.T) and np.allclose(kernel, kernel[::-1, ::-1])


def test_lwir_default_keeps_about_two_thirds_of_a_point_in_its_pixel():
    kernel = cam.psf_kernel(12.0, 1.0, 10.0, 0.0)
    assert 0.6 < kernel[kernel.shape[0] // 2, kernel.shape[1] // 2] < 0.66


def test_defocus_spreads_the_psf_and_a_large_blur_circle_is_a_uniform_disk():
    sharp = cam.psf_kernel(12.0, 1.0, 10.0, 0.0)
    soft = cam.psf_kernel(12.0, 1.0, 10.0, 24.0)
    c = sharp.shape[0] // 2
    assert soft[soft.shape[0] // 2, soft.shape[0] // 2] < sharp[c, c] - 0.2
    disk = cam.psf_kernel(12.0, 1.0, 10.0, 240.0)   # blur circle radius 10 px >> diffraction
    cd = disk.shape[0] // 2
    inner = disk[cd - 5:cd + 6, cd - 5:cd + 6]
    assert inner.std() / inner.mean() < 0.05
    assert disk[cd, cd] == pytest.approx(1.0 / (np.pi * 10.0 ** 2), rel=0.05)


def test_kernel_filter_conserves_a_flat_image_and_energy():
    f = cam.KernelFilter(cam.psf_kernel(12.0, 1.0, 10.0, 0.0))
    flat = np.full((40, 50), 7.0)
    assert np.allclose(f(flat), 7.0, atol=1e-4)
    point = np.zeros((60, 60))
    point[30, 30] = 1.0
    out = f(point)
    assert out.sum() == pytest.approx(1.0, abs=1e-4)
    assert out[30, 30] == pytest.approx(f.kernel[f.radius, f.radius], abs=1e-5)


def _flat_thermal(tl, temp_k=300.0):
    p = tl.scenario.camera_rig.thermal
    return np.full((p.height_px, p.width_px), float(thermal.band_radiance(temp_k)), np.float32)


def test_netd_noise_std_on_a_flat_scene():
    tl = _timeline(w=256, h=200, fpn_column_offset_k=0.0, fpn_column_gain=0.0, netd_k=0.04)
    sensor = cam.ThermalSensor(tl.scenario.camera_rig.thermal, tl, 1 / 30, 288.0)
    kelvin, counts, _ = sensor.record(0, _flat_thermal(tl))
    assert kelvin.mean() == pytest.approx(300.0, abs=0.01)
    assert kelvin.std() == pytest.approx(0.04, rel=0.03)
    assert (counts.astype(float) * 0.01).std() == pytest.approx(0.04, rel=0.05)


def test_fixed_pattern_is_per_column_and_fixed_over_frames():
    tl = _timeline(w=200, h=150, netd_k=0.01, fpn_column_offset_k=0.2, fpn_column_gain=0.0)
    sensor = cam.ThermalSensor(tl.scenario.camera_rig.thermal, tl, 1 / 30, 288.0)
    a, _, _ = sensor.record(0, _flat_thermal(tl))
    b, _, _ = sensor.record(1, _flat_thermal(tl))
    cols_a, cols_b = a.mean(axis=0) - 300.0, b.mean(axis=0) - 300.0
    assert cols_a.std() == pytest.approx(0.2, rel=0.15)
    assert np.corrcoef(cols_a, cols_b)[0, 1] > 0.99          # same pattern in both frames
    assert a.std(axis=0).mean() == pytest.approx(0.01, rel=0.1)   # rows: only temporal noise
    assert not np.array_equal(a, b)


def test_column_gain_acts_about_the_nuc_reference():
    tl = _timeline(w=200, h=20, netd_k=1e-6, fpn_column_offset_k=0.0, fpn_column_gain=0.05)
    sensor = cam.ThermalSensor(tl.scenario.camera_rig.thermal, tl, 1 / 30, 300.0)
    at_ref, _, _ = sensor.record(0, _flat_thermal(tl, 300.0))
    assert np.abs(at_ref - 300.0).max() < 1e-3
    sensor2 = cam.ThermalSensor(tl.scenario.camera_rig.thermal, tl, 1 / 30, 300.0)
    cold, _, _ = sensor2.record(0, _flat_thermal(tl, 260.0))
    assert (cold.mean(axis=0) - 260.0).std() == pytest.approx(40 * 0.05, rel=0.2)


def test_pixel_gain_is_a_fixed_grain_about_the_nuc_reference_and_leaves_the_columns_alone():
    base = dict(w=120, h=100, netd_k=1e-6, fpn_column_offset_k=0.01, fpn_column_gain=0.002)
    tl0 = _timeline(**base)
    tl = _timeline(**base, fpn_pixel_gain=0.004)
    p = tl.scenario.camera_rig.thermal
    at_ref, _, _ = cam.ThermalSensor(p, tl, 1 / 30, 300.0).record(0, _flat_thermal(tl, 300.0))
    assert np.abs(at_ref - 300.0).max() < 0.05            # only the column offsets (0.01 K rms) at the reference
    sensor = cam.ThermalSensor(p, tl, 1 / 30, 300.0)
    cold_a, _, _ = sensor.record(0, _flat_thermal(tl, 260.0))
    cold_b, _, _ = sensor.record(1, _flat_thermal(tl, 260.0))
    without, _, _ = cam.ThermalSensor(tl0.scenario.camera_rig.thermal, tl0, 1 / 30, 300.0).record(
        0, _flat_thermal(tl0, 260.0))
    grain = cold_a.astype(np.float64) - without                 # the same column draws: only the pixel term left
    assert grain.std() == pytest.approx(40 * 0.004, rel=0.05)  # 40 K below the reference x 0.4 %
    # no column structure of its own: the column means of 100 independent pixels spread by std / 10
    assert grain.mean(axis=0).std() == pytest.approx(grain.std() / 10, rel=0.3)
    assert np.abs(cold_a - cold_b).max() < 1e-3                 # fixed over frames


def test_pixel_gain_unset_is_left_out_of_the_scenario_dump():
    p = _timeline().scenario.camera_rig.thermal
    assert "fpn_pixel_gain" not in p.model_dump()
    assert p.model_copy(update={"fpn_pixel_gain": 0.001}).model_dump()["fpn_pixel_gain"] == 0.001


def test_bolometer_lag_is_first_order():
    tl = _timeline(w=32, h=24, frames=8)
    p = tl.scenario.camera_rig.thermal
    sensor = cam.ThermalSensor(p, tl, 1 / 100, 288.0)   # 10 ms frames, tau 10 ms
    low, high = _flat_thermal(tl, 280.0).astype(np.float64), _flat_thermal(tl, 320.0).astype(np.float64)
    sensor.detector_radiance(0, low)
    a = 1 - np.exp(-1.0)
    assert sensor.lag_alpha == pytest.approx(a)
    for n in range(1, 4):
        y = sensor.detector_radiance(n, high)
        expected = high[0, 0] - (high[0, 0] - low[0, 0]) * (1 - a) ** n
        assert y[12, 16] == pytest.approx(expected, rel=1e-4)


def test_motion_blur_spreads_a_point_along_its_motion_and_keeps_its_energy():
    img = np.zeros((40, 60))
    img[20, 20] = 1.0
    motion = cam._Motion(centre_px=np.array([[[20.5, 20.5]]]), step_px=np.array([[[10.0, 0.0]]]),
                         half_size_px=np.array([[1.0]]), in_front=np.array([[True]]))
    box = cam.motion_blur(img, motion, 0, 1.0, "box", 0.0, 1 / 30, 2)
    assert box.sum() == pytest.approx(1.0)
    row = box[20]
    assert np.count_nonzero(row > 1e-3) >= 10 and row[10:21].sum() > 0.99  # trail runs back (to smaller x)
    assert np.allclose(box[[19, 21]], 0)
    expo = cam.motion_blur(img, motion, 0, 1.0, "exponential", 0.010, 1 / 30, 2)
    assert expo.sum() == pytest.approx(1.0)
    assert expo[20, 19] > expo[20, 14] > expo[20, 11]       # newest positions weigh most


def test_rgb_shot_and_read_noise_follow_the_electron_count():
    tl = _timeline(w=200, h=160)
    p = tl.scenario.camera_rig.rgb
    sensor = cam.RgbSensor(p, tl, 1 / 30, render_exposure=1.0)
    lam = np.full((160, 200), 400.0)
    rng = np.random.default_rng(0)
    shot = cam.shot_noise(lam, rng)
    assert shot.mean() == pytest.approx(400.0, rel=0.01) and shot.var() == pytest.approx(400.0, rel=0.05)
    big = cam.shot_noise(np.full((160, 200), 1e5), rng)
    assert big.var() == pytest.approx(1e5, rel=0.05)
    with_read = cam.shot_noise(np.full((160, 200), 1e4), rng, read_noise_e=50.0)
    assert with_read.var() == pytest.approx(1e4 + 2500.0, rel=0.05)
    dark = cam.shot_noise(np.full((160, 200), 20.0), rng, read_noise_e=3.0)
    assert dark.mean() == pytest.approx(20.0, abs=0.2) and dark.var() == pytest.approx(29.0, rel=0.06)
    assert sensor.full_well_e == pytest.approx(p.full_well_e
                                               * (p.sensor_width_mm * 1000 / 200 / p.native_pixel_pitch_um) ** 2)


def test_rgb_auto_exposure_caps_at_the_frame_period_and_raises_gain_in_the_dark():
    tl = _timeline(w=64, h=48)
    p = tl.scenario.camera_rig.rgb
    day = cam.RgbSensor(p, tl, 1 / 30, render_exposure=5.0)        # key radiance 0.09 W m^-2 sr^-1 nm^-1
    dusk = cam.RgbSensor(p, tl, 1 / 30, render_exposure=5e3)
    assert day.exposure_time_s < 1 / 30 and day.gain == 1.0
    assert dusk.exposure_time_s == pytest.approx(1 / 30) and dusk.gain > 1.0
    flat = np.full((48, 64, 3), 0.45, np.float32)
    noisy_day = day.record(0, flat).astype(float).std()
    noisy_dusk = dusk.record(0, flat).astype(float).std()
    assert noisy_dusk > noisy_day


def test_record_is_deterministic_per_seed_and_frame():
    def run(seed):
        tl = _timeline(seed=seed)
        model = cam.CameraModel(tl, render_exposure=30.0)
        rgb = np.full((48, 64, 3), 0.3, np.float32)
        rec = [model.record(i, rgb, _flat_thermal(tl), np.full((48, 64), 300.0, np.float32)) for i in range(2)]
        return [(r.rgb8.tobytes(), r.thermal_counts.tobytes(), r.thermal_agc8.tobytes()) for r in rec]

    a, b, c = run(1), run(1), run(2)
    assert a == b
    assert a != c
    assert a[0][1] != a[1][1]          # fresh temporal noise every frame


def test_ideal_sensor_is_the_plain_encoding():
    s = load_scenario("clear_day_quad")
    s = s.model_copy(update={"camera_rig": s.camera_rig.model_copy(update={"sensor": "ideal"})})
    tl = build_timeline(s, 0, 1)
    model = cam.CameraModel(tl, 1.0)
    rgb = np.random.default_rng(0).uniform(0, 1, (8, 9, 3)).astype(np.float32)
    kelvin = np.random.default_rng(1).uniform(250, 300, (8, 9)).astype(np.float32)
    rec = model.record(0, rgb, thermal.band_radiance(kelvin), kelvin)
    assert np.array_equal(rec.rgb8, rgb_to_srgb8(rgb))
    assert np.array_equal(rec.thermal_counts, kelvin_to_counts(kelvin, 0.01))
    assert np.array_equal(rec.thermal_agc8, agc_8bit(kelvin)[0])
    assert model.metadata() == {"sensor": "ideal"}


def test_metadata_records_every_sensor_parameter():
    tl = _timeline()
    meta = cam.CameraModel(tl, 10.0).metadata()
    for field in ThermalCamera.model_fields:
        if field in ThermalCamera._OMIT_WHEN_UNSET:   # opt-in, left out of every dump while unset
            assert field not in meta["thermal"]
            continue
        assert field in meta["thermal"]
    rgb_model = type(tl.scenario.camera_rig.rgb)
    for field in rgb_model.model_fields:
        if field in rgb_model._OMIT_WHEN_UNSET:      # opt-in, left out of every dump while unset
            assert field not in meta["rgb"]
            continue
        assert field in meta["rgb"]
    assert 0.6 < meta["thermal"]["psf_centre_pixel_fraction"] < 0.66
    pinned = cam.CameraModel(_timeline(agc="plateau", agc_mean_level=0.41), 10.0)
    assert pinned.metadata()["thermal"]["agc_mean_level"] == 0.41                 # recorded once set
    assert pinned.thermal._plateau.mean_level == 0.41                            # and passed to the gain stage
    assert pinned.thermal._plateau.base_opening_px == 0                          # unset: the Gaussian base
    opened = cam.CameraModel(_timeline(agc="plateau", agc_base_sigma_px=15.0, agc_base_opening_px=13), 10.0)
    assert opened.metadata()["thermal"]["agc_base_opening_px"] == 13
    assert opened.thermal._plateau.base_opening_px == 13
    with pytest.raises(ValidationError, match="agc_base_opening_px"):
        ThermalCamera(agc="plateau", agc_base_sigma_px=15.0, agc_base_opening_px=1)   # a 1 px disc opens nothing
    with pytest.raises(ValidationError, match="agc_base_opening_px"):
        ThermalCamera(agc="plateau", agc_base_opening_px=21)                     # no base to open: inert, refused


def test_14_bit_counts_clip_and_need_a_coarse_enough_scale():
    with pytest.raises(ValidationError, match="kelvin_per_count"):
        ThermalCamera(adc_bits=14, kelvin_per_count=0.01)
    ThermalCamera(adc_bits=14, kelvin_per_count=0.04)


@pytest.mark.parametrize("mode", ["minmax", "percentile", "histogram"])
def test_agc_modes_span_the_8_bit_range(mode):
    k = np.random.default_rng(0).normal(280, 3, (50, 60)).astype(np.float32)
    out = cam.agc(k, mode)
    assert out.dtype == np.uint8 and out.min() == 0 and out.max() == 255
    assert np.all(np.diff(out.ravel()[np.argsort(k.ravel())].astype(int)) >= 0)   # monotonic in temperature


# --- the fast implementations against their reference computations --------------------------------
def _mirror_convolve_reference(image, kernel):
    from scipy.ndimage import convolve

    return convolve(image.astype(np.float64), kernel, mode="mirror")   # numpy 'reflect' padding


@pytest.mark.parametrize("kernel_args", [(9.64, 2.8, 0.55, 0.0), (9.64, 2.8, 0.465, 0.0),   # RGB: direct
                                         (12.0, 1.0, 10.0, 0.0), (12.0, 1.0, 10.0, 24.0)])  # LWIR: FFT
def test_kernel_filter_equals_the_mirrored_spatial_convolution(kernel_args):
    kernel = cam.psf_kernel(*kernel_args)
    rng = np.random.default_rng(1)
    image = (10.0 + rng.random((70, 90))).astype(np.float32)
    image[30:34, 40:46] += 50.0                                          # a hot target: an edge to blur
    out = cam.KernelFilter(kernel)(image)
    ref = _mirror_convolve_reference(image, kernel)
    assert out.dtype == np.float32 and out.shape == image.shape
    assert np.max(np.abs(out - ref) / ref) < 1e-6                        # float32 rounding (2^-23 = 1.2e-7)


def test_kernel_filter_does_not_depend_on_the_opencv_thread_count():
    import cv2

    image = np.random.default_rng(2).random((130, 150)).astype(np.float32)
    filters = [cam.KernelFilter(cam.psf_kernel(9.64, 2.8, 0.61, 0.0)),
               cam.KernelFilter(cam.psf_kernel(12.0, 1.0, 10.0, 0.0))]
    before = cv2.getNumThreads()
    try:
        outs = []
        for threads in (1, 2, 4):
            cv2.setNumThreads(threads)
            outs.append([f(image) for f in filters])
    finally:
        cv2.setNumThreads(before)
    for other in outs[1:]:
        assert all(np.array_equal(a, b) for a, b in zip(outs[0], other))


def _blur_along_reference(window, displacement_px, frac, weights):
    """The definition: weighted sum of scipy.ndimage.shift (bilinear, edges replicated), float64."""
    from scipy.ndimage import shift

    out = np.zeros(window.shape)
    for f, w in zip(frac, weights):
        dx, dy = -np.asarray(displacement_px) * f
        out += w * shift(window.astype(np.float64), (dy, dx) + (0,) * (window.ndim - 2), order=1, mode="nearest")
    return out


@pytest.mark.parametrize("displacement", [(12.3, 0.0), (-4.37, 2.9), (0.6, -7.25), (3.0, 3.0), (-0.3, 0.1)])
@pytest.mark.parametrize("kind", ["box", "exponential"])
@pytest.mark.parametrize("channels", [0, 3])
def test_blur_along_equals_the_sum_of_bilinear_shifts(displacement, kind, channels):
    rng = np.random.default_rng(3)
    shape = (41, 57) + ((channels,) if channels else ())
    window = (1.0 + rng.random(shape)).astype(np.float32)
    window[15:22, 20:30] += 20.0                                        # the target, near the trail's path
    length = float(np.hypot(*displacement))
    frac, weights = cam.trail_weights(int(np.ceil(2 * length)) + 2, kind, 0.010, 1 / 30)
    out = cam.blur_along(window, np.array(displacement), frac, weights)
    ref = _blur_along_reference(window, displacement, frac, weights)
    assert out.dtype == np.float32 and out.shape == window.shape
    assert np.max(np.abs(out - ref) / ref) < 1e-6                       # float32 rounding


def test_trail_kernel_sums_the_weights_and_runs_along_the_motion():
    frac, weights = cam.trail_weights(10, "box", 0.0, 1 / 30)
    k = cam.trail_kernel(np.array([4.0, 0.0]), frac, weights)
    assert k.shape[0] == 3 and k.sum() == pytest.approx(1.0, abs=1e-6)
    centre = k.shape[1] // 2
    assert (np.all(k[1, :centre] == 0)
            and k[1, centre:centre + 5].sum() == pytest.approx(1.0, abs=1e-6))   # out[p] reads in[p + o], o >= 0


@pytest.mark.parametrize("kelvin_per_count", [0.01, 0.04, 0.0123])
def test_equalise_counts_is_histogram_agc_of_the_shown_temperatures(kelvin_per_count):
    rng = np.random.default_rng(4)
    counts = np.clip(rng.normal(29000, 300, (60, 80)), 0, 65535).astype(np.uint16)
    counts[:5, :7] = 65535                                            # a hot clipped corner
    counts[10, :] = rng.integers(0, 100, 80)                          # far-away cold levels (gaps)
    shown = counts.astype(np.float32) * np.float32(kelvin_per_count)
    assert np.array_equal(cam.equalise_counts(counts), cam.agc(shown, "histogram"))
    flat = np.full((8, 9), 1234, np.uint16)
    assert np.array_equal(cam.equalise_counts(flat), cam.agc(flat.astype(np.float32) * np.float32(0.01), "histogram"))


@pytest.mark.parametrize("agc_mode", ["minmax", "histogram"])
def test_recorded_frames_are_fresh_arrays_not_reused_work_arrays(agc_mode):
    tl = _timeline(frames=4, agc=agc_mode)
    model = cam.CameraModel(tl, render_exposure=30.0)
    rng = np.random.default_rng(6)
    inputs = [((0.2 + 0.1 * rng.random((48, 64, 3))).astype(np.float32),
               _flat_thermal(tl) * (1 + 0.01 * rng.random((48, 64))).astype(np.float32),
               np.full((48, 64), 300.0, np.float32)) for _ in range(3)]
    first = model.record(0, *inputs[0])
    kept = {k: getattr(first, k).copy() for k in ("rgb8", "thermal_counts", "thermal_agc8", "thermal_kelvin")}
    later = [model.record(i, *inputs[i]) for i in (1, 2)]
    for k, v in kept.items():
        assert np.array_equal(getattr(first, k), v)                     # not overwritten by later frames
        assert not any(np.shares_memory(getattr(first, k), getattr(r, k)) for r in later)
    fresh = cam.CameraModel(tl, render_exposure=30.0)                   # same frames from a new model
    again = [fresh.record(i, *inputs[i]) for i in range(3)]
    for a, b in zip([first, *later], again):
        assert a.rgb8.tobytes() == b.rgb8.tobytes() and a.thermal_counts.tobytes() == b.thermal_counts.tobytes()


def test_plateau_agc_and_camcorder_tone_are_deterministic_and_stateful():
    def run(seed):
        tl = _timeline(seed=seed, frames=3, agc="plateau")
        rig = tl.scenario.camera_rig
        rgb_params = rig.rgb.model_copy(update={"tone": "camcorder"})
        model = cam.CameraModel(tl, render_exposure=30.0)
        model.rgb = cam.RgbSensor(rgb_params, tl, 1 / 30, 30.0)
        rng = np.random.default_rng(3)
        out = []
        for i in range(3):
            rgb = np.full((48, 64, 3), 0.1 * (i + 1), np.float32)      # the scene brightens: AE follows, damped
            k = (280 + 5 * rng.random((48, 64))).astype(np.float32)
            r = model.record(i, rgb, thermal.band_radiance(k).astype(np.float32), k)
            out.append((r.rgb8.tobytes(), r.thermal_agc8.tobytes(), float(np.median(r.rgb8))))
        return out

    a, b = run(1), run(1)
    assert a == b and run(2) != a
    medians = [m for _, _, m in a]
    assert medians[0] == pytest.approx(125, abs=3)                      # first frame: metered straight to the key
    assert medians[1] > medians[0] and medians[2] > medians[1]         # then damped: brighter scene, brighter frame


def test_gaussian_blur_adds_its_variance_to_the_psf():
    sharp = cam.psf_kernel(12.0, 1.0, 0.5, 0.0)  # diffraction negligible: a point stays in its pixel
    assert sharp[sharp.shape[0] // 2, sharp.shape[1] // 2] > 0.98
    soft = cam.psf_kernel(12.0, 1.0, 0.5, 0.0, 12.0)                   # sigma = 1 pixel
    r = soft.shape[0] // 2
    x = np.arange(-r, r + 1)
    var_x = float((soft.sum(axis=0) * x ** 2).sum())
    assert (soft.sum() == pytest.approx(1.0)
            and var_x == pytest.approx(1.0 + 1 / 12, rel=0.04))   # sigma^2 + binning (Sheppard)
    default = cam.psf_kernel(12.0, 1.0, 10.0, 0.0)
    assert np.array_equal(default, cam.psf_kernel(12.0, 1.0, 10.0, 0.0, 0.0))   # 0 = the former kernel


@pytest.mark.parametrize("n", [1, 2, 7, 200_001])
def test_standard_normal_f32_is_standard_normal_and_reproducible(n):
    out = cam.standard_normal_f32(np.random.default_rng(11), np.empty(n, np.float32))
    again = cam.standard_normal_f32(np.random.default_rng(11), np.empty(n, np.float32))
    other = cam.standard_normal_f32(np.random.default_rng(12), np.empty(n, np.float32))
    assert out.dtype == np.float32 and out.tobytes() == again.tobytes() and out.tobytes() != other.tobytes()
    assert np.isfinite(out).all() and np.abs(out).max() < 5.9
    if n > 1000:
        from scipy import stats

        assert abs(out.mean()) < 5 / np.sqrt(n) and out.std() == pytest.approx(1.0, abs=5 / np.sqrt(2 * n))
        assert stats.kstest(out, "norm").pvalue > 1e-3
        assert np.mean(np.abs(out) > 3) == pytest.approx(0.0027, rel=0.15)
        half = (n + 1) // 2                       # the cos and sin halves of the same pairs are independent
        assert abs(np.corrcoef(out[:n - half], out[half:])[0, 1]) < 5 / np.sqrt(n)


def test_standard_normal_f32_keeps_the_generator_stream_and_needs_a_contiguous_buffer():
    rng = np.random.default_rng(4)
    cam.standard_normal_f32(rng, np.empty((3, 5), np.float32))      # 8 raw draws for 15 values
    ref = np.random.default_rng(4)
    ref.bit_generator.advance(8)
    assert rng.random() == ref.random()
    with pytest.raises(ValueError, match="contiguous float32"):
        cam.standard_normal_f32(rng, np.empty((4, 6), np.float32)[:, ::2])
    with pytest.raises(ValueError, match="contiguous float32"):
        cam.standard_normal_f32(rng, np.empty(4, np.float64))


def test_shot_noise_is_exact_poisson_only_on_the_dark_pixels():
    lam = np.where(np.arange(40_000).reshape(200, 200) % 2 == 0, 20.0, 5e4).astype(np.float32)
    out = cam.shot_noise(lam, np.random.default_rng(2), read_noise_e=3.0)
    dark, bright = out[lam < 1000], out[lam >= 1000]
    assert dark.mean() == pytest.approx(20.0, abs=0.2) and dark.var() == pytest.approx(29.0, rel=0.06)
    assert bright.mean() == pytest.approx(5e4, rel=1e-3) and bright.var() == pytest.approx(5e4 + 9.0, rel=0.05)
    pure = cam.shot_noise(lam, np.random.default_rng(2), read_noise_e=0.0)[lam < 1000]   # Poisson: integers
    assert np.array_equal(pure, np.rint(pure)) and not np.array_equal(dark, np.rint(dark))
    again = cam.shot_noise(lam, np.random.default_rng(2), read_noise_e=3.0)
    assert again.tobytes() == out.tobytes()


@pytest.mark.parametrize("mode", ["minmax", "percentile", "histogram"])
@pytest.mark.parametrize("seed", range(12))
def test_agc_counts_equals_agc_of_the_shown_temperatures(mode, seed):
    rng = np.random.default_rng(seed)
    h, w = rng.integers(1, 80, 2)
    kelvin_per_count = (0.01, 0.04, 0.001)[seed % 3]
    kelvin = rng.normal(280, rng.uniform(0.01, 10), (h, w))
    counts = np.clip(np.rint(kelvin / kelvin_per_count), 0, 65535).astype(np.uint16)
    shown = np.multiply(counts, np.float32(kelvin_per_count), dtype=np.float32)
    assert np.array_equal(cam.agc_counts(counts, kelvin_per_count, mode), cam.agc(shown, mode))


def test_rgb_colour_gain_is_opt_in_needs_the_camcorder_and_scales_the_recorded_chroma():
    """Unset: out of every dump (scenario files and their hashes unchanged); set with tone srgb: refused, naming
    the field; set with the camcorder: a bluish sky's B' - R' in the recorded frame scales by the gain."""
    from scenes.schema import RgbCamera

    assert "colour_gain" not in RgbCamera().model_dump()
    assert RgbCamera(tone="camcorder", colour_gain=1.5).model_dump()["colour_gain"] == 1.5
    with pytest.raises(ValidationError, match="colour_gain"):
        RgbCamera(colour_gain=1.5)
    with pytest.raises(ValidationError, match="colour_gain"):
        RgbCamera(tone="camcorder", colour_gain=0.0)

    def chroma(gain):
        tl = _timeline(seed=4, frames=1)
        params = tl.scenario.camera_rig.rgb.model_copy(update={"tone": "camcorder", "colour_gain": gain})
        model = cam.CameraModel(tl, render_exposure=30.0)
        model.rgb = cam.RgbSensor(params, tl, 1 / 30, 30.0)
        sky = np.broadcast_to(np.array([0.06, 0.09, 0.14], np.float32), (48, 64, 3)).copy()
        k = np.full((48, 64), 280.0, np.float32)
        rec = model.record(0, sky, thermal.band_radiance(k).astype(np.float32), k).rgb8.astype(float)
        return float(np.median(rec[..., 2] - rec[..., 0]))

    plain, vivid = chroma(None), chroma(1.8)
    assert plain > 10 and vivid == pytest.approx(1.8 * plain, abs=2.0)
