"""Statistics and headline answers of a detection run, from its tables alone (re-runnable without
the models): per-condition tables, paired comparisons, uncertainty rankings, vacuity against
thermal contrast, and the four headline questions decided by the one verdict rule."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from harness.experiments.detection.config import (
    CONDITIONS,
    DetectionConfig,
    condition_keys,
    load_detection_config,
    split_key,
)
from harness.runfolder import write_json

_TEXT_FIELDS = {"set", "sequence", "key", "stream"}


def _read_rows(path: Path) -> list[dict[str, Any]]:
    import csv

    def conv(k: str, v: str) -> Any:
        if k in _TEXT_FIELDS:
            return v
        if v in ("True", "False"):
            return v == "True"
        if v == "":
            return float("nan")
        try:
            return float(v)
        except ValueError:
            return v

    with open(path, newline="") as fh:
        return [{k: conv(k, v) for k, v in row.items()} for row in csv.DictReader(fh)]


def summarise_run(run_dir: Path) -> dict[str, Any]:
    """Statistics and headline answers from a run folder's tables (re-runnable without the models)."""
    run_dir = Path(run_dir)
    cfg = load_detection_config(json.loads((run_dir / "config.json").read_text()))
    t = run_dir / "tables"
    tools = json.loads((t / "tools.json").read_text())
    fitted = json.loads((run_dir / "fitted.json").read_text())
    summary = summarise(cfg, _read_rows(t / "per_sequence.csv"), _read_rows(t / "detections.csv"),
                        _read_rows(t / "crops.csv"),
                        _read_rows(t / "frames.csv"), tools["ap50"], tools["mot"], fitted["tracking"], fitted["gate"])
    summary["gate_timing"] = json.loads((t / "gate_timing.json").read_text())
    summary["headline"] = headline(summary, cfg)
    write_json(run_dir / "metrics.json", summary)
    return summary


# ------------------------------------------------------------------------------------ summaries
def _mean(rows: list[dict], field: str) -> float:
    v = np.array([r[field] for r in rows if r.get(field) is not None], float)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else float("nan")


def summarise(cfg, per_seq, det_rows, crop_rows, frame_rows, ap50, mot, fitted, gate) -> dict[str, Any]:
    from evids.metrics import detection_ece
    from harness.experiments.detection import metrics as M

    seed, nb = cfg.bootstrap.seed, cfg.bootstrap.n_resamples
    nb_u = cfg.bootstrap.n_resamples_uauc
    keys = condition_keys(cfg)
    sets = sorted({r["set"] for r in per_seq})
    table = []
    for set_name in sets + ["all"]:
        for key in keys:
            rows = [r for r in per_seq if r["key"] == key and (set_name == "all" or r["set"] == set_name)]
            if not rows:
                continue
            dets = [r for r in det_rows if r["key"] == key and (set_name == "all" or r["set"] == set_name)]
            row = {"set": set_name, "key": key, "n_sequences": len(rows), "state_acc": _mean(rows, "state_acc"),
                   "state_acc_penalised": _mean(rows, "state_acc_penalised"),
                   "acc_thermal_blind": _mean(rows, "acc_thermal_blind"), "acc_rgb_blind": _mean(rows, "acc_rgb_blind"),
                   "trk_on_abs": _mean(rows, "trk_on_abs"), "tracker_share": _mean(rows, "tracker_share")}
            if set_name != "all":
                row["ap50"] = ap50.get(f"{set_name}|{key}", float("nan"))
                m = mot.get(f"{set_name}|{key}", {})
                if "COMBINED_SEQ" in m:
                    row.update({k: m["COMBINED_SEQ"][k] for k in ("mota", "idf1", "hota", "ids")})
            if dets:
                s = np.array([d["score"] for d in dets])
                tp = np.array([d["tp"] for d in dets])
                row["det_ece"] = detection_ece(s, tp)
                row["n_detections"], row["n_tp"] = len(dets), int(tp.sum())
            table.append(row)
    # paired comparisons on per-sequence plain state accuracy (and thermal-blind frames)
    pairs = [("b_evidential/rgb", "a_sigmoid/rgb"), ("b_evidential/thermal", "a_sigmoid/thermal"),
             ("c_evidential_tau/rgb", "b_evidential/rgb"), ("c_evidential_tau/thermal", "b_evidential/thermal"),
             ("e_ds/fused", "d_average/fused"), ("e_ds/fused", "g_feature_fusion/fused"),
             ("f_ds_gated/fused", "e_ds/fused"), ("h_feature_fusion_ts/fused", "g_feature_fusion/fused"),
             ("e_ds/fused", "b_evidential/rgb"), ("d_average/fused", "g_feature_fusion/fused")]
    comps = []
    for set_name in sets + ["all"]:
        for a, b in pairs:
            for field in ("state_acc", "acc_thermal_blind"):
                ra = {r["sequence"]: r[field] for r in per_seq if r["key"] == a
                      and (set_name == "all" or r["set"] == set_name)}
                rb = {r["sequence"]: r[field] for r in per_seq if r["key"] == b
                      and (set_name == "all" or r["set"] == set_name)}
                common = sorted(set(ra) & set(rb))
                if len(common) < 2:
                    continue
                c = M.paired_comparison([ra[s] for s in common], [rb[s] for s in common], seed, nb)
                comps.append({"set": set_name, "a": a, "b": b, "metric": field, **c})
    # uncertainty ranking at anchor level (decoded detections) and at crop level
    unc = []
    for key in keys:
        dets = [d for d in det_rows if d["key"] == key]
        if not dets:
            continue
        area = np.array([d["area"] for d in dets])
        strata = M.area_stratum(area)
        for stratum in ["all"] + [s for s, _, _ in M.AREA_STRATA]:
            sel = np.ones(len(dets), bool) if stratum == "all" else strata == stratum
            if sel.sum() == 0:
                continue
            err = ~np.array([d["tp"] for d in dets])[sel]
            cl = np.array([d["sequence"] for d in dets])[sel]
            scores = {"confidence": 1.0 - np.array([d["score"] for d in dets])[sel],
                      "entropy": np.array([d["entropy"] for d in dets])[sel]}
            if split_key(key)[0].evidential:
                scores["vacuity"] = np.array([d["unc"] for d in dets])[sel]
                tps = ~err
                mean_u_tp = float(scores["vacuity"][tps].mean()) if tps.any() else np.nan
                mean_u_fp = float(scores["vacuity"][err].mean()) if err.any() else np.nan
            else:
                mean_u_tp = mean_u_fp = np.nan
            for name, u in scores.items():
                unc.append({"level": "anchor", "key": key, "stratum": stratum, "score": name,
                            "mean_u_tp": mean_u_tp if name == "vacuity" else np.nan,
                            "mean_u_fp": mean_u_fp if name == "vacuity" else np.nan,
                            **M.clustered_uauc(u, err, cl, seed, nb_u)})
    for stream in ("rgb", "thermal"):
        rows = [r for r in crop_rows if r["stream"] == stream]
        if not rows:
            continue
        strata = M.area_stratum(np.array([r["area"] for r in rows]))
        for stratum in ["all"] + [s for s, _, _ in M.AREA_STRATA]:
            sel = np.ones(len(rows), bool) if stratum == "all" else strata == stratum
            if sel.sum() == 0:
                continue
            err = ~np.array([r["tp"] for r in rows])[sel]
            cl = np.array([r["sequence"] for r in rows])[sel]
            for name in ("anchor_u", "crop_u", "crop_u_avg", "crop_u_ds_identical"):
                u = np.array([r[name] for r in rows], float)[sel]
                ok = np.isfinite(u)
                if ok.sum() == 0:
                    continue
                unc.append({"level": "crop" if name != "anchor_u" else "anchor (same detections)",
                            "key": f"b_evidential/{stream}",
                            "stratum": stratum, "score": name, **M.clustered_uauc(u[ok], err[ok], cl[ok], seed, nb_u)})
    # thermal vacuity against |dT| / NETD on frames with the target in the thermal frame
    fr = [r for r in frame_rows if r["exist_thermal"] and np.isfinite(r["contrast_k"])
          and np.isfinite(r["thermal_u_at_target"])]
    vac: dict[str, Any] = {}
    if fr:
        ratio = np.array([abs(r["contrast_k"]) / r["netd_k"] for r in fr])
        u = np.array([r["thermal_u_at_target"] for r in fr])
        p = np.array([r["thermal_p_at_target"] for r in fr])
        cl = np.array([r["sequence"] for r in fr])
        vac["spearman_u"] = M.spearman_clustered(ratio, u, cl, seed, nb_u)
        vac["spearman_p"] = M.spearman_clustered(ratio, p, cl, seed, nb_u)
        bins = [0, 1, 2, 4, 8, 16, 1e9]
        vac["bins"] = [{"lo": lo, "hi": hi, "n": int(((ratio >= lo) & (ratio < hi)).sum()),
                        "mean_u": float(u[(ratio >= lo) & (ratio < hi)].mean()) if ((ratio >= lo) & (ratio < hi)).any()
                        else np.nan,
                        "mean_p": float(p[(ratio >= lo) & (ratio < hi)].mean()) if ((ratio >= lo) & (ratio < hi)).any()
                        else np.nan}
                       for lo, hi in zip(bins[:-1], bins[1:])]
        vac["points"] = {"ratio": ratio.tolist(), "u": u.tolist(), "set": [r["set"] for r in fr]}
    conflict = {}
    for set_name in sets:
        cv = np.array([r["ds_conflict_at_target"] for r in frame_rows if r["set"] == set_name and r["exist"]], float)
        cv = cv[np.isfinite(cv)]
        if cv.size:
            conflict[set_name] = {"mean": float(cv.mean()), "p90": float(np.quantile(cv, 0.9)), "max": float(cv.max()),
                                  "n": int(cv.size)}
    obs = {}
    for set_name in sets:
        rows = [r for r in frame_rows if r["set"] == set_name and r["exist"]]
        obs[set_name] = {"frames_with_target": len(rows), "rgb_observed": _mean(rows, "rgb_observed"),
                         "thermal_observed": _mean(rows, "thermal_observed"),
                         "absent_frames": sum(1 for r in frame_rows if r["set"] == set_name and not r["exist"]),
                         "sequences": len({r["sequence"] for r in frame_rows if r["set"] == set_name})}
    gate_rows = [r for r in per_seq if r["key"] == "_gate"]
    gate_usage = {k: _mean(gate_rows, k)
                  for k in ("rgb_evaluated", "thermal_evaluated", "rgb_fused", "thermal_fused")} if gate_rows else None
    return {"table": table, "comparisons": comps, "uncertainty": unc, "vacuity_vs_contrast": vac,
            "ds_conflict_at_target": conflict, "observability": obs, "gate_usage": gate_usage, "fitted": fitted,
            "gate": gate, "conditions": {c: CONDITIONS[c] for c in cfg.conditions}}


def _verdict(c: dict | None, better: str, worse: str, unit: float = 100.0, what: str = "pp") -> str:
    """The numbers and the verdict of the one rule (evids.metrics.significance.comparison_verdict)."""
    from evids.metrics.significance import comparison_verdict, verdict_sentence

    if c is None or not np.isfinite(c.get("diff", np.nan)):
        return "not measured"
    txt = (f"{better} - {worse} = {c['diff'] * unit:+.2f} {what} (sequence-bootstrap 95% CI "
           f"[{c['ci_low'] * unit:+.2f}, {c['ci_high'] * unit:+.2f}], sign-flip p = {c['p']:.3f}, "
           f"n = {c['n']} sequences, "
           f"MDE {c['mde'] * unit:.2f} {what})")
    verdict = comparison_verdict(c["diff"], c["ci_low"], c["ci_high"], c["mde"])
    return txt + ": " + verdict_sentence(verdict, better, worse) + "."


def _comp(summary, set_name, a, b, metric="state_acc"):
    for c in summary["comparisons"]:
        if c["set"] == set_name and c["a"] == a and c["b"] == b and c["metric"] == metric:
            return c
    return None


def _unc(summary, level, key, score, stratum="all"):
    for u in summary["uncertainty"]:
        if u["level"] == level and u["key"] == key and u["score"] == score and u["stratum"] == stratum:
            return u
    return None


def _uauc_txt(u) -> str:
    if u is None or not np.isfinite(u.get("uauc", np.nan) if u.get("uauc") is not None else np.nan):
        return "not estimable (one class missing)"
    return f"{u['uauc']:.3f} [{u['ci_low']:.3f}, {u['ci_high']:.3f}] (n = {u['n']}, {u['n_error']} errors)"


def headline(summary: dict[str, Any], cfg: DetectionConfig) -> dict[str, str]:
    """The four headline questions, answered from the numbers by the one verdict rule (or 'undecided')."""
    xs = cfg.crossover_set
    out = {}
    q1 = [_verdict(_comp(summary, xs, "e_ds/fused", "d_average/fused"), "DS", "average"),
          _verdict(_comp(summary, xs, "e_ds/fused", "g_feature_fusion/fused"), "DS", "feature fusion"),
          "On thermal-blind frames only: " + _verdict(_comp(summary, xs, "e_ds/fused", "d_average/fused",
                                                            "acc_thermal_blind"),
                                                     "DS", "average")]
    out["q1_ds_through_crossover"] = f"State accuracy on the '{xs}' set. " + " ".join(q1)
    v = summary.get("vacuity_vs_contrast", {})
    if v.get("spearman_u"):
        s = v["spearman_u"]
        rises = s["ci_high"] < 0
        out["q2_thermal_vacuity_vs_dT"] = (
            f"Spearman rho(|dT|/NETD, thermal vacuity at the target cell) = {s['rho']:.3f} [{s['ci_low']:.3f}, "
            f"{s['ci_high']:.3f}] "
            f"over {s['n']} frames / {s.get('n_clusters', '?')} sequences: " +
            ("vacuity rises as |dT| falls toward the NETD." if rises else
             "vacuity does not rise as |dT| falls (the CI does not lie below 0)." if s["ci_low"] > 0
             or s["ci_high"] >= 0 else ""))
    else:
        out["q2_thermal_vacuity_vs_dT"] = "not measured (no evidential thermal condition)"
    parts = []
    for stream in ("rgb", "thermal"):
        a = _unc(summary, "anchor", f"b_evidential/{stream}", "vacuity")
        c = _unc(summary, "crop", f"b_evidential/{stream}", "crop_u")
        inv = a is not None and a.get("ci_high") is not None and np.isfinite(a["ci_high"]) and a["ci_high"] < 0.5
        rec = c is not None and c.get("ci_low") is not None and np.isfinite(c["ci_low"]) and c["ci_low"] > 0.5
        parts.append(f"{stream}: anchor-level vacuity UAUC {_uauc_txt(a)} "
                     f"({'inverted' if inv else 'no inversion established'}); "
                     f"crop-level {_uauc_txt(c)} "
                     f"({'recovered (CI above 0.5)' if rec else 'not recovered (CI includes or is below 0.5)'}).")
    out["q3_anchor_inversion_crop_recovery"] = " ".join(parts)
    g = summary.get("gate_timing")
    if g:
        acc = _comp(summary, "all", "f_ds_gated/fused", "e_ds/fused")
        out["q4_gating_saves_cpu"] = (
            f"Batch-1 CPU time per frame: {g['full_s_per_frame'] * 1e3:.1f} ms without the gate, "
            f"{g['gated_s_per_frame'] * 1e3:.1f} ms with it "
            f"(saving {g['saving'] * 100:.1f} %, {g['evaluated_fraction'] * 100:.1f} % of stream forwards run; load "
            f"average {g['loadavg_1m']:.1f}). "
            f"Accuracy cost: " + _verdict(acc, "gated", "ungated"))
    else:
        out["q4_gating_saves_cpu"] = "not measured (condition f not run)"
    return out
