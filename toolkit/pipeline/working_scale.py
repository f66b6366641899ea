"""The resolution a frame's stages 2-3 work at: the person a few hundred pixels tall, whatever the camera.

Segmentation (template fit, the parts' colour models), the stage-3 position
score (every part's pixels warped between cameras) and the billboards
(textures supersampled :data:`~toolkit.rendering.fans.RENDER_SUPERSAMPLE` times)
cost in proportion to the person's pixels, and what they decide does not need
them all: part labels and 3D joints to about a centimetre need the body a few
hundred pixels tall.  Full-HD portrait footage of a near person (the Pose2Sim
demo: its joints span 610-790 px) costs several times what a 300 px one does.

So :class:`FrameProcessor <toolkit.pipeline.frame.FrameProcessor>` runs a
frame's stages 2-3 and builds its billboards on each source camera resized by
:func:`working_scales` (its images, silhouettes, plates and 2D poses; the
camera by :meth:`toolkit.cameras.Camera.scaled`), so that the person's longer
side in that camera is at most ``work_height_px`` pixels
(:data:`~toolkit.rendering.freeviewpoint.WORK_HEIGHT_PX`, 300).  What comes
back is in the cameras' own resolution:

* the part labels are resized back and moved onto the full-resolution
  silhouettes (:meth:`WorkingFrame.full_labels`), so their edge is the
  silhouette's, not a staircase of working pixels;
* the billboard models keep the full-resolution cameras (their quads are in
  metres); their textures come from the working images, supersampled
  :meth:`WorkingFrame.supersample` times (the configured supersampling times
  the scale, so about as many texels per full-resolution pixel as without a
  working scale);
* the visual hull is carved from the full-resolution silhouettes (its voxels
  cost the same at any image size).

The views are rendered at the cameras' full resolution.  A frame in which the
person is at most ``work_height_px`` tall in every camera (the synthetic
default scene: 100-140 px) runs exactly as with ``work_height_px=None``.
``docs/real_footage.md`` measures the gain and the effect on held-out views.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.rendering.freeviewpoint import WORK_HEIGHT_PX

__all__ = ["WORK_HEIGHT_PX", "person_extent_px", "working_scales", "WorkingFrame", "upsample_labels"]


def person_extent_px(camera, joints3d: np.ndarray) -> float:
    """The longer side of the box of ``joints3d`` projected into ``camera``, pixels (0: none projects).

    Parameters
    ----------
    camera : Camera
    joints3d : ndarray of shape (J, 3)
        Metres, NaN = missing.
    """
    uv = camera.project(np.asarray(joints3d, float))
    uv = uv[np.isfinite(uv).all(-1)]
    if len(uv) < 2:
        return 0.0
    return float(np.max(np.ptp(uv, axis=0)))


def working_scales(rig: Rig, joints3d: np.ndarray, work_height_px: float | None = WORK_HEIGHT_PX) -> np.ndarray:
    """Per camera, the factor its images are resized by for stages 2-3 (1: full resolution).

    Parameters
    ----------
    rig : Rig
    joints3d : ndarray of shape (J, 3)
        The frame's stage-1 joints, metres.
    work_height_px : float or None
        The person's longer side in the working image at most (:data:`WORK_HEIGHT_PX`); None or
        0: every camera at full resolution.

    Returns
    -------
    ndarray of shape (n_cams,)
        In (0, 1], rig order: ``min(1, work_height_px / extent)``.

    Raises
    ------
    InputError
        ``work_height_px`` negative or not finite.
    """
    if not work_height_px:
        return np.ones(len(rig))
    if not (np.isfinite(work_height_px) and work_height_px > 0):
        raise InputError("work_height_px", "a finite number of pixels > 0 (or None: full resolution)",
                         repr(work_height_px))
    ext = np.array([person_extent_px(c, joints3d) for c in rig])
    return np.where(ext > work_height_px, work_height_px / np.maximum(ext, 1e-9), 1.0)


def _resized(image: np.ndarray | None, size: tuple[int, int]) -> np.ndarray | None:
    if image is None:
        return None
    a = np.asarray(image)
    if a.shape[1::-1] == tuple(size):
        return a
    return cv2.resize(np.ascontiguousarray(a), size, interpolation=cv2.INTER_AREA)


@dataclass(frozen=True, eq=False)
class WorkingFrame:
    """One frame's inputs of stages 2-3 at the working resolution, and the way back.

    Attributes
    ----------
    full : Rig
        The source cameras at their own resolution (as given).
    rig : Rig
        The same cameras resized by ``scales`` (:meth:`toolkit.cameras.Camera.scaled`).
    scales : ndarray of shape (n_cams,)
        Per camera its factor (:func:`working_scales`).
    """

    full: Rig
    rig: Rig
    scales: np.ndarray

    @classmethod
    def of(cls, rig: Rig, scales) -> "WorkingFrame":
        """The working cameras of ``rig`` resized by ``scales`` (n_cams,)."""
        s = np.asarray(scales, float)
        if s.shape != (len(rig),) or not np.all((s > 0) & (s <= 1)):
            raise InputError("scales", f"({len(rig)},) factors in (0, 1]", f"{s}")
        return cls(rig, Rig(tuple(c.scaled(float(f)) if f < 1 else c for c, f in zip(rig, s))), s)

    @property
    def scaled(self) -> bool:
        """Whether any camera works below its resolution."""
        return bool(np.any(self.scales < 1))

    def images(self, images: dict | None) -> dict | None:
        """Per camera name its image (H, W, ...) resized to the working size (area average); None stays None."""
        if images is None:
            return None
        return {c: _resized(im, self.rig[c].size) if c in self.rig.names else im for c, im in images.items()}

    def masks(self, masks: list) -> list:
        """Silhouettes (rig order; (H, W) bool or None) at the working size: a pixel is inside when at
        least half of what it covers is."""
        out = []
        for m, cam in zip(masks, self.rig):
            if m is None:
                out.append(None)
                continue
            small = _resized(np.asarray(m, np.uint8) * 255, cam.size)
            out.append(np.asarray(small) >= 128)
        return out

    def points(self, points2d: np.ndarray) -> np.ndarray:
        """2D points per camera (n_cams, ..., 2), full-resolution pixels, in working pixels (NaN stays)."""
        p = np.asarray(points2d, float)
        f = self.scales.reshape((-1,) + (1,) * (p.ndim - 1))
        return (p + 0.5) * f - 0.5

    def offsets(self, offsets: np.ndarray) -> np.ndarray:
        """Stage 1's per-camera offsets (n_cams, 2), pixels, in working pixels (NaN stays)."""
        return np.asarray(offsets, float) * self.scales[:, None]

    def full_labels(self, labels: dict, masks: list | None = None) -> dict:
        """Part labels (working size, uint8) back at each camera's own size.

        Parameters
        ----------
        labels : dict of str to ndarray (h, w) uint8
            Per camera at its working size.
        masks : list of (ndarray (H, W) bool or None), optional
            The full-resolution silhouettes (rig order) the labels were made from: the labels then
            follow their edge (a pixel of the silhouette within one working pixel of a labelled one
            takes the label of the nearest; labelled pixels outside it become background), not the
            working pixels' staircase.

        Returns
        -------
        dict of str to ndarray (H, W) uint8
        """
        out = {}
        for k, cam in enumerate(self.full):
            if cam.name not in labels:
                continue
            a = np.asarray(labels[cam.name])
            if a.shape[1::-1] == tuple(cam.size):
                out[cam.name] = a
                continue
            up = upsample_labels(a, cam.size)
            m = None if masks is None else masks[k]
            out[cam.name] = up if m is None or not up.any() else _on_silhouette(up, np.asarray(m, bool),
                                                                                self.scales[k])
        return out

    def supersample(self, supersample: int) -> int:
        """The billboards' texture supersampling at the working size: ``supersample`` times the largest
        working scale, rounded, at least 1 (``supersample`` itself when a camera is at full size).

        On the Pose2Sim demo (scales 0.38-0.49 at 300 px) 6 becomes 3; at 400 px (0.50-0.65) the
        held-out view's PSNR on the person was 13.84 dB with 6, 4 and 3 (``docs/real_footage.md``).
        """
        return int(max(1, min(int(supersample), round(int(supersample) * float(self.scales.max())))))

    def full_result(self, result, cameras: Rig, masks: list | None = None):
        """A frame's result made at the working resolution, at the cameras' own.

        Parameters
        ----------
        result : toolkit.rendering.freeviewpoint.FrameResult
            Made with the working cameras.
        cameras : Rig
            The full-resolution cameras corrected by the frame's offsets (what ``result.cameras``
            are at the working size).
        masks : list of (ndarray (H, W) bool or None), optional
            The full-resolution silhouettes (:meth:`full_labels`).

        Returns
        -------
        FrameResult
            ``cameras`` and the labels at full size; the billboard models with ``cameras`` (their
            quads are in metres, their textures as made); the rest unchanged.
        """
        from dataclasses import replace

        from toolkit.billboards.model import BillboardModel

        def full(model):
            return None if model is None else BillboardModel(model.fans, cameras, model.frame, model.joints)

        return replace(result, cameras=cameras, labels=self.full_labels(result.labels, masks),
                       model=full(result.model),
                       standard=full(result.standard))

    def observer(self, observer):
        """``observer`` told of the working images at each camera's own size (:class:`_FullSize`), so a
        recording's labels and masks lie over the camera's frame; ``observer`` itself when nothing is
        scaled or there is none."""
        from toolkit.observe import NullObserver

        keep = observer is None or isinstance(observer, NullObserver) or not self.scaled
        return observer if keep else _FullSize(observer, self)


def upsample_labels(labels: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Part labels resized up with smooth boundaries: each pixel takes the label whose indicator,
    interpolated bilinearly, is the largest there (the background's included).

    Nearest-neighbour resizing draws every boundary as the working pixels' staircase, one working
    pixel (2-3 full pixels at the scales of real footage) off in places; the thin parts lose most.
    Measured on the full-resolution labels of zoo seed 71's 361 and 521 px subjects (6 cameras)
    resized to 300 px and back onto their silhouettes: part mIoU 0.864 at full size, 0.839 through
    nearest resizing, 0.851 through this (worst camera 0.870 → 0.782 / 0.815).

    Parameters
    ----------
    labels : ndarray of shape (h, w) uint8
        0 = background.
    size : tuple of int
        ``(W, H)``, the size wanted (pixel-centre convention, as ``cv2.resize``).

    Returns
    -------
    ndarray of shape (H, W) uint8
    """
    a = np.asarray(labels)
    W, H = int(size[0]), int(size[1])
    out = np.zeros((H, W), a.dtype)
    ys, xs = np.nonzero(a)
    if ys.size == 0:
        return out
    h, w = a.shape
    sx, sy = w / W, h / H
    # the full-size box of the labelled working pixels and one working pixel around (outside: background)
    X0, X1 = max(int(np.floor((xs.min() - 0.5) / sx - 0.5)), 0), min(int(np.ceil((xs.max() + 1.5) / sx - 0.5)) + 1, W)
    Y0, Y1 = max(int(np.floor((ys.min() - 0.5) / sy - 0.5)), 0), min(int(np.ceil((ys.max() + 1.5) / sy - 0.5)) + 1, H)
    mx, my = np.meshgrid(((np.arange(X0, X1) + 0.5) * sx - 0.5).astype(np.float32),
                         ((np.arange(Y0, Y1) + 0.5) * sy - 0.5).astype(np.float32))
    best = np.full(mx.shape, -1.0, np.float32)
    crop = np.zeros(mx.shape, a.dtype)
    for lab in np.unique(a):  # the background first: a tie keeps it
        p = cv2.remap((a == lab).astype(np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        better = p > best
        best[better] = p[better]
        crop[better] = lab
    out[Y0:Y1, X0:X1] = crop
    return out


def _on_silhouette(up: np.ndarray, mask: np.ndarray, scale: float) -> np.ndarray:
    """Labels resized up (nearest) moved onto the full-resolution silhouette ``mask``: its pixels within
    a working pixel (``1 / scale`` pixels) of a labelled one take the nearest label, the others none."""
    reach = int(np.ceil(1.0 / scale))
    ys, xs = np.nonzero(up)
    h, w = up.shape
    y0, y1 = max(ys.min() - reach, 0), min(ys.max() + reach + 1, h)
    x0, x1 = max(xs.min() - reach, 0), min(xs.max() + reach + 1, w)
    u, m = up[y0:y1, x0:x1], mask[y0:y1, x0:x1]
    dist, idx = cv2.distanceTransformWithLabels((u == 0).astype(np.uint8), cv2.DIST_L2, 5,
                                                labelType=cv2.DIST_LABEL_PIXEL)
    zy, zx = np.nonzero(u)  # DIST_LABEL_PIXEL numbers the zero pixels of its input (the labelled ones) in raster order
    near = u[zy, zx][np.clip(idx - 1, 0, len(zy) - 1)]
    crop = np.where(m & (dist <= reach), np.where(u > 0, u, near), 0).astype(up.dtype)
    out = np.zeros_like(up)
    out[y0:y1, x0:x1] = crop
    return out


class _FullSize:
    """Passes reports on, a camera's ``labels`` and ``mask`` images resized (nearest) to its own size."""

    def __init__(self, observer, work: WorkingFrame):
        self._observer, self._work = observer, work

    def report(self, kind: str, **data) -> None:
        cam = data.get("camera")
        if kind in ("labels", "mask") and cam in self._work.full.names and kind in data:
            size = self._work.full[cam].size
            a = np.asarray(data[kind])
            if a.ndim == 2 and a.shape[::-1] != tuple(size):
                dtype = a.dtype
                a = cv2.resize(a.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST)
                data = {**data, kind: a.astype(dtype)}
        self._observer.report(kind, **data)
