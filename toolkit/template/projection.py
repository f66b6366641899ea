"""The pre-segmented body template, posed and projected (source 000 §2.2-2.3).

The template is the synthetic body's volumes (:class:`toolkit.body.model.BodyModel`
with a generic, average shape) whose triangles carry part ids.  Posed on a 3D
pose, it is ray cast in a camera into a part-label image and a depth image.

Thinning and thickening (the *slightly thinned and thickened template* of
§2.3) are done in the image, on the projected labels: the thin projection
keeps a pixel of part ``p`` when every pixel within ``radius`` of it belongs
to ``p`` (per-part erosion, so pixels near part borders and near the outline
drop out); the thick projection gives a pixel to the *front-most* part whose
mask, dilated by ``radius``, covers it (per-part dilation, occlusions resolved
by the template's depth).  The radius is a fraction of the subject's image
height (:data:`THIN_THICK_FRACTION`), so it means the same on a 100 px
broadcast subject and a 600 px studio subject.  Image-space morphology was
chosen over scaling the template's radii because it also shrinks parts along
the bone (at joints, where neighbouring parts meet) and costs one ray cast
instead of two; ``docs/stage2_segmentation.md`` has the measured effect of
the radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import open3d as o3d

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14
from toolkit.body.model import BodyModel, BodyShape

#: Thinning / thickening radius as a fraction of the subject's image height
#: (measured, see docs/stage2_segmentation.md): 0.01 = 2 px on a 200 px subject.
THIN_THICK_FRACTION = 0.01
#: Per part, the thinning radius is at most this fraction of the part's largest
#: inscribed radius in the image, so narrow parts (forearms of a 100 px broadcast
#: subject) keep their centre line (measured, see docs/stage2_segmentation.md).
THIN_PART_FRACTION = 0.5
#: Smallest thinning / thickening radius, pixels.
MIN_RADIUS_PX = 1
#: Number of body parts (label ids 1..N_PARTS).
N_PARTS = len(SKELETON_14.parts)
#: Tessellation of the template mesh (fraction of the synthetic body's default detail).
TEMPLATE_DETAIL = 0.5


@dataclass(frozen=True)
class TemplateProjection:
    """A posed template seen by one camera.

    Attributes
    ----------
    labels : ndarray of shape (H, W), uint8
        Part id of the nearest template surface (0 = none).
    depth : ndarray of shape (H, W), float32
        Camera-frame z of the nearest template surface, metres (NaN = none).
    thin : ndarray of shape (H, W), uint8
        Thinned labels (per-part erosion by ``radius_px``).
    thick : ndarray of shape (H, W), uint8
        Thickened labels (per-part dilation, front-most part wins).
    part_depth : ndarray of shape (N_PARTS,)
        Median camera depth of each part's visible pixels, metres (NaN = not visible).
    radius_px : int
        Thinning / thickening radius used.
    height_px : float
        Image height of the subject (projected joints' vertical extent plus head), pixels.
    """

    labels: np.ndarray
    depth: np.ndarray
    thin: np.ndarray
    thick: np.ndarray
    part_depth: np.ndarray
    radius_px: int
    height_px: float


def disc(radius: int) -> np.ndarray:
    """Elliptical structuring element of radius ``radius`` pixels, (2r+1, 2r+1) uint8."""
    r = max(0, int(radius))
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def subject_height_px(joints3d: np.ndarray, camera: Camera) -> float:
    """Vertical image extent of the projected joints, scaled to include the head top and soles (pixels)."""
    uv = camera.project(np.asarray(joints3d, float))
    v = uv[np.isfinite(uv).all(1), 1]
    if len(v) < 2:
        return 0.0
    # joints span from the head joint (ear level) to the ankles: about 0.90 of stature
    return float((v.max() - v.min()) / 0.90)


class Template:
    """A generic pre-segmented body template.

    Parameters
    ----------
    height : float
        Stature of the template body, metres (its part radii scale with it).
    detail : float
        Mesh tessellation (see :class:`toolkit.body.model.BodyModel`).
    """

    def __init__(self, height: float = 1.75, detail: float = TEMPLATE_DETAIL):
        if not 0.5 < float(height) < 3.0:
            raise InputError("Template: height", "a stature in metres (0.5, 3.0)", repr(height))
        self.height = float(height)
        self.model = BodyModel(BodyShape(BodyProportions.from_height(self.height)), rng=0, detail=detail)

    def mesh(self, joints3d: np.ndarray):
        """The template posed on ``joints3d`` (14, 3): a :class:`toolkit.body.model.BodyMesh`."""
        return self.model.mesh(joints3d)

    def render(self, joints3d: np.ndarray, camera: Camera, margin_px: int = 4,
               mesh=None) -> tuple[np.ndarray, np.ndarray]:
        """Ray-cast the posed template: part labels (H, W) uint8 and depth (H, W) float32 metres.

        Only the pixels of the box around the projected mesh (plus ``margin_px``) are cast.
        ``mesh``: :meth:`mesh` of ``joints3d`` when the caller has it already (one pose seen by
        several cameras).
        """
        mesh = self.mesh(joints3d) if mesh is None else mesh
        w, h = camera.size
        labels = np.zeros((h, w), np.uint8)
        depth = np.full((h, w), np.nan, np.float32)
        uv = camera.project(mesh.vertices)
        uv = uv[np.isfinite(uv).all(1)]
        if len(uv) == 0:
            return labels, depth
        x0 = int(max(0, np.floor(uv[:, 0].min()) - margin_px))
        x1 = int(min(w - 1, np.ceil(uv[:, 0].max()) + margin_px))
        y0 = int(max(0, np.floor(uv[:, 1].min()) - margin_px))
        y1 = int(min(h - 1, np.ceil(uv[:, 1].max()) + margin_px))
        if x1 < x0 or y1 < y0:
            return labels, depth
        u, v = np.meshgrid(np.arange(x0, x1 + 1, dtype=np.float64), np.arange(y0, y1 + 1, dtype=np.float64))
        n = camera.undistort_points(np.stack([u, v], -1))
        d = np.concatenate([n, np.ones(n.shape[:-1] + (1,))], -1) @ camera.R  # t_hit = camera z
        o = np.broadcast_to(camera.center, d.shape)
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                            o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
        ans = scene.cast_rays(o3d.core.Tensor(np.concatenate([o, d], -1).astype(np.float32)))
        t = ans["t_hit"].numpy()
        pid = ans["primitive_ids"].numpy().astype(np.int64)
        hit = np.isfinite(t)
        sub_l = np.zeros(t.shape, np.uint8)
        sub_l[hit] = mesh.triangle_parts[pid[hit]]
        labels[y0:y1 + 1, x0:x1 + 1] = sub_l
        depth[y0:y1 + 1, x0:x1 + 1] = np.where(hit, t, np.nan)
        return labels, depth

    def project(self, joints3d: np.ndarray, camera: Camera, fraction: float = THIN_THICK_FRACTION,
                radius_px: int | None = None) -> TemplateProjection:
        """Pose, ray-cast, thin and thicken the template.

        Parameters
        ----------
        joints3d : ndarray of shape (14, 3)
            World, metres (the exact fit for this camera).
        camera : Camera
            Corrected by stage 1's offsets (:func:`toolkit.multiview.corrected_rig`).
        fraction : float
            Thinning / thickening radius as a fraction of the subject's image height.
        radius_px : int, optional
            Explicit radius in pixels (overrides ``fraction``).

        Returns
        -------
        TemplateProjection
        """
        J = np.asarray(joints3d, float)
        if J.shape != (14, 3) or not np.isfinite(J).all():
            raise InputError("Template.project: joints3d", "a finite array of shape (14, 3)", f"shape {J.shape}")
        labels, depth = self.render(J, camera)
        hpx = subject_height_px(J, camera)
        r = int(radius_px) if radius_px is not None else max(MIN_RADIUS_PX, int(round(fraction * hpx)))
        thin, thick = thin_thick(labels, depth, r)
        part_depth = np.full(N_PARTS, np.nan)
        for p in range(1, N_PARTS + 1):
            sel = labels == p
            if sel.any():
                part_depth[p - 1] = float(np.median(depth[sel]))
        return TemplateProjection(labels, depth, thin, thick, part_depth, r, hpx)


def _box(mask: np.ndarray, pad: int, shape) -> tuple[slice, slice] | None:
    ys, xs = np.nonzero(mask)
    if len(ys) == 0:
        return None
    h, w = shape
    return (slice(max(0, ys.min() - pad), min(h, ys.max() + pad + 1)),
            slice(max(0, xs.min() - pad), min(w, xs.max() + pad + 1)))


def thin_thick(labels: np.ndarray, depth: np.ndarray, radius: int) -> tuple[np.ndarray, np.ndarray]:
    """Thinned and thickened part-label images.

    Parameters
    ----------
    labels : ndarray of shape (H, W), uint8
        Part ids (0 = none).
    depth : ndarray of shape (H, W), float
        Camera depth of the labelled surface, metres (NaN where unlabelled).
    radius : int
        Structuring-element radius, pixels (0 = no change).

    Returns
    -------
    thin, thick : ndarray of shape (H, W), uint8
        ``thin``: pixels of part p whose whole disc of radius
        ``min(radius, THIN_PART_FRACTION * inscribed radius of p)`` is part p.
        ``thick``: per pixel, of the parts whose dilated mask covers it, the
        one with the nearest (dilated, i.e. local minimum) depth.
    """
    L = np.asarray(labels)
    if L.ndim != 2:
        raise InputError("thin_thick: labels", "an (H, W) label image", f"shape {L.shape}")
    if radius <= 0:
        return L.copy(), L.copy()
    k = disc(radius)
    box = _box(L > 0, radius + 2, L.shape)
    thin = np.zeros_like(L)
    thick = np.zeros_like(L)
    if box is None:
        return thin, thick
    Lb = L[box]
    Db = np.where(Lb > 0, np.nan_to_num(np.asarray(depth, np.float32)[box], nan=1e6), 1e6).astype(np.float32)
    best = np.full(Lb.shape, np.inf, np.float32)
    tb = np.zeros_like(Lb)
    kb = np.zeros_like(Lb)
    for p in np.unique(Lb[Lb > 0]):
        m = (Lb == p).astype(np.uint8)
        # erode with pixels outside the image counted as "not p" (border value 0), by at most
        # THIN_PART_FRACTION of the part's inscribed radius
        inscribed = float(cv2.distanceTransform(np.pad(m, 1), cv2.DIST_L2, 3).max())
        rp = int(min(radius, max(0, np.floor(THIN_PART_FRACTION * inscribed))))
        er = cv2.erode(m, disc(rp), borderType=cv2.BORDER_CONSTANT, borderValue=0) if rp > 0 else m
        tb[er > 0] = p
        dil = cv2.dilate(m, k) > 0
        dp = cv2.erode(np.where(m > 0, Db, np.float32(1e6)), k)  # local minimum depth of part p
        take = dil & (dp < best)
        kb[take] = p
        best[take] = dp[take]
    thin[box] = tb
    thick[box] = kb
    return thin, thick
