"""Parallel maps hand their results back in call order, whatever order the workers finish in."""
from __future__ import annotations

from types import SimpleNamespace

from harness.experiments import pipeline, runner


def _square(group: int, extra: tuple) -> tuple[int, int]:
    return group, group * group + extra[0]


def test_forked_results_is_in_call_order_when_jobs_finish_in_reverse(reverse_forked_map):
    calls = [(g, (1,)) for g in (3, 1, 2)]
    assert pipeline.forked_results(_square, calls, workers=1) == [(3, 10), (1, 2), (2, 5)]


def test_map_groups_is_in_group_order_when_jobs_finish_in_reverse(reverse_forked_map):
    ctx = SimpleNamespace(cfg=SimpleNamespace(models=SimpleNamespace(train_workers=2)), progress=False)
    result = runner.map_groups(ctx, [5, 0, 4], (2,), "label", job=_square)
    assert result == [(5, 27), (0, 2), (4, 18)]
