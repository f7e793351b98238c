"""Peak memory of `evids degrade` (stored degraded copy) against the sequence length.

Writes two miniature 640x512 native sequences (the streaming test's writer, format facts only) of
SHORT and LONG frames and degrades each in a fresh process with one spec of the streaming test's
table (``--spec``: frame_local = ir_blind + noise, the default; frame_drop, frame_freeze, desync,
frame_rate_mismatch, misalignment, dropout, rgb_decoy, thermal_decoy, mixed):
``streamed`` = simulator.dataset.degrade.degrade_sequence (frame by frame); ``in-memory reference``
= the previous algorithm, measured in the same run: every frame loaded, apply_spec on the whole clip.
Prints peak RSS (MB) per length, the growth per frame, and the ratio reference/streamed at LONG.

Run: .venv/bin/python benchmarks/degrade_memory.py [--short 20 --long 80] [--spec frame_drop]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

_CHILD = textwrap.dedent("""
    import json, resource, sys
    sys.path.insert(0, {root!r})
    import numpy as np
    from degradations.spec import apply_spec, load_spec
    from simulator.dataset.degrade import _frame_meta, degrade_sequence
    from simulator.formats.native import load_labels, load_meta, load_rgb, load_thermal_kelvin
    seq, spec_path, out, mode = sys.argv[1:5]
    spec = load_spec(spec_path)
    if mode == "streamed":
        degrade_sequence(seq, spec, out, 0)
    else:
        info, labels = load_meta(seq), load_labels(seq)
        n = info["n_frames"]
        meta, times = _frame_meta(info, labels, __import__("pathlib").Path(seq), slice(0, n))
        streams = {{"rgb": np.stack([load_rgb(seq, i) for i in range(n)]),
                   "thermal": np.stack([load_thermal_kelvin(seq, i) for i in range(n)])}}
        apply_spec(spec, streams, meta, 0, times)
    print(json.dumps(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024))
""")


def peak_mb(seq: Path, spec: Path, out: Path, mode: str) -> float:
    proc = subprocess.run([sys.executable, "-c", _CHILD.format(root=str(ROOT)), str(seq), str(spec), str(out), mode],
                          capture_output=True, text=True, check=True)
    return float(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    import yaml

    from tests.reliability.test_degrade_streaming import ALL_SPECS, write_sequence

    ap = argparse.ArgumentParser()
    ap.add_argument("--short", type=int, default=20)
    ap.add_argument("--long", type=int, default=80)
    ap.add_argument("--spec", choices=sorted(ALL_SPECS), default="frame_local")
    args = ap.parse_args()
    print(f"spec {args.spec}; load average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        spec = tmp / "spec.yaml"
        spec.write_text(yaml.safe_dump(ALL_SPECS[args.spec]))
        res = {}
        for n in (args.short, args.long):
            seq = write_sequence(tmp / f"seq{n}", n, 640, 512)
            for mode in ("streamed", "reference"):
                res[(mode, n)] = peak_mb(seq, spec, tmp / f"out-{mode}-{n}", mode)
        for mode in ("streamed", "reference"):
            a, b = res[(mode, args.short)], res[(mode, args.long)]
            print(f"{mode:9s}: peak RSS {a:7.0f} MB at {args.short} frames, {b:7.0f} MB at {args.long} frames "
                  f"({(b - a) / (args.long - args.short):.2f} MB per extra frame)")
        print(f"ratio reference/streamed at {args.long} frames: "
              f"{res[('reference', args.long)] / res[('streamed', args.long)]:.2f}")


if __name__ == "__main__":
    main()
