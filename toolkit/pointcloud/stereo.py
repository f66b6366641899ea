"""Point clouds from trinocular stereo heads (issue 18; source 002, "data acquisition").

A trinocular head (``layout = "trinocular"`` of the scene generator, see
:func:`toolkit.synthetic.rigs.make_rig`) is three cameras ``3k, 3k+1, 3k+2``:
a reference, one to its right and one above it, 0.2-0.4 m apart.  Per head:

1. the reference/right pair is **rectified** with :func:`cv2.stereoRectify`
   from the rig's calibration (:func:`rectify_pair`);
2. OpenCV's **semi-global matcher** (:class:`cv2.StereoSGBM`, a correlation
   (Birchfield-Tomasi block cost) matcher with a smoothness term: the
   "simple correlation-based algorithm" of the source, maintained and fast)
   gives a disparity per rectified pixel, with its uniqueness test, speckle
   filter and a left-right check (``disp12MaxDiff``) (:func:`disparity_map`);
3. disparities are **triangulated** to the reference camera with the
   rectification's ``Q`` (:func:`cv2.reprojectImageTo3D`) and moved to the
   world (metres, z up), only where the reference sees the subject (a
   foreground mask: the ground truth, a given mask or background subtraction
   against the clean plate, chosen by the caller);
4. the **third camera validates** every match (trinocular consistency): the
   reference/up pair is matched the same way on images turned 90 degrees
   (:func:`rotated_camera`: a vertical baseline becomes a horizontal one), and
   a point of the horizontal pair is kept only where the vertical pair found
   the same depth at its reference pixel (:func:`depth_agreement`); the two
   depths are averaged (:func:`head_cloud`).

The result is a raw, noisy cloud; :mod:`toolkit.pointcloud.patches` reduces it
to robust surface patches.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError

__all__ = ["RectifiedPair", "StereoCloud", "StereoConfig", "depth_agreement", "disparity_map", "head_cloud",
           "head_pairs", "pair_cloud", "rectify_pair", "rotated_camera", "trinocular_heads"]


@dataclass(frozen=True)
class StereoConfig:
    """Options of the stereo matcher and the trinocular check.

    Parameters
    ----------
    block_size : int
        SGBM matching block side, pixels (odd, 3-11).
    min_depth_m, max_depth_m : float
        Depth range searched (sets the disparity range per pair), metres.
    uniqueness_ratio : int
        SGBM: the best match must beat the second by this percentage.
    speckle_window : int
        SGBM speckle filter: largest blob (pixels) of disparities removed as noise (0: off).
    speckle_range : int
        SGBM speckle filter: disparity variation within a blob (in 1/16 px units / 16).
    lr_max_diff : int
        SGBM left-right check tolerance, pixels (-1: off).
    agreement_px : float
        Trinocular check: largest depth difference between the two pairs of a head, in
        disparity pixels (``agreement_px * z^2 / (f b)`` metres at depth ``z``).
    mask_erode_px : int
        The reference mask is eroded by this many pixels (silhouette-edge matches are the worst).
    """

    block_size: int = 5
    min_depth_m: float = 1.0
    max_depth_m: float = 8.0
    uniqueness_ratio: int = 10
    speckle_window: int = 50
    speckle_range: int = 2
    lr_max_diff: int = 1
    agreement_px: float = 1.0
    mask_erode_px: int = 1

    def __post_init__(self):
        if not (isinstance(self.block_size, int) and self.block_size % 2 == 1 and 3 <= self.block_size <= 11):
            raise InputError("StereoConfig.block_size", "an odd integer from 3 to 11", repr(self.block_size))
        if not 0 < self.min_depth_m < self.max_depth_m:
            raise InputError("StereoConfig.min_depth_m/max_depth_m", "0 < min_depth_m < max_depth_m",
                             f"{self.min_depth_m!r}, {self.max_depth_m!r}")
        if not self.agreement_px > 0:
            raise InputError("StereoConfig.agreement_px", "a value > 0 (inf: no check)", repr(self.agreement_px))
        if self.mask_erode_px < 0:
            raise InputError("StereoConfig.mask_erode_px", "a value >= 0", repr(self.mask_erode_px))


def trinocular_heads(rig: Rig) -> list[tuple[Camera, Camera, Camera]]:
    """The heads of a trinocular rig: cameras ``(3k, 3k+1, 3k+2)`` = (reference, right, up).

    Raises
    ------
    InputError
        A rig whose camera count is not a multiple of 3, or whose second camera of a
        head is not to the right of its reference (not a trinocular rig).
    """
    cams = list(rig)
    if not cams or len(cams) % 3:
        raise InputError("calibration: cameras", "3 cameras per trinocular head (reference, right, up)",
                         f"{len(cams)} cameras")
    heads = []
    for k in range(0, len(cams), 3):
        ref, right, up = cams[k:k + 3]
        base = ref.R @ (right.center - ref.center)  # the right camera in the reference's frame
        if base[0] <= 0.5 * np.linalg.norm(base) or ref.size != right.size or ref.size != up.size:
            raise InputError(f"calibration: cameras {ref.name}, {right.name}, {up.name}",
                             "a trinocular head: the second camera to the right of the first, equal image sizes",
                             f"baseline {np.round(base, 3).tolist()} m in {ref.name}'s frame")
        heads.append((ref, right, up))
    return heads


@dataclass(frozen=True)
class RectifiedPair:
    """A rectified camera pair (OpenCV's :func:`cv2.stereoRectify`, zero-disparity principal points).

    Attributes
    ----------
    left, right : Camera
        The pair (``right`` along ``left``'s +x axis).
    maps_left, maps_right : tuple of ndarray of shape (H, W), float32
        ``cv2.remap`` maps of each image into the rectified frame.
    R1 : ndarray of shape (3, 3)
        Rotation from ``left``'s camera frame to the rectified left frame.
    Q : ndarray of shape (4, 4)
        Disparity-to-depth matrix (rectified left frame, metres).
    focal_px, baseline_m : float
        Rectified focal length (pixels) and baseline (metres).
    """

    left: Camera
    right: Camera
    maps_left: tuple
    maps_right: tuple
    R1: np.ndarray
    Q: np.ndarray
    focal_px: float
    baseline_m: float


def rectify_pair(left: Camera, right: Camera) -> RectifiedPair:
    """Rectify two calibrated cameras of the same image size (``right`` to the right of ``left``)."""
    R = right.R @ left.R.T  # x_right = R x_left + T (OpenCV's convention)
    T = (right.t - R @ left.t).reshape(3, 1)
    size = tuple(int(v) for v in left.size)
    K1, K2 = np.array(left.K, np.float64), np.array(right.K, np.float64)
    d1, d2 = np.array(left.dist, np.float64).reshape(-1, 1), np.array(right.dist, np.float64).reshape(-1, 1)
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(K1, d1, K2, d2, size, np.array(R, np.float64), T,
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
    m1 = cv2.initUndistortRectifyMap(K1, d1, R1, P1, size, cv2.CV_32FC1)
    m2 = cv2.initUndistortRectifyMap(K2, d2, R2, P2, size, cv2.CV_32FC1)
    return RectifiedPair(left, right, m1, m2, R1, Q, float(P1[0, 0]), float(np.linalg.norm(T)))


def _disparity_range(pair: RectifiedPair, config: StereoConfig) -> tuple[int, int]:
    """``(minDisparity, numDisparities)`` covering the config's depth range (numDisparities a multiple of 16)."""
    fb = pair.focal_px * pair.baseline_m
    lo = int(np.floor(fb / config.max_depth_m))
    hi = int(np.ceil(fb / config.min_depth_m))
    return lo, max(16, int(np.ceil((hi - lo) / 16.0)) * 16)


def disparity_map(rect_left: np.ndarray, rect_right: np.ndarray, pair: RectifiedPair,
                  config: StereoConfig | None = None) -> np.ndarray:
    """Disparities of a rectified pair by OpenCV's semi-global matcher.

    Parameters
    ----------
    rect_left, rect_right : ndarray of shape (H, W, 3) or (H, W), uint8
        Rectified images.
    pair : RectifiedPair
    config : StereoConfig, optional

    Returns
    -------
    ndarray of shape (H, W), float32
        Disparity in pixels (``x_left - x_right``), NaN where no reliable match.
    """
    cfg = config or StereoConfig()
    lo, num = _disparity_range(pair, cfg)
    ch = 1 if rect_left.ndim == 2 else rect_left.shape[2]
    b = cfg.block_size
    sgbm = cv2.StereoSGBM_create(minDisparity=lo, numDisparities=num, blockSize=b, P1=8 * ch * b * b,
                                 P2=32 * ch * b * b, disp12MaxDiff=cfg.lr_max_diff,
                                 uniquenessRatio=cfg.uniqueness_ratio, speckleWindowSize=cfg.speckle_window,
                                 speckleRange=cfg.speckle_range, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    # SGBM gives no disparity in the left image's first lo + num columns (their matches could lie left of
    # the right image); padding both images there keeps that band: on the vertical pair (images turned 90
    # degrees) it was the bottom third of the picture, the lower legs.
    pad = lo + num
    border = lambda im: cv2.copyMakeBorder(im, 0, 0, pad, 0, cv2.BORDER_CONSTANT, value=0)  # noqa: E731
    d = sgbm.compute(border(rect_left), border(rect_right))[:, pad:].astype(np.float32) / 16.0
    d[d < lo + 0.5] = np.nan  # OpenCV marks failures with minDisparity - 1
    return d


def pair_cloud(image_left: np.ndarray, image_right: np.ndarray, pair: RectifiedPair,
               mask_left: np.ndarray | None = None, config: StereoConfig | None = None):
    """Triangulated points of a rectified pair, in the world.

    Parameters
    ----------
    image_left, image_right : ndarray of shape (H, W, 3), uint8 RGB
    pair : RectifiedPair
    mask_left : ndarray of shape (H, W) of bool, optional
        Where the left camera sees the subject (points elsewhere are dropped).
    config : StereoConfig, optional

    Returns
    -------
    points : ndarray of shape (N, 3)
        World points, metres.
    pixels : ndarray of shape (N, 2)
        Their pixels in the (unrectified) left image.
    """
    cfg = config or StereoConfig()
    size = pair.left.size
    for name, img in (("image_left", image_left), ("image_right", image_right)):
        if img.shape[:2] != (size[1], size[0]):
            raise InputError(f"pair_cloud: {name}", f"an image of {size[0]}x{size[1]}",
                             f"{img.shape[1]}x{img.shape[0]}")
    rl = cv2.remap(image_left, *pair.maps_left, cv2.INTER_LINEAR)
    rr = cv2.remap(image_right, *pair.maps_right, cv2.INTER_LINEAR)
    disp = disparity_map(rl, rr, pair, cfg)
    if mask_left is not None:
        m = np.asarray(mask_left, np.uint8)
        if cfg.mask_erode_px:
            m = cv2.erode(m, np.ones((2 * cfg.mask_erode_px + 1,) * 2, np.uint8))
        disp[cv2.remap(m, *pair.maps_left, cv2.INTER_NEAREST) == 0] = np.nan
    ok = np.isfinite(disp)
    if not ok.any():
        return np.zeros((0, 3)), np.zeros((0, 2))
    xyz = cv2.reprojectImageTo3D(np.where(ok, disp, 0).astype(np.float32), pair.Q)[ok].astype(float)
    xyz = xyz[(xyz[:, 2] >= cfg.min_depth_m) & (xyz[:, 2] <= cfg.max_depth_m)]
    cam = xyz @ pair.R1  # rectified left frame -> left camera frame (R1.T applied to column vectors)
    world = (cam - pair.left.t) @ pair.left.R
    return world, pair.left.project(world)


def rotated_camera(camera: Camera) -> Camera:
    """The camera whose image is ``camera``'s turned 90 degrees clockwise (``cv2.ROTATE_90_CLOCKWISE``).

    Its x axis is the original's up (-y) axis, so a camera *above* the original is
    to the *right* of the turned one: a vertical pair becomes a horizontal pair
    for the matcher.  Pixel ``(u, v)`` of the original is ``(H - 1 - v, u)``;
    radial distortion is unchanged, the tangential terms turn with the axes
    (``p1' = p2, p2' = -p1``).
    """
    K = np.asarray(camera.K, float)
    w, h = camera.size
    Kr = np.array([[K[1, 1], 0.0, h - 1 - K[1, 2]], [0.0, K[0, 0], K[0, 2]], [0.0, 0.0, 1.0]])
    d = np.zeros(max(5, len(camera.dist)))
    d[:len(camera.dist)] = camera.dist
    d[2], d[3] = d[3], -d[2]
    T = np.array(camera.cam_from_world, float)
    T[:3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) @ T[:3]
    return Camera(camera.name, Kr, d, (h, w), T)


def _turned(image):
    return None if image is None else cv2.rotate(np.ascontiguousarray(image), cv2.ROTATE_90_CLOCKWISE)


def depth_agreement(points_a: np.ndarray, points_b: np.ndarray, camera: Camera, tolerance_m) -> tuple:
    """Points of one pair confirmed by another pair's points along the same pixel of ``camera``.

    Parameters
    ----------
    points_a, points_b : ndarray of shape (N, 3) and (M, 3)
        World points of the two pairs sharing the reference ``camera``, metres.
    camera : Camera
        The shared reference.
    tolerance_m : callable
        ``tolerance_m(z)`` (ndarray (N,) -> (N,)): the largest depth difference accepted at depth ``z``.

    Returns
    -------
    keep : ndarray of shape (N,) of bool
        Points of ``a`` whose pixel has a ``b`` point within the tolerance in depth.
    depth_b : ndarray of shape (N,)
        The ``b`` depth at each ``a`` point's pixel (NaN where none).
    """
    w, h = camera.size
    zmap = np.full((h, w), np.nan)
    if len(points_b):
        uv = np.round(camera.project(points_b)).astype(int)
        ok = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        zmap[uv[ok, 1], uv[ok, 0]] = camera.depth_of(points_b[ok])
    if not len(points_a):
        return np.zeros(0, bool), np.zeros(0)
    uv = np.round(camera.project(points_a)).astype(int)
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    zb = np.full(len(points_a), np.nan)
    zb[inside] = zmap[uv[inside, 1], uv[inside, 0]]
    za = camera.depth_of(points_a)
    with np.errstate(invalid="ignore"):
        keep = np.abs(za - zb) <= tolerance_m(za)
    return keep, zb


@dataclass(frozen=True)
class StereoCloud:
    """The cloud of one trinocular head in one frame.

    Attributes
    ----------
    points : ndarray of shape (N, 3)
        World points, metres (confirmed by the third camera).
    colours : ndarray of shape (N, 3), uint8
        Their colour in the reference image.
    n_matched : int
        Points the horizontal pair triangulated before the trinocular check.
    """

    points: np.ndarray
    colours: np.ndarray
    n_matched: int


def head_cloud(images, cameras, masks=None, config: StereoConfig | None = None, pairs=None) -> StereoCloud:
    """The stereo cloud of one trinocular head: two pairs that check each other.

    The reference/right pair and the reference/up pair (matched on images turned
    90 degrees, :func:`rotated_camera`) are triangulated separately; a point of the
    horizontal pair is kept when the vertical pair found the same depth at its
    reference pixel within ``config.agreement_px`` of disparity (the depth error
    of one disparity step, ``z^2 / (f b)``, times that), and its depth becomes
    the mean of the two.

    Parameters
    ----------
    images : sequence of 3 ndarray of shape (H, W, 3), uint8 RGB
        Reference, right and up images of one frame.
    cameras : sequence of 3 Camera
        The head (see :func:`trinocular_heads`).
    masks : sequence of 3 (ndarray of shape (H, W) of bool or None), optional
        The subject in each image (the reference's limits the matches).
    config : StereoConfig, optional
    pairs : tuple of 2 RectifiedPair, optional
        :func:`head_pairs` of ``cameras``, computed once per head by the caller.

    Returns
    -------
    StereoCloud
    """
    cfg = config or StereoConfig()
    if len(images) != 3 or len(cameras) != 3:
        raise InputError("head_cloud", "3 images and 3 cameras (reference, right, up)",
                         f"{len(images)} images, {len(cameras)} cameras")
    masks = list(masks) if masks is not None else [None, None, None]
    ph, pv = pairs or head_pairs(cameras)
    ref = cameras[0]
    pts_h, uv = pair_cloud(images[0], images[1], ph, masks[0], cfg)
    pts_v, _ = pair_cloud(_turned(images[0]), _turned(images[2]), pv, _turned(masks[0]), cfg)
    step = 1.0 / min(ph.focal_px * ph.baseline_m, pv.focal_px * pv.baseline_m)  # depth of one px at 1 m, / m
    keep, zv = depth_agreement(pts_h, pts_v, ref, lambda z: cfg.agreement_px * step * z * z)
    z = 0.5 * (ref.depth_of(pts_h[keep]) + zv[keep])
    pts = ref.backproject(uv[keep], z)
    ij = np.round(uv[keep]).astype(int)
    cols = images[0][ij[:, 1].clip(0, ref.height - 1), ij[:, 0].clip(0, ref.width - 1)]
    return StereoCloud(pts, np.asarray(cols, np.uint8).reshape(-1, 3), len(pts_h))


def head_pairs(cameras) -> tuple[RectifiedPair, RectifiedPair]:
    """The rectified reference/right pair and the (turned) reference/up pair of a head."""
    return rectify_pair(cameras[0], cameras[1]), rectify_pair(rotated_camera(cameras[0]), rotated_camera(cameras[2]))
