"""Experiment configuration (YAML, validated by pydantic; errors name the field path and value).

An experiment = a dataset (a TRIDENT generation config to create it, or a path to a TRIDENT-layout
folder), a clip-level split, model/training hyper-parameters, the degradation protocol (noise
specs and noise seeds), fusion and gate settings, sweep, conflict study and bootstrap settings.
:data:`DEMO_CONFIG` / :data:`QUICK_CONFIG` are the configs `evids demo` runs.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from evids.models.train import TrainConfig
from scenes.errors import UserInputError


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class DatasetConfig(_Model):
    """Exactly one of ``generate`` (preset name, YAML path or inline TRIDENT generation mapping) or ``path``."""

    generate: str | dict[str, Any] | None = None
    path: str | None = None
    seed: int = Field(default=0, ge=0)
    n_clips: int | None = Field(default=None, ge=2)
    clip_duration_s: float | None = Field(default=None, gt=0.0, description="override the generation config's")
    render_px: int | None = Field(default=None, ge=16, le=1024,
                                  description="render video at this size and resize to video_px (None: video_px)")
    workers: int = Field(default=2, ge=1, le=64,
                         description="processes that write clips (files are byte-identical for any count)")

    @model_validator(mode="after")
    def _one_source(self) -> DatasetConfig:
        if (self.generate is None) == (self.path is None):
            raise ValueError("give exactly one of dataset.generate (a generation config) or dataset.path (a folder)")
        return self


class SplitConfig(_Model):
    """Scene-disjoint split; test scenes are never used to choose anything.

    ``source: dataset`` keeps a generated dataset's own scene split (recorded per clip); otherwise
    (or for data without one) ``unit`` groups (scenes, or single clips) are assigned by fraction."""

    source: Literal["dataset", "fractions"] = "dataset"
    unit: Literal["scene", "clip"] = "scene"
    seed: int = Field(default=42, ge=0)
    val_fraction: float = Field(default=0.2, gt=0.0, lt=1.0)
    test_fraction: float = Field(default=0.3, gt=0.0, lt=1.0)

    @model_validator(mode="after")
    def _fractions(self) -> SplitConfig:
        if self.val_fraction + self.test_fraction >= 1.0:
            raise ValueError("val_fraction + test_fraction must be < 1")
        return self


class ModelsConfig(_Model):
    """Backbone sizes, the unimodal training loop and the stage-2 fusion heads."""

    seeds: list[int] = Field(default=[0, 1, 2], min_length=1,
                             description="training seeds (>= 3 for a training-variance +-)")
    width: int = Field(default=8, ge=2, le=256)
    embedding: int = Field(default=32, ge=4, le=1024)
    video_pool: int = Field(default=4, ge=1, le=8, description="stride of the first (full-resolution) video conv")
    video_frames: int = Field(default=2, ge=1, le=7, description="frames of the 7 the video model uses")
    torch_threads: int = Field(default=1, ge=1, le=64, description=(
        "torch threads for training and inference: fixed (results do not depend on the machine's load); "
        "1 avoids OpenMP spin-contention on a shared 2-core machine"))
    train_workers: int = Field(default=2, ge=1, le=64, description=(
        "processes that train the unimodal models (one job per seed x modality x head) and evaluate the "
        "conditions (one job per noise variant and seed), each on torch_threads threads; weights and "
        "metrics do not depend on this count"))
    fusion_fit: Literal["val_noisy", "train_clean"] = Field(default="val_noisy", description=(
        "Late Fusion / GMU fitted on validation outputs under the test noise protocol (default) or on clean "
        "train outputs; the other variant is always fitted too, as a labelled control"))
    fusion_noise_seed: int = Field(default=7, ge=0, description="noise seed of the validation outputs the heads see")
    temperature_bounds: tuple[float, float] = (0.05, 20.0)
    train: TrainConfig = Field(default_factory=TrainConfig)
    fusion_epochs: int = Field(default=200, ge=1, le=10000)
    fusion_lr: float = Field(default=0.02, gt=0.0)
    gmu_hidden: int = Field(default=16, ge=1, le=1024)


class NoiseEntry(_Model):
    """One test-time degradation: a registered name plus severity or explicit params."""

    name: str
    severity: float | None = Field(default=None, ge=0.0, le=5.0)
    params: dict[str, Any] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _known(self) -> NoiseEntry:
        import degradations

        if self.name not in degradations.REGISTRY:
            raise ValueError(f"unknown degradation {self.name!r}")
        return self


class ProtocolConfig(_Model):
    """Test-time noise: ``standard`` = audio + video (RF clean, as the paper's E2), ``rf_spec`` adds
    spectrogram-domain RF noise (conditions d', g), ``rf_iq`` adds I/Q noise before the STFT (i)."""

    noise_seeds: list[int] = Field(default=[42, 123, 456], min_length=1)
    audio: list[NoiseEntry] = Field(default_factory=lambda: [NoiseEntry(name="audio.white_noise",
                                                                        params={"snr_db": 10.0})])
    video: list[NoiseEntry] = Field(default_factory=lambda: [NoiseEntry(name="video.gaussian_noise",
                                                                        params={"sigma": 0.18})])
    rf_spec: list[NoiseEntry] = Field(default_factory=lambda: [
        NoiseEntry(name="rf.spec_pink_noise", params={"snr_db": 0.0}),
        NoiseEntry(name="rf.spec_time_mask", params={"mask_fraction": 0.3})])
    rf_iq: list[NoiseEntry] = Field(default_factory=lambda: [NoiseEntry(name="rf.awgn", params={"snr_db": 20.0})])


class FusionConfig(_Model):
    c_max: float = Field(default=0.95, ge=0.0, le=1.0, description="DS fallback threshold on the conflict C")
    construction: Literal["canonical", "scaled"] = "canonical"


class GateConfig(_Model):
    """Grid for the gate sweep; condition (f) uses the point chosen on the VALIDATION split: the
    largest validation skip rate whose validation accuracy is within ``max_val_accuracy_drop`` of
    ungated DS (ties: smaller tau_high)."""

    tau_high: list[float] = Field(default=[0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8])
    tau_low: list[float] = Field(default=[0.05, 0.1, 0.2, 0.3, 0.5])
    n: list[int] = Field(default=[1, 3, 5, 10])
    max_val_accuracy_drop: float = Field(default=0.01, ge=0.0, le=1.0)
    timing_repeats: int = Field(default=2, ge=1, le=20)


class SweepConfig(_Model):
    """Severity grid per modality (others clean) for the degradation sweep."""

    severities: list[float] = Field(default=[0.0, 1.0, 2.0, 3.0, 4.0, 5.0], min_length=2)
    audio: str = "audio.white_noise"
    video: str = "video.gaussian_noise"
    rf: str = "rf.spec_pink_noise"
    n_seeds: int | None = Field(default=None, ge=1, description="first n noise seeds (None: all)")


class SwapProgram(_Model):
    """A twin-swap conflict program (degradations.schedule.SWAP_PROGRAMS) at a strength."""

    name: str
    strength: float = Field(default=1.0, gt=0.0, le=1.0, description="1 strongly wrong, < 1 weakly wrong")

    @model_validator(mode="after")
    def _known(self) -> SwapProgram:
        from degradations.schedule import SWAP_PROGRAMS

        if self.name not in SWAP_PROGRAMS:
            raise ValueError(f"unknown conflict program {self.name!r}; known: {sorted(SWAP_PROGRAMS)}")
        return self

    @property
    def key(self) -> str:
        return self.name if self.strength == 1.0 else f"{self.name}@{self.strength:g}"


def _default_swaps() -> list[SwapProgram]:
    names = ["video_occluded", "audio_drowned", "rf_autonomous", "video_decoy", "audio_decoy", "rf_decoy",
             "audio_rf_blind", "audio_rf_decoy", "video_rf_decoy"]
    return [SwapProgram(name=n) for n in names] + [SwapProgram(name="video_decoy", strength=0.5),
                                                   SwapProgram(name="audio_rf_decoy", strength=0.5)]


class ConflictConfig(_Model):
    """Conflict study over [onset, onset + duration) of every test clip. ``swaps``: twin-swap
    programs (need a dataset with counterfactual twins); ``programs``: the older degradation-based
    programs, run and measured the same way when listed (empty by default: they proved inert)."""

    swaps: list[SwapProgram] = Field(default_factory=_default_swaps)
    programs: list[Literal["audio_masked", "rf_silent", "rgb_blind", "decoy"]] = Field(default_factory=list)
    onset_fraction: float = Field(default=0.25, ge=0.0, lt=1.0)
    duration_fraction: float = Field(default=0.5, gt=0.0, le=1.0)
    severity: float = Field(default=5.0, gt=0.0, le=5.0)
    min_flip_rate: float = Field(default=0.5, ge=0.0, le=1.0,
                                 description="a program below this is reported as not biting")
    inert_flip_rate: float = Field(default=0.05, ge=0.0, le=1.0, description="a program below this is marked inert")


class BootstrapConfig(_Model):
    """Statistics of paired comparisons: clustered bootstrap CI, sign-flip permutation p, MDE."""

    n_resamples: int = Field(default=2000, ge=100, le=100000)
    confidence: float = Field(default=0.95, gt=0.5, lt=1.0)
    seed: int = Field(default=42, ge=0)
    n_permutations: int = Field(default=10000, ge=100, le=1000000)
    effect_of_interest: float = Field(default=0.05, gt=0.0, le=1.0, description=(
        "'no difference' is claimed only when the MDE (80 % power) is below this accuracy difference"))


class AuditConfig(_Model):
    """Shortcut audit settings (target-blind baselines fitted on train, scored on test)."""

    enabled: bool = True
    min_segments: int = Field(default=20, ge=2, description="per class, for a baseline to be scored")
    # one seed for every audit: the demo's/train's audit stage and `evids audit` (which uses these defaults)
    seed: int = Field(default=42, ge=0, description="scene-bootstrap seed of every audit")
    n_resamples: int = Field(default=1000, ge=100, le=100000)
    tolerance: float = Field(default=0.05, gt=0.0, lt=0.5, description=(
        "the audit's MDE in the verdict rule: 'at chance' only when the CI lies within 0.5 +- this, "
        "'beats chance' only when the CI excludes 0.5 and |score - 0.5| >= this"))


class ExperimentConfig(_Model):
    """A whole experiment."""

    name: str = Field(default="experiment", min_length=1)
    dataset: DatasetConfig
    split: SplitConfig = Field(default_factory=SplitConfig)
    models: ModelsConfig = Field(default_factory=ModelsConfig)
    protocol: ProtocolConfig = Field(default_factory=ProtocolConfig)
    fusion: FusionConfig = Field(default_factory=FusionConfig)
    gate: GateConfig = Field(default_factory=GateConfig)
    sweep: SweepConfig = Field(default_factory=SweepConfig)
    conflict: ConflictConfig = Field(default_factory=ConflictConfig)
    bootstrap: BootstrapConfig = Field(default_factory=BootstrapConfig)
    audit: AuditConfig = Field(default_factory=AuditConfig)
    ece_bins: int = Field(default=15, ge=2, le=100)


def load_experiment_config(source: str | Path | dict | ExperimentConfig) -> ExperimentConfig:
    """Validate a mapping, a YAML file or an already-built config; bad input -> UserInputError."""
    from harness.experiments.validate import validate_experiment
    from scenes.loader import load_validated

    if isinstance(source, ExperimentConfig):
        return source
    name = "<experiment config>" if isinstance(source, dict) else str(source)
    cfg = validate_experiment(load_validated(source, ExperimentConfig, None, "experiment config"), name)
    if cfg.dataset.generate is not None:
        from simulator.dataset.trident import load_trident_config

        try:
            load_trident_config(cfg.dataset.generate)
        except UserInputError as exc:
            raise UserInputError(f"{name}: dataset.generate: {exc}") from None
    return cfg


DEMO_CONFIG: dict[str, Any] = {
    "name": "demo",
    "dataset": {"generate": "trident_scenes", "seed": 7},
    "split": {"source": "dataset"},
    "sweep": {"n_seeds": 1},
}

QUICK_CONFIG: dict[str, Any] = {
    "name": "demo_quick",
    "dataset": {"generate": "trident_scenes_quick", "seed": 7},
    "split": {"source": "dataset"},
    "models": {"seeds": [0, 1], "train": {"epochs": 3, "patience": 2, "kl_anneal_epochs": 2.0}, "fusion_epochs": 60},
    "gate": {"tau_high": [0.3, 0.5, 0.7], "tau_low": [0.1, 0.2], "n": [1, 3]},
    "sweep": {"severities": [0.0, 3.0, 5.0], "n_seeds": 1},
    "protocol": {"noise_seeds": [42, 123]},
    "bootstrap": {"n_resamples": 300, "n_permutations": 2000},
}
