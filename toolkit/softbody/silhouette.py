"""Silhouette observations from the cameras (source 002's optional term, Plänkers & Fua).

Point clouds from stereo miss what the matcher cannot match (thin limbs, plain
cloth), while the subject's foreground mask in each camera still outlines the
whole body.  Two residual blocks per camera and frame, both in metres:

* **outline rays**: points on the mask's outline (``cv2.findContours``,
  spaced ``step_px`` apart, moved half a pixel outwards onto the boundary)
  give camera rays that must graze the model: the residual of a ray is the
  minimum over the ray of the model's distance
  (:func:`toolkit.softbody.distance.distance`), zero when it touches the
  surface, positive when it misses it, negative when it cuts through.  By
  the envelope theorem its derivative with respect to the parameters is the
  distance's derivative at the ray's nearest point (the derivative along
  the ray is zero there), so the Jacobian is exact and analytic.
* **mask**: points on the model's surface (the metaballs' samples of
  :func:`toolkit.softbody.residuals.coverage_samples`, not buried in other
  metaballs) projected into the image must fall in the mask: the residual is
  the distance transform of the mask's outside (``cv2.distanceTransform``,
  pixels, less ``mask_margin_px``) at the projection, bilinearly
  interpolated, times the point's depth over the focal length; its Jacobian
  chains the interpolant's gradient, the projection's
  (``cv2.projectPoints``: lens distortion included) and the surface point's
  (:meth:`~toolkit.softbody.residuals.CoverageSamples.jacobian`).

Both use Cauchy losses (outlines are noisy, a second person or an occluder
has outlines too); the rays whose residual at the start pose exceeds ``gate``
(another body's outline, specks) are left out of that fit, as the tracker
leaves out points far from the model.

Masks come from the run's own foreground step (the stereo heads' masks,
:mod:`toolkit.pipeline.soft_body_sources`) with the calibrated cameras
(:class:`toolkit.cameras.Camera`): a mask of another size than its camera's
image is refused; an empty mask (the subject not seen) or one without an
outline inside the image gives a view in an explicit state (``"empty"``,
``"no_outline"``) that adds no residual.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.observe import Observer
from toolkit.softbody.distance import distance, distance_and_jacobian
from toolkit.softbody.model import ModelState, SoftBodyModel, SoftBodyParams
from toolkit.softbody.residuals import CoverageSamples, coverage_samples, robust

__all__ = ["project_jacobian", "mask_edge_offset", "edge_offset", "SilhouetteConfig", "SilhouetteView", "SilhouetteBlock", "VIEW_STATES", "silhouette_views",
           "ray_minimum", "model_mask", "report_silhouettes"]

#: States of one camera's silhouette in one frame.
VIEW_STATES = ("ok", "empty", "no_outline")


@dataclass(frozen=True)
class SilhouetteConfig:
    """Settings of the silhouette blocks.

    Attributes
    ----------
    step_px : float
        Spacing of the outline points along the mask's contours, pixels.
    max_outline : int
        Outline points per view at most (an even subsample).
    border_px : float
        Outline points this close to the image border are left out (the subject cut by the frame).
    min_contour_px : int
        Contours with fewer points are specks and left out.
    gate : float
        Rays whose residual at the start pose is beyond this (either sign) are left out of the fit, metres.
    scale : float
        Scale of the Cauchy losses, metres.
    mask_weight : float
        Weight of the mask block relative to the outline block.
    mask_margin_px : float
        Model points projecting less than this outside the mask count as inside (the mask's noise), pixels.
    sample_dirs : int
        Surface points per metaball considered for the mask block.
    ray_tol : float
        Precision of each ray's least distance along the ray, metres (:func:`ray_minimum`).
    edge_search_px : float
        With the camera's image given (:class:`SilhouetteView`), the outline is moved onto the image's
        edge: along each outline point's normal, within this many pixels either side, the strongest
        colour gradient; the median offset over the outline (:attr:`SilhouetteView.edge_offset_px`) moves
        every outline point (0: not moved).  Foreground masks found by background subtraction are fatter
        than the subject (blurred, compressed edges): on the trinocular benchmark the clean-plate masks
        held 15-20 % more pixels than the true silhouettes, their outline 1.5 px outside the image's
        edge (the true masks' within 0.5 px), and outline rays that had to graze the model stretched it
        (the head 10-30 mm high, the ankles 15-40 mm low after the global fit).
    min_edge_points : int
        Fewest outline points with a clear edge (a gradient peak above twice the median gradient inside
        the mask) for the offset to be measured; fewer: the outline stays (a low-contrast view).
    """

    step_px: float = 3.0
    max_outline: int = 200
    border_px: float = 2.0
    min_contour_px: int = 12
    gate: float = 0.1
    scale: float = 0.02
    mask_weight: float = 1.0
    mask_margin_px: float = 1.0
    sample_dirs: int = 16
    ray_tol: float = 1e-4
    edge_search_px: float = 3.0
    min_edge_points: int = 30

    def __post_init__(self):
        for name in ("step_px", "gate", "scale"):
            if not getattr(self, name) > 0:
                raise InputError(f"SilhouetteConfig.{name}", "a positive number", repr(getattr(self, name)))
        if not self.edge_search_px >= 0:
            raise InputError("SilhouetteConfig.edge_search_px", "a number of pixels >= 0", repr(self.edge_search_px))
        if self.max_outline < 1 or self.sample_dirs < 1:
            raise InputError("SilhouetteConfig.max_outline/sample_dirs", "positive counts",
                             f"{self.max_outline}, {self.sample_dirs}")


def _outline(mask: np.ndarray, config: SilhouetteConfig) -> tuple[np.ndarray, np.ndarray]:
    """Outline points of a mask (K, 2) pixels (x, y), on the boundary between mask and background, and their
    outward unit normals (K, 2)."""
    u8 = mask.astype(np.uint8)
    contours, _ = cv2.findContours(u8, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    h, w = mask.shape
    out = []
    for c in contours:
        c = c[:, 0, :].astype(float)
        if len(c) < config.min_contour_px:
            continue
        # outward normal from the tangent over +-2 contour points, oriented away from the mask
        tang = np.roll(c, -2, axis=0) - np.roll(c, 2, axis=0)
        nrm = np.stack([tang[:, 1], -tang[:, 0]], 1)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-9)
        probe = np.round(c + 1.5 * nrm).astype(int)
        inside = (probe[:, 0] >= 0) & (probe[:, 0] < w) & (probe[:, 1] >= 0) & (probe[:, 1] < h)
        inside[inside] = mask[probe[inside, 1], probe[inside, 0]]
        nrm[inside] *= -1
        pts = np.hstack([c + 0.5 * nrm, nrm])
        pts = pts[np.arange(0, len(pts), max(1, int(round(config.step_px))))]
        out.append(pts)
    if not out:
        return np.zeros((0, 2)), np.zeros((0, 2))
    pts = np.concatenate(out)
    b = config.border_px
    ok = (pts[:, 0] >= b) & (pts[:, 0] <= w - 1 - b) & (pts[:, 1] >= b) & (pts[:, 1] <= h - 1 - b)
    pts = pts[ok]
    if len(pts) > config.max_outline:
        pts = pts[np.linspace(0, len(pts) - 1, config.max_outline).round().astype(int)]
    return pts[:, :2], pts[:, 2:]


def edge_offset(image: np.ndarray, mask: np.ndarray, outline: np.ndarray, normals: np.ndarray,
                config: SilhouetteConfig) -> float:
    """How far the image's edge lies from a mask's outline, pixels along the outward normal (median).

    Parameters
    ----------
    image : ndarray of shape (H, W, 3) or (H, W)
        The camera's image the mask was found in (uint8 or float).
    mask : ndarray of shape (H, W) of bool
    outline, normals : ndarray of shape (K, 2)
        Outline points on the mask's boundary and their outward unit normals (pixels).
    config : SilhouetteConfig
        ``edge_search_px``, ``min_edge_points``.

    Returns
    -------
    float
        Negative: the edge lies inside the mask (a fat mask).  0 when fewer than ``min_edge_points``
        outline points have a clear edge within ``edge_search_px``.
    """
    r = float(config.edge_search_px)
    if r <= 0 or len(outline) == 0 or not mask.any():
        return 0.0
    g = cv2.GaussianBlur(np.asarray(image, np.float32), (3, 3), 0.7)
    gx, gy = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.sqrt(gx ** 2 + gy ** 2) if g.ndim == 2 else np.sqrt((gx ** 2 + gy ** 2).sum(-1))
    ts = np.arange(-r, r + 1e-9, 0.25)
    P = outline[:, None, :] + ts[None, :, None] * normals[:, None, :]
    h, w = mask.shape
    prof = cv2.remap(mag, np.clip(P[..., 0], 0, w - 1).astype(np.float32),
                     np.clip(P[..., 1], 0, h - 1).astype(np.float32), cv2.INTER_LINEAR)
    clear = prof.max(axis=1) > 2.0 * float(np.median(mag[mask]))
    if clear.sum() < config.min_edge_points:
        return 0.0
    return float(np.median(ts[np.argmax(prof[clear], axis=1)]))


def mask_edge_offset(image: np.ndarray, mask, config: SilhouetteConfig = SilhouetteConfig()) -> float:
    """:func:`edge_offset` of a mask's own outline (pixels; 0 for an empty mask): what a source measures
    once, when it finds the mask, so that it need not keep the image for :class:`SilhouetteView`."""
    m = np.asarray(mask) > 0
    if not m.any():
        return 0.0
    outline, normals = _outline(m, config)
    return edge_offset(np.asarray(image), m, outline, normals, config) if len(outline) else 0.0


class SilhouetteView:
    """One camera's silhouette of the subject in one frame.

    Parameters
    ----------
    camera : Camera
        Calibrated, world in metres.
    mask : ndarray of shape (H, W)
        The subject's foreground (bool, or nonzero = foreground), ``(H, W)`` the camera's image size.
    config : SilhouetteConfig
    image : ndarray of shape (H, W, 3) or (H, W), optional
        The image the mask was found in: the outline is moved onto its edge (:func:`edge_offset`).
    edge_offset_px : float, optional
        The offset measured already (:func:`mask_edge_offset`), used instead of measuring it on ``image``.
    unknown : ndarray of shape (H, W), optional
        Pixels outside the mask that may still be the subject (nonzero; e.g. a depth camera's readings
        just in front of the background, :func:`toolkit.pointcloud.ambiguous_mask`: the soles of feet
        on the floor): model points projecting there cost nothing, and outline points next to them
        (the mask's edge there need not be the body's) give no rays.

    Attributes
    ----------
    state : str
        One of :data:`VIEW_STATES`.
    outline : ndarray of shape (K, 2)
        Outline points, pixels (moved by ``edge_offset_px``).
    edge_offset_px : float
        How far the outline was moved along its outward normal to the image's edge (0: no image).
    origins, directions : ndarray of shape (K, 3)
        Their rays (the camera centre, unit directions), world.
    outside : ndarray of shape (H, W) float32
        Distance of each pixel to the mask, pixels (0 in the mask).

    Raises
    ------
    InputError
        If ``camera`` is not a Camera or ``mask`` is not of the camera's image size.
    """

    def __init__(self, camera: Camera, mask, config: SilhouetteConfig = SilhouetteConfig(), image=None,
                 unknown=None, edge_offset_px: float | None = None):
        if not isinstance(camera, Camera):
            raise InputError("silhouette camera", "a toolkit.cameras.Camera", type(camera).__name__)
        m = np.asarray(mask)
        w, h = camera.size
        if m.shape != (h, w):
            raise InputError(f"silhouette mask of camera {camera.name!r}", f"shape ({h}, {w}) (the camera's image)",
                             f"shape {m.shape}")
        m = m > 0
        u = np.zeros_like(m) if unknown is None else np.asarray(unknown)
        if u.shape != (h, w):
            raise InputError(f"silhouette unknown pixels of camera {camera.name!r}", f"shape ({h}, {w})",
                             f"shape {u.shape}")
        u = (u > 0) & ~m
        self.camera, self.config = camera, config
        self.focal = 0.5 * float(camera.K[0, 0] + camera.K[1, 1])
        self.outline, normals = _outline(m, config) if m.any() else (np.zeros((0, 2)), np.zeros((0, 2)))
        if u.any() and len(self.outline):
            # outline points whose outside (up to 2 px out) is unknown: not the body's edge for sure
            near = cv2.dilate(u.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
            q = np.clip(np.round(self.outline).astype(int), 0, [w - 1, h - 1])
            keep = ~near[q[:, 1], q[:, 0]]
            self.outline, normals = self.outline[keep], normals[keep]
        self.edge_offset_px = 0.0
        if edge_offset_px is not None and len(self.outline):
            if not np.isfinite(edge_offset_px):
                raise InputError(f"edge offset of camera {camera.name!r}", "a finite number of pixels",
                                 repr(edge_offset_px))
            self.edge_offset_px = float(edge_offset_px)
            self.outline = self.outline + self.edge_offset_px * normals
        elif image is not None and len(self.outline):
            im = np.asarray(image)
            if im.shape[:2] != (h, w):
                raise InputError(f"silhouette image of camera {camera.name!r}", f"shape ({h}, {w}[, 3])",
                                 f"shape {im.shape}")
            self.edge_offset_px = edge_offset(im, m, self.outline, normals, config)
            self.outline = self.outline + self.edge_offset_px * normals
        self.state = "empty" if not m.any() else "ok" if len(self.outline) else "no_outline"
        self.origins, self.directions = camera.rays(self.outline) if len(self.outline) else (np.zeros((0, 3)),) * 2
        self.outside = cv2.distanceTransform((~(m | u)).astype(np.uint8), cv2.DIST_L2, 5).astype(np.float32) \
            if m.any() else np.zeros((h, w), np.float32)

    def __repr__(self) -> str:
        return f"SilhouetteView({self.camera.name!r}, {self.state}, {len(self.outline)} outline points)"


def silhouette_views(cameras, masks, config: SilhouetteConfig = SilhouetteConfig(), unknowns=None,
                     edge_offsets=None) -> list:
    """The silhouettes of one frame: one :class:`SilhouetteView` per camera and mask (masks may be None: left out);
    ``edge_offsets``: per camera the mask's edge offset (pixels, :func:`mask_edge_offset`) or None (the outline
    stays); ``unknowns``: per camera the pixels that may still be the subject, or None."""
    cams, ms = list(cameras), list(masks)
    uns = [None] * len(cams) if unknowns is None else list(unknowns)
    offs = [None] * len(cams) if edge_offsets is None else list(edge_offsets)
    if not len(cams) == len(ms) == len(uns) == len(offs):
        raise InputError("silhouette masks, unknown pixels and edge offsets", f"one per camera ({len(cams)})",
                         f"{len(ms)}, {len(uns)}, {len(offs)}")
    return [SilhouetteView(c, m, config, unknown=un, edge_offset_px=off)
            for c, m, un, off in zip(cams, ms, uns, offs) if m is not None]


def _ray_candidates(st: ModelState, o: np.ndarray, d: np.ndarray, n: int) -> np.ndarray:
    """Per ray, the ray parameters (K, n) nearest (in each metaball's scaled axes) to its ``n`` closest metaballs."""
    inv_r = 1.0 / st.radii  # (P, 3)
    a = np.einsum("kj,pji->kpi", o, st.prim_R) - np.einsum("pj,pji->pi", st.centres, st.prim_R)[None]
    b = np.einsum("kj,pji->kpi", d, st.prim_R)
    a, b = a * inv_r[None], b * inv_r[None]
    s = -(a * b).sum(-1) / np.maximum((b * b).sum(-1), 1e-12)  # (K, P)
    q = np.sqrt(((a + s[..., None] * b) ** 2).sum(-1))
    rank = (q - 1.0) * st.radii.min(axis=1)[None]
    n = min(n, rank.shape[1])
    best = np.argpartition(rank, n - 1, axis=1)[:, :n]
    return np.take_along_axis(s, best, axis=1)


def ray_minimum(model: SoftBodyModel, params: SoftBodyParams, origins, directions, *,
                state: ModelState | None = None, candidates: int = 3, tol: float = 2e-5, max_iter: int = 30,
                start: np.ndarray | None = None, spacing: float = 0.02):
    """The minimum of the model's distance along each ray.

    Started at the points nearest to the ``candidates`` closest metaballs (in
    their scaled axes), or at ``start``, refined by parabolic steps on the
    distance sampled along the ray, the spacing (``spacing`` at first)
    shrinking once the minimum lies within it, down to ``tol``.

    Parameters
    ----------
    model, params
    origins, directions : ndarray of shape (K, 3)
        World, metres; unit directions.
    state : ModelState, optional
    candidates : int
    tol : float
        Last sampling spacing, metres.
    max_iter : int
        Parabolic steps at most.
    start : ndarray of shape (K,), optional
        Ray parameters to start from (a previous minimum: a fit's next evaluation), metres.
    spacing : float
        First sampling spacing, metres.

    Returns
    -------
    s : ndarray of shape (K,)
        Ray parameter of the minimum, metres from the origin.
    dmin : ndarray of shape (K,)
        The minimum distance, metres (negative: the ray cuts through the model).
    """
    o, d = np.asarray(origins, float).reshape(-1, 3), np.asarray(directions, float).reshape(-1, 3)
    st = model.state(params) if state is None else state
    if len(o) == 0:
        return np.zeros(0), np.zeros(0)
    s = _ray_candidates(st, o, d, candidates) if start is None else np.asarray(start, float).reshape(-1, 1).copy()
    k = len(o)
    val = distance(model, params, (o[:, None] + s[..., None] * d[:, None]).reshape(-1, 3), state=st).reshape(k, -1)
    i = np.argmin(val, axis=1)
    s, f0 = s[np.arange(k), i], val[np.arange(k), i]
    h = np.full(k, float(spacing))
    act = np.arange(k)  # rays still refined
    for _ in range(max_iter):
        oa, da, sa, ha, fa = o[act], d[act], s[act], h[act], f0[act]
        pts = np.concatenate([oa + (sa - ha)[:, None] * da, oa + (sa + ha)[:, None] * da])
        fm, fp = np.split(distance(model, params, pts, state=st), 2)
        curv = fm + fp - 2 * fa
        conv = curv > 1e-15
        step = np.where(conv, 0.5 * ha * (fm - fp) / np.where(conv, curv, 1.0), np.where(fm < fp, -2 * ha, 2 * ha))
        step = np.clip(step, -2 * ha, 2 * ha)
        f_new = distance(model, params, oa + (sa + step)[:, None] * da, state=st)
        better = f_new < fa
        s[act], f0[act] = np.where(better, sa + step, sa), np.where(better, f_new, fa)
        # the spacing shrinks once the minimum lies within it
        h[act] = np.where(np.abs(step) < ha, np.maximum(ha / 4, tol), ha)
        act = act[(h[act] > tol) | (np.abs(step) >= ha)]
        if len(act) == 0:
            break
    return s, f0


def model_mask(model: SoftBodyModel, params: SoftBodyParams, camera: Camera, *, tol: float = 2e-4) -> np.ndarray:
    """The model's own silhouette in a camera: pixels whose centre's ray meets the surface.

    Parameters
    ----------
    model, params
    camera : Camera
    tol : float
        Last spacing of :func:`ray_minimum` along the rays, metres.

    Returns
    -------
    ndarray of shape (H, W) bool
    """
    st = model.state(params)
    w, h = camera.size
    z = camera.depth_of(st.centres)
    front = z > 1e-3
    m = np.zeros((h, w), bool)
    if not front.any():
        return m
    uv = camera.project(st.centres[front])
    r = st.radii[front].max(1)[:, None] * camera.K[0, 0] / z[front][:, None]
    lo = np.maximum(np.floor((uv - r).min(0)).astype(int) - 2, 0)
    hi = np.minimum(np.ceil((uv + r).max(0)).astype(int) + 2, [w - 1, h - 1])
    if np.any(hi < lo):
        return m
    xs, ys = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    xs, ys = xs.ravel(), ys.ravel()
    o, d = camera.rays(np.stack([xs, ys], 1).astype(float))
    s = _ray_candidates(st, o, d, 1)[:, 0]
    near = distance(model, params, o + s[:, None] * d, state=st) < 0.05  # rays passing near a metaball
    _, dm = ray_minimum(model, params, o[near], d[near], state=st, tol=tol)
    m[ys[near], xs[near]] = dm < 0
    return m


def _bilinear(img: np.ndarray, uv: np.ndarray):
    """Bilinear values (N,) and gradients (N, 2) of an image at pixels (N, 2) (x, y) inside it."""
    h, w = img.shape
    x = np.clip(uv[:, 0], 0, w - 1 - 1e-9)
    y = np.clip(uv[:, 1], 0, h - 1 - 1e-9)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    ax, ay = x - x0, y - y0
    a, b = img[y0, x0], img[y0, x0 + 1]
    c, e = img[y0 + 1, x0], img[y0 + 1, x0 + 1]
    val = (1 - ay) * ((1 - ax) * a + ax * b) + ay * ((1 - ax) * c + ax * e)
    gx = (1 - ay) * (b - a) + ay * (e - c)
    gy = (1 - ax) * (c - a) + ax * (e - b)
    return val, np.stack([gx, gy], 1)


def project_jacobian(camera: Camera, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project world points and differentiate the projection (OpenCV's model, lens distortion included).

    Parameters
    ----------
    camera : Camera
    pts : ndarray of shape (N, 3)
        Metres, world.

    Returns
    -------
    uv : ndarray of shape (N, 2)
        Pixels.
    duv : ndarray of shape (N, 2, 3)
        Derivatives of the pixels in the world point, pixels per metre.
    depth : ndarray of shape (N,)
        Camera depths, metres.
    """
    pc = camera.to_cam(pts)
    uv, jac = cv2.projectPoints(pc.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, camera.dist)
    du_dpc = jac[:, 3:6].reshape(-1, 2, 3)  # the translation's columns: d pixel / d camera point
    return uv.reshape(-1, 2), du_dpc @ camera.R, pc[:, 2]


class SilhouetteBlock:
    """The silhouette residuals of one frame for one fit.

    The outline rays within ``config.gate`` of the start model and the model's
    surface samples are chosen once, at ``start`` (as the coverage block's samples).

    Parameters
    ----------
    model : SoftBodyModel
    start : SoftBodyParams
    views : sequence of SilhouetteView
        Views not in state ``"ok"`` are left out.
    config : SilhouetteConfig, optional
        Default: the first view's.

    Attributes
    ----------
    n_rays : int
        Outline rays kept.
    """

    def __init__(self, model: SoftBodyModel, start: SoftBodyParams, views, config: SilhouetteConfig | None = None):
        self.views = [v for v in views if v.state == "ok"]
        if config is None:
            config = self.views[0].config if self.views else SilhouetteConfig()
        self.model, self.config = model, config
        o = [v.origins for v in self.views]
        d = [v.directions for v in self.views]
        o = np.concatenate(o) if o else np.zeros((0, 3))
        d = np.concatenate(d) if d else np.zeros((0, 3))
        st = model.state(start)
        s0, r0 = ray_minimum(model, start, o, d, state=st, tol=config.ray_tol)
        keep = np.abs(r0) < config.gate
        self.origins, self.directions = o[keep], d[keep]
        self._s = s0[keep]  # each ray's last minimum: the next evaluation starts there
        self.n_rays = int(keep.sum())
        self.samples = coverage_samples(model, start, n_dirs=config.sample_dirs) if self.views \
            else CoverageSamples(np.zeros(0, int), np.zeros((0, 3)))

    def __len__(self) -> int:
        return self.n_rays + len(self.samples) * len(self.views)

    def residuals(self, params: SoftBodyParams, st: ModelState, columns: np.ndarray, with_jac: bool = True):
        """Robust residuals (R,) metres and their Jacobian (R, len(columns)) or None.

        Parameters
        ----------
        params : SoftBodyParams
        st : ModelState
            ``model.state(params)``.
        columns : ndarray of int
            Parameter columns of the Jacobian.
        with_jac : bool
        """
        c = self.config
        s, r = ray_minimum(self.model, params, self.origins, self.directions, state=st, tol=c.ray_tol,
                           start=self._s, spacing=0.005)
        self._s = s
        J = None
        if with_jac:
            x = self.origins + s[:, None] * self.directions
            J = distance_and_jacobian(self.model, params, x, state=st)[1][:, columns] if len(x) \
                else np.zeros((0, len(columns)))
        r, J = robust(r, J, "cauchy", c.scale)
        rm, Jm = self._mask(st, columns, with_jac)
        w = np.sqrt(c.mask_weight)
        return np.concatenate([r, w * rm]), (None if not with_jac else np.vstack([J, w * Jm]))

    def _mask(self, st: ModelState, columns: np.ndarray, with_jac: bool):
        c = self.config
        if not self.views or len(self.samples) == 0:
            return np.zeros(0), np.zeros((0, len(columns)))
        y = self.samples.points(st)
        Jy = self.samples.jacobian(self.model, st)[:, :, columns] if with_jac else None
        rs, Js = [], []
        for v in self.views:
            uv, duv, z = project_jacobian(v.camera, y)
            ok = (z > 1e-6) & v.camera.in_image(uv, margin=1.0) & np.isfinite(uv).all(axis=1)
            val, g = _bilinear(v.outside, np.where(ok[:, None], uv, 0.0))
            out = ok & (val > c.mask_margin_px)
            px = np.where(out, val - c.mask_margin_px, 0.0)
            r = px * z / v.focal
            rs.append(r)
            if with_jac:
                # d r / d y = (z / f) grad . du/dy + (px / f) dz/dy
                dr = (z / v.focal)[:, None] * np.einsum("ni,nij->nj", g, duv) \
                    + (px / v.focal)[:, None] * v.camera.R[2][None]
                dr *= out[:, None]
                Js.append(np.einsum("nj,njk->nk", dr, Jy))
        r = np.concatenate(rs)
        J = np.vstack(Js) if with_jac else None
        return robust(r, J, "cauchy", c.scale)


def report_silhouettes(observer: Observer, model: SoftBodyModel, params: SoftBodyParams, views, frame: int) -> None:
    """Report each view's outline points and their residuals (``silhouette`` reports) for one frame."""
    st = model.state(params)
    for v in views:
        if v.state != "ok":
            continue
        _, r = ray_minimum(model, params, v.origins, v.directions, state=st)
        observer.report("silhouette", camera=v.camera.name, points=v.outline, residuals=r, frame=frame,
                        name="softbody/silhouette")
