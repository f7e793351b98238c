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
    entropy_from_log_probs,
    fit_temperature,
    fit_temperature_flagged,
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
from evids.metrics.significance import (
    PermutationResult,
    cluster_means,
    minimum_detectable_difference,
    null_rejection_rate,
    paired_permutation_test,
)
from evids.metrics.tracking import hota, track_scores

__all__ = [
    "BootstrapResult",
    "DetectionMatch",
    "PermutationResult",
    "ReliabilityData",
    "accuracy",
    "apply_temperature",
    "average_precision",
    "box_iou",
    "brier",
    "cluster_means",
    "clustered_bootstrap",
    "clustered_resample",
    "detection_ece",
    "detection_uauc",
    "ece",
    "entropy_from_log_probs",
    "fit_temperature",
    "fit_temperature_flagged",
    "hota",
    "macro_f1",
    "match_detections",
    "minimum_detectable_difference",
    "mot_metrics",
    "nll",
    "null_rejection_rate",
    "paired_bootstrap",
    "paired_permutation_test",
    "plot_reliability",
    "reliability_diagram",
    "track_scores",
    "state_accuracy",
    "uauc",
]
