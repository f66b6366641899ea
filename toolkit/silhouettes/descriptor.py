"""The silhouette descriptor of source 000 §2.1 and the bounding-box joint frame.

A silhouette (a boolean mask) is cut to its bounding box and resampled to a
grid of :data:`SILHOUETTE_GRID` = 32 x 40 cells (32 wide, 40 tall; the aspect
ratio is *not* preserved, which normalises subjects of different sizes and
builds).  Each cell holds the fraction of its area covered by silhouette
pixels (exact area averaging, pixels taken as unit squares), so values lie in
[0, 1].  Stacking the cells row by row gives the vector ``v`` of
``n = 32 * 40 = 1280`` values of eq. (1).

2D joints are expressed in the same frame: normalised to the bounding box,
``(0, 0)`` at its top-left corner and ``(1, 1)`` at its bottom-right corner.

Bounding boxes use pixel edges: with the toolkit's pixel convention (the
centre of the top-left pixel is (0, 0)), a silhouette covering columns
``c0..c1`` and rows ``r0..r1`` has the box ``(c0 - 0.5, r0 - 0.5, c1 + 0.5,
r1 + 0.5)``.

The optional optical-flow descriptor (a variant of the source: "an optical
flow is also stored with the reference silhouette") resamples a dense flow
field over the same box to the same grid, in units of the box size.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError

#: Grid the silhouette is resampled to: (width, height) in cells (source 000 §2.1: 32 x 40).
SILHOUETTE_GRID = (32, 40)
#: Length n of the stacked descriptor (32 * 40 = 1280).
DESCRIPTOR_SIZE = SILHOUETTE_GRID[0] * SILHOUETTE_GRID[1]
#: Quantisation of stored descriptors: a cell value v in [0, 1] is kept as round(255 v).
DESCRIPTOR_LEVELS = 255

#: Silhouette states (per frame and camera) and their codes, as written by the pipeline.
STATE_OK = 0
STATE_EMPTY = 1
STATE_TOO_SMALL = 2
STATE_FULL_FRAME = 3
STATE_TRUNCATED = 4
STATE_NO_FRAME = 5
SILHOUETTE_STATES = {
    STATE_OK: "ok",
    STATE_EMPTY: "empty silhouette",
    STATE_TOO_SMALL: "silhouette too small",
    STATE_FULL_FRAME: "silhouette fills the frame",
    STATE_TRUNCATED: "silhouette touches the image border (person leaving the image)",
    STATE_NO_FRAME: "no video frame (the camera's video is shorter)",
}
#: Fewest silhouette pixels for a usable descriptor (a 32 x 40 grid needs some support).
MIN_SILHOUETTE_PIXELS = 100
#: Largest fraction of the image a usable silhouette may cover.
MAX_FILL_FRACTION = 0.6


def _check_mask(mask, name: str = "mask") -> np.ndarray:
    m = np.asarray(mask)
    if m.ndim != 2 or m.size == 0:
        raise InputError(name, "a 2D (H, W) boolean mask", f"shape {m.shape}")
    return m.astype(bool, copy=False)


def bounding_box(mask: np.ndarray) -> np.ndarray | None:
    """Bounding box of a silhouette, in pixel-edge coordinates.

    Parameters
    ----------
    mask : ndarray of shape (H, W), bool

    Returns
    -------
    ndarray of shape (4,) or None
        ``(x0, y0, x1, y1)`` in pixels (``x0 = first column - 0.5``,
        ``x1 = last column + 0.5``, same for rows); ``None`` for an empty mask.
    """
    m = _check_mask(mask)
    cols = np.flatnonzero(m.any(axis=0))
    if cols.size == 0:
        return None
    rows = np.flatnonzero(m.any(axis=1))
    return np.array([cols[0] - 0.5, rows[0] - 0.5, cols[-1] + 0.5, rows[-1] + 0.5])


def _area_matrix(n_cells: int, n_pixels: int) -> np.ndarray:
    """(n_cells, n_pixels) weights: fraction of each cell covered by each unit pixel."""
    edges = np.arange(n_cells + 1) * (n_pixels / n_cells)
    lo, hi = edges[:-1, None], edges[1:, None]
    p = np.arange(n_pixels)[None, :]
    overlap = np.clip(np.minimum(hi, p + 1) - np.maximum(lo, p), 0.0, None)
    return overlap / (n_pixels / n_cells)


def silhouette_grid(mask: np.ndarray, bbox: np.ndarray | None = None) -> np.ndarray:
    """Resample a silhouette to the 32 x 40 grid by exact area averaging.

    Parameters
    ----------
    mask : ndarray of shape (H, W), bool
    bbox : ndarray of shape (4,), optional
        Integer-aligned pixel-edge box ``(x0, y0, x1, y1)``; defaults to
        :func:`bounding_box` of ``mask``.

    Returns
    -------
    ndarray of shape (40, 32), float32
        Covered fraction of each cell, in [0, 1].

    Raises
    ------
    InputError
        If the mask is empty or the box is not a non-empty box inside the image.
    """
    m = _check_mask(mask)
    box = bounding_box(m) if bbox is None else np.asarray(bbox, float)
    if box is None:
        raise InputError("mask", "a silhouette with at least one pixel", "an empty mask")
    c0, r0 = int(round(box[0] + 0.5)), int(round(box[1] + 0.5))
    c1, r1 = int(round(box[2] - 0.5)), int(round(box[3] - 0.5))
    h, w = m.shape
    if box.shape != (4,) or not (0 <= c0 <= c1 < w and 0 <= r0 <= r1 < h):
        raise InputError("bbox", f"a non-empty pixel-edge box inside the {w}x{h} image", f"{box.tolist()}")
    crop = m[r0:r1 + 1, c0:c1 + 1].astype(np.float64)
    gw, gh = SILHOUETTE_GRID
    grid = _area_matrix(gh, crop.shape[0]) @ crop @ _area_matrix(gw, crop.shape[1]).T
    return np.clip(grid, 0.0, 1.0).astype(np.float32)


def silhouette_descriptor(mask: np.ndarray, bbox: np.ndarray | None = None) -> np.ndarray:
    """The stacked descriptor ``v`` of eq. (1): :func:`silhouette_grid` row by row.

    Parameters
    ----------
    mask : ndarray of shape (H, W), bool
    bbox : ndarray of shape (4,), optional

    Returns
    -------
    ndarray of shape (1280,), float32
        Values in [0, 1].

    Examples
    --------
    >>> m = np.zeros((100, 60), bool); m[10:90, 20:40] = True
    >>> v = silhouette_descriptor(m)
    >>> v.shape, float(v.min()), float(v.max())
    ((1280,), 1.0, 1.0)
    """
    return silhouette_grid(mask, bbox).reshape(-1)


def descriptor_grid(descriptor: np.ndarray) -> np.ndarray:
    """Inverse of the stacking: (1280,) or (N, 1280) to (40, 32) or (N, 40, 32)."""
    v = np.asarray(descriptor)
    if v.shape[-1] != DESCRIPTOR_SIZE:
        raise InputError("descriptor", f"an array of shape (..., {DESCRIPTOR_SIZE})", f"shape {v.shape}")
    return v.reshape(v.shape[:-1] + (SILHOUETTE_GRID[1], SILHOUETTE_GRID[0]))


def quantise_descriptor(descriptor: np.ndarray) -> np.ndarray:
    """Descriptor values in [0, 1] to the stored uint8 levels ``round(255 v)``, same shape."""
    v = np.asarray(descriptor, dtype=np.float64)
    if v.shape[-1] != DESCRIPTOR_SIZE:
        raise InputError("descriptor", f"an array of shape (..., {DESCRIPTOR_SIZE})", f"shape {v.shape}")
    if not np.all(np.isfinite(v)) or v.min(initial=0.0) < 0 or v.max(initial=0.0) > 1:
        raise InputError("descriptor", "finite values in [0, 1]",
                         f"values in [{np.nanmin(v)}, {np.nanmax(v)}]" if v.size else "nothing")
    return np.rint(v * DESCRIPTOR_LEVELS).astype(np.uint8)


def _check_bbox(bbox, name: str = "bbox") -> np.ndarray:
    b = np.asarray(bbox, dtype=np.float64)
    if b.shape[-1:] != (4,) or not np.all(np.isfinite(b)) or np.any(b[..., 2] <= b[..., 0]) \
            or np.any(b[..., 3] <= b[..., 1]):
        raise InputError(name, "finite boxes (..., 4) = (x0, y0, x1, y1) with x1 > x0 and y1 > y0",
                         f"{b.tolist() if b.size <= 8 else f'shape {b.shape}'}")
    return b


def normalise_joints(joints: np.ndarray, bbox: np.ndarray) -> np.ndarray:
    """Pixel joints to bounding-box coordinates.

    Parameters
    ----------
    joints : ndarray of shape (..., J, 2)
        Pixels; NaN stays NaN.
    bbox : ndarray of shape (..., 4)
        Pixel-edge boxes, broadcast against the leading axes of ``joints``.

    Returns
    -------
    ndarray of shape (..., J, 2)
        ``(0, 0)`` = top-left corner of the box, ``(1, 1)`` = bottom-right.
    """
    j = np.asarray(joints, dtype=np.float64)
    if j.ndim < 2 or j.shape[-1] != 2:
        raise InputError("joints", "an array of shape (..., J, 2) in pixels", f"shape {j.shape}")
    b = _check_bbox(bbox)[..., None, :]
    return (j - b[..., :2]) / (b[..., 2:] - b[..., :2])


def denormalise_joints(joints: np.ndarray, bbox: np.ndarray) -> np.ndarray:
    """Bounding-box coordinates (..., J, 2) back to pixels; inverse of :func:`normalise_joints`."""
    j = np.asarray(joints, dtype=np.float64)
    if j.ndim < 2 or j.shape[-1] != 2:
        raise InputError("joints", "an array of shape (..., J, 2) in box coordinates", f"shape {j.shape}")
    b = _check_bbox(bbox)[..., None, :]
    return b[..., :2] + j * (b[..., 2:] - b[..., :2])


def flow_descriptor(flow: np.ndarray, bbox: np.ndarray) -> np.ndarray:
    """Dense optical flow over a silhouette box, resampled to the 32 x 40 grid.

    Parameters
    ----------
    flow : ndarray of shape (H, W, 2)
        Per-pixel displacement (dx, dy) in pixels, e.g. from
        ``cv2.calcOpticalFlowFarneback`` between this frame and the next;
        NaN where unknown (counted as 0).
    bbox : ndarray of shape (4,)
        The silhouette's integer-aligned pixel-edge box.

    Returns
    -------
    ndarray of shape (2560,), float32
        The area-averaged dx grid (40, 32) divided by the box width, then the
        dy grid divided by the box height, stacked row by row: the motion in
        units of the subject's box, comparable across image scales.
    """
    f = np.asarray(flow, dtype=np.float64)
    if f.ndim != 3 or f.shape[2] != 2:
        raise InputError("flow", "an array of shape (H, W, 2) in pixels", f"shape {f.shape}")
    b = _check_bbox(bbox)
    c0, r0, c1, r1 = (int(round(b[0] + 0.5)), int(round(b[1] + 0.5)), int(round(b[2] - 0.5)),
                      int(round(b[3] - 0.5)))
    h, w = f.shape[:2]
    if not (0 <= c0 <= c1 < w and 0 <= r0 <= r1 < h):
        raise InputError("bbox", f"a box inside the {w}x{h} flow field", f"{b.tolist()}")
    crop = np.nan_to_num(f[r0:r1 + 1, c0:c1 + 1])
    gw, gh = SILHOUETTE_GRID
    ay, ax = _area_matrix(gh, crop.shape[0]), _area_matrix(gw, crop.shape[1])
    dx = ay @ crop[..., 0] @ ax.T / (b[2] - b[0])
    dy = ay @ crop[..., 1] @ ax.T / (b[3] - b[1])
    return np.concatenate([dx.ravel(), dy.ravel()]).astype(np.float32)


@dataclass(frozen=True)
class SilhouetteCheck:
    """Whether a silhouette can be matched against the database.

    Attributes
    ----------
    state : int
        One of the ``STATE_*`` codes (:data:`SILHOUETTE_STATES`).
    bbox : ndarray of shape (4,) or None
        Pixel-edge box of the silhouette (None when empty).
    n_pixels : int
    """

    state: int
    bbox: np.ndarray | None
    n_pixels: int

    @property
    def ok(self) -> bool:
        return self.state == STATE_OK

    def __bool__(self) -> bool:
        return self.ok

    @property
    def reason(self) -> str:
        return SILHOUETTE_STATES[self.state]


def check_silhouette(mask: np.ndarray, *, min_pixels: int = MIN_SILHOUETTE_PIXELS,
                     max_fill: float = MAX_FILL_FRACTION, border_px: int = 0) -> SilhouetteCheck:
    """Classify a silhouette as usable or not (empty, tiny, full frame, cut by the border).

    Parameters
    ----------
    mask : ndarray of shape (H, W), bool
    min_pixels : int
        Fewest pixels of a usable silhouette.
    max_fill : float
        Largest usable fraction of the image.
    border_px : int
        A silhouette with a pixel within this many pixels of the image border
        is ``STATE_TRUNCATED`` (0: only pixels on the border row or column).

    Returns
    -------
    SilhouetteCheck
        Falsy when the silhouette is not usable; ``reason`` says why.
    """
    m = _check_mask(mask)
    n = int(np.count_nonzero(m))
    box = bounding_box(m)
    if box is None:
        return SilhouetteCheck(STATE_EMPTY, None, 0)
    h, w = m.shape
    if n > max_fill * m.size:
        return SilhouetteCheck(STATE_FULL_FRAME, box, n)
    if n < min_pixels:
        return SilhouetteCheck(STATE_TOO_SMALL, box, n)
    b = int(border_px)
    if box[0] + 0.5 <= b or box[1] + 0.5 <= b or box[2] - 0.5 >= w - 1 - b or box[3] - 0.5 >= h - 1 - b:
        return SilhouetteCheck(STATE_TRUNCATED, box, n)
    return SilhouetteCheck(STATE_OK, box, n)
