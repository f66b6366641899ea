"""Normal maps from depth gradients with a 3 x 3 kernel (source 001, figures 3 and 4).

The 3 x 3 Sobel kernel (:data:`SOBEL_X`, :data:`SOBEL_Y`) gives the depth
gradients ``z_u``, ``z_v`` per pixel (the source's "dZ/dX and dZ/dY from a 3 x 3
convolution mask"); with the back-projection ``P(u, v) = z (x, y, 1)`` the
surface tangents are ``dP/du = z_u (x, y, 1) + (z / f_x) e_x`` and
``dP/dv = z_v (x, y, 1) + (z / f_y) e_y``, and their cross product is the
normal, exact under perspective.  Pixels whose 3 x 3 neighbourhood holds a
missing reading or a depth jump get no normal (NaN).

The same kernel gives the normals of the orthographic user grid from its depth
(:func:`grid_normals`), where the bin spacing is constant.
"""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.cameras import Camera
from toolkit.pointcloud.cloud import _check_depth, pixel_rays
from toolkit.errors import InputError

__all__ = ["NORMAL_MAX_JUMP_M", "SOBEL_X", "SOBEL_Y", "grid_normals", "normal_map"]

#: Horizontal 3 x 3 derivative kernel (Sobel; divide by 8 for a unit-spacing derivative).
SOBEL_X = np.array([[-1, 0, 1], [-2, 0, 2], [-1, 0, 1]], np.float32)
#: Vertical 3 x 3 derivative kernel.
SOBEL_Y = SOBEL_X.T.copy()
#: A 3 x 3 neighbourhood whose depths span more than this (metres, plus 5 % of the
#: depth) straddles a depth edge and gets no normal.
NORMAL_MAX_JUMP_M = 0.06


def _sobel(img: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    return cv2.filter2D(img, cv2.CV_32F, kernel, borderType=cv2.BORDER_REPLICATE) / 8.0


def normal_map(depth: np.ndarray, camera: Camera, mask: np.ndarray | None = None,
               max_jump_m: float = NORMAL_MAX_JUMP_M) -> np.ndarray:
    """Unit surface normals of a depth map, camera frame, facing the camera.

    Parameters
    ----------
    depth : ndarray of shape (H, W)
        Metres, NaN or <= 0 = no reading.
    camera : Camera
    mask : ndarray of shape (H, W), bool, optional
        Only these pixels get normals (the work is limited to their bounding box).
    max_jump_m : float
        Depth-edge threshold (see :data:`NORMAL_MAX_JUMP_M`).

    Returns
    -------
    ndarray of shape (H, W, 3), float32
        NaN where no normal can be computed.
    """
    d = _check_depth(depth, camera)
    h, w = d.shape
    out = np.full((h, w, 3), np.nan, np.float32)
    valid = np.isfinite(d) & (d > 0)
    if mask is not None:
        m = np.asarray(mask, bool)
        if m.shape != d.shape:
            raise InputError("mask", f"a boolean image of shape {d.shape}", f"shape {m.shape}")
        sel = valid & m
    else:
        sel = valid
    rows, cols = np.nonzero(sel)
    if len(rows) == 0:
        return out
    r0, r1 = max(rows.min() - 1, 0), min(rows.max() + 2, h)
    c0, c1 = max(cols.min() - 1, 0), min(cols.max() + 2, w)
    vb = valid[r0:r1, c0:c1]
    z = np.where(vb, d[r0:r1, c0:c1], 0).astype(np.float32)
    zu = _sobel(z, SOBEL_X)
    zv = _sobel(z, SOBEL_Y)
    rays = pixel_rays(camera)[r0:r1, c0:c1]
    fx, fy = float(camera.K[0, 0]), float(camera.K[1, 1])
    # P = z (x, y, 1): dP/du = zu (x, y, 1) + (z / fx) e_x, dP/dv = zv (x, y, 1) + (z / fy) e_y; their
    # cross product, scaled by fx fy / z and turned towards the camera:
    n = np.empty(z.shape + (3,), np.float32)
    n[..., 0] = fx * zu
    n[..., 1] = fy * zv
    n[..., 2] = -(fx * zu * rays[..., 0] + fy * zv * rays[..., 1] + z)
    norm = np.sqrt(np.einsum("...i,...i", n, n))[..., None]
    n /= np.maximum(norm, 1e-12)
    k = np.ones((3, 3), np.uint8)
    zbig = np.where(vb, z, 1e4).astype(np.float32)
    full = cv2.erode(vb.astype(np.uint8), k, borderType=cv2.BORDER_CONSTANT, borderValue=0) > 0
    rng_ = cv2.dilate(z, k) - cv2.erode(zbig, k)
    ok = full & (rng_ <= max_jump_m + 0.05 * z) & sel[r0:r1, c0:c1] & (norm[..., 0] > 0)
    block = out[r0:r1, c0:c1]
    block[ok] = n[ok]
    return out


def grid_normals(z: np.ndarray, spacing: float) -> np.ndarray:
    """Normals of a regularly spaced height field (the orthographic grid's depth).

    Parameters
    ----------
    z : ndarray of shape (ny, nx)
        Depth (metres) per bin, NaN where empty.
    spacing : float
        Bin size, metres.

    Returns
    -------
    ndarray of shape (ny, nx, 3)
        Unit normals ``(dz/dx, dz/dy, -1)`` normalised (outward, facing the camera);
        NaN where ``z`` is NaN.  Empty neighbours count as their opposite
        neighbour (one-sided difference at borders).
    """
    z = np.asarray(z, np.float64)
    ok = np.isfinite(z)
    zf = np.where(ok, z, 0.0)
    # one-sided at borders: replace missing neighbours by mirror-extrapolation of the centre
    pad = np.pad(zf, 1, mode="edge")
    okp = np.pad(ok, 1, mode="constant", constant_values=False)
    ny, nx = z.shape
    gx = np.zeros_like(zf)
    gy = np.zeros_like(zf)
    wx = np.zeros_like(zf)
    wy = np.zeros_like(zf)
    for k, wk in zip((-1, 0, 1), (1.0, 2.0, 1.0)):
        # horizontal derivative along x in row offset k (central, else one-sided)
        rows = slice(1 + k, 1 + k + ny)
        left, right = pad[rows, 0:nx], pad[rows, 2:nx + 2]
        lo, ro = okp[rows, 0:nx], okp[rows, 2:nx + 2]
        centre, co = pad[rows, 1:nx + 1], okp[rows, 1:nx + 1]
        has = (lo & ro) | (ro & co) | (lo & co)
        diff = np.where(lo & ro, (right - left) / 2, np.where(ro & co, right - centre,
                                                              np.where(lo & co, centre - left, 0.0)))
        gx += wk * diff
        wx += wk * has
        cols = slice(1 + k, 1 + k + nx)
        up_, dn = pad[0:ny, cols], pad[2:ny + 2, cols]
        uo, do = okp[0:ny, cols], okp[2:ny + 2, cols]
        centre, co = pad[1:ny + 1, cols], okp[1:ny + 1, cols]
        has = (uo & do) | (do & co) | (uo & co)
        diff = np.where(uo & do, (dn - up_) / 2, np.where(do & co, dn - centre,
                                                          np.where(uo & co, centre - up_, 0.0)))
        gy += wk * diff
        wy += wk * has
    gx /= np.maximum(wx, 1e-9) * spacing
    gy /= np.maximum(wy, 1e-9) * spacing
    n = np.stack([gx, gy, -np.ones_like(gx)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n[~ok] = np.nan
    return n
