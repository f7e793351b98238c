"""The typed outputs store of an E2 run in memory (:class:`harness.experiments.runner.Context`).

Three kinds of entry, each under a frozen, hashable key: the per-modality outputs of a split under a
noise variant (:class:`OutputsKey`), one modality's encoding under its own noise entries
(:class:`ModalityKey`), and one modality's degraded inputs (:class:`InputsKey`, shared across
training runs, freed by :meth:`OutputsStore.drop_inputs`). Every entry is a pure function of its key,
so what a store holds (a warm-up before a fork, results copied back from workers) changes the work
done, never a value.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from harness.experiments.pipeline import Outputs

#: a noise description: sorted (stream, repr(entries)) pairs; () is noise-free
NoiseDesc = tuple[tuple[str, str], ...]
ModalityOutputs = tuple[np.ndarray, np.ndarray, np.ndarray]   # (logit, alpha, emb) of one modality


def noise_desc(noise: Mapping[str, Any]) -> NoiseDesc:
    """The hashable description of stream -> noise entries (order-free)."""
    return tuple(sorted((k, repr(v)) for k, v in noise.items()))


@dataclass(frozen=True)
class OutputsKey:
    variant: str            # runner.VARIANTS, or a caller's name for an ``override`` (e.g. "sweep")
    seed: int
    split: str
    run: int
    override: NoiseDesc = ()


@dataclass(frozen=True)
class ModalityKey:
    modality: str
    seed: int
    split: str
    run: int
    noise: NoiseDesc


@dataclass(frozen=True)
class InputsKey:
    modality: str
    seed: int
    split: str
    noise: NoiseDesc


@dataclass
class OutputsStore:
    outputs: dict[OutputsKey, Outputs] = field(default_factory=dict)
    modality: dict[ModalityKey, ModalityOutputs] = field(default_factory=dict)
    inputs: dict[InputsKey, np.ndarray] = field(default_factory=dict)

    def put_clean(self, out: Outputs, split: str, run: int, seeds: Iterable[int]) -> None:
        """Noise-free outputs under every seed's key (they do not depend on the seed; 0 is canonical)."""
        for s in (0, *seeds):
            self.outputs[OutputsKey("clean", s, split, run)] = out

    def clean(self, split: str, run: int) -> Outputs | None:
        """The noise-free outputs if held (else None: the caller encodes per modality)."""
        return self.outputs.get(OutputsKey("clean", 0, split, run))

    def modality_outputs(self, key: ModalityKey, compute: Callable[[], ModalityOutputs]) -> ModalityOutputs:
        if key not in self.modality:
            self.modality[key] = compute()
        return self.modality[key]

    def degraded_inputs(self, key: InputsKey, compute: Callable[[], np.ndarray]) -> np.ndarray:
        if key not in self.inputs:
            self.inputs[key] = compute()
        return self.inputs[key]

    def drop_inputs(self) -> None:
        """Free the degraded inputs (outputs stay)."""
        self.inputs.clear()
