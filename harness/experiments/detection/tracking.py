"""EDTC-style detection-tracking switching for one target, on filterpy's Kalman filter and scipy's
Hungarian assignment.

Two modes. *Detector* (global re-detection): the best detection in the whole frame with score >=
``det_threshold`` (and, for condition (c), uncertainty <= ``tau_det``) starts a track. *Tracker*:
a constant-velocity Kalman filter predicts the centre; detections within ``search_px`` of the
prediction are assigned to it (Hungarian on centre distance); the tracker keeps control while the
assigned detection's uncertainty is below ``theta`` and hands back to global re-detection when it
rises, or when nothing is assigned (the target is absent or lost). Tracking-on-Absence (E1's
TrkOnAbs) is the fraction of target-absent frames on which the tracker kept control.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import KalmanFilter
from scipy.optimize import linear_sum_assignment


@dataclass
class FrameDetections:
    """Decoded detections of one frame: ``boxes`` (N, 4) [x, y, w, h], ``scores`` (N,), ``uncertainty`` (N,)."""

    boxes: np.ndarray
    scores: np.ndarray
    uncertainty: np.ndarray

    @staticmethod
    def empty() -> "FrameDetections":
        return FrameDetections(np.zeros((0, 4)), np.zeros(0), np.zeros(0))


@dataclass
class TrackStep:
    box: list[float] | None      # output box (None = "no target")
    score: float
    in_control: str              # "tracker" or "detector"
    handed_over: bool            # the tracker gave control back to the detector on this frame
    track_id: int


@dataclass
class SwitchingTracker:
    det_threshold: float
    theta: float
    search_px: float = 24.0
    tau_det: float | None = None
    frame_dt_s: float = 0.04
    _kf: KalmanFilter | None = field(default=None, init=False, repr=False)
    _size: np.ndarray | None = field(default=None, init=False, repr=False)
    track_id: int = field(default=0, init=False)

    def _new_filter(self, box: np.ndarray) -> None:
        kf = KalmanFilter(dim_x=4, dim_z=2)
        dt = self.frame_dt_s
        kf.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
        kf.H = np.array([[1, 0, 0, 0], [0, 1, 0, 0]], float)
        kf.R *= 2.0 ** 2
        kf.P = np.diag([4.0, 4.0, 400.0 ** 2, 400.0 ** 2])
        kf.Q = np.diag([1.0, 1.0, 100.0, 100.0])
        kf.x = np.array([box[0] + box[2] / 2, box[1] + box[3] / 2, 0.0, 0.0])
        self._kf = kf
        self._size = np.asarray(box[2:], float)
        self.track_id += 1

    @property
    def tracking(self) -> bool:
        return self._kf is not None

    def _redetect(self, dets: FrameDetections) -> tuple[list[float] | None, float]:
        ok = dets.scores >= self.det_threshold
        if self.tau_det is not None:
            ok &= dets.uncertainty <= self.tau_det
        if not ok.any():
            return None, 0.0
        i = int(np.flatnonzero(ok)[np.argmax(dets.scores[ok])])
        box = np.asarray(dets.boxes[i], float)
        self._new_filter(box)
        return box.tolist(), float(dets.scores[i])

    def step(self, dets: FrameDetections) -> TrackStep:
        """Advance one frame with this frame's detections."""
        if self._kf is not None:
            kf, size = self._kf, self._size
            if size is None:
                raise RuntimeError("tracker state: a Kalman filter without a box size")
            kf.predict()
            pred = kf.x[:2]
            if dets.boxes.shape[0]:
                centres = dets.boxes[:, :2] + dets.boxes[:, 2:] / 2
                dist = np.linalg.norm(centres - pred[None], axis=1)
                cost = np.where(dist <= self.search_px, dist - 1e-3 * dets.scores, 1e6)[None, :]
                _, cols = linear_sum_assignment(cost)
                j = int(cols[0])
                if cost[0, j] < 1e6 and dets.uncertainty[j] < self.theta:
                    kf.update(centres[j])
                    self._size = size = 0.5 * size + 0.5 * dets.boxes[j, 2:]
                    cx, cy = kf.x[:2]
                    tracked = [float(cx - size[0] / 2), float(cy - size[1] / 2), float(size[0]), float(size[1])]
                    return TrackStep(tracked, float(dets.scores[j]), "tracker", False, self.track_id)
            self._kf = None
            box, score = self._redetect(dets)
            return TrackStep(box, score, "detector", True, self.track_id)
        box, score = self._redetect(dets)
        return TrackStep(box, score, "detector", False, self.track_id)


def run_tracker(frames: list[FrameDetections], det_threshold: float, theta: float, search_px: float,
                tau_det: float | None = None, frame_dt_s: float = 0.04) -> list[TrackStep]:
    trk = SwitchingTracker(det_threshold, theta, search_px, tau_det, frame_dt_s)
    return [trk.step(f) for f in frames]


def tracking_on_absence(steps: list[TrackStep], exist: np.ndarray) -> float:
    """Fraction of target-absent frames on which the tracker kept control (NaN without absent frames)."""
    absent = ~np.asarray(exist, bool)
    if not absent.any():
        return float("nan")
    return float(np.mean([s.in_control == "tracker" for s, a in zip(steps, absent) if a]))
