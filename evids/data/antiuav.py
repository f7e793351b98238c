"""Deprecated: moved to :mod:`simulator.formats.antiuav` (writer, reader and spec in one module).
This re-export keeps old imports working for one release."""
from simulator.formats.antiuav import *  # noqa: F401,F403
