"""The "real benchmark" report section (`evids realbench`): per-sensor scores (a/b/c x softmax /
evidential) on the real evaluation half, the sweep-agreement figure (real drop vs synthetic drop per
degradation x severity cell, identity line), the disagreeing and inert cells, and example crops."""
from __future__ import annotations

import base64
import html
import io
from pathlib import Path
from typing import Any

import numpy as np

from harness.report.html import CSS, _table

METRIC_LABELS = {"balanced_accuracy": "balanced accuracy", "ece": "ECE", "uauc_vacuity": "UAUC vacuity",
                 "uauc_entropy": "UAUC entropy", "uauc_confidence": "UAUC 1 - confidence"}
SENSOR_LABELS = {"ir": "IR (thermal) crops", "visible": "Visible crops", "audio": "Audio, drone vs not-drone"}


def _ci(r: dict | None, signed: bool = False, digits: int = 3) -> str:
    if not r or r.get("estimate") is None or not np.isfinite(r["estimate"]):
        return "&ndash;"
    f = f"{{:+.{digits}f}}" if signed else f"{{:.{digits}f}}"
    s = f"{f.format(r['estimate'])} [{f.format(r['ci_low'])}, {f.format(r['ci_high'])}]"
    if r.get("mde") is not None and np.isfinite(r["mde"]):
        s += f" MDE {r['mde']:.{digits}f}"
    return s


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80, metadata={"Software": None})
    return buf.getvalue()


def agreement_figure(summary: dict[str, Any]) -> bytes | None:
    """Real drop vs synthetic drop (points, own-domain evidential models) per cell and sensor."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sensors = [(s, r["sweep"]["own_domain"]["evidential"]) for s, r in summary["sensors"].items()
               if "sweep" in r and "own_domain" in r["sweep"]]
    if not sensors:
        return None
    fig, axes = plt.subplots(1, len(sensors), figsize=(4.2 * len(sensors), 4.0), squeeze=False)
    for ax, (sensor, res) in zip(axes[0], sensors):
        xs = np.array([c["drop_synthetic"]["estimate"] for c in res["cells"]])
        ys = np.array([c["drop_real"]["estimate"] for c in res["cells"]])
        xe = np.array([[c["drop_synthetic"]["estimate"] - c["drop_synthetic"]["ci_low"],
                        c["drop_synthetic"]["ci_high"] - c["drop_synthetic"]["estimate"]] for c in res["cells"]]).T
        ye = np.array([[c["drop_real"]["estimate"] - c["drop_real"]["ci_low"],
                        c["drop_real"]["ci_high"] - c["drop_real"]["estimate"]] for c in res["cells"]]).T
        bad = np.array([c["disagree"] for c in res["cells"]])
        for mask, colour, lab in ((~bad, "tab:blue", "agree"), (bad, "tab:red", "disagree (CI excludes 0)")):
            if mask.any():
                ax.errorbar(xs[mask], ys[mask], xerr=np.nan_to_num(xe[:, mask]), yerr=np.nan_to_num(ye[:, mask]),
                            fmt="o", ms=4, color=colour, ecolor="0.7", lw=0.8, label=lab)
        ends = np.r_[xs - np.nan_to_num(xe[0]), ys - np.nan_to_num(ye[0]), xs + np.nan_to_num(xe[1]),
                     ys + np.nan_to_num(ye[1]), 0.0, 1.0]
        lo, hi = float(np.nanmin(ends)) - 2, float(np.nanmax(ends)) + 2
        ax.plot([lo, hi], [lo, hi], "k--", lw=0.8, label="identity")
        rho = res["spearman"]
        title = f"{sensor}: Spearman {rho['estimate']:.2f}"
        if res.get("at_chance"):     # a domain's model at chance: its drops measure nothing
            title += f"\nNOT INFORMATIVE ({' and '.join(res['at_chance'])} model at chance)"
        ax.set_title(title, fontsize=10, color="tab:red" if res.get("at_chance") else "black")
        ax.set_xlabel("synthetic accuracy drop (points)")
        ax.set_ylabel("real accuracy drop (points)")
        ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    data = _png(fig)
    plt.close(fig)
    return data


def examples_figure(examples: dict[str, Any]) -> bytes | None:
    """Example crops, per sensor and domain: clean, then each degradation at its top severity."""
    import cv2

    rows = []
    for sensor, ex in examples.items():
        if not ex:
            continue
        for domain, cells in ex.items():
            tiles = []
            for _, crops in cells.items():
                im = crops[0] if len(crops) else np.zeros((32, 32), np.uint8)
                im = im if im.ndim == 3 else np.repeat(im[..., None], 3, axis=2)
                tiles.append(cv2.resize(im, (64, 64), interpolation=cv2.INTER_NEAREST))
            row = np.concatenate(tiles, axis=1)
            bar = np.full((16, row.shape[1], 3), 255, np.uint8)
            cv2.putText(bar, f"{sensor} {domain}: clean | " + " | ".join(c.split("@")[0].split(".")[-1]
                                                                          for c in list(cells)[1:]),
                        (2, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
            rows.append(np.concatenate([bar, row], axis=0))
    if not rows:
        return None
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(np.concatenate(rows, axis=0)[..., ::-1]))
    return buf.tobytes() if ok else None


def _img(data: bytes | None, caption: str) -> str:
    if not data:
        return ""
    b64 = base64.b64encode(data).decode("ascii")
    return (f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{b64}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _sensor(sensor: str, res: dict[str, Any]) -> str:
    if "scores" not in res:
        return f"<h3>{SENSOR_LABELS.get(sensor, sensor)}</h3><p class='note'>{html.escape(str(res))}</p>"
    n = res["n_eval"]
    parts = [f"<h3>{SENSOR_LABELS.get(sensor, sensor)}</h3>",
             f"<p class='note'>Real evaluation half: {n['real']['clips']} clips, {n['real']['rows']} inputs; "
             f"synthetic evaluation half: {n['synthetic']['clips']} clips, {n['synthetic']['rows']} inputs. "
             f"Classes: {', '.join(res['classes'])}. Training inputs: "
             + ", ".join(f"{k} {v}" for k, v in res["n_train"].items()) + ".</p>"]
    rows = [[html.escape(k)] + [_ci(v[m]) for m in METRIC_LABELS] for k, v in res["scores"]["models"].items()]
    parts.append(_table(["model (condition/head)", *METRIC_LABELS.values()], rows))
    rows = [[html.escape(k)] + [_ci(v[m], signed=True) for m in ("balanced_accuracy", "ece")]
            for k, v in res["scores"]["differences"].items()]
    parts.append(_table(["paired difference", "balanced accuracy", "ECE"], rows))
    for run, title in (("own_domain", "each domain through its own model: real (a), synthetic (b)"),
                       ("mixed", "both domains through the mixed model (c)")):
        sw = res["sweep"].get(run, {}).get("evidential")
        if not sw:
            continue
        parts.append(f"<h4>Sweep agreement, {title} (evidential head)</h4>")
        ref = res["sweep"].get("clean_balanced_accuracy", {})
        cr, cs = ("a_real", "b_synthetic") if run == "own_domain" else ("c_both", "c_both")
        if ref:
            parts.append("<p class='note'>Clean balanced accuracy, the reference of every drop: real "
                         f"{_ci(ref.get('real', {}).get(cr, {}).get('evidential'))}, synthetic "
                         f"{_ci(ref.get('synthetic', {}).get(cs, {}).get('evidential'))}.</p>")
        parts.append(_table(["Spearman of drops", "median |drop real - drop synthetic| (points)",
                             "same-sign vacuity change", "cells"],
                            [[_ci(sw["spearman"]), _ci(sw["median_abs_drop_difference_points"], digits=1),
                              _ci(sw.get("vacuity_same_sign_fraction")), str(sw["n_cells"])]]))
        if sw.get("at_chance"):
            who = html.escape(" and ".join(sw["at_chance"]))
            parts.append("<p style='color:#a00'><b>Not informative:</b> the " + who
                         + " model is at chance on its clean inputs (95 % interval reaches chance), so a degradation "
                         "has nothing to take away: the drops of that domain, and every agreement figure below, "
                         "measure nothing.</p>")
        bad = sw["disagreeing_cells"]
        parts.append("<p><b>Disagreeing cells</b> (real - synthetic drop, 95 % CI excludes 0; do not trust these "
                     "synthetic stress tests for this sensor): "
                     + (html.escape("; ".join(bad)) if bad else "none") + ".</p>")
        inert = sw["inert"]
        parts.append("<p><b>Inert</b> (no measurable drop or vacuity change at the top severity): real: "
                     + html.escape(", ".join(inert["real"]) or "none") + "; synthetic: "
                     + html.escape(", ".join(inert["synthetic"]) or "none") + ".</p>")
        rows = [[html.escape(c["label"]), _ci(c["drop_real"], True, 1), _ci(c["drop_synthetic"], True, 1),
                 _ci(c["drop_difference"], True, 1), _ci(c.get("vacuity_change_real"), True),
                 _ci(c.get("vacuity_change_synthetic"), True)] for c in sw["cells"]]
        parts.append("<details><summary>every cell</summary>" + _table(
            ["cell", "drop real (points)", "drop synthetic", "real - synthetic", "vacuity change real",
             "vacuity change synthetic"], rows) + "</details>")
    return "\n".join(parts)


def _conflict(res: dict[str, Any]) -> str:
    """The "Conflict programs on pseudo-triplets" table: one row per reading x domain x program x rule."""
    parts = ["<h3>Conflict programs on pseudo-triplets</h3>", f"<p><b>{html.escape(res['note'])}</b></p>"]
    if "status" in res:
        return "\n".join(parts + [f"<p class='note'>{html.escape(res['status'])}</p>"])
    audio = ", ".join(f"{k} &rarr; {v}" for k, v in res["audio_class_of"].items())
    parts.append(
        f"<p class='note'>Per domain, {res['n_triplets_requested']} triplets of the sensors "
        f"{html.escape(', '.join(res['sensors']))} drawn with replacement from the evaluation half, half drone and "
        "half not drone; the audio clip of a triplet is of the class "
        f"{audio} (the audio set has no birds or airplanes). Synthetic IR and visible crops of a triplet come from "
        "one generated sequence (synchronised). Each sensor's input is its evidential model's clip opinion "
        "coarsened to {not drone, drone}. Program <i>blind m</i>: sensor m's opinion is replaced by that of a twin "
        "clip of the opposite label from the same domain's evaluation half. Rules: "
        + "; ".join(f"{html.escape(k)} = {html.escape(v)}" for k, v in res["rules"].items())
        + f" (c_max {res['c_max']:g}, the experiment default). 95 % intervals from {res['bootstrap']} bootstrap "
        "resamples of the triplets (within label); they do not include the sampling of the clip pool itself. "
        f"<b>Inert</b>: the compromised sensor's realised vote-flip rate is below {res['inert_flip_rate']:g} or its "
        "interval reaches 0; the program did not test the fusion there.</p>")
    for reading, title in (("own_domain", "each domain through its own models: real (a), synthetic (b)"),
                           ("mixed", "both domains through the mixed models (c)")):
        out = res["readings"].get(reading)
        if not out:
            continue
        rows = []
        for domain in ("real", "synthetic"):
            d = out.get(domain)
            if d is None or "status" in d:
                rows.append([domain, "&ndash;", html.escape(d["status"] if d else "not run")] + ["&ndash;"] * 5)
                continue
            for r in res["rules"]:
                rows.append([f"{domain} ({d['n_triplets']})", "none (clean)", "&ndash;", html.escape(r),
                             "&ndash;", _ci(d["clean"]["accuracy"][r]), "&ndash;", _ci(d["clean"]["ds_conflict"])])
            for name, p in d["programs"].items():
                if "rules" not in p:
                    rows.append([domain, html.escape(name), html.escape(p["note"])] + ["&ndash;"] * 5)
                    continue
                flip = _ci(p["sensor_flip_rate"]) + (" <b>inert</b>" if p["inert"] else "")
                for r, v in p["rules"].items():
                    rows.append([f"{domain} ({d['n_triplets']})", html.escape(name), flip, html.escape(r),
                                 _ci(v["fused_flip_rate"]), _ci(d["clean"]["accuracy"][r]), _ci(v["accuracy"]),
                                 _ci(p["ds_conflict"])])
        tab = _table(["domain (triplets)", "program", "compromised sensor's vote flips", "rule", "fused flips",
                      "fused accuracy clean", "fused accuracy under program", "mean DS conflict"], rows)
        diff = out.get("real_minus_synthetic_fused_flip_rate", {})
        drows = [[html.escape(p), html.escape(r), _ci(v, signed=True)] for p, rules in diff.items()
                 for r, v in rules.items()]
        body = f"<h4>Pseudo-triplets, {title}</h4>" + tab + (
            _table(["program", "rule", "real - synthetic fused flip rate (MDE)"], drows) if drows else "")
        parts.append(body if reading == "own_domain" else f"<details><summary>{title}</summary>{body}</details>")
    return "\n".join(parts)


def section_html(summary: dict[str, Any], examples: dict[str, Any] | None = None) -> str:
    parts = ["<h2>Real benchmark: the evidential pipeline on the Svanström clips beside the generated scenarios</h2>",
             "<p class='note'>" + html.escape(summary["split_rule"]) + ". Every figure is on an evaluation half; "
             f"means over training seeds {summary['seeds']}, {summary['train_steps']} fixed training steps (nothing "
             f"chosen on held-out data); 95 % intervals from {summary['bootstrap']} clip-bootstrap resamples "
             "(clips drawn within class), MDE = 2.8 x the bootstrap SD of a paired difference. Degradations at "
             f"severities {summary['severities']} act on the classifier's 32-px crop (visual) or the whole clip "
             "(audio).</p>",
             _img(agreement_figure(summary), "Sweep agreement: accuracy drop on real vs synthetic evaluation inputs, "
                                             "each through its own-domain evidential model; one point per "
                                             "degradation x severity, 95 % CIs, dashed identity line")]
    for sensor, res in summary["sensors"].items():
        parts.append(_sensor(sensor, res))
    if "conflict" in summary:
        parts.append(_conflict(summary["conflict"]))
    if examples:
        parts.append(_img(examples_figure(examples), "Example evaluation crops: clean, then each degradation at "
                                                     "the top severity (first crop of each set)"))
    t = summary.get("timings_s", {})
    parts.append("<p class='note'>Stage times (s): " + ", ".join(f"{k} {v:.0f}" for k, v in t.items()) + "</p>")
    return "\n".join(parts)


def write_page(run_dir: Path, summary: dict[str, Any], examples: dict[str, Any] | None = None) -> Path:
    from simulator.files import write_atomic

    doc = ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>evids realbench</title>"
           f"<style>{CSS}</style></head><body><h1>evids real-benchmark report</h1>"
           f"{' <p class=note>(--quick: toy scale)</p>' if summary.get('quick') else ''}"
           f"{section_html(summary, examples)}</body></html>")
    out = Path(run_dir) / "realbench.html"
    write_atomic(out, doc)
    fig = agreement_figure(summary)
    if fig:
        write_atomic(Path(run_dir) / "realbench_agreement.png", fig)
    return out
