"""Self-contained HTML report of an experiment run (inline base64 PNGs, no external files), built
only from the run folder's JSON/CSV/NPZ outputs."""
from __future__ import annotations

from harness.report.html import build_report, example_figure, headline

__all__ = ["build_report", "example_figure", "headline"]
