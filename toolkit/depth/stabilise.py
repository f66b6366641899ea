"""Stabilisation of the control points (source 001, step 240).

Threshold-gated progressive filtering, after the method the source cites
(WO-A-2011/080281): a new measurement that differs from the reference by less
than a threshold is replaced by a corrected value that reduces the difference
with a first filtering factor; if the next difference is also below the
threshold a smaller factor is used, and so on (progressively stronger
smoothing while a point is nearly still); a difference above the threshold is
real motion and is taken as measured, restarting the progression.

Here the reference is the previous stabilised position moved by the point's
smoothed velocity (so steady motion is not lagged) and the gate is per point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError

__all__ = ["Stabiliser", "StabiliserConfig"]


@dataclass(frozen=True)
class StabiliserConfig:
    """Settings of the threshold-gated progressive filter.

    Attributes
    ----------
    threshold_m : float
        Differences at or above this are real motion.
    factors : tuple of float
        Filtering factors of the 1st, 2nd, ... consecutive frame below the
        threshold (the fraction of the difference kept); the last repeats.
    use_velocity : bool
        Move the reference by the stabilised velocity ...
    velocity_smoothing : float
        ... an exponential average of the stabilised steps with this weight on the past.
    """

    threshold_m: float = 0.03
    factors: tuple = (0.7, 0.5, 0.35)
    use_velocity: bool = True
    velocity_smoothing: float = 0.7

    def __post_init__(self):
        if not self.factors or not all(0.0 < f <= 1.0 for f in self.factors):
            raise InputError("StabiliserConfig.factors", "factors in (0, 1]", repr(self.factors))
        if self.threshold_m <= 0:
            raise InputError("StabiliserConfig.threshold_m", "a positive distance", repr(self.threshold_m))


class Stabiliser:
    """Per-point threshold-gated progressive filter.

    Parameters
    ----------
    n_points : int
    config : StabiliserConfig
    """

    def __init__(self, n_points: int = 13, config: StabiliserConfig = StabiliserConfig()):
        self.n = int(n_points)
        self.config = config
        self.reset()

    def reset(self) -> None:
        """Forget the history (the next measurement is taken as is)."""
        self.last = None
        self.velocity = np.zeros((self.n, 3))
        self.count = np.zeros(self.n, int)

    def __call__(self, X: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
        """Stabilise one frame of points (n, 3); points not ``active`` are passed through."""
        Y = np.array(X, float)
        if Y.shape != (self.n, 3):
            raise InputError("X", f"an array of shape ({self.n}, 3)", f"shape {Y.shape}")
        act = np.ones(self.n, bool) if active is None else np.asarray(active, bool)
        if self.last is None:
            self.last = Y.copy()
            return Y
        ref = self.last + (self.velocity if self.config.use_velocity else 0.0)
        diff = Y - ref
        dist = np.linalg.norm(diff, axis=1)
        below = act & np.isfinite(dist) & (dist < self.config.threshold_m)
        f = np.array(self.config.factors)[np.minimum(self.count, len(self.config.factors) - 1)]
        out = np.where(below[:, None], ref + f[:, None] * diff, Y)
        self.count = np.where(below, self.count + 1, 0)
        step = np.where(np.isfinite(out), out - self.last, 0.0)
        k = self.config.velocity_smoothing
        self.velocity = k * self.velocity + (1 - k) * step
        self.last = out.copy()
        return out
