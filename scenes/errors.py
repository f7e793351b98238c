"""Errors that mean "the user's input is wrong" (exit 2 at the CLI), as opposed to bugs."""
from __future__ import annotations


class UserInputError(ValueError):
    """Bad input: the message names the field path and the offending value."""


def short_repr(value: object, limit: int = 80) -> str:
    """repr truncated to ``limit`` characters, built with reprlib so a huge or deeply shared input
    (an expanded alias bomb) is never rendered in full just to be cut."""
    import reprlib

    r = reprlib.Repr()
    r.maxstring, r.maxother, r.maxlong, r.maxlist, r.maxtuple, r.maxdict, r.maxset = limit, limit, 40, 6, 6, 6, 6
    r.maxlevel = 3
    text = r.repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
