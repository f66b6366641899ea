"""Per-camera blending weights of a billboard fan (source 000 §4.1, eqs. 5 and 7).

For one fan (the billboards of one body part, one per source camera) seen by a
virtual camera V:

* ``omega_j = exp(-beta_j**2 / (2 sigma**2))`` with ``beta_j`` the angle at the
  fan's centre between the directions to V and to source camera j
  (:data:`ANGLE_SIGMA` = 0.32 rad, the same Gaussian as the position score);
* the attenuation ``f = 1`` for the source camera with the largest ``omega``
  (the nearest one) and ``f = 1 - exp(-d**2 / (2 sigma**2))`` for every other
  camera, ``d`` the distance from V to that nearest source camera
  (:data:`ATTENUATION_SIGMA_M` = 1 m, eq. 7), so a virtual camera placed on a
  source camera sees that camera alone;
* a fade-out of billboards seen at a grazing angle or from behind (§4.2, last
  paragraph), :func:`grazing_fade`;
* where V sees every billboard of a fan from behind (a reverse angle), their
  back faces, weighted by :func:`back_view_angles` (the renderer's fallback,
  :func:`toolkit.rendering.blend.fan_weights`).

All functions are vectorised over fans.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError

#: Width of the Gaussian camera weight omega(beta), radians (source 000, eq. 5: 0.32).
ANGLE_SIGMA = 0.32
#: Width of the attenuation function f, metres (source 000, eq. 7: 1 m).
ATTENUATION_SIGMA_M = 1.0
#: Foreshortening ratio (cos seen by V / cos seen by the source) below which a billboard is invisible.
FADE_RATIO_LOW = 0.15
#: Foreshortening ratio above which a billboard is fully visible.
FADE_RATIO_HIGH = 0.4


def omega(beta: np.ndarray, sigma: float = ANGLE_SIGMA) -> np.ndarray:
    """Gaussian camera weight of eq. 5, ``exp(-beta^2 / 2 sigma^2)``.

    Parameters
    ----------
    beta : ndarray
        Angles in radians.
    sigma : float
        Width in radians.
    """
    b = np.asarray(beta, np.float64)
    return np.exp(-b * b / (2.0 * sigma * sigma))


def attenuation(distance_m: np.ndarray, sigma_m: float = ATTENUATION_SIGMA_M) -> np.ndarray:
    """Eq. 7, ``1 - exp(-d^2 / 2 sigma^2)``: the weight factor of the non-nearest cameras."""
    d = np.asarray(distance_m, np.float64)
    return 1.0 - np.exp(-d * d / (2.0 * sigma_m * sigma_m))


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-12)


def view_angles(anchors: np.ndarray, virtual_center: np.ndarray, source_centers: np.ndarray) -> np.ndarray:
    """Angles beta between the directions from each anchor to V and to each source camera.

    Parameters
    ----------
    anchors : ndarray of shape (F, 3)
        Fan centres in metres.
    virtual_center : ndarray of shape (3,)
    source_centers : ndarray of shape (C, 3)

    Returns
    -------
    ndarray of shape (F, C)
        Radians in [0, pi].
    """
    a = np.asarray(anchors, np.float64).reshape(-1, 3)
    v = _unit(np.asarray(virtual_center, np.float64)[None] - a)  # (F, 3)
    s = _unit(np.asarray(source_centers, np.float64)[None] - a[:, None])  # (F, C, 3)
    c = np.clip(np.einsum("fk,fck->fc", v, s), -1.0, 1.0)
    return np.arccos(c)


def grazing_fade(normals: np.ndarray, points: np.ndarray, virtual_center: np.ndarray,
                 source_centers: np.ndarray, low: float = FADE_RATIO_LOW, high: float = FADE_RATIO_HIGH,
                 side: str = "front") -> np.ndarray:
    """Fade factor in [0, 1] of billboards seen at a grazing angle or from behind.

    The ratio ``r = cos(angle to V) / cos(angle to the billboard's own source camera)``
    measures how much more foreshortened V sees the billboard than its source did;
    the factor rises linearly from 0 at ``r = low`` to 1 at ``r = high``, and
    is 0 when V is behind the plane.  At the source camera ``r = 1``: no fade.
    With ``side="back"`` the same is measured for the billboard's back face
    (V behind the plane; 0 when V is in front of it).

    Parameters
    ----------
    normals : ndarray of shape (F, C, 3)
        Billboard normals (any sign; oriented towards their source camera here).
    points : ndarray of shape (F, C, 3)
        A point on each billboard (metres).
    virtual_center : ndarray of shape (3,)
    source_centers : ndarray of shape (C, 3)
    low, high : float
        Ratios where the fade starts and ends.
    side : {"front", "back"}
        Which face of the billboards V is to see.

    Returns
    -------
    ndarray of shape (F, C)
    """
    if side not in ("front", "back"):
        raise InputError("grazing_fade: side", "'front' or 'back'", repr(side))
    r = foreshortening(normals, points, virtual_center, source_centers) * (1.0 if side == "front" else -1.0)
    fade = np.clip((r - low) / (high - low), 0.0, 1.0)
    return np.where(r > 0, fade, 0.0)


def foreshortening(normals: np.ndarray, points: np.ndarray, virtual_center: np.ndarray,
                   source_centers: np.ndarray) -> np.ndarray:
    """Ratio ``cos(angle to V) / cos(angle to the billboard's own source camera)`` of each billboard.

    The angles are those between the billboard's normal, turned towards its
    source camera, and the directions from its point to V and to that source:
    1 at the source, 0 edge-on, negative when V is behind the plane (V sees
    its back face; ``-1`` for V at the source mirrored through the plane).

    Parameters
    ----------
    normals : ndarray of shape (F, C, 3)
        Billboard normals (any sign).
    points : ndarray of shape (F, C, 3)
        A point on each billboard (metres).
    virtual_center : ndarray of shape (3,)
    source_centers : ndarray of shape (C, 3)

    Returns
    -------
    ndarray of shape (F, C)
        Dimensionless.
    """
    n = _oriented(normals, points, source_centers)
    p = np.asarray(points, np.float64)
    cos_src = np.einsum("fck,fck->fc", n, _unit(np.asarray(source_centers, np.float64)[None] - p))
    cos_v = np.einsum("fck,fck->fc", n, _unit(np.asarray(virtual_center, np.float64)[None, None] - p))
    return cos_v / np.maximum(cos_src, 1e-6)


def _oriented(normals: np.ndarray, points: np.ndarray, source_centers: np.ndarray) -> np.ndarray:
    """Unit normals (F, C, 3) turned towards each billboard's source camera."""
    n = _unit(np.asarray(normals, np.float64))
    to_src = np.asarray(source_centers, np.float64)[None] - np.asarray(points, np.float64)
    return n * np.where(np.einsum("fck,fck->fc", n, to_src) < 0, -1.0, 1.0)[..., None]


def back_view_angles(anchors: np.ndarray, normals: np.ndarray, points: np.ndarray, virtual_center: np.ndarray,
                     source_centers: np.ndarray) -> np.ndarray:
    """Angles beta of billboards seen from behind, for the blend.

    A plane seen from V behind it looks exactly like the mirror image of the
    plane seen from V', V reflected through the plane; its source camera's
    texture is right for V' when the source is near V'.  So the camera weight
    of a back face is omega of the angle, at the fan's anchor, between the
    directions to V' and to the source camera.

    Parameters
    ----------
    anchors : ndarray of shape (F, 3)
        Fan centres, metres.
    normals, points : ndarray of shape (F, C, 3)
        Billboard normals (any sign) and a point on each billboard, metres.
    virtual_center : ndarray of shape (3,)
    source_centers : ndarray of shape (C, 3)

    Returns
    -------
    ndarray of shape (F, C)
        Radians in [0, pi].
    """
    a = np.asarray(anchors, np.float64).reshape(-1, 1, 3)
    n = _unit(np.asarray(normals, np.float64))
    p = np.asarray(points, np.float64)
    v = np.asarray(virtual_center, np.float64)[None, None]
    mirrored = v - 2.0 * np.einsum("fck,fck->fc", v - p, n)[..., None] * n  # (F, C, 3)
    d_v = _unit(mirrored - a)
    d_s = _unit(np.asarray(source_centers, np.float64)[None] - a)
    return np.arccos(np.clip(np.einsum("fck,fck->fc", d_v, d_s), -1.0, 1.0))


@dataclass(frozen=True)
class CameraWeights:
    """Per-fan, per-camera weights for one virtual view.

    Attributes
    ----------
    beta : ndarray of shape (F, C)
        Angles (radians) between V and each source camera, seen from each fan centre.
    omega : ndarray of shape (F, C)
        Eq. 5 weights.
    attenuation : ndarray of shape (F, C)
        Eq. 7 factor f: 1 for each fan's nearest camera, ``1 - exp(-d^2/2sigma^2)`` else.
    fade : ndarray of shape (F, C)
        Grazing / back-facing fade factor (1 when not given).
    nearest : ndarray of shape (F,), int
        Index of each fan's nearest source camera (largest omega).
    distance_m : ndarray of shape (F,)
        Distance from V to that camera.
    back : ndarray of shape (F, C), bool, or None
        Billboards drawn from behind (their back face; ``beta`` and ``omega``
        are then those of :func:`back_view_angles`); None = none.
    """

    beta: np.ndarray
    omega: np.ndarray
    attenuation: np.ndarray
    fade: np.ndarray
    nearest: np.ndarray
    distance_m: np.ndarray
    back: np.ndarray | None = None

    @property
    def weight(self) -> np.ndarray:
        """``omega * f * fade``, (F, C): eq. 9 without the per-pixel alpha."""
        return self.omega * self.attenuation * self.fade

    @property
    def omega_faded(self) -> np.ndarray:
        """``omega * fade`` (F, C): the denominator weights of eq. 10."""
        return self.omega * self.fade


def camera_weights(anchors: np.ndarray, virtual_center: np.ndarray, source_centers: np.ndarray, *,
                   normals: np.ndarray | None = None, points: np.ndarray | None = None,
                   angle_sigma: float = ANGLE_SIGMA, attenuation_sigma_m: float = ATTENUATION_SIGMA_M
                   ) -> CameraWeights:
    """Camera blending weights of every fan for one virtual camera (eqs. 5, 7 and the fade-out).

    Parameters
    ----------
    anchors : ndarray of shape (F, 3)
        Fan centres (e.g. bone midpoints), metres.
    virtual_center : ndarray of shape (3,)
        Virtual camera centre, metres.
    source_centers : ndarray of shape (C, 3)
        Source camera centres, metres.
    normals, points : ndarray of shape (F, C, 3), optional
        Billboard normals and points for :func:`grazing_fade`; no fade when omitted.

    Returns
    -------
    CameraWeights

    Raises
    ------
    InputError
        On wrong shapes or non-finite centres.
    """
    a = np.asarray(anchors, np.float64)
    src = np.asarray(source_centers, np.float64)
    vc = np.asarray(virtual_center, np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError("camera_weights: anchors", "shape (F, 3)", f"shape {a.shape}")
    if src.ndim != 2 or src.shape[1] != 3 or len(src) == 0:
        raise InputError("camera_weights: source_centers", "shape (C, 3) with C >= 1", f"shape {src.shape}")
    if vc.shape != (3,) or not np.all(np.isfinite(vc)):
        raise InputError("camera_weights: virtual_center", "a finite (3,) point", f"{vc.tolist()}")
    beta = view_angles(a, vc, src)
    om = omega(beta, angle_sigma)
    nearest = np.argmax(om, axis=1)
    dist = np.linalg.norm(src[nearest] - vc, axis=1)
    att = np.repeat(attenuation(dist, attenuation_sigma_m)[:, None], len(src), axis=1)
    att[np.arange(len(a)), nearest] = 1.0
    if normals is None:
        fade = np.ones_like(om)
    else:
        fade = grazing_fade(normals, points, vc, src)
    return CameraWeights(beta, om, att, fade, nearest, dist)
