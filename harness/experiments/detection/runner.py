"""The detection experiment: ``train`` (data + five detectors), ``evaluate`` (conditions (a)-(h),
thresholds fitted on val only, tracking, metrics through pycocotools / TrackEval / the Anti-UAV
formula on exported files, uncertainty analyses, gating time). Its jobs by module: inference
(maps and each condition's detections) in :mod:`~harness.experiments.detection.detect`, fitting on
val in :mod:`~harness.experiments.detection.fit`, the statistics and headline answers from its tables
in :mod:`~harness.experiments.detection.summary`.

Run folder: ``config.json`` (resolved config, every seed and hyper-parameter), ``data.json`` (the
datasets, their manifests' ids and the load-time degradations), ``models/*.pt`` + ``train.json``,
``fitted.json`` (every threshold and where it was fitted), ``exports/`` (COCO/MOT/Anti-UAV ground
truth and our result files), ``metrics.json``, ``tables/*.csv``, ``run.json`` (stage times).
"""
from __future__ import annotations

import json
import shutil
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch

from harness.experiments.detection.conditions import (
    StreamMaps,
    frame_vacuity,
)
from harness.experiments.detection.config import (
    DETECTION_CONDITIONS,
    DetectionConfig,
    condition_keys,
    load_detection_config,
    split_key,
)
from harness.experiments.detection.data import SequenceData, crop_resize, dataset_entries, inputs, load_sequence
from harness.experiments.detection.detect import compute_maps, condition_dets, gt_of
from harness.experiments.detection.fit import fit_gate, fit_temperature_on_val, fit_tracking
from harness.experiments.detection.summary import summarise_run
from harness.experiments.detection.tracking import run_tracker, tracking_on_absence
from harness.experiments.detection.train import MODEL_IDS, build_model, train_model
from harness.runfolder import create_run_folder, mark_stage, write_csv, write_json
from scenes.errors import UserInputError
from simulator.files import atomic_path, check_output
from simulator.jobs import run_jobs

Log = Callable[[str], None]



def models_needed(conditions: list[str]) -> list[str]:
    """The trained detectors the conditions read, in MODEL_IDS order."""
    need = {m for c in conditions for m in DETECTION_CONDITIONS[c].models}
    return [m for m in MODEL_IDS if m in need]


# ------------------------------------------------------------------------------------------ data
def _data_root(cfg: DetectionConfig, run_dir: Path) -> Path:
    root = Path(cfg.data.root)
    return root if root.is_absolute() else run_dir.resolve().parent / root


def _check_source(src, field: str) -> None:
    if src.path is not None:
        return
    from simulator.dataset.config import load_generation_config

    try:
        load_generation_config(src.generate)
    except UserInputError as exc:
        raise UserInputError(f"{field}.generate: {exc}") from None


def check_inputs(cfg: DetectionConfig) -> None:
    """Everything that can be checked before anything is written (bad input -> UserInputError)."""
    _check_source(cfg.data.train, "data.train")
    if cfg.data.train.path is not None:
        dataset_entries(Path(cfg.data.train.path), ("train", "val"), "data.train.path")
    for name, src in cfg.data.test.items():
        _check_source(src, f"data.test.{name}")
        if src.path is not None:
            dataset_entries(Path(src.path), ("test",), f"data.test.{name}.path")
    if cfg.crossover_set not in cfg.data.test:
        raise UserInputError(f"crossover_set: {cfg.crossover_set!r} is not one of data.test "
                             f"({', '.join(cfg.data.test)})")


def _resolve(src, field: str, folder: Path, need: tuple[str, ...], log: Log) -> Path:
    if src.path is not None:
        return Path(src.path)
    from simulator.dataset.generate import generate_dataset

    stem = f"{Path(src.generate).stem}_s{src.seed}" + (f"_n{src.sequences}" if src.sequences else "") + (
        f"_f{src.frames}" if src.frames else "")
    out = folder / stem
    log(f"data: {field} <- evids generate {src.generate} (cached in {out})")
    generate_dataset(src.generate, out, src.seed, sequences=src.sequences, frames=src.frames, progress=False)
    dataset_entries(out, need, field)
    return out


def resolve_data(cfg: DetectionConfig, run_dir: Path, log: Log, tests: bool) -> dict[str, Any]:
    """Generate (cached) or locate the training dataset, and with ``tests`` the test datasets."""
    folder = _data_root(cfg, run_dir)
    train = _resolve(cfg.data.train, "data.train", folder, ("train", "val"), log)
    out: dict[str, Any] = {"train": str(train), "datasets": {"train": _identity(train)}}
    if tests:
        found = {name: _resolve(src, f"data.test.{name}", folder, ("test",), log)
                 for name, src in cfg.data.test.items()}
        out["test"] = {n: str(t) for n, t in found.items()}
        out["datasets"].update({f"test.{n}": _identity(t) for n, t in found.items()})
    return out


def _identity(path: Path) -> dict[str, Any]:
    return {"path": str(path), "dataset_id": json.loads((Path(path) / "manifest.json").read_text()).get("dataset_id")}


def load_split(data: dict[str, Any], cfg: DetectionConfig, which: str) -> list[SequenceData]:
    """``which``: 'train', 'val' (from the training dataset) or 'test' (every test set)."""
    out = []
    if which in ("train", "val"):
        entries = [e for e in dataset_entries(Path(data["train"]), ("train", "val"), "data.train")
                   if e["split"] == which]
        out += [load_sequence(e, which, cfg, cfg.train.seed, 0) for e in entries]
    else:
        for k, (name, path) in enumerate(sorted(data["test"].items())):
            entries = [e for e in dataset_entries(Path(path), ("test",), f"data.test.{name}") if e["split"] == "test"]
            out += [load_sequence(e, name, cfg, cfg.train.seed, k + 1) for e in entries]
    return out


# ----------------------------------------------------------------------------------------- train
def train(config_source: str | Path | dict, run_dir: Path, log: Log = print) -> Path:
    cfg = load_detection_config(config_source)
    check_inputs(cfg)
    run_dir = Path(run_dir)
    inputs = [Path(src.path) for src in (cfg.data.train, *cfg.data.test.values()) if src.path is not None]
    if isinstance(config_source, (str, Path)) and Path(config_source).is_file():
        inputs.append(Path(config_source))
    check_output(run_dir, inputs=inputs, allow_resume=True)  # the safe-output rule, before any work
    if (run_dir / "config.json").exists():
        old = json.loads((run_dir / "config.json").read_text())
        if old != json.loads(cfg.model_dump_json()):
            raise UserInputError(f"--out: {str(run_dir)!r} holds a run of another config; choose a new folder")
    t0 = time.perf_counter()
    data = resolve_data(cfg, run_dir, log, tests=False)
    create_run_folder(run_dir, inputs=inputs, kind="detection run")
    write_json(run_dir / "config.json", json.loads(cfg.model_dump_json()))
    torch.set_num_threads(cfg.train.threads)
    seqs = load_split(data, cfg, "train")
    write_json(run_dir / "data.json", {**data, "train_sequences": [s.name for s in seqs],
                                       "degradations": {s.name: s.degradations for s in seqs}})
    (run_dir / "models").mkdir(exist_ok=True)
    todo = [n for n in models_needed(cfg.conditions) if not (run_dir / "models" / f"{n}.pt").is_file()]
    records = []
    if cfg.train.workers > 1 and len(todo) > 1:
        del seqs
        log(f"train: {len(todo)} models in {min(cfg.train.workers, len(todo))} processes")
        records = run_jobs(_train_one, [(json.loads(cfg.model_dump_json()), data, n, str(run_dir)) for n in todo],
                           workers=cfg.train.workers, start="spawn",
                           progress=lambda i, rec: log(f"train: {rec['name']} done in {rec['seconds']} s"))
    else:
        for name in todo:
            model, rec = train_model(name, seqs, cfg.train, log)
            with atomic_path(run_dir / "models" / f"{name}.pt", hidden=False) as tmp:
                torch.save(model.state_dict(), tmp)
            records.append(rec)
    old = json.loads((run_dir / "train.json").read_text()) if (run_dir / "train.json").is_file() else {"models": []}
    write_json(run_dir / "train.json", {"models": old["models"] + records})
    mark_stage(run_dir, "train", time.perf_counter() - t0)
    return run_dir


def _train_one(cfg_dict: dict, data: dict, name: str, run_dir: str) -> dict:
    """Worker: load the training split, train one model, save it (atomically) and return its record."""
    cfg = load_detection_config(cfg_dict)
    torch.set_num_threads(1)
    seqs = load_split(data, cfg, "train")
    model, rec = train_model(name, seqs, cfg.train, None)
    with atomic_path(Path(run_dir) / "models" / f"{name}.pt", hidden=False) as tmp:
        torch.save(model.state_dict(), tmp)
    return rec


def load_models(run_dir: Path, cfg: DetectionConfig) -> dict[str, torch.nn.Module]:
    models = {}
    for name in models_needed(cfg.conditions):
        path = Path(run_dir) / "models" / f"{name}.pt"
        if not path.is_file():
            raise UserInputError(f"{run_dir}: model {name} is missing; run `evids detect train` first")
        m = build_model(name, cfg.train.width)
        m.load_state_dict(torch.load(path, weights_only=True))
        models[name] = m.eval()
    return models


# ------------------------------------------------------------------------------------- evaluate
def _tracker_name(key: str) -> str:
    return key.replace("/", "__")


def _crop_uncertainty(model, img: np.ndarray, boxes: np.ndarray, cfg: DetectionConfig) -> np.ndarray:
    """Alpha at the most probable location of the crop's central half, for each detection box, (N, 2)."""
    if boxes.shape[0] == 0:
        return np.zeros((0, 2))
    crops = np.stack([crop_resize(img, b, cfg.crop_context, cfg.crop_px) for b in boxes])
    with torch.no_grad():
        out = model(torch.from_numpy(crops))
    h, w = out.prob.shape[1:]
    q0, q1 = h // 4, w // 4
    centre = out.prob[:, q0:h - q0, q1:w - q1].reshape(len(boxes), -1)
    idx = centre.argmax(1)
    a = out.alpha[:, q0:h - q0, q1:w - q1].reshape(len(boxes), -1, 2)
    return a[torch.arange(len(boxes)), idx].numpy().astype(np.float64)


def _evaluate_sequence(seq: SequenceData, models, cfg: DetectionConfig, gate, temperature, fitted, exports: Path,
                       keys: list[str], want_example: bool) -> dict[str, Any]:
    """Conditions, tracking and per-detection/crop/frame rows of one test sequence."""
    from evids.fusion import dempster_shafer
    from harness.experiments.detection import metrics as M

    per_seq: list[dict[str, Any]] = []
    det_rows: list[dict[str, Any]] = []
    crop_rows: list[dict[str, Any]] = []
    frame_rows: list[dict[str, Any]] = []
    coco_dets: dict[str, list] = {}
    example = None
    maps = compute_maps(seq, models)
    out = condition_dets(seq, maps, cfg, gate, temperature)
    video = f"{seq.set_name}_{seq.name}"
    ex = out["extra"]
    for t in range(seq.n_frames):
        frame_rows.append({"set": seq.set_name, "sequence": video, "frame": t, "exist": seq.gt_rgb[t] is not None,
                           "exist_thermal": seq.gt_thermal[t] is not None,
                           "rgb_observed": bool(seq.rgb_observed[t]), "thermal_observed": bool(seq.thermal_observed[t]),
                           "contrast_k": seq.contrast_k[t], "netd_k": seq.netd_k,
                           "thermal_u_at_target": ex.get("thermal_u_at_target", [np.nan] * seq.n_frames)[t],
                           "thermal_p_at_target": ex.get("thermal_p_at_target", [np.nan] * seq.n_frames)[t],
                           "rgb_u_at_target": ex.get("rgb_u_at_target", [np.nan] * seq.n_frames)[t],
                           "rgb_p_at_target": ex.get("rgb_p_at_target", [np.nan] * seq.n_frames)[t],
                           "ds_conflict_at_target": (ex.get("ds_conflict_at_target")
                                                     if ex.get("ds_conflict_at_target") is not None
                                                     else [np.nan] * seq.n_frames)[t]})
    if ex.get("gate") is not None:
        ev = ex["gate"]["evaluated"]
        per_seq.append({"set": seq.set_name, "sequence": video, "key": "_gate", "rgb_evaluated": float(ev[:, 0].mean()),
                        "thermal_evaluated": float(ev[:, 1].mean()),
                        "rgb_fused": float(ex["gate"]["fused"][:, 0].mean()),
                        "thermal_fused": float(ex["gate"]["fused"][:, 1].mean())})
    for key in keys:
        if key not in out["dets"]:
            continue
        frames, decoded = out["dets"][key]
        cond, stream = split_key(key)
        thermal = stream == "thermal"
        gt = gt_of(seq, key)
        f = fitted[key]
        steps = run_tracker(frames, f["det_threshold"], f["theta"], cfg.tracker.search_px, f.get("tau_det"))
        boxes_out = [s.box for s in steps]
        M.write_mot_tracker(exports / "mot" / "trackers" / f"{'IR' if thermal else 'RGB'}-"
                                                           f"{seq.set_name}"
                            / _tracker_name(key) / "data" / f"{video}.txt", boxes_out, [s.score for s in steps],
                            [s.track_id for s in steps])
        label_file = exports / "antiuav" / seq.set_name / (video if thermal
                                                           else f"{video}_visible") / (
            "IR_label.json" if thermal else "visible.json")
        sa = M.antiuav_state_accuracy(label_file, boxes_out)
        vals = M.per_frame_state_values(boxes_out, gt)
        th_blind = np.array([g is not None for g in gt]) & ~seq.thermal_observed
        rgb_blind = np.array([g is not None for g in gt]) & ~seq.rgb_observed
        exist = np.array([g is not None for g in gt])
        per_seq.append({"set": seq.set_name, "sequence": video, "key": key, "state_acc": sa["plain"],
                        "state_acc_penalised": sa["penalised"],
                        "acc_thermal_blind": float(vals[th_blind].mean()) if th_blind.any() else np.nan,
                        "acc_rgb_blind": float(vals[rgb_blind].mean()) if rgb_blind.any() else np.nan,
                        "trk_on_abs": tracking_on_absence(steps, exist), "absent_frames": int((~exist).sum()),
                        "handovers": int(sum(s.handed_over for s in steps)),
                        "tracker_share": float(np.mean([s.in_control == "tracker" for s in steps]))})
        coco_dets.setdefault(f"{seq.set_name}|{key}", []).extend(
            (video, t, fr.boxes, fr.scores) for t, fr in enumerate(frames))
        for t, (fr, _decoded) in enumerate(zip(frames, decoded)):
            all_gt = (seq.boxes_thermal if thermal else seq.boxes_rgb)[t]
            tp = M.detections_matched(fr.boxes, fr.scores, all_gt)
            for i in range(fr.boxes.shape[0]):
                p = float(fr.scores[i])
                ent = -(p * np.log(max(p, 1e-300)) + (1 - p) * np.log(max(1 - p, 1e-300)))
                det_rows.append({"set": seq.set_name, "sequence": video, "key": key, "frame": t, "score": p,
                                 "unc": float(fr.uncertainty[i]), "entropy": ent, "tp": bool(tp[i]),
                                 "area": float(fr.boxes[i, 2] * fr.boxes[i, 3])})
        if cond.crop_uncertainty:
            model = models[f"{stream}_evidential"]
            x = inputs(seq)
            other = "thermal" if stream == "rgb" else "rgb"
            for t, fr in enumerate(frames):
                top = np.argsort(-fr.scores, kind="stable")[:5]
                if top.size == 0:
                    continue
                img = x[stream][t].numpy()
                a = _crop_uncertainty(model, img, fr.boxes[top], cfg)
                all_gt = (seq.boxes_thermal if stream == "thermal" else seq.boxes_rgb)[t]
                tp = M.detections_matched(fr.boxes[top], fr.scores[top], all_gt)
                avg_u = np.full(top.size, np.nan)
                if seq.registered:
                    b_other = _crop_uncertainty(models[f"{other}_evidential"], x[other][t].numpy(), fr.boxes[top], cfg)
                    avg_u = 2.0 / ((a + b_other) / 2).sum(1)
                ds = dempster_shafer(torch.tensor(np.stack([a, a])))
                for i in range(top.size):
                    crop_rows.append({"set": seq.set_name, "sequence": video, "stream": stream, "frame": t,
                                      "tp": bool(tp[i]), "anchor_u": float(fr.uncertainty[top[i]]),
                                      "crop_u": float(2.0 / a[i].sum()), "crop_u_avg": float(avg_u[i]),
                                      "crop_u_ds_identical": float(ds.u[i]),
                                      "area": float(fr.boxes[top[i], 2] * fr.boxes[top[i], 3])})
    if want_example and seq.set_name == cfg.crossover_set:
        example = _example_frames(seq, maps, out, fitted, cfg)
    return {"per_seq": per_seq, "det_rows": det_rows, "crop_rows": crop_rows, "frame_rows": frame_rows,
            "coco_dets": coco_dets, "example": example}

_WORKER: dict[str, Any] = {}


def _worker_init(cfg_dict: dict, run_dir: str) -> None:
    """Per-process state for parallel evaluation: the config and the frozen models."""
    cfg = load_detection_config(cfg_dict)
    torch.set_num_threads(1 if cfg.train.workers > 1 else cfg.train.threads)
    _WORKER["cfg"] = cfg
    _WORKER["models"] = load_models(Path(run_dir), cfg)


def _evaluate_entry(args, set_name: str, dataset_index: int, entry: dict) -> dict[str, Any]:
    _, _, gate, temperature, fitted, exports, keys = args
    cfg = _WORKER["cfg"]
    seq = load_sequence(entry, set_name, cfg, cfg.train.seed, dataset_index)
    first = entry["name"] == "seq000001"
    return _evaluate_sequence(seq, _WORKER["models"], cfg, gate, temperature, fitted, Path(exports), keys, first)


def evaluate(run_dir: Path, log: Log = print) -> dict[str, Any]:
    from harness.experiments.detection import metrics as M

    run_dir = Path(run_dir)
    if not (run_dir / "config.json").is_file() or not (run_dir / "data.json").is_file():
        raise UserInputError(f"{run_dir}: not a detection run folder (no config.json/data.json); run `evids detect "
                             "train` first")
    cfg = load_detection_config(json.loads((run_dir / "config.json").read_text()))
    data = json.loads((run_dir / "data.json").read_text())
    t0 = time.perf_counter()
    if "test" not in data:
        data.update(resolve_data(cfg, run_dir, log, tests=True))
        write_json(run_dir / "data.json", data)
    torch.set_num_threads(cfg.train.threads)
    models = load_models(run_dir, cfg)
    keys = condition_keys(cfg)

    # ---- fit every threshold on val (never on test)
    log("evaluate: fitting thresholds on val")
    val_seqs = load_split(data, cfg, "val")
    val_maps = [compute_maps(s, models) for s in val_seqs]
    val = [(s, condition_dets(s, m, cfg, None, None)) for s, m in zip(val_seqs, val_maps)]
    fitted: dict[str, Any] = {}
    temperature = fit_temperature_on_val(val) if "h_feature_fusion_ts" in cfg.conditions else None
    gate = None
    for key in keys:
        if split_key(key)[0].fit_after is not None:
            continue
        fitted[key] = fit_tracking(val, key, cfg, tau_det_grid=split_key(key)[0].tau_det)
    if "f_ds_gated" in cfg.conditions:
        gate = fit_gate(val, val_maps, cfg, fitted["e_ds/fused"])
    if gate is not None or temperature is not None:
        val = [(s, condition_dets(s, m, cfg, gate, temperature)) for s, m in zip(val_seqs, val_maps)]
        for key in keys:
            if split_key(key)[0].fit_after is not None:
                fitted[key] = fit_tracking(val, key, cfg)
    del val_maps, val
    write_json(run_dir / "fitted.json", {"tracking": fitted, "gate": gate, "temperature": temperature,
                                         "val_sequences": [s.name for s in val_seqs]})

    # ---- exports of the test ground truth (the benchmarks' layouts) and per-sequence evaluation
    log("evaluate: exporting test ground truth (COCO, MOT, Anti-UAV) and running the conditions")
    from simulator.formats.antiuav import export_antiuav

    exports = run_dir / "exports"
    if exports.is_dir() and not exports.is_symlink():
        # this stage's own output inside the run folder (checked above: config.json/data.json), rebuilt in
        # full below: a rerun after an interrupted evaluate replaces its partial export instead of refusing it
        shutil.rmtree(exports)
    test_sets: dict[str, list[dict]] = {}
    for name, path in sorted(data["test"].items()):
        ents = [e for e in dataset_entries(Path(path), ("test",), f"data.test.{name}") if e["split"] == "test"]
        test_sets[name] = [{**e, "video": f"{name}_{e['name']}"} for e in ents]
    image_ids: dict[str, dict[str, int]] = {}
    for set_name, ents in test_sets.items():
        named = [{**e, "name": e["video"]} for e in ents]
        for modality in ("rgb", "ir"):
            image_ids[f"{set_name}/{modality}"] = M.write_coco_gt(named, modality,
                                                                  exports / "coco" / f"{set_name}_{modality}.json")
        for camera, bench in (("rgb", "RGB"), ("thermal", "IR")):
            M.write_mot_gt(named, camera, exports / "mot" / "gt", f"{bench}-{set_name}")
        for e in ents:
            export_antiuav(Path(e["path"]), exports / "antiuav" / set_name, e["video"])

    entries = [(name, k + 1, e) for k, (name, path) in enumerate(sorted(data["test"].items()))
               for e in dataset_entries(Path(path), ("test",), f"data.test.{name}") if e["split"] == "test"]
    args = (json.loads(cfg.model_dump_json()), str(run_dir), gate, temperature, fitted, str(exports), keys)
    workers = min(cfg.train.workers, len(entries))
    if workers <= 1:
        _worker_init(*args[:2])  # in-process: the same per-process state a pool worker sets up
    finished = [0]

    def tick(i: int, result: dict) -> None:
        finished[0] += 1
        if workers > 1 and (finished[0] % 6 == 0 or finished[0] == len(entries)):
            log(f"  {finished[0]}/{len(entries)} test sequences")

    results = run_jobs(_evaluate_entry, [(args, name, k, e) for name, k, e in entries], workers=workers,
                       start="spawn" if workers > 1 else "inline", initializer=_worker_init, initargs=args[:2],
                       progress=tick)
    per_seq = [r for res in results for r in res["per_seq"]]
    det_rows = [r for res in results for r in res["det_rows"]]
    crop_rows = [r for res in results for r in res["crop_rows"]]
    frame_rows = [r for res in results for r in res["frame_rows"]]
    coco_dets: dict[str, list] = {}
    for res in results:
        for key, v in res["coco_dets"].items():
            coco_dets.setdefault(key, []).extend(v)
    example = next((res["example"] for res in results if res["example"] is not None), None)
    if example is not None:
        with atomic_path(run_dir / "example_crossover.npz", suffix=".npz") as tmp:
            np.savez_compressed(tmp, **example)
    write_csv(run_dir / "tables" / "per_sequence.csv", per_seq)
    write_csv(run_dir / "tables" / "detections.csv", det_rows)
    write_csv(run_dir / "tables" / "crops.csv", crop_rows)
    write_csv(run_dir / "tables" / "frames.csv", frame_rows)

    # ---- the field's tools on the exported files
    log("evaluate: COCOeval, TrackEval, Anti-UAV state accuracy")
    ap50 = {}
    for sk, dets in coco_dets.items():
        set_name, key = sk.split("|")
        modality = "ir" if split_key(key)[1] == "thermal" else "rgb"
        ap50[sk] = M.coco_ap50(exports / "coco" / f"{set_name}_{modality}.json",
                               exports / "coco" / "results" / f"{set_name}__{_tracker_name(key)}.json", dets,
                               image_ids[f"{set_name}/{modality}"])
    mot = {}
    for set_name in test_sets:
        for bench, streams in (("RGB", ("rgb", "fused")), ("IR", ("thermal",))):
            trackers = [_tracker_name(k) for k in keys if split_key(k)[1] in streams]
            trackers = [t for t in trackers if (exports / "mot" / "trackers" / f"{bench}-{set_name}" / t).is_dir()]
            if trackers:
                res = M.trackeval_mot(exports / "mot" / "gt", exports / "mot" / "trackers", bench, set_name, trackers)
                for tr, rows in res.items():
                    mot[f"{set_name}|{tr.replace('__', '/')}"] = rows
    write_json(run_dir / "tables" / "tools.json", {"ap50": ap50, "mot": mot})
    mark_stage(run_dir, "evaluate_conditions", time.perf_counter() - t0)
    log("evaluate: timing the gate (batch 1, real skipped forwards)")
    timing_seqs = [load_sequence(e, name, cfg, cfg.train.seed, k) for name, k, e in entries
                   if e["name"] in ("seq000001", "seq000002")]
    write_json(run_dir / "tables" / "gate_timing.json", time_gating(timing_seqs, models, cfg, gate) if gate is not None
               else None)
    log("evaluate: statistics")
    summary = summarise_run(run_dir)
    mark_stage(run_dir, "evaluate", time.perf_counter() - t0)
    return summary


def _example_frames(seq: SequenceData, maps, out, fitted, cfg) -> dict[str, np.ndarray]:
    """Four frames around the crossover for the report: images, GT, per-stream and fused tops, u maps."""
    cand = np.flatnonzero(~seq.thermal_observed & seq.exist)
    centre = int(cand[len(cand) // 2]) if cand.size else seq.n_frames // 2
    idx = np.unique(np.clip([centre - 8, centre - 3, centre, centre + 4], 0, seq.n_frames - 1))
    top = {}
    for key in ("b_evidential/rgb", "b_evidential/thermal", "e_ds/fused", "d_average/fused", "g_feature_fusion/fused"):
        if key in out["dets"]:
            frames = out["dets"][key][0]
            top[key] = np.array([f.boxes[0] if f.boxes.shape[0] else [np.nan] * 4 for f in (frames[i] for i in idx)])
            top[key + "_score"] = np.array([f.scores[0] if f.scores.size else np.nan for f in (frames[i] for i in idx)])
    res = {"frames": idx, "rgb": seq.rgb[idx], "thermal_k": seq.thermal_k[idx],
           "gt_rgb": np.array([g if g is not None else [np.nan] * 4 for g in (seq.gt_rgb[i] for i in idx)]),
           "gt_thermal": np.array([g if g is not None else [np.nan] * 4 for g in (seq.gt_thermal[i] for i in idx)]),
           "contrast_k": seq.contrast_k[idx], "netd_k": np.array(seq.netd_k), "name": np.array(seq.name)}
    if "rgb_evidential" in maps:
        from harness.experiments.detection.conditions import fuse_maps

        p, u, _ = fuse_maps(maps["rgb_evidential"], maps["thermal_evidential"], "ds")
        res["u_rgb"] = maps["rgb_evidential"].vacuity[idx].numpy()
        res["u_thermal"] = maps["thermal_evidential"].vacuity[idx].numpy()
        res["u_fused"] = u[idx].numpy()
    res.update({k.replace("/", "__"): v for k, v in top.items()})
    return res


def time_gating(seqs: list[SequenceData], models, cfg: DetectionConfig, gate: dict[str, float]) -> dict[str, Any]:
    """Real CPU time per frame at batch 1: (e) both detectors + per-location DS on every frame vs
    (f) only the detectors the gate plans to evaluate (window form) + DS with the vacuous opinion
    for a skipped stream. Interleaved per sequence so both see the same machine load."""
    import os

    from evids.gating import GateParams, HysteresisGate
    from harness.experiments.detection.conditions import fuse_maps

    r_m, t_m = models["rgb_evidential"], models["thermal_evidential"]
    t_full = t_gated = 0.0
    frames = evaluated = 0
    with torch.no_grad():
        for seq in seqs:
            x = inputs(seq)
            t0 = time.perf_counter()
            for t in range(seq.n_frames):
                a = StreamMaps.of(r_m(x["rgb"][t:t + 1]))
                b = StreamMaps.of(t_m(x["thermal"][t:t + 1]))
                fuse_maps(a, b, "ds")
            t_full += time.perf_counter() - t0
            g = HysteresisGate(2,
                               GateParams(tau_high=gate["tau_high"], tau_low=gate["tau_low"], n=cfg.gate.n,
                                          mode="window"))
            t0 = time.perf_counter()
            for t in range(seq.n_frames):
                plan = g.plan()
                outs = [StreamMaps.of(m(x[s][t:t + 1])) if ev else None
                        for ev, m, s in zip(plan, (r_m, t_m), ("rgb", "thermal"))]
                us = [float(frame_vacuity(o)[0]) if o is not None else 1.0 for o in outs]
                fused = g.update(us)
                ref = next(o for o in outs if o is not None)
                vac = StreamMaps(ref.prob, ref.box, torch.ones_like(ref.alpha), None)
                fuse_maps(outs[0] if outs[0] is not None and fused[0] else vac,
                          outs[1] if outs[1] is not None and fused[1] else vac, "ds")
                evaluated += sum(plan)
            t_gated += time.perf_counter() - t0
            frames += seq.n_frames
    load = os.getloadavg()
    return {"frames": frames, "full_s_per_frame": t_full / max(frames, 1),
            "gated_s_per_frame": t_gated / max(frames, 1),
            "saving": 1.0 - t_gated / t_full if t_full > 0 else float("nan"),
            "evaluated_fraction": evaluated / max(2 * frames, 1), "loadavg_1m": load[0],
            "note": "measured inside the evaluate stage, machine load as printed"}
