"""Evaluation metrics: classification, calibration, uncertainty ranking (UAUC), clip-clustered
bootstrap, detection (IoU matching, AP50, detection ECE/UAUC), Anti-UAV state accuracy, MOTA/IDF1, HOTA."""
from __future__ import annotations

from evids.metrics.bootstrap import (
    BootstrapResult,
    clustered_bootstrap,
    clustered_resample,
    paired_bootstrap,
)
from evids.metrics.calibration import (
    ReliabilityData,
    detection_ece,
    ece,
    plot_reliability,
    reliability_diagram,
)
from evids.metrics.classification import (
    accuracy,
    apply_temperature,
    brier,
    fit_temperature,
    macro_f1,
    nll,
    uauc,
)
from evids.metrics.detection import (
    DetectionMatch,
    average_precision,
    box_iou,
    detection_uauc,
    match_detections,
    mot_metrics,
    state_accuracy,
)
from evids.metrics.tracking import hota, track_scores

__all__ = [
    "BootstrapResult",
    "DetectionMatch",
    "ReliabilityData",
    "accuracy",
    "apply_temperature",
    "average_precision",
    "box_iou",
    "brier",
    "clustered_bootstrap",
    "clustered_resample",
    "detection_ece",
    "detection_uauc",
    "ece",
    "fit_temperature",
    "hota",
    "macro_f1",
    "match_detections",
    "mot_metrics",
    "nll",
    "paired_bootstrap",
    "plot_reliability",
    "reliability_diagram",
    "track_scores",
    "state_accuracy",
    "uauc",
]
