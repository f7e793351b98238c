"""Recording-chain filters: the peaking filter's gain and resonances keeping the RMS."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.physics import acoustics as ac
from tests.simulator.physics.acoustics.helpers import FS


def _gain_db(f_hz: float, centre_hz: float, gain_db: float, q: float) -> float:
    """Steady-state gain of ac.peaking_filter for a sine at f_hz (the first half second, the filter's
    start-up, left out)."""
    t = np.arange(2 * FS) / FS
    x = np.sin(2 * np.pi * f_hz * t)
    y = ac.peaking_filter(x, FS, centre_hz, gain_db, q)
    return float(20 * np.log10(np.sqrt(np.mean(y[FS // 2:] ** 2)) / np.sqrt(np.mean(x[FS // 2:] ** 2))))


@pytest.mark.parametrize("centre_hz, gain_db, q", [(1000.0, 10.0, 3.0), (300.0, 6.0, 1.5), (6000.0, 14.0, 5.0)])
def test_peaking_filter_gain_at_centre_and_far_from_it(centre_hz, gain_db, q):
    """At the centre the band-pass of iirpeak is 1 at zero phase, so the gain is gain_db exactly; what is left is
    the 1.5 s window holding a non-integer number of periods (< 0.01 dB at >= 300 Hz). Off the centre the
    band-pass is at most 1 / (q |r - 1/r|), r = f / centre (2nd-order band-pass), so the gain lies between
    0 dB (the Regalia-Mitra form never cuts for G > 1) and 20 log10(1 + (G - 1) / (q |r - 1/r|)): at r = 3 and
    1/10 under 2.3 / 0.7 dB for these three, at r = 1/100 under 0.07 dB, i.e. about 0 dB far from the peak."""
    assert _gain_db(centre_hz, centre_hz, gain_db, q) == pytest.approx(gain_db, abs=0.01)
    g = 10 ** (gain_db / 20)
    for r in (0.01, 0.1, 3.0):
        bound = 20 * np.log10(1 + (g - 1) / (q * abs(r - 1 / r)))
        measured = _gain_db(r * centre_hz, centre_hz, gain_db, q)
        assert -1e-6 < measured <= bound + 0.01, (r, measured, bound)
    assert 20 * np.log10(1 + (g - 1) / (q * abs(0.01 - 100))) < 0.07


def test_resonances_keep_the_rms_and_no_peaks_keep_the_bytes():
    x = np.random.default_rng(4).standard_normal(FS)
    y = ac.resonances(x, FS, [(500.0, 12.0, 2.0), (3000.0, 8.0, 4.0)])
    assert np.sqrt(np.mean(y ** 2)) == pytest.approx(np.sqrt(np.mean(x ** 2)), rel=1e-12)
    spec_x, spec_y = np.abs(np.fft.rfft(x)) ** 2, np.abs(np.fft.rfft(y)) ** 2
    f = np.fft.rfftfreq(x.size, 1.0 / FS)
    band = (f > 450) & (f < 550)
    assert spec_y[band].sum() / spec_y.sum() > 2.0 * spec_x[band].sum() / spec_x.sum()   # energy moved into the peak
    assert ac.resonances(x, FS, []).tobytes() == x.tobytes()
    with pytest.raises(ValueError, match="centre_hz"):
        ac.peaking_filter(x, FS, 0.6 * FS, 6.0, 2.0)
    with pytest.raises(ValueError, match="q"):
        ac.peaking_filter(x, FS, 1000.0, 6.0, 0.0)
