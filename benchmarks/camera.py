"""Camera-model benchmark: cost per paired frame of simulator.sensors.camera, stage by stage, against a
reference implementation (a git revision, by default the one before issue 27) in the same run.

Two worker processes, one importing this tree and one the reference revision's ``simulator`` and
``scenes`` (extracted with ``git archive`` into a temporary folder), record the same synthetic
frames; the driver lets them run alternately, a few frames at a time, so load on the shared machine
hits both alike. Stage times are exclusive wall times from wrappers around the camera model's
functions (each stage's own time, its sub-stages subtracted), so they add up to the total.

Configurations: ``default`` (preset clear_day_quad: RGB 640x512 sRGB + thermal 640x512 min/max AGC,
no recorder) and ``realism`` (examples/sim2real/realism_drone.yaml: camcorder tone, thermal 320x256
with Gaussian blur and plateau AGC with local contrast, H.264 recording of both 8-bit views).
Inputs are synthetic (sky gradient + ground band, a moving target, per-pixel render noise so the
thermal radiance is as rough as a 4-spp path-traced frame), prepared before timing.

    PYTHONPATH=. .venv/bin/python benchmarks/camera.py [--frames 40] [--chunk 5] [--reference ee86f6c]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REFERENCE_REV = "ee86f6c"          # main before issue 27 (float64/ziggurat noise, np.interp kelvin, full Poisson)
CONFIGS = {"default": "clear_day_quad", "realism": str(ROOT / "examples/sim2real/realism_drone.yaml")}
N_INPUTS = 8                       # distinct input frames, cycled
# stage name -> (owner path, attribute): exclusive wall time of each call
STAGES = [
    ("RGB optics (PSF, 3 channels)", "camera", "RgbSensor.focal_plane"),
    ("motion blur (both cameras)", "camera", "motion_blur"),
    ("RGB shot + read noise", "camera", "shot_noise"),
    ("RGB ADC + sRGB LUT (rest of record)", "camera", "RgbSensor.record"),
    ("RGB camcorder AE + tone", "agc", "CamcorderExposure.__call__"),
    ("thermal optics + lag", "camera", "ThermalSensor.detector_radiance"),
    ("thermal brightness temperature", "thermal", "brightness_temperature"),
    ("thermal brightness temperature", "thermal", "brightness_temperature_f32"),
    ("thermal FPN + NETD noise + counts (rest)", "camera", "ThermalSensor.record"),
    ("thermal histogram AGC", "camera", "equalise_counts"),
    ("thermal min/max or percentile AGC", "camera", "agc"),
    ("thermal min/max or percentile AGC", "camera", "agc_counts"),
    ("thermal plateau AGC", "agc", "PlateauAgc.__call__"),
    ("H.264 recording (both views)", "recording", "H264Stream.__call__"),
    ("camera model (rest)", "camera", "CameraModel.record"),
]


# --- worker: runs inside a process whose PYTHONPATH is the tree under test --------------------------
def _inputs(scenario, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from simulator.physics import thermal

    rig = scenario.camera_rig
    rng = np.random.default_rng(1000 + frame)
    out = []
    for cam in (rig.rgb, rig.thermal):
        h, w = cam.height_px, cam.width_px
        yy, xx = np.mgrid[0:h, 0:w]
        cx, cy = 0.2 * w + 3 * frame, h // 2
        target = (np.abs(xx - cx) < max(2, w // 100)) & (np.abs(yy - cy) < max(2, h // 120))
        ground = yy > 0.7 * h
        out.append((yy, target, ground, rng))
    (yy, target, ground, rng), (tyy, ttarget, tground, _) = out
    h = yy.shape[0]
    rgb = np.repeat((0.3 + 0.2 * yy / h)[..., None], 3, axis=-1)
    rgb[ground] = 0.12
    rgb[target] = 0.05
    rgb *= 1.0 + 0.05 * rng.standard_normal(rgb.shape)                 # 4-spp render noise
    th = tyy.shape[0]
    kelvin = 250.0 + 20.0 * tyy / th
    kelvin[tground] = 283.0
    kelvin[ttarget] = 300.0
    kelvin += 0.3 * rng.standard_normal(kelvin.shape)
    kelvin = kelvin.astype(np.float32)
    return rgb.astype(np.float32), thermal.band_radiance(kelvin).astype(np.float32), kelvin


def _resolve(module, dotted: str):
    owner = module
    parts = dotted.split(".")
    for p in parts[:-1]:
        owner = getattr(owner, p, None)
        if owner is None:
            return None, None
    return (owner, parts[-1]) if hasattr(owner, parts[-1]) else (None, None)


def _instrument(totals: dict[str, float]) -> None:
    """Wrap every stage function with an exclusive-time accumulator."""
    import functools

    import simulator.physics.thermal as thermal_mod
    import simulator.sensors.agc as agc_mod
    import simulator.sensors.camera as camera_mod
    import simulator.sensors.recording as recording_mod

    modules = {"camera": camera_mod, "agc": agc_mod, "thermal": thermal_mod, "recording": recording_mod}
    stack: list[float] = []                                            # child time of each open call

    def wrap(name, fn):
        @functools.wraps(fn)
        def timed(*args, **kwargs):
            stack.append(0.0)
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                spent = time.perf_counter() - t0
                children = stack.pop()
                totals[name] = totals.get(name, 0.0) + spent - children
                if stack:
                    stack[-1] += spent
        return timed

    for name, mod, dotted in STAGES:
        owner, attr = _resolve(modules[mod], dotted)
        if owner is not None:
            setattr(owner, attr, wrap(name, getattr(owner, attr)))


def worker(config: str) -> None:
    """Reads 'run N' lines; records N more frames; answers one JSON line of stage seconds."""
    from scenes import load_scenario
    from simulator.physics.timeline import build_timeline

    t0 = time.perf_counter()
    import simulator.sensors.camera as camera_mod  # noqa: F401  (import + Planck table)
    from simulator.physics import thermal
    thermal.band_radiance(300.0)
    import_s = time.perf_counter() - t0
    scenario = load_scenario(CONFIGS[config])
    scenario = scenario.model_copy(update={"duration_s": 10_000 / scenario.frame_rate_hz})
    timeline = build_timeline(scenario, 0)
    inputs = [_inputs(scenario, i) for i in range(N_INPUTS)]
    totals: dict[str, float] = {}
    _instrument(totals)
    t0 = time.perf_counter()
    model = camera_mod.CameraModel(timeline, render_exposure=30.0)
    setup_s = time.perf_counter() - t0
    model.record(0, *inputs[0])                                         # warm-up (LUTs, FFT plans)
    totals.clear()
    frame = 1
    print(json.dumps({"ready": True, "import_s": import_s, "setup_s": setup_s}), flush=True)
    for line in sys.stdin:
        n = int(line.split()[1])
        before = dict(totals)
        t0 = time.perf_counter()
        for _ in range(n):
            model.record(frame, *inputs[frame % N_INPUTS])
            frame += 1
        wall = time.perf_counter() - t0
        print(json.dumps({"wall_s": wall, "frames": n,
                          "stages": {k: v - before.get(k, 0.0) for k, v in totals.items()}}), flush=True)


# --- driver -----------------------------------------------------------------------------------------
class Worker:
    def __init__(self, tree: Path, config: str, quiet: bool = False):
        env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
        self.proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--worker", config],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env, cwd=tree,
                                     stderr=subprocess.DEVNULL if quiet else None)
        self.hello = self._read()
        self.wall, self.frames, self.stages = 0.0, 0, {}

    def _read(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("benchmark worker died (run it with --worker to see the error)")
        return json.loads(line)

    def run(self, n: int) -> float:
        self.proc.stdin.write(f"run {n}\n")
        self.proc.stdin.flush()
        r = self._read()
        self.wall += r["wall_s"]
        self.frames += r["frames"]
        for k, v in r["stages"].items():
            self.stages[k] = self.stages.get(k, 0.0) + v
        return r["wall_s"] / n

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()


def extract(rev: str, into: Path) -> Path:
    """The reference revision's importable packages, via git archive (no worktree touched)."""
    data = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev, "simulator", "scenes"],
                          check=True, capture_output=True).stdout
    import io

    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(into, filter="data")
    return into


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=40, help="timed frames per configuration and implementation")
    parser.add_argument("--chunk", type=int, default=2, help="frames per turn before the other worker runs")
    parser.add_argument("--reference", default=REFERENCE_REV, help="git revision to compare with ('none': skip)")
    parser.add_argument("--config", choices=[*CONFIGS, "both"], default="both")
    parser.add_argument("--worker", choices=list(CONFIGS), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.worker)
        return
    configs = list(CONFIGS) if args.config == "both" else [args.config]
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:
        ref_tree = extract(args.reference, Path(tmp)) if args.reference != "none" else None
        for config in configs:
            ours = Worker(ROOT, config)
            ref = None
            if ref_tree:
                try:
                    ref = Worker(ref_tree, config, quiet=True)
                except RuntimeError:                # e.g. its schema predates the config's fields
                    print(f"\n[{config}] the reference {args.reference} cannot record this configuration "
                          "(its scenario schema predates fields the config uses): ours alone")
            per_turn: list[tuple[float, float]] = []
            done = 0
            while done < args.frames:
                n = min(args.chunk, args.frames - done)
                a = ours.run(n)
                b = ref.run(n) if ref else float("nan")
                per_turn.append((a, b))
                done += n
            ours.close()
            if ref:
                ref.close()
            _report(config, args, ours, ref, per_turn)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


def _report(config: str, args, ours: Worker, ref: Worker | None, per_turn: list[tuple[float, float]]) -> None:
    label = f"reference {args.reference}" if ref else "no reference"
    print(f"\n[{config}] {ours.frames} paired frames each, turns of {args.chunk}, {label}")
    print(f"  import + Planck table: ours {ours.hello['import_s']:.2f} s" +
          (f", reference {ref.hello['import_s']:.2f} s" if ref else ""))
    print(f"  {'stage':44s} {'ours ms':>9s} {'ref ms':>9s} {'ref/ours':>9s}")
    names = list(dict.fromkeys(s[0] for s in STAGES))
    for name in names:
        a = ours.stages.get(name, 0.0) / ours.frames * 1e3
        b = ref.stages.get(name, 0.0) / ref.frames * 1e3 if ref else float("nan")
        if a < 0.005 and not b >= 0.005:
            continue
        ratio = f"{b / a:9.2f}" if ref and a > 0 else f"{'':9s}"
        print(f"  {name:44s} {a:9.2f} {b:9.2f} {ratio}")
    a_ms = ours.wall / ours.frames * 1e3
    if ref:
        b_ms = ref.wall / ref.frames * 1e3
        turn_ratios = np.array([b / a for a, b in per_turn])
        print(f"  {'total per paired frame':44s} {a_ms:9.2f} {b_ms:9.2f} {b_ms / a_ms:9.2f}")
        print(f"  speed-up per turn (ref/ours): median {np.median(turn_ratios):.2f}, "
              f"range {turn_ratios.min():.2f}-{turn_ratios.max():.2f} over {len(per_turn)} turns")
    print(f"camera model [{config}]: {a_ms:.1f} ms per paired frame ({1e3 / a_ms:.1f} paired frames/s alone, "
          f"load average {os.getloadavg()[0]:.2f})")


if __name__ == "__main__":
    main()
