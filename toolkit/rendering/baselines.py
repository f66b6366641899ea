"""Baselines the articulated billboards are compared against (source 000 §4, §5).

* **Standard billboards**: one billboard per subject and source camera, a
  vertical plane through the subject's centre turned towards that camera,
  textured with the camera's image and silhouette; rendered with the same
  blend as the articulated billboards (one fan holding every camera).
* **Visual hull**: voxels inside every silhouette (shape from silhouette),
  surface voxels coloured from the cameras that see them (omega-weighted),
  splatted into the view with a z-buffer.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.billboards.model import Billboard, BillboardFan, BillboardModel
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.rendering.weights import ANGLE_SIGMA, omega

#: Texel size of baseline billboards relative to a source pixel at the billboard's depth.
TEXEL_PER_PIXEL = 0.25
#: Part id given to the single fan of standard billboards (no body part).
WHOLE_BODY_PART = 0
#: Border added around the silhouette's footprint on a standard billboard, metres.
STANDARD_MARGIN_M = 0.05


def sample_billboard(part: int, camera: Camera, image: np.ndarray, mask: np.ndarray, origin: np.ndarray,
                     e_u: np.ndarray, e_v: np.ndarray, u_range, v_range, texel_per_pixel: float = TEXEL_PER_PIXEL) -> Billboard:
    """A planar billboard textured from one source image.

    Parameters
    ----------
    part : int
        Part id stored in the billboard.
    camera : Camera
        Source camera, corrected by stage 1's offsets (:func:`toolkit.multiview.corrected_rig`).
    image : ndarray of shape (H, W, 3), uint8
    mask : ndarray of shape (H, W)
        Coverage of what the billboard shows (bool or float in [0, 1]).
    origin : ndarray of shape (3,)
        A point of the plane, metres.
    e_u, e_v : ndarray of shape (3,)
        Orthonormal in-plane directions of texture columns and rows.
    u_range, v_range : tuple of float
        Extent along ``e_u`` and ``e_v`` from ``origin``, metres.
    texel_per_pixel : float
        Texel size as a fraction of a source pixel at the billboard.

    Returns
    -------
    Billboard
    """
    W, H = camera.size
    if image.shape[:2] != (H, W) or np.asarray(mask).shape != (H, W):
        raise InputError(f"sample_billboard: image/mask of {camera.name!r}", f"shape ({H}, {W})",
                         f"{image.shape[:2]} and {np.asarray(mask).shape}")
    origin, e_u, e_v = (np.asarray(a, float) for a in (origin, e_u, e_v))
    centre = origin + 0.5 * (u_range[0] + u_range[1]) * e_u + 0.5 * (v_range[0] + v_range[1]) * e_v
    depth = max(float(camera.depth_of(centre)), 1e-3)
    texel = texel_per_pixel * depth / camera.K[0, 0]
    w = max(int(np.ceil((u_range[1] - u_range[0]) / texel)), 1)
    h = max(int(np.ceil((v_range[1] - v_range[0]) / texel)), 1)
    tl = origin + u_range[0] * e_u + v_range[0] * e_v
    du, dv = w * texel * e_u, h * texel * e_v
    corners = np.array([tl, tl + du, tl + du + dv, tl + dv])
    normal = np.cross(e_v, e_u)
    if np.dot(normal, camera.center - centre) < 0:
        normal = -normal
    probe = Billboard(part, camera.name, corners, np.zeros((h, w, 3), np.uint8), np.zeros((h, w), np.float32),
                      normal)
    Hs = probe.view_from_texture(camera)
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    tex = cv2.warpPerspective(np.ascontiguousarray(image), Hs, (w, h), flags=flags, borderMode=cv2.BORDER_CONSTANT)
    al = cv2.warpPerspective(np.asarray(mask, np.float32), Hs, (w, h), flags=flags, borderMode=cv2.BORDER_CONSTANT)
    return Billboard(part, camera.name, corners, tex, al, normal)


def standard_billboards(images: dict, masks: dict, joints: np.ndarray, rig: Rig,
                        frame: int = 0) -> BillboardModel:
    """One billboard per source camera for the whole subject (the classic billboard method).

    Parameters
    ----------
    images : dict of str -> ndarray (H, W, 3) uint8
    masks : dict of str -> ndarray (H, W)
        Subject silhouettes.
    joints : ndarray of shape (14, 3)
        3D joints (metres) giving the subject's position and height.
    rig : Rig
        Source cameras, corrected by stage 1's offsets (:func:`toolkit.multiview.corrected_rig`).

    Returns
    -------
    BillboardModel
        One fan (part :data:`WHOLE_BODY_PART`) with one billboard per camera that has a silhouette.
    """
    j = np.asarray(joints, float)
    if j.ndim != 2 or j.shape[1] != 3 or not np.isfinite(j).any():
        raise InputError("standard_billboards: joints", "a (J, 3) array with finite joints", f"shape {j.shape}")
    ok = np.isfinite(j).all(1)
    centre = j[ok].mean(0)
    top, bottom = j[ok, 2].max() + 0.15, 0.0
    axis = np.array([[centre[0], centre[1], top], [centre[0], centre[1], bottom]])
    e_v = np.array([0.0, 0.0, -1.0])
    boards = []
    for ci, cam in enumerate(rig):
        if cam.name not in images or cam.name not in masks:
            continue
        m = np.asarray(masks[cam.name])
        if not m.any():
            continue
        n = cam.center - centre
        n[2] = 0.0
        if np.linalg.norm(n) < 1e-6:
            continue
        n /= np.linalg.norm(n)
        e_u = np.cross(n, e_v)
        # footprint of the silhouette on the plane: rays through its bounding box
        ys, xs = np.nonzero(m)
        box = np.array([[xs.min(), ys.min()], [xs.max(), ys.min()], [xs.max(), ys.max()], [xs.min(), ys.max()]],
                       float)
        o, d = cam.rays(box)
        t = ((centre - o) @ n) / np.where(np.abs(d @ n) < 1e-9, 1e-9, d @ n)
        pts = o + t[:, None] * d - centre
        us, vs = pts @ e_u, pts @ e_v
        u_range = (us.min() - STANDARD_MARGIN_M, us.max() + STANDARD_MARGIN_M)
        v_range = (max(vs.min(), -top + centre[2]) - STANDARD_MARGIN_M, vs.max() + STANDARD_MARGIN_M)
        boards.append(sample_billboard(WHOLE_BODY_PART, cam, images[cam.name], m, centre, e_u, e_v,
                                       u_range, v_range))
    fans = (BillboardFan(WHOLE_BODY_PART, tuple(boards), axis),) if boards else ()
    return BillboardModel(fans, rig, frame, j if j.shape == (14, 3) else np.full((14, 3), np.nan))


@dataclass(frozen=True, eq=False)
class VisualHull:
    """Surface voxels of a visual hull with colours.

    Attributes
    ----------
    points : ndarray of shape (N, 3)
        Surface voxel centres, metres.
    colors : ndarray of shape (N, 3), float32
        RGB 0..255.
    voxel_m : float
        Voxel size, metres.
    """

    points: np.ndarray
    colors: np.ndarray
    voxel_m: float


#: Default voxel size of the visual hull, metres.
HULL_VOXEL_M = 0.015
#: Half-size of the box searched around the joints, metres.
HULL_MARGIN_M = 0.3


def visual_hull(images: dict, masks: dict, joints: np.ndarray, rig: Rig, voxel_m: float = HULL_VOXEL_M) -> VisualHull:
    """Carve a voxel visual hull from silhouettes and colour its surface.

    A voxel is kept when it projects inside the silhouette of every camera that
    sees it (cameras it falls outside of do not carve).  Surface voxels are
    coloured by the omega-weighted (angle between the voxel's outward
    direction and the camera) mean of the cameras that see them unoccluded.

    Parameters
    ----------
    images, masks : dict of str -> ndarray
    joints : ndarray of shape (J, 3)
        Bounds the carved box (plus :data:`HULL_MARGIN_M`).
    rig : Rig
        Source cameras, corrected by stage 1's offsets (:func:`toolkit.multiview.corrected_rig`).
    voxel_m : float

    Returns
    -------
    VisualHull
        Possibly with zero points.
    """
    j = np.asarray(joints, float)
    j = j[np.isfinite(j).all(1)]
    if len(j) == 0:
        raise InputError("visual_hull: joints", "at least one finite joint", "none")
    lo = j.min(0) - HULL_MARGIN_M
    hi = j.max(0) + HULL_MARGIN_M
    lo[2] = max(lo[2], 0.0)
    axes = [np.arange(lo[k], hi[k], voxel_m) + voxel_m / 2 for k in range(3)]
    shape = tuple(len(a) for a in axes)
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    alive = np.arange(len(grid))  # voxels no camera has carved yet: only these are projected by the next one
    uvs = []
    for ci, cam in enumerate(rig):
        m = np.asarray(masks[cam.name]).astype(bool)
        uv = np.full((len(grid), 2), np.nan)
        uv[alive] = cam.project(grid[alive])
        uvs.append(uv)
        W, H = cam.size
        x = np.rint(uv[alive, 0])
        y = np.rint(uv[alive, 1])
        seen = np.isfinite(x) & (x >= 0) & (x < W) & (y >= 0) & (y < H)
        xi = np.where(seen, x, 0).astype(np.int64)
        yi = np.where(seen, y, 0).astype(np.int64)
        alive = alive[~seen | m[yi, xi]]
    inside = np.zeros(len(grid), bool)
    inside[alive] = True
    occ = inside.reshape(shape)
    if not occ.any():
        return VisualHull(np.zeros((0, 3)), np.zeros((0, 3), np.float32), voxel_m)
    interior = occ.copy()
    interior[1:-1, 1:-1, 1:-1] = (occ[:-2, 1:-1, 1:-1] & occ[2:, 1:-1, 1:-1] & occ[1:-1, :-2, 1:-1]
                                  & occ[1:-1, 2:, 1:-1] & occ[1:-1, 1:-1, :-2] & occ[1:-1, 1:-1, 2:]
                                  & occ[1:-1, 1:-1, 1:-1])
    surf = (occ & ~interior).reshape(-1)
    pts = grid[surf]
    centre = pts.mean(0)
    outward = pts - centre
    outward[:, 2] = 0
    outward /= np.maximum(np.linalg.norm(outward, axis=1, keepdims=True), 1e-9)
    num = np.zeros((len(pts), 3), np.float64)
    den = np.zeros(len(pts), np.float64)
    for ci, cam in enumerate(rig):
        uv = uvs[ci][surf]
        W, H = cam.size
        z = cam.depth_of(pts)
        x = np.rint(uv[:, 0])
        y = np.rint(uv[:, 1])
        seen = np.isfinite(x) & (x >= 0) & (x < W) & (y >= 0) & (y < H) & (z > 0)
        xi = np.where(seen, x, 0).astype(np.int64)
        yi = np.where(seen, y, 0).astype(np.int64)
        zbuf = np.full((H, W), np.inf)
        np.minimum.at(zbuf, (yi[seen], xi[seen]), z[seen])
        vis = seen & (z <= zbuf[yi, xi] + 2.5 * voxel_m)
        d = cam.center - pts
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        beta = np.arccos(np.clip(np.sum(d * outward, 1), -1, 1))
        wgt = np.where(vis, omega(beta, 2 * ANGLE_SIGMA) + 1e-6, 0.0)
        num += wgt[:, None] * images[cam.name][yi, xi].astype(np.float64)
        den += wgt
    keep = den > 0
    return VisualHull(pts[keep], (num[keep] / den[keep, None]).astype(np.float32), voxel_m)


def render_points(hull: VisualHull, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Splat a coloured hull into ``camera`` with a z-buffer.

    Returns
    -------
    rgb : ndarray of shape (H, W, 3), float32
        Premultiplied colour 0..255.
    alpha : ndarray of shape (H, W), float32
        1 where the hull covers the pixel.
    """
    W, H = camera.size
    rgb = np.zeros((H, W, 3), np.float32)
    alpha = np.zeros((H, W), np.float32)
    if len(hull.points) == 0:
        return rgb, alpha
    z = camera.depth_of(hull.points)
    uv = camera.project(hull.points)
    ok = np.isfinite(uv).all(1) & (z > 0)
    uv, z, col = uv[ok], z[ok], hull.colors[ok]
    r = int(np.clip(np.ceil(0.5 * hull.voxel_m * camera.K[0, 0] / np.median(z)), 0, 8))
    off = np.arange(-r, r + 1)
    dx, dy = (a.ravel() for a in np.meshgrid(off, off))
    xs = (np.rint(uv[:, 0]).astype(np.int64)[:, None] + dx[None]).ravel()
    ys = (np.rint(uv[:, 1]).astype(np.int64)[:, None] + dy[None]).ravel()
    zz = np.repeat(z, len(dx))
    cc = np.repeat(col, len(dx), axis=0)
    s = (xs >= 0) & (xs < W) & (ys >= 0) & (ys < H)
    order = np.argsort(-zz[s], kind="stable")  # far first: nearer splats overwrite
    xs, ys, cc = xs[s][order], ys[s][order], cc[s][order]
    rgb[ys, xs] = cc
    alpha[ys, xs] = 1.0
    return rgb, alpha
