"""Motion compensation: the previous frame's mask warped by dense optical flow.

Source 000 §2.1 mentions motion compensation / optical flow from the previous
frame as a help for the segmentation.  The flow is computed from the current
frame to the previous one (backward), so every current pixel looks up where it
came from and the warped mask has no holes.
"""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.errors import InputError

#: Farneback parameters: pyramid scale, levels, window, iterations, poly_n, poly_sigma, flags.
FARNEBACK_PARAMS = (0.5, 3, 15, 3, 5, 1.2, 0)


def _grey(image: np.ndarray, where: str) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8:
        return cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    if img.ndim == 2 and img.dtype == np.uint8:
        return img
    raise InputError(where, "a uint8 RGB (H, W, 3) or grey (H, W) image", f"shape {img.shape}, dtype {img.dtype}")


def dense_flow(src: np.ndarray, dst: np.ndarray, method: str = "dis") -> np.ndarray:
    """Dense optical flow from ``src`` to ``dst``: ``src[y, x]`` moves to ``(x, y) + flow[y, x]``.

    Parameters
    ----------
    src, dst : ndarray of shape (H, W, 3) or (H, W), uint8
    method : str
        ``"dis"`` (OpenCV DIS, medium preset) or ``"farneback"``.

    Returns
    -------
    ndarray of shape (H, W, 2), float32
        Pixels.
    """
    a, b = _grey(src, "src"), _grey(dst, "dst")
    if a.shape != b.shape:
        raise InputError("dense_flow", "images of equal size", f"{a.shape} and {b.shape}")
    if method == "dis":
        dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
        return dis.calc(a, b, None)
    if method == "farneback":
        return cv2.calcOpticalFlowFarneback(a, b, None, *FARNEBACK_PARAMS)
    raise InputError("method", "'dis' or 'farneback'", repr(method))


def warp_previous_mask(previous_mask: np.ndarray, previous_frame: np.ndarray, frame: np.ndarray,
                       method: str = "dis") -> np.ndarray:
    """The previous frame's mask moved to the current frame by optical flow.

    Parameters
    ----------
    previous_mask : ndarray of shape (H, W) of bool
    previous_frame, frame : ndarray of shape (H, W, 3), uint8 RGB
    method : str
        Flow method, see :func:`dense_flow`.

    Returns
    -------
    ndarray of shape (H, W) of bool
        Pixels of the current frame whose flow leads back into the previous mask.
    """
    m = np.asarray(previous_mask)
    if m.ndim != 2 or m.shape != np.asarray(frame).shape[:2]:
        raise InputError("previous_mask", f"a mask of the frame's size {np.asarray(frame).shape[:2]}",
                         f"shape {m.shape}")
    flow = dense_flow(frame, previous_frame, method)  # current -> previous
    h, w = m.shape
    gx, gy = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    warped = cv2.remap(m.astype(np.uint8) * 255, gx + flow[..., 0], gy + flow[..., 1], cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return warped >= 128
