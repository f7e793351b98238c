"""Render one scenario into the native layout (and optionally the Anti-UAV layout and a preview)."""
from __future__ import annotations

import json
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from scenes.loader import scenario_to_yaml
from scenes.schema import Scenario
from simulator.files import atomic_folder, package_versions, write_hashes
from simulator.formats.native import FORMAT_VERSION, frame_name, write_json, write_png
from simulator.physics.timeline import Timeline, build_timeline
from simulator.render.labels import CLASS_OF_KIND, frame_labels
from simulator.sensors.camera import CameraModel
from simulator.sensors.encode import kelvin_to_counts, rgb_to_srgb8

FORMATS = ("native", "antiuav")


@dataclass
class PassTimes:
    """Wall-clock seconds spent per stage, summed over frames (for benchmarks and --verbose)."""

    seconds: dict[str, float] = field(default_factory=dict)

    def add(self, name: str, start: float) -> float:
        now = time.perf_counter()
        self.seconds[name] = self.seconds.get(name, 0.0) + now - start
        return now


def _camera_meta(timeline: Timeline, which: str) -> dict:
    rig = timeline.scenario.camera_rig
    cam = timeline.cameras[which]
    intr = rig.rgb if which == "rgb" else rig.thermal
    out = {"width_px": cam.width_px, "height_px": cam.height_px, "hfov_deg": cam.hfov_deg,
           "focal_px": round(cam.focal_px, 6), "spp": intr.spp}
    if which == "thermal":
        out.update({"netd_k": rig.thermal.netd_k, "kelvin_per_count": rig.thermal.kelvin_per_count,
                    "counts_to_kelvin": "T_K = counts * kelvin_per_count"})
    return out


def _timeline_arrays(timeline: Timeline) -> dict[str, np.ndarray]:
    arrays = {"times_s": timeline.times_s}
    for name, cam in timeline.cameras.items():
        arrays[f"camera_{name}_origin_m"] = cam.origin_m
        arrays[f"camera_{name}_forward"] = cam.forward
        arrays[f"camera_{name}_up"] = cam.up
    for t in timeline.targets:
        arrays[f"target{t.target_id}_position_m"] = t.position_m
        arrays[f"target{t.target_id}_velocity_mps"] = t.velocity_mps
        arrays[f"target{t.target_id}_rotation"] = t.rotation
        arrays[f"target{t.target_id}_rotor_rpm"] = t.rotor_rpm
        for role, temps in sorted(t.part_temperature_k.items()):
            arrays[f"target{t.target_id}_temperature_k_{role}"] = temps
    return arrays


def _write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """np.savez writes zip entries with the current time; write raw .npy members with a fixed date."""
    import io
    import zipfile

    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for key in sorted(arrays):
            buf = io.BytesIO()
            np.save(buf, np.ascontiguousarray(arrays[key]), allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, buf.getvalue())


def render_sequence(scenario: Scenario, seed: int, out_dir: Path, *, n_frames: int | None = None,
                    formats: tuple[str, ...] = ("native",), preview: bool = False, progress: bool = True,
                    times: PassTimes | None = None) -> dict[str, Path]:
    """Render ``scenario`` with ``seed`` into ``out_dir``; returns the written paths by kind.

    native: ``out_dir/<name>/`` (docs/NATIVE_FORMAT.md); antiuav: ``out_dir/antiuav/<name>/`` and
    ``<name>_visible/``; preview: ``out_dir/<name>_preview.png``. Nothing is left half-written.
    """
    from simulator.render.renderer import SequenceRenderer

    unknown = [f for f in formats if f not in FORMATS]
    if unknown:
        raise ValueError(f"unknown format(s) {unknown}; valid: {list(FORMATS)}")
    out_dir = Path(out_dir)
    times = times or PassTimes()
    timeline = build_timeline(scenario, seed, n_frames)
    renderer = SequenceRenderer(timeline)
    camera = CameraModel(timeline, renderer.exposure)  # issue 13: the camera model (sensor: ideal = plain encodings)
    netd = scenario.camera_rig.thermal.netd_k
    kpc = scenario.camera_rig.thermal.kelvin_per_count
    written: dict[str, Path] = {}
    final = out_dir / scenario.name
    keep_native = "native" in formats
    staging = final if keep_native else out_dir / f".native-{scenario.name}"
    with atomic_folder(staging) as tmp:
        frames = []
        iterator = range(timeline.n_frames)
        bar = None
        if progress:
            from rich.progress import (
                BarColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
            )

            bar = Progress(TextColumn(f"render {scenario.name}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                           TimeRemainingColumn(), transient=True)
            task = bar.add_task("frames", total=timeline.n_frames)
            bar.start()
        try:
            for i in iterator:
                t0 = time.perf_counter()
                buffers = renderer.render_frame(i)
                t0 = times.add("render (rgb + thermal + masks)", t0)
                recorded = camera.record(i, buffers.rgb_linear, buffers.thermal_radiance, buffers.thermal_kelvin)
                t0 = times.add("camera model", t0)
                write_png(tmp / "rgb" / frame_name(i, "png"), recorded.rgb8)
                write_png(tmp / "thermal" / frame_name(i, "png"), recorded.thermal_counts)
                write_png(tmp / "thermal_agc" / frame_name(i, "png"), recorded.thermal_agc8)
                write_png(tmp / "masks" / "rgb" / frame_name(i, "png"), buffers.mask_rgb)
                write_png(tmp / "masks" / "thermal" / frame_name(i, "png"), buffers.mask_thermal)
                t0 = times.add("encode + write", t0)
                kelvin_q = kelvin_to_counts(buffers.thermal_kelvin, kpc).astype(np.float32) * np.float32(kpc)
                frames.append({
                    "index": i, "time_s": round(float(timeline.times_s[i]), 6),
                    "rgb": frame_labels(timeline, i, "rgb", buffers.mask_rgb),
                    "thermal": frame_labels(timeline, i, "thermal", buffers.mask_thermal, kelvin_q, netd),
                })
                times.add("labels", t0)
                if bar is not None:
                    bar.advance(task)
        finally:
            if bar is not None:
                bar.stop()
        objects = [{"id": t.target_id, "name": t.name, "kind": t.kind, "class": CLASS_OF_KIND[t.kind],
                    "size_m": t.size_m} for t in timeline.targets]
        write_json(tmp / "labels.json", {"objects": objects, "frames": frames})
        (tmp / "scenario.yaml").write_text(scenario_to_yaml(scenario))
        _write_npz(tmp / "timeline.npz", _timeline_arrays(timeline))
        write_json(tmp / "meta.json", {
            "format_version": FORMAT_VERSION, "scenario_name": scenario.name, "seed": int(seed),
            "n_frames": timeline.n_frames, "frame_rate_hz": scenario.frame_rate_hz,
            "cameras": {"rgb": _camera_meta(timeline, "rgb"), "thermal": _camera_meta(timeline, "thermal")},
            "sensor": camera.metadata(),
            "rgb_exposure": round(renderer.exposure, 9), "mitsuba_variant": renderer.mi.variant(),
            "versions": package_versions(),
        })
        write_hashes(tmp)
    if keep_native:
        written["native"] = final
    try:
        if "antiuav" in formats:
            from simulator.formats.antiuav import export_antiuav

            ir, vis = export_antiuav(staging, out_dir / "antiuav", scenario.name)
            written["antiuav"], written["antiuav_visible"] = ir, vis
        if preview:
            from simulator.dataset.preview import contact_sheet

            written["preview"] = contact_sheet(staging, out_dir / f"{scenario.name}_preview.png")
    finally:
        if not keep_native:
            shutil.rmtree(staging, ignore_errors=True)
    return written


def render_rgb_video(scenario: Scenario, seed: int, n_frames: int, width_px: int, height_px: int) -> np.ndarray:
    """(F, H, W, 3) uint8 RGB frames at a chosen size (for small-video datasets such as TRIDENT)."""
    from simulator.render.renderer import SequenceRenderer

    rig = scenario.camera_rig
    small = scenario.model_copy(update={"camera_rig": rig.model_copy(update={
        "rgb": rig.rgb.model_copy(update={"width_px": width_px, "height_px": height_px}),
        "thermal": rig.thermal.model_copy(update={"width_px": 16, "height_px": 16})})})
    timeline = build_timeline(small, seed, n_frames)
    renderer = SequenceRenderer(timeline)
    return np.stack([rgb_to_srgb8(renderer.render_frame(i).rgb_linear) for i in range(timeline.n_frames)])


def load_json(path: Path) -> dict:
    return json.loads(Path(path).read_text())
