"""Benchmark: vectorised Dempster-Shafer fusion vs a per-sample pure-Python reference.

3 modalities x 1,000,000 samples x K = 2 (float32) through ``evids.fusion.dempster_shafer``
(best of several runs after a warm-up), and the same rule written as a plain Python loop over a
subset of samples. Prints the times and, last, ``ds speedup vs per-sample: X`` (per-sample cost
ratio). Run: ``.venv/bin/python benchmarks/fusion.py [--n 1000000] [--subset 20000]``.
"""
from __future__ import annotations

import argparse
import time

import torch

from evids.fusion import dempster_shafer


def ds_reference(alphas: list[list[float]]) -> tuple[list[float], float]:
    """Per-sample DS fold (canonical construction) in pure Python: returns (fused alpha, u)."""
    k = len(alphas[0])
    s = sum(alphas[0])
    b = [(a - 1.0) / s for a in alphas[0]]
    u = k / s
    for row in alphas[1:]:
        s2 = sum(row)
        b2 = [(a - 1.0) / s2 for a in row]
        u2 = k / s2
        agree = sum(x * y for x, y in zip(b, b2))
        one_minus_c = u + u2 - u * u2 + agree
        b = [(x * y + x * u2 + y * u) / one_minus_c for x, y in zip(b, b2)]
        u = u * u2 / one_minus_c
    strength = k / u
    return [x * strength + 1.0 for x in b], u


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000, help="samples for the vectorised run")
    parser.add_argument("--subset", type=int, default=20_000, help="samples for the per-sample reference")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--threads", type=int, default=1,
                        help="torch intra-op threads (0: torch default); 1 by default because on a shared 2-core "
                             "machine intra-op threads are descheduled and timings swing 5-10x")
    args = parser.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)

    gen = torch.Generator().manual_seed(0)
    m, k = 3, 2
    alphas = 1.0 + 10 ** (torch.rand(m, args.n, k, generator=gen) * 4.0) - 1.0
    dempster_shafer(alphas[:, :1000], c_max=0.9)

    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        res = dempster_shafer(alphas, c_max=0.9)
        times.append(time.perf_counter() - t0)
    t_vec = min(times)
    t_med = sorted(times)[len(times) // 2]

    sub = alphas[:, : args.subset].double()
    rows = sub.permute(1, 0, 2).tolist()
    t0 = time.perf_counter()
    ref = [ds_reference(r) for r in rows]
    t_ref = time.perf_counter() - t0

    vec64 = dempster_shafer(sub)
    ref_alpha = torch.tensor([r[0] for r in ref], dtype=torch.float64)
    max_rel = float(((ref_alpha - vec64.alpha).abs() / ref_alpha).max())

    per_vec = t_vec / args.n
    per_ref = t_ref / args.subset
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}, dtype {alphas.dtype}")
    print(f"ds vectorised: {args.n} samples x {m} modalities x K={k}: {t_vec:.4f} s (best of {args.repeats}, median "
          f"{t_med:.4f} s); "
          f"fallback on {int(res.fallback.sum())} samples")
    print(f"ds per-sample python: {args.subset} samples: {t_ref:.4f} s ({per_ref * 1e6:.2f} us/sample)")
    print(f"max relative difference (float64 subset): {max_rel:.2e}")
    print(f"ds speedup vs per-sample: {per_ref / per_vec:.0f}")


if __name__ == "__main__":
    main()
