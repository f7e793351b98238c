"""Degradation parameters (the Python API and spec files): every explicit parameter has a closed,
finite domain, so nonsense is refused with the parameter named before any pixel is touched, and no
value can make a call allocate hundreds of GiB."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import degradations
from degradations.base import PARAM_DOMAINS
from degradations.errors import DegradationError, SpecError
from degradations.spec import parse_spec

REFUSED = [
    ("video.gaussian_noise", {"sigma": -1.0}, "sigma"),
    ("video.frame_drop", {"drop_prob": 2.0}, "drop_prob"),
    ("thermal.dead_pixels", {"fraction": 5.0}, "fraction"),
    ("video.defocus_blur", {"radius_px": 1e5}, "radius_px"),
    ("video.motion_blur", {"length_px": 1e6}, "length_px"),
    ("audio.white_noise", {"snr_db": math.inf}, "snr_db"),
    ("audio.white_noise", {"snr_db": math.nan}, "snr_db"),
    ("rf.awgn", {"snr_db": -math.inf}, "snr_db"),
    ("video.jpeg", {"quality": 0}, "quality"),
    ("video.jpeg", {"quality": 101}, "quality"),
    ("thermal.netd_noise", {"netd_k": "0.1"}, "netd_k"),
    ("video.resolution_drop", {"factor": 0.5}, "factor"),
    ("audio.dropout", {"gap_ms": 0.0}, "gap_ms"),
    ("rf.fading", {"n_taps": 1e6}, "n_taps"),
]


@pytest.mark.parametrize("name,params,field", REFUSED, ids=[f"{r[0]}:{r[1]}" for r in REFUSED])
def test_out_of_domain_parameters_are_refused_naming_them(name, params, field):
    with pytest.raises(DegradationError, match=field):
        degradations.apply(name, np.zeros((8, 8, 3), np.uint8) if name.startswith("video.") else
                           np.zeros((2, 8, 8), np.float32) + 290 if name.startswith("thermal.") else
                           np.zeros(64, np.complex64) if name.startswith("rf.") else np.zeros(64, np.float32),
                           seed=0, **params)


@pytest.mark.parametrize("name,params,field", REFUSED, ids=[f"{r[0]}:{r[1]}" for r in REFUSED])
def test_spec_files_refuse_them_too(name, params, field):
    with pytest.raises(SpecError, match=field):
        parse_spec({"version": 1, "degradations": [{"name": name, "params": params}]})


def test_inf_severity_and_inf_schedule_values_are_refused():
    with pytest.raises(SpecError, match="severity"):
        parse_spec({"version": 1, "degradations": [{"name": "video.fog", "severity": math.inf}]})
    with pytest.raises(SpecError):
        parse_spec({"version": 1, "programs": [{"name": "ir_blind", "onset_s": math.inf, "duration_s": 1.0}]})


def test_every_table_parameter_of_every_degradation_has_a_domain():
    missing = sorted(f"{name}.{p}" for name, cls in degradations.REGISTRY.items()
                     for p in cls.table if p not in PARAM_DOMAINS and p not in cls.domains)
    assert missing == []


def test_every_level_of_every_table_lies_in_its_domain():
    """The severity tables themselves are inside the domains (a domain never refuses a level)."""
    outside = []
    for name, cls in degradations.REGISTRY.items():
        for p, values in cls.table.items():
            lo, hi = cls.domains.get(p, PARAM_DOMAINS[p])
            outside += [f"{name}.{p}={v}" for v in values if not lo <= v <= hi]
    assert outside == []


PARAMS = sorted((name, p) for name, cls in degradations.REGISTRY.items()
                for p in list(cls.table) + list(cls.extra) if p in PARAM_DOMAINS or p in cls.domains)


def _accepted(cls, p: str, value) -> bool:
    try:
        cls(None, **{p: value})
    except DegradationError as exc:
        assert p in str(exc) or "must" in str(exc)
        return False
    return True


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(PARAMS), st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**9, 10**9)),
       st.floats(0.0, 1.0))
def test_a_value_is_accepted_exactly_inside_its_domain(name_param, value, t):
    """Outside the domain (or not finite) is refused; inside is accepted: the random value when it
    happens to fall inside, and always a value drawn inside [lo, hi] (a whole number for integer
    parameters), so both halves are checked on every example."""
    name, p = name_param
    cls = degradations.REGISTRY[name]
    lo, hi = cls.domains.get(p, PARAM_DOMAINS[p])
    whole = p in cls.integer_params
    inside = math.isfinite(float(value)) and lo <= float(value) <= hi and (not whole or float(value).is_integer())
    if inside:
        assert _accepted(cls, p, value), f"{name}.{p}={value!r} inside [{lo}, {hi}] was refused"
    elif not (math.isfinite(float(value)) and lo <= float(value) <= hi):
        assert not _accepted(cls, p, value), f"{name}.{p}={value!r} outside [{lo}, {hi}] was accepted"
    drawn = min(max(lo + t * (hi - lo), lo), hi)
    if whole:
        drawn = int(min(max(math.floor(drawn), math.ceil(lo)), math.floor(hi)))
    assert _accepted(cls, p, drawn), f"{name}.{p}={drawn!r} inside [{lo}, {hi}] was refused"


@pytest.mark.parametrize("name,p", PARAMS, ids=[f"{n}.{p}" for n, p in PARAMS])
def test_both_ends_of_every_domain_are_accepted(name, p):
    cls = degradations.REGISTRY[name]
    lo, hi = cls.domains.get(p, PARAM_DOMAINS[p])
    ends = [math.ceil(lo), math.floor(hi)] if p in cls.integer_params else [lo, hi]
    assert [v for v in ends if not _accepted(cls, p, v)] == []
