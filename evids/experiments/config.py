"""Experiment configuration (YAML, validated by pydantic; errors name the field path and value).

An experiment = a dataset (a TRIDENT generation config to create it, or a path to a TRIDENT-layout
folder), a clip-level split, model/training hyper-parameters, the degradation protocol (noise
specs and noise seeds), fusion and gate settings, sweep, conflict study and bootstrap settings.
:data:`DEMO_CONFIG` / :data:`QUICK_CONFIG` are the configs `evids demo` runs.
"""
from __future__ import annotations

import copy
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

    @model_validator(mode="after")
    def _one_source(self) -> "DatasetConfig":
        if (self.generate is None) == (self.path is None):
            raise ValueError("give exactly one of dataset.generate (a generation config) or dataset.path (a folder)")
        return self


class SplitConfig(_Model):
    """Clip-level split, stratified by label; test clips are never used to choose anything."""

    seed: int = Field(default=42, ge=0)
    val_fraction: float = Field(default=0.2, gt=0.0, lt=1.0)
    test_fraction: float = Field(default=0.3, gt=0.0, lt=1.0)

    @model_validator(mode="after")
    def _fractions(self) -> "SplitConfig":
        if self.val_fraction + self.test_fraction >= 1.0:
            raise ValueError("val_fraction + test_fraction must be < 1")
        return self


class ModelsConfig(_Model):
    """Backbone sizes, the unimodal training loop and the stage-2 fusion heads."""

    seed: int = Field(default=0, ge=0)
    width: int = Field(default=8, ge=2, le=256)
    embedding: int = Field(default=32, ge=4, le=1024)
    video_pool: int = Field(default=4, ge=1, le=16)
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
    def _known(self) -> "NoiseEntry":
        import degradations

        if self.name not in degradations.REGISTRY:
            raise ValueError(f"unknown degradation {self.name!r}")
        return self


class ProtocolConfig(_Model):
    """Test-time noise: ``standard`` = audio + video (RF clean, as the paper's E2), ``rf_spec`` adds
    spectrogram-domain RF noise (conditions d', g), ``rf_iq`` adds I/Q noise before the STFT (i)."""

    noise_seeds: list[int] = Field(default=[42, 123, 456], min_length=1)
    audio: list[NoiseEntry] = Field(default_factory=lambda: [NoiseEntry(name="audio.white_noise", params={"snr_db": 10.0})])
    video: list[NoiseEntry] = Field(default_factory=lambda: [NoiseEntry(name="video.gaussian_noise", params={"sigma": 0.18})])
    rf_spec: list[NoiseEntry] = Field(default_factory=lambda: [
        NoiseEntry(name="rf.spec_pink_noise", params={"snr_db": 20.0}),
        NoiseEntry(name="rf.spec_time_mask", params={"mask_fraction": 0.05})])
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


class ConflictConfig(_Model):
    """Conflict programs applied to every test clip over [onset, onset + duration) of the clip."""

    programs: list[Literal["audio_masked", "rf_silent", "rgb_blind", "decoy"]] = Field(
        default=["audio_masked", "rf_silent", "rgb_blind", "decoy"], min_length=1)
    onset_fraction: float = Field(default=0.25, ge=0.0, lt=1.0)
    duration_fraction: float = Field(default=0.5, gt=0.0, le=1.0)
    severity: float = Field(default=5.0, gt=0.0, le=5.0)


class BootstrapConfig(_Model):
    n_resamples: int = Field(default=2000, ge=100, le=100000)
    confidence: float = Field(default=0.95, gt=0.5, lt=1.0)
    seed: int = Field(default=42, ge=0)


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
    ece_bins: int = Field(default=15, ge=2, le=100)


def load_experiment_config(source: str | Path | dict | ExperimentConfig) -> ExperimentConfig:
    """Validate a mapping, a YAML file or an already-built config; bad input -> UserInputError."""
    from evids.experiments.validate import validate_experiment
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


_DEMO_CLIPS: list[dict[str, Any]] = [
    {"scenario": "clear_day_quad", "count": 5, "ambience": {"wind_db": 42, "birdsong_db": 38}},
    {"scenario": "out_of_view", "count": 4, "ambience": {"wind_db": 40, "traffic_db": 45}},
    {"scenario": "fixed_wing_pass", "count": 3, "ambience": {"wind_db": 40}},
    {"scenario": "low_elevation_haze", "group": "autonomous_far_hexa", "count": 4, "rf_silent": True,
     "ambience": {"wind_db": 48, "gust_depth": 0.9}},
    {"group": "birds", "count": 8, "ambience": {"wind_db": 40, "birdsong_db": 45}, "scenario": {
        "name": "birds_near", "duration_s": 10.0,
        "targets": [
            {"name": "crow", "kind": "bird", "size_m": 0.5, "wingbeat_hz": 4.0,
             "trajectory": {"kind": "flyby", "start_m": [-30, 60, 15], "velocity_mps": [6, 0, 0.5]}},
            {"name": "gull", "kind": "bird", "size_m": 0.7, "wingbeat_hz": 3.0,
             "trajectory": {"kind": "orbit", "center_m": [5, 80, 25], "radius_m": 12, "speed_mps": 7}}],
        "camera_rig": {"position_m": [0, 0, 1.5], "look_at_m": [0, 70, 20], "rgb": {"hfov_deg": 40}}}},
    {"group": "airliner_rain", "count": 8, "ambience": {"wind_db": 38, "rain_db": 50, "traffic_db": 42}, "scenario": {
        "name": "distant_airliner", "duration_s": 10.0,
        "targets": [{"name": "jet", "kind": "airliner", "size_m": 40.0,
                     "trajectory": {"kind": "flyby", "start_m": [-3000, 6000, 2500], "velocity_mps": [120, 0, 0]}}],
        "camera_rig": {"position_m": [0, 0, 1.5], "look_at_m": [-1800, 6000, 2500], "rgb": {"hfov_deg": 10}}}},
]

DEMO_CONFIG: dict[str, Any] = {
    "name": "demo",
    "dataset": {"generate": {"name": "demo_trident", "description": "evids demo: 16 drone + 16 background clips of 4 s",
                             "clip_duration_s": 4.0, "save_iq": True, "clips": _DEMO_CLIPS},
                "seed": 7},
    "split": {"seed": 42, "val_fraction": 0.25, "test_fraction": 0.35},
}

QUICK_CONFIG: dict[str, Any] = copy.deepcopy(DEMO_CONFIG)
QUICK_CONFIG.update({
    "name": "demo_quick",
    "models": {"train": {"epochs": 4, "patience": 2, "kl_anneal_epochs": 2.0}, "fusion_epochs": 60},
    "gate": {"tau_high": [0.3, 0.5, 0.7], "tau_low": [0.1, 0.2], "n": [1, 3]},
    "sweep": {"severities": [0.0, 3.0, 5.0], "n_seeds": 1},
    "bootstrap": {"n_resamples": 300},
})
_QUICK_COUNTS = (2, 1, 1, 1, 3, 2)            # 5 drone + 5 background clips
QUICK_CONFIG["dataset"] = {**DEMO_CONFIG["dataset"], "clip_duration_s": 1.0, "render_px": 56,
                           "generate": {**DEMO_CONFIG["dataset"]["generate"], "name": "demo_quick_trident",
                                        "description": "evids demo --quick: 5 drone + 5 background clips of 1 s",
                                        "clips": [{**c, "count": k} for c, k in zip(_DEMO_CLIPS, _QUICK_COUNTS)]}}
