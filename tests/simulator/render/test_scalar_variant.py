"""Mitsuba's scalar variant (the fallback without libLLVM >= 16) renders what the llvm variant does.

A tiny scene (96 x 80 px, 2 frames, 32 spp, a 256 x 128 sky map in both runs) is rendered on the
scalar variant in a subprocess (Mitsuba's variant is process-global) and on the llvm variant here.
Stated tolerances: masks and coverage identical (the same rays hit the same faces); thermal and
every RGB pixel no target touches within 1e-4 relative (the same rays, float32 rounding only);
RGB over the pixels a target touches within 3 % in the mean (path-traced: another sampler stream;
at 64 spp the two agree to 0.7 %, at 4 spp they differed by 8 %, Monte Carlo noise).
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from simulator.render import mitsuba_setup

ROOT = Path(__file__).resolve().parents[3]
SKY_MAP = (256, 128)


def render_tiny(path: str) -> None:
    """Render the tiny scene with the current variant into an .npz at ``path`` (also run as a script)."""
    from scenes import load_scenario
    from simulator.physics.timeline import build_timeline
    from simulator.render import renderer
    from tests.conftest import shrink

    renderer.ENV_WIDTH, renderer.ENV_HEIGHT = SKY_MAP
    timeline = build_timeline(shrink(load_scenario("clear_day_quad"), 96, 80, spp=32), 3, 2)
    r = renderer.SequenceRenderer(timeline)
    out = {"variant": np.array(r.mi.variant())}
    for f, fb in r.iter_frames():
        out.update({f"rgb{f}": fb.rgb_linear, f"thermal{f}": fb.thermal_radiance, f"mask_rgb{f}": fb.mask_rgb,
                    f"mask_thermal{f}": fb.mask_thermal})
        for cam in ("rgb", "thermal"):
            out[f"coverage_{cam}{f}"] = np.concatenate([c.coverage.ravel() for c in fb.coverage[cam]] or [np.zeros(0)])
        touched = np.zeros(fb.mask_rgb.shape, bool)  # pixels any target covers at all
        for c in fb.coverage["rgb"]:
            x0, y0, x1, y1 = c.region
            touched[y0:y1, x0:x1] |= c.coverage > 0
        out[f"target{f}"] = touched
    np.savez(path, **out)


def _unknown_variant_cli(value: str) -> tuple[int, str]:
    env = {**os.environ, "EVIDS_MITSUBA_VARIANT": value, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", "scenes", "list"],
                          env=env, capture_output=True, text=True, timeout=120)
    return proc.returncode, proc.stderr


def test_unknown_variant_is_one_line_exit_2():
    code, err = _unknown_variant_cli("cuda_rgb")
    assert code == 2
    assert err.count("\n") == 1 and "EVIDS_MITSUBA_VARIANT" in err and "llvm_ad_rgb" in err and "scalar_rgb" in err


def test_requested_variant_validates(monkeypatch):
    monkeypatch.setenv("EVIDS_MITSUBA_VARIANT", " scalar_rgb ")
    assert mitsuba_setup.requested_variant() == "scalar_rgb"
    monkeypatch.delenv("EVIDS_MITSUBA_VARIANT")
    assert mitsuba_setup.requested_variant() is None
    monkeypatch.setenv("EVIDS_MITSUBA_VARIANT", "llvm")
    with pytest.raises(ValueError, match="allowed: llvm_ad_rgb, scalar_rgb"):
        mitsuba_setup.requested_variant()


@pytest.mark.skipif(mitsuba_setup.find_libllvm() is None, reason="the llvm reference needs libLLVM >= 16")
def test_scalar_variant_render_matches_llvm(tmp_path, monkeypatch):
    env = {**os.environ, "EVIDS_MITSUBA_VARIANT": "scalar_rgb", "PYTHONPATH": str(ROOT)}
    target = json.dumps(str(tmp_path / "s.npz"))
    script = f"from tests.simulator.render.test_scalar_variant import render_tiny; render_tiny({target})"
    proc = subprocess.run([sys.executable, "-c", script], env=env, cwd=ROOT, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    monkeypatch.delenv("EVIDS_MITSUBA_VARIANT", raising=False)
    from simulator.render import renderer

    monkeypatch.setattr(renderer, "ENV_WIDTH", renderer.ENV_WIDTH)  # restored after render_tiny patches it
    monkeypatch.setattr(renderer, "ENV_HEIGHT", renderer.ENV_HEIGHT)
    render_tiny(str(tmp_path / "l.npz"))
    s, ref = np.load(tmp_path / "s.npz"), np.load(tmp_path / "l.npz")
    assert str(s["variant"]) == "scalar_rgb" and str(ref["variant"]) == "llvm_ad_rgb"
    for f in (0, 1):
        for key in ("mask_rgb", "mask_thermal", "coverage_rgb", "coverage_thermal"):
            np.testing.assert_array_equal(s[f"{key}{f}"], ref[f"{key}{f}"])
        target = ref[f"target{f}"]
        assert target.sum() >= 4  # the drone is in view: the comparison covers a target
        np.testing.assert_allclose(s[f"thermal{f}"], ref[f"thermal{f}"], rtol=1e-4)
        np.testing.assert_allclose(s[f"rgb{f}"][~target], ref[f"rgb{f}"][~target], rtol=1e-4, atol=1e-6)
        mean_s, mean_ref = s[f"rgb{f}"][target].mean(axis=0), ref[f"rgb{f}"][target].mean(axis=0)
        np.testing.assert_allclose(mean_s, mean_ref, rtol=0.03)


def test_finite_radiance_replaces_a_nan_sample_by_its_neighbourhood_median():
    import numpy as np

    from simulator.render.renderer import finite_radiance

    img = np.arange(5 * 5 * 3, dtype=np.float32).reshape(5, 5, 3)
    assert finite_radiance(img) is img                      # nothing to replace: the same array
    bad = img.copy()
    bad[2, 2] = np.nan
    with pytest.warns(RuntimeWarning, match="1 non-finite pixel"):
        fixed = finite_radiance(bad)
    assert np.isfinite(fixed).all() and np.array_equal(np.delete(fixed.reshape(25, 3), 12, 0),
                                                        np.delete(img.reshape(25, 3), 12, 0))
    assert np.allclose(fixed[2, 2], img[2, 2])  # the median of the 8 finite neighbours of a linear ramp = the centre
    gray = np.ones((4, 4), np.float32)
    gray[0, 0] = np.inf
    with pytest.warns(RuntimeWarning):
        assert finite_radiance(gray)[0, 0] == 1.0
