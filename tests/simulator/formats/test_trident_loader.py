"""TRIDENT: round trip of a tiny generated clip, the public layout (export and a hand-written miniature),
the `mfcc: trident` pipeline against the public formula, SigMF beside the I/Q, and corrupt clips."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.dataset import trident as tr
from simulator.formats.trident import LABELS, TridentDataset, discover_clips


def _frames(n: int, px: int = 112) -> np.ndarray:
    """Frame i is a flat grey of level 8 * i (survives JPEG), so segment alignment is checkable."""
    return np.broadcast_to((np.arange(n, dtype=np.uint8) * 8)[:, None, None, None], (n, px, px, 3)).copy()


@pytest.fixture
def tiny_trident(tmp_path):
    """A tiny TRIDENT-layout folder: one 1 s drone clip (4 segments) written by the generator, no rendering."""
    cfg = tr.load_trident_config({
        "name": "tiny", "clip_duration_s": 1.0, "rf": {"capture_samples": 112 * 40},
        "clips": [{"scenario": {"name": "hover", "duration_s": 1.0,
                                "targets": [{"name": "d", "kind": "quadcopter", "size_m": 0.45,
                                             "trajectory": {"kind": "hover", "center_m": [0, 60, 15]}}],
                                "camera_rig": {"position_m": [0, 0, 1.5], "look_at_m": [0, 60, 15]}}}]})
    scen = tr.clip_scenario(tr.resolve_scenario(cfg.clips[0]), cfg)
    clip = tr.synthesize_clip(scen, 9, cfg, frames=_frames(28))
    tr.write_clip(tmp_path, "hover", 1, clip, cfg, {"seed": 9})
    return tmp_path, clip


def test_round_trip_of_a_generated_clip(tiny_trident):
    root, clip = tiny_trident
    ds = TridentDataset(root)
    assert len(ds) == 4 and [c.clip_id for c in ds.clips] == ["Drone/hover/1"]
    segs = list(ds)
    assert [s.segment_index for s in segs] == [0, 1, 2, 3]
    for s, seg in enumerate(segs):
        assert seg.label == LABELS.index("Drone") == 0 and seg.clip_id == "Drone/hover/1"
        assert (seg.audio_mfcc.shape == (1, 40, 40) and seg.video.shape == (7, 112, 112, 3)
                and seg.rf.shape == (112, 112))
        assert np.allclose(seg.audio_mfcc, clip.mfcc[s], atol=1e-4)           # same WAV values -> same MFCC
        assert np.array_equal(np.round(seg.rf * 255).astype(np.uint8), clip.rf_images[s])   # PNG is lossless
        levels = seg.video.reshape(7, -1).mean(axis=1)
        assert np.allclose(levels, 8 * np.arange(7 * s, 7 * s + 7), atol=2)   # frames 7s..7s+6, in order
        assert seg.observability == {"video": bool(clip.truth.video_visible[s]),
                                     "audio": bool(clip.truth.audio_audible[s]),
                                     "rf": bool(clip.truth.rf_observable[s])}
    again = ds[2]
    assert np.array_equal(again.audio_mfcc, segs[2].audio_mfcc)


def test_public_layout_variants(tmp_path):
    """Real-TRIDENT style: 16-bit WAV, 1-based frames at another size, colour RF JPEGs, no labels/."""
    import cv2
    import soundfile

    for label, n in (("Drone", "7"), ("Background", "3")):
        for sub in ("audio", "video", "rf"):
            (tmp_path / sub / label / "site_a").mkdir(parents=True)
        t = np.arange(44100) / 44100
        soundfile.write(str(tmp_path / "audio" / label / "site_a" / f"{n}.wav"), 0.3 * np.sin(2 * np.pi * 300 * t),
                        44100, subtype="PCM_16")
        for i in range(1, 30):                                   # 29 frames -> 4 full segments
            img = np.full((224, 224, 3), 8 * (i - 1), np.uint8)
            cv2.imwrite(str(tmp_path / "video" / label / "site_a" / f"{n}_frame_{i}.jpg"), img)
        for s in range(5):                                       # one more RF image than needed
            cv2.imwrite(str(tmp_path / "rf" / label / "site_a" / f"{n}_spec_{s}.jpg"),
                        np.full((112, 112, 3), 40 * s, np.uint8))
    # a clip present in audio only is skipped
    soundfile.write(str(tmp_path / "audio" / "Drone" / "site_a" / "99.wav"), np.zeros(44100), 44100)
    ds = TridentDataset(tmp_path)
    assert [c.clip_id for c in ds.clips] == ["Drone/site_a/7", "Background/site_a/3"]
    assert len(ds) == 8                                          # S = 4 audio segments; 29 >= 28 frames, 5 >= 4 rf
    seg = ds[5]
    assert seg.label == 1 and seg.clip_id == "Background/site_a/3" and seg.segment_index == 1
    assert seg.video.shape == (7, 112, 112, 3) and seg.rf.shape == (112, 112, 3)
    assert np.allclose(seg.video.reshape(7, -1).mean(axis=1), 8 * np.arange(7, 14), atol=2)
    assert np.allclose(seg.rf, 40 / 255, atol=2 / 255)
    assert seg.observability is None


def test_missing_modality_root_is_reported(tmp_path):
    (tmp_path / "audio").mkdir()
    with pytest.raises(ValueError, match="video"):
        discover_clips(tmp_path)


# --------------------------------------------------------------------------------------------
# The public layout, mfcc: trident, SigMF
# --------------------------------------------------------------------------------------------

def _public_formula(path, n_segments):
    """The public DroneFusionDataset.__getitem__ audio path, re-computed here from its description."""
    import librosa

    out = []
    for k in range(n_segments):
        waveform, sr = librosa.load(str(path), sr=44100, offset=k * 0.25, duration=0.25)
        waveform = np.asfortranarray(waveform[::3])
        mfcc = librosa.feature.mfcc(y=waveform, sr=sr, n_mfcc=40, n_fft=2048, hop_length=512)
        mfcc = np.pad(mfcc, pad_width=((0, 0), (0, max(0, 40 - mfcc.shape[1]))), mode="constant")
        out.append(np.float32(mfcc)[None])
    return np.stack(out)


def test_mfcc_trident_equals_the_public_formula_bit_for_bit(tmp_path):
    import soundfile

    from simulator.formats.trident import mfcc_segments, mfcc_trident

    t = np.arange(44100) / 44100
    rng = np.random.default_rng(np.random.SeedSequence([3, 14]))
    signal = 0.2 * np.sin(2 * np.pi * 440 * t) + 0.01 * rng.standard_normal(t.size)
    soundfile.write(str(tmp_path / "1.wav"), signal, 44100, subtype="PCM_16")
    ours = mfcc_trident(tmp_path / "1.wav", 4)
    assert ours.shape == (4, 1, 40, 40) and ours.dtype == np.float32
    assert np.array_equal(ours, _public_formula(tmp_path / "1.wav", 4))
    # 3675 decimated samples, hop 512, centred: 1 + 3675 // 512 = 8 real columns, the rest zero padding
    assert (np.abs(ours[0, 0]).sum(axis=0) > 0).sum() == 8 and not ours[0, 0, :, 8:].any()
    correct = mfcc_segments(signal.astype(np.float32), 44100.0, 4)
    assert (np.abs(correct[0, 0]).sum(axis=0) > 0).sum() == 40          # the default uses all 40 frames


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """A generated TRIDENT dataset: 3 drone clips + 2 background clips of 1 s (4 segments), no rendering."""
    base = tmp_path_factory.mktemp("gen")

    def frames(scenario, seed, n, w, h, layout=None):
        return _frames(n, w)

    hover = {"name": "d", "kind": "quadcopter", "size_m": 0.45,
             "trajectory": {"kind": "hover", "center_m": [0, 60, 15]}}
    bird = {"name": "b", "kind": "bird", "size_m": 0.4, "trajectory": {"kind": "hover", "center_m": [0, 50, 15]}}
    rig = {"position_m": [0, 0, 1.5], "look_at_m": [0, 60, 15]}
    cfg = tr.load_trident_config({
        "name": "tiny", "clip_duration_s": 1.0, "save_iq": True, "rf": {"capture_samples": 112 * 40},
        "clips": [{"scenario": {"name": "quad", "duration_s": 1.0, "targets": [hover], "camera_rig": rig}, "count": 3},
                  {"scenario": {"name": "birds", "duration_s": 1.0, "targets": [bird], "camera_rig": rig},
                   "count": 2}]})
    return tr.generate_trident(cfg, base / "ds", 4, progress=False, render_frames=frames)


def test_sigmf_meta_beside_the_saved_iq(generated):
    from simulator.formats.sigmf import read_sigmf

    npy = generated / "rf_iq" / "Drone" / "quad" / "1.npy"
    iq, meta = read_sigmf(npy.with_suffix(".sigmf-meta"))
    assert np.array_equal(iq, np.load(npy)) and iq.shape == (4, 112 * 40)
    assert meta["global"]["core:datatype"] == "cf32_le" and meta["global"]["core:dataset"] == "1.npy"
    assert meta["global"]["core:sample_rate"] == 20e6 and len(meta["captures"]) == 4
    assert [a["core:label"] for a in meta["annotations"]] == ["Drone"] * 4


def test_export_public_layout_and_read_it_back(generated, tmp_path):
    import cv2

    from simulator.dataset.exporters import export_dataset
    from simulator.formats.sigmf import read_sigmf

    out = export_dataset(generated, "trident", tmp_path / "pub", mfcc="trident", test_fraction=0.4, progress=False)
    names = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    # per label, clip j is Test when floor((j+1) f + 1/2) > floor(j f + 1/2): f = 0.4 -> j = 1, i.e. drone
    # clip 2 (of 1, 2, 3) and background clip 5 (of 4, 5)
    audio = sorted(n for n in names if n.startswith("Audio/"))
    assert audio == ["Audio/Test/Background/birds/5.wav", "Audio/Test/Drone/quad/2.wav",
                     "Audio/Train/Background/birds/4.wav", "Audio/Train/Drone/quad/1.wav",
                     "Audio/Train/Drone/quad/3.wav"]
    assert "Video/Test/Drone/quad/Images/2_frame_1.jpg" in names and ("Video/Test/Drone/quad/Images/"
                                                                      "2_frame_28.jpg") in names
    assert "Video/Train/Drone/quad/Images_Extracted/1_frame_28.jpg" in names
    assert "Video/Train/Drone/quad/Images_Extracted/1_frame_0.jpg" not in names
    assert "Video/Train/Drone/quad/Images_Extracted/1_frame_29.jpg" not in names
    assert "RF_Spectrograms/Train/Drone/quad/Images_Spectrograms/1_frame_1.jpg" in names
    assert "RF_Spectrograms/Test/Drone/quad/Images/2_frame_4.jpg" in names
    assert {"Labels/Train/Drone/quad/1.json", "RF_IQ/Train/Drone/quad/1.sigmf-data", "manifest.json"} <= names
    assert not any(n.endswith(".png") for n in names)
    img = cv2.imread(str(out / "RF_Spectrograms/Test/Drone/quad/Images/2_frame_1.jpg"))
    assert img is not None and img.shape[:2] == (112, 112)
    iq, _ = read_sigmf(out / "RF_IQ/Train/Drone/quad/1.sigmf-meta")
    assert np.array_equal(iq, np.load(generated / "rf_iq/Drone/quad/1.npy"))

    src = TridentDataset(generated)
    pub = TridentDataset(out)
    assert pub.mfcc_pipeline == "trident" and src.mfcc_pipeline == "evids"
    assert sorted(c.clip_id.split("/", 1)[1] for c in pub.clips) == sorted(c.clip_id for c in src.clips)
    by_id = {c.clip_id: c for c in src.clips}
    for clip in pub.clips:
        twin = by_id[clip.clip_id.split("/", 1)[1]]
        assert clip.n_segments == twin.n_segments == 4
        for a, b in zip(pub.iter_clip(clip), src.iter_clip(twin)):
            assert np.array_equal(a.video, b.video)                       # JPEG bytes copied
            assert np.abs(a.rf - b.rf).max() < 0.1                       # PNG -> JPEG re-encoded
            assert a.observability == b.observability and a.label == b.label
            assert (np.abs(a.audio_mfcc[0]).sum(axis=0) > 0).sum() == 8   # the public pipeline, recorded
        direct = _public_formula(clip.audio, 4)
        assert np.array_equal(np.stack([s.audio_mfcc for s in pub.iter_clip(clip)]), direct)
    assert TridentDataset(out, mfcc="evids").mfcc_pipeline == "evids"


def _miniature_public(root, n_segments=40, label="Drone", scenario="1", number="1", split="Train"):
    """The public TRIDENT layout written from its description: 10 s WAV, 280 frames, 40 RF JPEGs."""
    import cv2
    import soundfile

    sub = {"Train": ("Images_Extracted", "Images_Spectrograms"), "Test": ("Images", "Images")}[split]
    audio = root / "Audio" / split / label / scenario
    video = root / "Video" / split / label / scenario / sub[0]
    rf = root / "RF_Spectrograms" / split / label / scenario / sub[1]
    for d in (audio, video, rf):
        d.mkdir(parents=True, exist_ok=True)
    t = np.arange(int(n_segments * 0.25 * 44100)) / 44100
    soundfile.write(str(audio / f"{number}.wav"), 0.1 * np.sin(2 * np.pi * 500 * t), 44100, subtype="PCM_16")
    for i in range(1, 7 * n_segments + 1):
        cv2.imwrite(str(video / f"{number}_frame_{i}.jpg"), np.full((16, 16, 3), i % 250, np.uint8))
    for j in range(1, n_segments + 1):
        cv2.imwrite(str(rf / f"{number}_frame_{j}.jpg"), np.full((16, 32, 3), 6 * j, np.uint8))
    return audio / f"{number}.wav", video, rf


def test_hand_written_public_miniature(tmp_path):
    _miniature_public(tmp_path, label="Drone", scenario="2")
    _miniature_public(tmp_path, label="Background", scenario="10", number="5", split="Test")
    ds = TridentDataset(tmp_path)
    assert [c.clip_id for c in ds.clips] == ["Train/Drone/2/1", "Test/Background/10/5"]
    assert len(ds) == 80                                           # 40 segments each (the public fixed 10 s)
    seg = ds[41]
    assert seg.label == 1 and seg.segment_index == 1 and seg.video.shape == (7, 112, 112, 3)
    assert np.allclose(seg.video.reshape(7, -1).mean(axis=1), np.arange(8, 15), atol=2)   # frames 8..14
    assert seg.rf.shape == (112, 112, 3) and np.allclose(seg.rf, 12 / 255, atol=2 / 255)  # RF image 2


CORRUPTIONS = [
    ("missing video frame", lambda wav, video, rf: (video / "1_frame_100.jpg").unlink(), "index 100 is missing"),
    ("missing RF image", lambda wav, video, rf: (rf / "1_frame_7.jpg").unlink(), "index 7 is missing"),
    ("last RF image missing", lambda wav, video, rf: (rf / "1_frame_40.jpg").unlink(),
     "39 files but the clip needs 40"),
    ("truncated WAV", lambda wav, video, rf: wav.write_bytes(wav.read_bytes()[: len(wav.read_bytes()) // 2]),
     "truncated WAV"),
    ("garbage WAV", lambda wav, video, rf: wav.write_bytes(b"RIFF0000WAVEjunk"), "not a readable WAV"),
    ("no RF images", lambda wav, video, rf: [p.unlink() for p in rf.glob("1_frame_*")], "no RF spectrogram images"),
]


@pytest.mark.parametrize("name,corrupt,message", CORRUPTIONS, ids=[c[0] for c in CORRUPTIONS])
def test_corrupt_public_clip_is_refused_naming_the_file(tmp_path, name, corrupt, message):
    from simulator.formats.validation import FormatError, SkippedRowsWarning

    wav, video, rf = _miniature_public(tmp_path)
    _miniature_public(tmp_path, number="2")                          # an intact neighbour
    corrupt(wav, video, rf)
    with pytest.raises(FormatError, match=message) as err:
        TridentDataset(tmp_path)
    assert str(tmp_path) in str(err.value)
    with pytest.warns(SkippedRowsWarning, match="skipped 1 bad clip"):
        ds = TridentDataset(tmp_path, strict=False)
    assert [c.number for c in ds.clips] == ["2"] and len(ds.skipped) == 1 and len(ds) == 40


def test_generated_clip_missing_a_frame_is_refused(generated, tmp_path):
    import shutil

    from simulator.formats.validation import FormatError

    copy = tmp_path / "copy"
    shutil.copytree(generated, copy)
    (copy / "video" / "Drone" / "quad" / "2_frame_10.jpg").unlink()
    with pytest.raises(FormatError, match="2_frame_11.jpg"):
        TridentDataset(copy)
    (copy / "video" / "Drone" / "quad").rename(copy / "video" / "Drone" / "gone")
    with pytest.raises(FormatError, match="no video frames"):
        TridentDataset(copy)


def test_webdataset_of_a_clip_set(generated, tmp_path):
    from simulator.dataset.exporters import export_dataset
    from simulator.formats import webdataset as wdsfmt

    out = export_dataset(generated, "webdataset", tmp_path / "wds", mfcc="trident", progress=False)
    samples = list(wdsfmt.iter_samples(wdsfmt.shards(out, "all")))
    ds = TridentDataset(generated, mfcc="trident")
    segs = list(ds)
    assert len(samples) == len(segs) == 20
    for sample, seg in zip(samples, segs):
        assert sample["__key__"] == f"{seg.clip_id.replace('/', '_')}_{seg.segment_index:02d}"
        assert np.array_equal(np.load(__import__("io").BytesIO(sample["mfcc.npy"])), seg.audio_mfcc)
        assert sample["json"]["mfcc"] == "trident" and sample["json"]["label_id"] == seg.label
        assert sample["json"]["observability"] == seg.observability
        assert sorted(k for k in sample if k.startswith("frame")) == [f"frame{k}.jpg" for k in range(7)]
    with pytest.raises(Exception, match="exports to trident, webdataset only"):
        export_dataset(generated, "mot", tmp_path / "mot", progress=False)


@pytest.mark.parametrize("labels,message", [
    ("{not json", "not valid JSON"),
    ("[1, 2]", "segments.drone_present"),
    ('{"segments": {"drone_present": 3}}', "segments.drone_present"),
    ('{"segments": {"drone_present": [1, 1, 1, 1], "video_visible": 5}}', "needs video_visible"),
])
def test_corrupt_labels_json(generated, tmp_path, labels, message):
    import shutil

    from simulator.formats.validation import FormatError

    copy = tmp_path / "copy"
    shutil.copytree(generated, copy)
    (copy / "labels" / "Drone" / "quad" / "1.json").write_text(labels)
    with pytest.raises(FormatError, match=message):
        list(TridentDataset(copy))


def test_load_iq_from_both_layouts(generated, tmp_path):
    from simulator.dataset.exporters import export_dataset
    from simulator.formats.trident import load_iq

    out = export_dataset(generated, "trident", tmp_path / "pub", progress=False)
    src = {c.clip_id: c for c in TridentDataset(generated).clips}
    for clip in TridentDataset(out).clips:
        twin = src[clip.clip_id.split("/", 1)[1]]
        assert clip.iq.name.endswith(".sigmf-meta") and twin.iq.suffix == ".npy"
        assert np.array_equal(load_iq(clip), load_iq(twin)) and load_iq(clip).shape == (4, 112 * 40)
