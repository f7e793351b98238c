"""`evids sim2real`: how far the simulator's output is from a real multi-sensor drone benchmark
(Svanström 2021), measured with one command (docs/SIM2REAL.md).

config   the shipped protocol (examples/sim2real_svanstrom.yaml), validated by pydantic
samples  target crops, background patches and per-frame image statistics from real clips and
         from generated native sequences, through the same functions
classify crop classifiers (conditions a, b, c, d, d+), the real-vs-synthetic domain classifier,
         clip-bootstrap confidence intervals
audio    the audio track (statistics, drone vs not-drone models)
harness  runs it all into a run folder: sim2real.json, sheets, sim2real.html

Split rule: the real clips with an odd number are the calibration half (training, fitting, looking),
the even ones the evaluation half (reported numbers only).
"""
