"""Fan geometry: the billboard plane of a bone for one source camera (source 000 §1).

The plane goes through the bone's proximal end ``x`` and holds the bone
direction ``b`` and ``b x (c - x)``; its normal is therefore the component of
``c - x`` orthogonal to ``b``.  When the bone points (almost) at the camera the
plane is undefined: :func:`billboard_frame` returns None ("edge-on").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.cameras import Camera


@dataclass(frozen=True, eq=False)
class BillboardFrame:
    """Orthonormal frame of a billboard plane.

    Attributes
    ----------
    origin : ndarray of shape (3,)
        Proximal bone end, metres (a = s = 0).
    e_u : ndarray of shape (3,)
        Across the bone, ``normal x e_v``.
    e_v : ndarray of shape (3,)
        Along the bone, proximal to distal.
    normal : ndarray of shape (3,)
        Towards the source camera.
    length : float
        Bone length, metres.
    """

    origin: np.ndarray
    e_u: np.ndarray
    e_v: np.ndarray
    normal: np.ndarray
    length: float

    def to_world(self, a, s) -> np.ndarray:
        """World points (..., 3) of plane coordinates ``a`` (across) and ``s`` (along), metres."""
        a = np.asarray(a, float)[..., None]
        s = np.asarray(s, float)[..., None]
        return self.origin + a * self.e_u + s * self.e_v

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plane coordinates ``(a, s)`` (N,) where rays hit the plane, and ``t`` (N,) along the rays.

        ``t`` is inf (and a, s NaN) for rays parallel to the plane.
        """
        o = np.asarray(origins, float).reshape(-1, 3)
        d = np.asarray(directions, float).reshape(-1, 3)
        den = d @ self.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((self.origin - o) @ self.normal) / den
        t = np.where(np.abs(den) > 1e-12, t, np.inf)
        p = o + np.where(np.isfinite(t), t, np.nan)[:, None] * d
        q = p - self.origin
        return np.stack([q @ self.e_u, q @ self.e_v], axis=-1), t


def billboard_frame(proximal, distal, center, edge_on_deg: float = 8.0) -> BillboardFrame | None:
    """The billboard plane of bone ``proximal -> distal`` for a camera centred at ``center``.

    Parameters
    ----------
    proximal, distal : array_like of shape (3,)
        Bone ends, metres.
    center : array_like of shape (3,)
        Source camera centre, metres.
    edge_on_deg : float
        Smallest angle between the bone and the ray from the camera to the
        proximal end, degrees.

    Returns
    -------
    BillboardFrame or None
        None when the bone has (almost) zero length, contains non-finite values,
        or points at the camera within ``edge_on_deg``.
    """
    x = np.asarray(proximal, float)
    y = np.asarray(distal, float)
    c = np.asarray(center, float)
    b = y - x
    L = float(np.linalg.norm(b))
    if not np.isfinite(L) or L < 1e-6:
        return None
    b = b / L
    d = c - x
    dn = float(np.linalg.norm(d))
    if dn < 1e-9:
        return None
    d_perp = d - (d @ b) * b
    sin = float(np.linalg.norm(d_perp)) / dn
    if sin < np.sin(np.radians(edge_on_deg)):
        return None
    n = d_perp / np.linalg.norm(d_perp)
    e_u = np.array([n[1] * b[2] - n[2] * b[1], n[2] * b[0] - n[0] * b[2], n[0] * b[1] - n[1] * b[0]])
    return BillboardFrame(origin=x, e_u=e_u, e_v=b, normal=n, length=L)


def segment_extent(frame: BillboardFrame, camera: Camera, pixels: np.ndarray, margin_m: float = 0.0, max_extent_m: float = 0.5) -> tuple[float, float, float, float] | None:
    """Rectangle ``(a0, a1, s0, s1)`` in plane coordinates covering a segment's pixels.

    Parameters
    ----------
    frame : BillboardFrame
    camera : Camera
        The source camera, corrected by stage 1's offsets.
    pixels : ndarray of shape (N, 2)
        Outline points of the part's segment in the image, pixels (e.g. the
        corners of its convex hull).
    margin_m : float
        Border added on every side, metres.
    max_extent_m : float
        The rectangle never reaches further than this from the bone across it,
        nor past its ends along it, metres.

    Returns
    -------
    tuple of float or None
        None when no outline ray hits the plane in front of the camera.
    """
    px = np.asarray(pixels, float).reshape(-1, 2)
    o, d = camera.rays(px)
    as_, t = frame.intersect(o, d)
    ok = np.isfinite(t) & (t > 0)
    if not ok.any():
        return None
    a, s = as_[ok, 0], as_[ok, 1]
    a0 = max(float(a.min()) - margin_m, -max_extent_m)
    a1 = min(float(a.max()) + margin_m, max_extent_m)
    s0 = max(float(s.min()) - margin_m, -max_extent_m)
    s1 = min(float(s.max()) + margin_m, frame.length + max_extent_m)
    if a1 <= a0 or s1 <= s0:
        return None
    return a0, a1, s0, s1
