"""Per-frame images: file names, PNG reading and the depth encoding.

Per-frame images of a dataset are PNG files named by frame index with six
digits (``000000.png``, ``000001.png``, ...).  Depth maps are stored as
``uint16`` millimetres with 0 meaning "no depth", the convention of consumer
depth cameras.
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from toolkit.errors import InputError

__all__ = [
    "FRAME_DIGITS",
    "DEPTH_UNITS_PER_METRE",
    "DEPTH_MAX_M",
    "frame_filename",
    "read_png",
    "depth_to_mm",
    "mm_to_depth",
]

#: Digits of the zero-padded frame index in per-frame file names.
FRAME_DIGITS = 6
#: Depth PNGs hold integer millimetres.
DEPTH_UNITS_PER_METRE = 1000.0
#: Largest depth a uint16 millimetre PNG can hold, metres.
DEPTH_MAX_M = np.iinfo(np.uint16).max / DEPTH_UNITS_PER_METRE


def frame_filename(index: int, suffix: str = ".png") -> str:
    """``"000042.png"`` for frame 42.

    Raises
    ------
    InputError
        If ``index`` is negative or does not fit in :data:`FRAME_DIGITS` digits.
    """
    i = int(index)
    if i != index or not 0 <= i < 10**FRAME_DIGITS:
        raise InputError("frame index", f"an integer in [0, {10**FRAME_DIGITS})", f"{index!r}")
    return f"{i:0{FRAME_DIGITS}d}{suffix}"


def read_png(
    path: str | os.PathLike, *, channels: int | None = None, dtype: type | None = None
) -> np.ndarray:
    """Read a PNG (or any image OpenCV reads) unchanged, colour in RGB order.

    Parameters
    ----------
    path : str or PathLike
    channels : {1, 3, None}
        Expected channel count (1 gives an (H, W) array); ``None`` accepts any.
    dtype : numpy dtype or None
        Expected dtype (``np.uint8``, ``np.uint16``); ``None`` accepts any.

    Returns
    -------
    ndarray of shape (H, W) or (H, W, C)
        RGB / RGBA for colour images.

    Raises
    ------
    InputError
        Missing or unreadable file, or channels / dtype other than expected.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(str(path), "an existing image file", "no such file")
    data = np.fromfile(path, dtype=np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise InputError(str(path), "an image file OpenCV can decode", "unreadable contents")
    if img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    elif img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2RGBA)
    n_ch = 1 if img.ndim == 2 else img.shape[2]
    if channels is not None and n_ch != channels:
        raise InputError(str(path), f"an image with {channels} channel(s)", f"{n_ch} channel(s)")
    if dtype is not None and img.dtype != np.dtype(dtype):
        raise InputError(str(path), f"a {np.dtype(dtype)} image", f"dtype {img.dtype}")
    return img


def depth_to_mm(depth_m: np.ndarray, where: str = "depth") -> np.ndarray:
    """Encode a depth map in metres as uint16 millimetres.

    Parameters
    ----------
    depth_m : ndarray of shape (H, W)
        Camera-frame z in metres; NaN, +inf and 0 mean "no depth".
    where : str
        Name used in error messages.

    Returns
    -------
    ndarray of shape (H, W), uint16
        Millimetres rounded to the nearest integer; 0 where there is no depth,
        and also where the depth is at or beyond :data:`DEPTH_MAX_M` (65.535 m,
        out of range, as depth sensors report it).

    Raises
    ------
    InputError
        For a non-2D array, negative depths or -inf.
    """
    d = np.asarray(depth_m, dtype=np.float64)
    if d.ndim != 2:
        raise InputError(where, "a depth map of shape (H, W)", f"shape {d.shape}")
    bad = (d < 0) | np.isneginf(d)
    if bad.any():
        raise InputError(
            where,
            "depths >= 0 metres (NaN / inf / 0 for none)",
            f"{int(bad.sum())} negative value(s), min {np.nanmin(d):.4g}",
        )
    mm = np.rint(np.where(np.isfinite(d), d, 0.0) * DEPTH_UNITS_PER_METRE)
    mm[mm >= np.iinfo(np.uint16).max + 0.5] = 0
    return mm.astype(np.uint16)


def mm_to_depth(mm: np.ndarray) -> np.ndarray:
    """Decode uint16 millimetres to float32 metres with NaN where the value is 0.

    Parameters
    ----------
    mm : ndarray of shape (H, W), uint16

    Returns
    -------
    ndarray of shape (H, W), float32
    """
    m = np.asarray(mm)
    out = m.astype(np.float32) / np.float32(DEPTH_UNITS_PER_METRE)
    out[m == 0] = np.nan
    return out
