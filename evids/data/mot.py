"""Deprecated: moved to :mod:`simulator.formats.mot` (writer, reader and spec in one module).
This re-export keeps old imports working for one release."""
from simulator.formats.mot import *  # noqa: F401,F403
