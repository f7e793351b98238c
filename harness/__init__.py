"""The product around the evidential library: the experiment harnesses (E2 classification, E1/E3
detection, sim-to-real, the real benchmark), the HTML report, run folders and the `evids` command.

`evids/` is the library (heads, losses, fusion, gating, metrics, models, the modality table) and
never imports this package; tests/test_import_graph.py holds the rule."""
