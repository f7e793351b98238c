"""``detection.html``: a self-contained page for a detection run folder (reads metrics.json, the
tables and example_crossover.npz; never re-runs anything)."""
from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from harness.runfolder import read_run
from simulator.files import write_atomic

_CSS = ("body{font-family:sans-serif;max-width:1200px;margin:1em auto;padding:0 1em}table{border-collapse:collapse;"
        "font-size:12px;margin:.5em 0}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}th{background:#eee}"
        "td:first-child,th:first-child,td:nth-child(2){text-align:left}img{max-width:100%}.q{background:#f6f6ff;"
        "padding:.5em;border-left:4px solid #88f;margin:.5em 0}")


def _png(fig) -> str:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _img(b64: str, alt: str) -> str:
    return (f'<figure><img alt="{html.escape(alt)}" '
            f'src="data:image/png;base64,{b64}"><figcaption>{html.escape(alt)}</figcaption></figure>')


def _f(v: Any, pct: bool = False, nd: int = 3) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "–"
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, float):
        return f"{100 * v:.1f}" if pct else f"{v:.{nd}f}"
    return html.escape(str(v))


def _table(headers: list[str], rows: list[list[str]]) -> str:
    h = "".join(f"<th>{html.escape(x)}</th>" for x in headers)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def example_figure(npz) -> str:
    """RGB | thermal side by side on a crossover sequence: ground truth (white), RGB-stream and
    thermal-stream top detections (green, red), the DS-fused one (yellow); vacuity overlaid."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    frames = npz["frames"]
    n = len(frames)
    fig = Figure(figsize=(9, 2.4 * n))
    for r in range(n):
        for c, (title, img, u_key) in enumerate((("RGB", npz["rgb"][r], "u_rgb"),
                                                 ("thermal", npz["thermal_k"][r], "u_thermal"))):
            ax = fig.add_subplot(n, 2, 2 * r + 1 + c)
            if c == 0:
                ax.imshow(np.clip(img.astype(np.float32), 0, 1))
            else:
                lo, hi = np.percentile(img, [1, 99.5])
                ax.imshow(img, cmap="gray", vmin=lo, vmax=max(hi, lo + 0.5))
            if u_key in npz.files:
                u = npz[u_key][r]
                h, w = img.shape[:2]
                ax.imshow(u, cmap="magma", alpha=0.35, extent=(0, w, h, 0), vmin=0, vmax=1)
            gt = npz["gt_rgb" if c == 0 else "gt_thermal"][r]
            boxes = [(gt, "white", "--")]
            for key, col in (("b_evidential__rgb", "lime"), ("b_evidential__thermal", "red"),
                             ("e_ds__fused", "yellow")):
                if key in npz.files:
                    boxes.append((npz[key][r], col, "-"))
            for b, col, ls in boxes:
                if np.all(np.isfinite(b)):
                    ax.add_patch(Rectangle((b[0], b[1]), b[2], b[3], fill=False, ec=col, ls=ls, lw=1.2))
            dt = float(npz["contrast_k"][r])
            ax.set_title(f"frame {int(frames[r]) + 1} {title}" + (f"  dT={dt:+.2f} K (NETD {float(npz['netd_k']):.2f})"
                                                                  if c == 1 else ""),
                         fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle("white dashed: ground truth; green: RGB evidential; red: thermal evidential; yellow: DS fused; "
                 "colour overlay: per-location vacuity (0-1)", fontsize=8)
    return _png(fig)


def vacuity_figure(vac: dict) -> str:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.5))
    ax = fig.add_subplot(1, 1, 1)
    pts = vac["points"]
    r = np.maximum(np.array(pts["ratio"]), 1e-2)
    ax.scatter(r, pts["u"], s=6, alpha=0.4, c="gray", label="frames")
    mids = [np.sqrt(max(b["lo"], 0.05) * min(b["hi"], 64)) for b in vac["bins"]]
    ax.plot(mids, [b["mean_u"] for b in vac["bins"]], "o-", c="C3", label="bin mean")
    ax.axvline(1.0, ls="--", c="k", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlabel("|dT| / NETD (1 = crossover threshold)")
    ax.set_ylabel("thermal vacuity at the target cell")
    ax.legend(fontsize=8)
    return _png(fig)


def build_detection_report(run_dir: str | Path) -> Path:
    run_dir = Path(run_dir)
    mpath = run_dir / "metrics.json"
    if not mpath.is_file():
        from scenes.errors import UserInputError

        raise UserInputError(f"{run_dir}: no metrics.json; run `evids detect evaluate {run_dir}` first")
    m = json.loads(mpath.read_text())
    cfg = json.loads((run_dir / "config.json").read_text())
    parts = [f"<h1>Detection experiment: {html.escape(cfg.get('name', ''))}</h1>",
             "<p>Paired RGB/thermal renders, per-stream CPU centre/heatmap detectors (sigmoid and K = 2 evidential "
             "heads), decision-level fusion, EDTC-style detection-tracking switching (the paper's E1/E3 on generated "
             "data). "
             "Every threshold is fitted on the validation split of the training scenes; test scenes are disjoint "
             "(variant-b presets). AP50 from pycocotools COCOeval on the COCO export, MOTA/IDF1/HOTA from TrackEval "
             "(MM-UAV class convention), state accuracy from the Anti-UAV label files.</p>"]
    parts.append("<h2>Headline questions</h2>")
    for k, v in m.get("headline", {}).items():
        parts.append(f'<div class="q"><b>{html.escape(k)}</b>: {html.escape(v)}</div>')
    ex = run_dir / "example_crossover.npz"
    if ex.is_file():
        with np.load(ex) as npz:
            parts.append("<h2>Example frames (crossover set)</h2>" + _img(example_figure(npz),
                                                                          f"sequence {npz['name']}"))
    parts.append("<h2>Data: which stream observes the target</h2>")
    rows = [[html.escape(s), _f(o["sequences"]), _f(o["frames_with_target"]), _f(o["absent_frames"]),
             _f(o["rgb_observed"], True),
             _f(o["thermal_observed"], True)] for s, o in m.get("observability", {}).items()]
    parts.append(_table(["set", "sequences", "frames with target", "absent frames", "RGB observes %",
                         "thermal observes %"], rows))
    parts.append("<h2>Results per set and condition</h2>")
    cols = ["state_acc", "state_acc_penalised", "acc_thermal_blind", "acc_rgb_blind", "ap50", "mota", "idf1", "hota",
            "trk_on_abs", "det_ece", "n_detections", "n_tp"]
    rows = [[html.escape(r["set"]), html.escape(r["key"]), _f(r["n_sequences"])] + [_f(r.get(c)) for c in cols]
            for r in m["table"]]
    parts.append(_table(["set", "condition/stream", "seqs"] + cols, rows))
    parts.append("<p>state_acc: Anti-UAV state accuracy (mean IoU, 1 for a correct empty prediction); _penalised: the "
                 "EDTC variant (minus 0.2 mean(penalty)^0.3); acc_*_blind: mean per-frame term on frames where that "
                 "stream does "
                 "not observe the target; trk_on_abs: fraction of absent frames with the tracker in control (here the "
                 "tracker "
                 "in control always outputs a box, so on absent frames this is a false positive: lower is better); "
                 "fused outputs are in RGB coordinates.</p>")
    parts.append("<h2>Paired comparisons (per-sequence, clustered)</h2>")
    rows = [[html.escape(c["set"]), html.escape(f"{c['a']} - {c['b']}"), html.escape(c["metric"]), _f(c["diff"]),
             f"[{_f(c['ci_low'])}, {_f(c['ci_high'])}]", _f(c["p"]), _f(c["mde"]), _f(c["n"])]
             for c in m["comparisons"]]
    parts.append(_table(["set", "A - B", "metric", "diff", "95% CI", "p (sign flip)", "MDE", "n seq"], rows))
    parts.append("<h2>Uncertainty ranking (UAUC: 1 = errors most uncertain, 0.5 = chance, &lt; 0.5 inverted)</h2>")
    rows = [[html.escape(u["level"]), html.escape(u["key"]), html.escape(u["stratum"]), html.escape(u["score"]),
             _f(u.get("uauc")),
             f"[{_f(u.get('ci_low'))}, {_f(u.get('ci_high'))}]", _f(u.get("n")), _f(u.get("n_error")),
             _f(u.get("mean_u_tp")),
             _f(u.get("mean_u_fp"))] for u in m["uncertainty"]]
    parts.append(_table(["level", "condition", "area px²", "score", "UAUC", "95% CI", "n", "errors", "mean u TP",
                         "mean u FP"], rows))
    vac = m.get("vacuity_vs_contrast") or {}
    if vac.get("points"):
        parts.append("<h2>Thermal vacuity against |dT| / NETD</h2>" + _img(vacuity_figure(vac),
                                                                           "thermal evidential detector"))
        rows = [[f"{b['lo']:g}-{b['hi']:g}", _f(b["n"]), _f(b["mean_u"]), _f(b["mean_p"])] for b in vac["bins"]]
        parts.append(_table(["|dT|/NETD", "frames", "mean vacuity", "mean p(target)"], rows))
    if m.get("ds_conflict_at_target"):
        rows = [[html.escape(s), _f(c["mean"]), _f(c["p90"]), _f(c["max"]), _f(c["n"])]
                for s, c in m["ds_conflict_at_target"].items()]
        parts.append("<h2>DS conflict C at the target cell</h2>" + _table(["set", "mean", "90th pct", "max", "frames"],
                                                                          rows))
    g = m.get("gate_timing")
    if g:
        parts.append("<h2>Gating: real CPU time</h2>" + _table(
            ["frames", "ms/frame ungated", "ms/frame gated", "saving %", "forwards run %", "load avg"],
            [[_f(g["frames"]), _f(g["full_s_per_frame"] * 1e3, nd=1), _f(g["gated_s_per_frame"] * 1e3, nd=1),
              _f(g["saving"], True),
              _f(g["evaluated_fraction"], True), _f(g["loadavg_1m"], nd=1)]]))
    fitted = json.loads((run_dir / "fitted.json").read_text()) if (run_dir / "fitted.json").is_file() else {}
    parts.append("<h2>Fitted on val</h2><pre>" + html.escape(json.dumps(fitted, indent=1)[:6000]) + "</pre>")
    parts.append("<h2>Run</h2><pre>" + html.escape(json.dumps(read_run(run_dir), indent=1)) + "</pre>")
    page = ("<!doctype html><html><head><meta charset='utf-8'><title>evids "
            f"detection</title><style>{_CSS}</style></head><body>{''.join(parts)}</body></html>")
    out = run_dir / "detection.html"
    write_atomic(out, page)
    return out
