"""Experiment configs checked before any work starts (no data generated, no model trained).

pydantic checks types and simple ranges; this module checks what needs the degradation registry
or cross-field knowledge: every referenced degradation exists and acts on the stream it is listed
under, every noise parameter is known and inside its domain (so `evaluate`/`sweep` cannot die on
it after minutes of training), noise seeds are valid SeedSequence entropy, and the gate grid is
meaningful. All problems are reported at once, each naming its field path.
"""
from __future__ import annotations

from typing import Any

from evids.modalities import PROTOCOL_MODALITY, SWEEP_MODALITY
from scenes.errors import UserInputError

MAX_SEED = 2 ** 32 - 1


def _degradation_problems(path: str, name: str, severity: float | None, params: dict[str, Any],
                          modalities: tuple[str, ...], name_path: str | None = None) -> list[str]:
    import degradations
    from degradations.errors import DegradationError

    name_path = name_path or f"{path}.name"
    cls = degradations.REGISTRY.get(name)
    if cls is None:
        near = sorted(k for k in degradations.REGISTRY if k.split(".")[0] == str(name).split(".")[0])
        return [f"{name_path}: unknown degradation {str(name)[:60]!r}; known: "
                f"{', '.join(near) or '(see docs/DEGRADATIONS.md)'}"]
    problems = []
    if cls.modality not in modalities:
        problems.append(f"{name_path}: {name} acts on {cls.modality!r}, not on {' or '.join(modalities)}")
    try:
        cls(severity, **params)
    except DegradationError as exc:
        problems.append(f"{path}: {exc}")
    return problems


def experiment_problems(cfg) -> list[str]:
    """Every problem of a parsed ExperimentConfig, as 'field.path: message' lines (empty: valid)."""
    from pathlib import Path

    problems: list[str] = []
    if cfg.dataset.path is not None and not Path(cfg.dataset.path).is_dir():
        problems.append(f"dataset.path: {str(cfg.dataset.path)[:200]!r} is not a folder")
    proto = cfg.protocol
    for k, seed in enumerate(proto.noise_seeds):
        if isinstance(seed, bool) or not 0 <= seed <= MAX_SEED:
            problems.append(f"protocol.noise_seeds[{k}]: must be an integer in [0, {MAX_SEED}], got {seed!r}")
    if len(set(proto.noise_seeds)) != len(proto.noise_seeds):
        problems.append(f"protocol.noise_seeds: repeated seeds {proto.noise_seeds} would count one draw twice")
    for field, modality in PROTOCOL_MODALITY.items():
        for k, entry in enumerate(getattr(proto, field)):
            problems += _degradation_problems(f"protocol.{field}[{k}]", entry.name, entry.severity, entry.params,
                                              (modality,))
    for field, modalities in SWEEP_MODALITY.items():
        problems += _degradation_problems(f"sweep.{field}", getattr(cfg.sweep, field), None, {}, modalities,
                                          name_path=f"sweep.{field}")
    for k, sev in enumerate(cfg.sweep.severities):
        if not 0.0 <= sev <= 5.0:
            problems.append(f"sweep.severities[{k}]: must be in [0, 5], got {sev!r}")
    if cfg.sweep.n_seeds is not None and cfg.sweep.n_seeds > len(proto.noise_seeds):
        problems.append(f"sweep.n_seeds: {cfg.sweep.n_seeds} is more than the {len(proto.noise_seeds)} noise seeds")
    gate = cfg.gate
    for field in ("tau_high", "tau_low", "n"):
        if not getattr(gate, field):
            problems.append(f"gate.{field}: give at least one value")
    for field in ("tau_high", "tau_low"):
        for k, v in enumerate(getattr(gate, field)):
            if not 0.0 <= v <= 1.0:
                problems.append(f"gate.{field}[{k}]: a threshold on a probability must be in [0, 1], got {v!r}")
    for k, v in enumerate(gate.n):
        if v < 1:
            problems.append(f"gate.n[{k}]: the hysteresis count must be >= 1, got {v!r}")
    if gate.tau_low and gate.tau_high and min(gate.tau_low) >= max(gate.tau_high):
        problems.append(f"gate: every tau_low {gate.tau_low} is >= every tau_high {gate.tau_high}; no gate point is "
                        "valid")
    return problems


def validate_experiment(cfg, source: str = "<experiment config>"):
    """Raise UserInputError listing every problem (see :func:`experiment_problems`); returns cfg."""
    problems = experiment_problems(cfg)
    if problems:
        shown = problems[:20] + ([f"... and {len(problems) - 20} more"] if len(problems) > 20 else [])
        raise UserInputError("\n".join(f"{source}: {p}" for p in shown))
    return cfg
