"""Experiment harness: validated configs, data preparation, the E2-style ablation conditions,
degradation sweep, conflict study, gate sweep and the `evids demo` main job."""
from __future__ import annotations

import time
from pathlib import Path

from harness.experiments.config import (
    DEMO_CONFIG,
    QUICK_CONFIG,
    ExperimentConfig,
    load_experiment_config,
)

__all__ = ["DEMO_CONFIG", "QUICK_CONFIG", "ExperimentConfig", "load_experiment_config", "run_all", "run_demo"]


def run_all(cfg: ExperimentConfig, out: Path, progress: bool = True, log=print) -> dict[str, float]:
    """train -> evaluate -> examples -> sweep -> conflict -> gate -> report; returns wall seconds per stage."""
    from harness.experiments import conflict_study, gate_timing, runner
    from harness.report import build_report
    from harness.runfolder import mark_stage

    out = Path(out)
    times: dict[str, float] = {}

    def timed(name, fn, *args):
        t0 = time.perf_counter()
        res = fn(*args)
        times[name] = time.perf_counter() - t0
        log(f"stage {name}: {times[name]:.1f} s")
        return res

    ctx = timed("data+train", runner.stage_train, cfg, out, progress)
    if cfg.audit.enabled:
        timed("audit", runner.stage_audit, ctx)
    timed("evaluate", runner.stage_evaluate, ctx)
    timed("examples", runner.stage_examples, ctx)
    timed("sweep", runner.stage_sweep, ctx)
    timed("conflict", conflict_study.stage_conflict, ctx)
    timed("gate", gate_timing.stage_gate, ctx)
    timed("report", build_report, out)
    mark_stage(out, "complete", sum(times.values()), {"stage_seconds": {k: round(v, 2) for k, v in times.items()}})
    return times


def run_demo(out: str | Path, quick: bool = False, progress: bool = True, log=print) -> dict[str, float]:
    """The main job: a small seeded tri-modal scenario set (cached in ``out/data``), trained and stress-tested."""
    cfg = load_experiment_config(QUICK_CONFIG if quick else DEMO_CONFIG)
    return run_all(cfg, Path(out), progress, log)
