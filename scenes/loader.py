"""Read and write scenarios: YAML files or named presets in scenes/library/, with field-named errors."""
from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from scenes.errors import UserInputError, short_repr
from scenes.schema import Scenario
from scenes.yaml_safe import load_yaml_file

LIBRARY_DIR = Path(__file__).with_name("library")
GENERATION_DIR = Path(__file__).with_name("generation")
MAX_ERROR_LINES = 20
ModelT = TypeVar("ModelT", bound=BaseModel)


def preset_names() -> list[str]:
    return sorted(p.stem for p in LIBRARY_DIR.glob("*.yaml"))


def format_validation_error(exc: ValidationError, source: str) -> str:
    """One line per problem: `source: field.path: message (got value)`."""
    lines = []
    errors = exc.errors(include_url=False)
    for err in errors[:MAX_ERROR_LINES]:
        loc = ".".join(str(p) for p in err["loc"]) or "<root>"
        if err["type"] == "missing":
            lines.append(f"{source}: {loc}: {err['msg']}")
            continue
        got_text = short_repr(err.get("input"))
        lines.append(f"{source}: {loc}: {err['msg']} (got {got_text})")
    if len(errors) > MAX_ERROR_LINES:
        lines.append(f"{source}: ... and {len(errors) - MAX_ERROR_LINES} more problem(s)")
    return "\n".join(lines)


def validate_mapping(model: type[ModelT], data: Any, source: str) -> ModelT:
    """Validate a parsed YAML mapping against a pydantic model; errors name field path and value."""
    if not isinstance(data, dict):
        raise UserInputError(f"{source}: expected a mapping at the top level, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise UserInputError(format_validation_error(exc, source)) from None


def load_validated(path_or_name: str | Path | dict, model: type[ModelT], library_dir: Path | None, kind: str) -> ModelT:
    """A mapping, a YAML path, or a preset name (no suffix, no separator) from ``library_dir``
    (``None``: files only)."""
    if isinstance(path_or_name, dict):
        return validate_mapping(model, path_or_name, f"<{kind}>")
    text_arg = str(path_or_name)
    path = Path(text_arg)
    names = sorted(p.stem for p in Path(library_dir).glob("*.yaml")) if library_dir is not None else []
    if library_dir is not None and not path.suffix and "/" not in text_arg and not path.exists():
        path = Path(library_dir) / f"{text_arg}.yaml"
        if not path.is_file():
            raise UserInputError(f"unknown {kind} preset {text_arg!r}; valid presets: {', '.join(names)}")
    if not path.is_file():
        hint = f"; presets: {', '.join(names)}" if names else ""
        raise UserInputError(f"{kind} file {text_arg!r} does not exist{hint}")
    return validate_mapping(model, load_yaml_file(path), str(path))


def scenario_from_dict(data: Any, source: str = "<scenario>") -> Scenario:
    return validate_mapping(Scenario, data, source)


def load_scenario(path_or_name: str | Path) -> Scenario:
    """Load a scenario from a YAML path, or from a preset name (no path separator, no suffix)."""
    return load_validated(path_or_name, Scenario, LIBRARY_DIR, "scene")


def scenario_to_yaml(scenario: Scenario) -> str:
    return yaml.safe_dump(scenario.model_dump(mode="json"), sort_keys=False)
