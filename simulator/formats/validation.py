"""Shared rules for the format readers: one error naming file, row/key and rule, or (``strict=False``)
a count of the rows that were skipped.

Every reader in ``simulator.formats`` checks its files against its spec (counts and index
consistency, value domains, box sanity) and raises :class:`FormatError` on the first violation.
With ``strict=False`` a reader skips the offending row (or frame, or clip), records why in a
:class:`Skipped` list and warns once per file with the count, so data is never wrong silently.
Low-level failures (corrupt JSON, undecodable text, unreadable audio) are re-raised as
:class:`FormatError` with the file name.
"""
from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from scenes.errors import UserInputError


class FormatError(UserInputError):
    """A file does not follow its format's spec: ``path``, ``where`` (row or key) and ``rule``."""

    def __init__(self, path: Path | str, where: str, rule: str):
        self.path, self.where, self.rule = str(path), where, rule
        super().__init__(f"{path}: {where}: {rule}" if where else f"{path}: {rule}")


class SkippedRowsWarning(UserWarning):
    """Emitted by a non-strict reader that skipped rows; the message gives the count and the first reason."""


@dataclass
class Skipped:
    """Rows a non-strict reader left out, as readable reasons (``file: row: rule``)."""

    reasons: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.reasons)

    def add(self, err: FormatError) -> None:
        self.reasons.append(str(err))


class Checker:
    """Raise (strict) or collect (non-strict) violations found in one file."""

    def __init__(self, path: Path | str, strict: bool = True, skipped: Skipped | None = None):
        self.path, self.strict = Path(path), strict
        self.skipped = skipped if skipped is not None else Skipped()
        self._start = len(self.skipped)

    def fail(self, where: str, rule: str) -> None:
        """Always an error: the file's structure is broken (nothing sensible to skip)."""
        raise FormatError(self.path, where, rule)

    def bad_row(self, where: str, rule: str) -> None:
        """A bad row: raise when strict, else record it (the caller then skips the row)."""
        err = FormatError(self.path, where, rule)
        if self.strict:
            raise err
        self.skipped.add(err)

    def finish(self) -> None:
        """Warn once with the number of rows this file had skipped."""
        n = len(self.skipped) - self._start
        if n:
            warnings.warn(f"{self.path}: skipped {n} bad row(s) (strict=False); first: "
                          f"{self.skipped.reasons[self._start]}",
                          SkippedRowsWarning, stacklevel=3)


def read_text(path: Path | str) -> str:
    """UTF-8 text of ``path``; undecodable or unreadable files raise FormatError naming it."""
    path = Path(path)
    try:
        return path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FormatError(path, f"byte {exc.start}", "not UTF-8 text") from None
    except IsADirectoryError:
        raise FormatError(path, "", "is a folder, expected a file") from None


def read_json(path: Path | str) -> Any:
    """Parsed JSON of ``path``; corrupt JSON raises FormatError with the line and column."""
    text = read_text(path)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(path, f"line {exc.lineno} column {exc.colno}", f"not valid JSON ({exc.msg})") from None
    except RecursionError:
        raise FormatError(path, "", "JSON nested too deeply") from None


def is_number(value: Any) -> bool:
    """A finite int or float (bools are not numbers here)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def box_problem(box: Any) -> str | None:
    """Why ``box`` is not a valid [x, y, w, h] (finite numbers, w > 0, h > 0); None when it is."""
    if not isinstance(box, (list, tuple)) or len(box) != 4:
        return f"box must be [x, y, w, h], got {_short(box)}"
    if not all(is_number(v) for v in box):
        return f"box values must be finite numbers, got {_short(box)}"
    if box[2] <= 0 or box[3] <= 0:
        return f"box width and height must be > 0, got {_short(box)}"
    return None


def integral(value: float) -> bool:
    return math.isfinite(value) and float(value).is_integer()


def _short(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
