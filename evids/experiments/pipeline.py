"""Training and inference pipeline of the E2-style ablation: six unimodal models (audio/video/RF x
sigmoid/evidential), stage-2 fusion heads on frozen backbones (Late Fusion, GMU), a temperature
for the sigmoid control, and batched encoding of (degraded) inputs into per-modality outputs."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from evids.experiments.config import ExperimentConfig
from evids.experiments.data import Prepared, labels_of, stack
from evids.fusion import GMU, LateFusion
from evids.models.backbones import MODALITIES, UnimodalModel, build_model, seeded_init
from evids.models.train import TrainResult, predict, train_model

HEADS = ("sigmoid", "evidential")


def model_seed(base: int, modality: str, head: str) -> tuple[int, int]:
    """(init seed, data-order seed) of one model, from SeedSequence([base, modality, head])."""
    ss = np.random.SeedSequence([int(base), MODALITIES.index(modality), HEADS.index(head)])
    a, b = ss.generate_state(2, dtype=np.uint32)
    return int(a), int(b)


@dataclass
class Models:
    """Everything trained: unimodal models, fusion heads and the control's temperature."""

    unimodal: dict[tuple[str, str], UnimodalModel]
    late: LateFusion
    gmu: GMU
    temperature: float


@dataclass
class Outputs:
    """Per-modality outputs on N segments: sigmoid logits (3, N), evidential alphas (3, N, 2),
    sigmoid-backbone embeddings (3, N, d)."""

    logit: np.ndarray
    alpha: np.ndarray
    emb: np.ndarray

    def replace(self, m: int, other: "Outputs") -> "Outputs":
        logit, alpha, emb = self.logit.copy(), self.alpha.copy(), self.emb.copy()
        logit[m], alpha[m], emb[m] = other.logit[m], other.alpha[m], other.emb[m]
        return Outputs(logit, alpha, emb)


def _inputs(modality: str, mfcc: np.ndarray, video: np.ndarray, rf: np.ndarray) -> np.ndarray:
    return {"audio": mfcc, "video": video, "rf": rf}[modality]


def encode(models: Models, mfcc: np.ndarray, video: np.ndarray, rf: np.ndarray,
           only: tuple[str, ...] = MODALITIES) -> Outputs:
    """Run the frozen unimodal models; modalities not in ``only`` are left zero."""
    n = len(mfcc)
    d = int(models.unimodal[("audio", "sigmoid")].backbone.out_features)
    logit, alpha, emb = np.zeros((3, n)), np.ones((3, n, 2)), np.zeros((3, n, d), np.float32)
    for m, modality in enumerate(MODALITIES):
        if modality not in only:
            continue
        x = _inputs(modality, mfcc, video, rf)
        logit[m], emb[m] = predict(models.unimodal[(modality, "sigmoid")], x)
        alpha[m], _ = predict(models.unimodal[(modality, "evidential")], x)
    return Outputs(logit, alpha, emb)


def late_probs(models: Models, out: Outputs) -> np.ndarray:
    """Late Fusion P(class 1) (N,)."""
    with torch.no_grad():
        return models.late(torch.from_numpy(out.logit)).double().numpy()


def gmu_logit(models: Models, out: Outputs) -> np.ndarray:
    with torch.no_grad():
        return models.gmu([torch.from_numpy(e) for e in out.emb]).squeeze(-1).double().numpy()


def _train_fusion(module: torch.nn.Module, forward, y: np.ndarray, epochs: int, lr: float, logits_out: bool) -> list[float]:
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


def train_all(cfg: ExperimentConfig, prep: Prepared, progress: bool = True) -> tuple[Models, dict]:
    """Stage 1 (six unimodal models) and stage 2 (fusion heads on frozen train-split outputs)."""
    from evids.metrics import fit_temperature

    tr, va = prep.split["train"], prep.split["val"]
    y_tr, y_va = labels_of(prep.clips, tr), labels_of(prep.clips, va)
    x = {s: {k: stack(prep.clips, idx, k) for k in ("mfcc", "video", "rf")} for s, idx in (("train", tr), ("val", va))}
    mc = cfg.models
    unimodal: dict[tuple[str, str], UnimodalModel] = {}
    record: dict = {"unimodal": {}}
    jobs = [(m, h) for m in MODALITIES for h in HEADS]
    if progress:
        from rich.progress import track

        jobs = track(jobs, description="training unimodal models", total=len(jobs))
    key = {"audio": "mfcc", "video": "video", "rf": "rf"}
    for modality, head in jobs:
        init_seed, order_seed = model_seed(mc.seed, modality, head)
        model = build_model(modality, head, init_seed, mc.width, mc.embedding, mc.video_pool)
        res: TrainResult = train_model(model, x["train"][key[modality]], y_tr, x["val"][key[modality]], y_va,
                                       mc.train, order_seed)
        unimodal[(modality, head)] = model
        record["unimodal"][f"{modality}/{head}"] = {"init_seed": init_seed, "order_seed": order_seed, **res.to_json()}
    stub = Models(unimodal, LateFusion(3), GMU([mc.embedding] * 3, mc.gmu_hidden, 1), 1.0)
    out_tr = encode(stub, x["train"]["mfcc"], x["train"]["video"], x["train"]["rf"])
    fs = int(np.random.SeedSequence([mc.seed, 99]).generate_state(1, dtype=np.uint32)[0])
    with seeded_init(fs):
        late = LateFusion(3)
        gmu = GMU([mc.embedding] * 3, mc.gmu_hidden, 1, gate="sigmoid")
    lt = torch.from_numpy(out_tr.logit).float()
    late_loss = _train_fusion(late, lambda: late(lt), y_tr, mc.fusion_epochs, mc.fusion_lr, logits_out=False)
    et = [torch.from_numpy(e) for e in out_tr.emb]
    gmu_loss = _train_fusion(gmu, lambda: gmu(et).squeeze(-1), y_tr, mc.fusion_epochs, mc.fusion_lr, logits_out=True)
    late.eval()
    gmu.eval()
    models = Models(unimodal, late, gmu, 1.0)
    out_va = encode(models, x["val"]["mfcc"], x["val"]["video"], x["val"]["rf"])
    p_va = np.clip(late_probs(models, out_va), 1e-6, 1 - 1e-6)
    models.temperature = float(fit_temperature(np.log(p_va / (1 - p_va)), y_va, t_min=0.05, t_max=200.0))
    record["fusion"] = {"fusion_seed": fs, "late_fusion_weights": late.weights.detach().numpy().round(4).tolist(),
                        "late_final_loss": round(late_loss[-1], 6), "gmu_final_loss": round(gmu_loss[-1], 6),
                        "temperature_fitted_on": "val", "temperature": round(models.temperature, 5)}
    return models, record


def save_models(models: Models, path) -> None:
    """Atomic torch.save of every state dict."""
    import os

    state = {"unimodal": {f"{m}/{h}": mod.state_dict() for (m, h), mod in models.unimodal.items()},
             "late": models.late.state_dict(), "gmu": models.gmu.state_dict(), "temperature": models.temperature}
    tmp = f"{path}.tmp-{os.getpid()}"
    torch.save(state, tmp)
    os.replace(tmp, path)


def load_models(cfg: ExperimentConfig, path) -> Models:
    state = torch.load(path, map_location="cpu", weights_only=True)
    mc = cfg.models
    unimodal = {}
    for key, sd in state["unimodal"].items():
        m, h = key.split("/")
        model = build_model(m, h, 0, mc.width, mc.embedding, mc.video_pool)
        model.load_state_dict(sd)
        model.eval()
        unimodal[(m, h)] = model
    with seeded_init(0):
        late, gmu = LateFusion(3), GMU([mc.embedding] * 3, mc.gmu_hidden, 1, gate="sigmoid")
    late.load_state_dict(state["late"])
    gmu.load_state_dict(state["gmu"])
    late.eval()
    gmu.eval()
    return Models(unimodal, late, gmu, float(state["temperature"]))
