"""Body primitives of the fitting energy and the distances of points to them.

The body around the 13 control points (:mod:`toolkit.body.control_points`) is made of
8 tapered limb capsules (:data:`~toolkit.body.control_points.LIMBS`), 5 end spheres
(head, hands, feet) and an elliptic cylinder on the torso patch whose
half-width follows the shoulder and hip spans (plus the flesh beyond the
joints) and whose half-depth is a fraction of stature; primitive ``k`` is
``PRIMITIVE_NAMES[k]``.  Distances are signed: negative inside a primitive.
"""

from __future__ import annotations

import numpy as np

from toolkit.body.control_points import (
    END_SPHERES,
    L_HIP,
    L_SHOULDER,
    LIMBS,
    R_HIP,
    R_SHOULDER,
    TYPICAL_RADII,
    BodyDimensions,
)

__all__ = [
    "N_PRIMITIVES",
    "PRIMITIVE_NAMES",
    "TORSO",
    "capsule_distances",
    "primitive_radii",
    "sphere_distances",
    "torso_distance",
    "torso_frame",
]

PRIMITIVE_NAMES = tuple(n for n, *_ in LIMBS) + tuple(n for n, *_ in END_SPHERES) + ("torso",)
N_PRIMITIVES = len(PRIMITIVE_NAMES)
TORSO = N_PRIMITIVES - 1
_N_CAPS = len(LIMBS)
_CAP_A = np.array([a for _, a, _, _ in LIMBS])
_CAP_B = np.array([b for _, _, b, _ in LIMBS])
_SPH = np.array([p for _, p, _ in END_SPHERES])
_XYZ = np.arange(3)[None, :]


_TORSO_POINTS = (L_SHOULDER, R_SHOULDER, L_HIP, R_HIP)



def torso_frame(X: np.ndarray, dims: BodyDimensions):
    """Torso axis ends, unit axes (up, lateral, forward), half-widths at top and bottom, half-depths."""
    s = dims.scale
    ms = 0.5 * (X[L_SHOULDER] + X[R_SHOULDER])
    mh = 0.5 * (X[L_HIP] + X[R_HIP])
    d = ms - mh
    eu = d / max(np.linalg.norm(d), 1e-9)
    lat = (X[R_SHOULDER] - X[L_SHOULDER]) + (X[R_HIP] - X[L_HIP])
    lat_p = lat - (lat @ eu) * eu
    nl = np.linalg.norm(lat_p)
    el = lat_p / nl if nl > 1e-9 else np.cross(eu, [0.0, 0.0, 1.0]) / max(np.linalg.norm(np.cross(eu, [0, 0, 1.0])), 1e-9)
    ef = np.cross(eu, el)
    top = ms + TYPICAL_RADII["torso_top_extent"] * s * eu
    bot = mh - TYPICAL_RADII["torso_bottom_extent"] * s * eu
    ext_s, ext_h = (x * s for x in TYPICAL_RADII["torso_side_extent"])
    ws = 0.5 * np.linalg.norm(X[R_SHOULDER] - X[L_SHOULDER]) + ext_s
    wh = 0.5 * np.linalg.norm(X[R_HIP] - X[L_HIP]) + ext_h
    ds, dh = (x * s for x in TYPICAL_RADII["torso_half_depth"])
    return top, bot, eu, el, ef, ws, wh, ds, dh, nl


def torso_distance(P: np.ndarray, X: np.ndarray, dims: BodyDimensions):
    """Signed distance of points (n, 3) to the torso's elliptic cylinder and the quantities for its Jacobian."""
    top, bot, eu, el, ef, ws, wh, ds, dh, nl = torso_frame(X, dims)
    tb = bot - top
    L = max(np.sqrt(tb @ tb), 1e-9)
    v_raw = ((top - P) @ eu) / L
    v = np.minimum(np.maximum(v_raw, 0.0), 1.0)
    q = P - top[None] - v[:, None] * tb[None]
    qu = q @ eu
    qp = q - qu[:, None] * eu[None]
    rp = np.sqrt(np.einsum("ij,ij->i", qp, qp))
    qh = qp / np.maximum(rp, 1e-9)[:, None]
    cl = qh @ el
    cf = qh @ ef
    a = (1 - v) * ws + v * wh
    b = (1 - v) * ds + v * dh
    rho = 1.0 / np.sqrt(cl ** 2 / a ** 2 + cf ** 2 / b ** 2)
    d_rad = rp - rho
    beyond = (v_raw - v) * L
    d = np.where(np.abs(beyond) > 1e-9, np.sqrt(np.maximum(d_rad, 0.0) ** 2 + beyond ** 2) * np.sign(
        np.maximum(d_rad, 0.0) + np.abs(beyond)), d_rad)
    aux = dict(v=v, qh=qh, cl=cl, a=a, b=b, rho=rho, eu=eu, el=el, nl=nl, rp=rp, beyond=beyond, d_rad=d_rad)
    return d, aux


def capsule_distances(P: np.ndarray, X: np.ndarray, radii: np.ndarray):
    """Distances (n, 8) of points to the limb capsules' surfaces, with projections t and unit offsets."""
    A = X[_CAP_A]
    B = X[_CAP_B]
    AB = B - A                                            # (8, 3)
    L2 = np.maximum(np.einsum("ij,ij->i", AB, AB), 1e-12)
    AP = P[:, None, :] - A[None]                           # (n, 8, 3)
    t = np.minimum(np.maximum(np.einsum("nij,ij->ni", AP, AB) / L2, 0.0), 1.0)
    q = AP - t[..., None] * AB[None]
    dist = np.sqrt(np.einsum("nij,nij->ni", q, q))
    r = radii[:, 0][None] + t * (radii[:, 1] - radii[:, 0])[None]
    return dist - r, dist, t, q


def sphere_distances(P: np.ndarray, X: np.ndarray, radii: np.ndarray):
    q = P[:, None, :] - X[_SPH][None]
    dist = np.sqrt(np.einsum("nij,nij->ni", q, q))
    return dist - radii[None], dist, q


def primitive_radii(dims: BodyDimensions) -> tuple[np.ndarray, np.ndarray]:
    return dims.limb_radii, dims.sphere_radii
