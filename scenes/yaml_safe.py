"""Bounded, strict YAML reading for every user-supplied config (scenes, generation, TRIDENT,
experiments, degradation specs).

PyYAML's ``safe_load`` builds only plain data, but it accepts three things that hurt: duplicate
keys (the last silently wins), alias "bombs" (a 1.2 KB file whose anchors expand to 10^9 nodes
once anything walks it) and deep nesting (a RecursionError traceback). This loader refuses each
with a :class:`~scenes.errors.UserInputError` naming the file and line, before any of it is
expanded. Limits are generous for real configs (the deepest preset nests 7 levels).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, SequenceNode

from scenes.errors import UserInputError

MAX_BYTES = 4 * 1024 * 1024        # a config file larger than this is not a config
MAX_DEPTH = 64                     # nesting levels of mappings/sequences
MAX_NODES = 200_000                # nodes after alias expansion (the real presets: < 2 000)
_MERGE_TAG = "tag:yaml.org,2002:merge"


class _BoundedLoader(yaml.SafeLoader):
    """SafeLoader that limits nesting while composing and refuses duplicate mapping keys."""

    def __init__(self, stream: str):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                mark = self.peek_event().start_mark
                raise UserInputError(f"line {mark.line + 1}: nested deeper than {MAX_DEPTH} levels")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node, deep=False):
        if isinstance(node, MappingNode):
            seen: dict[Any, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == _MERGE_TAG:
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    hash(key)
                except TypeError:
                    continue  # PyYAML reports unhashable keys itself
                if key in seen:
                    raise UserInputError(f"line {key_node.start_mark.line + 1}: duplicate key {_short(key)} "
                                         f"(first given on line {seen[key]}); each key may appear once")
                seen[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep)


def _short(value: Any, limit: int = 60) -> str:
    text = repr(value) if isinstance(value, (str, int, float, bool)) or value is None else type(value).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def expanded_size(root: Node, limit: int = MAX_NODES) -> int:
    """Number of nodes ``root`` stands for once every alias is expanded (memoised over the shared
    node graph, so a bomb is measured without being expanded); stops counting past ``limit``."""
    memo: dict[int, int] = {}
    stack: list[tuple[Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if key in memo:
            continue
        if isinstance(node, SequenceNode):
            children = list(node.value)
        elif isinstance(node, MappingNode):
            children = [n for pair in node.value for n in pair]
        else:
            memo[key] = 1
            continue
        if not done:
            stack.append((node, True))
            stack.extend((c, False) for c in children if id(c) not in memo)
            continue
        memo[key] = min(limit + 1, 1 + sum(memo.get(id(c), 1) for c in children))
    return memo[id(root)]


def load_yaml(text: str, source: str) -> Any:
    """Parse one YAML document from ``text`` with the limits above; errors name ``source``."""
    if len(text) > MAX_BYTES:
        raise UserInputError(f"{source}: {len(text)} characters is larger than the {MAX_BYTES} a config may have")
    try:
        loader = _BoundedLoader(text)
    except yaml.YAMLError as exc:  # the reader refuses control characters up front
        raise UserInputError(f"{source}: not valid YAML: {_bounded_text(str(exc))}") from None
    try:
        try:
            node = loader.get_single_node()
        except UserInputError as exc:
            raise UserInputError(f"{source}: {exc}") from None
        if node is None:
            return None
        size = expanded_size(node)
        if size > MAX_NODES:
            raise UserInputError(f"{source}: expands to more than {MAX_NODES} values once its anchors/aliases are "
                                 "followed (an alias bomb?); refused before expanding it")
        try:
            return loader.construct_document(node)
        except UserInputError as exc:
            raise UserInputError(f"{source}: {exc}") from None
    except yaml.YAMLError as exc:
        raise UserInputError(f"{source}: not valid YAML: {_bounded_text(str(exc))}") from None
    except RecursionError:
        raise UserInputError(f"{source}: nested too deeply to read") from None
    finally:
        loader.dispose()


def load_yaml_file(path: str | Path) -> Any:
    """Read and parse a YAML file with the limits above (file size checked before reading)."""
    p = Path(path)
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise UserInputError(f"cannot read {str(p)!r}: {exc.strerror}") from None
    if size > MAX_BYTES:
        raise UserInputError(f"{p}: {size} bytes is larger than the {MAX_BYTES} a config may have")
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise UserInputError(f"{p}: not UTF-8 text (byte {exc.start})") from None
    return load_yaml(text, str(p))


def _bounded_text(text: str, limit: int = 400) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."
