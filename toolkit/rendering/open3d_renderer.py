"""Open3D off-screen renderer of articulated billboards.

Every billboard is a textured quad drawn with the real camera model
(``setup_camera(K', cam_from_world, w, h)``, ``K'`` with the half-pixel
principal-point shift of :func:`toolkit.synthetic.render.open3d_intrinsics`),
post-processing off and one sample per pixel.  Each billboard is rasterised
alone twice (its colour texture, then its alpha as a grey texture) with the
unlit shader (the transparent unlit shader crashes Open3D 0.20 here), so the
per-pixel blend of :func:`toolkit.rendering.blend.composite` is exactly the
one of the CPU compositor: only the warping differs (GPU texture sampling vs
``cv2.warpPerspective``).

Open3D's unlit shader does not hand texture values through unchanged (sRGB
decoding and a gain, see :mod:`toolkit.synthetic.render`); the renderer
measures its transfer curve once at start-up by drawing a calibration texture
texel for pixel and inverts it with a look-up table.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d
from open3d.visualization import rendering

from toolkit.billboards.model import Billboard, BillboardModel
from toolkit.billboards.warp import footprint_roi
from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.observe import Observer
from toolkit.rendering.blend import RenderResult, composite
from toolkit.rendering.config import BlendConfig
from toolkit.synthetic.render import TEXTURE_GAIN, open3d_intrinsics, srgb_encode

def _quad(corners: np.ndarray) -> o3d.geometry.TriangleMesh:
    """Both windings of the quad TL, TR, BR, BL, texture row 0 at TL (Open3D's v = 0 is the last row)."""
    tris = np.array([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]])
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.array(corners, np.float64)),
                                  o3d.utility.Vector3iVector(tris.astype(np.int32)))
    uv = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]])
    m.triangle_uvs = o3d.utility.Vector2dVector(uv[tris.reshape(-1)])
    return m


def _material(texture_rgb: np.ndarray) -> rendering.MaterialRecord:
    mat = rendering.MaterialRecord()
    mat.shader = "defaultUnlit"
    mat.base_color = (TEXTURE_GAIN, TEXTURE_GAIN, TEXTURE_GAIN, 1.0)
    mat.albedo_img = o3d.geometry.Image(np.ascontiguousarray(srgb_encode(texture_rgb)))
    return mat


class Open3DRenderer:
    """Renders billboard models with Open3D's off-screen renderer.

    Parameters
    ----------
    size : tuple of int
        Image ``(width, height)`` of every view rendered.
    config : BlendConfig

    Notes
    -----
    One instance owns one ``OffscreenRenderer`` and measures the shader's
    transfer curve when created (about 0.5 s); reuse it for all frames and
    views of that size.
    """

    def __init__(self, size: tuple[int, int], config: BlendConfig = BlendConfig()):
        w, h = (int(v) for v in size)
        if w < 16 or h < 16:
            raise InputError("Open3DRenderer: size", "(width, height) of at least 16 pixels", f"{size}")
        self.size = (w, h)
        self.config = config
        self._r = rendering.OffscreenRenderer(w, h)
        self._r.scene.view.set_post_processing(False)
        self._r.scene.view.set_sample_count(1)
        self._r.scene.set_background([0.0, 0.0, 0.0, 1.0])
        self._names: dict[int, tuple[str, str]] = {}
        self._model_id = None
        self._lut = self._calibrate()

    # ----------------------------------------------------------- calibration
    def _calibrate(self) -> np.ndarray:
        """Look-up table (256,) from rendered value to texture value."""
        w, h = self.size
        f = 1000.0
        K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])
        cam = Camera("calibration", K, np.zeros(5), (w, h), np.eye(4))
        z = 2.0
        hw, hh = w / 2 * z / f, h / 2 * z / f
        corners = np.array([[-hw, -hh, z], [hw, -hh, z], [hw, hh, z], [-hw, hh, z]])
        value = (np.arange(w) * 256) // w  # a ramp along x, one texel per pixel
        tex = np.repeat(np.repeat(value[None, :, None], h, axis=0), 3, axis=2).astype(np.uint8)
        self._r.scene.add_geometry("calibration", _quad(corners), _material(tex))
        img = self._draw(cam)[h // 4: 3 * h // 4, :, 0].astype(np.float64).mean(axis=0)
        self._r.scene.remove_geometry("calibration")
        out = np.full(256, np.nan)
        inner = np.arange(w)
        inner = inner[(inner > 0) & (inner < w - 1)]
        for v in np.unique(value[inner]):
            sel = inner[value[inner] == v]
            out[v] = img[sel].mean()
        known = np.isfinite(out)
        out = np.interp(np.arange(256), np.nonzero(known)[0], out[known])
        out = np.maximum.accumulate(out + np.arange(256) * 1e-6)  # strictly increasing
        return np.interp(np.arange(256), out, np.arange(256)).astype(np.float32)

    def _draw(self, camera: Camera) -> np.ndarray:
        w, h = self.size
        self._r.setup_camera(open3d_intrinsics(camera), camera.cam_from_world, w, h)
        return np.asarray(self._r.render_to_image())

    # ------------------------------------------------------------- geometry
    def _load(self, model: BillboardModel) -> None:
        if self._model_id == id(model):
            return
        for c, a in self._names.values():
            self._r.scene.remove_geometry(c)
            self._r.scene.remove_geometry(a)
        self._names = {}
        for k, b in enumerate(model.billboards):
            q = _quad(b.corners)
            grey = np.clip(np.rint(b.alpha * 255.0), 0, 255).astype(np.uint8)
            names = (f"bb{k}/rgb", f"bb{k}/alpha")
            self._r.scene.add_geometry(names[0], q, _material(b.texture))
            self._r.scene.add_geometry(names[1], q, _material(np.repeat(grey[..., None], 3, axis=2)))
            self._r.scene.show_geometry(names[0], False)
            self._r.scene.show_geometry(names[1], False)
            self._names[id(b)] = names
        self._model_id = id(model)

    def _warp(self, billboard: Billboard, camera: Camera, pose=None):
        corners = billboard.corners if pose is None else billboard.corners @ pose[:3, :3].T + pose[:3, 3]
        if np.any(camera.depth_of(corners) <= 1e-6):
            return None
        px = camera.project(corners)
        roi = footprint_roi(px, camera.size)
        if roi[2] <= roi[0] or roi[3] <= roi[1]:
            return None
        view = camera.replace(dist=np.zeros(5))
        c_name, a_name = self._names[id(billboard)]
        x0, y0, x1, y1 = roi
        out = []
        for name in (c_name, a_name):
            self._r.scene.set_geometry_transform(name, np.eye(4) if pose is None else pose)  # turned to the view
            self._r.scene.show_geometry(name, True)
            img = self._draw(view)[y0:y1, x0:x1]
            self._r.scene.show_geometry(name, False)
            out.append(self._lut[img])
        return out[0], out[1][..., 0] / 255.0, roi

    # ----------------------------------------------------------------- API
    def render(self, model: BillboardModel, camera: Camera, observer: Observer | None = None,
               frame: int | None = None) -> RenderResult:
        """Render ``model`` into ``camera`` (same blend as :class:`~toolkit.rendering.CpuCompositor`)."""
        if tuple(camera.size) != self.size:
            raise InputError(f"Open3DRenderer.render: camera {camera.name!r} size", f"{self.size}", f"{camera.size}")
        self._load(model)
        return composite(model, camera, self._warp, self.config, observer, frame)
