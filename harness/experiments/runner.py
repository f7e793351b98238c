"""Stages of an experiment run folder: train -> evaluate -> sweep (degradation sweep, conflict
study, gate sweep with realised CPU timing) -> report. Each stage writes its files atomically
(temporary name, then rename) and records itself in ``run.json`` only when complete."""
from __future__ import annotations

import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
import yaml

from evids.gating import GateParams
from evids.metrics import paired_bootstrap, paired_permutation_test
from evids.metrics.significance import UNDECIDED, comparison_verdict
from evids.modalities import INPUT_FIELD, MODALITIES, MODALITY_STREAMS, MODALITY_TABLE, NOISE_STREAMS
from harness.experiments.conditions import (
    CONDITIONS,
    Condition,
    Prediction,
    choose_gate,
    metrics_of,
    predict_condition,
)
from harness.experiments.config import ExperimentConfig, load_experiment_config
from harness.experiments.data import (
    Prepared,
    clip_ids_of,
    labels_of,
    prepare,
    scene_ids_of,
)
from harness.experiments.noise import (
    degrade_clip,
)
from harness.experiments.pipeline import (
    Models,
    Outputs,
    encode_modality,
    forked_results,
    load_models,
    save_models,
    train_all,
    train_unimodal,
)
from harness.experiments.store import InputsKey, ModalityKey, OutputsKey, OutputsStore, noise_desc
from harness.runfolder import mark_stage, write_csv, write_json
from scenes.errors import UserInputError
from simulator.files import atomic_path, environment_record, write_atomic
from simulator.jobs import job_context

VARIANTS = ("clean", "standard", "all_spec", "iq")
#: the sweep's unimodal rows (after the fusion rules): row name -> the head of the swept modality
SWEEP_HEADS = {"unimodal_sigmoid": "sigmoid", "unimodal_edl": "edl"}


# ------------------------------------------------------------------------------------------
# run folder I/O
# ------------------------------------------------------------------------------------------

def _versions() -> dict[str, str]:
    from simulator.files import environment_record

    return environment_record()["versions"]  # evids and every numeric dependency (run.json: commit, lock)


# ------------------------------------------------------------------------------------------
# context
# ------------------------------------------------------------------------------------------

@dataclass
class Context:
    """A run in memory: config, data, models, the outputs store and the chosen gate."""

    run_dir: Path
    cfg: ExperimentConfig
    prep: Prepared
    models: list[Models] | None = None
    progress: bool = True
    store: OutputsStore = field(default_factory=OutputsStore)
    gate: tuple[GateParams, dict] | None = None     # condition (f)'s gate, chosen on val once

    @property
    def test(self) -> list[int]:
        return self.prep.split["test"]

    def labels(self, split: str = "test") -> np.ndarray:
        return labels_of(self.prep.clips, self.prep.split[split])

    def clip_ids(self, split: str = "test") -> np.ndarray:
        return clip_ids_of(self.prep.clips, self.prep.split[split])

    def scene_ids(self, split: str = "test") -> np.ndarray:
        """Cluster unit of every statistic: the scene (a drone clip and its twin share one)."""
        return scene_ids_of(self.prep.clips, self.prep.split[split])

    @property
    def runs(self) -> range:
        return range(len(self.models or []))

    @property
    def trained(self) -> list[Models]:
        """Every training run's models; an error for a run opened without them (``need_models=False``)."""
        if self.models is None:
            raise ValueError(f"{str(self.run_dir)!r} was opened without its trained models")
        return self.models

    def has_iq(self) -> bool:
        return self.prep.rf_config is not None and all(self.prep.clips[i].iq is not None for i in self.test)

    def noise_kwargs(self, variant: str) -> dict:
        return _noise_kwargs(self.cfg, self.prep, variant)

    def outputs(self, variant: str, seed: int, split: str = "test", run: int = 0, **override) -> Outputs:
        """Per-modality outputs of a split under a noise variant and seed, for training run ``run`` (cached).

        ``override`` gives stream -> noise entries instead of the variant's. Each modality is encoded
        once per (its own noise entries, seed, run): an untouched modality reuses the clean outputs,
        and variants that share a modality's noise (standard, all_spec and iq share audio and video)
        share its degraded inputs and encoding."""
        key = OutputsKey(variant, seed, split, run, noise_desc(override))
        if key in self.store.outputs:
            return self.store.outputs[key]
        noise = {k: v for k, v in (override or self.noise_kwargs(variant)).items()
                 if k in NOISE_STREAMS and v}
        clean = self.store.clean(split, run) if noise else None
        per = []
        for m, modality in enumerate(MODALITIES):
            mine = {k: v for k, v in noise.items() if k in MODALITY_STREAMS[modality]}
            if not mine and clean is not None:
                per.append((clean.logit[m], clean.alpha[m], clean.emb[m]))
            else:
                per.append(self._modality_outputs(modality, mine, seed if mine else 0, split, run))
        out = Outputs(*(np.stack(arrays) for arrays in zip(*per)))
        if not noise:                   # clean outputs serve every seed (0 is the canonical key)
            self.store.put_clean(out, split, run, self.cfg.protocol.noise_seeds)
        self.store.outputs[key] = out
        return out

    def _modality_outputs(self, modality: str, noise: dict, seed: int, split: str, run: int) -> tuple:
        """(logit, alpha, emb) of one modality under its own noise entries (cached per run; the
        degraded inputs are cached across runs until drop_inputs)."""
        desc = noise_desc(noise)

        def degraded() -> np.ndarray:
            kw = {"rf_range_db": self.prep.rf_range_db, "rf_config": self.prep.rf_config, **noise}
            return np.concatenate([getattr(degrade_clip(self.prep.clips[i], i, seed, **kw), INPUT_FIELD[modality])
                                   for i in self.prep.split[split]])

        def encoded() -> tuple:
            x = self.store.degraded_inputs(InputsKey(modality, seed, split, desc), degraded)
            return encode_modality(self.trained[run], modality, x)

        return self.store.modality_outputs(ModalityKey(modality, seed, split, run, desc), encoded)

    def drop_inputs(self) -> None:
        """Free cached degraded inputs (outputs stay cached)."""
        self.store.drop_inputs()


def _noise_kwargs(cfg: ExperimentConfig, prep: Prepared, variant: str) -> dict:
    p = cfg.protocol
    kw: dict = {"rf_range_db": prep.rf_range_db, "rf_config": prep.rf_config}
    if variant == "clean":
        return kw
    kw.update(audio=p.audio, video=p.video)
    if variant == "all_spec":
        kw["rf_spec"] = p.rf_spec
    elif variant == "iq":
        kw["rf_iq"] = p.rf_iq
    return kw


def open_run(run_dir: Path, progress: bool = True, need_models: bool = True) -> Context:
    """Context of an existing run folder (after `train`)."""
    run_dir = Path(run_dir)
    cfg_path = run_dir / "config.yaml"
    if not cfg_path.is_file():
        raise UserInputError(f"{str(run_dir)!r} is not a run folder (no config.yaml); run `evids train` first")
    cfg = load_experiment_config(cfg_path)
    if need_models and not (run_dir / "models.pt").is_file():
        raise UserInputError(f"{str(run_dir)!r} has no trained models (models.pt); run `evids train` first")
    prep = prepare(cfg.dataset, cfg.split, run_dir, progress)
    torch.set_num_threads(cfg.models.torch_threads)
    models = load_models(cfg, run_dir / "models.pt") if need_models else None
    return Context(run_dir, cfg, prep, models, progress)


# ------------------------------------------------------------------------------------------
# stages
# ------------------------------------------------------------------------------------------

def stage_train(cfg: ExperimentConfig, run_dir: Path, progress: bool = True) -> Context:
    """Prepare data (generated once into run_dir/data) and train every model."""
    t0 = time.perf_counter()
    run_dir = Path(run_dir)
    existing = run_dir / "config.yaml"
    resolved = yaml.safe_dump(cfg.model_dump(mode="json"), sort_keys=False)
    if existing.is_file() and existing.read_text() != resolved:
        raise UserInputError(f"{str(run_dir)!r} holds a run with a different config; choose a new --out")
    if cfg.dataset.path is not None and not Path(cfg.dataset.path).is_dir():
        raise UserInputError(f"dataset.path: {cfg.dataset.path!r} is not a folder")
    t_data = time.perf_counter()
    prep = prepare(cfg.dataset, cfg.split, run_dir, progress)
    data_s = time.perf_counter() - t_data
    write_atomic(existing, resolved)
    torch.set_num_threads(cfg.models.torch_threads)
    va = prep.split["val"]
    parts = [degrade_clip(prep.clips[i], i, cfg.models.fusion_noise_seed, **_noise_kwargs(cfg, prep, "standard"))
             for i in va]
    val_noisy = {"mfcc": np.concatenate([p.mfcc for p in parts]), "video": np.concatenate([p.video for p in parts]),
                 "rf": np.concatenate([p.rf for p in parts])}
    trained = train_unimodal(cfg, prep, list(cfg.models.seeds), progress)
    # stage 2 (fusion heads, temperatures) of every training seed as forked jobs (identical results
    # for any worker count: each depends only on its own seed's models and the shared inputs)
    fitted = forked_results(_fusion_job, [(k,) for k in range(len(trained))], cfg.models.train_workers,
                            "fitting fusion heads" if progress else None, context=(cfg, prep, val_noisy, trained))
    models = [m for m, _ in fitted]
    records = [r for _, r in fitted]
    record = {"runs": records}
    save_models(models, run_dir / "models.pt")
    split = {s: [prep.clips[i].clip_id for i in idx] for s, idx in prep.split.items()}
    n_seg = {s: int(sum(prep.clips[i].n_segments for i in idx)) for s, idx in prep.split.items()}
    scenes = {s: sorted({prep.clips[i].scene for i in idx}) for s, idx in prep.split.items()}
    train_info = {"dataset_root": str(prep.root), "generated": prep.generated, "split_seed": cfg.split.seed,
                  "split_source": "dataset" if all(c.split is not None for c in prep.clips) and
                  cfg.split.source == "dataset" else "fractions", "split_unit": "scene",
                  "split": split, "scenes": scenes, "n_scenes": {s: len(v) for s, v in scenes.items()},
                  "segments": n_seg, "training_seeds": cfg.models.seeds, "noise_seeds": cfg.protocol.noise_seeds,
                  "hyper_parameters": cfg.models.model_dump(mode="json"), "training": record,
                  "data_seconds": round(data_s, 2), "versions": _versions(),
                  "environment": {k: v for k, v in environment_record().items() if k != "versions"},
                  "torch_threads": torch.get_num_threads()}
    write_json(run_dir / "train.json", train_info)
    mark_stage(run_dir, "train", time.perf_counter() - t0, {"data_seconds": round(data_s, 2)})
    return Context(run_dir, cfg, prep, models, progress)


def _fusion_job(k: int) -> tuple:
    """train_all's stage 2 for the k-th training seed (in a worker)."""
    cfg, prep, val_noisy, trained = job_context()
    torch.set_num_threads(cfg.models.torch_threads)
    return train_all(cfg, prep, False, cfg.models.seeds[k], val_noisy, trained=trained[k])


def _aggregate(per_seed: list[dict]) -> dict:
    out: dict[str, float | None] = {}
    for k in per_seed[0]:
        vals = [r[k] for r in per_seed if r.get(k) is not None]
        if vals:
            out[k] = float(np.mean(vals))
            out[f"{k}_std"] = float(np.std(vals))
        else:
            out[k] = None
    return out


def gate_params(ctx: Context) -> tuple[GateParams, dict]:
    if ctx.gate is None:
        seed = ctx.cfg.protocol.noise_seeds[0]
        val = ctx.outputs("standard", seed, "val")
        ctx.gate = choose_gate(val.alpha, ctx.labels("val"), ctx.clip_ids("val"), ctx.cfg.gate,
                               ctx.cfg.gate.max_val_accuracy_drop, ctx.cfg.fusion.construction)
    return ctx.gate


#: paired comparisons (A, B, name); the objective's effect is each modality's EDL vs sigmoid head
COMPARISONS = (
    ("d", "b", "EDL + average (d) vs Late Fusion (b)"),
    ("e", "b", "EDL + DS (e) vs Late Fusion (b)"),
    ("d", "c", "EDL + average (d) vs GMU (c)"),
    ("d", "b_clean_fit", "EDL + average (d) vs clean-fitted Late Fusion (control)"),
    ("e", "d", "DS (e) vs average (d), standard noise"),
    ("g", "d_prime", "DS (g) vs average (d'), all modalities noisy"),
    ("h_discounted", "d", "discounted (h) vs average (d)"),
    ("f", "e", "DS + gating (f) vs DS (e)"),
    ("clean_e", "clean_d", "DS vs average, clean test"),
    *((f"a_edl_{m}", f"a_{m}", f"objective: EDL vs sigmoid head, {m}") for m in MODALITIES),
)


def comparison_id(a: str, b: str) -> str:
    """The stable id of the paired comparison A - B (condition keys): what the report looks rows up by;
    the display name may change, the id does not."""
    return f"{a} vs {b}"


def compare(ctx: Context, name: str, correct_a: np.ndarray, correct_b: np.ndarray, clusters: np.ndarray,
            comparison: str | None = None) -> dict:
    """Paired accuracy comparison A - B on per-row correctness (averaged over training runs and
    noise seeds): scene-clustered sign-flip permutation p, MDE at 80 % power, clustered bootstrap CI,
    and the verdict of evids.metrics.significance.comparison_verdict ("A beats B", "B beats A",
    "no difference", "undecided")."""
    bc = ctx.cfg.bootstrap
    n_cl = len(set(clusters.tolist())) if len(clusters) else 0
    row = {"comparison": name, "id": comparison or name, "n_segments": len(clusters), "n_clusters": n_cl,
           "cluster_unit": "scene"}
    if len(clusters) == 0 or n_cl < 2:
        return {**row, "delta_accuracy": None, "ci_low": None, "ci_high": None, "p_value": None,
                "p_permutation": None, "mde": None, "verdict": UNDECIDED}
    rng = np.random.default_rng(np.random.SeedSequence([bc.seed, zlib.crc32(name.encode())]))
    perm = paired_permutation_test(correct_a, correct_b, clusters, rng, bc.n_permutations)
    y0 = np.zeros(len(clusters), np.int64)
    boot = paired_bootstrap(lambda a, yy: float(np.mean(a)), y0, correct_a, correct_b, clusters, rng,
                            n_resamples=bc.n_resamples, confidence=bc.confidence)
    # the one verdict rule (docs/EXPERIMENTS.md): beats only when the CI excludes zero and |effect| >= MDE,
    # no difference only when the CI lies inside +-MDE, else undecided
    verdict = comparison_verdict(perm.estimate, boot.ci_low, boot.ci_high, perm.mde)
    return {**row, "delta_accuracy": perm.estimate, "ci_low": boot.ci_low, "ci_high": boot.ci_high,
            "p_value": perm.p_value, "p_bootstrap": boot.p_value, "p_permutation": perm.p_value,
            "permutation_exact": perm.exact, "n_permutations": perm.n_permutations, "mde": perm.mde,
            "sd_cluster_difference": perm.sd, "confidence": boot.confidence, "verdict": verdict}


def _video_by_size(ctx: Context, correct: np.ndarray) -> dict:
    """Video (EDL) accuracy by apparent drone size, on clean test drone segments (mean over runs)."""
    px = np.concatenate([ctx.prep.clips[i].drone_px if ctx.prep.clips[i].drone_px is not None
                         else np.full(ctx.prep.clips[i].n_segments, np.nan) for i in ctx.test])
    y = ctx.labels()
    edges = [0.0, 1.0, 3.0, 6.0, 12.0, 24.0, 48.0]
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (y == 0) & (px >= lo) & (px < hi)
        rows.append({"px_low": lo, "px_high": hi, "n": int(sel.sum()),
                     "accuracy": float(correct[sel].mean()) if sel.any() else None})
    bg = y == 1
    return {"bins": rows, "background_accuracy": float(correct[bg].mean()) if bg.any() else None,
            "condition": "a_edl_video", "variant": "clean"}


def observability_summary(ctx: Context) -> dict:
    """Per split: histogram of the drone's apparent size per segment and the fraction of drone
    segments each sensor observes (simulator truth)."""
    out = {}
    edges = [0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48]
    for split, idx in ctx.prep.split.items():
        drone = [ctx.prep.clips[i] for i in idx if ctx.prep.clips[i].label == 0]
        sizes = [c.drone_px for c in drone if c.drone_px is not None]
        px = np.concatenate(sizes) if sizes else np.zeros(0)
        obs = {m: float(np.mean(np.concatenate([c.observability[m] for c in drone if m in c.observability])))
               if drone and all(m in c.observability for c in drone) else None for m in ("video", "audio", "rf")}
        out[split] = {"n_clips": len(idx), "n_drone_clips": len(drone), "px_edges": edges,
                      "px_hist": np.histogram(px, edges)[0].tolist() if px.size else [],
                      "px_median": float(np.median(px)) if px.size else None, "observed_fraction": obs}
    return out


def stage_evaluate(ctx: Context) -> dict:
    """Every condition under every (training run, noise seed); mean/std over both; scene-clustered
    permutation tests, MDEs and bootstrap CIs on per-row correctness averaged over runs and seeds."""
    t0 = time.perf_counter()
    cfg = ctx.cfg
    y, cid, scn = ctx.labels(), ctx.clip_ids(), ctx.scene_ids()
    gate, gate_info = gate_params(ctx)
    conds = [c for c in CONDITIONS if c.variant != "iq" or ctx.has_iq()]
    skipped = [{"condition": c.key, "reason": "dataset has no rf_iq/ captures (I/Q-level noise impossible)"}
               for c in CONDITIONS if c not in conds]
    # groups of jobs that share degraded inputs: the clean variant once (its outputs serve every
    # seed), then per noise seed every noisy variant (they share the audio and video noise, so
    # those are degraded and encoded once per seed); each group covers every training run
    used = [v for v in VARIANTS if any(c.variant == v for c in conds)]
    noisy = tuple(v for v in used if v != "clean")
    groups = ([(("clean",), tuple(cfg.protocol.noise_seeds))] if "clean" in used else []) + \
        ([((noisy, (s,))) for s in cfg.protocol.noise_seeds] if noisy else [])
    per: dict[str, list[dict]] = {c.key: [] for c in conds}
    correct: dict[str, list[np.ndarray]] = {c.key: [] for c in conds}
    preds0: dict[str, Prediction] = {}
    results = dict(map_groups(ctx, groups, (conds, y, cid, gate), "evaluating conditions"))
    for group in groups:                                   # accumulate in job order (deterministic)
        for variant, seed, run, out, items in results[group]:
            ctx.store.outputs[OutputsKey(variant, seed, "test", run)] = out
            if variant == "clean":
                ctx.store.put_clean(out, "test", run, cfg.protocol.noise_seeds)
            for key, m, ok, pred in items:
                per[key].append(m)
                correct[key].append(ok)
                if pred is not None:
                    preds0[key] = pred
    rows = []
    for c in conds:
        agg = _aggregate([{k: v for k, v in r.items() if k not in ("run", "noise_seed")} for r in per[c.key]])
        accs = np.array([r["accuracy"] for r in per[c.key]]).reshape(-1)
        by_run = [float(np.mean([r["accuracy"] for r in per[c.key] if r["run"] == k])) for k in ctx.runs]
        rows.append({"key": c.key, "label": c.label, "variant": c.variant, "n_segments": len(y),
                     "n_clips": len(set(cid)), "n_scenes": len(set(scn)), "n_runs": len(ctx.runs),
                     "n_seeds": len(cfg.protocol.noise_seeds), "n_evaluations": int(accs.size),
                     "accuracy_std_training": float(np.std(by_run)), **agg})
    mean_correct = {k: np.mean(v, axis=0) for k, v in correct.items()}
    comps = [compare(ctx, name, mean_correct[a], mean_correct[b], scn, comparison_id(a, b))
             for a, b, name in COMPARISONS if a in mean_correct and b in mean_correct]
    arrays = {"labels": y, "clip_ids": cid.astype(str), "scene_ids": scn.astype(str),
              **{f"{k}__probs": p.probs for k, p in preds0.items()},
              **{f"{k}__vacuity": p.vacuity for k, p in preds0.items() if p.vacuity is not None},
              **{f"{k}__conflict": p.conflict for k, p in preds0.items() if p.conflict is not None}}
    with atomic_path(ctx.run_dir / "predictions.npz", suffix=".npz") as tmp:
        # mypy matches a **dict of arrays against the stub's allow_pickle: bool keyword too
        np.savez_compressed(tmp, **arrays)  # type: ignore[arg-type]
    temps = [{"run": k, **{f"T_{n}": v for n, v in m.temperatures.items()},
              **{f"bound_{n}": f for n, f in m.temperature_flags.items()}} for k, m in enumerate(ctx.trained)]
    rf_drop = None
    rows_by = {r["key"]: r for r in rows}
    if "a_edl_rf" in rows_by:
        clean_rf = _clean_unimodal(ctx, "rf", y)
        noisy_rf = _noisy_unimodal(ctx, "rf", y)
        rf_drop = {"clean": clean_rf, "rf_spec_noise": noisy_rf,
                   "drop": None if noisy_rf is None else clean_rf - noisy_rf,
                   "noise": [e.model_dump(mode="json") for e in cfg.protocol.rf_spec]}
    result = {"conditions": rows, "skipped": skipped, "bootstrap": comps, "comparisons": comps,
              "gate_condition_f": gate_info, "noise_protocol": cfg.protocol.model_dump(mode="json"),
              "temperatures": temps, "rf_noise_effect": rf_drop,
              "video_by_size": _video_by_size(ctx, _clean_correct(ctx, "video", y)),
              "observability": observability_summary(ctx),
              "majority_class_accuracy": float(max(np.mean(y == 0), np.mean(y == 1)))}
    write_json(ctx.run_dir / "evaluate.json", result)
    write_csv(ctx.run_dir / "conditions.csv", rows)
    write_csv(ctx.run_dir / "bootstrap.csv", comps)
    mark_stage(ctx.run_dir, "evaluate", time.perf_counter() - t0)
    return result


def _evaluate_group(group: tuple, extra: tuple) -> tuple[tuple, list]:
    """Every condition of the group's variants under its noise seeds and every training run (in a worker)."""
    ctx = job_context()
    conds, y, cid, gate = extra
    cfg = ctx.cfg
    variants, seeds = group
    torch.set_num_threads(cfg.models.torch_threads)
    rows = []
    for seed in seeds:
        for run, variant in [(r, v) for r in ctx.runs for v in variants]:
            out = ctx.outputs(variant, seed, run=run)
            items = []
            for c in conds:
                if c.variant != variant:
                    continue
                pred = predict_condition(c, ctx.trained[run], out, cid, cfg.fusion.c_max, cfg.fusion.construction, gate)
                m = metrics_of(pred, y, cfg.ece_bins)
                m.update({"run": run, "noise_seed": seed})
                first = seed == cfg.protocol.noise_seeds[0] and run == 0
                items.append((c.key, m, pred.probs.argmax(1) == y, pred if first else None))
            rows.append((variant, seed, run, out, items))
        ctx.drop_inputs()
    return group, rows


def map_groups(ctx: Context, groups: list, extra: tuple, label: str, job=None) -> list:
    """The results of ``job(group, extra)`` (default _evaluate_group; each a (group, result) pair)
    for every group, in the order of ``groups`` whatever order the workers finish in, through
    pipeline.forked_results on ``models.train_workers`` processes (each on models.torch_threads
    threads, inheriting the context; results do not depend on the count)."""
    return forked_results(job or _evaluate_group, [(g, extra) for g in groups], ctx.cfg.models.train_workers,
                          label if ctx.progress else None, context=ctx)


def warm_clean(ctx: Context) -> None:
    """Compute every run's clean test outputs here (no-op when cached), so forked jobs inherit them
    instead of each recomputing them."""
    for run in ctx.runs:
        ctx.outputs("clean", 0, run=run)


def _clean_correct(ctx: Context, modality: str, y: np.ndarray) -> np.ndarray:
    m = MODALITIES.index(modality)
    return np.mean([(ctx.outputs("clean", 0, run=r).alpha[m].argmax(1) == y) for r in ctx.runs], axis=0)


def _clean_unimodal(ctx: Context, modality: str, y: np.ndarray) -> float:
    return float(_clean_correct(ctx, modality, y).mean())


def _noisy_unimodal(ctx: Context, modality: str, y: np.ndarray) -> float | None:
    m = MODALITIES.index(modality)
    vals = [(ctx.outputs("all_spec", s, run=r).alpha[m].argmax(1) == y).mean()
            for r in ctx.runs for s in ctx.cfg.protocol.noise_seeds]
    return float(np.mean(vals)) if vals else None


FUSION_RULES = ("late", "gmu", "average", "ds", "yager", "discounted")  # the rules the sweep and conflict study compare


def _sweep_job(job: tuple, extra: tuple) -> tuple[tuple, list[dict]]:
    """The sweep rows of one (modality, severity) over every noise seed and training run (in a worker)."""
    from harness.experiments.config import NoiseEntry

    ctx = job_context()
    cfg, sc = ctx.cfg, ctx.cfg.sweep
    (seeds,) = extra
    modality, sev = job
    torch.set_num_threads(cfg.models.torch_threads)
    y, cid = ctx.labels(), ctx.clip_ids()
    name = getattr(sc, modality)
    import degradations

    stream = MODALITY_TABLE[modality].stream_of(degradations.REGISTRY[name].modality)  # validated: it has one
    if stream == "rf_iq" and not ctx.has_iq():
        return job, []
    per: dict[str, list[dict]] = {}
    for seed, run in [(s_, r_) for s_ in seeds for r_ in ctx.runs]:
        out = ctx.outputs("clean", 0, run=run) if sev == 0 else ctx.outputs(
            "sweep", seed, run=run, **{stream: [NoiseEntry(name=name, severity=sev)]})
        for rule in (*FUSION_RULES, *SWEEP_HEADS):
            head = SWEEP_HEADS.get(rule)        # a unimodal row: the swept modality's own head
            cond = Condition(rule, rule, "sweep", head or rule, modality if head else None)
            pred = predict_condition(cond, ctx.trained[run], out, cid, cfg.fusion.c_max, cfg.fusion.construction,
                                     None)
            m = metrics_of(pred, y, cfg.ece_bins)
            per.setdefault(rule, []).append({k: m[k] for k in ("accuracy", "macro_f1", "ece", "uauc_entropy",
                                                               "uauc_vacuity")})
    ctx.drop_inputs()
    return job, [{"modality": modality, "degradation": name, "severity": sev, "rule": rule,
                  "n_seeds": len(seeds), "n_runs": len(ctx.runs), **_aggregate(vals)} for rule, vals in per.items()]


def stage_sweep(ctx: Context) -> dict:
    """Degradation sweep: one modality degraded at a time over the severity grid, every noise seed."""
    t0 = time.perf_counter()
    cfg = ctx.cfg
    sc = cfg.sweep
    seeds = cfg.protocol.noise_seeds[: sc.n_seeds or None]
    jobs = [(m, s) for m in MODALITIES for s in sc.severities]
    warm_clean(ctx)
    results = dict(map_groups(ctx, jobs, (seeds,), "degradation sweep", job=_sweep_job))
    rows = [row for job in jobs for row in results[job]]   # in job order (deterministic)
    write_csv(ctx.run_dir / "sweep.csv", rows)
    write_json(ctx.run_dir / "sweep.json", {"rows": rows, "seeds": seeds})
    mark_stage(ctx.run_dir, "sweep", time.perf_counter() - t0)
    return {"rows": rows}


def stage_audit(ctx: Context) -> dict:
    """The shortcut audit on this run's own split (train -> test), written to audit.json."""
    from harness.experiments.audit import audit_clips

    t0 = time.perf_counter()
    res = audit_clips(ctx.prep.clips, ctx.prep.split, ctx.cfg.audit)
    write_json(ctx.run_dir / "audit.json", res)
    mark_stage(ctx.run_dir, "audit", time.perf_counter() - t0)
    return res


def stage_examples(ctx: Context) -> Path:
    """figures/examples.png: one Drone and one Background test clip, clean and degraded."""
    from harness.report import example_figure

    seed = ctx.cfg.protocol.noise_seeds[0]
    idx = []
    for label in (0, 1):
        idx += [i for i in ctx.test if ctx.prep.clips[i].label == label][:1]
    variants = ["standard", "all_spec"] + (["iq"] if ctx.has_iq() else [])
    deg = {v: [degrade_clip(ctx.prep.clips[i], i, seed, **ctx.noise_kwargs(v)) for i in idx] for v in variants}
    path = ctx.run_dir / "figures" / "examples.png"
    example_figure(ctx.prep.clips, idx, deg, path)
    return path
