"""HOW the world is observed: scene -> timeline -> physics -> render -> sensors -> labels -> formats,
and whole datasets (``dataset/``). See docs/ARCHITECTURE.md."""
