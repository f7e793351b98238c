"""Deprecated: moved to :mod:`simulator.formats.trident` (writer, reader and spec in one module).
This re-export keeps old imports working for one release."""
from simulator.formats.trident import *  # noqa: F401,F403
from simulator.formats.trident import ClipFiles, TridentDataset, TridentSegment, discover_clips  # noqa: F401
