"""One torch thread per test process: `pytest -n 2` already runs two workers on the two cores."""
from __future__ import annotations

import pytest
import torch


@pytest.fixture(autouse=True)
def _one_torch_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture
def reverse_forked_map(monkeypatch):
    """Make ``pipeline.forked_map`` run in-process and deliver its results in reverse call order (the worst
    completion order): whatever collects them must put them back in call order."""
    from harness.experiments import pipeline

    original = pipeline.forked_map

    def reverse_order_map(fn, calls, workers, label=None, context=None):
        return reversed(list(original(fn, calls, 1, None, context=context)))

    monkeypatch.setattr(pipeline, "forked_map", reverse_order_map)
