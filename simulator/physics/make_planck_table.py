"""Write the shipped LWIR Planck table (run by hand when the band or the grid changes, not at run time).

    python -m simulator.physics.make_planck_table [--out FILE]

``simulator/physics/data/planck_lwir_8_14um.npy``: the 8-14 um band radiance (float64, W sr^-1 m^-2)
at 100-1500 K in 0.05 K steps, as ``thermal.compute_table`` gives it (a test checks it is equal), so a
new process loads it in ~1 ms instead of integrating Planck's law for ~3-5 s. ``np.save`` writes the
same bytes for the same array (no time stamp)."""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from simulator.files import atomic_path
from simulator.physics.thermal import PLANCK_TABLE_PATH, compute_table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=PLANCK_TABLE_PATH)
    args = parser.parse_args()
    _, radiances = compute_table()
    with atomic_path(args.out, suffix=".npy") as tmp:
        np.save(tmp, radiances, allow_pickle=False)
    print(f"wrote {args.out} ({radiances.size} values)")


if __name__ == "__main__":
    main()
