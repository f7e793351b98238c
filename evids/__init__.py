"""The evidential library: EDL heads and losses, fusion rules (Dempster-Shafer and others), gating,
calibration/ranking metrics, the models and the modality table. It imports only `scenes`; the
product around it (experiment harnesses, report, run folders, the `evids` command) is `harness/`."""
