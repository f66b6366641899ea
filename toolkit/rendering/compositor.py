"""The fast CPU compositor: billboards warped by plane-induced homographies.

Each billboard is a plane, so bringing its texture into a pinhole view is one
3x3 homography (:meth:`toolkit.billboards.model.Billboard.view_from_texture`)
applied with ``cv2.warpPerspective`` to the billboard's footprint only (stage
3's :func:`toolkit.billboards.warp_billboard`); the blend of
:func:`toolkit.rendering.blend.composite` does the rest.  Lens
distortion of the view is ignored (synthetic and virtual cameras have none).
"""

from __future__ import annotations

from toolkit.billboards.model import Billboard, BillboardModel
from toolkit.billboards.warp import warp_billboard
from toolkit.cameras import Camera
from toolkit.observe import Observer
from toolkit.rendering.blend import RenderResult, composite
from toolkit.rendering.config import BlendConfig

def warp_to_view(billboard: Billboard, camera: Camera, offset=(0.0, 0.0)):
    """The :data:`~toolkit.rendering.blend.Warper` of the CPU compositor.

    Calls :func:`toolkit.billboards.warp_billboard` (one homography per planar
    billboard, ``cv2.warpPerspective`` over its footprint only).

    Returns
    -------
    (rgb, alpha, roi) or None
        rgb (h, w, 3) float32 0..255, alpha (h, w) float32, roi (x0, y0, x1, y1);
        None when the billboard is behind the view or outside the image.
    """
    w = warp_billboard(billboard, camera, offset=offset)
    if w.empty:
        return None
    return w.rgb, w.alpha, tuple(int(v) for v in w.roi)


class CpuCompositor:
    """Renders billboard models with the blend of source 000 §4 on the CPU.

    Parameters
    ----------
    config : BlendConfig
    """

    def __init__(self, config: BlendConfig = BlendConfig()):
        self.config = config

    def render(self, model: BillboardModel, camera: Camera, offset=(0.0, 0.0),
               observer: Observer | None = None, frame: int | None = None) -> RenderResult:
        """Render ``model`` into ``camera``; see :func:`toolkit.rendering.blend.composite`."""
        return composite(model, camera, warp_to_view, self.config, offset, observer, frame)
