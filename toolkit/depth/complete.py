"""Completion of unseen control points (source 001, step 250).

When the depth data hold nothing for a control point (it is hidden behind the
body or outside the image) its position is completed by, in order:

1. **Kalman extrapolation**: a constant-velocity Kalman filter per point
   (:class:`PointKalman`) predicts it from its previous position and velocity;
   the velocity of a point unseen for a while decays (:attr:`CompletionConfig.velocity_decay`);
2. **gravity**: an unseen hand or foot moves by ``gravity_speed_m_s * weight * dt``
   towards where it would hang (straight down from its shoulder along the
   torso, or from its hip), never below the ground;
3. **inverse kinematics**: the arm and leg chains are given back their segment
   lengths with two-bone IK, the elbow or knee bending the way it did;
4. **joint limits**: elbows and knees are opened to their limits
   (:func:`toolkit.depth.constraints.enforce_joint_limits`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.depth.constraints import enforce_joint_limits
from toolkit.body.control_points import (
    HEAD,
    L_ELBOW,
    L_FOOT,
    L_HAND,
    L_HIP,
    L_KNEE,
    L_SHOULDER,
    N_POINTS,
    R_ELBOW,
    R_FOOT,
    R_HAND,
    R_HIP,
    R_KNEE,
    R_SHOULDER,
    BodyDimensions,
)
from toolkit.motion.kinematics import two_bone_ik

__all__ = ["GRAVITY_WEIGHTS", "CompletionConfig", "PointKalman", "complete"]

#: Relative weight of each control point in the gravity simulation.
GRAVITY_WEIGHTS = np.array([0.0, 0.0, 0.0, 0.5, 0.5, 1.0, 1.0, 0.0, 0.0, 0.3, 0.3, 1.0, 1.0])
_CHAINS = ((L_SHOULDER, L_ELBOW, L_HAND), (R_SHOULDER, R_ELBOW, R_HAND), (L_HIP, L_KNEE, L_FOOT),
           (R_HIP, R_KNEE, R_FOOT))


@dataclass(frozen=True)
class CompletionConfig:
    """Settings of the completion.

    Attributes
    ----------
    process_noise_m_s2 : float
        Acceleration noise of the Kalman filter.
    measurement_noise_m : float
    velocity_decay : float
        Factor applied to the velocity of an unseen point each frame.
    gravity_speed_m_s : float
        Sinking speed of an unseen point of weight 1.
    """

    process_noise_m_s2: float = 8.0
    measurement_noise_m: float = 0.02
    velocity_decay: float = 0.5
    gravity_speed_m_s: float = 1.0


class PointKalman:
    """Constant-velocity Kalman filters, one per control point and axis (independent).

    Parameters
    ----------
    n_points : int
    config : CompletionConfig
    """

    def __init__(self, n_points: int = N_POINTS, config: CompletionConfig = CompletionConfig()):
        self.n = n_points
        self.config = config
        self.x = None                       # (n, 3) positions
        self.v = np.zeros((n_points, 3))    # velocities
        self.P = np.zeros((n_points, 2, 2))  # covariance of (position, velocity), same for the 3 axes

    def reset(self, X: np.ndarray) -> None:
        self.x = np.array(X, float)
        self.v = np.zeros((self.n, 3))
        r = self.config.measurement_noise_m ** 2
        self.P = np.tile(np.diag([r, 1.0]), (self.n, 1, 1))

    @property
    def initialised(self) -> bool:
        return self.x is not None

    def predict(self, dt: float) -> np.ndarray:
        """Predicted positions (n, 3) after ``dt`` seconds (the state is advanced)."""
        F = np.array([[1.0, dt], [0.0, 1.0]])
        q = self.config.process_noise_m_s2 ** 2
        Q = q * np.array([[dt ** 4 / 4, dt ** 3 / 2], [dt ** 3 / 2, dt ** 2]])
        self.x = self.x + self.v * dt
        self.P = F @ self.P @ F.T + Q
        return self.x.copy()

    def update(self, X: np.ndarray, observed: np.ndarray) -> None:
        """Correct the predicted state with measurements ``X`` (n, 3) of the ``observed`` points;
        the velocity of the others decays."""
        obs = np.asarray(observed, bool) & np.all(np.isfinite(X), axis=1)
        r = self.config.measurement_noise_m ** 2
        S = self.P[:, 0, 0] + r
        K = self.P[:, :, 0] / S[:, None]                 # (n, 2)
        innov = np.asarray(X, float) - self.x
        self.x = np.where(obs[:, None], self.x + K[:, 0:1] * innov, self.x)
        self.v = np.where(obs[:, None], self.v + K[:, 1:2] * innov, self.v * self.config.velocity_decay)
        I_KH = np.eye(2)[None] - K[:, :, None] * np.array([1.0, 0.0])[None, None, :]
        Pn = I_KH @ self.P
        self.P = np.where(obs[:, None, None], Pn, self.P)
        # unseen points follow the completed skeleton
        self.x = np.where(obs[:, None], self.x, np.asarray(X, float))


def complete(X: np.ndarray, observed: np.ndarray, predicted: np.ndarray | None, dims: BodyDimensions,
             dt: float, config: CompletionConfig = CompletionConfig(), ground_y: float | None = None,
             X_prev: np.ndarray | None = None) -> np.ndarray:
    """Complete the unseen control points of a fitted skeleton.

    Parameters
    ----------
    X : ndarray of shape (13, 3)
        Fitted skeleton, view frame (y down).
    observed : ndarray of shape (13,), bool
        Points the data support.
    predicted : ndarray of shape (13, 3) or None
        Kalman prediction for this frame.
    dims : BodyDimensions
    dt : float
        Seconds since the previous frame.
    config : CompletionConfig
    ground_y : float or None
        View-frame y of the ground.
    X_prev : ndarray of shape (13, 3), optional
        Previous output (gives the bending direction of the chains).

    Returns
    -------
    ndarray of shape (13, 3)
    """
    Y = np.array(X, float)
    obs = np.asarray(observed, bool)
    unseen = ~obs
    unseen[HEAD] = unseen[HEAD] and predicted is not None
    if predicted is not None:
        P = np.asarray(predicted, float)
        # extrapolate the unseen points, keeping them attached where their parents moved
        Y[unseen] = P[unseen]
    down_torso = 0.5 * (Y[L_HIP] + Y[R_HIP]) - 0.5 * (Y[L_SHOULDER] + Y[R_SHOULDER])
    down_torso /= max(np.linalg.norm(down_torso), 1e-9)
    for a, b, c in _CHAINS:
        for j in (b, c):
            if not unseen[j]:
                continue
            down = down_torso if c in (L_HAND, R_HAND) else np.array([0.0, 1.0, 0.0])
            reach = dims.length(a, b) if j == b else 0.97 * (dims.length(a, b) + dims.length(b, c))
            hang = Y[a] + reach * down
            step = config.gravity_speed_m_s * GRAVITY_WEIGHTS[j] * dt
            d = hang - Y[j]
            n = np.linalg.norm(d)
            if n > 1e-9:
                Y[j] += d * min(1.0, step / n)
    if ground_y is not None:
        Y[:, 1] = np.minimum(Y[:, 1], ground_y - 0.02 * dims.scale)
    for a, b, c in _CHAINS:
        if not (unseen[b] or unseen[c]):
            continue
        l1, l2 = dims.length(a, b), dims.length(b, c)
        ref = X_prev if X_prev is not None else Y
        pole = ref[b] - 0.5 * (ref[a] + ref[c])
        if np.linalg.norm(pole) < 1e-6:
            # a straight limb of a user facing the camera: elbows bend backwards, knees forwards
            pole = np.array([0.0, 0.0, 1.0]) if c in (L_HAND, R_HAND) else np.array([0.0, 0.0, -1.0])
        target = Y[c]
        mid, end, _ = two_bone_ik(Y[a][None], target[None], l1, l2, pole)
        Y[b] = mid[0]
        Y[c] = end[0]
    Y, _ = enforce_joint_limits(Y)
    return Y
