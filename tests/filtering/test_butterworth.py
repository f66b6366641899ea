"""Zero-phase Butterworth low-pass (toolkit.filtering)."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.filtering import ButterworthFilter, butterworth_lowpass
from toolkit.filtering.butterworth import MIN_RUN_PER_ORDER

RATE = 100.0
#: Edge samples left out of the checks (filtfilt's start-up at the ends of a run).
EDGE = 50
#: A 1 Hz component below a 6 Hz cut-off comes through within this amplitude.
PASS_TOL = 0.01
#: A 20 Hz component is cut to at most this share (order 4, zero-phase: about 0.4 %).
STOP_GAIN = 0.02
#: The gain at the cut-off of a forward-backward filter is 0.5 (-6 dB), within this.
CUTOFF_GAIN_TOL = 0.01


def _t(n):
    return np.arange(n) / RATE


def test_passes_low_cuts_high_without_lag():
    t = _t(1000)
    low, high = np.sin(2 * np.pi * 1.0 * t), np.sin(2 * np.pi * 20.0 * t)
    y = butterworth_lowpass(low + high, RATE, 6.0)
    assert np.max(np.abs(y - low)[EDGE:-EDGE]) < PASS_TOL               # zero phase: no lag on the 1 Hz wave
    z = butterworth_lowpass(high, RATE, 6.0)
    assert np.max(np.abs(z[EDGE:-EDGE])) < STOP_GAIN


def test_gain_half_at_cutoff():
    y = butterworth_lowpass(np.sin(2 * np.pi * 6.0 * _t(3000)), RATE, 6.0)
    assert abs(np.max(np.abs(y[500:-500])) - 0.5) < CUTOFF_GAIN_TOL


def test_nan_gaps_stay_and_runs_are_filtered_apart():
    t = _t(400)
    x = np.stack([np.sin(2 * np.pi * t) + np.sin(2 * np.pi * 25 * t), np.cos(2 * np.pi * t)], axis=1)[:, None, :]
    x[200:210, 0, 0] = np.nan                                           # a gap in one coordinate
    x[300:300 + MIN_RUN_PER_ORDER * 4 - 1, 0, 1] = np.nan
    y = butterworth_lowpass(x, RATE, 6.0)
    assert y.shape == x.shape
    np.testing.assert_array_equal(np.isnan(y), np.isnan(x))
    # each run on its own equals filtering that run alone
    np.testing.assert_allclose(y[:200, 0, 0], butterworth_lowpass(x[:200, 0, 0], RATE, 6.0))
    np.testing.assert_allclose(y[210:, 0, 0], butterworth_lowpass(x[210:, 0, 0], RATE, 6.0))
    assert np.max(np.abs(y[EDGE:200 - EDGE, 0, 0] - np.sin(2 * np.pi * t[EDGE:200 - EDGE]))) < PASS_TOL
    # a run too short to filter is left as it is
    short = np.full(30, np.nan)
    short[10:10 + MIN_RUN_PER_ORDER * 4 - 1] = np.arange(MIN_RUN_PER_ORDER * 4 - 1.0) ** 2
    np.testing.assert_array_equal(butterworth_lowpass(short, RATE, 6.0), short)


def test_filter_spec_and_bad_arguments():
    f = ButterworthFilter(6.0)
    assert f.describe() == "butterworth low-pass, zero-phase, order 4, cut-off 6 Hz"
    np.testing.assert_array_equal(f.apply(np.ones(50), RATE), butterworth_lowpass(np.ones(50), RATE, 6.0))
    with pytest.raises(InputError, match="Nyquist"):
        butterworth_lowpass(np.ones(50), RATE, 50.0)
    with pytest.raises(InputError, match="order"):
        ButterworthFilter(6.0, 3)
    with pytest.raises(InputError, match="cutoff_hz"):
        ButterworthFilter(-1.0)
    with pytest.raises(InputError, match="rate_hz"):
        butterworth_lowpass(np.ones(50), 0.0, 6.0)
