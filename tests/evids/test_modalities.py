"""The modality table: one record per model modality; every translation derived from it."""
import degradations.base
from evids import modalities as M


def test_table_order_is_the_model_order_and_names_are_the_keys():
    assert M.MODALITIES == ("audio", "video", "rf")
    assert all(spec.name == key for key, spec in M.MODALITY_TABLE.items())


def test_derived_translations_hold_the_values_the_experiment_used_before():
    # hand-written from the tables these replaced (runner, pipeline, noise, validate)
    assert M.NOISE_STREAMS == ("audio", "video", "rf_spec", "rf_iq")
    assert M.MODALITY_STREAMS == {"audio": ("audio",), "video": ("video",), "rf": ("rf_spec", "rf_iq")}
    assert M.PROTOCOL_MODALITY == {"audio": "audio", "video": "rgb", "rf_spec": "rf_spec", "rf_iq": "rf_iq"}
    assert M.SWEEP_MODALITY == {"audio": ("audio",), "video": ("rgb",), "rf": ("rf_spec", "rf_iq")}
    assert M.INPUT_FIELD == {"audio": "mfcc", "video": "video", "rf": "rf"}
    assert [s.compromised_key for s in M.MODALITY_TABLE.values()] == ["audio", "rgb", "rf_spec"]


def test_streams_are_unique_and_act_on_known_degradation_modalities():
    assert len(set(M.NOISE_STREAMS)) == len(M.NOISE_STREAMS)
    assert set(M.PROTOCOL_MODALITY.values()) <= set(degradations.base.MODALITIES)


def test_stream_of_picks_the_stream_by_what_a_degradation_acts_on():
    import degradations

    rf = M.MODALITY_TABLE["rf"]
    assert rf.stream_of(degradations.REGISTRY["rf.awgn"].modality) == "rf_iq"
    assert rf.stream_of(degradations.REGISTRY["rf.spec_time_mask"].modality) == "rf_spec"
    assert M.MODALITY_TABLE["video"].stream_of("rgb") == "video"
    try:
        M.MODALITY_TABLE["video"].stream_of("thermal")
    except KeyError:
        pass
    else:
        raise AssertionError("video has no thermal noise stream")
