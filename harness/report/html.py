"""report.html: condition table, headline answers, reliability diagrams, sweep curves, gate
trade-off, conflict histograms, example contact sheets/spectrograms. Matplotlib draws through an
Agg canvas on a ``Figure`` (no pyplot global state)."""
from __future__ import annotations

import base64
import html
import io
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from evids.metrics.significance import comparison_verdict, separating_digits, verdict_sentence
from evids.modalities import MODALITIES
from simulator.files import atomic_path


def _fig(w: float, h: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), dpi=90)
    FigureCanvasAgg(fig)
    return fig


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _img(b64: str, alt: str) -> str:
    return (f'<figure><img alt="{html.escape(alt)}" '
            f'src="data:image/png;base64,{b64}"><figcaption>{html.escape(alt)}</figcaption></figure>')


def _fmt(v: Any, std: Any = None, pct: bool = False) -> str:
    if v is None:
        return "&ndash;"
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return str(v)
    if isinstance(v, float):
        s = f"{100 * v:.2f}" if pct else f"{v:.3f}"
        if std is not None:
            s += f" &plusmn; {100 * std:.2f}" if pct else f" &plusmn; {std:.3f}"
        return s
    return html.escape(str(v))


def _table(headers: list[str], rows: list[list[str]], cls: str = "") -> str:
    head = "".join(f"<th>{h}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="{cls}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def example_figure(clips, idx: list[int], degraded: dict[str, list], path: Path) -> None:
    """Contact sheet: per example clip, video frames clean vs noisy, MFCC and RF spectrograms."""
    n = len(idx)
    fig = _fig(12, 2.3 * n)
    for r, i in enumerate(idx):
        clip = clips[i]
        s = clip.n_segments // 2
        panels = [("video clean", clip.video[s, 3]), ("video noisy", degraded["standard"][r].video[s, 3]),
                  ("MFCC clean", clip.mfcc[s, 0]), ("MFCC noisy", degraded["standard"][r].mfcc[s, 0]),
                  ("RF clean", clip.rf[s]), ("RF spec. noise", degraded["all_spec"][r].rf[s])]
        if degraded.get("iq"):
            panels.append(("RF I/Q noise", degraded["iq"][r].rf[s]))
        for c, (title, im) in enumerate(panels):
            ax = fig.add_subplot(n, 7, r * 7 + c + 1)
            ax.imshow(im, cmap=None if im.ndim == 3 else ("magma" if "RF" in title else "viridis"),
                      aspect="auto", origin="upper" if "MFCC" not in title else "lower")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{title}" + (f"\n{clip.clip_id} seg {s}" if c == 0 else ""), fontsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=80)


def _cond(ev: dict, key: str) -> dict | None:
    return next((c for c in ev["conditions"] if c["key"] == key), None)


def _verdict(x: dict | None, a: str, b: str) -> str:
    """The comparison's verdict (the one rule: evids.metrics.significance.comparison_verdict on the
    bootstrap CI and the permutation MDE), recomputed from the numbers so the label always agrees."""
    if not x or x.get("delta_accuracy") is None:
        return f"{a} vs {b}: no test available"
    v = comparison_verdict(x["delta_accuracy"], x.get("ci_low"), x.get("ci_high"), x.get("mde"))
    return html.escape(verdict_sentence(v, a, b))


def _stat(x: dict | None) -> str:
    if not x or x.get("delta_accuracy") is None:
        return "(no test available)"
    return (f"&Delta; = {100 * x['delta_accuracy']:+.2f} pp, 95% CI [{100 * x['ci_low']:+.2f}, "
            f"{100 * x['ci_high']:+.2f}] pp, "
            f"permutation p = {x['p_permutation']:.3f}, MDE(80%) = {100 * x['mde']:.2f} pp, {x['n_clusters']} scenes")


# run folders written before the comparison rows carried an id (2026-12-03): display name -> id
_IDS_OF_OLD_NAMES = {"EDL + average (d) vs Late Fusion (b)": "d vs b",
                     "EDL + average (d) vs clean-fitted Late Fusion (control)": "d vs b_clean_fit",
                     "DS (e) vs average (d), standard noise": "e vs d",
                     "DS (g) vs average (d'), all modalities noisy": "g vs d_prime",
                     "DS + gating (f) vs DS (e)": "f vs e",
                     **{f"objective: EDL vs sigmoid head, {m}": f"a_edl_{m} vs a_{m}" for m in MODALITIES}}


def _comparison_key(row: dict) -> str:
    """The stable id of a comparison row (``id``; older run folders: from the display name)."""
    return row.get("id") or _IDS_OF_OLD_NAMES.get(row["comparison"], row["comparison"])


def headline(ev: dict, conflict: dict | None, gate: dict | None, audit: dict | None = None) -> list[str]:
    """Plain-language answers, with the numbers, whatever they are."""
    out = []
    b, d, e = _cond(ev, "b"), _cond(ev, "d"), _cond(ev, "e")
    comps = {_comparison_key(x): x for x in ev.get("comparisons", ev.get("bootstrap", []))}
    if audit:
        bad = [r for r in audit["baselines"] if r.get("beats_chance") and r.get("decisive", True)]
        scored = [r for r in audit["baselines"] if r.get("score") is not None and r.get("decisive", True)]
        worst = max(scored, key=lambda r: abs(r["score"] - 0.5)) if scored else None
        out.append("<b>Shortcut audit:</b> " + (
            f"SHORTCUT: {', '.join(r['feature'] + '/' + r['model'] for r in bad)} beat chance beyond the CI, so "
            "every answer below may be learned from the scene, not the drone." if bad else
            f"none of {len(scored)} target-blind baselines beats chance (largest deviation: {worst['feature']}/"
            f"{worst['model']} {100 * worst['score']:.1f}% balanced accuracy, CI [{_pct_vs_chance(worst['ci_low'])}, "
            f"{_pct_vs_chance(worst['ci_high'])}]%)." if worst else "no baseline could be scored."))
    if b and d:
        name = "d vs b"
        out.append(f"<b>EDL + average vs sigmoid Late Fusion (fitted on noisy validation outputs):</b> "
                   f"{100 * d['accuracy']:.2f}% vs {100 * b['accuracy']:.2f}% under the standard noise protocol: "
                   f"{_verdict(comps.get(name), 'EDL + average', 'Late Fusion')}; {_stat(comps.get(name))}.")
        bc = _cond(ev, "b_clean_fit")
        if bc:
            n2 = "d vs b_clean_fit"
            out.append(f"<b>Control, Late Fusion fitted on clean train outputs:</b> {100 * bc['accuracy']:.2f}%; "
                       f"{_verdict(comps.get(n2), 'EDL + average', 'clean-fitted Late Fusion')}; "
                       f"{_stat(comps.get(n2))}.")
    pairs = [(m, _cond(ev, f"a_{m}"), _cond(ev, f"a_edl_{m}")) for m in MODALITIES]
    obj = [f"{m}: {100 * ed['accuracy']:.1f}% EDL vs {100 * sg['accuracy']:.1f}% sigmoid, "
           f"{_verdict(comps.get(f'a_edl_{m} vs a_{m}'), 'EDL', 'sigmoid')} "
           f"({_stat(comps.get(f'a_edl_{m} vs a_{m}'))})" for m, sg, ed in pairs if sg and ed]
    if obj:
        out.append("<b>Does the evidential objective help?</b> (same backbone, standard noise) " + "; ".join(obj) + ".")
    if d and e:
        name = "e vs d"
        out.append(f"<b>DS vs averaging, no controlled conflict:</b> DS {100 * e['accuracy']:.2f}% vs average "
                   f"{100 * d['accuracy']:.2f}%: {_verdict(comps.get(name), 'DS', 'averaging')}; "
                   f"{_stat(comps.get(name))}.")
    g, dp = _cond(ev, "g"), _cond(ev, "d_prime")
    if g and dp:
        name = "g vs d_prime"
        out.append(f"<b>All modalities noisy:</b> DS {100 * g['accuracy']:.2f}% vs average "
                   f"{100 * dp['accuracy']:.2f}%: "
                   f"{_verdict(comps.get(name), 'DS', 'averaging')}; {_stat(comps.get(name))}.")
    rf = ev.get("rf_noise_effect")
    if rf and rf.get("drop") is not None:
        out.append(f"<b>RF noise protocol:</b> RF (EDL) accuracy {100 * rf['clean']:.1f}% clean vs "
                   f"{100 * rf['rf_spec_noise']:.1f}% under the RF spectrogram noise (drop {100 * rf['drop']:.1f} pp).")
    if conflict and conflict.get("programs"):
        progs = [p for p in conflict["programs"] if p.get("n_targeted")]
        bites = [p for p in progs if p["status"] == "bites"]
        differ = [p for p in progs if p.get("ds_average_disagree_rate", 0) > 0]
        weak = ", ".join(f"{p['program']} {100 * p['flip_rate']:.0f}%" for p in progs if p["status"] != "bites")
        s = (f"<b>Conflict that bites:</b> {len(bites)} of {len(progs)} programs flip the compromised modality's vote "
             f"on &ge; half of their targeted segments" + (f" (not: {weak})" if weak else "") + ". ")
        if differ:
            top = max(differ, key=lambda p: p["ds_average_disagree_rate"])
            dc = top["ds_vs_average"]
            s += (f"DS and averaging decide differently under {len(differ)} programs; most under {top['program']} "
                  f"({100 * top['ds_average_disagree_rate']:.1f}% of its targeted segments; there DS is right on "
                  f"{_fmt(top['ds_average_disagree_accuracy'].get('ds'), pct=True)}% and averaging on "
                  f"{_fmt(top['ds_average_disagree_accuracy'].get('average'), pct=True)}%). On {top['program']}'s "
                  "targeted "
                  f"segments: DS {_fmt(top['accuracy'].get('ds'), pct=True)}% vs average "
                  f"{_fmt(top['accuracy'].get('average'), pct=True)}%: {_verdict(dc, 'DS', 'averaging')}; {_stat(dc)}.")
        else:
            s += "No program made DS and averaging decide differently."
        out.append(s)
    if gate:
        t = gate["timing"]
        f = _cond(ev, "f")
        name = "f vs e"
        out.append(f"<b>Gating:</b> at the validation-chosen point (&tau;<sub>high</sub>={t['params']['tau_high']}, "
                   f"&tau;<sub>low</sub>={t['params']['tau_low']}, N={t['params']['n']}) the encoders skipped "
                   f"{', '.join(f'{m} {100 * s:.1f}%' for m, s in zip(MODALITIES, t['skip_rate_per_modality']))}; "
                   f"realised CPU time saved {100 * t['realised_saving_fraction']:.1f}% vs projected "
                   f"{100 * t['projected_saving_fraction']:.1f}% (batch-1 streaming, gated encoders really skipped)"
                   + (f"; accuracy {100 * f['accuracy']:.2f}% gated vs {100 * e['accuracy']:.2f}% ungated: "
                      f"{_verdict(comps.get(name), 'gated DS', 'DS')} ({_stat(comps.get(name))})." if f and e else "."))
    return out


def _pct_vs_chance(v: float | None) -> str:
    """A CI bound in % with enough digits to show which side of 50 % it lies (50.004, not 50.00)."""
    return "&ndash;" if v is None else separating_digits(100 * v, 50.0, digits=2)


def _audit_html(audit: dict) -> str:
    rows = [[r.get("variant", "observed"), r["feature"], r["model"], f"{r['n_train'][0]}/{r['n_train'][1]}",
             f"{r['n_test'][0]}/{r['n_test'][1]}",
             _fmt(r.get("n_test_scenes")), _fmt(r.get("score"), pct=True), _pct_vs_chance(r.get("ci_low")),
             _pct_vs_chance(r.get("ci_high")), html.escape(r["status"])] for r in audit["baselines"]]
    verdict = ("<b style='color:#b00'>SHORTCUT FOUND</b>: a target-blind baseline beats chance; the class is "
               "readable without the target." if audit["shortcut"] else
               "<b>No shortcut found</b>: no target-blind baseline beats chance by the rule below (CI excluding 50% "
               f"and at least {100 * audit.get('tolerance', 0.05):.0f} pp from it).")
    return ("<h2>Shortcut audit (target-blind baselines)</h2><p>" + verdict + "</p><p class='note'>Fitted on train, "
            "scored on test; balanced accuracy (chance 50%), 95% CI by resampling test scenes. Features describe the "
            "scene, not the drone: median frame colour, colour of the target-free top/bottom strips, mean MFCC and "
            "mean RF spectrum on segments where the simulator says that sensor does not observe the drone. "
            "n = drone/background segments. Where twins exist the <i>twin_counterfactual</i> rows decide (a drone "
            "clip's "
            "features taken from its drone-absent twin: only a difference other than the drone can be learned); "
            "<i>observed</i> rows above chance there show drone signal in the feature, not a shortcut.</p>" + _table(
                ["variant", "feature", "model", "n train", "n test", "test scenes", "balanced acc %", "CI low",
                 "CI high",
                 "status"], rows, "audit"))


def _observability_html(ev: dict) -> str:
    obs = ev.get("observability") or {}
    if not obs:
        return ""
    fig = _fig(6.0, 3.0)
    ax = fig.add_subplot(1, 1, 1)
    for split, col in (("train", "tab:blue"), ("val", "tab:green"), ("test", "tab:red")):
        o = obs.get(split)
        if o and o["px_hist"]:
            h = np.asarray(o["px_hist"], float)
            ax.stairs(h / max(h.sum(), 1), np.asarray(o["px_edges"], float), label=f"{split} (n={int(h.sum())})",
                      color=col)
    ax.set_xlabel("apparent drone size per segment (px, 112 px frame)")
    ax.set_ylabel("fraction of drone segments")
    ax.legend(fontsize=7)
    rows = [[s, _fmt(o["n_clips"]), _fmt(o["n_drone_clips"]), _fmt(o.get("px_median")),
             *[_fmt(o["observed_fraction"].get(m), pct=True) for m in ("video", "audio", "rf")]]
             for s, o in obs.items()]
    vb = ev.get("video_by_size") or {}
    size_rows = [[f"{b['px_low']:g}-{b['px_high']:g}", _fmt(b["n"]), _fmt(b["accuracy"], pct=True)]
                 for b in vb.get("bins", []) if b["n"]]
    return ("<h2>What each sensor can see (simulator truth)</h2>" + _img(_png(fig), "Apparent drone size per segment")
            + _table(["split", "clips", "drone clips", "median px", "video observes %", "audio observes %",
                      "RF observes %"], rows, "observability")
            + "<h3>Video accuracy by drone size (EDL video model, clean test, mean over training runs)</h3>"
            + _table(["drone px", "segments", "accuracy %"], size_rows, "bysize")
            + f"<p class='note'>Background test segments: {_fmt(vb.get('background_accuracy'), pct=True)}% "
              "correct.</p>")


def _comparisons_html(comps: list[dict]) -> str:
    rows = [[html.escape(b["comparison"]), _fmt(b["n_segments"]), _fmt(b.get("n_clusters")),
             _fmt(None if b["delta_accuracy"] is None else 100 * b["delta_accuracy"]),
             _fmt(None if b.get("ci_low") is None else 100 * b["ci_low"]),
             _fmt(None if b.get("ci_high") is None else 100 * b["ci_high"]),
             _fmt(b.get("p_permutation")), _fmt(b.get("p_bootstrap")),
             _fmt(None if b.get("mde") is None else 100 * b["mde"]),
             html.escape(comparison_verdict(b.get("delta_accuracy"), b.get("ci_low"), b.get("ci_high"), b.get("mde")))]
            for b in comps]
    return ("<h2>Paired comparisons</h2><p class='note'>Per-segment correctness averaged over training runs and noise "
            "seeds, then per scene (the cluster unit: a drone clip and its twin share one). p: two-sided sign-flip "
            "permutation test over scenes (calibrated at this cluster count; see the null-simulation test); CI: "
            "scene-clustered bootstrap; MDE: minimum detectable difference at 80% power, 2-sided 5%. "
            "'No difference' is written only when the MDE is below the effect of interest.</p>" + _table(
                ["comparison (A &minus; B, accuracy)", "segments", "scenes", "&Delta; pp", "CI low", "CI high",
                 "p perm.", "p boot.", "MDE pp", "verdict"], rows, "bootstrap"))


def _conflict_html(conf: dict) -> str:
    rows = []
    for p in conf["programs"]:
        acc = p.get("accuracy", {})
        rows.append([html.escape(p["program"]), p["kind"], "+".join(p["modalities"]), _fmt(p.get("n_targeted")),
                     _fmt(p.get("flip_rate"), p.get("flip_rate_std_training"), pct=True),
                     _fmt(p.get("wrong_class_probability")),
                     _fmt((p.get("ds_conflict") or {}).get("mean")), _fmt(p.get("fallback_rate"), pct=True),
                     *[_fmt(acc.get(r), pct=True) for r in ("majority_vote", "average", "ds", "yager", "discounted",
                                                            "late", "gmu")],
                     _fmt(p.get("ds_average_disagree_rate"), pct=True), html.escape(p["status"])])
    hdr = ["program", "kind", "compromised", "targeted segs", "vote flips %", "P(wrong)", "mean C", "DS fallback %",
           "majority %", "average %", "DS %", "Yager %", "discounted %", "Late F. %", "GMU %", "DS&ne;avg %", "status"]
    where = []
    for p in conf["programs"]:
        for w in p.get("disagreements", [])[:3]:
            where.append([html.escape(p["program"]), html.escape(w["clip"]), _fmt(w["segment"]),
                          ["Drone", "Background"][w["label"]], ["Drone", "Background"][w["ds"]],
                          ["Drone", "Background"][w["average"]],
                          html.escape("; ".join(f"{m} ({a[0]:.1f}, {a[1]:.1f})"
                                                for m, a in zip(MODALITIES, w["alpha"])))])
    fig = _fig(6.0, 3.2)
    ax = fig.add_subplot(1, 1, 1)
    for p in conf["programs"]:
        c = p.get("ds_conflict")
        if c and sum(c["hist"]):
            h = np.asarray(c["hist"], float)
            ax.stairs(h / h.sum(), np.asarray(c["edges"]), label=p["program"])
    ax.axvline(conf["c_max"], color="k", ls=":", label="C_max (fallback)")
    ax.set_xlabel("DS conflict C on targeted segments")
    ax.set_ylabel("fraction")
    ax.legend(fontsize=6, ncol=2)
    legacy = [[html.escape(x["program"]), x.get("modality", "-"), _fmt(x.get("n_targeted")),
               _fmt(x.get("flip_rate"), pct=True), html.escape(x.get("status", "no compromised segment"))]
              for x in conf.get("legacy_programs", [])]
    return ("<h2>Conflict study: realised effect per program</h2><p class='note'>Twin-swap programs: inside the "
            "middle half of each test clip the compromised sensor's stream moves to the scene's counterfactual twin "
            "(blind: a drone clip's sensor loses the drone; decoy: a background clip's sensor gains a drone's "
            "signature; strength &lt; 1 = weakly wrong). Targeted = segments where the drone clip's sensor observes "
            "the "
            "drone (truth). Vote flips: share of targeted segments where the compromised sensor's EDL vote changes "
            "vs the same clip without the program, mean &plusmn; std over training runs; P(wrong): its mean "
            "probability of the wrong class there. Rule accuracies are on the targeted segments. 'bites' = flips "
            "&ge; 50%; 'inert' = flips &lt; 5%.</p>" + _table(hdr, rows, "conflict")
            + _img(_png(fig), "DS conflict C per program")
            + ("<h3>Where DS and averaging decide differently (first training run)</h3>"
               + _table(["program", "clip", "segment", "truth", "DS", "average",
                         "alpha (Drone, Background) per sensor"],
                        where, "where") if where else "<p>DS and averaging never decided differently.</p>")
            + (("<h3>Older degradation-based programs</h3>" + _table(
                ["program", "modality", "compromised segs", "vote flips %", "status"], legacy, "legacy")) if legacy
                else ""))


def _temperature_html(ev: dict) -> str:
    temps = ev.get("temperatures") or []
    if not temps:
        return ""
    names = [k[2:] for k in temps[0] if k.startswith("T_")]
    rows = [[str(t["run"]),
             *[_fmt(t[f"T_{n}"]) + (f" <b>(at {t[f'bound_{n}']} bound)</b>" if t.get(f"bound_{n}") else "")
                              for n in names]] for t in temps]
    return ("<h3>Temperatures (fitted on validation outputs under the test noise protocol)</h3>"
            + _table(["training run", *names], rows, "temps")
            + "<p class='note'>A temperature at a bound of the search is not a calibrated optimum and is flagged.</p>")


def _reliability(npz, keys: list[tuple[str, str]], bins: int) -> str:
    from evids.metrics import plot_reliability, reliability_diagram

    fig = _fig(3.2 * len(keys), 3.4)
    for j, (k, title) in enumerate(keys):
        ax = fig.add_subplot(1, len(keys), j + 1)
        plot_reliability(reliability_diagram(npz[f"{k}__probs"], npz["labels"], n_bins=bins), ax=ax, title=title)
    fig.tight_layout()
    return _png(fig)


def _sweep_fig(rows: list[dict], metric: str) -> str:
    fig = _fig(12, 3.3)
    for j, m in enumerate(MODALITIES):
        ax = fig.add_subplot(1, 3, j + 1)
        for rule in sorted({r["rule"] for r in rows}):
            rr = sorted((r for r in rows if r["modality"] == m and r["rule"] == rule), key=lambda r: r["severity"])
            if not rr or all(r.get(metric) is None for r in rr):
                continue
            xs = [r["severity"] for r in rr]
            ys = [np.nan if r.get(metric) is None else r[metric] for r in rr]
            es = [0.0 if r.get(f"{metric}_std") is None else r[f"{metric}_std"] for r in rr]
            ax.errorbar(xs, ys, yerr=es, marker="o", ms=3, capsize=2, label=rule,
                        ls="--" if rule.startswith("unimodal") else "-")
        name = rows[0]["degradation"] if rows else ""
        deg = next((r["degradation"] for r in rows if r["modality"] == m), name)
        ax.set_title(f"{m}: {deg}", fontsize=9)
        ax.set_xlabel("severity")
        ax.set_ylabel(metric)
        if j == 2:
            ax.legend(fontsize=6)
    fig.tight_layout()
    return _png(fig)


def _gate_fig(gate: dict) -> str:
    rows = gate["rows"]
    fig = _fig(5.5, 3.8)
    ax = fig.add_subplot(1, 1, 1)
    for n in sorted({r["n"] for r in rows}):
        rr = [r for r in rows if r["n"] == n]
        ax.scatter([r["skip_rate"] for r in rr], [r["accuracy"] for r in rr], s=14, label=f"N={n}")
    ax.axhline(gate["ungated_accuracy"], color="grey", ls="--", label="ungated DS")
    p = gate["timing"]["params"]
    sel = [r for r in rows if r["tau_high"] == p["tau_high"] and r["tau_low"] == p["tau_low"] and r["n"] == p["n"]]
    if sel:
        ax.scatter([sel[0]["skip_rate"]], [sel[0]["accuracy"]], marker="*", s=160, color="k",
                   label="chosen on val (f)")
    ax.set_xlabel("mean encoder skip rate (test)")
    ax.set_ylabel("accuracy (test)")
    ax.legend(fontsize=7)
    return _png(fig)


CSS = """body{font-family:sans-serif;max-width:1200px;margin:1em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.6em 0;font-size:13px}th,td{border:1px solid #bbb;padding:3px 6px;text-align:right}
th{background:#eee}td:first-child,th:first-child{text-align:left}figure{margin:.5em 0}img{max-width:100%}
figcaption{font-size:12px;color:#555}.note{color:#555;font-size:13px}li{margin:.3em 0}"""  # noqa: E501 (CSS)


def build_report(run_dir: str | Path) -> Path:
    """Write run_dir/report.html from the stage outputs present; returns its path."""
    run_dir = Path(run_dir)

    def load(name: str) -> dict | None:
        p = run_dir / name
        return json.loads(p.read_text()) if p.is_file() else None

    ev, sweep, conflict, gate = load("evaluate.json"), load("sweep.json"), load("conflict.json"), load("gate.json")
    train, run, audit = load("train.json"), load("run.json") or {}, load("audit.json")
    if ev is None or train is None:
        from scenes.errors import UserInputError

        raise UserInputError(f"{str(run_dir)!r}: run `evids train` and `evids evaluate` before `evids report`")
    parts = [f"<h1>evids experiment report</h1><p class='note'>Run folder: {html.escape(str(run_dir.name))}; built "
             f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Test split: "
             f"{train['segments']['test']} segments from {len(train['split']['test'])} clips in "
             f"{train.get('n_scenes', {}).get('test', '?')} scenes never seen in training (split unit: "
             f"{train.get('split_unit', 'clip')}); majority-class accuracy "
             f"{100 * ev['majority_class_accuracy']:.1f}%. Training seeds {train.get('training_seeds')}; noise seeds "
             f"{train['noise_seeds']}. Nothing was tuned on the test split (gate point, fusion heads and temperatures: "
             "validation).</p>"]
    if audit:
        parts.append(_audit_html(audit))
    parts.append("<h2>Answers</h2><ul>" + "".join(f"<li>{h}</li>"
                                                  for h in headline(ev, conflict, gate, audit)) + "</ul>")
    parts.append(_observability_html(ev))
    hdr = ["condition", "inputs", "accuracy %", "macro-F1", "ECE", "NLL", "Brier", "UAUC entropy", "UAUC vacuity",
           "mean C", "fallback", "skip"]
    rows = []
    for c in ev["conditions"]:
        rows.append([html.escape(c["label"]), c["variant"], _fmt(c["accuracy"], c.get("accuracy_std"), pct=True),
                     _fmt(c["macro_f1"], c.get("macro_f1_std")), _fmt(c["ece"], c.get("ece_std")), _fmt(c["nll"]),
                     _fmt(c["brier"]), _fmt(c["uauc_entropy"], c.get("uauc_entropy_std")),
                     _fmt(c.get("uauc_vacuity"), c.get("uauc_vacuity_std")), _fmt(c.get("mean_conflict")),
                     _fmt(c.get("fallback_rate")), _fmt(c.get("skip_rate"))])
    parts.append("<h2>Conditions</h2><p class='note'>Mean &plusmn; std over training runs x noise seeds (the std "
                 "covers training variance and test-time noise). Inputs: standard = audio + "
                 "video noise, RF clean (as the paper's E2); all_spec = plus RF spectrogram-domain noise; iq = plus RF "
                 "noise on I/Q before the STFT; clean = no noise.</p>" + _table(hdr, rows, "conditions"))
    if ev.get("skipped"):
        parts.append("<p class='note'>Skipped: " + "; ".join(f"{s['condition']}: {html.escape(s['reason'])}"
                                                           for s in ev["skipped"]) + "</p>")
    parts.append(_temperature_html(ev))
    parts.append(_comparisons_html(ev.get("comparisons", ev.get("bootstrap", []))))
    pred = run_dir / "predictions.npz"
    if pred.is_file():
        with np.load(pred, allow_pickle=False) as npz:
            keys = [(k, t) for k, t in (("b", "Late Fusion"), ("b_temp", "Late Fusion + T"), ("d", "EDL + average"),
                                        ("e", "EDL + DS")) if f"{k}__probs" in npz]
            parts.append("<h2>Reliability diagrams</h2>" + _img(_reliability(npz, keys, 15),
                                                              "Reliability diagrams, first noise seed (15 bins)"))
    if sweep:
        parts.append("<h2>Degradation sweep</h2><p class='note'>One modality degraded at a time (others clean); "
                     f"mean &plusmn; std over training runs x noise seeds {sweep['seeds']}.</p>")
        for metric in ("accuracy", "ece", "uauc_entropy", "uauc_vacuity"):
            parts.append(_img(_sweep_fig(sweep["rows"], metric), f"{metric} vs severity"))
    if conflict and "programs" in conflict and isinstance(conflict["programs"], list) and \
            (not conflict["programs"] or isinstance(conflict["programs"][0], dict)):
        parts.append(_conflict_html(conflict))
    if gate:
        t = gate["timing"]
        parts.append("<h2>Gating</h2>" + _img(_gate_fig(gate), "Gate sweep: accuracy vs skip rate (test; the chosen "
                                                              "point was selected on validation)"))
        trow = [["ungated", _fmt(t["ungated"]["total_s"]), *[_fmt(v) for v in t["ungated"]["encoder_runs"]]],
                ["gated (f)", _fmt(t["gated"]["total_s"]), *[_fmt(v) for v in t["gated"]["encoder_runs"]]]]
        parts.append(_table(["stream", "wall s", "audio runs", "video runs", "rf runs"], trow, "timing") +
                     "<p>Encoder ms per segment (audio, video, rf): "
                     f"{', '.join(f'{v:.2f}' for v in t['encoder_ms_per_segment'])}. "
                     f"Realised saving {100 * t['realised_saving_fraction']:.1f}%, projected "
                     f"{100 * t['projected_saving_fraction']:.1f}% ({t['torch_threads']} torch threads).</p>")
    ex = run_dir / "figures" / "examples.png"
    if ex.is_file():
        parts.append("<h2>Example scenarios</h2>" + _img(base64.b64encode(ex.read_bytes()).decode("ascii"),
                                                          "Video frame, MFCC and RF spectrogram, clean and degraded"))
    if (run_dir / "detection" / "detection.html").is_file():  # `evids demo --detection` writes it beside this run
        parts.append("<h2>Detection experiment</h2><p><a href='detection/detection.html'>RGB/thermal detection, fusion "
                     "and tracking (the paper's E1/E3 on generated video)</a></p>")
    stages = run.get("stages", {})
    parts.append("<h2>Run</h2>" + _table(["stage", "seconds"],
                                         [[k, _fmt(float(v["seconds"]))] for k, v in stages.items() if k != "complete"])
                 + "<details><summary>hyper-parameters and training record</summary><pre>"
                 + html.escape(json.dumps({"hyper_parameters": train["hyper_parameters"],
                                           "training": train["training"], "gate_condition_f": ev["gate_condition_f"],
                                           "noise_protocol": ev["noise_protocol"]}, indent=1)) + "</pre></details>")
    doc = ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>evids report</title>"
           f"<style>{CSS}</style></head><body>" + "\n".join(parts) + "</body></html>")
    from simulator.files import write_atomic

    out = run_dir / "report.html"
    write_atomic(out, doc)
    metrics = {"conditions": ev["conditions"], "bootstrap": ev["bootstrap"], "gate_condition_f": ev["gate_condition_f"],
               "comparisons": ev.get("comparisons"), "audit": audit, "rf_noise_effect": ev.get("rf_noise_effect"),
               "video_by_size": ev.get("video_by_size"), "temperatures": ev.get("temperatures"),
               "conflict": conflict, "gate_timing": gate and gate["timing"],
               "headline": headline(ev, conflict, gate, audit)}
    from harness.runfolder import write_json

    write_json(run_dir / "metrics.json", metrics)
    return out
