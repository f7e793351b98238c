"""Detection experiment (issue 16): the paper's E1/E3 on generated paired RGB/thermal video.

``run_detection(config, out)`` = train + evaluate + report; ``evids detect ...`` is the CLI.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable


def run_detection(config, out: str | Path, log: Callable[[str], None] = print) -> Path:
    from harness.experiments.detection.report import build_detection_report
    from harness.experiments.detection.runner import evaluate, train

    t0 = time.perf_counter()
    train(config, Path(out), log)
    evaluate(Path(out), log)
    path = build_detection_report(Path(out))
    log(f"detection: {time.perf_counter() - t0:.1f} s")
    return path


def run_detection_demo(out: str | Path, log: Callable[[str], None] = print) -> Path:
    """`evids demo --detection`: the reduced detection experiment into OUT/detection."""
    return run_detection("demo", Path(out) / "detection", log)
