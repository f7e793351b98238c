"""Deprecated: the loaders moved to :mod:`simulator.formats` (one module per format, writer + reader +
spec). ``evids.data.antiuav`` etc. re-export them for one release."""
