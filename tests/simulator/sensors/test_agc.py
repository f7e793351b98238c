"""Plateau equalisation (LWIR) and the camcorder auto-exposure + tone curve (visible)."""
import numpy as np
import pytest

from simulator.sensors.agc import (
    CamcorderExposure,
    PlateauAgc,
    bt709_knee,
    plateau_transfer,
    scale_chroma,
)


def test_plateau_transfer_by_hand():
    hist = np.array([0, 10, 0, 10, 80, 0])
    # cap 20 of 100 pixels: kept [0, 10, 0, 10, 20, 0]; mid-bin cumulative / 40
    eq = plateau_transfer(hist, 0.2, 0.0, 0.0, 0.0)
    assert np.allclose(eq, [0, 0.125, 0.25, 0.375, 0.75, 1.0])
    lin = plateau_transfer(hist, 0.2, 1.0, 0.0, 0.0)         # occupied bins 1..4
    assert np.allclose(lin, [0, 0, 1 / 3, 2 / 3, 1, 1])
    mix = plateau_transfer(hist, 0.2, 0.25, 0.0, 0.0)
    assert np.allclose(mix, 0.25 * lin + 0.75 * eq)
    # plain equalisation (no cap) gives the 80-pixel bin most of the range
    assert np.allclose(plateau_transfer(hist, 1.0, 0.0, 0.0, 0.0), [0, 0.05, 0.1, 0.15, 0.6, 1.0])


def test_narrow_scene_is_not_stretched_beyond_the_maximum_gain():
    hist = np.zeros(100)
    hist[40:60] = 5                                            # 20 bins wide
    t = plateau_transfer(hist, 1.0, 1.0, 0.0, 80.0)            # min span 80 bins: a quarter of the range
    assert t[40] == pytest.approx(0.5 - 0.5 * 19 / 80) and t[59] == pytest.approx(0.5 + 0.5 * 19 / 80)
    flat = np.zeros(10)
    flat[3] = 50
    assert np.allclose(plateau_transfer(flat, 0.01, 0.3, 0.0, 4.0)[3], 0.5)


def _horizon_counts(rng, hot_ground_k=12.0, h=120, w=160):
    """Sky cooling upward (a 4 K gradient) over a warm ground in the lower third, 0.01 K counts."""
    y = np.arange(h)[:, None] * np.ones((1, w))
    kelvin = 270.0 + 4.0 * y / h
    kelvin[int(2 * h / 3):] = 283.0 + hot_ground_k * rng.random((h - int(2 * h / 3), w))
    kelvin += rng.normal(0, 0.04, kelvin.shape)
    return np.rint(kelvin / 0.01).astype(np.uint16)


def test_plateau_puts_the_sky_at_mid_grey_and_keeps_a_faint_target_faint():
    rng = np.random.default_rng(0)
    counts = _horizon_counts(rng)
    counts[30:32, 80:82] += 100                                  # +1 K target in the sky
    agc = PlateauAgc(0.01, 0.05, 0.005, 0.2, 0.005, 4.0, 0.0)
    out = agc(counts).astype(int)
    sky = out[:70]
    assert 40 < np.median(sky) < 160                             # not black as a min/max stretch makes it
    assert np.all(np.diff(out.ravel()[np.argsort(counts.ravel(), kind="stable")]) >= 0)   # monotonic
    target = out[30:32, 80:82].mean() - np.median(out[26:36, 76:86])
    plain = PlateauAgc(0.01, 0.05, 1.0, 0.0, 0.0, 4.0, 0.0)(counts).astype(int)
    target_plain = plain[30:32, 80:82].mean() - np.median(plain[26:36, 76:86])
    assert 5 < target < target_plain                              # the plateau caps the sky's share of grey levels
    lo, hi = np.percentile(counts, [0, 100])
    minmax = np.rint((counts - lo) / (hi - lo) * 255)
    assert np.median(minmax[:70]) < 40                           # what the min/max view does to this sky


def test_plateau_transfer_is_damped_over_frames():
    rng = np.random.default_rng(1)
    a, b = _horizon_counts(rng), _horizon_counts(rng, hot_ground_k=30.0)
    args = (0.01, 0.05, 0.005, 0.2, 0.005, 4.0)
    damped = PlateauAgc(*args, 0.75)
    assert np.array_equal(damped(a), PlateauAgc(*args, 0.0)(a))  # the first frame has no memory
    second = damped(b)
    undamped = PlateauAgc(*args, 0.0)
    _, t_a = undamped.transfer_of(a)
    binned, t_b = undamped.transfer_of(b)
    assert np.array_equal(second, np.rint((0.75 * t_a + 0.25 * t_b) * 255).astype(np.uint8)[binned].reshape(b.shape))
    assert not np.array_equal(second, undamped(b))


def test_bt709_knee_by_hand():
    v = bt709_knee(np.array([0.0, 0.01, 0.018, 0.25, 1.0, 10.0]), 0.85, 0.25)
    assert v[0] == 0 and v[1] == pytest.approx(0.045) and v[2] == pytest.approx(0.081, abs=1e-3)
    assert v[3] == pytest.approx(1.099 * 0.25 ** 0.45 - 0.099)
    assert v[4] == pytest.approx(0.85 + 0.15 * 0.25) and v[5] == 1.0


def test_auto_exposure_drives_any_uniform_scene_to_the_key():
    levels = 4095
    outs = []
    for fill in (300, 1200, 3000):
        ae = CamcorderExposure(1.0 / levels, levels, 0.25, 0.0, 0.85, 0.25)
        outs.append(int(ae(np.full((16, 16, 3), fill, np.uint16))[0, 0, 0]))
    assert outs == [125, 125, 125]                               # 255 x BT.709(0.25) = 124.9
    slow = CamcorderExposure(1.0 / levels, levels, 0.25, 0.5, 0.85, 0.25)
    f1 = slow.factor(np.full((8, 8, 3), 1000, np.uint16))
    f2 = slow.factor(np.full((8, 8, 3), 4000, np.uint16))        # 4x brighter: half the log step
    assert f1 == pytest.approx(0.25 * levels / 1000) and f2 == pytest.approx(f1 * 0.5)


def test_local_contrast_flattens_a_slow_gradient_and_keeps_the_detail():
    y = np.mgrid[0:120, 0:160][0]
    counts = (27000 + 4 * y).astype(np.uint16)                     # a 4.8 K sky gradient (0.01 K counts)
    counts[60:62, 80:82] += 200                                    # a +2 K target
    agc = PlateauAgc(0.01, 0.05, 0.005, 0.5, 0.005, 4.0, 0.0, base_sigma_px=15.0, base_gain=0.0)
    flat = agc.local_contrast(counts).astype(float)
    assert np.ptp(flat[40:80, 40]) < 0.25 * np.ptp(counts[40:80, 40].astype(float))   # the gradient is gone inside
    assert flat[60:62, 80:82].mean() - np.median(flat[50:72, 70:92]) > 150                  # the target stays
    kept = PlateauAgc(0.01, 0.05, 0.005, 0.5, 0.005, 4.0, 0.0, base_sigma_px=15.0, base_gain=1.0)
    assert np.abs(kept.local_contrast(counts).astype(int) - counts).max() <= 1              # gain 1 = identity


def test_opening_base_leaves_no_dark_ring_round_a_hot_target():
    """The Gaussian base rises round a hot blob and leaves a dark ring (unsharp-mask halo); the base of the
    opening does not see a blob narrower than its disc: no ring, the blob's full amplitude kept as detail,
    and a wide warm ground still goes into the base (flattened)."""
    y, x = np.mgrid[0:128, 0:160]
    counts = np.full((128, 160), 27000, dtype=np.uint16)
    counts[(y - 40) ** 2 + (x - 80) ** 2 <= 36] += 800              # a 13 px, +8 K target
    counts[96:, :] += 1500                                          # warm ground, 15 K
    args = (0.01, 0.05, 0.005, 0.5, 0.005, 4.0, 0.0)
    ring = ((y - 40) ** 2 + (x - 80) ** 2 >= 100) & ((y - 40) ** 2 + (x - 80) ** 2 <= 196)
    far = np.s_[5:15, 5:30]
    gauss = PlateauAgc(*args, base_sigma_px=12.0, base_gain=0.02).local_contrast(counts).astype(float)
    opened = PlateauAgc(*args, base_sigma_px=12.0, base_gain=0.02, base_opening_px=25).local_contrast(counts)
    opened = opened.astype(float)
    assert gauss[ring].mean() < gauss[far].mean() - 40                            # the halo: > 0.4 K darker
    assert abs(opened[ring].mean() - opened[far].mean()) < 5                     # none
    assert opened[40, 80] - opened[far].mean() > 790                              # the target's full 8 K
    assert gauss[40, 80] - gauss[far].mean() < 750                                # the Gaussian base ate some
    assert np.median(opened[110:, :]) - np.median(opened[far]) < 0.2 * 1500      # the ground is flattened


def test_gamma_darkens_the_sky_and_keeps_black_and_white():
    """ACE gamma > 1: the transfer's mid levels go down (the sky darkens), its ends stay at 0 and 255."""
    rng = np.random.default_rng(1)
    counts = (28000 + 60 * rng.standard_normal((64, 80))).astype(np.uint16)     # sky, 0.6 K noise
    counts[40:, :] += 1500                                                       # warm ground, 15 K
    counts[10, 10] = 31000                                                       # a hot target
    args = (0.01, 0.05, 0.005, 0.5, 0.0, 4.0, 0.0)
    plain, ace = PlateauAgc(*args)(counts).astype(int), PlateauAgc(*args, gamma=1.5)(counts).astype(int)
    sky = np.s_[20:30, :]
    assert np.median(ace[sky]) < np.median(plain[sky]) - 10
    assert ace[10, 10] == plain[10, 10] == 255
    assert ace.min() == plain.min() == 0


def test_protocol_gain_lifts_a_clear_sky_over_warm_ground():
    """The sim2real protocol's IR gain (examples/sim2real/realism_*.yaml, one camera for all four classes;
    the drone clips' camera also holds its output mean and opens its base, docs/SIM2REAL.md "Drone-only sky
    level", "Drone halos")
    puts a clear sky over warm ground well above the former fit (linear 0.3, base gain 0.05, gamma 1.5),
    which printed clear skies 30-40 grey levels darker than the real camera (docs/SIM2REAL.md, "IR sky
    level under the gain stage"); a cloud layer lifts the frame under the former fit (the mechanism)."""
    from pathlib import Path

    import cv2
    import yaml

    root = Path(__file__).resolve().parents[3] / "examples" / "sim2real"
    thermal = [yaml.safe_load((root / f"realism_{c}.yaml").read_text())["camera_rig"]["thermal"]
               for c in ("drone", "bird", "airplane", "helicopter")]
    assert thermal[0].pop("agc_mean_level") == 0.42 and all("agc_mean_level" not in t for t in thermal[1:])
    assert thermal[0].pop("agc_base_opening_px") == 21 and all("agc_base_opening_px" not in t for t in thermal[1:])
    assert all(t == thermal[0] for t in thermal)                                 # one camera, every class
    t = thermal[0]
    rng = np.random.default_rng(2)
    y = np.mgrid[0:256, 0:320][0].astype(float)
    clear = 26000 + 300 * (y / 160) + 3 * rng.standard_normal(y.shape)          # 3 K sky gradient, 0.03 K noise
    clear[160:] = (28500 + 300 * cv2.GaussianBlur(rng.standard_normal(y.shape), (0, 0), 3))[160:]   # ground +25 K
    clear[80:83, 150:156] = 29500                                                # a hot drone
    cloud = cv2.GaussianBlur(rng.standard_normal(y.shape), (0, 0), 12)
    cloudy = clear.copy()
    cloudy[:160] += (np.clip(cloud / cloud.std(), 0, None) * 300)[:160]          # warm cloud patches, up to ~+10 K

    def shown(frame, linear, base_gain, gamma):
        agc = PlateauAgc(0.01, 0.05, t["agc_plateau_fraction"], linear, t["agc_tail_fraction"], t["agc_min_span_k"],
                         0.0, t["agc_base_sigma_px"], base_gain, gamma)
        return agc(np.clip(frame, 0, 65535).astype(np.uint16)).astype(float)

    former = shown(clear, 0.3, 0.05, 1.5)
    now = shown(clear, t["agc_linear_fraction"], t["agc_base_gain"], t["agc_gamma"])
    assert np.median(now[:150]) > np.median(former[:150]) + 15                   # the clear sky is lifted
    assert now[81, 152] == 255                                                   # the target stays white
    assert np.median(shown(cloudy, 0.3, 0.05, 1.5)) > np.median(former) + 5      # clouds lifted the old fit's frame


def test_mean_level_pins_the_frame_mean_and_is_off_by_default():
    """agc_mean_level (FLIR ITT mean): skies of different temperature spreads print at one output mean;
    unset, the output is the same array as before the option existed; the pin keeps the order of grey levels."""
    from scenes.schema import ThermalCamera

    rng = np.random.default_rng(3)
    y = np.mgrid[0:64, 0:80][0].astype(float)
    args = (0.01, 0.05, 0.005, 0.1, 0.0, 16.0, 0.0, 15.0, 0.02, 1.3)
    means = []
    for span in (500, 3000):                                                     # a 5 K and a 30 K sky gradient
        counts = (26000 + span * (y / 64) ** 2 + 3 * rng.standard_normal(y.shape)).astype(np.uint16)
        counts[30:32, 40:42] = 30000                                              # a hot target
        plain = PlateauAgc(*args)(counts)
        assert np.array_equal(plain, PlateauAgc(*args, mean_level=None)(counts))
        pinned = PlateauAgc(*args, mean_level=0.41)(counts).astype(float)
        assert abs(pinned.mean() - 0.41 * 255) < 2.0
        order = np.lexsort((pinned.ravel(), plain.ravel()))
        assert np.all(np.diff(pinned.ravel()[order]) >= 0)                        # a monotonic map of the old view
        means.append(plain.astype(float).mean())
    assert abs(means[0] - means[1]) > 10                                         # without the pin they differ
    assert "agc_mean_level" not in ThermalCamera().model_dump(mode="json")       # scenario.yaml bytes unchanged
    assert ThermalCamera(agc_mean_level=0.41).model_dump(mode="json")["agc_mean_level"] == 0.41
    with pytest.raises(ValueError):
        ThermalCamera(agc_mean_level=1.0)


def test_scale_chroma_by_hand_keeps_luma_and_greys():
    """(R', G', B') = (100, 150, 200): Y' = 21.26 + 107.28 + 14.44 = 142.98; gain 2 puts each channel twice
    as far from Y': (57.02, 157.02, 255 clipped from 257.02); a grey pixel and gain 1 change nothing."""
    px = np.array([[[100.0, 150.0, 200.0], [90.0, 90.0, 90.0]]], np.float32)
    out = scale_chroma(px.copy(), 2.0)
    assert out[0, 0] == pytest.approx([57.02, 157.02, 255.0], abs=1e-3)
    assert out[0, 1] == pytest.approx([90.0, 90.0, 90.0])
    assert scale_chroma(px.copy(), 1.0) == pytest.approx(px)
    inside = scale_chroma(np.array([[[120.0, 130.0, 150.0]]], np.float32), 1.5)   # no clipping: luma kept
    y = lambda v: 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]              # noqa: E731
    assert y(inside[0, 0]) == pytest.approx(y([120.0, 130.0, 150.0]), abs=1e-3)


def test_camcorder_colour_gain_scales_chroma_and_is_off_when_unset():
    """Unset: the rounded LUT path, byte for byte; set: the same frame's chroma (B' - R' of a bluish sky)
    scales by the gain within the one rounding, its luma stays within half a level."""
    levels = 4095
    sky = np.zeros((8, 8, 3), np.uint16)
    sky[...] = (900, 1200, 1800)
    plain = CamcorderExposure(1.0 / levels, levels, 0.25, 0.0, 0.85, 0.25)(sky)
    unit = CamcorderExposure(1.0 / levels, levels, 0.25, 0.0, 0.85, 0.25, colour_gain=1.0)(sky)
    vivid = CamcorderExposure(1.0 / levels, levels, 0.25, 0.0, 0.85, 0.25, colour_gain=1.5)(sky)
    assert np.array_equal(plain, unit)
    p, v = plain[0, 0].astype(float), vivid[0, 0].astype(float)
    assert (v[2] - v[0]) == pytest.approx(1.5 * (p[2] - p[0]), abs=1.5)
    luma = np.array([0.2126, 0.7152, 0.0722])
    assert float(v @ luma) == pytest.approx(float(p @ luma), abs=1.0)
