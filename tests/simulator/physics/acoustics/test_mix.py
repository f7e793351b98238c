"""Scene audio and output: the WAV round trip, scene determinism and the reported sound power."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.physics import acoustics as ac
from tests.simulator.physics.acoustics.helpers import FS


def test_wav_round_trip(tmp_path):
    import soundfile

    x = (0.01 * np.sin(np.arange(4410) / 7.0)).astype(np.float32)
    path = ac.write_wav(tmp_path / "a.wav", x, FS, full_scale_pa=0.1)
    y, rate = soundfile.read(str(path), dtype="float32")
    assert rate == FS and np.allclose(y, x / 0.1, atol=1e-7)
    raw = path.read_bytes()
    peak = raw.find(b"PEAK")
    assert peak > 0 and raw[peak + 12:peak + 16] == b"\0\0\0\0"      # no wall-clock stamp: byte-identical files


def test_scene_audio_is_deterministic_and_reports_sound_power():
    from scenes.loader import load_scenario
    from simulator.physics.timeline import build_timeline

    tl = build_timeline(load_scenario("clear_day_quad"), 0, n_frames=15)
    a = ac.synthesize_audio(tl, 5, duration_s=0.5)
    b = ac.synthesize_audio(tl, 5, duration_s=0.5)
    assert a.mix_pa.tobytes() == b.mix_pa.tobytes()
    name = tl.targets[0].name
    assert a.sound_power_dba[name] == pytest.approx(ac.sound_power_dba(tl.targets[0].kind, tl.targets[0].size_m))
    louder = ac.synthesize_audio(tl, 5, duration_s=0.5, sound_power_db={name: a.sound_power_dba[name] + 6.0})
    ratio = np.sqrt(np.mean(louder.targets_pa[name] ** 2) / np.mean(a.targets_pa[name] ** 2))
    assert 20 * np.log10(ratio) == pytest.approx(6.0, abs=0.01)
