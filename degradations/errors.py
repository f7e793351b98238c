"""Errors raised for bad degradation input: ValueError subclasses whose message names the field."""
from __future__ import annotations


class DegradationError(ValueError):
    """Bad parameter, shape or metadata for a degradation; the message names the culprit."""


class SpecError(DegradationError):
    """Invalid degradation spec file; the message gives the field path and the bad value."""
