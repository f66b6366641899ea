"""Projection surfaces other than planes (source 000 claim 11): cylinders and ellipsoids.

Both are parametrised on the billboard's plane frame: the point of plane
coordinates ``(a, s)`` (across, along the bone) is lifted along the plane
normal (towards the source camera) onto the front half of

* a cylinder of radius ``r`` around the bone: ``h = sqrt(r² - a²)``;
* an ellipsoid with semi-axes ``(r, r, L/2)`` centred mid-bone:
  ``h = r sqrt(1 - (a/r)² - ((s - L/2)/(L/2))²)``,

and stays on the plane where the square root is undefined (``h = 0``).  The
texture of such a billboard is the source image sampled at the projections of
the lifted points, so that seen from the source camera it reproduces the
segment exactly; from other views the bulge changes the parallax.
"""

from __future__ import annotations

import numpy as np

from toolkit.billboards.geometry import BillboardFrame
from toolkit.errors import InputError


def lift(frame: BillboardFrame, a: np.ndarray, s: np.ndarray, surface: str, radius: float) -> np.ndarray:
    """World points (..., 3) of the surface above plane coordinates ``a``, ``s`` (...,) metres."""
    a = np.asarray(a, float)
    s = np.asarray(s, float)
    if surface == "plane":
        h = np.zeros(np.broadcast(a, s).shape)
    elif surface == "cylinder":
        h = np.sqrt(np.clip(radius ** 2 - a ** 2, 0.0, None))
    elif surface == "ellipsoid":
        half = max(frame.length / 2.0, 1e-6)
        q = 1.0 - (a / radius) ** 2 - ((s - half) / half) ** 2
        h = radius * np.sqrt(np.clip(q, 0.0, None))
    else:
        raise InputError("surface", "'plane', 'cylinder' or 'ellipsoid'", repr(surface))
    return frame.to_world(a, s) + h[..., None] * frame.normal


def frame_of(corners: np.ndarray, normal: np.ndarray, axis: np.ndarray) -> BillboardFrame:
    """Rebuild the plane frame of a billboard from its corners, normal and bone ends."""
    c = np.asarray(corners, float)
    e_u = c[1] - c[0]
    e_u /= np.linalg.norm(e_u)
    e_v = c[3] - c[0]
    e_v /= np.linalg.norm(e_v)
    ax = np.asarray(axis, float)
    return BillboardFrame(origin=ax[0], e_u=e_u, e_v=e_v, normal=np.asarray(normal, float),
                          length=float(np.linalg.norm(ax[1] - ax[0])))
