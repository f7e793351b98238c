"""Print the before/after tables of docs/SIM2REAL.md from two `evids sim2real` run folders (not by hand).

    .venv/bin/python docs/make_sim2real_tables.py out/sim2real_baseline out/sim2real
"""
from __future__ import annotations

import json
import sys
from pathlib import Path


def _load(run: str) -> dict:
    return json.loads((Path(run) / "sim2real.json").read_text())


def _ci(r: dict | None, signed: bool = False) -> str:
    if not r or r.get("estimate") is None:
        return "–"
    f = "{:+.3f}" if signed else "{:.3f}"
    s = f"{f.format(r['estimate'])} [{f.format(r['ci_low'])}, {f.format(r['ci_high'])}]"
    return s + (f", MDE {r['mde']:.3f}" if r.get("mde") is not None else "")


def visual_rows(before: dict, after: dict) -> list[str]:
    out = []
    for sensor in ("ir", "visible"):
        b, a = before["sensors"].get(sensor), after["sensors"].get(sensor)
        if not (b and a):
            continue
        name = sensor.upper() if sensor == "ir" else "Visible"
        out += [f"\n**{name}** (classes before: {', '.join(b['classes'])}; "
                f"after: {', '.join(a['classes'])}; "
                f"chance {1 / len(b['classes']):.2f} / {1 / len(a['classes']):.2f})\n",
                "| balanced accuracy on the real evaluation half [95 % CI] | before | after |", "|---|---|---|"]
        for cond, v in a["classifier"]["conditions"].items():
            out.append(f"| {v['label']} | {_ci(b['classifier']['conditions'].get(cond))} | {_ci(v)} |")
        for key, label in (("ratio_b_over_a", "ratio (b)/(a)"), ("gain_c_minus_a", "(c) - (a)"),
                           ("gain_dplus_minus_d", "(d+) - (d)")):
            out.append(f"| {label} | {_ci(b['classifier'].get(key), key != 'ratio_b_over_a')} | "
                       f"{_ci(a['classifier'].get(key), key != 'ratio_b_over_a')} |")
        for name in ("real", "synthetic"):  # noqa: B007 (the loop variable names the row)
            bd = b.get("detector", {}).get("conditions", {}).get(name, {})
            ad = a.get("detector", {}).get("conditions", {}).get(name, {})
            nan = float("nan")
            out.append(f"| detector AP50, trained on {name} | {bd.get('ap50', nan):.3f} | {ad.get('ap50', nan):.3f} |")
        for kind in ("crop", "background"):
            out.append(f"| domain classifier, {kind}s (0.5 = indistinguishable) | "
                       f"{b['domain_classifier'][kind]['accuracy']:.3f} | "
                       f"{a['domain_classifier'][kind]['accuracy']:.3f} |")
        ins = []
        for res in (b, a):
            rows = [row for stats in res["statistics"].values() for row in stats.values() if row["inside"] is not None]
            ins.append(f"{sum(r['inside'] for r in rows)} of {len(rows)}")
        out.append(f"| statistics with the synthetic median inside the real IQR | {ins[0]} | {ins[1]} |")
        cal_rows = [row for stats in a["statistics"].values() for row in stats.values()
                    if row.get("calibration_inside") is not None]
        if cal_rows:
            out.append("| the same for the real calibration half's median (null reference) | - | "
                       f"{sum(r['calibration_inside'] for r in cal_rows)} of {len(cal_rows)} |")
    return out


def statistics_rows(after: dict, sensor: str) -> list[str]:
    res = after["sensors"].get(sensor)
    if not res:
        return []
    out = [f"\n{sensor} statistics after, median [IQR] (real evaluation half | synthetic):\n",
           "| class | statistic | real | synthetic | inside |", "|---|---|---|---|---|"]
    for cls, stats in res["statistics"].items():
        for st, row in stats.items():
            r, s = row["real_evaluation"], row["synthetic"]
            if not (r and s):
                continue
            real = f"{r['median']:.2f} [{r['q25']:.2f}, {r['q75']:.2f}]"
            out.append(f"| {cls} | {st} | {real} | {s['median']:.2f} | "
                       f"{'yes' if row['inside'] else 'no'} |")
    return out


def audio_rows(after: dict) -> list[str]:
    res = after["sensors"].get("audio")
    if not res:
        return []
    out = ["\n**Audio** (drone vs not drone, ROC-AUC on the real evaluation half [95 % CI])\n",
           "| condition | CNN | log-mel logistic regression |", "|---|---|---|"]
    cl = res["classifier"]
    for cond, v in cl["cnn"].items():
        if isinstance(v, dict):
            w = cl["logreg"][cond]
            out.append(f"| {v['description']} | "
                       f"{v['roc_auc']:.3f} [{v['roc_auc_ci95'][0]:.3f}, {v['roc_auc_ci95'][1]:.3f}] | "
                       f"{w['roc_auc']:.3f} [{w['roc_auc_ci95'][0]:.3f}, {w['roc_auc_ci95'][1]:.3f}] |")
    for key, ci, label in (("ratio_synthetic_over_real_auc", "ratio_ci95", "ratio (b)/(a)"),
                           ("synthetic_plus_real_gain_auc", "synthetic_plus_real_gain_ci95", "(c) - (a)"),
                           ("few_shot_gain_auc", "few_shot_gain_ci95", "(d+) - (d)")):
        out.append(f"| {label} | " + " | ".join(
            f"{cl[m][key]:+.3f} [{cl[m][ci][0]:+.3f}, {cl[m][ci][1]:+.3f}]" for m in ("cnn", "logreg")) + " |")
    out.append("| helicopter windows called drone by (b) | " + " | ".join(
        f"{100 * cl[m]['b_synthetic']['helicopter_called_drone']:.0f} %" for m in ("cnn", "logreg")) + " |")
    ins = res.get("statistics_inside_real_iqr", {})
    out.append("\nSpectral statistics inside the real IQR: "
               + ", ".join(f"{k} {v['inside']} of {v['of']}" for k, v in ins.items())
               + "; the real calibration half's medians (null reference): "
               + ", ".join(f"{k} {v.get('calibration_inside', '-')} of {v['of']}" for k, v in ins.items()))
    return out


def main(before: str, after: str) -> None:
    b, a = _load(before), _load(after)
    lines = visual_rows(b, a) + audio_rows(a) + statistics_rows(a, "ir") + statistics_rows(a, "visible")
    t = a.get("timings_s", {})
    lines.append("\nStage times of the after-run (s): " + ", ".join(f"{k} {v:.0f}" for k, v in t.items()))
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: make_sim2real_tables.py BEFORE_RUN AFTER_RUN")
    main(sys.argv[1], sys.argv[2])
