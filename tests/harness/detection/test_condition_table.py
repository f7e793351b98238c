"""The detection-condition table: one record per condition; what used to be string-prefix tests."""
import pytest

from harness.experiments.detection.config import (
    CONDITIONS,
    DETECTION_CONDITIONS,
    TINY_CONFIG,
    condition_key,
    condition_keys,
    load_detection_config,
    split_key,
)
from harness.experiments.detection.runner import models_needed


def test_keys_and_models_match_the_hand_written_tables_they_replace():
    cfg = load_detection_config(TINY_CONFIG)
    assert condition_keys(cfg)[:4] == ["a_sigmoid/rgb", "a_sigmoid/thermal", "b_evidential/rgb", "b_evidential/thermal"]
    assert set(condition_keys(cfg)) >= {"e_ds/fused", "f_ds_gated/fused", "h_feature_fusion_ts/fused"}
    assert models_needed(["a_sigmoid"]) == ["rgb_sigmoid", "thermal_sigmoid"]
    assert models_needed(["h_feature_fusion_ts", "g_feature_fusion"]) == ["fusion_sigmoid"]
    assert models_needed(["e_ds", "c_evidential_tau"]) == ["rgb_evidential", "thermal_evidential"]
    assert models_needed(list(CONDITIONS)) == ["rgb_sigmoid", "thermal_sigmoid", "rgb_evidential",
                                               "thermal_evidential", "fusion_sigmoid"]


def test_flags_replace_the_prefix_tests():
    by = DETECTION_CONDITIONS
    assert [k for k, c in by.items() if c.fit_after] == ["f_ds_gated", "h_feature_fusion_ts"]
    assert [k for k, c in by.items() if c.tau_det] == ["c_evidential_tau"]
    assert [k for k, c in by.items() if c.crop_uncertainty] == ["b_evidential"]
    assert [k for k, c in by.items() if c.evidential] == ["b_evidential", "c_evidential_tau", "d_average", "e_ds",
                                                          "f_ds_gated"]
    cond, stream = split_key(condition_key("e_ds", "fused"))
    assert cond is by["e_ds"] and stream == "fused"


@pytest.mark.parametrize("conds, need", [(["a_sigmoid", "f_ds_gated"], "e_ds"),
                                         (["h_feature_fusion_ts"], "g_feature_fusion")])
def test_a_condition_without_the_one_it_reuses_is_refused(conds, need):
    from scenes.errors import UserInputError

    with pytest.raises(UserInputError, match=f"needs {need}"):
        load_detection_config({**TINY_CONFIG, "conditions": conds})
