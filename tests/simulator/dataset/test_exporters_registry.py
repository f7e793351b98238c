"""The exporter registry: one record per (dataset kind, format), options validated at the boundary."""
from __future__ import annotations

import json

import pytest

from scenes.errors import UserInputError
from simulator.dataset import exporters as ex


def test_the_registry_lists_each_kinds_formats_once():
    assert ex.EXPORT_FORMATS == ("antiuav", "antiuav_rgbt", "antiuav2021", "mot", "coco", "webdataset", "zarr")
    assert ex.TRIDENT_EXPORT_FORMATS == ("trident", "webdataset")
    assert len(ex.EXPORTERS) == len(ex.EXPORT_FORMATS) + len(ex.TRIDENT_EXPORT_FORMATS)
    for exporter in ex.EXPORTERS.values():      # every format's defaults are valid options
        assert isinstance(exporter.options(), ex.ExportOptions)


@pytest.mark.parametrize("fmt, values, flag", [
    ("mot", {"annotate_every": 0}, "--annotate-every"),
    ("mot", {"distractors": "sometimes"}, "--distractors"),
    ("coco", {"naming": "x"}, "--coco-naming"),
    ("webdataset", {"shard_mb": 0.0}, "--shard-mb"),
])
def test_a_bad_option_names_its_flag_and_format(fmt, values, flag):
    with pytest.raises(UserInputError, match=f"{flag} \\({fmt}\\)"):
        ex.validate_options(ex.EXPORTERS[("native", fmt)], values)


def test_options_a_format_does_not_have_are_not_read():
    options = ex.validate_options(ex.EXPORTERS[("native", "antiuav")], {"annotate_every": 0, "naming": "x"})
    assert options == ex.ExportOptions()
    mot = ex.validate_options(ex.EXPORTERS[("native", "mot")], {"annotate_every": 20, "naming": "x"})
    assert mot == ex.MotOptions(annotate_every=20)


def test_the_dataset_kind_picks_the_exporter(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"format": "trident"}))
    assert ex.dataset_kind(tmp_path) == "trident"
    assert ex.exporter_for(tmp_path, "webdataset").source == "trident"
    with pytest.raises(UserInputError, match="exports to trident, webdataset only, got 'mot'"):
        ex.exporter_for(tmp_path, "mot")
    (tmp_path / "manifest.json").write_text(json.dumps({"format": "evids-native-dataset"}))
    assert ex.exporter_for(tmp_path, "webdataset").source == "native"
    with pytest.raises(UserInputError, match="--format must be one of"):
        ex.exporter_for(tmp_path, "trident")
