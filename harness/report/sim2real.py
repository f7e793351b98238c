"""The sim-to-real section of the report: reads ``sim2real.json`` and the sheets of a run folder
(written by `evids sim2real`) and writes ``sim2real.html``; ``section_html`` is the same section for
embedding in another page."""
from __future__ import annotations

import base64
import html
import time
from pathlib import Path
from typing import Any

from harness.report.html import CSS, _table

STAT_LABELS = {
    "box_w_px": "box width (px)", "box_h_px": "box height (px)",
    "contrast": "target contrast |box - ring| (grey levels)",
    "peak": "target peak |box - ring median|", "background": "background level (median grey)",
    "row_gradient": "row gradient (bottom - top quarter)", "spatial_noise": "spatial noise (robust std)",
    "temporal_noise": "temporal noise (robust std / sqrt 2)", "absent_fraction": "target-absent fraction (per clip)",
}


def _ci(r: dict | None, signed: bool = False) -> str:
    if not r or r.get("estimate") is None:
        return "&ndash;"
    f = "{:+.3f}" if signed else "{:.3f}"
    s = f"{f.format(r['estimate'])} [{f.format(r['ci_low'])}, {f.format(r['ci_high'])}]"
    if r.get("mde") is not None:
        s += f" (MDE {r['mde']:.3f})"
    return s


def _iqr(r: dict | None) -> str:
    if not r:
        return "&ndash;"
    return f"{r['median']:.2f} [{r['q25']:.2f}, {r['q75']:.2f}]"


def _sheet(run_dir: Path, name: str, caption: str) -> str:
    p = run_dir / "sheets" / name
    if not p.is_file():
        return ""
    b64 = base64.b64encode(p.read_bytes()).decode("ascii")
    return (f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{b64}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _recall(classes: list[str], recall: list[float | None] | None) -> str:
    """"drone 0.81, bird 0.40, ..." (runs written before per-class recall was recorded: "")."""
    if not recall:
        return ""
    return ", ".join(f"{html.escape(c.lower())} {'-' if r is None else f'{r:.2f}'}" for c, r in zip(classes, recall))


def _confusion_rows(classes: list[str], confusion: list[list[int]], source: str) -> list[list[str]]:
    """One row per true class: its share called each class (row-normalised; "-" for an empty row)."""
    rows = []
    for cls, counts in zip(classes, confusion):
        total = sum(counts)
        shares = ["&ndash;" if not total else (f"<b>{c / total:.2f}</b>" if k == cls else f"{c / total:.2f}")
                  for c, k in zip(counts, classes)]
        rows.append([f"{source} {html.escape(cls)}", *shares])
    return rows


def _visual(run_dir: Path, sensor: str, res: dict[str, Any]) -> str:
    c = res["classifier"]
    n = res["n_clips"]
    parts = [f"<h3>{'IR (thermal)' if sensor == 'ir' else 'Visible'}</h3>",
             f"<p class='note'>Clips: {n['real_calibration']} real calibration, {n['real_evaluation']} real "
             "evaluation, "
             f"{n['synthetic']} synthetic sequences. Crop classifier ({', '.join(res['classes'])}; chance "
             f"{1 / len(res['classes']):.2f}) evaluated on {c['n_test_crops']} crops of the {c['n_test_clips']} "
             "evaluation clips; mean over training seeds, 95 % clip-bootstrap interval.</p>"]
    rows = [[html.escape(v.get("label", k)), _ci(v), ", ".join(f"{x:.3f}" for x in v["per_seed"]),
             _recall(res["classes"], v.get("recall")), str(c["train_sizes"].get(k, "")),
             str(c["train_clips"].get(k, ""))] for k, v in c["conditions"].items()]
    parts.append(_table(["condition", "balanced accuracy [95 % CI]", "per seed", "recall per class (mean over seeds)",
                         "training crops", "training clips"], rows))
    b_conf = c["conditions"].get("b_synthetic", {}).get("confusion")
    reverse = c.get("reverse_transfer")
    if b_conf or reverse:
        rows = _confusion_rows(res["classes"], b_conf, "real") if b_conf else []
        if reverse:
            rows += _confusion_rows(res["classes"], reverse["confusion"], "synthetic")
        parts.append(_table(["true class", *(f"called {html.escape(k.lower())}" for k in res["classes"])], rows)
                     + "<p class='note'>Where the errors go, shares of each row over the training seeds: rows "
                     "'real' are the real evaluation crops as the synthetic-only model (b) calls them; rows "
                     "'synthetic' are the synthetic crops as the real-trained model (a) calls them (which real "
                     "class each synthetic class resembles). Bold: the true class.</p>")
    rows = [[label, _ci(c.get(key), signed=key != "ratio_b_over_a")] for key, label in
            (("ratio_b_over_a", "ratio (b) / (a)"), ("gain_c_minus_a", "(c) - (a)"),
             ("gain_dplus_minus_d", "(d+) - (d)"))]
    parts.append(_table(["comparison", "estimate [95 % CI] (MDE: smallest difference this test detects)"], rows))
    det = res.get("detector", {})
    if det.get("conditions"):
        rows = [[f"trained on {k}", f"{v['ap50']:.3f}" if "ap50" in v else html.escape(v.get("note", "")),
                 ", ".join(f"{x:.3f}" for x in v.get("per_seed", [])), str(v.get("train_clips", ""))]
                for k, v in det["conditions"].items()]
        ratio = det.get("ratio_synthetic_over_real")
        parts.append(_table(["E1/E3 detector (sigmoid head)", "AP50 on the real evaluation half (pycocotools)",
                             "per seed",
                             "training clips"], rows)
                     + f"<p class='note'>{det['n_test_frames']} evaluation frames of {det['n_test_clips']} clips, "
                     f"{det['n_test_boxes']} boxes (all classes are "
                     f"'target').{f' Ratio synthetic / real: {ratio:.3f}.' if ratio else ''}</p>")
    d = res["domain_classifier"]
    parts.append(_table(["domain classifier (real calibration half vs synthetic, split by clip)",
                         "held-out balanced accuracy"],
                        [[f"{k}s", f"{v['accuracy']:.3f}" if v.get("accuracy") is not None else "&ndash;"]
                         for k, v in d.items()])
                 + "<p class='note'>0.5 = the classifier cannot tell real from synthetic.</p>")
    rows = []
    for cls, stats in res["statistics"].items():
        for stat, row in stats.items():
            inside = row["inside"]
            mark = "&ndash;" if inside is None else ("yes" if inside else "<b>no</b>")
            cal_inside = row.get("calibration_inside")
            cal_mark = "&ndash;" if cal_inside is None else ("yes" if cal_inside else "no")
            rows.append([f"{cls}", STAT_LABELS.get(stat, stat), _iqr(row["real_evaluation"]),
                         _iqr(row["real_calibration"]),
                         _iqr(row["synthetic"]), mark, cal_mark])
    flags = [row for stats in res["statistics"].values() for row in stats.values() if row["inside"] is not None]
    n_syn = sum(bool(row["inside"]) for row in flags)
    n_cal = sum(bool(row.get("calibration_inside")) for row in flags)
    n_all = len(flags)
    parts.append("<details open><summary>Per-class statistics: median [IQR]</summary>" +
                 _table(["class", "statistic", "real, evaluation half", "real, calibration half", "synthetic",
                         "synthetic median inside real IQR", "calibration median inside (null reference)"], rows)
                 + f"<p class='note'>Synthetic medians inside the real evaluation IQR: {n_syn} of {n_all}; the real "
                 f"calibration half's medians (a second set of real clips, the criterion's null reference): "
                 f"{n_cal} of {n_all}.</p></details>")
    files = res.get("sheets", {})
    for kind, caption in (("crops", "target crops"), ("backgrounds", "background patches"), ("frames", "whole frames")):
        if kind in files:
            parts.append(_sheet(run_dir, files[kind],
                                f"{sensor}: {caption}, real (calibration half) vs synthetic, per class"))
    if "reverse" in files:
        parts.append(_sheet(run_dir, files["reverse"],
                            f"{sensor}: synthetic crops grouped by what the real-trained model (a) calls them "
                            "(majority over its training seeds)"))
    return "\n".join(parts)


def _audio(run_dir: Path, res: dict[str, Any]) -> str:
    n = res.get("n_clips", {})
    parts = ["<h3>Audio: drone vs not drone (helicopter and background)</h3>",
             f"<p class='note'>Clips: {n.get('calibration')} real calibration, {n.get('evaluation')} real evaluation, "
             f"{n.get('synthetic')} synthetic; 1 s log-mel windows; training seeds {res.get('seeds')}; ROC-AUC and "
             "balanced accuracy on the evaluation half, mean over seeds, 95 % clip-bootstrap intervals.</p>"]
    for model, r in res.get("classifier", {}).items():
        rows = []
        for cond, v in r.items():
            if not isinstance(v, dict):
                continue
            ci, bci = v.get("roc_auc_ci95", [None, None]), v.get("balanced_accuracy_ci95", [None, None])
            heli = v.get("helicopter_called_drone")
            rows.append([html.escape(v.get("description", cond)), f"{v['roc_auc']:.3f} [{ci[0]:.3f}, {ci[1]:.3f}]",
                         f"{v['balanced_accuracy']:.3f} [{bci[0]:.3f}, {bci[1]:.3f}]",
                         "&ndash;" if heli is None else f"{100 * heli:.0f} %"])
        parts.append(_table([f"{model}: condition", "ROC-AUC [95 % CI]", "balanced accuracy",
                             "helicopter windows called drone"], rows))
        comp = []
        for key, label in (("ratio_synthetic_over_real_auc", "ratio (b)/(a) AUC"),
                           ("synthetic_plus_real_gain_auc", "(c) - (a) AUC"),
                           ("few_shot_gain_auc", "(d+) - (d) AUC")):
            if key not in r:
                continue
            ci = r.get({"ratio_synthetic_over_real_auc": "ratio_ci95",
                        "synthetic_plus_real_gain_auc": "synthetic_plus_real_gain_ci95",
                        "few_shot_gain_auc": "few_shot_gain_ci95"}[key], [float("nan")] * 2)
            mde = r.get(key.replace("_auc", "_mde"))
            comp.append([label, f"{r[key]:+.3f} [{ci[0]:+.3f}, {ci[1]:+.3f}]"
                         + (f" (MDE {mde:.3f})" if mde is not None else "")])
        parts.append(_table(["comparison", "estimate [95 % CI]"], comp))
    inside = res.get("statistics_inside_real_iqr", {})
    if inside:
        parts.append("<p class='note'>Spectral statistics with the synthetic median inside the real evaluation half's "
                     "IQR: "
                     + ", ".join(f"{k} {v['inside']} of {v['of']}" for k, v in inside.items())
                     + "; the real calibration half's medians on the same test (a second set of real recordings, "
                     "the criterion's null reference): "
                     + ", ".join(f"{k} {v.get('calibration_inside', '-')} of {v['of']}" for k, v in inside.items())
                     + " (all values in sim2real.json).</p>")
    fig = res.get("figure")
    if fig:
        parts.append(_sheet(run_dir, Path(fig).name, "spectrograms, real (calibration half) | synthetic per class"))
    return "\n".join(parts)


def section_html(run_dir: Path, summary: dict[str, Any]) -> str:
    parts = ["<h2>Sim-to-real: the Svanström benchmark</h2>",
             "<p class='note'>Split rule: real clips with an odd number are the calibration half (training, fitting, "
             "looking); even numbers the evaluation half (every number below). Real clips skipped by the reader's "
             f"checks: {len(summary.get('skipped_clips', []))}.</p>"]
    if summary.get("test_half") == "calibration":
        parts.append("<p class='note'><b>Tuning run (<code>--tune</code>): the evaluation half was not read.</b> "
                     "Every figure called 'evaluation' below is the real calibration half: crop classifiers "
                     "cross-fitted over its two folds (runs of 5 consecutive clip numbers; each fold scored by models "
                     "trained on the other), statistics against its own IQR (the 'synthetic median inside' column), "
                     "the synthetic-trained detector scored on it (no real-trained one); audio: fold 0 tested, fold 1 "
                     "trained. Judge a change with two such runs, then make the one evaluation run.</p>")
    failures = summary.get("synthetic_failures") or {}
    if failures:
        parts.append("<p class='note'><b>Synthetic sequences that failed to render and are left out:</b> "
                     + "; ".join(f"{html.escape(cls)} {html.escape(n)}: {html.escape(m)}"
                                 for cls, f in failures.items() for n, m in sorted(f.items())) + "</p>")
    for sensor, res in summary["sensors"].items():
        parts.append(_audio(run_dir, res) if sensor == "audio" else _visual(run_dir, sensor, res))
    t = summary.get("timings_s", {})
    parts.append("<p class='note'>Stage times (s): " + ", ".join(f"{k} {v:.0f}" for k, v in t.items()) + "</p>")
    return "\n".join(parts)


def write_page(run_dir: Path, summary: dict[str, Any]) -> Path:
    from simulator.files import write_atomic

    doc = ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>evids sim2real</title>"
           f"<style>{CSS}</style></head><body><h1>evids sim-to-real report</h1><p class='note'>Built "
           f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
           f"{' (--quick: toy scale)' if summary.get('quick') else ''}."
           f"</p>{section_html(run_dir, summary)}</body></html>")
    out = Path(run_dir) / "sim2real.html"
    write_atomic(out, doc)
    return out
