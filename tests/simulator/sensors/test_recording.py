"""The H.264 recording chain: determinism, what it does to noise and faint targets, refused rates."""
import numpy as np
import pytest
from pydantic import ValidationError

from scenes import load_scenario
from scenes.errors import UserInputError
from scenes.schema import Recording
from simulator.physics import thermal
from simulator.physics.timeline import build_timeline
from simulator.sensors import camera as cam
from simulator.sensors.recording import H264Stream

pytest.importorskip("av")


def _sky_frames(n=30, h=96, w=128, sigma=0.45, target=0.0, seed=0):
    """A static smooth sky (vertical gradient) with fresh Gaussian noise every frame, 8 bit; an
    optional 2x2-px target of ``target`` grey levels drifting one pixel per frame."""
    rng = np.random.default_rng(seed)
    base = 90.0 + 20.0 * np.arange(h)[:, None] / h * np.ones((1, w))
    frames = []
    for i in range(n):
        g = base + rng.normal(0.0, sigma, (h, w))
        if target:
            g[40:42, 30 + i:32 + i] += target
        frames.append(np.clip(np.rint(g), 0, 255).astype(np.uint8))
    return frames


def test_grey_view_is_recorded_on_video_levels():
    ramp = np.tile(np.arange(256, dtype=np.uint8), (64, 1))[:, ::2].repeat(2, axis=1)
    limited = _through([ramp] * 2, crf=10)[1].astype(int)
    full = _through([ramp] * 2, crf=10, video_range="full")[1].astype(int)
    assert 14 <= limited.min() <= 18 and 233 <= limited.max() <= 237        # 16 + 219 v / 255
    assert full.min() <= 2 and full.max() >= 253
    assert np.abs(limited - np.rint(16 + ramp.astype(float) * 219 / 255)).mean() < 1.0


def _through(frames, colour=False, **params):
    h, w = frames[0].shape[:2]
    stream = H264Stream(w, h, 30.0, Recording(**params), colour=colour)
    return [stream(f) for f in frames]


def test_same_frames_give_the_same_bytes():
    frames = _sky_frames(n=12)
    a = b"".join(f.tobytes() for f in _through(frames, crf=28))
    b = b"".join(f.tobytes() for f in _through(frames, crf=28))
    assert a == b
    assert a != b"".join(f.tobytes() for f in frames)                  # it is lossy


def test_temporal_noise_of_a_static_sky_drops():
    # the sky's noise is given on the recorded (video-level) scale: full range keeps it as drawn
    frames = _sky_frames(n=30, h=256, w=320)                           # the benchmark's IR frame size
    before = np.stack(frames[5:]).astype(float).std(axis=0)
    after = np.stack(_through(frames, crf=28, video_range="full")[5:]).astype(float).std(axis=0)
    assert np.median(before) > 0.4                                      # 8-bit rounding of sigma 0.45
    assert np.median(after) == 0.0                                      # skipped blocks: the real clips' 0.00
    assert after.mean() < 0.5 * before.mean()


def test_a_faint_two_pixel_target_loses_contrast():
    frames = _sky_frames(n=30, h=256, w=320, target=8.0, seed=1)
    out = _through(frames, crf=28, video_range="full")

    def contrast(seq):
        return np.mean([seq[i][40:42, 30 + i:32 + i].mean() - np.median(seq[i][35:47, 25 + i:37 + i])
                        for i in range(5, len(seq))])

    assert contrast(frames) > 7.0
    assert contrast(out) < 0.8 * contrast(frames)


def test_rgb_round_trip_is_close_on_smooth_content_and_odd_sizes_work():
    h, w = 33, 47
    yy, xx = np.mgrid[:h, :w]
    rgb = np.stack([60 + xx, 80 + yy, 120 + 0 * xx], axis=-1).astype(np.uint8)
    out = _through([rgb] * 3, colour=True, crf=18)
    assert out[0].shape == rgb.shape and out[0].dtype == np.uint8
    assert np.abs(out[2].astype(int) - rgb).mean() < 3.0
    grey = _through([rgb[..., 1]] * 2, crf=18)
    assert grey[1].shape == (h, w)


def test_crf_and_bit_rate_are_exclusive():
    with pytest.raises(ValidationError, match="crf or bit_rate_bps"):
        Recording(crf=23, bit_rate_bps=100000)


def _scenario(**recording):
    s = load_scenario("clear_day_quad")
    rig = s.camera_rig
    rig = rig.model_copy(update={
        "rgb": rig.rgb.model_copy(update={"width_px": 64, "height_px": 48}),
        "thermal": rig.thermal.model_copy(update={"width_px": 64, "height_px": 48}),
        "recording": Recording(**recording)})
    return s.model_copy(update={"camera_rig": rig, "duration_s": 3 / s.frame_rate_hz})


def test_a_bit_rate_the_encoder_refuses_names_the_field():
    tl = build_timeline(_scenario(bit_rate_bps=100), 0)
    with pytest.raises(UserInputError, match=r"camera_rig\.recording\.bit_rate_bps = 100"):
        cam.CameraModel(tl, 30.0)


def test_camera_model_records_through_the_chain():
    tl = build_timeline(_scenario(bit_rate_bps=200000, gop_frames=2), 0)
    model = cam.CameraModel(tl, 30.0)
    k = np.full((48, 64), 285.0, np.float32)
    rec = [model.record(i, np.full((48, 64, 3), 0.3, np.float32), thermal.band_radiance(k).astype(np.float32), k)
           for i in range(3)]
    meta = model.metadata()
    assert meta["recording"]["bit_rate_bps"] == 200000 and meta["recording"]["encoder"] == "libx264"
    assert model.recording.rgb.bytes_written > 0 and model.recording.thermal.index == 3
    assert rec[2].thermal_counts.dtype == np.uint16                     # radiometric counts untouched


def test_cli_render_with_a_refused_bit_rate_exits_2_and_writes_nothing(tmp_path):
    import subprocess
    import sys

    import yaml

    from scenes.loader import LIBRARY_DIR

    data = yaml.safe_load((LIBRARY_DIR / "clear_day_quad.yaml").read_text())
    data["duration_s"] = 0.08
    data["camera_rig"]["rgb"].update(width_px=64, height_px=48)
    data["camera_rig"]["thermal"].update(width_px=64, height_px=48)
    data["camera_rig"]["recording"] = {"bit_rate_bps": 10}
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    result = subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", "render", str(bad),
                             "--out", str(out)], capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 2
    assert "camera_rig.recording.bit_rate_bps" in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()
