"""The user mask: given, or from a background depth model and connected components.

(:func:`foreground_mask` keeps every foreground component instead, for consumers
that tell the user from other people themselves.)

Foreground pixels are those with a reading clearly in front of the background
model (or any reading when there is no model).  Foreground pixels are grouped
into 8-connected components; the user is the component that overlaps the
previous user mask the most or, without one, the largest in metric area (pixel
counts depend on resolution and distance, square metres do not).  Nearby
smaller components at a similar depth (a hand cut off by a projector shadow) are
added to it.  Without a previous mask the user is the component with the most
pixels (usually the person nearest to the camera); components smaller than
``min_area_m2`` in metric area are never users.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.cameras import Camera
from toolkit.pointcloud.cloud import _check_depth
from toolkit.errors import InputError

__all__ = ["BackgroundModel", "MaskConfig", "UserMask", "ambiguous_mask", "foreground_mask", "user_mask"]


@dataclass(frozen=True)
class MaskConfig:
    """Settings of the user mask.

    Attributes
    ----------
    background_margin_m : float
        A pixel is foreground when it is this much (plus ``background_margin_rel``
        of the depth) in front of the background model.
    background_margin_rel : float
    min_area_m2 : float
        Smallest user component, square metres (a person seen from the front
        covers about 0.6 m^2).
    join_gap_m : float
        Components closer than this to the user (in the image, converted at the
        user's depth) are joined to it ...
    join_depth_m : float
        ... if their median depth is within this of the user's.
    min_join_area_m2 : float
        Smallest component worth joining.
    near_m, far_m : float
        Readings outside this range are ignored.
    ambiguous_margin_m, ambiguous_margin_rel : float
        :func:`ambiguous_mask`: a reading in front of the background by more than this (plus
        ``ambiguous_margin_rel`` of the depth; about three times the sensor's noise) but by less than the
        foreground margin cannot be told from the background: the soles of feet standing on the floor
        (the floor right behind them), a hand on a wall.
    """

    background_margin_m: float = 0.08
    background_margin_rel: float = 0.02
    min_area_m2: float = 0.04
    join_gap_m: float = 0.10
    join_depth_m: float = 0.5
    min_join_area_m2: float = 0.002
    near_m: float = 0.3
    far_m: float = 8.0
    ambiguous_margin_m: float = 0.02
    ambiguous_margin_rel: float = 0.01


class BackgroundModel:
    """Per-pixel depth of the empty scene.

    Parameters
    ----------
    depth : ndarray of shape (H, W)
        Background depth in metres, NaN where the sensor never saw anything.
    """

    def __init__(self, depth: np.ndarray):
        d = np.asarray(depth, np.float32)
        if d.ndim != 2:
            raise InputError("background depth", "an array of shape (H, W)", f"shape {d.shape}")
        self.depth = d

    @classmethod
    def from_frames(cls, frames) -> BackgroundModel:
        """The farthest reading per pixel over empty-scene frames (T, H, W): noise and passers-by
        only make a pixel closer, so the maximum is the background."""
        F = np.asarray(frames, np.float32)
        if F.ndim == 2:
            F = F[None]
        if F.ndim != 3 or F.shape[0] == 0:
            raise InputError("frames", "depth maps of shape (T, H, W)", f"shape {F.shape}")
        with np.errstate(invalid="ignore"):
            d = np.nanmax(np.where(np.isfinite(F), F, -np.inf), axis=0)
        d[~np.isfinite(d)] = np.nan
        return cls(d)


@dataclass(frozen=True)
class UserMask:
    """The user mask of one frame.

    Attributes
    ----------
    mask : ndarray of shape (H, W), bool
        User pixels (all False when no user was found).
    n_components : int
        Foreground components large enough to be a person.
    area_m2 : float
        Metric area of the user mask.
    median_depth : float
        Median depth of the user's pixels (NaN when empty).
    """

    mask: np.ndarray
    n_components: int
    area_m2: float
    median_depth: float

    @property
    def found(self) -> bool:
        return bool(self.mask.any())


def _empty(shape) -> UserMask:
    return UserMask(np.zeros(shape, bool), 0, 0.0, float("nan"))


def _valid(d: np.ndarray, config: MaskConfig) -> np.ndarray:
    """Readings within ``config.near_m``-``config.far_m`` (False for NaN)."""
    with np.errstate(invalid="ignore"):
        return (d > config.near_m) & (d < config.far_m)


def _background_depth(background: BackgroundModel, d: np.ndarray) -> np.ndarray:
    """The background model's depth map, checked against the frame's shape."""
    bg = background.depth
    if bg.shape != d.shape:
        raise InputError("background", f"a depth map of shape {d.shape}", f"shape {bg.shape}")
    return bg


def _foreground(d: np.ndarray, valid: np.ndarray, background: BackgroundModel | None,
                config: MaskConfig) -> np.ndarray:
    """Pixels with a valid reading clearly in front of the background (all valid ones without a model)."""
    if background is None:
        return valid
    bg = _background_depth(background, d)
    with np.errstate(invalid="ignore"):
        farther = d >= bg - (config.background_margin_m + config.background_margin_rel * bg)   # False for NaN bg
    return valid & ~farther


def ambiguous_mask(depth: np.ndarray, camera: Camera, *, background: BackgroundModel | None = None,
                   config: MaskConfig = MaskConfig()) -> np.ndarray:
    """Pixels whose reading is in front of the background, but too little to call it foreground.

    Between ``ambiguous_margin_m`` (+ ``ambiguous_margin_rel`` of the depth) and the foreground
    margin (``background_margin_m`` + ``background_margin_rel``) in front of the background model:
    a body touching the background there (the lowest 5-10 cm of feet on the floor, seen from 3 m)
    is left out of :func:`foreground_mask` and yet is not background.  Consumers that compare a
    model with the mask (:class:`toolkit.softbody.silhouette.SilhouetteView`) treat them as unknown.

    Parameters
    ----------
    depth : ndarray of shape (H, W)
        Metres, NaN = no reading.
    camera : Camera
    background : BackgroundModel, optional
        Without one nothing is ambiguous.
    config : MaskConfig

    Returns
    -------
    ndarray of shape (H, W), bool
    """
    d = _check_depth(depth, camera)
    if background is None:
        return np.zeros(d.shape, bool)
    bg = _background_depth(background, d)
    with np.errstate(invalid="ignore"):
        gap = bg - d                                                     # NaN where either is missing
        out = (gap > config.ambiguous_margin_m + config.ambiguous_margin_rel * bg) \
            & (gap < config.background_margin_m + config.background_margin_rel * bg)
    return _valid(d, config) & out


def foreground_mask(depth: np.ndarray, camera: Camera, *, background: BackgroundModel | None = None,
                    config: MaskConfig = MaskConfig()) -> np.ndarray:
    """Every foreground component of at least ``config.min_join_area_m2`` (all people in view, not
    only the user; specks of sensor noise left out).

    For consumers that tell the user apart themselves (the soft-body tracker separates
    the subject from other bodies with its model:
    :mod:`toolkit.softbody.separate`): a second person standing apart stays in, so
    the choice of :func:`user_mask` (the largest person when there is no previous
    mask) cannot pick the wrong one.

    Parameters
    ----------
    depth : ndarray of shape (H, W)
        Metres, NaN = no reading.
    camera : Camera
    background : BackgroundModel, optional
    config : MaskConfig

    Returns
    -------
    ndarray of shape (H, W), bool
    """
    d = _check_depth(depth, camera)
    valid = _valid(d, config)
    fg = _foreground(d, valid, background, config)
    if not fg.any():
        return fg
    n, lab = cv2.connectedComponents(fg.view(np.uint8), connectivity=8)
    z = d[fg].astype(np.float64)
    areas = np.bincount(lab[fg], weights=z * z, minlength=n) / (camera.K[0, 0] * camera.K[1, 1])
    areas[0] = 0.0
    return (areas >= config.min_join_area_m2)[lab] & fg


def user_mask(depth: np.ndarray, camera: Camera, *, background: BackgroundModel | None = None,
              given: np.ndarray | None = None, previous: np.ndarray | None = None,
              config: MaskConfig = MaskConfig()) -> UserMask:
    """Find the user's pixels in a depth map (see the module docstring).

    Parameters
    ----------
    depth : ndarray of shape (H, W)
        Metres, NaN = no reading.
    camera : Camera
    background : BackgroundModel, optional
    given : ndarray of shape (H, W), bool, optional
        A user mask from elsewhere: only pixels with a reading are kept.
    previous : ndarray of shape (H, W), bool, optional
        Last frame's user mask, to keep following the same person.
    config : MaskConfig

    Returns
    -------
    UserMask
        Empty (``found`` False) when no component is large enough.
    """
    d = _check_depth(depth, camera)
    valid = _valid(d, config)
    f2 = camera.K[0, 0] * camera.K[1, 1]
    if given is not None:
        g = np.asarray(given, bool)
        if g.shape != d.shape:
            raise InputError("given mask", f"a boolean image of shape {d.shape}", f"shape {g.shape}")
        m = g & valid
        if not m.any():
            return _empty(d.shape)
        zm = d[m].astype(np.float64)
        return UserMask(m, 1, float((zm * zm).sum() / f2), float(np.median(zm)))
    fg = _foreground(d, valid, background, config)
    if not fg.any():
        return _empty(d.shape)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(fg.view(np.uint8), connectivity=8)
    if n <= 1:
        return _empty(d.shape)
    lf = lab[fg]
    zf = d[fg].astype(np.float64)
    areas = np.bincount(lf, weights=zf * zf, minlength=n) / f2      # m^2: a pixel covers (z / f)^2
    areas[0] = 0.0
    big = np.nonzero(areas >= config.min_area_m2)[0]
    if len(big) == 0:
        return _empty(d.shape)
    main = None
    if previous is not None:
        p = np.asarray(previous, bool)
        if p.shape == d.shape and p.any():
            overlap = np.bincount(lab[p], minlength=n)[big]
            if overlap.max() > 0:
                main = int(big[np.argmax(overlap)])
    if main is None:
        # the most prominent person: most pixels (a nearer person covers more of the image)
        main = int(big[np.argmax(stats[big, cv2.CC_STAT_AREA])])
    m = lab == main
    zmed = float(np.median(zf[lf == main]))
    # join nearby components at a similar depth
    gap_px = int(np.ceil(config.join_gap_m * camera.K[0, 0] / max(zmed, 0.1)))
    others = (areas >= config.min_join_area_m2)
    others[main] = False
    if gap_px > 0 and others.any():
        x0, y0, ww, hh = stats[main, :4]
        H, W = d.shape
        r0, r1 = max(y0 - gap_px, 0), min(y0 + hh + gap_px, H)
        c0, c1 = max(x0 - gap_px, 0), min(x0 + ww + gap_px, W)
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * gap_px + 1, 2 * gap_px + 1))
        near = cv2.dilate(m[r0:r1, c0:c1].astype(np.uint8), k) > 0
        cand = np.unique(lab[r0:r1, c0:c1][near])
        for c in cand:
            if c == 0 or not others[c]:
                continue
            if abs(float(np.median(zf[lf == c])) - zmed) <= config.join_depth_m:
                m |= lab == c
    zm = d[m].astype(np.float64)
    return UserMask(m, len(big), float((zm * zm).sum() / f2), float(np.median(zm)))
