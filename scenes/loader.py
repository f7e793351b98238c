"""Read and write scenarios: YAML files or named presets in scenes/library/, with field-named errors."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from evids.errors import UserInputError
from scenes.schema import Scenario

LIBRARY_DIR = Path(__file__).with_name("library")


def preset_names() -> list[str]:
    return sorted(p.stem for p in LIBRARY_DIR.glob("*.yaml"))


def preset_path(name: str) -> Path:
    path = LIBRARY_DIR / f"{name}.yaml"
    if not path.is_file():
        raise UserInputError(f"unknown scene preset {name!r}; valid presets: {', '.join(preset_names())}")
    return path


def format_validation_error(exc: ValidationError, source: str) -> str:
    """One line per problem: `source: field.path: message (got value)`."""
    lines = []
    for err in exc.errors():
        loc = ".".join(str(p) for p in err["loc"]) or "<root>"
        if err["type"] == "missing":
            lines.append(f"{source}: {loc}: {err['msg']}")
            continue
        got = err.get("input")
        got_text = repr(got) if len(repr(got)) < 80 else repr(got)[:77] + "..."
        lines.append(f"{source}: {loc}: {err['msg']} (got {got_text})")
    return "\n".join(lines)


def scenario_from_dict(data: Any, source: str = "<scenario>") -> Scenario:
    if not isinstance(data, dict):
        raise UserInputError(f"{source}: expected a mapping at the top level, got {type(data).__name__}")
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        raise UserInputError(format_validation_error(exc, source)) from None


def load_scenario(path_or_name: str | Path) -> Scenario:
    """Load a scenario from a YAML path, or from a preset name (no path separator, no suffix)."""
    text_arg = str(path_or_name)
    path = Path(text_arg)
    if not path.suffix and "/" not in text_arg and not path.exists():
        path = preset_path(text_arg)
    if not path.is_file():
        raise UserInputError(f"scene file {text_arg!r} does not exist; presets: {', '.join(preset_names())}")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise UserInputError(f"{path}: not valid YAML: {exc}") from None
    return scenario_from_dict(data, source=str(path))


def scenario_to_yaml(scenario: Scenario) -> str:
    return yaml.safe_dump(scenario.model_dump(mode="json"), sort_keys=False)
