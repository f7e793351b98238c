"""Training and inference pipeline of the E2-style ablation: six unimodal models (audio/video/RF x
sigmoid/evidential), stage-2 fusion heads on frozen backbones (Late Fusion, GMU), a temperature
for the sigmoid control, and batched encoding of (degraded) inputs into per-modality outputs."""
from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import torch

from evids.fusion import GMU, LateFusion
from evids.modalities import INPUT_FIELD, MODALITIES, Modality
from evids.models.backbones import HeadKind, UnimodalModel, build_model, seeded_init
from evids.models.train import TrainResult, predict, train_model
from harness.experiments.config import ExperimentConfig, ModelsConfig
from harness.experiments.data import Prepared, labels_of, stack
from simulator.files import atomic_path
from simulator.jobs import Start, iter_jobs, job_context
from simulator.seeding import STREAMS

HEADS: tuple[HeadKind, ...] = ("sigmoid", "evidential")


def model_seed(base: int, modality: str, head: str) -> tuple[int, int]:
    """(init seed, data-order seed) of one model, from SeedSequence([base, modality, head])."""
    ss = np.random.SeedSequence([int(base), MODALITIES.index(modality), HEADS.index(head)])
    a, b = ss.generate_state(2, dtype=np.uint32)
    return int(a), int(b)


@dataclass
class Models:
    """Everything trained with one training seed: unimodal models, fusion heads (fitted on noisy
    validation outputs, and clean-fitted controls) and temperatures with their bound flags."""

    unimodal: dict[tuple[str, str], UnimodalModel]
    late: LateFusion
    gmu: GMU
    late_clean: LateFusion | None = None
    gmu_clean: GMU | None = None
    temperatures: dict[str, float] = field(default_factory=dict)
    temperature_flags: dict[str, str | None] = field(default_factory=dict)

    @property
    def temperature(self) -> float:
        return self.temperatures.get("late", 1.0)

    def late_head(self, clean_fit: bool = False) -> LateFusion:
        """Late Fusion fitted on noisy validation outputs, or (``clean_fit``) the clean-fitted control."""
        head = self.late_clean if clean_fit else self.late
        if head is None:
            raise ValueError(f"these models have no {'clean-fitted ' if clean_fit else ''}Late Fusion head")
        return head

    def gmu_head(self, clean_fit: bool = False) -> GMU:
        """GMU fitted on noisy validation outputs, or (``clean_fit``) the clean-fitted control."""
        head = self.gmu_clean if clean_fit else self.gmu
        if head is None:
            raise ValueError(f"these models have no {'clean-fitted ' if clean_fit else ''}GMU head")
        return head


@dataclass
class Outputs:
    """Per-modality outputs on N segments: sigmoid logits (3, N), evidential alphas (3, N, 2),
    sigmoid-backbone embeddings (3, N, d)."""

    logit: np.ndarray
    alpha: np.ndarray
    emb: np.ndarray

    def replace(self, m: int, other: Outputs) -> Outputs:
        """A copy with modality ``m`` taken from ``other``."""
        return self.with_modality(m, other.logit[m], other.alpha[m], other.emb[m])

    def with_modality(self, m: int, logit: np.ndarray, alpha: np.ndarray, emb: np.ndarray) -> Outputs:
        """A copy with modality ``m``'s outputs replaced."""
        new_logit, new_alpha, new_emb = self.logit.copy(), self.alpha.copy(), self.emb.copy()
        new_logit[m], new_alpha[m], new_emb[m] = logit, alpha, emb
        return Outputs(new_logit, new_alpha, new_emb)


def _inputs(modality: str, mfcc: np.ndarray, video: np.ndarray, rf: np.ndarray) -> np.ndarray:
    return (mfcc, video, rf)[MODALITIES.index(modality)]


def encode_modality(models: Models, modality: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sigmoid logits (N,), evidential alphas (N, 2), sigmoid-backbone embeddings (N, d)) of one
    modality's frozen models on its inputs ``x``."""
    logit, emb = predict(models.unimodal[(modality, "sigmoid")], x)
    alpha, _ = predict(models.unimodal[(modality, "evidential")], x)
    return logit, alpha, emb


def encode(models: Models, mfcc: np.ndarray, video: np.ndarray, rf: np.ndarray,
           only: tuple[str, ...] = MODALITIES) -> Outputs:
    """Run the frozen unimodal models; modalities not in ``only`` are left zero."""
    n = len(mfcc)
    d = int(models.unimodal[("audio", "sigmoid")].backbone.out_features)
    logit, alpha, emb = np.zeros((3, n)), np.ones((3, n, 2)), np.zeros((3, n, d), np.float32)
    for m, modality in enumerate(MODALITIES):
        if modality not in only:
            continue
        logit[m], alpha[m], emb[m] = encode_modality(models, modality, _inputs(modality, mfcc, video, rf))
    return Outputs(logit, alpha, emb)


def late_probs(models: Models, out: Outputs, clean_fit: bool = False) -> np.ndarray:
    """Late Fusion P(class 1) (N,); ``clean_fit`` uses the control fitted on clean train outputs."""
    head = models.late_head(clean_fit)
    with torch.no_grad():
        return head(torch.from_numpy(out.logit)).double().numpy()


def gmu_logit(models: Models, out: Outputs, clean_fit: bool = False) -> np.ndarray:
    head = models.gmu_head(clean_fit)
    with torch.no_grad():
        return head([torch.from_numpy(e) for e in out.emb]).squeeze(-1).double().numpy()


def _train_fusion(module: torch.nn.Module, forward, y: np.ndarray, epochs: int, lr: float,
                  logits_out: bool) -> list[float]:
    target = torch.from_numpy(y.astype(np.float64)).float()
    opt = torch.optim.Adam(module.parameters(), lr=lr)
    losses = []
    for _ in range(epochs):
        out = forward().float()
        if logits_out:
            loss = torch.nn.functional.binary_cross_entropy_with_logits(out, target)
        else:
            loss = torch.nn.functional.binary_cross_entropy(out.clamp(1e-6, 1 - 1e-6), target)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    return losses


def training_seed_base(seed: int) -> int:
    return int(seed)


def _train_job(mc: ModelsConfig, modality: Modality, head: HeadKind, train_seed: int) -> tuple[dict, dict]:
    """Train one unimodal model on the arrays in the job context; (state dict, record)."""
    arrays = job_context()
    x, y_tr, y_va = arrays["x"], arrays["y_tr"], arrays["y_va"]
    torch.set_num_threads(mc.torch_threads)
    init_seed, order_seed = model_seed(training_seed_base(train_seed), modality, head)
    model = build_model(modality, head, init_seed, mc.width, mc.embedding, mc.video_pool, mc.video_frames)
    res: TrainResult = train_model(model, x["train"][INPUT_FIELD[modality]], y_tr, x["val"][INPUT_FIELD[modality]],
                                   y_va, mc.train, order_seed)
    return model.state_dict(), {"init_seed": init_seed, "order_seed": order_seed, **res.to_json()}


def forked_map(fn: Callable, calls: list[tuple], workers: int, label: str | None = None, context: Any = None):
    """Yield (i, fn(*calls[i])) for every call, in completion order: in ``workers`` forked
    processes (they inherit this process's memory, so large inputs are never pickled), else
    in-process; with a progress bar when ``label`` is given; ``context`` is what
    ``simulator.jobs.job_context()`` returns inside ``fn`` (see simulator.jobs)."""
    start: Start = "fork" if workers > 1 and len(calls) > 1 else "inline"
    return iter_jobs(fn, calls, workers=workers, start=start, progress=label, context=context)


def forked_results(fn: Callable, calls: list[tuple], workers: int, label: str | None = None,
                   context: Any = None) -> list:
    """``forked_map``'s results as a list in call order (completion order depends on timing: where
    the results' order matters, e.g. training samples, take them from here)."""
    done = dict(forked_map(fn, calls, workers, label, context))
    return [done.pop(i) for i in range(len(calls))]


def train_unimodal(cfg: ExperimentConfig, prep: Prepared, seeds: list[int], progress: bool = True
                   ) -> list[tuple[dict[tuple[str, str], UnimodalModel], dict]]:
    """Stage 1 for every training seed: six unimodal models per seed, trained as independent jobs
    (seed x modality x head) in ``models.train_workers`` forked processes, longest (video) first.
    Each job's weights depend only on its seeds, so the result is the same for any worker count."""
    tr, va = prep.split["train"], prep.split["val"]
    arrays = dict(x={s: {k: stack(prep.clips, idx, k) for k in ("mfcc", "video", "rf")}
                     for s, idx in (("train", tr), ("val", va))},
                  y_tr=labels_of(prep.clips, tr), y_va=labels_of(prep.clips, va))
    mc = cfg.models
    order = {"video": 0, "rf": 1, "audio": 2}
    jobs = sorted(((s, m, h) for s in seeds for m in MODALITIES for h in HEADS), key=lambda j: order[j[1]])
    calls = [(mc, m, h, s) for s, m, h in jobs]
    label = f"training unimodal models ({len(seeds)} seeds)" if progress else None
    # fork: the workers inherit the arrays (pickling ~0.7 GB of video per worker is avoided);
    # torch has run no parallel region in this process yet (1 thread), so forking is safe
    done = {jobs[i]: r for i, r in forked_map(_train_job, calls, mc.train_workers, label, context=arrays)}
    del arrays
    results = []
    for seed in seeds:
        unimodal: dict[tuple[str, str], UnimodalModel] = {}
        record: dict[str, Any] = {"train_seed": int(seed), "unimodal": {}}
        for modality in MODALITIES:
            for head in HEADS:
                state, rec = done[(seed, modality, head)]
                model = build_model(modality, head, 0, mc.width, mc.embedding, mc.video_pool, mc.video_frames)
                model.load_state_dict(state)
                model.eval()
                unimodal[(modality, head)] = model
                record["unimodal"][f"{modality}/{head}"] = rec
        results.append((unimodal, record))
    return results


def train_all(cfg: ExperimentConfig, prep: Prepared, progress: bool = True, train_seed: int = 0,
              val_noisy: dict[str, np.ndarray] | None = None,
              trained: tuple[dict[tuple[str, str], UnimodalModel], dict] | None = None) -> tuple[Models, dict]:
    """Stage 1 (six unimodal models, seed ``train_seed``; or ``trained``, from train_unimodal) and
    stage 2: Late Fusion / GMU fitted on validation outputs under the test noise protocol
    (``val_noisy`` inputs) and, as a labelled control, on clean train outputs; temperatures for
    every sigmoid model and fusion head."""
    from evids.metrics import fit_temperature_flagged

    tr, va = prep.split["train"], prep.split["val"]
    y_tr, y_va = labels_of(prep.clips, tr), labels_of(prep.clips, va)
    x = {s: {k: stack(prep.clips, idx, k) for k in ("mfcc", "video", "rf")} for s, idx in (("train", tr), ("val", va))}
    mc = cfg.models
    if trained is None:
        trained = train_unimodal(cfg, prep, [train_seed], progress)[0]
    unimodal, record = trained
    stub = Models(unimodal, LateFusion(3), GMU([mc.embedding] * 3, mc.gmu_hidden, 1))
    out_tr = encode(stub, x["train"]["mfcc"], x["train"]["video"], x["train"]["rf"])
    noisy = val_noisy if val_noisy is not None else x["val"]
    out_va = encode(stub, noisy["mfcc"], noisy["video"], noisy["rf"])
    fs = int(np.random.SeedSequence([int(train_seed), STREAMS["fusion_init"]]).generate_state(1, dtype=np.uint32)[0])
    heads = {}
    for name, out, y in (("val_noisy", out_va, y_va), ("train_clean", out_tr, y_tr)):
        with seeded_init(fs):
            late = LateFusion(3)
            gmu = GMU([mc.embedding] * 3, mc.gmu_hidden, 1, gate="sigmoid")
        lt = torch.from_numpy(out.logit).float()
        late_loss = _train_fusion(late, lambda: late(lt), y, mc.fusion_epochs, mc.fusion_lr, logits_out=False)
        et = [torch.from_numpy(e) for e in out.emb]
        gmu_loss = _train_fusion(gmu, lambda: gmu(et).squeeze(-1), y, mc.fusion_epochs, mc.fusion_lr, logits_out=True)
        late.eval()
        gmu.eval()
        heads[name] = (late, gmu)
        record.setdefault("fusion", {})[name] = {
            "late_fusion_weights": late.weights.detach().numpy().round(4).tolist(),
            "late_final_loss": round(late_loss[-1], 6), "gmu_final_loss": round(gmu_loss[-1], 6)}
    main = mc.fusion_fit
    control = "train_clean" if main == "val_noisy" else "val_noisy"
    models = Models(unimodal, heads[main][0], heads[main][1], heads[control][0], heads[control][1])
    # temperatures: on validation outputs under the test protocol, with a fresh noise draw for the heads
    t_lo, t_hi = mc.temperature_bounds
    temps: dict[str, float] = {}
    flags: dict[str, str | None] = {}
    for m, modality in enumerate(MODALITIES):
        temps[modality], flags[modality] = fit_temperature_flagged(out_va.logit[m], y_va, t_lo, t_hi)
    p_va = np.clip(late_probs(models, out_va), 1e-12, 1 - 1e-12)
    temps["late"], flags["late"] = fit_temperature_flagged(np.log(p_va / (1 - p_va)), y_va, t_lo, t_hi)
    temps["gmu"], flags["gmu"] = fit_temperature_flagged(gmu_logit(models, out_va), y_va, t_lo, t_hi)
    models.temperatures, models.temperature_flags = temps, flags
    record["fusion"].update({"fusion_seed": fs, "fitted_on": main, "control": control,
                             "temperature_fitted_on": "val (test noise protocol)",
                             "temperature_bounds": [t_lo, t_hi],
                             "temperatures": {k: round(v, 5) for k, v in temps.items()},
                             "temperature_at_bound": flags})
    return models, record


def _state(models: Models) -> dict:
    return {"unimodal": {f"{m}/{h}": mod.state_dict() for (m, h), mod in models.unimodal.items()},
            "late": models.late.state_dict(), "gmu": models.gmu.state_dict(),
            "late_clean": models.late_head(clean_fit=True).state_dict(),
            "gmu_clean": models.gmu_head(clean_fit=True).state_dict(),
            # keys interned: models fitted in a worker arrive with fresh key strings, which pickle
            # would otherwise store again instead of referencing (same values, other bytes)
            "temperatures": {sys.intern(k): v for k, v in models.temperatures.items()},
            "temperature_flags": {sys.intern(k): v for k, v in models.temperature_flags.items()}}


def save_models(models: list[Models], path) -> None:
    """Atomic torch.save of every training seed's state dicts."""
    with atomic_path(Path(path), hidden=False) as tmp:  # torch: archive named "models.pt" as before
        torch.save({"runs": [_state(m) for m in models]}, tmp)


_M = TypeVar("_M", bound=torch.nn.Module)


def _loaded(mod: _M, state_dict: dict) -> _M:
    """``mod`` with ``state_dict`` loaded, in eval mode."""
    mod.load_state_dict(state_dict)
    mod.eval()
    return mod


def _load_one(cfg: ExperimentConfig, state: dict) -> Models:
    mc = cfg.models
    unimodal = {}
    for key, sd in state["unimodal"].items():
        m, h = key.split("/")
        model = build_model(m, h, 0, mc.width, mc.embedding, mc.video_pool, mc.video_frames)
        model.load_state_dict(sd)
        model.eval()
        unimodal[(m, h)] = model

    def late(name: str) -> LateFusion:
        with seeded_init(0):
            mod = LateFusion(3)
        return _loaded(mod, state[name])

    def gmu(name: str) -> GMU:
        with seeded_init(0):
            mod = GMU([mc.embedding] * 3, mc.gmu_hidden, 1, gate="sigmoid")
        return _loaded(mod, state[name])

    return Models(unimodal, late("late"), gmu("gmu"), late("late_clean"), gmu("gmu_clean"),
                  temperatures=dict(state["temperatures"]), temperature_flags=dict(state["temperature_flags"]))


def load_models(cfg: ExperimentConfig, path) -> list[Models]:
    state = torch.load(path, map_location="cpu", weights_only=True)
    return [_load_one(cfg, s) for s in state["runs"]]
