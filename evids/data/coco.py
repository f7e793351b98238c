"""Deprecated: moved to :mod:`simulator.formats.coco` (writer, reader and spec in one module).
This re-export keeps old imports working for one release."""
from simulator.formats.coco import *  # noqa: F401,F403
