"""pytest plugin (entry point ``pytest11: evids``): tiny generated datasets as fixtures.

Fixtures (session-scoped, rendered once per content key and cached on disk):

- ``evids_fixture(name, preset="clear_day_quad", seed=0) -> Path``: factory for any of
  ``simulator.dataset.fixtures.FIXTURES`` (native, antiuav, antiuav_rgbt, mmuav, coco, trident);
- ``evids_antiuav_sequence``, ``evids_mmuav_sequence``, ``evids_coco_file``,
  ``evids_trident_folder``, ``evids_native_dataset``: the same with the default preset and seed.

Cache: ``$EVIDS_FIXTURE_CACHE`` if set, else pytest's cache dir (``.pytest_cache/d/evids-fixtures``),
else the session's temporary base. Bytes are stable for a given package version.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import pytest


@pytest.fixture(scope="session")
def evids_fixture_cache(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Folder where evids fixtures are cached."""
    env = os.environ.get("EVIDS_FIXTURE_CACHE")
    if env:
        return Path(env)
    cache = getattr(request.config, "cache", None)
    if cache is not None:
        return Path(cache.mkdir("evids-fixtures"))
    return tmp_path_factory.getbasetemp().parent / "evids-fixtures"


@pytest.fixture(scope="session")
def evids_fixture(evids_fixture_cache: Path) -> Callable[..., Path]:
    """Factory: ``evids_fixture("mmuav", preset="bird_confuser", seed=3)`` -> path (cached)."""
    from simulator.dataset.fixtures import cached_fixture

    def make(name: str, preset: str = "clear_day_quad", seed: int = 0) -> Path:
        return cached_fixture(name, evids_fixture_cache, preset=preset, seed=seed)

    return make


@pytest.fixture(scope="session")
def evids_antiuav_sequence(evids_fixture: Callable[..., Path]) -> Path:
    """An Anti-UAV thermal sequence folder (000001.jpg..., IR_label.json; <name>_visible/ beside it)."""
    return evids_fixture("antiuav")


@pytest.fixture(scope="session")
def evids_mmuav_sequence(evids_fixture: Callable[..., Path]) -> Path:
    """An MM-UAV sequence folder (rgb_frame/, ir_frame/, gt_rgb/gt.txt, gt_ir/gt.txt, seqinfo-*.ini)."""
    return evids_fixture("mmuav")


@pytest.fixture(scope="session")
def evids_coco_file(evids_fixture: Callable[..., Path]) -> Path:
    """A COCO-video JSON (RGB) in the MM-UAV baseline style; images resolve under ../train/."""
    return evids_fixture("coco")


@pytest.fixture(scope="session")
def evids_trident_folder(evids_fixture: Callable[..., Path]) -> Path:
    """A TRIDENT-layout folder with one 1 s drone clip."""
    return evids_fixture("trident")


@pytest.fixture(scope="session")
def evids_native_dataset(evids_fixture: Callable[..., Path]) -> Path:
    """A one-sequence native evids dataset (manifest.json, sequences/seq000001/)."""
    return evids_fixture("native")
