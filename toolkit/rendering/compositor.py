"""The fast CPU compositor: billboards warped by plane-induced homographies.

Each billboard is a plane, so bringing its texture into a pinhole view is one
3x3 homography (:meth:`toolkit.billboards.model.Billboard.view_from_texture`)
applied with ``cv2.warpPerspective`` to the billboard's footprint only (stage
3's :func:`toolkit.billboards.warp_billboard`); the blend of
:func:`toolkit.rendering.blend.composite` does the rest.  Lens
distortion of the view is ignored (synthetic and virtual cameras have none).
"""

from __future__ import annotations

import numpy as np

from toolkit.billboards.model import Billboard, BillboardModel
from toolkit.billboards.warp import warp_billboard, warp_texture
from toolkit.cameras import Camera
from toolkit.observe import Observer
from toolkit.rendering.blend import RenderResult, composite
from toolkit.rendering.config import BlendConfig

def posed_homography(billboard: Billboard, camera: Camera, pose: np.ndarray | None = None):
    """Homography (3, 3) from texels of ``billboard``, moved by the rigid ``pose`` (4, 4), to pixels of ``camera``."""
    if pose is None:
        return billboard.view_from_texture(camera)
    M = pose[:3, :3] @ billboard.world_from_texture()
    M[:, 2] += pose[:3, 3]
    A = camera.R @ M
    A[:, 2] += camera.t
    return camera.K @ A


def warp_to_view(billboard: Billboard, camera: Camera, pose: np.ndarray | None = None):
    """The :data:`~toolkit.rendering.blend.Warper` of the CPU compositor, without caching.

    Calls :func:`toolkit.billboards.warp_billboard` (one homography per planar
    billboard, ``cv2.warpPerspective`` over its footprint only); a planar
    billboard moved by ``pose`` (a rigid (4, 4) world transform,
    :func:`toolkit.rendering.blend.facing_pose`) goes through
    :func:`posed_homography`.

    Returns
    -------
    (rgb, alpha, roi) or None
        rgb (h, w, 3) float32 0..255, alpha (h, w) float32, roi (x0, y0, x1, y1);
        None when the billboard is behind the view or outside the image.
    """
    if pose is not None and billboard.surface == "plane":
        rgba = np.dstack([billboard.texture.astype(np.float32), billboard.alpha])
        w = warp_texture(rgba, posed_homography(billboard, camera, pose), None, camera.size)
        return None if w is None else (w.rgb, w.alpha, tuple(int(v) for v in w.roi))
    w = warp_billboard(billboard, camera, min_cos=-2.0)  # the blend fades back faces itself
    if w.empty:
        return None
    return w.rgb, w.alpha, tuple(int(v) for v in w.roi)


class CpuCompositor:
    """Renders billboard models with the blend of source 000 §4 on the CPU.

    Planar billboards go through stage 3's homography warp with their 8-bit
    RGBA texture packed once per model (cached while the same model is
    rendered into several views) and without the per-pixel depth the
    compositor does not need; other surfaces through
    :func:`toolkit.billboards.warp_billboard`.

    Parameters
    ----------
    config : BlendConfig
    """

    def __init__(self, config: BlendConfig = BlendConfig()):
        self.config = config
        self._model = None
        self._rgba: dict[int, np.ndarray] = {}

    def _warp(self, billboard: Billboard, camera: Camera, pose=None):
        if billboard.surface != "plane":
            return warp_to_view(billboard, camera, pose)
        rgba = self._rgba.get(id(billboard))
        if rgba is None:
            rgba = billboard.rgba()  # uint8: 8-bit alpha is plenty for the binary blend
            self._rgba[id(billboard)] = rgba
        w = warp_texture(rgba, posed_homography(billboard, camera, pose), None, camera.size)
        if w is None:
            return None
        return w.rgb.astype(np.float32), w.alpha.astype(np.float32) * np.float32(1 / 255), \
            tuple(int(v) for v in w.roi)

    def render(self, model: BillboardModel, camera: Camera, observer: Observer | None = None,
               frame: int | None = None) -> RenderResult:
        """Render ``model`` into ``camera`` (a source view: its corrected camera from ``model.rig``);
        see :func:`toolkit.rendering.blend.composite`."""
        if self._model is not model:
            self._model, self._rgba = model, {}
        return composite(model, camera, self._warp, self.config, observer, frame)
