"""The E2 conflict study stage: twin-swap and legacy conflict programs on the test split, each
program's realised effect and every fusion rule's accuracy under it (conflict.json)."""
from __future__ import annotations

import time
from typing import Any

import numpy as np
import torch

from evids.modalities import MODALITIES
from harness.experiments.conditions import Condition, fuse, predict_condition
from harness.experiments.noise import conflict_clip, program_window, swap_clip, targeted_segments
from harness.experiments.pipeline import Outputs, encode
from harness.experiments.runner import FUSION_RULES, Context, compare, map_groups, warm_clean
from harness.runfolder import mark_stage, write_csv, write_json
from simulator.jobs import job_context


def _majority(alpha: np.ndarray) -> np.ndarray:
    votes = alpha.argmax(-1)                          # (3, N)
    return (votes.sum(0) >= 2).astype(np.int64)       # class 1 when >= 2 of 3 vote Background


def _rule_preds(ctx: Context, run: int, out: Outputs, cid: np.ndarray) -> dict[str, np.ndarray]:
    cfg = ctx.cfg
    preds = {rule: predict_condition(Condition(rule, rule, "conflict", rule), ctx.trained[run], out, cid,
                                     cfg.fusion.c_max, cfg.fusion.construction, None).probs.argmax(1)
             for rule in FUSION_RULES}
    preds["majority_vote"] = _majority(out.alpha)
    return preds


def _swap_program(ctx: Context, prog) -> dict:
    """Realised effect of one twin-swap program on the test split, over every training run."""
    from degradations.schedule import swap_program

    cfg, cc = ctx.cfg, ctx.cfg.conflict
    desc, kind, mods = swap_program(prog.name)
    by_id = {c.clip_id: k for k, c in enumerate(ctx.prep.clips)}
    want = 0 if kind == "blind" else 1
    items = [(i, by_id[twin]) for i in ctx.test
             if ctx.prep.clips[i].label == want and (twin := ctx.prep.clips[i].twin) is not None and twin in by_id]
    base = {"program": prog.key, "name": prog.name, "strength": prog.strength, "kind": kind,
            "modalities": list(mods), "description": desc}
    if not items:
        return {**base, "n_targeted": 0, "status": "not run: no test clip of this kind has a twin"}
    parts, targ, ys, cids, scns = [], [], [], [], []
    for i, j in items:
        clip, donor = ctx.prep.clips[i], ctx.prep.clips[j]
        w = program_window(clip.n_segments, cc.onset_fraction, cc.duration_fraction)
        parts.append(swap_clip(clip, donor, mods, prog.strength, w, ctx.prep.rf_range_db))
        targ.append(targeted_segments(clip, donor, kind, mods, w))
        ys.append(np.full(clip.n_segments, clip.label))
        cids.append(np.full(clip.n_segments, clip.clip_id, dtype=object))
        scns.append(np.full(clip.n_segments, clip.scene, dtype=object))
    T, y, cid, scn = np.concatenate(targ), np.concatenate(ys), np.concatenate(cids), np.concatenate(scns)
    if not T.any():
        return {**base, "n_clips": len(items), "n_targeted": 0,
                "status": "not run: no test segment where the drone clip's sensor observes the drone"}
    x = (np.concatenate([p.mfcc for p in parts]), np.concatenate([p.video for p in parts]),
         np.concatenate([p.rf for p in parts]))
    offsets = np.cumsum([0] + [ctx.prep.clips[i].n_segments for i in ctx.test])
    pos = {i: k for k, i in enumerate(ctx.test)}
    rows = np.concatenate([np.arange(offsets[pos[i]], offsets[pos[i] + 1]) for i, _ in items])
    m_idx = [MODALITIES.index(m) for m in mods]
    flips, conf, C, FB, dis = [], [], [], [], []
    acc: dict[str, list[float | None]] = {}
    dis_acc: dict[str, list[float | None]] = {"ds": [], "average": []}
    where = []
    runs_c: list[dict[str, np.ndarray]] = []        # per training run: each rule's correctness on T
    for run in ctx.runs:
        full = ctx.outputs("clean", 0, run=run)
        clean = Outputs(full.logit[:, rows], full.alpha[:, rows], full.emb[:, rows])
        out = clean
        swapped = encode(ctx.trained[run], *x, only=tuple(mods))
        for m in m_idx:
            out = out.replace(m, swapped)
        v_clean = clean.alpha[m_idx].argmax(-1)[:, T]             # (k, n_targeted)
        v_prog = out.alpha[m_idx].argmax(-1)[:, T]
        flips.append(float((v_clean != v_prog).mean()))
        p_prog = out.alpha[m_idx] / out.alpha[m_idx].sum(-1, keepdims=True)
        conf.append(float(p_prog[..., 1 - want][:, T].mean()))    # probability of the WRONG class
        ds = fuse("ds", out.alpha, cfg.fusion.c_max, cfg.fusion.construction)
        if ds.conflict is None or ds.fallback is None:
            raise ValueError("the DS prediction has no conflict or fallback record")
        C.append(ds.conflict[T])
        FB.append(ds.fallback[T])
        preds = _rule_preds(ctx, run, out, cid)
        for rule, pr in preds.items():
            acc.setdefault(rule, []).append(float((pr[T] == y[T]).mean()) if T.any() else None)
        differ = (preds["ds"] != preds["average"]) & T
        dis.append(float(differ[T].mean()) if T.any() else 0.0)
        for rule in ("ds", "average"):
            dis_acc[rule].append(float((preds[rule][differ] == y[differ]).mean()) if differ.any() else None)
        if run == 0 and differ.any():
            for k in np.flatnonzero(differ)[:5]:
                seg = int(k - np.flatnonzero(cid == cid[k])[0])
                where.append({"clip": str(cid[k]), "segment": seg, "label": int(y[k]),
                              "ds": int(preds["ds"][k]), "average": int(preds["average"][k]),
                              "alpha": np.round(out.alpha[:, k], 3).tolist()})
        runs_c.append({r: (preds[r] == y)[T] for r in ("ds", "average")})
    Cs = np.concatenate(C)
    flip = float(np.mean(flips))
    status = ("inert" if flip < cc.inert_flip_rate else
              "bites" if flip >= cc.min_flip_rate else "weak (flips fewer than the target share)")
    ds_c = np.mean([r["ds"] for r in runs_c], axis=0)
    av_c = np.mean([r["average"] for r in runs_c], axis=0)
    comp = compare(ctx, f"DS vs average, {prog.key} targeted segments", ds_c, av_c, scn[T],
                   f"conflict {prog.key}: ds vs average")
    edges = np.linspace(0.0, 1.0, 21)

    def mean_or_none(v):
        v = [a for a in v if a is not None]
        return float(np.mean(v)) if v else None

    return {**base, "n_clips": len(items), "n_targeted": int(T.sum()), "n_segments": len(T),
            "flip_rate": flip, "flip_rate_std_training": float(np.std(flips)),
            "wrong_class_probability": float(np.mean(conf)), "status": status,
            "ds_conflict": {"mean": float(Cs.mean()) if Cs.size else None,
                            "quantiles": np.quantile(Cs, [0.1, 0.5, 0.9]).tolist() if Cs.size else None,
                            "hist": np.histogram(Cs, edges)[0].tolist(), "edges": edges.tolist()},
            "fallback_rate": float(np.concatenate(FB).mean()) if Cs.size else None,
            "accuracy": {r: mean_or_none(v) for r, v in acc.items()},
            "ds_average_disagree_rate": float(np.mean(dis)),
            "ds_average_disagree_accuracy": {r: mean_or_none(v) for r, v in dis_acc.items()},
            "disagreements": where, "ds_vs_average": comp}


def stage_conflict(ctx: Context) -> dict:
    """Conflict study: twin-swap programs (realised flip rate, wrong-class confidence, DS conflict C,
    fallback, each rule's accuracy on the targeted segments, where DS and averaging disagree), and
    any listed legacy programs measured the same way (flip rate of the compromised modality)."""
    t0 = time.perf_counter()
    cc = ctx.cfg.conflict
    progs = list(cc.swaps)
    warm_clean(ctx)
    results = dict(map_groups(ctx, list(range(len(progs))), (progs,), "conflict study", job=_conflict_job))
    rows = [results[k] for k in range(len(progs))]          # in program order (deterministic)
    legacy = [_legacy_program(ctx, name) for name in cc.programs]
    decisive = [r["program"] for r in rows if r.get("ds_average_disagree_rate", 0.0) > 0.0]
    result = {"programs": rows, "legacy_programs": legacy,
              "programs_where_ds_and_average_differ": decisive,
              "all_bite": all(r.get("status") == "bites" for r in rows) if rows else None,
              "onset_fraction": cc.onset_fraction, "duration_fraction": cc.duration_fraction,
              "c_max": ctx.cfg.fusion.c_max, "runs": len(ctx.runs)}
    write_json(ctx.run_dir / "conflict.json", result)
    flat = [{k: v for k, v in r.items() if not isinstance(v, (dict, list))} for r in rows + legacy]
    write_csv(ctx.run_dir / "conflict.csv", flat)
    mark_stage(ctx.run_dir, "conflict", time.perf_counter() - t0)
    return result


def _conflict_job(k: int, extra: tuple) -> tuple[int, dict]:
    """The realised effect of program ``k`` (in a worker)."""
    ctx = job_context()
    (progs,) = extra
    torch.set_num_threads(ctx.cfg.models.torch_threads)
    return k, _swap_program(ctx, progs[k])


def _legacy_program(ctx: Context, program: str) -> dict:
    """An older degradation-based program on every test clip (run 0): flip rate of the compromised
    modality's vote on the segments the program marks compromised."""
    cfg, cc = ctx.cfg, ctx.cfg.conflict
    seed = cfg.protocol.noise_seeds[0]
    degs, flags = [], []
    for i in ctx.test:
        clip = ctx.prep.clips[i]
        dur = clip.n_segments * 0.25
        d, f = conflict_clip(clip, i, seed, program, cc.onset_fraction * dur, cc.duration_fraction * dur,
                             cc.severity, ctx.prep.rf_range_db)
        degs.append(d)
        flags.append(f)
    out = encode(ctx.trained[0], np.concatenate([d.mfcc for d in degs]), np.concatenate([d.video for d in degs]),
                 np.concatenate([d.rf for d in degs]))
    clean = ctx.outputs("clean", 0)
    res: dict[str, Any] = {"program": program, "kind": "legacy"}
    for m, modality in enumerate(MODALITIES):
        comp = np.concatenate([f["compromised"][modality] for f in flags])
        if comp.any():
            flip = float((out.alpha[m].argmax(-1)[comp] != clean.alpha[m].argmax(-1)[comp]).mean())
            res.update({"modality": modality, "n_targeted": int(comp.sum()), "flip_rate": flip,
                        "status": "inert" if flip < cc.inert_flip_rate else
                        "bites" if flip >= cc.min_flip_rate else "weak (flips fewer than the target share)"})
    return res
