"""`evids realbench`: the evidential pipeline trained and stress-tested on the real Svanström clips beside
the generated counterpart of a `evids sim2real` run, and whether synthetic stress tests predict real ones
(issue 25; docs/EXPERIMENTS.md, section "Real benchmark")."""
