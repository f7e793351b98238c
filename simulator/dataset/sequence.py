"""Render one scenario into the native layout (and optionally the Anti-UAV layout and a preview)."""
from __future__ import annotations

import shutil
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from scenes.loader import scenario_to_yaml
from scenes.schema import Scenario
from simulator.files import (
    atomic_folder,
    package_versions,
    remove_output,
    temp_sibling,
    write_hashes,
    write_marker,
)
from simulator.formats.native import FORMAT_VERSION, frame_name, write_json, write_png
from simulator.physics.timeline import Timeline, build_timeline
from simulator.render.labels import CLASS_OF_KIND, coverage_labels, pad_labels
from simulator.sensors.camera import CameraModel
from simulator.sensors.encode import rgb_to_srgb8

FORMATS = ("native", "antiuav")
WRITER_THREADS = 2       # PNG encoding runs beside rendering (cv2 and numpy release the GIL)
MAX_PENDING_FRAMES = 32  # bound on frames queued for writing (memory: ~6 MB per 640x512 paired frame)


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
    out: dict[str, Any] = {"width_px": cam.width_px, "height_px": cam.height_px, "hfov_deg": cam.hfov_deg,
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


def camera_outputs(recorded, buffers) -> dict[str, np.ndarray]:
    """The images written for one frame, by path under the sequence folder: what the camera
    model recorded (``simulator.sensors.camera``) and the exact masks. Labels never pass through
    here (they come from the exact geometry, before any sensor effect)."""
    return {
        "rgb": recorded.rgb8,
        "thermal": recorded.thermal_counts,
        "thermal_agc": recorded.thermal_agc8,
        "masks/rgb": buffers.mask_rgb,
        "masks/thermal": buffers.mask_thermal,
    }


def _write_frame(folder: Path, index: int, recorded, buffers) -> None:
    for sub, image in camera_outputs(recorded, buffers).items():
        write_png(folder / sub / frame_name(index, "png"), image)


class _FrameWriter:
    """Encodes and writes frames on worker threads while the caller renders the next batch."""

    def __init__(self, folder: Path, threads: int = WRITER_THREADS):
        self.folder = folder
        self.pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="evids-write")
        self.pending: list[Future] = []

    def submit(self, index: int, recorded, buffers) -> None:
        self.pending.append(self.pool.submit(_write_frame, self.folder, index, recorded, buffers))
        while len(self.pending) > MAX_PENDING_FRAMES:
            self.pending.pop(0).result()

    def finish(self) -> None:
        """Wait for every frame; re-raise the first write error."""
        try:
            for future in self.pending:
                future.result()
        finally:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pending = []


def render_sequence(scenario: Scenario, seed: int, out_dir: Path, *, n_frames: int | None = None,
                    formats: tuple[str, ...] = ("native",), preview: bool = False, progress: bool = True,
                    times: PassTimes | None = None, writer_threads: int = WRITER_THREADS, overwrite: bool = False,
                    notes: list[str] | None = None, render_ahead: bool = True) -> dict[str, Path]:
    """Render ``scenario`` with ``seed`` into ``out_dir``; returns the written paths by kind.

    native: ``out_dir/<name>/`` (docs/NATIVE_FORMAT.md); antiuav: ``out_dir/antiuav/<name>/`` and
    ``<name>_visible/``; preview: ``out_dir/<name>_preview.png``. Nothing is left half-written.
    Frames are rendered in batches (simulator.render.plan), the next batch on a worker thread while
    the camera model records this one (``render_ahead``; the same bytes either way), and written by
    worker threads.
    Existing outputs are replaced only with ``overwrite`` and only if evids wrote them. A camera
    pose that sees nothing is refused before rendering; plausibility findings (a target never in
    view, clipped thermal counts) are appended to ``notes``.
    """
    from simulator.dataset.plausibility import check_camera_poses, targets_never_seen
    from simulator.render.renderer import SequenceRenderer

    unknown = [f for f in formats if f not in FORMATS]
    if unknown:
        raise ValueError(f"unknown format(s) {unknown}; valid: {list(FORMATS)}")
    out_dir = Path(out_dir)
    times = times or PassTimes()
    timeline = build_timeline(scenario, seed, n_frames)
    check_camera_poses(timeline)
    renderer = SequenceRenderer(timeline)
    camera = CameraModel(timeline, renderer.exposure)  # issue 13: the camera model (sensor: ideal = plain encodings)
    netd = scenario.camera_rig.thermal.netd_k
    rgb_cam, th_cam = timeline.cameras["rgb"], timeline.cameras["thermal"]
    clipped_px = 0
    counts_max = 2 ** getattr(scenario.camera_rig.thermal, "adc_bits", 16) - 1
    written: dict[str, Path] = {}
    final = out_dir / scenario.name
    keep_native = "native" in formats
    staging = final if keep_native else temp_sibling(final, "native")
    with atomic_folder(staging, overwrite=overwrite, kind="sequence") as tmp:
        frames = []
        bar = None
        if progress:
            from rich.progress import (
                BarColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
            )

            bar = Progress(TextColumn(f"render {scenario.name}"), BarColumn(),
                           TextColumn("{task.completed}/{task.total}"),
                           TimeRemainingColumn(), transient=True)
            task = bar.add_task("frames", total=timeline.n_frames)
            bar.start()
        writer = _FrameWriter(tmp, writer_threads)
        # the next batch renders on a worker thread while this one goes through the camera model
        rendered = renderer.iter_frames(ahead=render_ahead)
        try:
            t0 = time.perf_counter()
            for i, buffers in rendered:
                t0 = times.add("wait for the render (rgb + thermal + coverage, one batch ahead)", t0)
                # the camera model keeps state (bolometer lag): it runs here, in frame order
                recorded = camera.record_buffers(i, buffers)   # the ideal kelvin only for the ideal sensor
                clipped_px += int(np.count_nonzero(np.asarray(recorded.thermal_counts) >= counts_max))
                t0 = times.add("camera model", t0)
                frames.append({
                    "index": i, "time_s": round(float(timeline.times_s[i]), 6),
                    "rgb": pad_labels(coverage_labels(timeline, i, "rgb", buffers.coverage["rgb"], rgb_cam.width_px,
                                                      rgb_cam.height_px),
                                      scenario.camera_rig.rgb.label_margin_px, rgb_cam.width_px, rgb_cam.height_px),
                    "thermal": pad_labels(coverage_labels(timeline, i, "thermal", buffers.coverage["thermal"],
                                                          th_cam.width_px, th_cam.height_px, netd),
                                          scenario.camera_rig.thermal.label_margin_px, th_cam.width_px,
                                          th_cam.height_px),
                })
                t0 = times.add("labels", t0)
                writer.submit(i, recorded, buffers)
                t0 = times.add("queue for writing", t0)
                if bar is not None:
                    bar.advance(task)
            t0 = time.perf_counter()
        finally:
            try:
                rendered.close()   # waits for a batch still rendering
                writer.finish()
            finally:
                renderer_meta = {"exposure": renderer.exposure, "variant": renderer.mi.variant(),
                                 "layout": renderer.record()}
                renderer.close()
                if bar is not None:
                    bar.stop()
        times.add("wait for writers", t0)
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
            "rgb_exposure": round(renderer_meta["exposure"], 9), "mitsuba_variant": renderer_meta["variant"],
            "render_layout": renderer_meta["layout"],
            "versions": package_versions(),
        })
        write_hashes(tmp)
    if keep_native:
        written["native"] = final
    if notes is not None:
        notes.extend(f"target {name!r} is never in view of any camera (all frames exist: 0)"
                     for name in targets_never_seen(frames))
        if clipped_px:
            notes.append(f"{clipped_px} thermal pixel(s) clipped at {counts_max} counts; raise kelvin_per_count")
    try:
        if "antiuav" in formats:
            from simulator.formats.antiuav import export_antiuav

            if overwrite:
                remove_output(out_dir / "antiuav" / scenario.name)
                remove_output(out_dir / "antiuav" / f"{scenario.name}_visible")
            ir, vis = export_antiuav(staging, out_dir / "antiuav", scenario.name)
            write_marker(ir, "render antiuav")  # so a later `render --overwrite` may replace them
            write_marker(vis, "render antiuav")
            written["antiuav"], written["antiuav_visible"] = ir, vis
        if preview:
            from simulator.dataset.preview import contact_sheet

            written["preview"] = contact_sheet(staging, out_dir / f"{scenario.name}_preview.png")
    finally:
        if not keep_native:
            shutil.rmtree(staging, ignore_errors=True)
    return written


def render_rgb_video(scenario: Scenario, seed: int, n_frames: int, width_px: int, height_px: int,
                     layout: Scenario | None = None) -> np.ndarray:
    """(F, H, W, 3) uint8 RGB frames at a chosen size (for small-video datasets such as TRIDENT).
    RGB only, no labels: whole frames batched many per launch. ``layout``: render with the launch
    layout of that scene (the same cameras, these targets first): a counterfactual twin passes its
    drone clip's scene, so every pixel the drone does not reach gets byte-identical values."""
    from simulator.render.renderer import SequenceRenderer

    def small(sc: Scenario) -> Scenario:
        rig = sc.camera_rig
        return sc.model_copy(update={"camera_rig": rig.model_copy(update={
            "rgb": rig.rgb.model_copy(update={"width_px": width_px, "height_px": height_px}),
            "thermal": rig.thermal.model_copy(update={"width_px": 16, "height_px": 16})})})

    timeline = build_timeline(small(scenario), seed, n_frames)
    from simulator.dataset.plausibility import check_camera_poses

    check_camera_poses(timeline)
    layout_timeline = None if layout is None else build_timeline(small(layout), seed, n_frames)
    renderer = SequenceRenderer(timeline, cameras=("rgb",), labels=False, layout=layout_timeline)
    out = np.empty((timeline.n_frames, height_px, width_px, 3), np.uint8)
    rendered = renderer.iter_frames(ahead=True)   # the next batch renders while this one is encoded
    try:
        for i, buffers in rendered:
            out[i] = rgb_to_srgb8(buffers.rgb_linear)
    finally:
        rendered.close()
        renderer.close()
    return out
