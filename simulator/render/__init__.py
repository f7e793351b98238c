"""The Mitsuba backend (the only Mitsuba importer, lazily inside :mod:`.mitsuba_setup`) and labels from
masks. ``SequenceRenderer`` lives in :mod:`simulator.render.renderer`."""
