"""`evids realbench`: per-sensor softmax and evidential classifiers trained on (a) the real
calibration half, (b) synthetic, (c) both, scored on the real evaluation half; and the degradation
sweep on real and synthetic evaluation inputs with its agreement figures.

Inputs: the Svanström benchmark and a finished `evids sim2real` run folder, whose protocol
(``sim2real.json`` "config"), synthetic counterpart (``synthetic/<CLASS>/sequences``) and real-sample
cache (``cache/real_samples.pkl``, copied into ``--out`` when missing there) are reused: the crops are
made by the same functions (``sim2real.samples``) for both domains. Synthetic sequences and synthetic
audio clips are split like the real clips: odd number = training half, even = evaluation half.
Nothing is tuned: training is a fixed number of steps, no threshold or temperature is fitted.

Writes OUT/realbench.json, OUT/realbench.html and OUT/realbench_agreement.png.
"""
from __future__ import annotations

import json
import shutil
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from harness.experiments.realbench import conflict, stats
from harness.experiments.realbench import models as M
from harness.experiments.realbench.sweep import SPECS, degrade_audio, degrade_crops

CONDITIONS = {"a_real": "(a) real calibration half", "b_synthetic": "(b) synthetic (training half)",
              "c_both": "(c) real calibration half + synthetic"}
SEVERITIES = (1.0, 2.0, 3.0, 4.0, 5.0)
QUICK_SEVERITIES = (5.0,)
STEPS, QUICK_STEPS = 300, 15
BATCH, LEARNING_RATE = 128, 2e-3
BOOT, QUICK_BOOT = 1000, 40
SENSOR_INDEX = {"ir": 0, "visible": 1, "audio": 2}
_TAG = 25          # "sim2real" sub-stream of this track's degradation seeds (issue 25)


def cell_name(deg: str, severity: float) -> str:
    return f"{deg}@{severity:g}"


def _cells(sensor: str, severities: tuple[float, ...]) -> tuple[list[str], dict[str, str], dict[str, str]]:
    """(cells incl. "clean", cell -> readable label, degradation -> its top-severity cell)."""
    cells, labels, top = ["clean"], {"clean": "clean"}, {}
    for short, deg in SPECS[sensor]:
        for s in severities:
            c = cell_name(deg, s)
            cells.append(c)
            labels[c] = f"{sensor} {short} ({deg}) severity {s:g}"
        top[f"{sensor} {short} ({deg})"] = cell_name(deg, max(severities))
    return cells, labels, top


def _deg_seed(seed: int, domain: int, sensor: str, k: int) -> int:
    from simulator.seeding import rng_for

    return int(rng_for(seed, "sim2real", _TAG, domain, SENSOR_INDEX[sensor], k).integers(0, 2 ** 31 - 1))


def _to_input(crops: np.ndarray) -> np.ndarray:
    x = crops.astype(np.float32) / 255.0 - 0.5
    return np.ascontiguousarray(x[:, None] if x.ndim == 3 else x.transpose(0, 3, 1, 2))


def _visual_job(cond: str, head: str, seed: int) -> dict[str, Any]:
    """Train one crop model and predict every cell of both evaluation sets."""
    import torch

    from evids.models.backbones import seeded_init

    torch.set_num_threads(1)
    from simulator.jobs import job_context

    f = job_context()
    x, y = f["train"][cond]
    with seeded_init(seed):     # not the global RNG state the worker's previous job left
        net = M.crop_net(x.shape[1], f["n_classes"], head)
    M.train(net, x, y, M.class_balanced_weights(y, f["n_classes"]), head=head, n_classes=f["n_classes"], seed=seed,
            steps=f["steps"], batch_size=BATCH, learning_rate=LEARNING_RATE, flips=True)
    return _predict_cells(net, head, f["tests"], _to_input)


def _predict_cells(net, head: str, tests: dict, to_input: Callable) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for domain, cells in tests.items():
        out[domain] = {}
        for cell, data in cells.items():
            s = M.predict(net, to_input(data), head)
            vac = None if s.vacuity is None else s.vacuity.astype(np.float32)
            out[domain][cell] = (s.probs.astype(np.float32), vac)
    return out


def _audio_job(cond: str, head: str, seed: int) -> dict[str, Any]:
    import torch

    from evids.models.backbones import seeded_init

    torch.set_num_threads(1)
    from simulator.jobs import job_context

    f = job_context()
    x, y, w = f["train"][cond]
    mean = x.mean(axis=(0, 2), keepdims=True)
    std = x.std(axis=(0, 2), keepdims=True) + 1e-3
    with seeded_init(seed):
        net = M.audio_net(head)
    M.train(net, ((x - mean) / std)[:, None], y, w, head=head, n_classes=2, seed=seed, steps=f["steps"],
            batch_size=64, learning_rate=LEARNING_RATE, flips=False)
    return _predict_cells(net, head, f["tests"], lambda v: ((v - mean) / std)[:, None].astype(np.float32))


def _run_models(job: Callable, train: dict, tests: dict, n_classes: int, seeds: list[int], steps: int, workers: int,
                label: str | None) -> dict[tuple[str, str, int], dict]:
    from harness.experiments.pipeline import forked_map

    jobs = [(c, h, int(s)) for c in CONDITIONS if c in train for h in M.HEADS for s in seeds]
    ctx = dict(train=train, tests=tests, n_classes=n_classes, steps=steps)
    return {jobs[i]: r for i, r in forked_map(job, jobs, workers, label, context=ctx)}


def at_chance(clean: dict[str, dict[str, float]], chance: float) -> list[str]:
    """The domains whose model is not above chance on its clean inputs (95 % interval reaches chance):
    there a degradation has nothing to take away, so that domain's drops, and the sweep agreement
    built on them, measure nothing."""
    return [d for d, r in clean.items() if not np.isfinite(r["ci_low"]) or r["ci_low"] <= chance]


def _evaluate(preds: dict, y: dict[str, np.ndarray], clip: dict[str, np.ndarray], cells: list[str],
              labels: dict[str, str], top: dict[str, str], seeds: list[int], n_boot: int, seed: int,
              sensor: str, n_classes: int) -> dict[str, Any]:
    """Scores on the real evaluation half (clean) and the sweep on both domains."""
    from simulator.seeding import rng_for

    present = [c for c in CONDITIONS if any(k[0] == c for k in preds)]
    models = {}
    for c in present:
        for h in M.HEADS:
            rows = [preds[(c, h, s)]["real"]["clean"] for s in seeds]
            models[f"{c}/{h}"] = ([r[0] for r in rows], [r[1] for r in rows] if h == "evidential" else None)
    pairs = {f"{c}: evidential - softmax": (f"{c}/evidential", f"{c}/softmax") for c in present}
    for h in M.HEADS:
        pairs[f"{h}: (c) - (a)"] = (f"c_both/{h}", f"a_real/{h}")
        pairs[f"{h}: (b) - (a)"] = (f"b_synthetic/{h}", f"a_real/{h}")
    scores = stats.score_models(y["real"], clip["real"], models, pairs, n_boot=n_boot,
                                rng=rng_for(seed, "sim2real", _TAG, 90, SENSOR_INDEX[sensor]))
    # sweep: per-clip sums of correct predictions and vacuity, per domain and model condition
    effects: dict[str, dict[str, dict[str, Any]]] = {}
    clean: dict[str, dict[str, dict[str, Any]]] = {}
    for domain in ("real", "synthetic"):
        w = None
        for c in present:
            table = stats.CellTable(y[domain], clip[domain], cells)
            for h in M.HEADS:
                for s in seeds:
                    for cell in cells:
                        p, v = preds[(c, h, s)][domain][cell]
                        table.add(h, cell, p.argmax(1) == y[domain], v, len(seeds))
            if w is None:
                w = table.weights(rng_for(seed, "sim2real", _TAG, 91 + ("real", "synthetic").index(domain),
                                          SENSOR_INDEX[sensor]), n_boot)
            effects.setdefault(domain, {})[c] = stats.sweep_effects(table, "clean", w)
            for h in M.HEADS:     # the reference every drop is taken from
                acc = table.balanced_accuracy(w, h)[:, cells.index("clean")]
                clean.setdefault(domain, {}).setdefault(c, {})[h] = stats.interval(float(acc[0]), acc[1:])
    degraded = [c for c in cells if c != "clean"]
    idx = [cells.index(c) for c in degraded]

    def pick(e: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {k: v[:, idx] for k, v in e.items()}

    sweep: dict[str, Any] = {"cells": degraded, "labels": {c: labels[c] for c in degraded},
                             "clean_balanced_accuracy": clean}
    runs = {"own_domain": ("a_real", "b_synthetic"), "mixed": ("c_both", "c_both")}
    for name, (cr, cs) in runs.items():
        if cr not in effects["real"] or cs not in effects["synthetic"]:
            continue
        sweep[name] = {}
        for h in M.HEADS:
            er, es = pick(effects["real"][cr][h]), pick(effects["synthetic"][cs][h])
            res = stats.agreement(er, es, degraded, labels)
            res["inert"] = {"real": stats.inert(er, degraded, top), "synthetic": stats.inert(es, degraded, top)}
            res["at_chance"] = at_chance({"real": clean["real"][cr][h], "synthetic": clean["synthetic"][cs][h]},
                                         1.0 / n_classes)
            sweep[name][h] = res
    return {"scores": scores, "sweep": sweep,
            "n_eval": {d: {"clips": int(np.unique(clip[d]).size), "rows": int(len(y[d]))} for d in y}}


def _seq_number(name: str) -> int:
    digits = "".join(ch for ch in name.rsplit("/", 1)[-1] if ch.isdigit())
    return int(digits) if digits else 0


def visual_track(samples: list, sensor: str, classes: list[str], *, seeds: list[int], steps: int,
                 severities: tuple[float, ...], n_boot: int, seed: int, context: float, workers: int,
                 progress: bool) -> dict[str, Any]:
    """One visual sensor: train a/b/c x softmax/evidential x seeds, score and sweep."""
    from harness.experiments.sim2real.classify import crop_set

    s = [x for x in samples if x.sensor == sensor and x.cls in classes and x.crop.size]
    real_cal = [x for x in s if x.domain == "real" and x.half == "calibration"]
    real_eval = [x for x in s if x.domain == "real" and x.half == "evaluation"]
    syn_train = [x for x in s if x.domain == "synthetic" and _seq_number(x.clip) % 2 == 1]
    syn_eval = [x for x in s if x.domain == "synthetic" and _seq_number(x.clip) % 2 == 0]
    a, b = crop_set(real_cal, classes), crop_set(syn_train, classes)
    train = {}
    if len(a.y):
        train["a_real"] = (a.x, a.y)
    if len(b.y):
        train["b_synthetic"] = (b.x, b.y)
    if len(a.y) and len(b.y):
        train["c_both"] = (np.concatenate([a.x, b.x]), np.concatenate([a.y, b.y]))
    cells, labels, top = _cells(sensor, severities)
    tests: dict[str, dict[str, np.ndarray]] = {}
    y, clip = {}, {}
    for k, (domain, pool) in enumerate((("real", real_eval), ("synthetic", syn_eval))):
        crops = np.stack([x.crop for x in pool]) if pool else np.zeros((0, 32, 32), np.uint8)
        y[domain] = np.array([classes.index(x.cls) for x in pool], np.int64)
        clip[domain] = np.array([x.clip for x in pool])
        tests[domain] = {"clean": crops}
        for j, (_, deg) in enumerate(SPECS[sensor]):
            ds = _deg_seed(seed, k, sensor, j)
            for sev in severities:
                tests[domain][cell_name(deg, sev)] = degrade_crops(crops, sensor, deg, sev, ds, context)
    if not all(len(v) for v in y.values()) or "a_real" not in train:
        return {"note": "too few samples", "n": {d: int(len(v)) for d, v in y.items()}}
    preds = _run_models(_visual_job, train, tests, len(classes), seeds, steps, workers,
                        f"{sensor}: models" if progress else None)
    res = _evaluate(preds, y, clip, cells, labels, top, seeds, n_boot, seed, sensor, len(classes))
    res["classes"] = classes
    if "DRONE" in classes:      # for the conflict study; popped before anything is written
        res["clip_opinions"] = conflict.clip_opinions(preds, clip, {x.clip: x.cls for x in real_eval + syn_eval},
                                                      classes.index("DRONE"), seeds)
    res["n_train"] = {c: int(len(v[1])) for c, v in train.items()}
    res["examples"] = {d: {c: tests[d][c][:6] for c in ["clean", *[cell_name(g, max(severities))
                                                                   for _, g in SPECS[sensor]]]}
                       for d in tests}
    return res


def audio_track(real_clips: list, synthetic_clips: list, *, seeds: list[int], steps: int,
                severities: tuple[float, ...], n_boot: int, seed: int, workers: int, progress: bool) -> dict[str, Any]:
    """Drone vs not-drone on 1 s log-mel windows: train a/b/c x softmax/evidential x seeds, score and sweep."""
    from harness.experiments.sim2real.audio import logmel_windows
    from harness.experiments.sim2real.classify import domain_balanced_weights

    cal = [c for c in real_clips if c.half == "calibration"]
    ev = [c for c in real_clips if c.half == "evaluation"]
    syn_train = [c for c in synthetic_clips if c.number % 2 == 1]
    syn_eval = [c for c in synthetic_clips if c.number % 2 == 0]

    def stack(clips: list, transform: Callable | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xs, ys, ids = [], [], []
        for c in clips:
            x = c if transform is None else transform(c)
            f = logmel_windows(x)
            xs.append(f)
            ys += [int(c.cls == "DRONE")] * len(f)
            ids += [c.name] * len(f)
        return np.concatenate(xs), np.array(ys, np.int64), np.array(ids)

    xa, ya, _ = stack(cal)
    xb, yb, _ = stack(syn_train)
    train = {"a_real": (xa, ya, domain_balanced_weights(ya, np.zeros(len(ya)))),
             "b_synthetic": (xb, yb, domain_balanced_weights(yb, np.ones(len(yb)))),
             "c_both": (np.concatenate([xa, xb]), np.concatenate([ya, yb]),
                        domain_balanced_weights(np.concatenate([ya, yb]), np.r_[np.zeros(len(ya)), np.ones(len(yb))]))}
    cells, labels, top = _cells("audio", severities)
    tests: dict[str, dict[str, np.ndarray]] = {}
    y, clip = {}, {}
    from dataclasses import replace

    for k, (domain, pool) in enumerate((("real", ev), ("synthetic", syn_eval))):
        x0, y[domain], clip[domain] = stack(pool)
        tests[domain] = {"clean": x0}
        for j, (_, deg) in enumerate(SPECS["audio"]):
            ds = _deg_seed(seed, k, "audio", j)
            for sev in severities:
                tests[domain][cell_name(deg, sev)] = stack(pool, lambda c, d=deg, v=sev, q=ds: replace(
                    c, samples=degrade_audio(c.samples, c.sample_rate, d, v, q + c.number)))[0]
    preds = _run_models(_audio_job, train, tests, 2, seeds, steps, workers, "audio: models" if progress else None)
    res = _evaluate(preds, y, clip, cells, labels, top, seeds, n_boot, seed, "audio", 2)
    res["classes"] = ["not drone", "drone"]
    res["clip_opinions"] = conflict.clip_opinions(preds, clip, {c.name: c.cls for c in ev + syn_eval}, 1, seeds)
    res["n_train"] = {c: int(len(v[1])) for c, v in train.items()}
    return res


def run_realbench(real: Path, sim2real_dir: Path, out: Path, *, quick: bool = False, audio: bool = True,
                  visual: tuple[str, ...] = ("ir", "visible"), n_seeds: int | None = None,
                  severities: tuple[float, ...] | None = None, steps: int | None = None,
                  audio_clips_per_class: int | None = None, n_triplets: int | None = None, progress: bool = True,
                  log: Callable[[str], None] = print) -> dict[str, Any]:
    """The whole track into ``out`` (see the module docstring); returns the summary."""
    from harness.experiments.config import FusionConfig
    from harness.experiments.pipeline import forked_results
    from harness.experiments.sim2real import audio as s2r_audio
    from harness.experiments.sim2real.config import Sim2RealConfig, synthetic_set_folder
    from harness.experiments.sim2real.harness import VISUAL_SENSORS, _cached_real_samples, _set_calls, _synthetic_job
    from harness.report.realbench import write_page
    from harness.runfolder import write_json
    from scenes.errors import UserInputError
    from simulator.formats.svanstrom import SENSORS, Sensor, open_benchmark

    t0 = time.time()
    run_json = sim2real_dir / "sim2real.json"
    if not run_json.is_file():
        raise UserInputError(f"--sim2real: {str(sim2real_dir)!r} holds no sim2real.json (run `evids sim2real` first)")
    cfg = Sim2RealConfig(**json.loads(run_json.read_text())["config"])
    vis, tr = cfg.visual, cfg.training
    seeds, classes = list(tr.seeds)[:n_seeds], list(vis.classes)
    steps = steps or (QUICK_STEPS if quick else STEPS)
    severities = severities or (QUICK_SEVERITIES if quick else SEVERITIES)
    n_boot = QUICK_BOOT if quick else BOOT
    bench = open_benchmark(real)
    summary: dict[str, Any] = {"real": bench.where, "sim2real_run": str(sim2real_dir), "quick": quick,
                               "audio_clips_per_class": audio_clips_per_class,
                               "seeds": seeds, "train_steps": steps, "severities": list(severities),
                               "bootstrap": n_boot, "sensors": {}, "timings_s": {},
                               "split_rule": "real: odd clip numbers = calibration half (train), even = evaluation "
                                             "half (reported); synthetic sequences and audio clips: odd = training, "
                                             "even = evaluation"}
    as_sensor: dict[str, Sensor] = {s: s for s in SENSORS}     # the config's names (validated) as Sensor values
    sensors = [as_sensor[s] for s in cfg.sensors if s in VISUAL_SENSORS and s in visual]
    params = dict(frames_per_clip=vis.frames_per_real_clip, crop_px=vis.crop_px, context=vis.crop_context,
                  min_crop_px=vis.min_crop_px, seed=cfg.seed, keep=vis.detector_frames_per_clip)
    samples: list = []
    if sensors:
        t = time.time()
        cache = out / "cache" / "real_samples.pkl"
        if not cache.exists() and (sim2real_dir / "cache" / "real_samples.pkl").is_file():
            cache.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(sim2real_dir / "cache" / "real_samples.pkl", cache)
        calls = [(clip, params) for s in sensors for clip in bench.clips(s, classes=classes)]
        for got, _, err in _cached_real_samples(out, bench, calls, vis.workers, progress).values():
            if err is None:
                samples += got
        syn_calls = []
        for cls in classes:
            spec = vis.classes[cls]
            for own in spec.sets_read_by(sensors):      # the sim2real run's sets this run's sensors read
                syn_calls += _set_calls(sim2real_dir / "synthetic" / synthetic_set_folder(cls, own), cls, spec, own,
                                        sensors, params)
        # in call order, not forked_map's completion order (timing): the order sets the models' batches
        for got, _ in forked_results(_synthetic_job, syn_calls, vis.workers, "synthetic sequences" if progress
                                     else None):
            samples += got
        summary["timings_s"]["samples"] = time.time() - t
    for sensor in sensors:
        t = time.time()
        summary["sensors"][sensor] = visual_track(samples, sensor, classes, seeds=seeds, steps=steps,
                                                  severities=severities, n_boot=n_boot, seed=cfg.seed,
                                                  context=vis.crop_context, workers=vis.workers, progress=progress)
        summary["timings_s"][sensor] = time.time() - t
        log(f"[realbench] {sensor} done in {summary['timings_s'][sensor]:.0f} s")
        _write_partial(out, summary)
    if audio:
        t = time.time()
        real_clips = s2r_audio.real_audio_clips(bench)
        if real_clips:
            syn = s2r_audio.synthetic_audio_clips(cfg.audio, cfg.seed, audio_clips_per_class, quick=quick)
            summary["sensors"]["audio"] = audio_track(real_clips, syn, seeds=seeds, steps=steps, severities=severities,
                                                      n_boot=n_boot, seed=cfg.seed, workers=vis.workers,
                                                      progress=progress)
        summary["timings_s"]["audio"] = time.time() - t
        log(f"[realbench] audio done in {summary['timings_s']['audio']:.0f} s")
    bench.close()
    t = time.time()
    tables = {s: r.pop("clip_opinions", None) for s, r in summary["sensors"].items()}
    fusion = FusionConfig()           # the experiment's default c_max and construction, not tuned here
    summary["conflict"] = conflict.run_conflict(
        tables, seed=cfg.seed, n_triplets=n_triplets or (conflict.QUICK_N_TRIPLETS if quick else conflict.N_TRIPLETS),
        n_boot=n_boot, c_max=fusion.c_max, construction=fusion.construction)
    summary["timings_s"]["conflict"] = time.time() - t
    summary["timings_s"]["total"] = time.time() - t0
    examples = {s: r.pop("examples", None) for s, r in summary["sensors"].items()}
    write_page(out, summary, examples)
    write_json(out / "realbench.json", summary)
    return summary


def _write_partial(out: Path, summary: dict[str, Any]) -> None:
    """realbench.json so far (a later failure keeps the finished sensors), without the example crops."""
    from harness.runfolder import write_json

    write_json(out / "realbench.json", {**summary, "sensors": {s: {k: v for k, v in r.items()
                                                                   if k not in ("examples", "clip_opinions")}
                                                               for s, r in summary["sensors"].items()}})


def format_table(summary: dict[str, Any]) -> str:
    """The plain-text summary the command prints."""
    def ci(r: dict | None, f: str = "{:.3f}") -> str:
        return stats.format_interval(r, f)

    lines = []
    for sensor, res in summary["sensors"].items():
        if "scores" not in res:
            lines.append(f"{sensor}: {res}")
            continue
        n = res["n_eval"]["real"]
        lines.append(f"{sensor}: real evaluation half ({n['clips']} clips, {n['rows']} inputs)")
        lines.append(f"  {'model':<26} {'balanced accuracy':<26} {'ECE':<26} {'UAUC vacuity':<26} "
                     f"{'UAUC entropy':<26}")
        for k, v in res["scores"]["models"].items():
            lines.append(f"  {k:<26} {ci(v['balanced_accuracy']):<26} {ci(v['ece']):<26} {ci(v['uauc_vacuity']):<26} "
                         f"{ci(v['uauc_entropy']):<26}")
        for k, v in res["scores"]["differences"].items():
            lines.append(f"  {k:<34} balanced accuracy {ci(v['balanced_accuracy'], '{:+.3f}')}")
        for run in ("own_domain", "mixed"):
            sw = res["sweep"].get(run, {}).get("evidential")
            if sw:
                med = ci(sw["median_abs_drop_difference_points"], "{:.1f}")
                lines.append(f"  sweep agreement ({run}, evidential, {sw['n_cells']} cells): Spearman "
                             f"{ci(sw['spearman'])}; median |drop diff| {med}"
                             f" points; same-sign vacuity change {ci(sw.get('vacuity_same_sign_fraction'))}")
                lines.append(f"    disagreeing: {'; '.join(sw['disagreeing_cells']) or 'none'}")
                lines.append(f"    inert: real {', '.join(sw['inert']['real']) or 'none'}; synthetic "
                             f"{', '.join(sw['inert']['synthetic']) or 'none'}")
                if sw.get("at_chance"):
                    lines.append(f"    NOT INFORMATIVE: the {' and '.join(sw['at_chance'])} model is at chance on its "
                                 "clean inputs, so its drops (and this agreement) measure nothing")
    if "conflict" in summary:
        lines += conflict.format_lines(summary["conflict"])
    return "\n".join(lines)
