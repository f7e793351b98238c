"""Wall time of the main job, `evids demo`, per stage (fresh run folder, so data generation is timed).

Stages: data+train (scene-balanced TRIDENT-style generation with twins incl. Mitsuba video
rendering, loading, six unimodal models + Late Fusion/GMU per training seed), audit (target-blind
baselines), evaluate (all conditions x training seeds x noise seeds, permutation tests), examples,
sweep (severity grid per modality), conflict (twin-swap programs), gate (sweep + batch-1 timing),
report. Prints the machine's load average before and after (figures under load must say so) and
the test-split size. A second invocation on the same folder shows the cached-dataset re-run cost.

Run: .venv/bin/python benchmarks/demo.py [--quick] [--out DIR] [--rerun]   (last line: `demo minutes: X`)
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="toy scale (evids demo --quick)")
    ap.add_argument("--out", default=None, help="run folder (default: a fresh temporary folder, removed after)")
    ap.add_argument("--rerun", action="store_true", help="run a second time on the same folder (cached dataset)")
    args = ap.parse_args()
    from harness.experiments import run_demo

    tmp = None
    out = args.out
    if out is None:
        tmp = tempfile.mkdtemp(prefix="evids-demo-")
        out = os.path.join(tmp, "run")
    print(f"cpu cores: {os.cpu_count()}; out: {out}; quick: {args.quick}; load average before: {os.getloadavg()}")
    try:
        t0 = time.perf_counter()
        times = run_demo(out, quick=args.quick, progress=False, log=lambda s: None)
        total = time.perf_counter() - t0
        for name, sec in times.items():
            print(f"{name:>12s}: {sec:7.1f} s")
        if args.rerun:
            t1 = time.perf_counter()
            run_demo(out, quick=args.quick, progress=False, log=lambda s: None)
            print(f"{'re-run':>12s}: {time.perf_counter() - t1:7.1f} s (dataset cached in the run folder)")
        import json

        train = json.loads(open(os.path.join(out, "train.json")).read())
        print(f"test split: {len(train['split']['test'])} clips, {train['segments']['test']} segments, "
              f"{train['n_scenes']['test']} scenes; load average after: {os.getloadavg()}")
        print(f"demo minutes: {total / 60:.2f}")
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
