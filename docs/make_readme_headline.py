"""Rewrite the README's headline answers from `evids demo` run folders (not by hand).

    .venv/bin/python docs/make_readme_headline.py out/demo [out/demo_seed1 ...] [--readme README.md] [--check]

The first run folder gives the answers (its ``metrics.json`` "headline" list, the same sentences the
report prints, each with its verdict by the one verdict rule of docs/EXPERIMENTS.md) and the commit and
lock hash it was made with (``train.json`` "environment"). Every further run folder (another seed or
another environment of the same demo) adds to the spread: for each comparison, the range of its effect
and the verdicts across all the runs. The text between the two markers below in the README is replaced;
``--check`` only reports (exit 1) whether the README already says exactly that.
"""
from __future__ import annotations

import argparse
import html
import json
import re
import sys
from pathlib import Path

BEGIN = "<!-- headline:begin (written by docs/make_readme_headline.py; do not edit by hand) -->"
END = "<!-- headline:end -->"


class HeadlineError(ValueError):
    """A run folder that is not a finished demo run, or a README without the markers."""


def load_run(run: Path) -> dict:
    """The pieces of one run folder the headline needs: metrics.json and train.json's environment."""
    run = Path(run)
    try:
        metrics = json.loads((run / "metrics.json").read_text())
        train = json.loads((run / "train.json").read_text())
    except FileNotFoundError as exc:
        raise HeadlineError(f"{run}: not a finished demo run folder ({Path(exc.filename).name} missing)") from None
    env = train.get("environment") or {}
    if not metrics.get("headline") or not isinstance(metrics.get("comparisons"), list):
        raise HeadlineError(f"{run}/metrics.json: no headline or comparisons (run `evids evaluate` first)")
    if not env.get("git_commit") or not env.get("lock_sha256"):
        raise HeadlineError(f"{run}/train.json: no environment.git_commit / lock_sha256 (made before they were "
                            "recorded: rerun the demo)")
    return {"name": run.as_posix(), "metrics": metrics, "env": env, "seeds": train.get("training_seeds"),
            "noise_seeds": train.get("noise_seeds"), "n_scenes": train.get("n_scenes")}


def to_markdown(sentence: str) -> str:
    """One report headline (HTML) as Markdown: bold kept, subscripts inline, entities decoded."""
    text = re.sub(r"</?b>", "**", sentence)
    text = re.sub(r"<sub>(.*?)</sub>", r"_\1", text)
    text = re.sub(r"<[^>]+>", "", text)
    return html.unescape(text)


def spread_rows(runs: list[dict]) -> list[str]:
    """A Markdown table: per comparison, the effect in every run, its range and the verdicts."""
    names = [c["comparison"] for c in runs[0]["metrics"]["comparisons"]]
    rows = ["| comparison | Δ per run (pp) | range (pp) | verdicts |", "|---|---|---|---|"]
    for name in names:
        found = [next((c for c in r["metrics"]["comparisons"] if c["comparison"] == name), None) for r in runs]
        deltas = [100.0 * c["delta_accuracy"] for c in found if c is not None]
        verdicts: dict[str, int] = {}
        for c in found:
            if c is not None:
                verdicts[c["verdict"]] = verdicts.get(c["verdict"], 0) + 1
        per_run = ", ".join("–" if c is None else f"{100.0 * c['delta_accuracy']:+.2f}" for c in found)
        rng = f"{max(deltas) - min(deltas):.2f}" if deltas else "–"
        rows.append(f"| {name} | {per_run} | {rng} | "
                    f"{', '.join(f'{v} x{n}' for v, n in sorted(verdicts.items()))} |")
    return rows


def headline_block(runs: list[dict]) -> str:
    """The README text between the markers."""
    main = runs[0]
    env = main["env"]
    scenes = main["n_scenes"]
    if isinstance(scenes, dict):
        scenes = ", ".join(f"{n} {split}" for split, n in scenes.items())
    lines = [BEGIN,
             f"Headline answers of the demo run `{main['name']}` (commit `{env['git_commit'][:12]}`, lock "
             f"`lock/requirements.txt` sha256 `{env['lock_sha256'][:16]}`; scenes {scenes}; training "
             f"seeds {main['seeds']}, noise seeds {main['noise_seeds']}); verdicts by the rule in "
             "[docs/EXPERIMENTS.md](docs/EXPERIMENTS.md#verdict-rule-every-comparison-in-the-report-the-detection-"
             "headline-and-the-audit):", ""]
    lines += [f"- {to_markdown(s)}" for s in main["metrics"]["headline"]]
    if len(runs) > 1:
        others = ", ".join(f"`{r['name']}` (`{r['env']['git_commit'][:12]}`, lock `{r['env']['lock_sha256'][:16]}`, "
                           f"seeds {r['seeds']})" for r in runs[1:])
        lines += ["", f"Spread over {len(runs)} runs (this one and {others}):", ""] + spread_rows(runs)
    else:
        lines += ["", "Spread across seeds or environments: not measured for this run (one run folder given)."]
    lines.append(END)
    return "\n".join(lines)


def rewrite(readme_text: str, block: str) -> str:
    """``readme_text`` with the text between the markers (markers included) replaced by ``block``."""
    once = readme_text.count(BEGIN) == 1 and readme_text.count(END) == 1
    if not once or readme_text.index(BEGIN) > readme_text.index(END):
        raise HeadlineError(f"the README must hold the markers once each, in order:\n{BEGIN}\n{END}")
    head, rest = readme_text.split(BEGIN)
    _, tail = rest.split(END)
    return head + block + tail


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="demo run folders; the first gives the answers")
    parser.add_argument("--readme", type=Path, default=Path(__file__).resolve().parents[1] / "README.md")
    parser.add_argument("--check", action="store_true", help="exit 1 when the README differs; write nothing")
    args = parser.parse_args(argv)
    try:
        runs = [load_run(r) for r in args.runs]
        text = args.readme.read_text()
        new = rewrite(text, headline_block(runs))
    except HeadlineError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.check:
        same = new == text
        print("README headline matches the run folders" if same else "README headline differs from the run folders")
        return 0 if same else 1
    if new != text:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from simulator.files import write_atomic

        write_atomic(args.readme, new)
    print(f"wrote the headline of {args.readme} from {', '.join(str(r) for r in args.runs)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
