"""Conflict programs on class-matched pseudo-triplets of the real benchmark, beside synthetic ones.

The benchmark's sensors are not synchronised: an IR clip and a visible clip with the same number are
different moments, and audio clips are separate recordings. A real *pseudo-triplet* is therefore one
IR, one visible and one audio clip of the same class drawn independently from the evaluation half;
the audio clip of a DRONE triplet is a DRONE recording, of a HELICOPTER triplet a HELICOPTER
recording, and of a BIRD or AIRPLANE triplet a BACKGROUND recording (the audio set has no birds or
airplanes). Synthetic IR and visible crops of one generated sequence are truly synchronised, so a
synthetic triplet takes both from one sequence and its audio clip by class as above.

Each sensor's input is its evidential model's opinion on the whole clip (:func:`clip_opinions`),
coarsened to the binary frame {not drone, drone}. A program "blind m" replaces sensor m's opinion by
that of a *twin*: a clip of the opposite label drawn from the same domain's evaluation half, so its
vote flips when the model is right on both (the twin-swap idea of the generated pipeline's conflict
programs, ``degradations.schedule.SWAP_PROGRAMS``). The opinions are fused with Dempster's rule,
Dempster's rule with the c_max fallback, discounted belief fusion and the averaging baseline
(``evids.fusion``), and every metric is a mean over triplets with a 95 % bootstrap interval
(triplets resampled within label).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from harness.experiments.realbench import stats

if TYPE_CHECKING:
    from evids.heads import Construction

NOT_SYNCHRONISED = ("The benchmark's sensors are not synchronised; each real triplet is one IR, one visible and "
                    "one audio clip of the same class drawn independently, not a multi-modal recording.")
AUDIO_CLASS = {"DRONE": "DRONE", "HELICOPTER": "HELICOPTER", "BIRD": "BACKGROUND", "AIRPLANE": "BACKGROUND"}
SENSORS = ("ir", "visible", "audio")
DOMAINS = ("real", "synthetic")
RULES = {"ds": "Dempster's rule", "ds_c_max": "Dempster's rule, c_max fallback to the most certain sensor",
         "discounted": "discounted belief fusion", "average": "averaging baseline (mean probability)"}
READINGS = {"own_domain": {"real": "a_real", "synthetic": "b_synthetic"},
            "mixed": {"real": "c_both", "synthetic": "c_both"}}
N_TRIPLETS, QUICK_N_TRIPLETS = 200, 40
INERT_FLIP_RATE = 0.1
_TAG, _SUB = 25, 100        # this track's "sim2real" sub-stream (harness._TAG); 100+ = the conflict study


# ---------------------------------------------------------------------------------------------
# Opinions


def binary_opinion(probs: np.ndarray, vacuity: np.ndarray, drone_index: int) -> np.ndarray:
    """Per-row opinions (n, 3) = (b_not_drone, b_drone, u) from a Dirichlet head's output.

    With K classes, ``S = K / u`` and ``p_k = alpha_k / S``, so the canonical belief is
    ``b_k = (alpha_k - 1) / S = p_k - u / K``. The coarsening to the binary frame {not drone, drone}
    keeps u and sums the beliefs: ``b_drone = b[drone_index]``, ``b_not = sum of the others``; the
    result is a valid opinion (non-negative, ``b_not + b_drone + u = 1``). Float rounding below 0 is
    clipped and the beliefs rescaled to ``1 - u``.
    """
    p = np.asarray(probs, np.float64)
    u = np.clip(np.asarray(vacuity, np.float64), 0.0, 1.0)
    if p.ndim != 2 or u.shape != (p.shape[0],) or not 0 <= drone_index < p.shape[1]:
        raise ValueError(f"probs (n, K) with drone_index < K and vacuity (n,) expected, got {p.shape}, {u.shape}, "
                         f"{drone_index}")
    b = np.clip(p - u[:, None] / p.shape[1], 0.0, None)
    mass = b.sum(axis=1)
    b *= np.where(mass > 0, (1.0 - u) / np.where(mass > 0, mass, 1.0), 0.0)[:, None]
    drone = b[:, drone_index]
    return np.stack([b.sum(axis=1) - drone, drone, u], axis=1)


def to_alpha(op: np.ndarray) -> np.ndarray:
    """Canonical binary Dirichlet parameters (..., 2) of opinions (..., 3): ``alpha = b 2 / u + 1``."""
    u = np.clip(op[..., 2:], 1e-9, 1.0)
    return op[..., :2] * (2.0 / u) + 1.0


def votes(op: np.ndarray) -> np.ndarray:
    """1 (drone) where b_drone > b_not_drone, else 0."""
    return (op[..., 1] > op[..., 0]).astype(np.int64)


def clip_opinions(preds: dict, clip: dict[str, np.ndarray], cls_of: dict[str, str], drone_index: int,
                  seeds: list[int]) -> dict[str, dict[str, Any]]:
    """Per domain: clip ids, their class and, per training condition, the evidential model's binary
    opinion on each clip of the clean evaluation half (n_clips, 3).

    A clip's opinion is the mean of its rows' opinions, then the mean over training seeds. Opinions
    are averaged rather than alphas because a convex mixture of opinions is an opinion that every
    frame weighs equally in; averaging alphas would let one frame with large evidence dominate.
    """
    out: dict[str, dict[str, Any]] = {}
    conds = sorted({k[0] for k in preds if k[1] == "evidential"})
    for domain, ids in clip.items():
        names, inv = np.unique(ids, return_inverse=True)
        n_rows = np.bincount(inv, minlength=names.size).astype(np.float64)
        table: dict[str, Any] = {"clip": names, "cls": np.array([cls_of[str(c)] for c in names]), "opinion": {}}
        for c in conds:
            acc = np.zeros((names.size, 3))
            for s in seeds:
                p, v = preds[(c, "evidential", s)][domain]["clean"]
                op = binary_opinion(p, v, drone_index)
                acc += np.stack([np.bincount(inv, weights=op[:, j], minlength=names.size) for j in range(3)], 1)
            table["opinion"][c] = acc / n_rows[:, None] / len(seeds)
        out[domain] = table
    return out


# ---------------------------------------------------------------------------------------------
# Triplets and twins


def _sensor_class(sensor: str, cls: str) -> str:
    return AUDIO_CLASS.get(cls, cls) if sensor == "audio" else cls


def draw_triplets(tables: dict[str, dict[str, Any]], n: int, synchronised: bool,
                  rng: np.random.Generator) -> dict[str, Any]:
    """``n`` class-matched triplets (indices into each sensor's clip table), drawn with replacement,
    half of them drone (rounded down) and the rest spread evenly over the not-drone classes that
    every sensor has a clip of. ``synchronised``: IR and visible come from one clip id (a synthetic
    sequence). Classes are those of the visual sensors (audio-only: the audio classes)."""
    sensors = [s for s in SENSORS if s in tables]
    visual = [s for s in sensors if s != "audio"]
    classes = sorted({str(c) for s in (visual or sensors) for c in tables[s]["cls"]})
    pools: dict[str, list[dict[str, Any]]] = {}     # each: {"cls": the class, sensor: clip indices}
    for cls in classes:
        pool = {s: np.flatnonzero(tables[s]["cls"] == _sensor_class(s, cls)) for s in sensors}
        if synchronised and len(visual) == 2:
            common = np.intersect1d(tables["ir"]["clip"][pool["ir"]], tables["visible"]["clip"][pool["visible"]])
            pool["ir"] = np.searchsorted(tables["ir"]["clip"], common)
            pool["visible"] = np.searchsorted(tables["visible"]["clip"], common)
        if all(v.size for v in pool.values()):
            pools.setdefault("drone" if cls == "DRONE" else "not_drone", []).append({"cls": cls, **pool})
    if "drone" not in pools or "not_drone" not in pools or n < 2:
        return {"n": 0, "eligible": {k: [p["cls"] for p in v] for k, v in pools.items()}}
    n_drone = n // 2
    chosen = [pools["drone"][0]] * n_drone
    others = pools["not_drone"]
    chosen += [others[i] for i in rng.permutation(np.arange(n - n_drone) % len(others))]
    idx = {s: np.empty(n, np.int64) for s in sensors}
    paired = synchronised and len(visual) == 2
    for t, pool in enumerate(chosen):
        k_seq = int(rng.integers(0, pool["ir"].size)) if paired else 0      # one sequence for IR and visible
        for s in sensors:
            k = k_seq if paired and s in visual else int(rng.integers(0, pool[s].size))
            idx[s][t] = pool[s][k]
    return {"n": n, "index": idx, "cls": np.array([p["cls"] for p in chosen]),
            "label": np.array([int(p["cls"] == "DRONE") for p in chosen], np.int64),
            "eligible": {k: [p["cls"] for p in v] for k, v in pools.items()}}


def draw_twins(table: dict[str, Any], label: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
    """Per triplet, a clip of this sensor's table with the opposite label (None when a label has no clip)."""
    drone = table["cls"] == "DRONE"
    pools = {1: np.flatnonzero(~drone), 0: np.flatnonzero(drone)}          # label -> the opposite clips
    if not all(p.size for p in pools.values()):
        return None
    return np.array([pools[int(y)][rng.integers(0, pools[int(y)].size)] for y in label], np.int64)


# ---------------------------------------------------------------------------------------------
# Fusion and metrics


def fuse(ops: np.ndarray, c_max: float,
         construction: Construction = "canonical") -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Fused votes of every rule (n,) for opinions (M, n, 3), and Dempster's conflict (largest fold step)."""
    import torch

    from evids.fusion import average, dempster_shafer, discounted_belief_fusion

    a = torch.from_numpy(to_alpha(ops))
    ds = dempster_shafer(a, construction=construction)
    if ds.conflict is None:
        raise ValueError("dempster_shafer returned no conflict term")
    out = {"ds": ds.p, "ds_c_max": dempster_shafer(a, c_max=c_max, construction=construction).p,
           "discounted": discounted_belief_fusion(a, construction=construction).p, "average": average(a).p}
    return {k: v.argmax(-1).numpy() for k, v in out.items()}, ds.conflict.amax(dim=0).numpy()


def program_rows(ops: np.ndarray, m: int, twin: np.ndarray, label: np.ndarray, c_max: float,
                 construction: Construction = "canonical",
                 clean: tuple[dict[str, np.ndarray], np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Per-triplet indicators of program "blind sensor m" (its opinion replaced by ``twin`` (n, 3)):
    the compromised sensor's vote flip, DS conflict clean and under the program, and per rule the
    fused-decision flip and correctness clean and under the program. ``clean``: :func:`fuse` of
    ``ops`` when the caller has it already (every program of a domain shares it)."""
    swapped = ops.copy()
    swapped[m] = twin
    clean_v, clean_c = clean if clean is not None else fuse(ops, c_max, construction)
    prog_v, prog_c = fuse(swapped, c_max, construction)
    rows = {"sensor_flip": (votes(twin) != votes(ops[m])).astype(np.float64),
            "ds_conflict": prog_c.astype(np.float64), "ds_conflict_clean": clean_c.astype(np.float64)}
    for r in RULES:
        rows[f"{r}/flip"] = (prog_v[r] != clean_v[r]).astype(np.float64)
        rows[f"{r}/correct"] = (prog_v[r] == label).astype(np.float64)
        rows[f"{r}/correct_clean"] = (clean_v[r] == label).astype(np.float64)
    return rows


def bootstrap_weights(label: np.ndarray, rng: np.random.Generator, n_boot: int) -> np.ndarray:
    """(1 + n_boot, n) multiplicities of triplets (row 0 the data), resampled within label."""
    return stats.CellTable(label, np.arange(label.size), ["clean"]).weights(rng, n_boot)


def means(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted means (1 + n_boot,) of a per-triplet value under bootstrap weights."""
    return (w @ x) / w.sum(axis=1)


def is_inert(flip: dict[str, float]) -> bool:
    """A program is inert when the compromised sensor's realised flip rate is below INERT_FLIP_RATE
    or its 95 % interval reaches 0 (an undefined interval counts as reaching 0)."""
    return bool(not flip["estimate"] >= INERT_FLIP_RATE or not flip["ci_low"] > 0.0)


def _ci(b: np.ndarray) -> dict[str, float]:
    return stats.interval(float(b[0]), b[1:])


def domain_study(tables: dict[str, dict[str, Any]], cond: str, trip: dict[str, Any], twins: dict[str, np.ndarray],
                 w: np.ndarray, c_max: float,
                 construction: Construction) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """One domain and reading: the clean fusion and every program's metrics; also each program's
    bootstrap arrays of the fused flip rate (for the real - synthetic difference)."""
    sensors = [s for s in SENSORS if s in tables]
    ops = np.stack([tables[s]["opinion"][cond][trip["index"][s]] for s in sensors])
    label = trip["label"]
    res: dict[str, Any] = {"n_triplets": int(label.size), "classes": {str(c): int((trip["cls"] == c).sum())
                                                                       for c in np.unique(trip["cls"])},
                           "sensor_accuracy_clean": {s: _ci(means((votes(ops[i]) == label).astype(float), w))
                                                     for i, s in enumerate(sensors)},
                           "programs": {}}
    clean_v, clean_c = fuse(ops, c_max, construction)
    res["clean"] = {"ds_conflict": _ci(means(clean_c.astype(np.float64), w)),
                    "accuracy": {r: _ci(means((clean_v[r] == label).astype(np.float64), w)) for r in RULES}}
    boots: dict[str, dict[str, Any]] = {}
    for i, s in enumerate(sensors):
        if s not in twins:
            res["programs"][f"blind_{s}"] = {"sensor": s, "note": "not run: no clip of one label for the twin"}
            continue
        rows = program_rows(ops, i, tables[s]["opinion"][cond][twins[s]], label, c_max, construction,
                            clean=(clean_v, clean_c))
        flip = _ci(means(rows["sensor_flip"], w))
        prog: dict[str, Any] = {"sensor": s, "sensor_flip_rate": flip, "inert": is_inert(flip),
                                "ds_conflict": _ci(means(rows["ds_conflict"], w)), "rules": {}}
        boots[f"blind_{s}"] = {}
        for r in RULES:
            fb = means(rows[f"{r}/flip"], w)
            boots[f"blind_{s}"][r] = fb
            prog["rules"][r] = {"fused_flip_rate": _ci(fb), "accuracy": _ci(means(rows[f"{r}/correct"], w))}
        res["programs"][f"blind_{s}"] = prog
    return res, boots


def run_conflict(tables: dict[str, dict[str, dict[str, Any]] | None], *, seed: int, n_triplets: int, n_boot: int,
                 c_max: float, construction: Construction = "canonical") -> dict[str, Any]:
    """The study over the sensors with a clip table (``tables[sensor][domain]`` from
    :func:`clip_opinions`), both domains and both readings (own-domain models (a)/(b), mixed (c))."""
    from simulator.seeding import rng_for

    tabs = {s: t for s, t in tables.items() if t}
    sensors = [s for s in SENSORS if s in tabs]
    head: dict[str, Any] = {"note": NOT_SYNCHRONISED, "sensors": sensors, "programs": [f"blind_{s}" for s in sensors],
                            "rules": RULES, "c_max": c_max, "construction": construction,
                            "audio_class_of": AUDIO_CLASS, "n_triplets_requested": n_triplets, "bootstrap": n_boot,
                            "inert_flip_rate": INERT_FLIP_RATE, "readings": {}}
    if len(sensors) < 2:
        return {**head, "status": f"not run: needs two sensors with evidential clip opinions, have {sensors}"}
    draws: dict[str, Any] = {}
    for k, domain in enumerate(DOMAINS):
        dt = {s: tabs[s][domain] for s in sensors}
        trip = draw_triplets(dt, n_triplets, domain == "synthetic", rng_for(seed, "sim2real", _TAG, _SUB, k))
        if not trip["n"]:
            draws[domain] = trip
            continue
        twins = {s: tw for j, s in enumerate(SENSORS) if s in dt
                 for tw in [draw_twins(dt[s], trip["label"], rng_for(seed, "sim2real", _TAG, _SUB + 1, k, j))]
                 if tw is not None}
        w = bootstrap_weights(trip["label"], rng_for(seed, "sim2real", _TAG, _SUB + 2, k), n_boot)
        draws[domain] = {**trip, "twins": twins, "weights": w}
    for reading, conds in READINGS.items():
        out: dict[str, Any] = {}
        boots: dict[str, Any] = {}
        for domain in DOMAINS:
            d = draws[domain]
            if not d["n"]:
                out[domain] = {"status": "not run: no class-matched triplet of both labels", "eligible": d["eligible"]}
                continue
            if not all(conds[domain] in tabs[s][domain]["opinion"] for s in sensors):
                continue
            out[domain], boots[domain] = domain_study({s: tabs[s][domain] for s in sensors}, conds[domain], d,
                                                      d["twins"], d["weights"], c_max, construction)
        if "real" in boots and "synthetic" in boots:
            out["real_minus_synthetic_fused_flip_rate"] = {
                p: {r: _difference(boots["real"][p][r], boots["synthetic"][p][r]) for r in RULES}
                for p in boots["real"] if p in boots["synthetic"]}
        if out:
            head["readings"][reading] = out
    return head


def _difference(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    """Real - synthetic from independent resamples paired row by row, with its MDE."""
    n = min(a.size, b.size)
    return stats.difference(float(a[0] - b[0]), a[1:n] - b[1:n])


def format_lines(res: dict[str, Any]) -> list[str]:
    """The key lines of the study for the command's printed summary (estimates [95 % CI])."""
    def ci(r: dict | None, f: str = "{:.2f}") -> str:
        return stats.format_interval(r, f, "{:.2f}")

    if "status" in res:
        return [f"conflict programs on pseudo-triplets: {res['status']}"]
    lines = ["conflict programs on pseudo-triplets (" + res["note"] + ")"]
    for reading, out in res["readings"].items():
        lines.append(f"  {reading} models:")
        for domain in DOMAINS:
            d = out.get(domain)
            if d is None or "status" in d:
                lines.append(f"    {domain}: {d['status'] if d else 'not run'}")
                continue
            acc = ", ".join(f"{r} {d['clean']['accuracy'][r]['estimate']:.2f}" for r in RULES)
            lines.append(f"    {domain} ({d['n_triplets']} triplets): clean fused accuracy {acc}; DS conflict "
                         f"{ci(d['clean']['ds_conflict'])}")
            for name, p in d["programs"].items():
                if "rules" not in p:
                    lines.append(f"      {name}: {p['note']}")
                    continue
                flips = ", ".join(f"{r} {ci(v['fused_flip_rate'])}" for r, v in p["rules"].items())
                acc = ", ".join(f"{r} {v['accuracy']['estimate']:.2f}" for r, v in p["rules"].items())
                lines.append(f"      {name}{' INERT' if p['inert'] else ''}: {p['sensor']} vote flips "
                             f"{ci(p['sensor_flip_rate'])}; DS conflict {ci(p['ds_conflict'])}; fused flips {flips}; "
                             f"accuracy {acc}")
        for name, rules in out.get("real_minus_synthetic_fused_flip_rate", {}).items():
            lines.append(f"    real - synthetic fused flip rate, {name}: "
                         + "; ".join(f"{r} {ci(v, '{:+.2f}')}" for r, v in rules.items()))
    return lines
