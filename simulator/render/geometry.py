"""Per-frame target geometry without rebuilding the procedural asset every frame.

``scenes.assets.build_asset`` lofts every part from scratch (about 15 ms per quadcopter), which was
the largest single cost of a rendered frame. Between frames only props (rotor angle) and bird wings
(flap phase) move, and each moves rigidly about a fixed axis. ``AnimatedAsset`` builds the asset
once, identifies every moving part's rotation axis, pivot and rate from two probe builds
(a rigid-body fit), and then poses parts by rotating the rest-pose vertices. It verifies the model
against a third ``build_asset`` call at other angles and falls back to calling ``build_asset`` per
frame if any vertex disagrees by more than ``POSE_TOLERANCE`` (so an asset change can never
silently change the rendered geometry).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from scenes.assets import build_asset
from simulator.physics.timeline import TargetTrack

POSE_TOLERANCE = 1e-9        # metres per metre of span
_ROTOR_PROBE_RAD = 0.7
_FLAP_PROBE_RAD = 0.9
_CHECK = (2.1, -1.3)         # (rotor angle, flap phase) of the verification build


def _rotation_matrix(rotvec: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation by |rotvec| about rotvec."""
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-15:
        return np.eye(3)
    k = rotvec / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * (kx @ kx)


def _rotvec(rot: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(rot).as_rotvec()


def _rigid_fit(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and pivot p with b = R (a - p) + p (least squares, Kabsch)."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    t = cb - rot @ ca
    pivot = np.linalg.lstsq(np.eye(3) - rot, t, rcond=None)[0]
    return rot, pivot


class AnimatedAsset:
    """Rest-pose parts of one target plus the rigid motion law of each moving part."""

    def __init__(self, kind: str, size_m: float, main_blades: int = 4):
        self.kind, self.size_m, self.main_blades = kind, float(size_m), int(main_blades)
        rest = build_asset(kind, size_m, main_blades=self.main_blades)
        rotor = build_asset(kind, size_m, rotor_angle_rad=_ROTOR_PROBE_RAD, main_blades=self.main_blades)
        flap = build_asset(kind, size_m, flap_phase_rad=_FLAP_PROBE_RAD, main_blades=self.main_blades)
        self.roles = sorted({p.role for p in rest}, key=[p.role for p in rest].index)
        self._parts = []  # (role, rest vertices, motion or None); motion = (driver, axis_per_unit, pivot)
        self.exact = True
        for p0, pr, pf in zip(rest, rotor, flap):
            moved_r = not np.array_equal(p0.vertices, pr.vertices)
            moved_f = not np.array_equal(p0.vertices, pf.vertices)
            motion = None
            if moved_r and moved_f:
                self.exact = False
            elif moved_r:
                rot, pivot = _rigid_fit(p0.vertices, pr.vertices)
                motion = ("rotor", _rotvec(rot) / _ROTOR_PROBE_RAD, pivot)
            elif moved_f:
                rot, pivot = _rigid_fit(p0.vertices, pf.vertices)
                motion = ("flap", _rotvec(rot) / np.sin(_FLAP_PROBE_RAD), pivot)
            self._parts.append((p0.role, p0.vertices, motion))
        self.faces_by_role: dict[str, np.ndarray] = {}
        for role in self.roles:
            offset, faces = 0, []
            for part in rest:
                if part.role == role:
                    faces.append(part.faces + offset)
                    offset += len(part.vertices)
            self.faces_by_role[role] = np.vstack(faces).astype(np.uint32)
        if self.exact:
            self.exact = self._verify()

    def _posed_parts(self, rotor_angle_rad: float, flap_phase_rad: float) -> list[np.ndarray]:
        out = []
        for _, verts, motion in self._parts:
            if motion is None:
                out.append(verts)
                continue
            driver, axis, pivot = motion
            amount = rotor_angle_rad if driver == "rotor" else np.sin(flap_phase_rad)
            rot = _rotation_matrix(axis * amount)
            out.append((verts - pivot) @ rot.T + pivot)
        return out

    def _verify(self) -> bool:
        reference = build_asset(self.kind, self.size_m, rotor_angle_rad=_CHECK[0], flap_phase_rad=_CHECK[1],
                                main_blades=self.main_blades)
        posed = self._posed_parts(*_CHECK)
        return all(np.max(np.abs(a - b.vertices), initial=0.0) <= POSE_TOLERANCE * max(self.size_m, 1.0)
                   for a, b in zip(posed, reference))

    def local_by_role(self, rotor_angle_rad: float, flap_phase_rad: float) -> dict[str, np.ndarray]:
        """Object-frame vertices per role (parts concatenated in asset order)."""
        if self.exact:
            parts = self._posed_parts(rotor_angle_rad, flap_phase_rad)
            roles = [role for role, _, _ in self._parts]
        else:
            built = build_asset(self.kind, self.size_m, rotor_angle_rad=rotor_angle_rad, flap_phase_rad=flap_phase_rad,
                                main_blades=self.main_blades)
            parts, roles = [p.vertices for p in built], [p.role for p in built]
        return {role: np.vstack([v for v, r in zip(parts, roles) if r == role]) for role in self.roles}


ASSET_CACHE_SIZE = 16        # AnimatedAssets kept per process (a few hundred kB each)


@lru_cache(maxsize=ASSET_CACHE_SIZE)
def animated_asset(kind: str, size_m: float, main_blades: int) -> AnimatedAsset:
    """``AnimatedAsset(kind, size_m, main_blades)``, shared by every sequence with that exact target
    (a clip and its counterfactual twin, clips of the same preset): it is a function of these three
    values only and is not changed after construction (its arrays are made read-only)."""
    asset = AnimatedAsset(kind, size_m, main_blades)
    for _, verts, motion in asset._parts:
        verts.flags.writeable = False
        if motion is not None:
            motion[1].flags.writeable = False
            motion[2].flags.writeable = False
    for faces in asset.faces_by_role.values():
        faces.flags.writeable = False
    return asset


class TrackGeometry:
    """World-space vertices per role of one target, per frame (cached)."""

    def __init__(self, track: TargetTrack):
        self.track = track
        self.asset = animated_asset(track.kind, float(track.size_m),
                                    int(track.n_blades) if track.kind == "helicopter" else 4)
        self._cache: dict[int, dict[str, np.ndarray]] = {}

    @property
    def roles(self) -> list[str]:
        return self.asset.roles

    def faces(self, role: str) -> np.ndarray:
        return self.asset.faces_by_role[role]

    def world(self, frame: int) -> dict[str, np.ndarray]:
        if frame not in self._cache:
            t = self.track
            local = self.asset.local_by_role(float(t.rotor_angle_rad[frame]), float(t.flap_phase_rad[frame]))
            self._cache[frame] = {role: v @ t.rotation[frame].T + t.position_m[frame] for role, v in local.items()}
        return self._cache[frame]

    def all_vertices(self, frame: int) -> np.ndarray:
        return np.vstack(list(self.world(frame).values()))
