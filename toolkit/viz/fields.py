"""Checks and conversions of observer report fields (no rerun import; used by :mod:`toolkit.viz.rerun_observer`).

Every function raises :class:`~toolkit.errors.InputError` naming the report
kind and field, what was expected and what was found.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from toolkit.errors import InputError, check_shape
from toolkit.viz.style import CENTRE_COLOR, LEFT_COLOR, RIGHT_COLOR


def _check_writable(path: str | Path) -> Path:
    """Make sure ``path`` can be written, creating missing parent directories.

    Raises :class:`InputError` naming the path otherwise.
    """
    p = Path(path).expanduser()
    where = f"RerunObserver: path {str(p)!r}"
    if p.is_dir():
        raise InputError(where, "a file path for the .rrd recording", "an existing directory")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(where, f"a creatable directory {str(p.parent)!r}",
                         f"{type(e).__name__}: {e}") from None
    existed = p.exists()
    try:
        with open(p, "ab"):
            pass
    except OSError as e:
        raise InputError(where, "a writable file", f"{type(e).__name__}: {e}") from None
    if not existed:
        p.unlink()
    return p


def _side_color(joint_name: str) -> tuple[int, int, int]:
    if joint_name.startswith("l_"):
        return LEFT_COLOR
    if joint_name.startswith("r_"):
        return RIGHT_COLOR
    return CENTRE_COLOR


def _camera_name(kind: str, data: Mapping[str, Any]) -> str:
    cam = data.get("camera")
    if cam is None:
        raise InputError(f"report {kind!r}: camera", "a camera name", "nothing")
    name = getattr(cam, "name", cam)
    if not isinstance(name, str) or not name:
        raise InputError(f"report {kind!r}: camera", "a non-empty camera name", f"{cam!r}")
    return name


def _field(kind: str, data: Mapping[str, Any], key: str) -> Any:
    if key not in data or data[key] is None:
        raise InputError(f"report {kind!r}: {key}", "a value", "nothing")
    return data[key]


def _array(kind: str, data: Mapping[str, Any], key: str, shape: tuple, dtype=np.float64) -> np.ndarray:
    arr = np.asarray(_field(kind, data, key))
    check_shape(f"report {kind!r}: {key}", arr, shape)
    try:
        return arr.astype(dtype, copy=False)
    except (TypeError, ValueError):
        raise InputError(f"report {kind!r}: {key}", f"values convertible to {np.dtype(dtype)}",
                         f"dtype {arr.dtype}") from None


def _colors(kind: str, data: Mapping[str, Any], key: str, n: int) -> np.ndarray | None:
    """Optional uint8 colours, (3,) / (4,) for all or (n, 3|4) per item."""
    if data.get(key) is None:
        return None
    c = np.asarray(data[key])
    if c.ndim == 1 and c.shape[0] in (3, 4):
        c = np.broadcast_to(c, (n, c.shape[0]))
    if c.ndim != 2 or c.shape[0] != n or c.shape[1] not in (3, 4):
        raise InputError(f"report {kind!r}: {key}", f"(3,) or ({n}, 3) colours", f"shape {c.shape}")
    if np.issubdtype(c.dtype, np.floating):
        c = np.clip(np.round(c * 255.0), 0, 255)
    return c.astype(np.uint8)


def _image_uint8(kind: str, key: str, img: np.ndarray) -> np.ndarray:
    """uint8 image from uint8 or float in [0, 1] (scaled by 255)."""
    if img.dtype == np.uint8:
        return img
    if img.dtype == bool:
        return img.astype(np.uint8) * 255
    if np.issubdtype(img.dtype, np.floating):
        return np.clip(np.round(np.nan_to_num(img) * 255.0), 0, 255).astype(np.uint8)
    raise InputError(f"report {kind!r}: {key}", "uint8 or float in [0, 1]", f"dtype {img.dtype}")


def _pack_atlas(textures: list[np.ndarray], max_width: int = 4096) -> tuple[np.ndarray, list[tuple]]:
    """Shelf-pack RGB textures into one atlas.

    Returns the atlas (H, W, 3) and per texture its (x0, y0, w, h) pixel rectangle.
    """
    rects, x, y, row_h, width = [], 0, 0, 0, 0
    for t in textures:
        h, w = t.shape[:2]
        if x > 0 and x + w > max_width:
            x, y, row_h = 0, y + row_h, 0
        rects.append((x, y, w, h))
        x += w
        row_h = max(row_h, h)
        width = max(width, x)
    atlas = np.zeros((y + row_h, width, 3), np.uint8)
    for t, (x0, y0, w, h) in zip(textures, rects):
        atlas[y0:y0 + h, x0:x0 + w] = t[..., :3]
    return atlas, rects

