"""Errors that mean "the user's input is wrong" (exit 2 at the CLI), as opposed to bugs."""
from __future__ import annotations


class UserInputError(ValueError):
    """Bad input: the message names the field path and the offending value."""
