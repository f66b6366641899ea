"""Pictures of a soft-body fit: the model's surface with the cloud over it, from the camera and from the side.

Drawn with OpenCV (orthographic views, triangles painted far to near with
Lambert shading, points coloured by their distance to the surface), so that
a run can write documentation images without a display or a renderer.
"""

from __future__ import annotations

import cv2
import numpy as np

#: Distance (metres) at which a point is drawn fully red (0: blue).
RESIDUAL_RED_M = 0.03


def _view_axes(forward: np.ndarray, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Rows: image right, image down, forward (world)."""
    f = np.asarray(forward, float)
    f = f / np.linalg.norm(f)
    r = np.cross(f, up)
    r = r / max(np.linalg.norm(r), 1e-9)
    return np.stack([r, np.cross(f, r), f])


def draw_view(points: np.ndarray, residuals: np.ndarray, vertices: np.ndarray, triangles: np.ndarray,
              forward: np.ndarray, size: int = 360, caption: str = "") -> np.ndarray:
    """One orthographic view of the fitted surface and the cloud.

    Parameters
    ----------
    points : ndarray of shape (N, 3)
        The cloud (or its patch centres), metres, world (z up).
    residuals : ndarray of shape (N,)
        Distance of each point to the fitted surface, metres.
    vertices : ndarray of shape (V, 3)
    triangles : ndarray of shape (F, 3)
        The fitted surface mesh.
    forward : array_like of shape (3,)
        Viewing direction (world).
    size : int
        Image height in pixels (the width is 3/4 of it).
    caption : str

    Returns
    -------
    ndarray of shape (size, 3 * size // 4, 3), uint8 RGB
    """
    A = _view_axes(forward)
    allp = np.concatenate([np.asarray(vertices, float).reshape(-1, 3), np.asarray(points, float).reshape(-1, 3)])
    h, w = size, 3 * size // 4
    img = np.full((h, w, 3), 245, np.uint8)
    if not len(allp):
        return img
    q = allp @ A.T
    lo, hi = np.percentile(q[:, :2], 0.5, axis=0), np.percentile(q[:, :2], 99.5, axis=0)
    scale = 0.9 * min(w / max(hi[0] - lo[0], 1e-3), h / max(hi[1] - lo[1], 1e-3))
    centre = 0.5 * (lo + hi)

    def px(p):
        v = (np.asarray(p, float) @ A.T)
        return np.stack([(v[:, 0] - centre[0]) * scale + w / 2, (v[:, 1] - centre[1]) * scale + h / 2], 1), v[:, 2]

    if len(triangles):
        uv, z = px(vertices)
        tri = np.asarray(triangles)
        n = np.cross(vertices[tri[:, 1]] - vertices[tri[:, 0]], vertices[tri[:, 2]] - vertices[tri[:, 0]])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        shade = 0.35 + 0.65 * np.abs(n @ A[2])
        order = np.argsort(-z[tri].mean(1))  # far first
        layer = img.copy()
        for i in order:
            c = tuple(int(v) for v in np.array([235, 170, 120]) * shade[i])
            cv2.fillConvexPoly(layer, np.round(uv[tri[i]] * 4).astype(np.int32), c, cv2.LINE_AA, shift=2)
        img = cv2.addWeighted(layer, 0.75, img, 0.25, 0)
    if len(points):
        uv, z = px(points)
        c = np.clip(np.asarray(residuals, float) / RESIDUAL_RED_M, 0, 1)[:, None]
        cols = np.round(255 * ((1 - c) * [0.1, 0.35, 1.0] + c * [0.95, 0.1, 0.1])).astype(int)
        for i in np.argsort(-z):
            cv2.circle(img, tuple(int(v) for v in np.round(uv[i])), 2, tuple(int(v) for v in cols[i]), -1)
    if caption:
        cv2.putText(img, caption, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (20, 20, 20), 1, cv2.LINE_AA)
    return img


def draw_fit(points, residuals, vertices, triangles, camera_forward, size: int = 360, caption: str = ""):
    """The fit seen along the camera's direction and from its side, side by side, (size, 3 size / 2, 3) RGB."""
    f = np.asarray(camera_forward, float)
    f = f - [0.0, 0.0, f[2]] if np.linalg.norm(f[:2]) > 1e-6 else np.array([0.0, 1.0, 0.0])
    side = np.cross([0.0, 0.0, 1.0], f)
    return np.concatenate([draw_view(points, residuals, vertices, triangles, f, size, caption),
                           draw_view(points, residuals, vertices, triangles, side, size, "side")], axis=1)
