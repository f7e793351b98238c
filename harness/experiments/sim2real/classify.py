"""Crop classifiers of the sim-to-real protocol and the real-vs-synthetic domain classifier.

Training conditions (docs/SIM2REAL.md), all evaluated on the real evaluation half:
(a) real calibration half; (b) synthetic only; (c) synthetic + real calibration half; (d) few-shot
real (``few_shot_fraction`` of the calibration clips per class, at least one); (d+) few-shot real +
synthetic. The mixed conditions (c) and (d+) are domain-balanced like the audio track's: real and
synthetic crops carry equal total weight in the loss, and inside each domain every class does, so a
larger synthetic set does not drown the real crops (:func:`domain_balanced_weights`). Each condition
is trained with every training seed; its figure is the mean over seeds of
the balanced accuracy, and its 95 % interval comes from a clip bootstrap of the evaluation half
(the same clip draws for every seed and condition, so ratios and differences are paired).
Tuning on the calibration half (``evids sim2real --tune``) cross-fits instead (:class:`CrossFit`): the
calibration clips split in two folds, each fold's crops scored by models trained on the other fold
(and on the synthetic crops), so every crop is scored by a model that never saw its clip.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from evids.metrics.bootstrap import clustered_bootstrap
from harness.experiments.sim2real.samples import FrameSample

CONDITIONS = ("a_real", "b_synthetic", "c_synthetic_plus_real", "d_few_shot", "d_plus_few_shot_synthetic")
CONDITION_LABELS = {
    "a_real": "(a) real calibration half",
    "b_synthetic": "(b) synthetic only",
    "c_synthetic_plus_real": "(c) synthetic + real calibration half (domain-balanced)",
    "d_few_shot": "(d) few-shot real",
    "d_plus_few_shot_synthetic": "(d+) few-shot real + synthetic (domain-balanced)",
}
Z_MDE = 1.959964 + 0.841621        # two-sided 5 % test with 80 % power


def balanced_accuracy(y: np.ndarray, pred: np.ndarray) -> float:
    """Mean recall over the classes present in ``y``."""
    classes = np.unique(y)
    if classes.size == 0:
        return float("nan")
    return float(np.mean([np.mean(pred[y == c] == c) for c in classes]))


def mean_balanced_accuracy(y: np.ndarray, predicted: np.ndarray) -> float:
    """The mean over seeds of the balanced accuracy of ``predicted`` (n_seeds, n) against ``y``: a
    condition's figure."""
    return float(np.mean([balanced_accuracy(y, p) for p in predicted]))


@dataclass
class CropSet:
    x: np.ndarray          # (n, channels, px, px) float32 in [-0.5, 0.5]
    y: np.ndarray          # (n,) int
    clip: np.ndarray       # (n,) str: the clip/sequence id
    domain: np.ndarray | None = None   # (n,) int: which set of a :func:`concat` a crop came from; None = one

    def images(self) -> np.ndarray:
        """The crops back as 8-bit images: (n, px, px) grey or (n, px, px, 3) colour (the inverse of
        :func:`crop_set`'s scaling)."""
        images = np.clip(np.rint((self.x + 0.5) * 255.0), 0, 255).astype(np.uint8)
        return images[:, 0] if images.shape[1] == 1 else images.transpose(0, 2, 3, 1)


def per_class(y: np.ndarray, preds: np.ndarray, n_classes: int) -> dict[str, list]:
    """Per-class recall (mean over the seeds' predictions ``preds``, shape (n_seeds, n_test); None for a
    class absent from ``y``) and the confusion counts summed over seeds (rows true, columns predicted)."""
    confusion = np.zeros((n_classes, n_classes), np.int64)
    for row in preds:
        np.add.at(confusion, (y, row), 1)
    totals = confusion.sum(axis=1)
    recall = [float(confusion[k, k] / totals[k]) if totals[k] else None for k in range(n_classes)]
    return {"recall": recall, "confusion": confusion.tolist()}


def majority_vote(preds: np.ndarray, n_classes: int) -> np.ndarray:
    """Per column of ``preds`` (n_seeds, n): the class most seeds predicted (a tie: the lowest index)."""
    counts = np.zeros((n_classes, preds.shape[1]), np.int64)
    for row in preds:
        np.add.at(counts, (row, np.arange(preds.shape[1])), 1)
    return counts.argmax(axis=0)


def crop_set(samples: Sequence[FrameSample], classes: Sequence[str], kind: str = "crop") -> CropSet:
    """Stack target crops (``kind="crop"``) or background patches into a training array."""
    rows: list[tuple[np.ndarray, int, str]] = []
    for s in samples:
        image = s.crop if kind == "crop" else s.background
        if s.cls in classes and image is not None and image.size:
            rows.append((image, classes.index(s.cls), s.clip))
    if not rows:
        return CropSet(np.zeros((0, 1, 1, 1), np.float32), np.zeros(0, np.int64), np.zeros(0, str))
    imgs = np.stack([r[0] for r in rows]).astype(np.float32) / 255.0 - 0.5
    x = imgs[:, None] if imgs.ndim == 3 else imgs.transpose(0, 3, 1, 2)
    return CropSet(np.ascontiguousarray(x), np.array([r[1] for r in rows], np.int64), np.array([r[2] for r in rows]))


def concat(*sets: CropSet) -> CropSet:
    """The crops of ``sets`` in order, each set its own domain (0, 1, ...; a set that is itself a
    concatenation keeps its domains, shifted past the earlier sets')."""
    sets = tuple(s for s in sets if len(s.y))
    domains, offset = [], 0
    for s in sets:
        d = np.zeros(len(s.y), np.int64) if s.domain is None else np.asarray(s.domain, np.int64)
        domains.append(d + offset)
        offset += int(d.max()) + 1
    return CropSet(np.concatenate([s.x for s in sets]), np.concatenate([s.y for s in sets]),
                   np.concatenate([s.clip for s in sets]), np.concatenate(domains) if domains else None)


def domain_balanced_weights(y: np.ndarray, domain: np.ndarray) -> np.ndarray:
    """Per-sample loss weights: every domain's total weight equal, and inside a domain every label
    present in it equal; mean 1. One domain: plain class balancing."""
    y, domain = np.asarray(y), np.asarray(domain)
    w = np.zeros(y.size)
    domains = np.unique(domain)
    for d in domains:
        in_d = domain == d
        labels = np.unique(y[in_d])
        for lab in labels:
            m = in_d & (y == lab)
            w[m] = 1.0 / (m.sum() * labels.size * domains.size)
    return w * y.size / w.sum()


def few_shot_clips(samples: Sequence[FrameSample], fraction: float, rng: np.random.Generator) -> set[str]:
    """``fraction`` of each class's clips (at least one), drawn with ``rng``."""
    by_class: dict[str, list[str]] = {}
    for s in samples:
        clips = by_class.setdefault(s.cls, [])
        if s.clip not in clips:
            clips.append(s.clip)
    chosen: set[str] = set()
    for cls in sorted(by_class):
        clips = sorted(by_class[cls])
        k = max(1, int(round(fraction * len(clips))))
        chosen.update(rng.choice(clips, size=min(k, len(clips)), replace=False).tolist())
    return chosen


def _net(in_channels: int, n_classes: int):
    from torch import nn

    # 32 px in: a 5x5 stride-2 stem, then two 3x3 blocks at 8x8 and 4x4 (0.7 M multiply-adds per grey
    # crop, a quarter of three 3x3 blocks at full resolution: the 2-core budget of the harness)
    return nn.Sequential(
        nn.Conv2d(in_channels, 16, 5, stride=2, padding=2), nn.BatchNorm2d(16), nn.ReLU(), nn.MaxPool2d(2),
        nn.Conv2d(16, 32, 3, padding=1), nn.BatchNorm2d(32), nn.ReLU(), nn.MaxPool2d(2),
        nn.Conv2d(32, 64, 3, padding=1), nn.BatchNorm2d(64), nn.ReLU(), nn.AdaptiveAvgPool2d(1),
        nn.Flatten(), nn.Dropout(0.2), nn.Linear(64, n_classes))


def train_cnn(train: CropSet, n_classes: int, *, seed: int, steps: int, batch_size: int, learning_rate: float):
    """A small CNN trained with class-balanced cross-entropy (domain- and class-balanced when ``train``
    holds more than one domain: :func:`domain_balanced_weights`) and random flips for a fixed number of
    optimiser ``steps`` (every condition gets the same number, whatever its size: counted in epochs, a
    few-shot set of 200 crops got 24 steps and the (d+)-(d) gain measured under-training); the
    batches cycle through fresh permutations. Deterministic per seed."""
    import torch

    torch.manual_seed(seed)
    gen = torch.Generator().manual_seed(seed)
    net = _net(train.x.shape[1], n_classes)
    counts = np.bincount(train.y, minlength=n_classes).astype(np.float64)
    weights = torch.tensor(np.where(counts > 0, counts.sum() / np.maximum(counts, 1) / n_classes, 0.0),
                           dtype=torch.float32)
    class_loss = torch.nn.CrossEntropyLoss(weight=weights)
    per_sample = torch.nn.CrossEntropyLoss(reduction="none")
    mixed = train.domain is not None and np.unique(train.domain).size > 1
    sample_w = torch.tensor(domain_balanced_weights(train.y, train.domain) if train.domain is not None and mixed
                            else np.ones(len(train.y)), dtype=torch.float32)

    def batch_loss(logits, target, idx):
        if not mixed:
            return class_loss(logits, target)
        w = sample_w[idx]      # the weighted mean over the batch, as CrossEntropyLoss(weight=)'s is
        return (per_sample(logits, target) * w).sum() / w.sum()

    opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
    x, y = torch.from_numpy(train.x), torch.from_numpy(train.y)
    n = len(y)
    batch = max(2, min(batch_size, n))
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=learning_rate, total_steps=max(1, steps))
    net.train()
    order = torch.randperm(n, generator=gen)
    at = 0
    for _ in range(max(1, steps)):
        if at + batch > n:
            order, at = torch.randperm(n, generator=gen), 0
        idx = order[at:at + batch]
        at += batch
        xb = x[idx]
        flip = torch.rand(len(idx), generator=gen) < 0.5
        xb = torch.where(flip[:, None, None, None], xb.flip(3), xb)
        opt.zero_grad()
        batch_loss(net(xb), y[idx], idx).backward()
        opt.step()
        sched.step()
    net.eval()
    return net


def predict(net, x: np.ndarray, batch_size: int = 1024) -> np.ndarray:
    """Class probabilities (n, n_classes)."""
    import torch

    out = []
    with torch.no_grad():
        for start in range(0, len(x), batch_size):
            out.append(torch.softmax(net(torch.from_numpy(x[start:start + batch_size])), dim=1).numpy())
    return np.concatenate(out) if out else np.zeros((0, 0), np.float32)


@dataclass
class CrossFit:
    """Cross-fitting: ``sets[k]`` are the training sets (condition -> crops) whose models score the test
    crops of ``held_out[k]`` (boolean masks over the test crops, together a partition). A condition
    whose set is the same object in several folds is trained once and scores all their crops."""

    sets: list[dict[str, CropSet]]
    held_out: list[np.ndarray]

    def __post_init__(self) -> None:
        if not self.sets or len(self.sets) != len(self.held_out):
            raise ValueError("sets and held_out: one mask per fold, at least one fold")
        masks = np.stack([np.asarray(m, bool) for m in self.held_out])
        if not np.all(masks.sum(axis=0) == 1):
            raise ValueError("held_out: every test crop must be held out by exactly one fold")
        names = [list(fold) for fold in self.sets]
        if any(n != names[0] for n in names):
            raise ValueError("sets: every fold needs the same conditions, in the same order")

    def units(self) -> list[tuple[str, CropSet, np.ndarray]]:
        """(condition, training set, held-out mask) per model to train: folds sharing a set merged."""
        out: list[tuple[str, CropSet, np.ndarray]] = []
        for name in self.sets[0]:
            seen: dict[int, int] = {}
            for fold, mask in zip(self.sets, self.held_out):
                key = id(fold[name])
                if key in seen:
                    k = seen[key]
                    out[k] = (name, out[k][1], out[k][2] | np.asarray(mask, bool))
                else:
                    seen[key] = len(out)
                    out.append((name, fold[name], np.asarray(mask, bool).copy()))
        return out


def _interval(res) -> dict[str, float]:
    return {"estimate": res.estimate, "ci_low": res.ci_low, "ci_high": res.ci_high}


def _condition_job(name: str, seed: int) -> tuple[np.ndarray, np.ndarray | None]:
    """Train condition ``name`` with ``seed`` (one torch thread); its predicted classes on the test crops
    and, for the condition named by the context's ``reverse`` (if any), on the reverse set's crops (else None)."""
    import torch

    torch.set_num_threads(1)
    from simulator.jobs import job_context

    f = job_context()
    net = train_cnn(f["sets"][name], f["n_classes"], seed=seed, **f["train"])
    test = predict(net, f["test"].x).argmax(1)
    reverse = f.get("reverse")
    if reverse is not None and reverse[0] == name:
        return test, predict(net, reverse[1].x).argmax(1)
    return test, None


def evaluate_conditions(sets: dict[str, CropSet] | CrossFit, test: CropSet, n_classes: int, *, seeds: Sequence[int],
                        steps: int, batch_size: int, learning_rate: float, bootstrap: int, rng_seed: int,
                        workers: int = 1, label: str | None = None, reverse: CropSet | None = None,
                        predictions: Path | None = None) -> dict[str, Any]:
    """Train every condition x seed (as forked jobs on ``workers`` processes, one torch thread each),
    evaluate on ``test``; balanced accuracy with clip-bootstrap CIs, the ratio (b)/(a), and the
    differences (c)-(a) and (d+)-(d) with their minimum detectable differences. With ``reverse`` (the
    synthetic crops), the real-trained models (a) also classify those: ``reverse_transfer`` holds their
    per-class recall and confusion (rows the synthetic class, columns what the real-trained model
    calls it), the mirror image of (b)'s confusion on the real crops. With ``predictions`` (a path), every
    condition's predicted classes on ``test`` are kept there for paired before / after comparisons of two
    runs (``harness.experiments.sim2real.compare``). ``sets`` may be a :class:`CrossFit` (tuning): every
    fold's models score its held-out crops; the reverse transfer then uses the first fold's (a) models."""
    from harness.experiments.pipeline import forked_map

    fit = sets if isinstance(sets, CrossFit) else CrossFit([sets], [np.ones(len(test.y), bool)])
    # one unit per model to train: a condition's set in one or more folds; empty sets are left out
    units = [(f"{name}#{k}", name, train, mask) for k, (name, train, mask) in enumerate(fit.units())]
    empty = {name for _, name, train, _ in units if not len(train.y)}
    units = [u for u in units if u[1] not in empty]    # a condition empty in any fold is left out entirely
    jobs = [(key, int(seed)) for key, _, _, _ in units for seed in seeds]
    first_a = next((key for key, name, _, _ in units if name == "a_real"), None)
    with_reverse = reverse is not None and len(reverse.y) > 0 and first_a is not None
    context = dict(sets={key: train for key, _, train, _ in units}, test=test, n_classes=n_classes,
                   train=dict(steps=steps, batch_size=batch_size, learning_rate=learning_rate),
                   reverse=(first_a, reverse) if with_reverse else None)
    done: dict[tuple[str, int], np.ndarray] = {}
    reverse_preds: dict[int, np.ndarray] = {}
    for i, (p, on_reverse) in forked_map(_condition_job, jobs, workers, label, context=context):
        done[jobs[i]] = p
        if on_reverse is not None:
            reverse_preds[jobs[i][1]] = on_reverse
    preds: dict[str, np.ndarray] = {}      # condition -> (n_seeds, n_test) predicted class
    per_seed: dict[str, list[float]] = {}
    for name in dict.fromkeys(name for _, name, _, _ in units):
        rows = []
        for seed in seeds:
            row = np.zeros(len(test.y), np.int64)
            for key, unit_name, _, mask in units:
                if unit_name == name:
                    row[mask] = done[(key, int(seed))][mask]
            rows.append(row)
        preds[name] = np.stack(rows)
        per_seed[name] = [balanced_accuracy(test.y, r) for r in rows]
    names = list(preds)
    stacked = np.stack([preds[n] for n in names], axis=2) if names else np.zeros((len(seeds), len(test.y), 0))
    if predictions is not None:
        from harness.experiments.sim2real.compare import write_predictions

        write_predictions(predictions, test.y, test.clip, names, seeds, stacked.transpose(2, 0, 1))

    def mean_balacc(k: int):
        return lambda y, p: mean_balanced_accuracy(y, p[:, :, k].T)

    # rows = test crops; arrays (n_test, n_seeds, n_conditions)
    data = stacked.transpose(1, 0, 2)
    out: dict[str, Any] = {"conditions": {}, "n_test_clips": int(np.unique(test.clip).size),
                           "n_test_crops": int(len(test.y)),
                           "train_sizes": {n: int(len(s.y)) for n, s in fit.sets[0].items()},
                           "train_clips": {n: int(np.unique(s.clip).size) for n, s in fit.sets[0].items()}}
    if len(fit.sets) > 1:
        out["cross_fit"] = {"folds": len(fit.sets),
                            "test_crops": [int(np.sum(m)) for m in fit.held_out],
                            "train_sizes": [{n: int(len(s.y)) for n, s in f.items()} for f in fit.sets],
                            "train_clips": [{n: int(np.unique(s.clip).size) for n, s in f.items()} for f in fit.sets]}
    for k, name in enumerate(names):
        res = clustered_bootstrap(mean_balacc(k), test.y, data, clusters=test.clip, rng=rng_seed, n_resamples=bootstrap)
        out["conditions"][name] = {"label": CONDITION_LABELS[name], **_interval(res), "per_seed": per_seed[name],
                                   **per_class(test.y, preds[name], n_classes)}

    def pair(a: str, b: str, kind: str) -> dict[str, float] | None:
        if a not in preds or b not in preds:
            return None
        ka, kb = names.index(a), names.index(b)
        if kind == "ratio":
            stat = lambda y, p: mean_balacc(kb)(y, p) / max(mean_balacc(ka)(y, p), 1e-9)  # noqa: E731
        else:
            stat = lambda y, p: mean_balacc(kb)(y, p) - mean_balacc(ka)(y, p)  # noqa: E731
        res = clustered_bootstrap(stat, test.y, data, clusters=test.clip, rng=rng_seed, n_resamples=bootstrap)
        d = _interval(res)
        finite = res.samples[np.isfinite(res.samples)]
        d["mde"] = float(Z_MDE * finite.std(ddof=1)) if finite.size > 2 else float("nan")
        return d

    if reverse is not None and with_reverse:
        stacked_reverse = np.stack([reverse_preds[int(s)] for s in seeds])
        out["reverse_transfer"] = {"label": "(a) real-trained model on the synthetic crops",
                                   "n_crops": int(len(reverse.y)), "n_sequences": int(np.unique(reverse.clip).size),
                                   **per_class(reverse.y, stacked_reverse, n_classes),
                                   "majority": majority_vote(stacked_reverse, n_classes).tolist()}
    out["ratio_b_over_a"] = pair("a_real", "b_synthetic", "ratio")
    out["gain_c_minus_a"] = pair("a_real", "c_synthetic_plus_real", "diff")
    out["gain_dplus_minus_d"] = pair("d_few_shot", "d_plus_few_shot_synthetic", "diff")
    return out


def domain_classifier(real: CropSet, synthetic: CropSet, *, seeds: Sequence[int], steps: int, batch_size: int,
                      learning_rate: float, rng: np.random.Generator, workers: int = 1) -> dict[str, Any]:
    """Held-out balanced accuracy of a CNN telling real from synthetic (0.5 = indistinguishable).
    Split by clip: half of the real clips and half of the synthetic sequences train, the rest test."""
    def halves(s: CropSet) -> tuple[np.ndarray, np.ndarray]:
        clips = np.unique(s.clip)
        train_clips = set(rng.permutation(clips)[: max(1, clips.size // 2)].tolist())
        mask = np.array([c in train_clips for c in s.clip])
        return mask, ~mask

    if len(real.y) < 4 or len(synthetic.y) < 4:
        return {"accuracy": float("nan"), "note": "too few crops"}
    rm, rt = halves(real)
    sm, st = halves(synthetic)
    train = CropSet(np.concatenate([real.x[rm], synthetic.x[sm]]),
                    np.concatenate([np.zeros(rm.sum(), np.int64), np.ones(sm.sum(), np.int64)]),
                    np.concatenate([real.clip[rm], synthetic.clip[sm]]))
    test_x = np.concatenate([real.x[rt], synthetic.x[st]])
    test_y = np.concatenate([np.zeros(rt.sum(), np.int64), np.ones(st.sum(), np.int64)])
    from harness.experiments.pipeline import forked_map

    context = dict(sets={"domain": train}, test=CropSet(test_x, test_y, np.zeros(len(test_y), str)), n_classes=2,
                   train=dict(steps=steps, batch_size=batch_size, learning_rate=learning_rate))
    done = {i: p for i, (p, _) in forked_map(_condition_job, [("domain", int(s)) for s in seeds], workers,
                                            context=context)}
    accs = [balanced_accuracy(test_y, done[i]) if len(test_y) else float("nan") for i in range(len(seeds))]
    return {"accuracy": float(np.mean(accs)), "per_seed": accs, "n_train": int(len(train.y)),
            "n_test": int(len(test_y)),
            "test_clips_real": int(np.unique(real.clip[rt]).size),
            "test_sequences_synthetic": int(np.unique(synthetic.clip[st]).size)}
