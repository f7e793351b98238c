"""Before / after: two `evids sim2real` run folders compared on the same real evaluation crops.

Each run keeps, per visual sensor, what every crop classifier predicted for every real evaluation crop
(``predictions/<sensor>.npz``: the true classes, the clip of each crop, and the predicted classes per
condition and training seed). Two runs of the same real data and protocol sizes hold the same crops in
the same order, so a change of the simulator can be judged *paired*: the difference of a condition's
balanced accuracy (mean over seeds) between the runs, with a 95 % interval from a bootstrap that draws
evaluation clips, the same draws for both runs, and its minimum detectable difference (2.8 standard
errors of that bootstrap: a two-sided 5 % test with 80 % power). Pairing removes the variance of the
real test set that an unpaired comparison of two runs' intervals carries; the variance of drawing
another synthetic set is not in it (that needs more draws, not more crops). Beside it, each condition's
recall per class before and after (mean over seeds; class names from the runs' ``sim2real.json``), to
see where a difference comes from.

The audio track keeps its drone scores the same way (``predictions/audio.npz``: per evaluation window its
label drone / not drone, its recording and class, and the score per model, condition and training seed);
its comparison is the ROC-AUC (mean over seeds) after - before per model and condition, with a bootstrap
that draws recordings per class (as the audio track's own intervals do), the same draws for both runs.
"""
from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from evids.metrics.bootstrap import clustered_bootstrap
from harness.experiments.sim2real.classify import CONDITION_LABELS, Z_MDE, mean_balanced_accuracy
from harness.experiments.sim2real.config import TEST_HALF_WORDS, VISUAL_SENSORS

PREDICTIONS_DIR = "predictions"
FORMAT_VERSION = 1
AUDIO = "audio"
AUDIO_FORMAT_VERSION = 1


def predictions_path(run: Path, sensor: str) -> Path:
    """Where a run folder keeps ``sensor``'s crop-classifier predictions."""
    return Path(run) / PREDICTIONS_DIR / f"{sensor}.npz"


def write_predictions(path: Path, y: np.ndarray, clip: np.ndarray, conditions: Sequence[str], seeds: Sequence[int],
                      predicted: np.ndarray) -> None:
    """Write (atomically) ``predicted`` (conditions x seeds x crops class indices) for the crops of
    classes ``y`` and clips ``clip``."""
    predicted = np.asarray(predicted)
    if predicted.shape != (len(conditions), len(seeds), len(y)):
        raise ValueError(f"predicted has shape {predicted.shape}, expected {(len(conditions), len(seeds), len(y))}")
    _write_npz(path, format_version=np.int64(FORMAT_VERSION), y=np.asarray(y, np.int64), clip=np.asarray(clip, str),
               conditions=np.asarray(list(conditions), str), seeds=np.asarray(list(seeds), np.int64),
               predicted=predicted.astype(np.int16))


def read_predictions(path: Path, field: str = "run") -> dict[str, Any]:
    """The arrays of :func:`write_predictions`; a missing or unreadable file is a ``UserInputError``
    naming ``field``."""
    return _read_npz(path, field, "predictions", FORMAT_VERSION, "an audio-only run")


def write_audio_scores(path: Path, y: np.ndarray, clip: Sequence[str] | np.ndarray, cls: Sequence[str] | np.ndarray,
                       models: Sequence[str], conditions: Sequence[str], seeds: Sequence[int], scores: Any) -> None:
    """Write (atomically) the audio track's drone ``scores`` (models x conditions x seeds x windows) for the
    evaluation windows of labels ``y`` (1 = drone), recordings ``clip`` and classes ``cls``."""
    scores = np.asarray(scores)
    shape = (len(models), len(conditions), len(seeds), len(y))
    if scores.shape != shape or len(clip) != len(y) or len(cls) != len(y):
        raise ValueError(f"scores has shape {scores.shape}, expected {shape} (and one clip and class per window)")
    _write_npz(path, format_version=np.int64(AUDIO_FORMAT_VERSION), y=np.asarray(y, np.int64),
               clip=np.asarray(list(clip), str), cls=np.asarray(list(cls), str), models=np.asarray(list(models), str),
               conditions=np.asarray(list(conditions), str), seeds=np.asarray(list(seeds), np.int64),
               scores=scores.astype(np.float32))


def read_audio_scores(path: Path, field: str = "run") -> dict[str, Any]:
    """The arrays of :func:`write_audio_scores`; a missing or unreadable file is a ``UserInputError``
    naming ``field``."""
    return _read_npz(path, field, "audio scores", AUDIO_FORMAT_VERSION, "a run without audio")


def _write_npz(path: Path, **arrays: Any) -> None:
    from simulator.files import write_atomic

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, buf.getvalue())


def _read_npz(path: Path, field: str, kind: str, version: int, absent_because: str) -> dict[str, Any]:
    """The arrays of a kept ``kind`` file of format ``version``; missing, unreadable or of another version: a
    ``UserInputError`` naming ``field``."""
    from scenes.errors import UserInputError

    if not path.is_file():
        raise UserInputError(f"{field}: {str(path.parent.parent)!r} holds no {PREDICTIONS_DIR}/{path.name} (a run of "
                             f"`evids sim2real` from before {kind} were kept, {absent_because}, or not a run "
                             f"folder): rerun it")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise UserInputError(f"{field}: {str(path)!r} is not a {kind} file ({exc})") from None
    if int(data.get("format_version", -1)) != version:
        raise UserInputError(f"{field}: {str(path)!r} has {kind} format {data.get('format_version')}, "
                             f"this version reads {version}")
    return data


def _stratified_draws(clip: np.ndarray, cls: np.ndarray, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """``n`` resamples of window indices: per class its recordings drawn with replacement (every resample
    keeps drone and not-drone recordings, so every ROC-AUC is defined)."""
    from evids.metrics.bootstrap import clustered_resample

    recordings = np.unique(clip)
    by_class: dict[str, list[str]] = {}
    for r in recordings:
        by_class.setdefault(str(cls[np.flatnonzero(clip == r)[0]]), []).append(r)
    out = []
    for _ in range(n):
        draw = np.concatenate([rng.choice(np.asarray(ids), size=len(ids), replace=True)
                               for _, ids in sorted(by_class.items())])
        out.append(clustered_resample(clip, draw))
    return out


def compare_audio(before: dict[str, Any], after: dict[str, Any], *, bootstrap: int, rng_seed: int) -> dict[str, Any]:
    """Paired ROC-AUC differences after - before per model and condition both runs have (see the module
    docstring), with each condition's helicopter and background windows called drone (score > 0.5) before
    and after."""
    from harness.experiments.sim2real.audio import roc_auc
    from scenes.errors import UserInputError

    if not all(np.array_equal(before[k], after[k]) for k in ("y", "clip", "cls")):
        raise UserInputError(f"audio: the two runs' real evaluation windows differ ({len(before['y'])} against "
                             f"{len(after['y'])} windows, or other recordings): they were not made from the same "
                             f"real data, so they cannot be paired")
    y, clip, cls = before["y"], before["clip"], before["cls"]
    draws = _stratified_draws(clip, cls, np.random.default_rng(rng_seed), bootstrap)
    out: dict[str, Any] = {"n_test_windows": int(len(y)), "n_test_clips": int(np.unique(clip).size), "models": {}}

    def auc(scores: np.ndarray, idx: np.ndarray | slice) -> float:
        return float(np.mean([roc_auc(y[idx], s[idx]) for s in scores]))

    def called(scores: np.ndarray, name: str) -> float | None:
        m = cls == name
        return float(np.mean(scores[:, m] > 0.5)) if m.any() else None

    for model in [str(m) for m in before["models"] if m in list(after["models"])]:
        mb, ma = list(before["models"]).index(model), list(after["models"]).index(model)
        names_b, names_a = [str(n) for n in before["conditions"]], [str(n) for n in after["conditions"]]
        rows: dict[str, Any] = {}
        for name in [n for n in names_b if n in names_a]:
            sb, sa = before["scores"][mb, names_b.index(name)], after["scores"][ma, names_a.index(name)]
            samples = np.array([auc(sa, i) - auc(sb, i) for i in draws])
            lo, hi = np.percentile(samples, [2.5, 97.5])
            b_auc, a_auc = auc(sb, slice(None)), auc(sa, slice(None))
            rows[name] = {"label": CONDITION_LABELS.get(name, name), "before": b_auc, "after": a_auc,
                          "difference": a_auc - b_auc,
                          "ci_low": float(lo), "ci_high": float(hi),
                          "mde": float(Z_MDE * samples.std(ddof=1)) if samples.size > 2 else float("nan"),
                          "helicopter_called_drone": [called(sb, "HELICOPTER"), called(sa, "HELICOPTER")],
                          "background_called_drone": [called(sb, "BACKGROUND"), called(sa, "BACKGROUND")]}
        out["models"][model] = rows
    return out


def class_recall(y: np.ndarray, predicted: np.ndarray) -> list[float | None]:
    """Per true class 0..max(y): the recall averaged over the seeds' predictions ``predicted`` (seeds x
    crops); None for a class with no crop."""
    n = int(y.max()) + 1 if y.size else 0
    return [float(np.mean(predicted[:, y == k] == k)) if np.any(y == k) else None for k in range(n)]


def compare_sensor(before: dict[str, Any], after: dict[str, Any], *, bootstrap: int, rng_seed: int,
                   sensor: str = "", classes: Sequence[str] | None = None) -> dict[str, Any]:
    """Paired differences after - before per condition both runs have (see the module docstring), and
    each condition's per-class recall before and after (to see where a difference comes from; no interval)."""
    from scenes.errors import UserInputError

    if not (np.array_equal(before["y"], after["y"]) and np.array_equal(before["clip"], after["clip"])):
        raise UserInputError(f"{sensor}: the two runs' real evaluation crops differ ({len(before['y'])} against "
                             f"{len(after['y'])} crops, or other clips or classes): they were not made from the same "
                             f"real data with the same frames per clip, so they cannot be paired")
    y, clips = before["y"], before["clip"]
    names_b, names_a = [str(n) for n in before["conditions"]], [str(n) for n in after["conditions"]]
    n_classes = int(y.max()) + 1 if y.size else 0
    names = list(classes) if classes is not None and len(classes) == n_classes else [f"class {k}"
                                                                                     for k in range(n_classes)]
    out: dict[str, Any] = {"n_test_crops": int(len(y)), "n_test_clips": int(np.unique(clips).size),
                           "classes": names, "conditions": {}}
    for name in [n for n in names_b if n in names_a]:
        pb, pa = before["predicted"][names_b.index(name)], after["predicted"][names_a.index(name)]
        data = np.concatenate([pb.T, pa.T], axis=1)      # rows = crops: before seeds, then after seeds
        k = pb.shape[0]

        def diff(yy: np.ndarray, d: np.ndarray, k: int = k) -> float:
            return mean_balanced_accuracy(yy, d[:, k:].T) - mean_balanced_accuracy(yy, d[:, :k].T)

        res = clustered_bootstrap(diff, y, data, clusters=clips, rng=rng_seed, n_resamples=bootstrap)
        finite = res.samples[np.isfinite(res.samples)]
        out["conditions"][name] = {
            "label": CONDITION_LABELS.get(name, name),
            "before": mean_balanced_accuracy(y, pb), "after": mean_balanced_accuracy(y, pa),
            "difference": res.estimate, "ci_low": res.ci_low, "ci_high": res.ci_high,
            "mde": float(Z_MDE * finite.std(ddof=1)) if finite.size > 2 else float("nan"),
            "recall_before": class_recall(y, pb), "recall_after": class_recall(y, pa)}
    return out


def compare_runs(before: Path, after: Path, *, sensors: Sequence[str] = VISUAL_SENSORS, bootstrap: int = 1000,
                 rng_seed: int = 0, audio: bool = True) -> dict[str, Any]:
    """Every visual sensor both runs measured: :func:`compare_sensor`; the audio track when both kept its
    scores: :func:`compare_audio` (under ``audio``). A sensor only one run has is listed under ``skipped``;
    nothing in common is a ``UserInputError``."""
    from scenes.errors import UserInputError

    halves = {field: _test_half(run) for field, run in (("--before", before), ("--after", after))}
    if halves["--before"] != halves["--after"]:
        raise UserInputError(f"--before / --after: one run was tested on the real {halves['--before']} half, the "
                             f"other on the {halves['--after']} half (`--tune`): compare runs of the same kind")
    result: dict[str, Any] = {"before": str(before), "after": str(after), "bootstrap": int(bootstrap),
                              "test_half": halves["--before"], "sensors": {}, "skipped": []}
    if audio:
        ab, aa = predictions_path(before, AUDIO), predictions_path(after, AUDIO)
        if ab.is_file() and aa.is_file():
            result["audio"] = compare_audio(read_audio_scores(ab, "--before"), read_audio_scores(aa, "--after"),
                                            bootstrap=bootstrap, rng_seed=rng_seed)
        elif ab.is_file() or aa.is_file():
            result["skipped"].append(f"audio: only the {'before' if ab.is_file() else 'after'} run has its scores")
    for sensor in sensors:
        pb, pa = predictions_path(before, sensor), predictions_path(after, sensor)
        if not pb.is_file() and not pa.is_file():
            continue
        if not (pb.is_file() and pa.is_file()):
            result["skipped"].append(f"{sensor}: only the {'before' if pb.is_file() else 'after'} run has it")
            continue
        result["sensors"][sensor] = compare_sensor(read_predictions(pb, "--before"), read_predictions(pa, "--after"),
                                                   bootstrap=bootstrap, rng_seed=rng_seed, sensor=sensor,
                                                   classes=_run_classes(before, sensor))
    if not result["sensors"] and "audio" not in result:
        kept = [*sensors, AUDIO] if audio else list(sensors)
        for field, run in (("--before", before), ("--after", after)):
            if not any(predictions_path(run, s).is_file() for s in kept):
                raise UserInputError(f"{field}: {str(run)!r} holds no {PREDICTIONS_DIR}/ files ({', '.join(kept)}: a "
                                     f"run of `evids sim2real` from before predictions were kept, or not a run "
                                     f"folder): rerun it")
        raise UserInputError(f"--before / --after: no sensor in common ({'; '.join(result['skipped'])})")
    return result


def _test_half(run: Path) -> str:
    """Which real half a run's classifiers were tested on: "calibration" for ``evids sim2real --tune``,
    else (and for runs from before the field existed, or without a readable summary) "evaluation"."""
    try:
        return str(json.loads((Path(run) / "sim2real.json").read_text()).get("test_half", "evaluation"))
    except (OSError, ValueError, AttributeError):
        return "evaluation"


def _run_classes(run: Path, sensor: str) -> list[str] | None:
    """The class names a run's summary lists for ``sensor`` (None when it has none to give)."""
    try:
        names = json.loads((Path(run) / "sim2real.json").read_text())["sensors"][sensor]["classes"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return [str(n) for n in names] if isinstance(names, list) else None


def _recall_line(names: Sequence[str], before: Sequence[float | None], after: Sequence[float | None]) -> str:
    return "recall " + ", ".join(f"{n.lower()} {100 * b:.0f} -> {100 * a:.0f}" for n, b, a in zip(names, before, after)
                                 if b is not None and a is not None)


def format_comparison(result: dict[str, Any]) -> str:
    """The comparison as a printed table, one block per sensor."""
    lines = [f"after:  {result['after']}", f"before: {result['before']}"]
    half = TEST_HALF_WORDS[result.get("test_half", "evaluation")]
    width = max([len(c["label"]) for res in result["sensors"].values() for c in res["conditions"].values()]
                + [len(c["label"]) for rows in result.get("audio", {}).get("models", {}).values()
                   for c in rows.values()] + [1])
    for sensor, res in result["sensors"].items():
        lines.append(f"{sensor}: balanced accuracy on {half} ({res['n_test_clips']} clips, "
                     f"{res['n_test_crops']} crops), after - before, paired ({result['bootstrap']} clip resamples)")
        for c in res["conditions"].values():
            lines.append(f"  {c['label']:{width}s} {c['before']:.3f} -> {c['after']:.3f}  "
                         f"{100 * c['difference']:+5.1f} "
                         f"[{100 * c['ci_low']:+5.1f}, {100 * c['ci_high']:+5.1f}] pt, MDE {100 * c['mde']:.1f}")
            if "recall_before" in c:
                lines.append(f"  {'':{width}s} {_recall_line(res['classes'], c['recall_before'], c['recall_after'])} %")
    if "audio" in result:
        res = result["audio"]
        lines.append(f"audio: drone ROC-AUC on {half} ({res['n_test_clips']} recordings, "
                     f"{res['n_test_windows']} windows), after - before, paired ({result['bootstrap']} recording "
                     f"resamples per class)")
        for model, rows in res["models"].items():
            for c in rows.values():
                interval = f"[{100 * c['ci_low']:+5.1f}, {100 * c['ci_high']:+5.1f}]"
                lines.append(f"  {model:6s} {c['label']:{width}s} {c['before']:.3f} -> {c['after']:.3f}  "
                             f"{100 * c['difference']:+5.1f} {interval} pt, MDE {100 * c['mde']:.1f}")
                called = [(k.split("_")[0], v) for k, v in c.items() if k.endswith("_called_drone") and None not in v]
                if called:
                    lines.append(f"  {'':6s} {'':{width}s} called drone: " + ", ".join(
                        f"{n} {100 * b:.0f} -> {100 * a:.0f} %" for n, (b, a) in called))
    lines += [f"  skipped {s}" for s in result["skipped"]]
    return "\n".join(lines)
