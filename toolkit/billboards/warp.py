"""Projective texturing, fast: one billboard into any view by a homography (source 000 §3.1, §4).

A planar billboard maps to a view by the homography ``view_from_texture``;
:func:`warp_billboard` applies it with ``cv2.warpPerspective`` to the
billboard's footprint only (the bounding box of its projected corners), and
returns the colour, alpha and per-pixel depth of the plane there.  Cylinder and
ellipsoid billboards are drawn as a grid of small planar cells, each with its
own homography, nearest cell first.

:func:`render_view` is a small reference compositor built on it: fans are drawn
back to front; the billboards of one fan are blended with the pair weight
ω(β) = exp(-β²/2σ²) of the angle β between the view's and the source camera's
directions to the bone.  The view-dependent renderer of the rendering issue
reuses :func:`warp_billboard`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.billboards.config import PAIR_ANGLE_SIGMA
from toolkit.billboards.model import Billboard, BillboardModel
from toolkit.billboards.surfaces import frame_of, lift
from toolkit.cameras import Camera
from toolkit.errors import InputError

#: Cells per side of the piecewise-planar mesh of a cylinder / ellipsoid billboard.
SURFACE_CELLS = 16


@dataclass(frozen=True, eq=False)
class Warp:
    """A billboard drawn into part of a view.

    Attributes
    ----------
    rgb : ndarray of shape (h, w, 3), float32
        Colour, 0..255 (premultiplied by nothing: read it where alpha > 0).
    alpha : ndarray of shape (h, w), float32
        Coverage in [0, 1].
    depth : ndarray of shape (h, w), float32
        Camera-frame z of the surface in metres, inf where alpha is 0.
    roi : tuple of int
        ``(x0, y0, x1, y1)``: the array covers view pixels x0 <= x < x1, y0 <= y < y1.
    """

    rgb: np.ndarray
    alpha: np.ndarray
    depth: np.ndarray
    roi: tuple[int, int, int, int]

    @property
    def empty(self) -> bool:
        return self.roi[2] <= self.roi[0] or self.roi[3] <= self.roi[1]


def _empty(roi=(0, 0, 0, 0)) -> Warp:
    h, w = max(roi[3] - roi[1], 0), max(roi[2] - roi[0], 0)
    return Warp(np.zeros((h, w, 3), np.float32), np.zeros((h, w), np.float32),
                np.full((h, w), np.inf, np.float32), roi)


def footprint_roi(points_px: np.ndarray, size: tuple[int, int], roi=None) -> tuple[int, int, int, int]:
    """Integer bounding box ``(x0, y0, x1, y1)`` of pixel points, clipped to the image and to ``roi``."""
    p = np.asarray(points_px, float).reshape(-1, 2)
    w, h = size
    x0, y0 = np.floor(p.min(axis=0) - 1).astype(int)
    x1, y1 = np.ceil(p.max(axis=0) + 2).astype(int)
    lo = (0, 0) if roi is None else (roi[0], roi[1])
    hi = (w, h) if roi is None else (min(w, roi[2]), min(h, roi[3]))
    return (int(max(x0, lo[0])), int(max(y0, lo[1])), int(min(x1, hi[0])), int(min(y1, hi[1])))


def plane_depth(camera: Camera, point, normal, roi) -> np.ndarray:
    """Camera-frame z (h, w) of a world plane at the pixels of ``roi`` (pinhole)."""
    x0, y0, x1, y1 = roi
    n_c = camera.R @ np.asarray(normal, float)
    d_c = float(n_c @ camera.to_cam(np.asarray(point, float)))
    Kinv = np.linalg.inv(camera.K)
    # n_c . (z K^-1 p) = d_c  ->  z = d_c / (n_c . K^-1 p), and n_c . K^-1 p is affine in (u, v)
    g = n_c @ Kinv
    u = np.arange(x0, x1, dtype=np.float64)
    v = np.arange(y0, y1, dtype=np.float64)
    den = g[0] * u[None, :] + g[1] * v[:, None] + g[2]
    with np.errstate(divide="ignore"):
        z = d_c / den
    return np.where(z > 0, z, np.inf).astype(np.float32)


def warp_texture(texture_rgba: np.ndarray, H: np.ndarray, roi, size) -> Warp | None:
    """Warp an RGBA texture into a view by the homography ``H`` (view pixels from texture pixels).

    Parameters
    ----------
    texture_rgba : ndarray of shape (h, w, 4) uint8
    H : ndarray of shape (3, 3)
    roi : tuple of int (x0, y0, x1, y1) or None
        Restrict the output to this region of the view (None: the quad's footprint only).
    size : tuple of int
        View ``(width, height)``.

    Returns
    -------
    Warp or None
        None when part of the quad lies behind the view or its footprint is empty.
    """
    hh, ww = texture_rgba.shape[:2]
    c = np.array([[-0.5, -0.5, 1], [ww - 0.5, -0.5, 1], [ww - 0.5, hh - 0.5, 1], [-0.5, hh - 0.5, 1]])
    q = c @ H.T
    if np.any(q[:, 2] <= 1e-9):
        return None  # part of the quad behind the view
    px = q[:, :2] / q[:, 2:3]
    r = footprint_roi(px, size, roi)
    if r[2] <= r[0] or r[3] <= r[1]:
        return None
    T = np.array([[1.0, 0, -r[0]], [0, 1.0, -r[1]], [0, 0, 1.0]])
    out = cv2.warpPerspective(texture_rgba, T @ H, (r[2] - r[0], r[3] - r[1]), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return Warp(out[..., :3], out[..., 3], np.empty(0, np.float32), r)


def warp_billboard(billboard: Billboard, camera: Camera, out_size: tuple[int, int] | None = None,
                   roi: tuple[int, int, int, int] | None = None, min_cos: float = 0.0) -> Warp:
    """Draw one billboard into a view.

    Parameters
    ----------
    billboard : Billboard
    camera : Camera
        The view (pinhole; its distortion is ignored); a source camera corrected
        by stage 1's offsets (the model's rig) reproduces its image.
    out_size : tuple of int, optional
        ``(width, height)`` of the view; the camera's size by default.
    roi : tuple of int, optional
        ``(x0, y0, x1, y1)`` to restrict the output to.
    min_cos : float
        Skip the billboard (empty result) when the cosine between its normal
        and the direction to the view is at most this (seen from behind or edge-on).

    Returns
    -------
    Warp
        Empty (``roi`` of zero area) when the billboard is outside the view,
        behind it, or seen edge-on / from behind.
    """
    if not isinstance(billboard, Billboard):
        raise InputError("billboard", "a Billboard", type(billboard).__name__)
    size = camera.size if out_size is None else (int(out_size[0]), int(out_size[1]))
    to_view = camera.center - billboard.center
    cos = float(billboard.normal @ to_view / max(np.linalg.norm(to_view), 1e-12))
    if cos <= min_cos:
        return _empty()
    rgba = np.dstack([billboard.texture.astype(np.float32), billboard.alpha])
    if billboard.surface == "plane":
        H = billboard.view_from_texture(camera)
        w = warp_texture(rgba, H, roi, size)
        if w is None:
            return _empty()
        depth = plane_depth(camera, billboard.corners[0], billboard.normal, w.roi)
        depth = np.where(w.alpha > 0, depth, np.inf).astype(np.float32)
        return Warp(np.ascontiguousarray(w.rgb), np.ascontiguousarray(w.alpha), depth, w.roi)
    return _warp_surface(billboard, rgba, camera, size, roi)


def _warp_surface(bb: Billboard, rgba, camera: Camera, size, roi) -> Warp:
    frame = frame_of(bb.corners, bb.normal, bb.axis)
    w_tex, h_tex = bb.size
    M = bb.world_from_texture()
    # plane coordinates of the texture's outer corners
    tl = bb.corners[0] - frame.origin
    a0, s0 = float(tl @ frame.e_u), float(tl @ frame.e_v)
    du, dv = np.linalg.norm(M[:, 0]), np.linalg.norm(M[:, 1])
    nu, nv = min(SURFACE_CELLS, w_tex), min(SURFACE_CELLS, h_tex)
    ue = np.linspace(0, w_tex, nu + 1)  # cell edges in texels (outer-corner convention)
    ve = np.linspace(0, h_tex, nv + 1)
    A, S = np.meshgrid(a0 + ue * du, s0 + ve * dv)
    P = lift(frame, A, S, bb.surface, bb.radius)  # (nv+1, nu+1, 3)
    q = camera.to_cam(P)
    if np.any(q[..., 2] <= 1e-9):
        return _empty()
    pix = (q[..., :2] / q[..., 2:3]) @ camera.K[:2, :2].T + camera.K[:2, 2]  # pinhole, like planes
    r = footprint_roi(pix, size, roi)
    if r[2] <= r[0] or r[3] <= r[1]:
        return _empty()
    hh, ww = r[3] - r[1], r[2] - r[0]
    rgb = np.zeros((hh, ww, 3), np.float32)
    alpha = np.zeros((hh, ww), np.float32)
    depth = np.full((hh, ww), np.inf, np.float32)
    for i in range(nv):
        for j in range(nu):
            src = np.float32([[ue[j] - 0.5, ve[i] - 0.5], [ue[j + 1] - 0.5, ve[i] - 0.5],
                              [ue[j + 1] - 0.5, ve[i + 1] - 0.5], [ue[j] - 0.5, ve[i + 1] - 0.5]])
            dst = np.float32([pix[i, j], pix[i, j + 1], pix[i + 1, j + 1], pix[i + 1, j]]) - np.float32(r[:2])
            Hc = cv2.getPerspectiveTransform(src, dst)
            cell = cv2.warpPerspective(rgba, Hc, (ww, hh), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
            poly = np.zeros((hh, ww), np.uint8)
            cv2.fillConvexPoly(poly, np.round(dst * 16).astype(np.int32), 1, lineType=cv2.LINE_8, shift=4)
            z = float(np.mean(q[i:i + 2, j:j + 2, 2]))
            take = (poly > 0) & (cell[..., 3] > 0) & (z < depth)
            rgb[take] = cell[..., :3][take]
            alpha[take] = cell[..., 3][take]
            depth[take] = z
    return Warp(rgb, alpha, depth, r)


@dataclass(frozen=True, eq=False)
class RenderInfo:
    """Per-pixel information of :func:`render_view`.

    Attributes
    ----------
    part : ndarray of shape (H, W), uint8
        Part id of the front-most fan drawn at each pixel (0 = none).
    depth : ndarray of shape (H, W), float32
        Its depth in metres (inf = none).
    """

    part: np.ndarray
    depth: np.ndarray


def render_view(model: BillboardModel, camera: Camera,
                sigma: float = PAIR_ANGLE_SIGMA) -> tuple[np.ndarray, np.ndarray, RenderInfo]:
    """Composite a billboard model into a view (reference CPU path).

    Parameters
    ----------
    model : BillboardModel
    camera : Camera
        The output view (a source view: its corrected camera from ``model.rig``).
    sigma : float
        σ of the camera weight ω(β), radians.

    Returns
    -------
    rgb : ndarray of shape (H, W, 3), float32, 0..255
    alpha : ndarray of shape (H, W), float32
    info : RenderInfo
    """
    W, H = camera.size
    rgb = np.zeros((H, W, 3), np.float32)
    alpha = np.zeros((H, W), np.float32)
    part = np.zeros((H, W), np.uint8)
    depth = np.full((H, W), np.inf, np.float32)
    order = sorted(model.fans, key=lambda f: -float(camera.depth_of(f.axis.mean(axis=0))))
    for fan in order:
        mid = fan.axis.mean(axis=0)
        dv = mid - camera.center
        dv /= np.linalg.norm(dv)
        warps, weights = [], []
        for bb in fan.billboards:
            c = model.rig[bb.camera].center
            ds = mid - c
            ds /= np.linalg.norm(ds)
            beta = float(np.arccos(np.clip(dv @ ds, -1, 1)))
            wp = warp_billboard(bb, camera, roi=None)
            if not wp.empty:
                warps.append(wp)
                weights.append(np.exp(-beta ** 2 / (2 * sigma ** 2)))
        if not warps:
            continue
        x0 = min(w.roi[0] for w in warps)
        y0 = min(w.roi[1] for w in warps)
        x1 = max(w.roi[2] for w in warps)
        y1 = max(w.roi[3] for w in warps)
        acc = np.zeros((y1 - y0, x1 - x0, 3), np.float32)
        wsum = np.zeros((y1 - y0, x1 - x0), np.float32)
        asum = np.zeros_like(wsum)
        zmin = np.full_like(wsum, np.inf)
        for wp, om in zip(warps, weights):
            sl = (slice(wp.roi[1] - y0, wp.roi[3] - y0), slice(wp.roi[0] - x0, wp.roi[2] - x0))
            wa = wp.alpha * om
            acc[sl] += wp.rgb * wa[..., None]
            wsum[sl] += wa
            asum[sl] += om * (wp.alpha > 0)
            zmin[sl] = np.minimum(zmin[sl], wp.depth)
        with np.errstate(invalid="ignore", divide="ignore"):
            col = np.where(wsum[..., None] > 0, acc / wsum[..., None], 0.0)
            a = np.where(asum > 0, wsum / asum, 0.0)
        a = np.clip(a, 0, 1).astype(np.float32)
        sl = (slice(y0, y1), slice(x0, x1))
        # front fan over what is already drawn (fans come back to front)
        rgb[sl] = col * a[..., None] + rgb[sl] * (1 - a[..., None])
        alpha[sl] = a + alpha[sl] * (1 - a)
        front = a > 0.5
        part[sl][front] = fan.part
        depth[sl][front] = zmin[front]
    return rgb, alpha, RenderInfo(part=part, depth=depth)
