"""Physical plausibility checks around a render: refuse camera poses that can see nothing, and report
targets that never appear in any camera (allowed: out-of-view scenes are a test case, but a user
should know). The scene-level checks (NaN/inf, clipping thermal scale, a fixed camera looking
straight up or at its own position) live in scenes/schema.py; these need the timeline."""
from __future__ import annotations

import numpy as np

from scenes.errors import UserInputError

#: a view direction closer than this to vertical (horizontal part / length) has no defined "up"
MIN_HORIZONTAL_FRACTION = 1e-3


def check_camera_poses(timeline) -> None:
    """Raise UserInputError if at some frame a camera has no usable view: its up vector is undefined
    (tracking a target straight overhead or below) or it stands inside a target."""
    for name, cam in timeline.cameras.items():
        fwd = np.asarray(cam.forward, dtype=np.float64)
        up = np.asarray(cam.up, dtype=np.float64)
        bad = ~np.isfinite(fwd).all(axis=1) | ~np.isfinite(up).all(axis=1)
        bad |= np.linalg.norm(fwd, axis=1) < 0.5
        bad |= np.linalg.norm(up, axis=1) < MIN_HORIZONTAL_FRACTION
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise UserInputError(
                f"camera_rig: the {name} camera has no usable view at frame {i + 1} (t = {timeline.times_s[i]:.3f} s): "
                "it looks straight up/down or at its own position; tilt it or move it")
        for track in timeline.targets:
            dist = np.linalg.norm(np.asarray(track.position_m) - np.asarray(cam.origin_m), axis=1)
            inside = dist < max(track.size_m, 0.05)
            if inside.any():
                i = int(np.flatnonzero(inside)[0])
                raise UserInputError(
                    f"camera_rig.position_m: the {name} camera is inside target {track.name!r} at frame {i + 1} "
                    f"({dist[i]:.2f} m from its centre, size {track.size_m} m): it would see nothing; move the camera")


def targets_never_seen(labels_frames: list[dict]) -> list[str]:
    """Names of targets with ``exist`` false in every frame of both cameras (from labels.json frames)."""
    seen: dict[str, bool] = {}
    for frame in labels_frames:
        for camera in ("rgb", "thermal"):
            for obj in frame.get(camera, []):
                name = obj.get("name", str(obj.get("id")))
                seen[name] = seen.get(name, False) or bool(obj.get("exist"))
    return sorted(name for name, ok in seen.items() if not ok)
