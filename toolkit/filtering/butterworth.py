"""Zero-phase low-pass Butterworth filtering of trajectories with gaps.

The filter runs forward and backward (``scipy.signal.sosfiltfilt``), so it adds no
lag and its order doubles: ``order`` here is the order of the whole zero-phase filter
(Pose2Sim's convention: ``order = 4`` designs a 2nd-order Butterworth and runs it
both ways), and the gain at the cut-off is 0.5 (-6 dB) rather than 1/sqrt(2).

NaN marks missing samples.  Each run of finite samples between gaps is filtered on
its own (nothing is interpolated across a gap, and gaps stay NaN); a run shorter
than :data:`MIN_RUN_PER_ORDER` x ``order`` samples is too short to filter and is left
as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from toolkit.errors import InputError

__all__ = ["ButterworthFilter", "butterworth_lowpass", "DEFAULT_ORDER", "MIN_RUN_PER_ORDER"]

#: Order of the zero-phase filter (Pose2Sim's default: 4).
DEFAULT_ORDER = 4
#: Runs of finite samples shorter than this many times the order are left unfiltered.
MIN_RUN_PER_ORDER = 3


@dataclass(frozen=True)
class ButterworthFilter:
    """A zero-phase low-pass Butterworth filter.

    Attributes
    ----------
    cutoff_hz : float
        Cut-off frequency (gain 0.5), Hz; below half the frame rate.
    order : int
        Order of the zero-phase filter, even (each pass has ``order / 2``).
    """

    cutoff_hz: float
    order: int = DEFAULT_ORDER

    def __post_init__(self):
        if not (isinstance(self.cutoff_hz, (int, float)) and math.isfinite(self.cutoff_hz) and self.cutoff_hz > 0):
            raise InputError("cutoff_hz", "a positive cut-off frequency (Hz)", repr(self.cutoff_hz))
        if isinstance(self.order, bool) or not isinstance(self.order, int) or self.order < 2 or self.order % 2:
            raise InputError("order", "an even order >= 2 (zero-phase: each pass has order / 2)",
                             repr(self.order))

    def describe(self) -> str:
        """One line for metadata: ``butterworth low-pass, zero-phase, order 4, cut-off 6 Hz``."""
        return f"butterworth low-pass, zero-phase, order {self.order}, cut-off {self.cutoff_hz:g} Hz"

    def apply(self, x: np.ndarray, rate_hz: float) -> np.ndarray:
        """Filter ``x`` (shape (T, ...), NaN = missing) sampled at ``rate_hz`` along axis 0."""
        return butterworth_lowpass(x, rate_hz, self.cutoff_hz, self.order)


def butterworth_lowpass(x: np.ndarray, rate_hz: float, cutoff_hz: float, order: int = DEFAULT_ORDER) -> np.ndarray:
    """Zero-phase low-pass Butterworth filter along axis 0, run by run between NaN gaps.

    Parameters
    ----------
    x : ndarray of shape (T, ...)
        Samples (e.g. joints (T, J, 3) in metres); NaN = missing.
    rate_hz : float
        Sampling rate, Hz.
    cutoff_hz : float
        Cut-off (gain 0.5), Hz, below ``rate_hz / 2``.
    order : int
        Even order of the zero-phase filter.

    Returns
    -------
    ndarray of the shape of ``x``
        Filtered; NaN where ``x`` is NaN; runs shorter than ``MIN_RUN_PER_ORDER * order``
        samples unchanged.

    Raises
    ------
    InputError
        A non-positive rate, a cut-off not below the Nyquist frequency, or a bad order.
    """
    spec = ButterworthFilter(float(cutoff_hz) if isinstance(cutoff_hz, (int, float)) else cutoff_hz, order)
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise InputError("rate_hz", "a positive sampling rate (Hz)", repr(rate_hz))
    if spec.cutoff_hz >= rate_hz / 2:
        raise InputError("cutoff_hz", f"below the Nyquist frequency {rate_hz / 2:g} Hz", f"{spec.cutoff_hz:g}")
    arr = np.asarray(x, float)
    if arr.ndim == 0:
        raise InputError("x", "an array of shape (T, ...)", "a scalar")
    sos = signal.butter(order // 2, spec.cutoff_hz, btype="low", fs=rate_hz, output="sos")
    flat = arr.reshape(len(arr), -1)
    out = flat.copy()
    min_run = MIN_RUN_PER_ORDER * order
    for c in range(flat.shape[1]):
        col = flat[:, c]
        ok = np.isfinite(col)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
        for start, stop in zip(edges[::2], edges[1::2]):
            if stop - start >= min_run:
                out[start:stop, c] = signal.sosfiltfilt(sos, col[start:stop], padlen=min(stop - start - 1,
                                                                                        3 * (2 * len(sos) + 1)))
    return out.reshape(arr.shape)
