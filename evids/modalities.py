"""The modality table of the classification models (E2): one frozen record per model modality, from
which every translation is derived (model-input field, observability key, the protocol's noise
streams and the degradation modality each stream's entries must act on). Torch-free, so the report
and the configs can read it without loading the models.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Modality = Literal["audio", "video", "rf"]


@dataclass(frozen=True)
class NoiseStream:
    """One noise list of the protocol (``protocol.<name>`` in the config, a ``degrade_clip`` keyword)."""

    name: str
    degradation_modality: str      # ``degradations.base.MODALITIES``: what its entries must act on


@dataclass(frozen=True)
class ModalitySpec:
    name: Modality
    input_field: str               # field of ``data.ClipArrays`` / ``noise.Degraded`` the model reads
    observability_key: str         # key of a segment's simulator observability record
    streams: tuple[NoiseStream, ...]   # the protocol's noise streams acting on it (the input stream first)

    @property
    def stream_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.streams)

    @property
    def degradation_modalities(self) -> tuple[str, ...]:
        return tuple(s.degradation_modality for s in self.streams)

    @property
    def compromised_key(self) -> str:
        """Key of a conflict program's ``compromised`` record for the stream the model reads."""
        return self.streams[0].degradation_modality

    def stream_of(self, degradation_modality: str) -> str:
        """The noise stream whose entries act on ``degradation_modality`` (KeyError if none)."""
        for s in self.streams:
            if s.degradation_modality == degradation_modality:
                return s.name
        raise KeyError(f"{self.name}: no noise stream acts on {degradation_modality!r}")


MODALITY_TABLE: dict[Modality, ModalitySpec] = {spec.name: spec for spec in (
    ModalitySpec("audio", "mfcc", "audio", (NoiseStream("audio", "audio"),)),
    ModalitySpec("video", "video", "video", (NoiseStream("video", "rgb"),)),
    ModalitySpec("rf", "rf", "rf", (NoiseStream("rf_spec", "rf_spec"), NoiseStream("rf_iq", "rf_iq"))),
)}

#: the model modalities, in the order of every per-modality array (models, outputs, fusion inputs)
MODALITIES: tuple[Modality, ...] = tuple(MODALITY_TABLE)
#: every protocol noise stream, in table order
NOISE_STREAMS: tuple[str, ...] = tuple(s for spec in MODALITY_TABLE.values() for s in spec.stream_names)
#: model modality -> the noise streams acting on it
MODALITY_STREAMS: dict[str, tuple[str, ...]] = {m: spec.stream_names for m, spec in MODALITY_TABLE.items()}
#: protocol noise stream -> the degradation modality its entries must have
PROTOCOL_MODALITY: dict[str, str] = {s.name: s.degradation_modality for spec in MODALITY_TABLE.values()
                                     for s in spec.streams}
#: sweep field (a model modality) -> the degradation modalities its degradation may act on
SWEEP_MODALITY: dict[str, tuple[str, ...]] = {m: spec.degradation_modalities for m, spec in MODALITY_TABLE.items()}
#: model modality -> the input field it reads
INPUT_FIELD: dict[str, str] = {m: spec.input_field for m, spec in MODALITY_TABLE.items()}
#: model modality -> its observability key
OBSERVABILITY_KEY: dict[str, str] = {m: spec.observability_key for m, spec in MODALITY_TABLE.items()}
