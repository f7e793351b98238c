"""Whole datasets: generation configs and planning, local/Ray executors, manifest/verify/export,
rendering one sequence, TRIDENT clip sets, fixtures and the pytest plugin, degrading a native dataset,
previews."""
