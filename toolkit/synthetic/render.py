"""Rendering of synthetic scenes: Open3D's off-screen renderer for colour,
Open3D's ray caster for exact labels, masks and depth.

Pixel convention.  Inside the toolkit the centre of the top-left pixel is
(0, 0) (OpenCV).  Open3D's ``setup_camera(K, ...)`` treats ``K`` with the
top-left *corner* at (0, 0) (checked: a single-sample render agrees pixel for
pixel with rays cast through (u + 0.5, v + 0.5)), so the renderer is handed a
principal point shifted by half a pixel.  With post-processing off the colours
come out exactly as given (no tone mapping), and with one sample per pixel the
rendered silhouette equals the ray-cast mask exactly; the default uses 4x MSAA
for natural edges, which only changes partially covered border pixels.

Lens distortion is not rendered; synthetic cameras are distortion-free.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d
from open3d.visualization import rendering

from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.body.model import BodyMesh
from toolkit.synthetic.environment import Surface

#: Geometry id of the body in the ray caster's answers (surfaces follow).
BODY_GEOMETRY = 0


def open3d_intrinsics(camera: Camera) -> np.ndarray:
    """``K`` as Open3D's renderer expects it (principal point in corner convention)."""
    K = camera.K.copy()
    K[0, 2] += 0.5
    K[1, 2] += 0.5
    return K


#: Base colour that makes Open3D's unlit textured material reproduce texture values.
#: Measured here: with post-processing off the unlit shader outputs half the
#: linear (sRGB-decoded) texture value; this base colour (sRGB-decoded to ~2)
#: compensates, leaving a gain error under 2 % (texture values within 4 levels).
TEXTURE_GAIN = 1.3624


def srgb_encode(image: np.ndarray) -> np.ndarray:
    """Encode linear uint8 values with the sRGB transfer curve (uint8 in, uint8 out)."""
    return _SRGB_LUT[np.asarray(image, np.uint8)]


def _srgb_lut() -> np.ndarray:
    x = np.arange(256) / 255.0
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.clip(np.round(y * 255.0), 0, 255).astype(np.uint8)


_SRGB_LUT = _srgb_lut()


def _legacy_mesh(vertices, triangles) -> o3d.geometry.TriangleMesh:
    return o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.asarray(vertices, np.float64)),
                                     o3d.utility.Vector3iVector(np.asarray(triangles, np.int32)))


class SceneRenderer:
    """Off-screen colour renderer of one scene at one image size.

    The static surroundings are rendered once per camera into a background
    plate; each frame only the bodies are rendered, twice (over black and over
    white) to recover their coverage alpha exactly, and composited over the
    plate.  (Rendering bodies and the large vertex-coloured surroundings in
    one pass made Open3D 0.20 on software Vulkan take seconds to minutes per
    frame on this machine; body-only passes take a few tens of milliseconds.)

    Parameters
    ----------
    size : tuple of int
        Image ``(width, height)``.
    surfaces : list of Surface
        Static textured surroundings.
    background : tuple of float
        RGB in [0, 1] where nothing is hit.
    sample_count : int
        MSAA samples per pixel (1 = exact agreement with the ray-cast mask).
    """

    def __init__(self, size: tuple[int, int], surfaces: list[Surface] = (), background=(0, 0, 0),
                 sample_count: int = 4):
        w, h = (int(v) for v in size)
        if w <= 0 or h <= 0:
            raise InputError("SceneRenderer: size", "positive (width, height)", f"{size}")
        self.size = (w, h)
        self.background = tuple(float(c) for c in background)
        self._r = rendering.OffscreenRenderer(w, h)
        view = self._r.scene.view
        view.set_post_processing(False)
        view.set_sample_count(int(sample_count))
        self._surfaces = list(surfaces)
        self._env_names: list[str] = []
        self._body_names: list[str] = []
        self._plates: dict = {}

    def _add_surface(self, surface: Surface) -> None:
        m = _legacy_mesh(surface.vertices, surface.triangles)
        mat = rendering.MaterialRecord()
        mat.shader = "defaultUnlit"
        name = f"env/{surface.name}"
        if surface.texture is None:
            m.vertex_colors = o3d.utility.Vector3dVector(np.asarray(surface.vertex_colors, np.float64))
        else:
            m.triangle_uvs = o3d.utility.Vector2dVector(
                np.asarray(surface.uvs, np.float64)[surface.triangles.reshape(-1)])
            mat.base_color = (TEXTURE_GAIN, TEXTURE_GAIN, TEXTURE_GAIN, 1.0)
            mat.albedo_img = o3d.geometry.Image(np.ascontiguousarray(srgb_encode(surface.texture)))
        self._r.scene.add_geometry(name, m, mat)
        self._env_names.append(name)

    def set_bodies(self, meshes: list[tuple[BodyMesh, np.ndarray]]) -> None:
        """Replace the posed bodies: a list of (mesh, vertex colours (V, 3) in [0, 1])."""
        for n in self._body_names:
            self._r.scene.remove_geometry(n)
        self._body_names = []
        mat = rendering.MaterialRecord()
        mat.shader = "defaultUnlit"
        for i, (mesh, colors) in enumerate(meshes):
            m = _legacy_mesh(mesh.vertices, mesh.triangles)
            m.vertex_colors = o3d.utility.Vector3dVector(np.asarray(colors, np.float64))
            name = f"body/{i}"
            self._r.scene.add_geometry(name, m, mat)
            self._body_names.append(name)

    def _show_bodies(self, show: bool) -> None:
        for n in self._body_names:
            self._r.scene.show_geometry(n, show)

    def _pass(self, camera: Camera, background) -> np.ndarray:
        w, h = self.size
        self._r.scene.set_background([*background, 1.0])
        self._r.setup_camera(open3d_intrinsics(camera), camera.cam_from_world, w, h)
        return np.asarray(self._r.render_to_image()).astype(np.float32)

    @staticmethod
    def _key(camera: Camera):
        return camera.K.tobytes(), camera.cam_from_world.tobytes()

    def prepare(self, cameras) -> None:
        """Render the background plates of ``cameras`` in one go (then the surroundings are unloaded)."""
        todo = [c for c in cameras if self._key(c) not in self._plates]
        if not todo:
            return
        self._show_bodies(False)
        for s in self._surfaces:
            self._add_surface(s)
        for c in todo:
            self._plates[self._key(c)] = self._pass(c, self.background)
        for n in self._env_names:
            self._r.scene.remove_geometry(n)
        self._env_names = []
        self._show_bodies(True)

    def background_plate(self, camera: Camera, keep: bool = True) -> np.ndarray:
        """The surroundings alone as seen by ``camera``, (H, W, 3) float32 in [0, 255] (cached unless
        ``keep`` is False)."""
        self.prepare([camera])
        return self._plates[self._key(camera)] if keep else self._plates.pop(self._key(camera))

    def render_layer(self, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
        """The bodies alone: premultiplied colour (H, W, 3) float32 and coverage alpha (H, W) in [0, 1]."""
        black = self._pass(camera, (0.0, 0.0, 0.0))
        white = self._pass(camera, (1.0, 1.0, 1.0))
        alpha = np.clip(1.0 - (white - black).mean(-1) / 255.0, 0.0, 1.0)
        return black, alpha

    def render(self, camera: Camera) -> np.ndarray:
        """Colour image seen by ``camera``, (H, W, 3) uint8 RGB."""
        if tuple(camera.size) != self.size:
            raise InputError(f"render: camera {camera.name!r} size", f"{self.size}", f"{camera.size}")
        plate = self.background_plate(camera)
        if not self._body_names:
            return np.clip(plate + 0.5, 0, 255).astype(np.uint8)
        colour, alpha = self.render_layer(camera)
        out = colour + (1.0 - alpha[..., None]) * plate
        return np.clip(out + 0.5, 0, 255).astype(np.uint8)


class Raycaster:
    """Exact per-pixel part labels and depth by ray casting (pixel centres).

    Parameters
    ----------
    surfaces : list of Surface
        Static surroundings (hit for depth, label 0).
    """

    def __init__(self, surfaces: list[Surface] = ()):
        self.surfaces = list(surfaces)
        self._dirs: dict = {}
        self._env_depth: dict = {}

    def _cam_dirs(self, camera: Camera) -> np.ndarray:
        key = (camera.K.tobytes(), camera.dist.tobytes(), camera.size)
        if key not in self._dirs:
            w, h = camera.size
            u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
            n = camera.undistort_points(np.stack([u, v], -1))
            self._dirs[key] = np.concatenate([n, np.ones(n.shape[:-1] + (1,))], -1).astype(np.float32)
        return self._dirs[key]

    def cast(self, camera: Camera, bodies: list[BodyMesh]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cast one ray per pixel.

        Parameters
        ----------
        camera : Camera
        bodies : list of BodyMesh
            Posed bodies; body ``i`` gets subject id ``i + 1``.

        Returns
        -------
        labels : ndarray of shape (H, W), uint8
            Part id of the nearest body surface (0 = no body).
        subject : ndarray of shape (H, W), uint8
            Subject id (0 = none).
        depth : ndarray of shape (H, W), float32
            Camera-frame z of the nearest surface in metres, NaN where nothing is hit.
        """
        d_cam = self._cam_dirs(camera)
        h, w = d_cam.shape[:2]
        rays = np.empty((h, w, 6), np.float32)
        rays[..., :3] = camera.center
        rays[..., 3:] = d_cam @ camera.R.astype(np.float32)  # unnormalised: t_hit is camera z directly
        # the surroundings are static: their depth is cast once per camera
        key = (camera.K.tobytes(), camera.dist.tobytes(), camera.cam_from_world.tobytes())
        if key not in self._env_depth:
            env = o3d.t.geometry.RaycastingScene()
            for s in self.surfaces:
                env.add_triangles(o3d.core.Tensor(s.vertices.astype(np.float32)),
                                  o3d.core.Tensor(s.triangles.astype(np.uint32)))
            self._env_depth[key] = env.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
        env_t = self._env_depth[key]
        labels = np.zeros((h, w), np.uint8)
        subject = np.zeros((h, w), np.uint8)
        t = env_t
        if bodies:
            scene = o3d.t.geometry.RaycastingScene()
            for b in bodies:
                scene.add_triangles(o3d.core.Tensor(b.vertices.astype(np.float32)),
                                    o3d.core.Tensor(b.triangles.astype(np.uint32)))
            ans = scene.cast_rays(o3d.core.Tensor(rays))
            tb = ans["t_hit"].numpy()
            gid = ans["geometry_ids"].numpy().astype(np.int64)
            pid = ans["primitive_ids"].numpy().astype(np.int64)
            front = np.isfinite(tb) & (tb <= env_t)  # inf where no surroundings are hit
            for i, b in enumerate(bodies):
                sel = front & (gid == i)
                labels[sel] = b.triangle_parts[pid[sel]]
                subject[sel] = i + 1
            t = np.where(front, tb, env_t)
        depth = np.where(np.isfinite(t), t, np.nan).astype(np.float32)
        return labels, subject, depth


def _packed(texture: np.ndarray) -> np.ndarray:
    """``texture`` (H, W, 3) uint8 as one uint32 per texel (RGB and a zero byte), (H, W): one load per gather."""
    h, w = texture.shape[:2]
    rgba = np.zeros((h, w, 4), np.uint8)
    rgba[..., :3] = texture
    return rgba.view(np.uint32)[..., 0]


def _bilinear(texture: np.ndarray, uv: np.ndarray, packed: np.ndarray | None = None,
              out: np.ndarray | None = None) -> np.ndarray:
    """Sample ``texture`` (H, W, 3) uint8 at ``uv`` (N, 2) in [0, 1] (v down): (N, 3) float32 in [0, 255].

    ``packed``: :func:`_packed` of ``texture`` when the caller keeps it;
    ``out`` (N, 3) float32, optional: written (and returned).  The four
    neighbours are gathered as uint8 texels (a quarter of a float32 copy's
    memory traffic) and blended one channel at a time (long loops instead of
    rows of three); every value is computed as a whole-array blend of a float32
    copy would.
    """
    h, w = texture.shape[:2]
    flat = (_packed(texture) if packed is None else packed).reshape(-1)
    x = np.clip(uv[:, 0] * w - 0.5, 0, w - 1)
    y = np.clip(uv[:, 1] * h - 0.5, 0, h - 1)
    x0 = np.floor(x).astype(np.int64)
    y0 = np.floor(y).astype(np.int64)
    x1 = np.minimum(x0 + 1, w - 1)
    y1 = np.minimum(y0 + 1, h - 1)
    fx = (x - x0).astype(np.float32)
    fy = (y - y0).astype(np.float32)
    gx, gy = 1 - fx, 1 - fy
    r0, r1 = y0 * w, y1 * w
    texels = [flat[i].view(np.uint8).reshape(-1, 4) for i in (r0 + x0, r0 + x1, r1 + x0, r1 + x1)]
    out = np.empty((len(x), 3), np.float32) if out is None else out
    for c in range(3):
        t00, t01, t10, t11 = (q[:, c].astype(np.float32) for q in texels)
        out[:, c] = (t00 * gx + t01 * fx) * gy + (t10 * gx + t11 * fx) * fy
    return out


#: Rays shaded per block when a background plate is coloured (keeps the temporaries in the CPU's cache;
#: every ray's colour is computed by the same operations whatever the block size).
SHADE_BLOCK = 1 << 15
#: Ray-direction grids kept per renderer (one per distinct intrinsics; a path through cameras with
#: interpolated focal lengths has a new one per view, so the cache is bounded).
DIR_CACHE_SIZE = 4


class RaycastRenderer:
    """Colour renderer built on Open3D's ray caster (same interface as :class:`SceneRenderer`).

    Each pixel is the average of ``supersample**2`` rays on a regular sub-pixel
    grid; vertex colours are interpolated with the hit's barycentric
    coordinates and textures sampled bilinearly.  Deterministic, thread-safe
    and independent of the graphics driver, so the generator's tests run
    the same everywhere; :class:`SceneRenderer` (Open3D's off-screen
    rasteriser) gives the same picture up to edge anti-aliasing.

    Parameters
    ----------
    size : tuple of int
    surfaces : list of Surface
    background : tuple of float
        RGB in [0, 1] where nothing is hit.
    supersample : int
        Rays per pixel along each axis.
    """

    def __init__(self, size: tuple[int, int], surfaces: list[Surface] = (), background=(0, 0, 0),
                 supersample: int = 2):
        w, h = (int(v) for v in size)
        if w <= 0 or h <= 0:
            raise InputError("RaycastRenderer: size", "positive (width, height)", f"{size}")
        if supersample < 1:
            raise InputError("RaycastRenderer: supersample", "an integer >= 1", str(supersample))
        self.size = (w, h)
        self.background = np.asarray(background, np.float32) * 255.0
        self.surfaces = list(surfaces)
        self.ss = int(supersample)
        self._plates: dict = {}
        self._bodies: list[tuple[BodyMesh, np.ndarray]] = []
        self._dir_cache: dict = {}
        self._tables: dict = {}

    def _subpixel_dirs(self, camera: Camera, x0=0, y0=0, x1=None, y1=None, out: np.ndarray | None = None
                       ) -> np.ndarray:
        """World ray directions (unnormalised, camera z = 1) of the sub-pixel grid of a pixel window.

        ``out`` (h*s, w*s, 3) float32, optional: written in place (and returned).
        """
        w, h = self.size
        x1 = w if x1 is None else x1
        y1 = h if y1 is None else y1
        s = self.ss
        key = (camera.K.tobytes(), camera.dist.tobytes())
        if key not in self._dir_cache:
            off = (np.arange(s) + 0.5) / s - 0.5
            xs = (np.arange(w)[:, None] + off[None, :]).ravel()
            ys = (np.arange(h)[:, None] + off[None, :]).ravel()
            if camera.has_distortion:
                u, v = np.meshgrid(xs, ys)
                n = camera.undistort_points(np.stack([u, v], -1)).astype(np.float32)
            else:  # Camera.undistort_points' pinhole inverse, by rows and columns (the same values)
                fx, skew, cx = camera.K[0]
                y = (ys - camera.K[1, 2]) / camera.K[1, 1]
                n = np.empty((len(ys), len(xs), 2), np.float32)
                n[..., 0] = (xs[None, :] - cx - skew * y[:, None]) / fx
                n[..., 1] = y[:, None]
            while len(self._dir_cache) >= DIR_CACHE_SIZE:
                self._dir_cache.pop(next(iter(self._dir_cache)))
            self._dir_cache[key] = n
        n = self._dir_cache[key][y0 * s:y1 * s, x0 * s:x1 * s]
        R = camera.R.astype(np.float32)
        if out is None:
            return n[..., 0:1] * R[0] + n[..., 1:2] * R[1] + R[2]  # (h*s, w*s, 3): R^T (x, y, 1)
        for k in range(3):  # the same sums, one component at a time (long loops instead of rows of three)
            out[..., k] = n[..., 0] * R[0, k] + n[..., 1] * R[1, k] + R[2, k]
        return out

    @staticmethod
    def _downsample(img: np.ndarray, s: int) -> np.ndarray:
        """The mean of each s x s block, (H/s, W/s[, C]) float32.

        A colour image (H, W, 3) is summed block element by block element in
        row-major order, the order of NumPy's ``mean`` over the block axes
        (the same values, ~3x faster; ``tests/synthetic/test_plates_golden.py``
        checks it); other arrays by ``mean``.
        """
        H, W = img.shape[:2]
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.float32:  # (mean's order depends on the layout)
            return img.reshape(H // s, s, W // s, s, *img.shape[2:]).mean(axis=(1, 3))
        acc = img[::s, ::s].copy()
        for k in range(1, s * s):
            acc += img[k // s::s, k % s::s]
        return np.true_divide(acc, np.intp(s * s), out=acc, casting="unsafe")  # as ``mean`` divides

    def _cast(self, scene, camera: Camera, dirs: np.ndarray):
        rays = np.empty(dirs.shape[:-1] + (6,), np.float32)
        rays[..., :3] = camera.center
        rays[..., 3:] = dirs
        return scene.cast_rays(o3d.core.Tensor(rays))

    def prepare(self, cameras) -> None:
        """Compute the background plates (and their depth) of ``cameras``."""
        for cam in cameras:
            key = (cam.K.tobytes(), cam.cam_from_world.tobytes())
            if key not in self._plates:
                self._plates[key] = self._plate(cam)

    def _plate(self, cam: Camera, depth: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """The surroundings seen by ``cam``: (H, W, 3) float32 colour and the sub-pixel rays' depth (None
        unless ``depth``)."""
        scene = o3d.t.geometry.RaycastingScene()
        for s in self.surfaces:
            scene.add_triangles(o3d.core.Tensor(s.vertices.astype(np.float32)),
                                o3d.core.Tensor(s.triangles.astype(np.uint32)))
        w, h = self.size
        rays = np.empty((h * self.ss, w * self.ss, 6), np.float32)
        for k in range(3):  # one component at a time (long loops instead of rows of three)
            rays[..., k] = cam.center[k]
        self._subpixel_dirs(cam, out=rays[..., 3:])
        ans = scene.cast_rays(o3d.core.Tensor(rays))
        del rays
        t = ans["t_hit"].numpy()
        col = np.empty(t.shape + (3,), np.float32)
        for k in range(3):
            col[..., k] = self.background[k]
        flat = (t.reshape(-1), ans["geometry_ids"].numpy().reshape(-1), ans["primitive_ids"].numpy().reshape(-1),
                ans["primitive_uvs"].numpy().reshape(-1, 2), col.reshape(-1, 3))
        for a in range(0, t.size, SHADE_BLOCK):
            self._shade(*(f[a:a + SHADE_BLOCK] for f in flat))
        return self._downsample(col, self.ss), np.where(np.isfinite(t), t, np.inf) if depth else None

    def _shade(self, t: np.ndarray, gid: np.ndarray, pid: np.ndarray, bary: np.ndarray, col: np.ndarray) -> None:
        """Colour a block of rays (N,) where they hit a surface; ``col`` (N, 3) float32 is written in place.

        Per ray: the barycentric blend of the hit triangle's corner colours or
        texture coordinates (one component at a time), then the texture's
        bilinear sample.
        """
        hit = np.isfinite(t)
        for i, s in enumerate(self.surfaces):
            sel = hit & (gid == i)
            if sel.all():
                sel = slice(None)  # the same rays, without the boolean gathers
            elif not sel.any():
                continue
            corners, packed = self._surface_tables(i)
            p = pid[sel]
            b1, b2 = bary[sel, 0], bary[sel, 1]
            b0 = 1.0 - b1 - b2
            v = np.empty((len(p), len(corners)), corners[0][0].dtype)
            for k, (c0, c1, c2) in enumerate(corners):
                v[:, k] = b0 * c0[p] + b1 * c1[p] + b2 * c2[p]
            if packed is None:
                col[sel] = v
            elif isinstance(sel, slice):
                _bilinear(s.texture, v, packed, out=col)
            else:
                col[sel] = _bilinear(s.texture, v, packed)

    def _surface_tables(self, i: int) -> tuple[list, np.ndarray | None]:
        """Surface ``i``'s corner values per triangle, per component ``[(c0, c1, c2)]`` of (T,) arrays (float32
        colours 0..255, or float64 texture coordinates), and its :func:`_packed` texture (None: vertex
        colours); kept."""
        if i not in self._tables:
            s = self.surfaces[i]
            if s.texture is None:
                table, packed = (np.asarray(s.vertex_colors, np.float32) * 255.0)[s.triangles], None
            else:
                table, packed = np.asarray(s.uvs, np.float64)[s.triangles], _packed(s.texture)
            comps = [tuple(np.ascontiguousarray(table[:, j, k]) for j in range(3)) for k in range(table.shape[2])]
            self._tables[i] = (comps, packed)
        return self._tables[i]

    def background_plate(self, camera: Camera, keep: bool = True) -> np.ndarray:
        """The surroundings alone, (H, W, 3) float32 in [0, 255] (cached with their depth unless ``keep`` is
        False: a camera seen once, e.g. a view of a camera path)."""
        key = (camera.K.tobytes(), camera.cam_from_world.tobytes())
        if key not in self._plates and not keep:
            return self._plate(camera, depth=False)[0]
        self.prepare([camera])
        return self._plates[key][0]

    def set_bodies(self, meshes: list[tuple[BodyMesh, np.ndarray]]) -> None:
        """Replace the posed bodies: a list of (mesh, vertex colours (V, 3) in [0, 1])."""
        self._bodies = list(meshes)

    def render(self, camera: Camera) -> np.ndarray:
        """Colour image seen by ``camera``, (H, W, 3) uint8 RGB."""
        if tuple(camera.size) != self.size:
            raise InputError(f"render: camera {camera.name!r} size", f"{self.size}", f"{camera.size}")
        self.prepare([camera])
        plate, env_t = self._plates[(camera.K.tobytes(), camera.cam_from_world.tobytes())]
        out = plate.copy()
        if not self._bodies:
            return np.clip(out + 0.5, 0, 255).astype(np.uint8)
        # restrict the rays to the bodies' image bounding box
        w, h = self.size
        verts = np.concatenate([m.vertices for m, _ in self._bodies])
        uv = camera.project(verts)
        uv = uv[np.isfinite(uv).all(1)]
        if len(uv) == 0:
            return np.clip(out + 0.5, 0, 255).astype(np.uint8)
        x0 = int(np.clip(np.floor(uv[:, 0].min()) - 1, 0, w))
        x1 = int(np.clip(np.ceil(uv[:, 0].max()) + 2, 0, w))
        y0 = int(np.clip(np.floor(uv[:, 1].min()) - 1, 0, h))
        y1 = int(np.clip(np.ceil(uv[:, 1].max()) + 2, 0, h))
        if x1 <= x0 or y1 <= y0:
            return np.clip(out + 0.5, 0, 255).astype(np.uint8)
        scene = o3d.t.geometry.RaycastingScene()
        for m, _ in self._bodies:
            scene.add_triangles(o3d.core.Tensor(m.vertices.astype(np.float32)),
                                o3d.core.Tensor(m.triangles.astype(np.uint32)))
        dirs = self._subpixel_dirs(camera, x0, y0, x1, y1)
        ans = self._cast(scene, camera, dirs)
        t = ans["t_hit"].numpy()
        gid = ans["geometry_ids"].numpy().astype(np.int64)
        pid = ans["primitive_ids"].numpy().astype(np.int64)
        bary = ans["primitive_uvs"].numpy()
        s = self.ss
        env_crop = env_t[y0 * s:y1 * s, x0 * s:x1 * s]
        hit = np.isfinite(t) & (t < env_crop)
        col = np.zeros(t.shape + (3,), np.float32)
        for i, (m, colors) in enumerate(self._bodies):
            sel = hit & (gid == i)
            if not sel.any():
                continue
            tri = m.triangles[pid[sel]]
            vc = np.asarray(colors, np.float32) * 255.0
            b1, b2 = bary[sel, 0:1], bary[sel, 1:2]
            col[sel] = (1.0 - b1 - b2) * vc[tri[:, 0]] + b1 * vc[tri[:, 1]] + b2 * vc[tri[:, 2]]
        alpha = self._downsample(hit.astype(np.float32), s)
        layer = self._downsample(col, s)  # premultiplied by coverage
        out[y0:y1, x0:x1] = layer + (1.0 - alpha[..., None]) * plate[y0:y1, x0:x1]
        return np.clip(out + 0.5, 0, 255).astype(np.uint8)
