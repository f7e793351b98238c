"""The sim2real audio track: statistics on hand-made signals, synthetic clips, the quick track."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest

from harness.experiments.sim2real import audio as A
from scenes.errors import UserInputError

SR = 44_100


def _tone(f0: float, n_harm: int, seconds: float = 10.0, noise: float = 1e-3, seed: int = 0) -> np.ndarray:
    t = np.arange(int(seconds * SR)) / SR
    x = sum(0.3 / k * np.sin(2 * np.pi * f0 * k * t) for k in range(1, n_harm + 1))
    return x + noise * np.random.default_rng(seed).standard_normal(t.size)


def test_harmonic_tone_gives_its_fundamental_and_harmonics():
    stats = A.audio_statistics(_tone(400.0, 5), SR)
    assert len(stats["segments"]) == 2
    for seg in stats["segments"]:
        assert seg["pitched"] is True
        assert seg["f0_hz"] == pytest.approx(400.0, rel=0.01)
        assert seg["n_harmonics"] == 5
        assert seg["level_fluctuation_db"] < 0.05          # a steady tone
        # centroid of lines with amplitudes 0.3/k: sum k f0 (1/k^2) / sum 1/k^2 = f0 H5 / H5^(2)
        k = np.arange(1, 6)
        assert seg["spectral_centroid_hz"] == pytest.approx(400 * np.sum(1 / k) / np.sum(1 / k ** 2), rel=0.02)


def test_white_noise_is_unpitched_flat_and_centred_at_a_quarter_of_fs():
    x = 0.1 * np.random.default_rng(1).standard_normal(10 * SR)
    for seg in A.audio_statistics(x, SR)["segments"]:
        assert seg["pitched"] is False
        assert seg["n_harmonics"] == 0
        assert seg["spectral_centroid_hz"] == pytest.approx(SR / 4, rel=0.02)
        bands = np.array(seg["third_octave_dbfs"])
        # white noise: band power ~ bandwidth, +1 dB per 1/3 octave; 26 bands 50 Hz - 16 kHz
        slope = np.polyfit(np.arange(bands.size), bands, 1)[0]
        assert slope == pytest.approx(1.0, abs=0.1)
        # total: 0.01 full-scale^2 over 22.05 kHz; the 1 kHz band (231.6 Hz wide) holds 0.01 x 231.6 / 22050
        assert bands[13] == pytest.approx(10 * np.log10(0.01 * 1000 * (10 ** 0.05 - 10 ** -0.05) / (SR / 2)), abs=1.0)


def test_full_scale_sine_reads_minus_3_dbfs_in_its_band():
    t = np.arange(5 * SR) / SR
    seg = A.audio_statistics(np.sin(2 * np.pi * 1000.0 * t), SR)["segments"][0]
    bands = np.array(seg["third_octave_dbfs"])
    assert A.NOMINAL_CENTRES_HZ[13] == 1000
    assert bands[13] == pytest.approx(-3.01, abs=0.1)
    assert np.max(np.delete(bands, [12, 13, 14])) < -40
    assert seg["level_dbfs"] == pytest.approx(-3.01, abs=0.01)


def test_level_fluctuation_is_the_std_of_100_ms_levels():
    x = np.random.default_rng(2).standard_normal(5 * SR)
    frame = int(0.1 * SR)
    gain = np.where((np.arange(x.size) // frame) % 2 == 0, 1.0, 10 ** (12 / 20))   # alternate L, L + 12 dB
    seg = A.audio_statistics(x * gain, SR)["segments"][0]
    assert seg["level_fluctuation_db"] == pytest.approx(6.0, abs=0.2)


def test_roc_auc_and_balanced_accuracy_by_hand():
    y = np.array([0, 0, 1, 1])
    s = np.array([0.1, 0.4, 0.35, 0.8])
    assert A.roc_auc(y, s) == pytest.approx(0.75)            # pairs (pos > neg): 0.35>0.1, 0.8>0.1, 0.8>0.4
    assert A.balanced_accuracy(y, s) == pytest.approx(0.75)  # negatives 2/2 right, positives 1/2
    assert np.isnan(A.roc_auc(np.ones(3), np.arange(3.0)))


def test_synthetic_clips_are_deterministic_per_seed_and_labelled():
    cfg = {"duration_s": 1.0, "drone_kinds": ["quadcopter"], "drone_range_m": [[10.0, 20.0]]}
    a = A.synthetic_audio_clips(cfg, 3, 1)
    b = A.synthetic_audio_clips(cfg, 3, 1)
    c = A.synthetic_audio_clips(cfg, 4, 1)
    assert [k.cls for k in a] == ["DRONE", "HELICOPTER", "BACKGROUND"]     # the helicopter source exists
    assert {k.half for k in a} == {"synthetic"}
    for x, y, z in zip(a, b, c):
        assert x.samples.dtype == np.float32 and x.samples.size == SR and x.sample_rate == SR
        assert x.samples.tobytes() == y.samples.tobytes()
        assert x.samples.tobytes() != z.samples.tobytes()
        assert np.all(np.isfinite(x.samples)) and np.max(np.abs(x.samples)) > 0


@pytest.mark.parametrize("bad, field", [({"drone_range_m": [[50.0, 10.0]]}, "drone_range_m[0]"),
                                        ({"drone_kinds": ["zeppelin"]}, "drone_kinds"),
                                        ({"duration_s": -1}, "duration_s"), ({"colour": 1}, "colour"),
                                        ({"rotor_noise": {"colour": [1.0, 2.0]}}, "rotor_noise.colour"),
                                        ({"helicopter": {"tip_noise_db": [-6.0, -16.0]}}, "helicopter.tip_noise_db"),
                                        ({"drone_bpf_hz": [190.0, 150.0]}, "drone_bpf_hz"),
                                        ({"drone_bpf_hz": [0.0, 150.0]}, "drone_bpf_hz"),
                                        ({"resonance_count": {"PLANE": [0, 2]}}, "resonance_count"),
                                        ({"resonance_count": {"DRONE": [2, 0]}}, "resonance_count.DRONE"),
                                        ({"resonance_count": {"DRONE": [-1, 2]}}, "resonance_count.DRONE"),
                                        ({"resonance_hz": [8000.0, 150.0]}, "resonance_hz"),
                                        ({"resonance_hz": [0.0, 150.0]}, "resonance_hz"),
                                        ({"resonance_db": [14.0, 6.0]}, "resonance_db"),
                                        ({"resonance_q": [5.0, 1.5]}, "resonance_q"),
                                        ({"microphone": {"agc_detector": "rms"}}, "microphone.agc_detector")])
def test_bad_config_names_the_field(bad, field):
    with pytest.raises(UserInputError, match=field.replace("[", r"\[").replace("]", r"\]")):
        A.synthetic_audio_clips(bad, 0, 1)


def _mini_clip(cls: str, number: int, half: str, seconds: float = 2.0) -> A.AudioClip:
    rng = np.random.default_rng(number * 7 + len(half))
    noise = 0.02 * rng.standard_normal(int(seconds * SR))
    if cls == "DRONE":
        x = _tone(rng.uniform(150, 400), 8, seconds, 0.0, number) + noise
    elif cls == "HELICOPTER":
        t = np.arange(noise.size) / SR
        x = noise * (1 + 0.9 * np.sin(2 * np.pi * 20 * t)) + 0.05 * np.sin(2 * np.pi * 60 * t)
    else:
        x = noise
    return A.AudioClip(f"{cls}_{number:03d}", cls, number, x.astype(np.float32), SR, half)


def test_quick_track_runs_under_30_s_and_separates_easy_classes(tmp_path):
    real = [_mini_clip(cls, n, "calibration" if n % 2 else "evaluation") for cls in A.CLASSES for n in range(1, 7)]
    syn = [_mini_clip(cls, 100 + n, "synthetic") for cls in A.CLASSES for n in range(3)]
    start = time.process_time()              # CPU time: the shared test machine's load does not count
    summary = A.run_audio_track(real, syn, [0, 1, 2], True, tmp_path, False)
    assert time.process_time() - start < 30.0
    assert (tmp_path / "audio_spectrograms.png").read_bytes()[:4] == b"\x89PNG"
    for model in A.MODELS:
        res = summary["classifier"][model]
        assert set(A.CONDITIONS) <= set(res)
        assert res["a_real"]["roc_auc"] > 0.9                        # tones vs noise: trivially separable
        lo, hi = res["a_real"]["roc_auc_ci95"]
        assert lo <= hi <= 1.0
        assert 0.0 <= res["b_synthetic"]["helicopter_called_drone"] <= 1.0
        assert res["ratio_synthetic_over_real_auc"] == pytest.approx(res["b_synthetic"]["roc_auc"]
                                                                     / res["a_real"]["roc_auc"])
    drone = summary["statistics"]["DRONE"]["evaluation"]
    assert drone["f0_hz"]["real_q25"] >= 140 and drone["pitched"]["real_median"] == 1.0
    assert summary["statistics"]["BACKGROUND"]["evaluation"]["pitched"]["real_median"] == 0.0
    # the null reference: the real calibration half's medians against the evaluation half's IQRs
    for cls in A.CLASSES:
        pools = {h: A._pooled(A.audio_statistics(c.samples, c.sample_rate) for c in real
                              if c.cls == cls and c.half == h) for h in ("calibration", "evaluation")}
        expected = sum(v["inside_real_iqr"] for v in A.compare_statistics(pools["evaluation"],
                                                                          pools["calibration"]).values())
        counts = summary["statistics_inside_real_iqr"][cls]
        assert counts["calibration_inside"] == expected and 0 < expected <= counts["of"]


def test_read_wav_clips_splits_odd_and_even(tmp_path):
    import soundfile

    stereo = np.stack([np.full(SR // 2, 0.25), np.full(SR // 2, -0.05)], axis=1)
    for name in ("DRONE_001", "DRONE_002", "HELICOPTER_013", "notes_1"):
        soundfile.write(str(tmp_path / f"{name}.wav"), stereo, SR, subtype="PCM_16")
    clips = A.read_wav_clips(tmp_path)
    assert [(c.name, c.cls, c.number, c.half) for c in clips] == [
        ("DRONE_001", "DRONE", 1, "calibration"), ("DRONE_002", "DRONE", 2, "evaluation"),
        ("HELICOPTER_013", "HELICOPTER", 13, "calibration")]
    assert clips[0].samples.dtype == np.float32 and np.allclose(clips[0].samples, 0.1, atol=1e-4)   # stereo mean


def test_clip_count_from_config_and_quick():
    cfg = {"duration_s": 1.0, "n_per_class": 2, "quick_n_per_class": 1, "drone_range_m": [[10.0, 20.0]]}
    assert len(A.synthetic_audio_clips(cfg, 0, quick=True)) == 3
    assert [c.number for c in A.synthetic_audio_clips(cfg, 0) if c.cls == "DRONE"] == [1, 2]


def test_real_audio_clips_from_a_benchmark_reader():
    class Clip:
        def __init__(self, cls, number):
            self.cls, self.number, self.name = cls, number, f"{cls}_{number:03d}"
            self.half = "calibration" if number % 2 else "evaluation"

    class Bench:
        def clips(self, sensor):
            assert sensor == "audio"
            return [Clip("DRONE", 1), Clip("BACKGROUND", 4)]

        def audio(self, clip):
            return np.full(SR, 0.5 if clip.cls == "DRONE" else 0.1, dtype=np.float32), SR

    clips = A.real_audio_clips(Bench())
    assert [(c.name, c.cls, c.half, round(float(c.samples[0]), 6)) for c in clips] == [
        ("DRONE_001", "DRONE", "calibration", 0.5), ("BACKGROUND_004", "BACKGROUND", "evaluation", 0.1)]


def test_audio_only_protocol_renders_no_video(tmp_path):
    pytest.importorskip("mcos_decoder")
    pytest.importorskip("av")
    import subprocess
    import sys

    from harness.experiments.sim2real.config import DEFAULT_CONFIG
    from tests.simulator.formats.svanstrom_miniature import write_miniature

    real = write_miniature(tmp_path / "real", numbers=(1, 2, 3, 4), n_frames=4, ir_size=(64, 48),
                           visible_size=(96, 80), audio_s=2.0)
    text = DEFAULT_CONFIG.read_text().replace("sensors: [ir, visible, audio]", "sensors: [audio]")
    assert "sensors: [audio]" in text
    config = tmp_path / "audio_only.yaml"          # its scenario paths are never opened: no video classes run
    config.write_text(text)
    proc = subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", "sim2real", "--real",
                           str(real), "--config", str(config), "--out", str(tmp_path / "run"), "--quick",
                           "--no-progress"], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert not (tmp_path / "run" / "synthetic").exists()                   # no video rendered
    summary = json.loads((tmp_path / "run" / "sim2real.json").read_text())
    assert list(summary["sensors"]) == ["audio"] and summary["sensors"]["audio"]["n_clips"]["evaluation"] > 0


def test_source_spans_reach_only_their_own_class():
    """The config's helicopter spans change the helicopter clip only, its rotor-noise spans the drone clip only."""
    cfg = {"duration_s": 1.0, "drone_range_m": [[10.0, 20.0]]}
    fitted = A.synthetic_audio_clips(cfg, 3, 1)                                 # the sim2real helicopter spans
    module = A.synthetic_audio_clips({**cfg, "helicopter": {}}, 3, 1)           # acoustics.HELICOPTER_RANGES
    low_edge = A.synthetic_audio_clips({**cfg, "rotor_noise": {"broadband_low_hz": [30.0, 120.0]}}, 3, 1)
    same = [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(fitted, module)]
    assert same == [True, False, True]                                          # DRONE, HELICOPTER, BACKGROUND
    same = [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(fitted, low_edge)]
    assert same == [False, True, True]


def test_drone_bpf_span_retunes_the_drone_clip_only():
    """``drone_bpf_hz`` puts the drone clip's blade-passing line where it is drawn and leaves the other
    classes byte-identical; None keeps the simulator's size law."""
    base = {"duration_s": 2.0, "drone_range_m": [[5.0, 6.0]], "ambience": {"wind_db": [5.0, 5.0]},
            "drone_rpm_wander": None,
            "rotor_noise": {"broadband_offset_db": [-15.0, -15.0], "harmonic_top_hz": [600.0, 600.0]}}
    peaks = {}
    clips = {}
    for bpf in (None, 150.0, 230.0):
        cfg = {**base, "drone_bpf_hz": None if bpf is None else [bpf, bpf]}
        clips[bpf] = A.synthetic_audio_clips(cfg, 5, 1)
        x = clips[bpf][0].samples.astype(np.float64)
        spec = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
        f = np.fft.rfftfreq(x.size, 1.0 / SR)
        band = (f > 120) & (f < 260)
        peaks[bpf] = f[band][np.argmax(spec[band])]
    assert peaks[150.0] == pytest.approx(150.0, rel=0.04)
    assert peaks[230.0] == pytest.approx(230.0, rel=0.04)
    assert abs(peaks[None] - 150.0) > 10 and abs(peaks[None] - 230.0) > 10     # the size law puts it elsewhere
    for other in (150.0, 230.0):
        same = [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(clips[None], clips[other])]
        assert same == [False, True, True]                                       # DRONE, HELICOPTER, BACKGROUND


def test_drone_rpm_wander_moves_all_rotors_together_and_nothing_when_off():
    from simulator.physics.timeline import build_timeline

    cfg = A.synthetic_audio_config({"duration_s": 20.0, "drone_bpf_hz": [170.0, 170.0],
                                    "drone_rpm_wander": [0.05, 0.05], "drone_rpm_wander_time_s": [0.5, 0.5]})
    rng = np.random.default_rng(0)
    scenario, _ = A._drone_scenario(cfg, rng, "d")
    timeline = build_timeline(scenario, 1)
    tuned = A._retuned(cfg, timeline, np.random.default_rng(1)).targets[0]
    bpf = tuned.rotor_rpm.mean(axis=1) * tuned.n_blades / 60.0
    assert np.median(bpf) == pytest.approx(170.0, rel=0.03)
    assert 0.03 < np.std(bpf / np.median(bpf)) < 0.07                     # the drawn 5 % wander (plus attitude)
    off = A.synthetic_audio_config({"duration_s": 20.0, "drone_bpf_hz": None, "drone_rpm_wander": None})
    assert A._retuned(off, timeline, np.random.default_rng(1)) is timeline
    still = A._retuned(A.synthetic_audio_config({"duration_s": 20.0, "drone_bpf_hz": [170.0, 170.0],
                                                "drone_rpm_wander": None}), timeline,
                       np.random.default_rng(1)).targets[0]
    assert np.std(still.rotor_rpm.mean(axis=1)) / np.mean(still.rotor_rpm) < 0.01    # no wander without the field


def test_machinery_bed_reaches_every_class_and_nothing_when_off():
    """``machinery`` adds the tonal bed to the clips of every class (one distribution: no class cue); None
    or probability 0 leaves every clip byte-identical to the clips without it."""
    cfg = {"duration_s": 2.0, "drone_range_m": [[10.0, 20.0]]}
    off = A.synthetic_audio_clips({**cfg, "machinery": None}, 3, 1)
    never = A.synthetic_audio_clips({**cfg, "machinery": {"probability": 0.0}}, 3, 1)
    hum = A.synthetic_audio_clips({**cfg, "machinery": {"probability": 1.0, "mains_probability": 1.0,
                                                        "mains_harmonics": [1, 1], "level_db": [70.0, 70.0]}}, 3, 1)
    assert [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(off, never)] == [True, True, True]
    assert [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(off, hum)] == [False, False, False]
    x = hum[2].samples.astype(np.float64)                                  # the background clip
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    f = np.fft.rfftfreq(x.size, 1.0 / SR)
    band = (f > 30) & (f < 300)
    assert f[band][np.argmax(spec[band])] == pytest.approx(50.0, abs=1.0)


def test_mic_wind_reaches_the_named_classes_at_its_drawn_level():
    """``mic_wind_probability`` adds gusty flow noise to the clips of the classes it names; 0 or an unnamed class
    draws nothing (those clips byte-identical); the bed's level is the clip mix's level plus the drawn offset; on
    or off, the same three draws; an unknown class or a gust depth over 1 is refused naming the field."""
    cfg = {"duration_s": 2.0, "drone_range_m": [[10.0, 20.0]]}
    off = A.synthetic_audio_clips({**cfg, "mic_wind_probability": {}}, 3, 1)
    shipped = A.synthetic_audio_clips(cfg, 3, 1)                              # the default: drones only
    assert [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(off, shipped)][1:] == [True, True]
    never = A.synthetic_audio_clips({**cfg, "mic_wind_probability": {"DRONE": 0.0}, "mic_wind_db": [5.0, 5.0]}, 3, 1)
    windy = A.synthetic_audio_clips({**cfg, "mic_wind_probability": {"DRONE": 1.0}, "mic_wind_db": [5.0, 5.0]}, 3, 1)
    both = A.synthetic_audio_clips({**cfg, "mic_wind_probability": {"DRONE": 1.0, "BACKGROUND": 1.0},
                                    "mic_wind_db": [5.0, 5.0]}, 3, 1)
    assert [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(off, never)] == [True, True, True]
    assert [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(off, windy)] == [False, True, True]
    assert [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(windy, both)] == [True, True, False]

    def band_db(x, lo, hi):
        spec = np.abs(np.fft.rfft(x.astype(np.float64))) ** 2
        f = np.fft.rfftfreq(x.size, 1.0 / SR)
        return 10 * np.log10(spec[(f >= lo) & (f < hi)].sum())

    # the recorder's AGC takes the total back to its target, so the wind shows as low-frequency share
    lf_share = lambda clip: band_db(clip.samples, 30, 90) - band_db(clip.samples, 1000, 4000)   # noqa: E731
    assert lf_share(windy[0]) - lf_share(off[0]) > 10.0
    mix = np.random.default_rng(0).standard_normal(2 * SR) * _pa(70.0)
    conf = A.synthetic_audio_config({"mic_wind_probability": {"DRONE": 1.0}, "mic_wind_db": [-6.0, -6.0]})
    wind = A._mic_wind(conf, "DRONE", np.random.default_rng(1), mix, 9, mix.size, SR)
    assert 20 * np.log10(np.sqrt(np.mean(wind ** 2)) / np.sqrt(np.mean(mix ** 2))) == pytest.approx(-6.0, abs=0.01)
    calm = A.synthetic_audio_config({"mic_wind_probability": {"DRONE": 1e-12}})
    a, b = np.random.default_rng(2), np.random.default_rng(2)
    assert not np.any(A._mic_wind(calm, "DRONE", a, mix, 9, mix.size, SR))
    A._mic_wind(conf, "DRONE", b, mix, 9, mix.size, SR)
    assert a.random() == b.random()
    with pytest.raises(UserInputError, match="mic_wind_gust_depth"):
        A.synthetic_audio_config({"mic_wind_gust_depth": [0.5, 1.5]})
    with pytest.raises(UserInputError, match="mic_wind_probability"):
        A.synthetic_audio_config({"mic_wind_probability": {"BIRD": 0.5}})


def test_background_only_beds_reach_only_the_background_clips():
    """``background_ambience`` and the background beds (flat broadband, high-frequency calls) change only the
    BACKGROUND clips (drone and helicopter byte-identical); probability 0 / None leaves every clip
    byte-identical; the broadband bed lands at its drawn level inside its band; a reversed span is refused."""
    cfg = {"duration_s": 2.0, "drone_range_m": [[10.0, 20.0]]}
    off = A.synthetic_audio_clips(cfg, 3, 1)
    never = A.synthetic_audio_clips({**cfg, "background_broadband_probability": 0.0,
                                     "background_insect_probability": 0.0, "background_ambience": None}, 3, 1)
    assert [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(off, never)] == [True, True, True]
    for extra in ({"background_broadband_probability": 1.0}, {"background_insect_probability": 1.0},
                  {"background_ambience": {"birdsong_probability": 0.25, "wind_db": [12.0, 30.0]}}):
        on = A.synthetic_audio_clips({**cfg, **extra}, 3, 1)
        assert [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(off, on)] == [True, True, False], extra
    conf = A.synthetic_audio_config({"background_broadband_probability": 1.0, "background_broadband_db": [60.0, 60.0],
                                     "background_broadband_band_hz": [500.0, 2000.0],
                                     "background_broadband_tilt_db": [0.0, 0.0]})
    bed = A._background_beds(conf, np.random.default_rng(1), 9, 2 * SR, SR)
    assert 20 * np.log10(np.sqrt(np.mean(bed ** 2)) / _pa(60.0)) == pytest.approx(0.0, abs=0.01)
    spec = np.abs(np.fft.rfft(bed)) ** 2
    f = np.fft.rfftfreq(bed.size, 1.0 / SR)
    assert spec[(f > 400) & (f < 2500)].sum() / spec.sum() > 0.85
    a, b = np.random.default_rng(2), np.random.default_rng(2)      # on or off, the same draws
    A._background_beds(conf, a, 9, 2 * SR, SR)
    A._background_beds(A.synthetic_audio_config({"background_broadband_probability": 1e-12}), b, 9, 2 * SR, SR)
    assert a.random() == b.random()
    with pytest.raises(UserInputError, match="background_broadband_band_hz"):
        A.synthetic_audio_config({"background_broadband_band_hz": [6000.0, 100.0]})


# sha256 of the samples of the clips below (seed 3, one per class, 2 s) on main 9ef1f81, before the
# resonances existed: with the module's bed shapes (``ambience_shapes: {}``) every class's clip is kept byte
# for byte (the default shapes are the twelfth pass's fit: the test below)
MAIN_2S_SHA256 = ("c8a1b39eaf7d5293b67761888bfeec7119991ba270472d283ff2b49498abca2e",
                  "78f9ecedb9822e0dc5c91859f93e4d02f0eac32c49edb040b0d764ee02578ac9",
                  "6fe30d997efdc94e354bbb0dcf8ac65d73891cfd3531e65271fcd3fc6d675924")


def test_resonances_off_by_default_and_reach_only_the_listed_classes():
    """``resonance_count`` {} (default) leaves every clip byte-identical to main's (sha256, with the module's bed
    shapes); listing a class changes that class's clip only (its own acoustics stream, drawn after everything
    else), its RMS kept before the recorder; a listed class with count 0 is unchanged."""
    import hashlib

    # the recorder and microphone wind of main 9ef1f81 (the peak-detector AGC until the fourteenth session)
    cfg = {"duration_s": 2.0, "drone_range_m": [[10.0, 20.0]], "ambience_shapes": {}, "mic_wind_db": [-6.0, 4.0],
           "microphone": {"agc_target_dbfs": [-28.0, -20.0], "presence_hz": [4000.0, 10000.0]}}
    off = A.synthetic_audio_clips(cfg, 3, 1)
    assert tuple(hashlib.sha256(c.samples.tobytes()).hexdigest() for c in off) == MAIN_2S_SHA256
    spans = {"resonance_hz": [150.0, 8000.0], "resonance_db": [6.0, 14.0], "resonance_q": [1.5, 5.0]}
    for counts, changed in (({"DRONE": [2, 2], "BACKGROUND": [1, 2]}, [True, False, True]),
                            ({"HELICOPTER": [1, 1]}, [False, True, False]),
                            ({"DRONE": [0, 0]}, [False, False, False])):
        on = A.synthetic_audio_clips({**cfg, **spans, "resonance_count": counts}, 3, 1)
        assert [x.samples.tobytes() != y.samples.tobytes() for x, y in zip(off, on)] == changed, counts
    conf = A.synthetic_audio_config({**spans, "resonance_count": {"DRONE": [2, 2]}})
    mix = np.random.default_rng(5).standard_normal(SR)
    out = A._resonances(conf, "DRONE", mix, 9, SR)
    assert np.sqrt(np.mean(out ** 2)) == pytest.approx(np.sqrt(np.mean(mix ** 2)), rel=1e-12)
    assert not np.allclose(out, mix)
    assert A._resonances(conf, "BACKGROUND", mix, 9, SR) is mix


def test_default_bed_shapes_are_the_fit_and_reach_the_clips_with_traffic():
    """The default ``ambience_shapes`` is the twelfth pass's fit (traffic 100 Hz-5 kHz at -5.5 dB/octave, the
    residual bed the module's); it reaches exactly the clips of any class that draw the traffic bed (the
    ambience is shared), deterministically; the module's shapes give main's samples back (the pinned sha256
    above; the beds take the same draws whatever their shape: tests/simulator/physics/acoustics/test_ambience.py)."""
    from simulator.physics.acoustics import BedShapes

    conf = A.synthetic_audio_config({})
    assert conf.ambience_shapes == BedShapes(traffic_band_hz=(100.0, 5000.0), traffic_tilt_db=-5.5)
    assert A.synthetic_audio_config({"ambience_shapes": {}}).ambience_shapes == BedShapes()
    from simulator.physics.acoustics import AmbienceDistribution, draw_ambience
    from simulator.seeding import rng_for

    cfg = {"duration_s": 2.0, "drone_range_m": [[10.0, 20.0]]}
    fit, again = A.synthetic_audio_clips(cfg, 3, 1), A.synthetic_audio_clips(cfg, 3, 1)
    module = A.synthetic_audio_clips({**cfg, "ambience_shapes": {}}, 3, 1)
    assert [x.samples.tobytes() == y.samples.tobytes() for x, y in zip(fit, again)] == [True, True, True]
    traffic = []                                     # which of these clips drew the traffic bed
    for k in range(3):
        rng = rng_for(3, "generation", A._SYNTH_TAG, k, 0)
        rng.integers(0, 2 ** 31 - 1)
        traffic.append(draw_ambience(rng, AmbienceDistribution()).traffic_db is not None)
    assert traffic == [False, True, False]
    assert [x.samples.tobytes() != y.samples.tobytes() for x, y in zip(fit, module)] == traffic
    always = {**cfg, "ambience": {"traffic_probability": 1.0}}       # the same draws, the bed on in every clip
    fit = A.synthetic_audio_clips(always, 3, 1)
    module = A.synthetic_audio_clips({**always, "ambience_shapes": {}}, 3, 1)
    assert [x.samples.tobytes() != y.samples.tobytes() for x, y in zip(fit, module)] == [True, True, True]
    with pytest.raises(UserInputError, match="ambience_shapes"):
        A.synthetic_audio_config({"ambience_shapes": {"residual_tilt_db": [-3.0, -6.0]}})


def _pa(level_db: float) -> float:
    from simulator.physics.acoustics import db_spl_to_pa

    return db_spl_to_pa(level_db)
