"""`evids sim2real`: generate the synthetic counterpart of the real benchmark, sample both through the
same functions, and measure the gap (statistics, classifiers a/b/c/d/d+, domain classifier, sheets).

Run folder (``--out``): ``synthetic/<CLASS>/`` (native datasets, cached and resumed), ``sim2real.json``
(everything measured), ``sim2real.html`` (the report section), ``sheets/*.png``, ``skipped.txt`` (real
clips left out because they failed the reader's checks, non-strict mode).
"""
from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Callable

import numpy as np

from harness.experiments.sim2real import classify
from harness.experiments.sim2real.config import (
    TEST_HALF_WORDS,
    VISUAL_SENSORS,
    Sim2RealConfig,
    SyntheticClass,
    load_config,
    synthetic_set_folder,
)
from harness.experiments.sim2real.samples import STAT_NAMES, ClipSummary, FrameSample
from simulator.files import write_atomic


def _real_job(clip, params: dict) -> tuple[list[FrameSample], ClipSummary | None, str | None]:
    from harness.experiments.sim2real.samples import real_clip_samples
    from simulator.formats.validation import FormatError
    from simulator.jobs import job_context

    bench = job_context()
    try:
        samples, summary = real_clip_samples(bench, clip, **params)
        return samples, summary, None
    except FormatError as err:
        return [], None, str(err)


def _synthetic_job(seq_dir: str, params: dict) -> tuple[list[FrameSample], ClipSummary]:
    from harness.experiments.sim2real.samples import synthetic_sequence_samples

    return synthetic_sequence_samples(Path(seq_dir), **params)


REAL_CACHE_VERSION = 1


def _cached_real_samples(out: Path, bench, calls: list, workers: int, progress: bool,
                         reuse: Path | None = None) -> dict:
    """The real clips' samples, from ``OUT/cache/real_samples.pkl`` (else the ``reuse`` run folder's)
    when it was made from the same copy of the benchmark with the same clips and sampling parameters
    (the real side does not change between simulator versions: reruns skip decoding), else computed;
    cached in OUT either way."""
    import hashlib
    import pickle

    key = hashlib.sha256(json.dumps({"version": REAL_CACHE_VERSION, "benchmark": bench.identity(),
                                     "calls": [(c.media, p) for c, p in calls]}, sort_keys=True).encode()).hexdigest()
    path = out / "cache" / "real_samples.pkl"
    for source in [path] + ([reuse / "cache" / "real_samples.pkl"] if reuse is not None else []):
        if not source.is_file():
            continue
        try:
            data = source.read_bytes()
            cached = pickle.loads(data)  # evids's own cache file (written below; `reuse` is an evids run folder)
            if cached.get("key") == key:
                if source != path:
                    write_atomic(path, data)
                return cached["results"]
        except (OSError, EOFError, pickle.UnpicklingError, AttributeError, ImportError):
            pass  # unreadable or from another version: recompute
    from harness.experiments.pipeline import forked_results

    # call order, not completion order: the same cache bytes
    results = dict(enumerate(forked_results(_real_job, calls, workers, "real clips" if progress else None,
                                            context=bench)))
    write_atomic(path, pickle.dumps({"key": key, "results": results}, protocol=pickle.HIGHEST_PROTOCOL))
    return results


def _generation_config(cfg: Sim2RealConfig, cls: str, base_dir: Path, quick: bool, own_sensor: str | None = None):
    """The generation config of the class's shared set (or of ``own_sensor``'s own set) with scenario
    paths made absolute (and shrunk for --quick)."""
    from simulator.dataset.config import GenerationConfig

    spec = cfg.visual.classes[cls]
    data = spec.generation_for(own_sensor)
    for entry in data.get("mixture", []):
        path = Path(entry["scenario"])
        if path.suffix and not path.is_absolute():
            entry["scenario"] = str((base_dir / path).resolve())
    data["sequences"] = spec.quick_sequences if quick else spec.sequences
    data["frames"] = cfg.visual.quick_frames if quick else cfg.visual.frames
    if quick:
        data["image_size"] = list(cfg.visual.quick_image_size)
        data["thermal_image_size"] = list(cfg.visual.quick_thermal_image_size)
        data["spp"] = 1
    from scenes.loader import validate_mapping

    where = "generation" if own_sensor is None else f"sensor_generation.{own_sensor} (merged into generation)"
    return validate_mapping(GenerationConfig, data, f"sim2real config: visual.classes.{cls}.{where}")


def _set_calls(folder: Path, cls: str, spec: SyntheticClass, own: str | None, sensors: Sequence[str],
               params: dict) -> list[tuple[str, dict]]:
    """The sample jobs of one synthetic set's finished sequences (in ``folder``/sequences), one per sequence
    and sensor that reads the set (``own``: None for the shared set), sequence by sequence."""
    seqs = folder / "sequences"
    done = sorted(p for p in seqs.iterdir() if p.is_dir() and not p.name.startswith(".")) if seqs.is_dir() else []
    return [(str(seq), dict(params, sensor=sensor, cls=cls, index=j)) for j, seq in enumerate(done)
            for sensor in sensors if spec.set_of(sensor) == own]


def _stat_summary(values: Sequence[float | None]) -> dict[str, float] | None:
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], np.float64)
    if v.size == 0:
        return None
    q25, q50, q75 = np.percentile(v, [25, 50, 75])
    return {"median": float(q50), "q25": float(q25), "q75": float(q75), "n": int(v.size)}


def statistics_table(samples: list[FrameSample], clips: list[ClipSummary], sensor: str, classes: list[str],
                     reference: str = "evaluation") -> dict:
    """Per class and statistic: real evaluation half, real calibration half and synthetic (median,
    IQR); ``inside`` says whether the synthetic median lies in the real evaluation half's IQR, and
    ``calibration_inside`` the same for the real calibration half's median: what a second set of real
    clips reaches on the same test (the criterion's null reference). ``reference="calibration"``
    (tuning): ``inside`` is against the calibration half's IQR and there is no null reference."""
    table: dict[str, dict] = {}
    groups = {"real_evaluation": ("real", "evaluation"), "real_calibration": ("real", "calibration"),
              "synthetic": ("synthetic", "synthetic")}
    for cls in classes:
        table[cls] = {}
        for stat in (*STAT_NAMES, "absent_fraction"):
            row: dict[str, Any] = {}
            for key, (domain, half) in groups.items():
                vals: list[float | None]
                if stat == "absent_fraction":
                    vals = [c.absent_fraction for c in clips if c.sensor == sensor and c.cls == cls
                            and c.domain == domain and c.half == half]
                else:
                    vals = [s.stats.get(stat) for s in samples if s.sensor == sensor and s.cls == cls
                            and s.domain == domain and s.half == half]
                row[key] = _stat_summary(vals)
            real, syn = row[f"real_{reference}"], row["synthetic"]
            row["inside"] = None if not (real and syn) else bool(real["q25"] <= syn["median"] <= real["q75"])
            cal = row["real_calibration"] if reference == "evaluation" else None
            row["calibration_inside"] = (None if not (real and cal and syn)
                                         else bool(real["q25"] <= cal["median"] <= real["q75"]))
            table[cls][stat] = row
    return table


def _tile(images: list[np.ndarray], px: int, cols: int) -> np.ndarray:
    import cv2

    tiles = []
    for im in images[:cols]:
        im = im if im.ndim == 3 else np.repeat(im[..., None], 3, axis=2)
        tiles.append(cv2.resize(im, (px, px), interpolation=cv2.INTER_NEAREST))
    while len(tiles) < cols:
        tiles.append(np.full((px, px, 3), 40, np.uint8))
    return np.concatenate(tiles, axis=1)


def _label(image: np.ndarray, text: str) -> np.ndarray:
    import cv2

    bar = np.full((18, image.shape[1], 3), 255, np.uint8)
    cv2.putText(bar, text, (4, 13), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([bar, image], axis=0)


#: row label of each (domain, half) on the contact sheets
ROW_LABELS = {("real", "calibration"): "real (calibration half)", ("synthetic", "synthetic"): "synthetic"}


def labelled_sheet(rows: list[tuple[str, np.ndarray]], gap_px: int = 0) -> np.ndarray:
    """One contact sheet of labelled rows: each RGB (or grey) uint8 row under a white bar with its label in
    black text, rows padded on the right to the widest, ``gap_px`` white pixels between rows."""
    width = max(r.shape[1] for _, r in rows)
    out = []
    for i, (text, row) in enumerate(rows):
        row = row if row.ndim == 3 else np.repeat(row[..., None], 3, axis=2)
        if row.shape[1] < width:
            row = np.concatenate([row, np.full((row.shape[0], width - row.shape[1], 3), 255, np.uint8)], axis=1)
        out.append(_label(row.astype(np.uint8), text))
        if gap_px and i < len(rows) - 1:
            out.append(np.full((gap_px, width, 3), 255, np.uint8))
    return np.concatenate(out, axis=0)


def _pick(items: list, k: int, rng: np.random.Generator) -> list:
    if len(items) <= k:
        return items
    return [items[i] for i in sorted(rng.choice(len(items), size=k, replace=False))]


def write_sheets(samples: list[FrameSample], clips: list[ClipSummary], sensor: str, classes: list[str], sheets: Path,
                 rng: np.random.Generator) -> dict[str, str]:
    """Contact sheets, real (calibration half) | synthetic per class: target crops, background patches,
    whole frames, each row labelled with its class and source. Returns {kind: file name}."""
    import cv2

    out = {}
    for kind in ("crops", "backgrounds"):
        rows: list[tuple[str, np.ndarray]] = []
        for cls in classes:
            for (domain, half), source in ROW_LABELS.items():
                pool = [s for s in samples if s.sensor == sensor and s.cls == cls and s.domain == domain
                        and s.half == half]
                imgs = [s.crop for s in pool if s.crop.size] if kind == "crops" else \
                    [s.background for s in pool if s.background is not None]
                rows.append((f"{cls}: {source}", _tile(_pick(imgs, 12, rng), 64, 12)))
        name = f"{sensor}_{kind}.png"
        _write_png(sheets / name, labelled_sheet(rows))
        out[kind] = name
    frame_rows: list[np.ndarray] = []
    for cls in classes:
        row = []
        for domain, half in (("real", "calibration"), ("synthetic", "synthetic")):
            thumbs = [c.thumbnail for c in clips if c.sensor == sensor and c.cls == cls and c.domain == domain
                      and c.half == half and c.thumbnail is not None]
            for im in _pick(thumbs, 3, rng) + [None] * (3 - min(3, len(thumbs))):
                im = np.full((128, 160, 3), 40, np.uint8) if im is None else im
                im = im if im.ndim == 3 else np.repeat(im[..., None], 3, axis=2)
                row.append(cv2.resize(im, (160, 128), interpolation=cv2.INTER_AREA))
        frame_rows.append(_label(np.concatenate(row, axis=1), f"{cls}: real (calibration half) x3 | synthetic x3"))
    name = f"{sensor}_frames.png"
    _write_png(sheets / name, np.concatenate(frame_rows, axis=0))
    out["frames"] = name
    return out


def reverse_sheet(synthetic: "classify.CropSet", called: Sequence[int], classes: list[str], path: Path,
                  rng: np.random.Generator, per_row: int = 12) -> None:
    """The synthetic crops grouped by what the real-trained model calls them (``called``: one class index per
    crop, its seeds' majority): one labelled row per (synthetic class, called class) pair that occurs."""
    images = synthetic.images()
    called_arr = np.asarray(called)
    rows: list[tuple[str, np.ndarray]] = []
    for k, cls in enumerate(classes):
        mine = synthetic.y == k
        for j, name in enumerate(classes):
            idx = np.flatnonzero(mine & (called_arr == j))
            if idx.size:
                share = idx.size / max(1, int(mine.sum()))
                rows.append((f"synthetic {cls} called {name} by the real-trained model: {idx.size} crops "
                             f"({100 * share:.0f} %)", _tile([images[i] for i in _pick(list(idx), per_row, rng)],
                                                             64, per_row)))
    if rows:
        _write_png(path, labelled_sheet(rows))


def _write_png(path: Path, rgb: np.ndarray) -> None:
    import cv2

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]))
    if not ok:
        raise RuntimeError(f"could not encode {path.name}")
    write_atomic(path, buf.tobytes())


def run_sim2real(real: Path, out: Path, *, config_path: Path | None = None, quick: bool = False, strict: bool = False,
                 progress: bool = True, log: Callable[[str], None] = print, tune: bool = False,
                 reuse_renders: Path | None = None) -> dict[str, Any]:
    """Run the whole protocol into ``out`` (see the module docstring); returns the summary. ``tune``: the
    calibration half only (the evaluation half is not read): classifiers cross-fitted over its two
    tuning folds (``svanstrom.tuning_fold``), statistics against its own IQR, the synthetic-trained
    detector scored on it, the audio track's fold 0 tested, fold 1 training: what a change is judged by
    before the one evaluation run. ``reuse_renders``: an earlier run folder whose synthetic sets with
    an unchanged recipe (and real samples with unchanged parameters) are hard-linked, not redone."""
    # every module the run needs is imported here, before the long work: a module loaded lazily at
    # the end could come from a different version of the files than the rest of the run
    from harness.experiments.pipeline import forked_results
    from harness.experiments.sim2real import audio as _audio  # noqa: F401
    from harness.experiments.sim2real import detect as _detect  # noqa: F401
    from harness.experiments.sim2real.compare import predictions_path
    from harness.report.sim2real import write_page
    from harness.runfolder import write_json
    from scenes.errors import UserInputError
    from simulator.dataset.driver import GenerationFailed
    from simulator.dataset.generate import generate_dataset
    from simulator.formats.svanstrom import open_benchmark, tuning_fold
    from simulator.seeding import rng_for

    t0 = time.time()
    cfg, base_dir = load_config(config_path)
    bench = open_benchmark(real)
    vis, tr = cfg.visual, cfg.training
    seeds = tr.seeds
    steps = tr.quick_steps if quick else tr.steps
    classes = list(vis.classes)
    summary: dict[str, Any] = {"config": cfg.model_dump(mode="json"), "quick": quick, "real": bench.where,
                               "split_rule": "odd clip numbers = calibration half (train, fit, look); "
                                             "even = evaluation half (reported numbers)",
                               "test_half": "calibration" if tune else "evaluation",
                               "sensors": {}, "timings_s": {}}
    skipped: list[str] = []
    sensors = [v for s in cfg.sensors for v in VISUAL_SENSORS if v == s]    # the config's order, typed
    gen_cfgs = {(cls, own): _generation_config(cfg, cls, base_dir, quick, own)   # every set's recipe checked
                for cls in (classes if sensors else []) for own in vis.classes[cls].sets_read_by(sensors)}

    # 1. real samples -----------------------------------------------------------------------------
    t = time.time()
    params = dict(frames_per_clip=vis.frames_per_real_clip, crop_px=vis.crop_px, context=vis.crop_context,
                  min_crop_px=vis.min_crop_px, seed=cfg.seed, keep=vis.detector_frames_per_clip)
    calls = [(clip, params) for s in sensors
             for clip in bench.clips(s, half="calibration" if tune else None, classes=classes)]
    fold_of = {clip.name: tuning_fold(clip.number) for clip, _ in calls} if tune else {}
    samples: list[FrameSample] = []
    clip_summaries: list[ClipSummary] = []
    results = _cached_real_samples(out, bench, calls, vis.workers, progress, reuse_renders)
    for i in range(len(calls)):
        got, summ, err = results[i]
        if err is not None:
            if strict:
                raise UserInputError(f"{err} (--strict stops at the first real clip that fails the reader's checks)")
            skipped.append(err)
            continue
        samples += got
        clip_summaries.append(summ)
    summary["timings_s"]["real_samples"] = time.time() - t
    if skipped:
        write_atomic(out / "skipped.txt", "\n".join(skipped) + "\n")
        log(f"[sim2real] {len(skipped)} real clip(s) skipped (listed in {out / 'skipped.txt'})")
    summary["skipped_clips"] = skipped

    # 2. synthetic counterpart --------------------------------------------------------------------
    t = time.time()
    syn_calls = []
    for k, cls in enumerate(classes if sensors else []):    # audio only: no video to render
        spec = vis.classes[cls]
        for own in spec.sets_read_by(sensors):  # all with the class's seed: a sensor's own set differs
            gen_cfg = gen_cfgs[cls, own]            # from the shared one only by what its sensor_generation changes
            name = synthetic_set_folder(cls, own)
            folder = out / "synthetic" / name
            earlier = None if reuse_renders is None else reuse_renders / "synthetic" / name
            try:
                made = generate_dataset(gen_cfg, folder, cfg.seed + k, workers=1 if quick else vis.workers,
                                        progress=progress, reuse_from=earlier)
                if made.linked:   # provenance: which sets came from which earlier run
                    summary["reuse_renders"] = str(reuse_renders)
                    summary.setdefault("synthetic_linked", {})[name] = len(made.linked)
                    log(f"[sim2real] {name}: {len(made.linked)} sequence(s) hard-linked from {reuse_renders} "
                        "(same recipe), not rendered")
            except GenerationFailed as exc:   # the other sequences are complete: measure them, report the failures
                if strict:
                    raise
                summary.setdefault("synthetic_failures", {})[name] = exc.failures
                log(f"[sim2real] {name}: {len(exc.failures)} synthetic sequence(s) failed to render and are left "
                    f"out (listed in sim2real.json): "
                    + "; ".join(f"{n}: {m}" for n, m in sorted(exc.failures.items())))
            syn_calls += _set_calls(folder, cls, spec, own, sensors, params)
    summary["timings_s"]["synthetic_render"] = time.time() - t
    t = time.time()
    # in call order (class, sequence, sensor), not completion order: the samples' order sets the
    # classifiers' batches and the detector's training list
    for got, summ in forked_results(_synthetic_job, syn_calls, vis.workers, "synthetic sequences" if progress
                                    else None):
        samples += got
        clip_summaries.append(summ)
    summary["timings_s"]["synthetic_samples"] = time.time() - t

    # 3. per sensor: statistics, classifiers, domain classifier, sheets ---------------------------
    sheets = out / "sheets"
    for sensor in sensors:
        t = time.time()
        s_samples = [s for s in samples if s.sensor == sensor]
        real_cal = [s for s in s_samples if s.domain == "real" and s.half == "calibration"]
        real_eval = [s for s in s_samples if s.domain == "real" and s.half == "evaluation"]
        synthetic = [s for s in s_samples if s.domain == "synthetic"]
        rng = rng_for(cfg.seed, "sim2real", 7, VISUAL_SENSORS.index(sensor))
        set_b = classify.crop_set(synthetic, classes)
        sets: dict[str, classify.CropSet] | classify.CrossFit
        if tune:    # the calibration half scores itself, each fold by models trained on the other fold
            test = classify.crop_set(real_cal, classes)
            folds, held_out = [], []
            for fold in (0, 1):
                train_real = [s for s in real_cal if fold_of[s.clip] != fold]
                folds.append(_condition_sets(train_real, set_b, classes, tr.few_shot_fraction, rng))
                held_out.append(np.array([fold_of[c] == fold for c in test.clip], bool))
            sets = classify.CrossFit(folds, held_out)
        else:
            sets = _condition_sets(real_cal, set_b, classes, tr.few_shot_fraction, rng)
            test = classify.crop_set(real_eval, classes)
        cond = classify.evaluate_conditions(sets, test, len(classes), seeds=seeds, steps=steps,
                                            batch_size=tr.batch_size, learning_rate=tr.learning_rate,
                                            bootstrap=min(tr.bootstrap, 200) if quick else tr.bootstrap,
                                            rng_seed=cfg.seed, reverse=set_b,
                                            predictions=predictions_path(out, sensor),
                                            workers=vis.workers, label=f"{sensor}: crop classifiers" if progress
                                            else None)
        domain = {}
        for kind in ("crop", "background"):
            domain[kind] = classify.domain_classifier(classify.crop_set(real_cal, classes, kind),
                                                      classify.crop_set(synthetic, classes, kind),
                                                      seeds=seeds, steps=steps, batch_size=tr.batch_size,
                                                      learning_rate=tr.learning_rate, workers=vis.workers,
                                                      rng=rng_for(cfg.seed, "sim2real", 8,
                                                                  VISUAL_SENSORS.index(sensor)))
        if vis.detector_frames_per_clip:
            from harness.experiments.sim2real import detect

            s_clips = [c for c in clip_summaries if c.sensor == sensor]
            real_train = [c for c in s_clips if c.domain == "real" and c.half == "calibration"]
            train_sets = {"real": real_train, "synthetic": [c for c in s_clips if c.domain == "synthetic"]}
            if tune:    # the synthetic-trained detector on the calibration half; no real-trained one to divide by
                train_sets.pop("real")
            detector = detect.run_detector(train_sets, real_train if tune else
                                           [c for c in s_clips if c.domain == "real" and c.half == "evaluation"],
                                           sensor, seeds=seeds, steps=vis.quick_detector_steps if quick
                                           else vis.detector_steps,
                                           folder=out / "detector" / sensor, workers=vis.workers,
                                           downscale=vis.detector_downscale.get(sensor, 1),
                                           label=f"{sensor}: detectors" if progress else None)
        else:
            detector = {"note": "off (visual.detector_frames_per_clip: 0)"}
        files = write_sheets(s_samples, [c for c in clip_summaries if c.sensor == sensor], sensor, classes, sheets,
                             rng_for(cfg.seed, "sim2real", 9, VISUAL_SENSORS.index(sensor)))
        if cond.get("reverse_transfer"):
            reverse_sheet(set_b, cond["reverse_transfer"]["majority"], classes, sheets / f"{sensor}_reverse.png",
                          rng_for(cfg.seed, "sim2real", 10, VISUAL_SENSORS.index(sensor)))
            files["reverse"] = f"{sensor}_reverse.png"
        summary["sensors"][sensor] = {
            "classes": classes,
            "n_clips": {"real_calibration": len({s.clip for s in real_cal}),
                        "real_evaluation": len({s.clip for s in real_eval}),
                        "synthetic": len({s.clip for s in synthetic})},
            "statistics": statistics_table(s_samples, clip_summaries, sensor, classes,
                                           reference="calibration" if tune else "evaluation"),
            "classifier": cond, "domain_classifier": domain, "detector": detector, "sheets": files,
        }
        summary["timings_s"][f"{sensor}_models"] = time.time() - t
        write_json(out / "sim2real.json", summary)     # partial results survive a later failure

    if "audio" in cfg.sensors:
        t = time.time()
        summary["sensors"]["audio"] = _audio_track(bench, cfg, out, quick, progress, tune)
        summary["timings_s"]["audio"] = time.time() - t

    summary["timings_s"]["total"] = time.time() - t0
    write_json(out / "sim2real.json", summary)
    write_page(out, summary)
    bench.close()
    return summary


def _condition_sets(real_train: list[FrameSample], set_b: "classify.CropSet", classes: list[str],
                    few_shot_fraction: float, rng: np.random.Generator) -> dict[str, "classify.CropSet"]:
    """The five training conditions from the real training crops and the synthetic set (the same object
    in every fold, so cross-fitting trains (b) once)."""
    few = classify.few_shot_clips(real_train, few_shot_fraction, rng)
    set_a = classify.crop_set(real_train, classes)
    set_d = classify.crop_set([s for s in real_train if s.clip in few], classes)
    return {"a_real": set_a, "b_synthetic": set_b, "c_synthetic_plus_real": classify.concat(set_b, set_a),
            "d_few_shot": set_d, "d_plus_few_shot_synthetic": classify.concat(set_b, set_d)}


def _audio_track(bench, cfg: Sim2RealConfig, out: Path, quick: bool, progress: bool, tune: bool) -> dict[str, Any]:
    """Real audio clips of both halves (``tune``: the calibration half's two tuning folds in their place,
    fold 0 tested, fold 1 training) and the synthetic clips of the config, through the audio track."""
    import dataclasses

    from harness.experiments.sim2real import audio
    from harness.experiments.sim2real.compare import AUDIO, predictions_path
    from simulator.formats.svanstrom import tuning_fold

    real = audio.real_audio_clips(bench, half="calibration" if tune else None)
    if tune:
        # the larger fold (clips 1-9, 21-29: ten per class) is the test, the five of 11-19 train (a)
        real = [dataclasses.replace(c, half="evaluation" if tuning_fold(c.number) == 0 else "calibration")
                for c in real]
    synthetic = audio.synthetic_audio_clips(cfg.audio, cfg.seed, quick=quick)
    return audio.run_audio_track(real, synthetic, seeds=cfg.training.seeds, quick=quick, out_dir=out / "sheets",
                                 progress=progress, predictions=predictions_path(out, AUDIO))


def format_table(summary: dict[str, Any]) -> str:
    """The plain-text table the command prints."""
    lines = []
    tuned = summary.get("test_half", "evaluation") == "calibration"
    half = TEST_HALF_WORDS[summary.get("test_half", "evaluation")]
    for sensor, res in summary["sensors"].items():
        if sensor not in VISUAL_SENSORS:
            for model, r in res.get("classifier", {}).items():
                lines.append(f"audio ({model}): ROC-AUC on {half}")
                for cond, v in r.items():
                    if isinstance(v, dict):
                        lines.append(f"  {v.get('description', cond):<52} {v['roc_auc']:.3f} "
                                     f"[{v['roc_auc_ci95'][0]:.3f}, {v['roc_auc_ci95'][1]:.3f}]")
                if "ratio_synthetic_over_real_auc" in r:
                    lines.append(f"  ratio (b)/(a) {r['ratio_synthetic_over_real_auc']:.3f}; helicopter windows called "
                                 "drone by (b) "
                                 f"{100 * (r['b_synthetic'].get('helicopter_called_drone') or 0):.0f} %")
            inside = res.get("statistics_inside_real_iqr", {})
            if inside:
                lines.append("audio statistics: synthetic median inside the real IQR for "
                             f"{sum(v['inside'] for v in inside.values())} of {sum(v['of'] for v in inside.values())}"
                             + (" (fold 0's IQR; fold 1's median: " if tuned
                                else " (the real calibration half's median: ")
                             + f"{sum(v.get('calibration_inside', 0) for v in inside.values())})")
            continue
        c = res["classifier"]
        lines.append(f"{sensor}: balanced accuracy on {half} ({c['n_test_clips']} clips, "
                     f"{c['n_test_crops']} crops; chance {1 / len(res['classes']):.2f})")
        for name, r in c["conditions"].items():
            recall = ", ".join(f"{k.lower()} {'-' if v is None else f'{v:.2f}'}"
                               for k, v in zip(res["classes"], r.get("recall") or []))
            lines.append(f"  {classify.CONDITION_LABELS[name]:<40} {r['estimate']:.3f} [{r['ci_low']:.3f}, "
                         f"{r['ci_high']:.3f}]" + (f"  recall {recall}" if recall else ""))
        rev = c.get("reverse_transfer")
        if rev:
            recall = ", ".join(f"{k.lower()} {'-' if v is None else f'{v:.2f}'}"
                               for k, v in zip(res["classes"], rev["recall"]))
            lines.append(f"  {'(a) on the synthetic crops (reverse)':<40} recall {recall}")
        for key, label in (("ratio_b_over_a", "ratio (b)/(a)"), ("gain_c_minus_a", "(c) - (a)"),
                           ("gain_dplus_minus_d", "(d+) - (d)")):
            r = c.get(key)
            if r:
                f = "{:.3f}" if key == "ratio_b_over_a" else "{:+.3f}"
                lines.append(f"  {label:<40} {f.format(r['estimate'])} [{f.format(r['ci_low'])}, "
                             f"{f.format(r['ci_high'])}]"
                             f" MDE {r['mde']:.3f}")
        det = res.get("detector", {})
        for name, r in det.get("conditions", {}).items():
            if "ap50" in r:
                lines.append(f"  detector AP50, trained on {name:<17} {r['ap50']:.3f} (per seed "
                             + ", ".join(f"{v:.3f}" for v in r["per_seed"]) + ")")
        if "ratio_synthetic_over_real" in det:
            lines.append(f"  detector AP50 ratio synthetic / real     {det['ratio_synthetic_over_real']:.3f}")
        for kind, d in res["domain_classifier"].items():
            lines.append(f"  domain classifier, {kind + 's':<23} {d['accuracy']:.3f} (0.5 = indistinguishable)")
        inside = [(cls, st) for cls, rows in res["statistics"].items() for st, row in rows.items()
                  if row["inside"] is not None]
        n_in = sum(res["statistics"][cls][st]["inside"] for cls, st in inside)
        n_cal = sum(bool(res["statistics"][cls][st].get("calibration_inside")) for cls, st in inside)
        lines.append(f"  statistics: synthetic median inside the real IQR for {n_in} of {len(inside)}"
                     + (" (the calibration half's IQR)" if tuned
                        else f" (the real calibration half's median: {n_cal} of {len(inside)})"))
    return "\n".join(lines)
