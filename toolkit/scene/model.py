"""The scene model: the sources' empty views carried on the proxy into any camera.

:meth:`SceneModel.render` draws the static scene seen by a camera: each pixel's
ray meets the proxy (:class:`~toolkit.scene.SceneProxy`) at a point, every
source camera that sees that point in its image gives its background colour
there, and the colours are blended view-dependently: a source's weight is its
confidence in that pixel (:class:`~toolkit.scene.SourceBackground`) times
``1 / (1 + angle / ANGLE_SCALE_DEG)^2``, the angle being between the view's ray
and the source's ray at the point (the source that looks most alike counts
most, as in unstructured lumigraph rendering).  A place no source saw empty
(someone stood there in every sample of every camera that sees it) and a place
no source sees at all are filled from their surroundings (:func:`_fill`), not
drawn with a person's ghost nor left black.

:meth:`SceneModel.carry` draws a given image of ONE source the same way (the
"nearest source carried through the proxy" baseline: the people in it lie flat
on the ground).

:func:`toolkit.scene.build.build_scene_model` estimates it from a dataset's videos (frames
sampled over the run, the detected people left out) and
:meth:`SceneModel.save` / :meth:`SceneModel.load` keep it in a run folder::

    scene/scene.json                 proxy, sources, samples, evidence of the radius
    scene/background/<camera>.png    the camera's estimated empty view, RGB uint8
    scene/confidence/<camera>.png    its confidence, uint8 (255 = 1)
"""

from __future__ import annotations

import hashlib
import json
from collections import OrderedDict
from pathlib import Path

import cv2
import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.scene.backgrounds import SourceBackground
from toolkit.scene.proxy import SURFACE_NONE, SceneProxy

__all__ = ["SceneModel", "ANGLE_SCALE_DEG", "RENDERS_KEPT"]

#: Angle (degrees) at which a source's weight has fallen to a quarter.
ANGLE_SCALE_DEG = 4.0
#: Renders of fixed cameras kept (an LRU; a camera path's views are drawn once each).
RENDERS_KEPT = 8
#: Source-to-camera maps kept by :meth:`SceneModel.carry` (about 8 MB each at 1280 x 720; a run carries
#: one source into each fixed camera every frame).
CARRIES_KEPT = 4
#: Pixel-ray tables kept (:meth:`SceneModel._pixel_rays`: one per camera intrinsics and size, 22 MB at
#: 1280 x 720; a camera path's views share theirs).
RAY_TABLES_KEPT = 4
#: A source's image border, undistorted, is widened by this share when deciding what it sees.
FRUSTUM_MARGIN = 0.02


def _frustum(cam: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Bounds ``(lo, hi)`` of the normalised image coordinates (x/z, y/z) a camera sees."""
    w, h = cam.size
    s = np.linspace(-0.5, 1.0, 65)
    border = np.concatenate([np.stack([s * w, np.full_like(s, -0.5)], 1), np.stack([s * w, np.full_like(s, h - 0.5)], 1),
                             np.stack([np.full_like(s, -0.5), s * h], 1), np.stack([np.full_like(s, w - 0.5), s * h], 1)])
    n = cam.undistort_points(border)
    lo, hi = np.nanmin(n, 0), np.nanmax(n, 0)
    pad = FRUSTUM_MARGIN * (hi - lo)
    return lo - pad, hi + pad


def _fill(img: np.ndarray, hole: np.ndarray) -> np.ndarray:
    """``img`` (H, W, 3) float32 with ``hole`` (H, W) bool filled from the surroundings.

    Push-pull: the seen pixels are averaged down an image pyramid (each level the
    mean of the seen pixels below it) until every pixel of a level has some, and the
    holes take the colour of the coarsest level that saw around them, blended up level
    by level: a smooth guess of a large unseen wall or floor, without the streaks of
    inpainting along a hole's border.
    """
    seen = (~hole).astype(np.float32)
    levels = [(img * seen[..., None], seen)]
    while levels[-1][1].shape[0] > 2 and levels[-1][1].shape[1] > 2 and (levels[-1][1] <= 0).any():
        c, w = levels[-1]
        levels.append((cv2.pyrDown(c), cv2.pyrDown(w)))
    c, w = levels[-1]
    fill = c / np.maximum(w, 1e-6)[..., None]
    if (w <= 0).any():  # nothing seen at all at the coarsest level: the mean of everything seen
        fill[w <= 0] = (img[~hole].mean(0) if (~hole).any() else 0.0)
    for c, w in reversed(levels[:-1]):
        up = cv2.pyrUp(fill, dstsize=(w.shape[1], w.shape[0]))
        a = np.clip(w, 0.0, 1.0)[..., None]
        fill = a * (c / np.maximum(w, 1e-6)[..., None]) + (1.0 - a) * up
    out = img.copy()
    out[hole] = fill[hole]
    return out


def _key(cam: Camera) -> bytes:
    return cam.K.tobytes() + cam.dist.tobytes() + cam.cam_from_world.tobytes() + np.asarray(cam.size).tobytes()


class SceneModel:
    """The static scene of a capture: source backgrounds on a proxy.

    Parameters
    ----------
    rig : Rig
        The source cameras (a held-out camera is not among them).
    backgrounds : dict of str -> SourceBackground
        One per camera of ``rig``.
    proxy : SceneProxy
    evidence : dict, optional
        How the proxy was chosen (kept in ``scene.json``).
    fill_holes : bool
        Fill the pixels no source sees empty from their surroundings (:func:`_fill`) rather than
        leaving them black.
    """

    def __init__(self, rig: Rig, backgrounds: dict, proxy: SceneProxy, evidence: dict | None = None,
                 fill_holes: bool = True):
        self.fill_holes = bool(fill_holes)
        missing = [c for c in rig.names if c not in backgrounds]
        if missing:
            raise InputError("SceneModel: backgrounds", f"one per source camera {rig.names}", f"none for {missing}")
        for cam in rig:
            b = backgrounds[cam.name]
            if b.image.shape[:2] != cam.size[::-1]:
                raise InputError(f"SceneModel: background of {cam.name}", f"an image of {cam.size[0]}x{cam.size[1]}",
                                 f"{b.image.shape[1]}x{b.image.shape[0]}")
        self.rig, self.backgrounds, self.proxy = rig, dict(backgrounds), proxy
        self.evidence = dict(evidence or {})
        self._frusta = {cam.name: _frustum(cam) for cam in rig}
        self._kept: OrderedDict = OrderedDict()
        self._carried: OrderedDict = OrderedDict()
        self._rays: OrderedDict = OrderedDict()
        self._rgbc: dict = {}  # per source, its background and confidence as one (H, W, 4) float32 image
        self._store = None  # SharedStore of the run's processes (share_views)
        self._shared: dict = {}  # _key(camera) -> the store's key, for the cameras of share_views

    # ------------------------------------------------------------------ rendering
    def _geometry(self, camera: Camera):
        """The proxy points (N, 3), surfaces (N,) and unit view rays (N, 3) of the camera's pixels."""
        d = camera.cam_from_world[:3, :3]
        d = self._pixel_rays(camera) @ d  # R^T d for row vectors, as Camera.rays
        d /= np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])[:, None]
        pts, surf = self.proxy.intersect(np.broadcast_to(camera.center, d.shape), d)
        return pts, surf, d

    def _pixel_rays(self, camera: Camera) -> np.ndarray:
        """The camera's pixel rays in its own frame, ``(x/z, y/z, 1)`` (N, 3) float64, read-only: the same for
        every camera of these intrinsics (a camera path's views), so undistorted once (:data:`RAY_TABLES_KEPT`)."""
        key = camera.K.tobytes() + camera.dist.tobytes() + np.asarray(camera.size).tobytes()
        if key in self._rays:
            self._rays.move_to_end(key)
            return self._rays[key]
        w, h = camera.size
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        n = camera.undistort_points(np.stack([u, v], -1).reshape(-1, 2))
        rays = np.concatenate([n, np.ones((n.shape[0], 1))], axis=1)
        rays.flags.writeable = False
        self._rays[key] = rays
        while len(self._rays) > RAY_TABLES_KEPT:
            self._rays.popitem(last=False)
        return rays

    def _sample(self, cam: Camera, pts: np.ndarray, shape: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Source ``cam``'s background colour (N, 3) and confidence (N,) at the proxy points, float32, and
        where it sees them (N,) bool: one remap of both (a four-channel image kept per source; each channel
        is resampled on its own, the same values as two remaps)."""
        mx, my, sees = self._maps(cam, pts, shape)
        both = self._rgbc.get(cam.name)
        if both is None:
            b = self.backgrounds[cam.name]
            both = self._rgbc[cam.name] = np.dstack([np.asarray(b.image, np.float32),
                                                      np.asarray(b.confidence, np.float32)])
        out = cv2.remap(both, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(pts.shape[0], 4)
        return out[:, :3], out[:, 3], sees

    def _maps(self, cam: Camera, pts: np.ndarray, shape: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where source ``cam`` sees the proxy points (N, 3): remap maps ``mx``, ``my`` of ``shape`` (float32
        pixels) and the points it sees (N,) bool."""
        pc = cam.to_cam(pts)
        lo, hi = self._frusta.get(cam.name) or _frustum(cam)
        with np.errstate(invalid="ignore", divide="ignore"):
            nx, ny = pc[:, 0] / pc[:, 2], pc[:, 1] / pc[:, 2]
            sees = (pc[:, 2] > 1e-6) & (nx >= lo[0]) & (nx <= hi[0]) & (ny >= lo[1]) & (ny <= hi[1])
        uv = np.full((pts.shape[0], 2), -1e4, np.float32)
        if sees.any():
            uv[sees] = cam.project_cam(pc[sees])
        sees &= np.isfinite(uv).all(1) & cam.in_image(uv)
        mx = np.ascontiguousarray(uv[:, 0].reshape(shape))
        my = np.ascontiguousarray(uv[:, 1].reshape(shape))
        return mx, my, sees

    def render(self, camera: Camera, with_surface: bool = False):
        """The static scene seen by ``camera``.

        Parameters
        ----------
        camera : Camera
            Any camera whose centre lies inside the proxy's cylinder.
        with_surface : bool
            Also return which surface each pixel shows.

        Returns
        -------
        image : ndarray of shape (H, W, 3) float32
            0..255 (0 where no source sees the pixel's proxy point).
        coverage : ndarray of shape (H, W) float32
            In [0, 1]: the best confidence among the sources seeing the pixel (0: none).
        surface : ndarray of shape (H, W) uint8
            Only with ``with_surface``: :data:`toolkit.scene.proxy.SURFACE_GROUND`, ``_WALL`` or ``_NONE``.
        """
        key = _key(camera)
        if not with_surface and key in self._kept:
            self._kept.move_to_end(key)
            return self._kept[key]
        if not with_surface and key in self._shared:
            got = self._store.get(self._shared[key])  # drawn by another process of the run (or waited for)
            if got is not None:
                return self._keep(key, (got["image"], got["coverage"]))
        w, h = camera.size
        pts, surf, view = self._geometry(camera)
        acc = np.zeros((pts.shape[0], 3), np.float64)
        wsum = np.zeros(pts.shape[0], np.float64)
        cover = np.zeros(pts.shape[0], np.float32)
        hit = surf != SURFACE_NONE
        for cam in self.rig:
            col, conf, sees = self._sample(cam, pts, (h, w))
            sees &= hit
            if not sees.any():
                continue
            # every pixel at once, the unseen ones weighted 0 (the same sums as over the seen ones alone)
            with np.errstate(invalid="ignore"):
                sx, sy, sz = (pts[:, k] - cam.center[k] for k in range(3))
                norm = np.sqrt(sx * sx + sy * sy + sz * sz)
                cos = (sx / norm) * view[:, 0] + (sy / norm) * view[:, 1] + (sz / norm) * view[:, 2]
                ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
                wt = np.where(sees, conf / (1.0 + ang / ANGLE_SCALE_DEG) ** 2, 0.0)
            acc += wt[:, None] * np.where(sees[:, None], col, np.float32(0))
            wsum += wt
            np.maximum(cover, np.where(sees, conf, np.float32(0)), out=cover)
        ok = wsum > 0
        with np.errstate(invalid="ignore", divide="ignore"):
            img = np.where(ok[:, None], acc / wsum[:, None], 0.0).astype(np.float32)
        img = img.reshape(h, w, 3)
        if self.fill_holes and not ok.all() and ok.any():
            img = _fill(img, ~ok.reshape(h, w))
        out = (img, cover.reshape(h, w))
        if with_surface:
            for a in out:
                a.flags.writeable = False
            return out + (surf.reshape(h, w),)
        return self._keep(key, out)

    def _keep(self, key: bytes, out: tuple) -> tuple:
        """Keep a fixed camera's render (:data:`RENDERS_KEPT`, read-only) and return it."""
        for a in out:
            a.flags.writeable = False
        self._kept[key] = out
        while len(self._kept) > RENDERS_KEPT:
            self._kept.popitem(last=False)
        return out

    def share_views(self, cameras: list, store) -> int:
        """Draw the views of fixed ``cameras`` into a store the processes of a run share; returns how many
        this process drew.

        Every worker of a run calls it while it warms up: each view is drawn once in all, by whichever
        process claims it first (:class:`toolkit.io.shared_store.SharedStore`), and :meth:`render` of
        these cameras then reads it from the store (the same float32 values), waiting while another
        process still draws it.

        Parameters
        ----------
        cameras : list of Camera
            The run's fixed cameras (novel, held-out, bird's-eye).
        store : path or SharedStore
            A folder of the run (removed when the run is finished).
        """
        from toolkit.io.shared_store import SharedStore

        self._store = store if isinstance(store, SharedStore) else SharedStore(store)
        digest = self._digest()
        drawn = 0
        for cam in cameras:
            key = _key(cam)
            stored = hashlib.sha1(digest + key).hexdigest()
            drawn += self._store.compute(stored, lambda cam=cam: dict(zip(("image", "coverage"), self.render(cam))))
            self._shared[key] = stored  # after drawing it: render() of a camera this process claimed draws it
        return drawn

    def _digest(self) -> bytes:
        """What the model's views depend on: its sources' cameras and backgrounds, its proxy (SHA-1)."""
        h = hashlib.sha1(json.dumps(self.proxy.to_json(), sort_keys=True, default=str).encode())
        h.update(str(self.fill_holes).encode())
        for cam in self.rig:
            b = self.backgrounds[cam.name]
            h.update(_key(cam))
            h.update(np.ascontiguousarray(b.image, np.float32).tobytes())
            h.update(np.ascontiguousarray(b.confidence, np.float32).tobytes())
        return h.digest()

    def nearest_source(self, camera: Camera) -> str:
        """The source camera whose view of the proxy's centre is closest in angle to ``camera``'s."""
        c = np.r_[np.asarray(self.proxy.centre, float), self.proxy.ground_z + 1.0]
        v = c - camera.center
        v /= np.linalg.norm(v)
        best, name = -2.0, self.rig.names[0]
        for cam in self.rig:
            s = c - cam.center
            s /= np.linalg.norm(s)
            if float(s @ v) > best:
                best, name = float(s @ v), cam.name
        return name

    def carry(self, camera: Camera, source: str, image: np.ndarray) -> np.ndarray:
        """One image of source camera ``source`` carried into ``camera`` through the proxy.

        Returns
        -------
        ndarray of shape (H, W, 3) uint8
            Black where the source does not see the pixel's proxy point.
        """
        w, h = camera.size
        mx, my, sees = self._carry_maps(camera, source)
        col = cv2.remap(np.asarray(image, np.float32), mx, my, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE).reshape(h * w, -1)
        out = np.zeros((h * w, 3), np.float32)
        out[sees] = col[sees]
        return np.clip(out.reshape(h, w, 3) + 0.5, 0, 255).astype(np.uint8)

    def _carry_maps(self, camera: Camera, source: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where source ``source`` sees ``camera``'s pixels on the proxy: remap maps ``mx``, ``my`` (H, W) float32
        and the pixels it sees (H * W,) bool; kept for a fixed camera (:data:`CARRIES_KEPT`)."""
        key = (_key(camera), source)
        if key in self._carried:  # a fixed camera (novel, held out): its maps are the same every frame
            self._carried.move_to_end(key)
            return self._carried[key]
        w, h = camera.size
        pts, surf, _ = self._geometry(camera)
        mx, my, sees = self._maps(self.rig[source], pts, (h, w))
        sees &= surf != SURFACE_NONE
        self._carried[key] = (mx, my, sees)
        while len(self._carried) > CARRIES_KEPT:
            self._carried.popitem(last=False)
        return mx, my, sees

    def prepare(self, cameras: list, carry: bool = True) -> None:
        """Draw the views of fixed ``cameras`` (a run's novel and held-out cameras, the bird's-eye view) and,
        with ``carry``, their maps from the nearest source, ahead of the first frame that needs them (a
        worker's warm-up): kept, the frames then find them (:meth:`render`, :meth:`carry`)."""
        for cam in cameras:
            self.render(cam)
            if carry:
                self._carry_maps(cam, self.nearest_source(cam))

    def report(self, observer) -> None:
        """Show the model: each source's empty view and confidence over its camera
        (``scene/background``, ``scene/confidence``), the proxy's outline in the world
        (``scene/proxy``: the ground's edge, the wall up to 3 m) and how it was chosen."""
        import json as _json

        from toolkit.observe import as_observer

        obs = as_observer(observer)
        for cam in self.rig:
            b = self.backgrounds[cam.name]
            obs.report("image", camera=cam.name, image=np.clip(b.image + 0.5, 0, 255).astype(np.uint8),
                       name="scene/background")
            obs.report("image", camera=cam.name, image=np.clip(np.rint(b.confidence * 255), 0, 255).astype(np.uint8),
                       name="scene/confidence")
        c, r, z = np.asarray(self.proxy.centre, float), float(self.proxy.radius_m), float(self.proxy.ground_z)
        th = np.linspace(0, 2 * np.pi, 97)
        ring = np.stack([c[0] + r * np.cos(th), c[1] + r * np.sin(th), np.full_like(th, z)], 1)
        posts = [np.array([[c[0] + r * np.cos(a), c[1] + r * np.sin(a), z],
                           [c[0] + r * np.cos(a), c[1] + r * np.sin(a), z + 3.0]]) for a in th[:-1:12]]
        obs.report("lines3d", name="scene/proxy", strips=[ring, ring + [0, 0, 3.0], *posts])
        obs.report("text", name="scene/proxy", text=_json.dumps({"proxy": self.proxy.to_json(),
                                                                   "evidence": self.evidence}, default=str))

    # ------------------------------------------------------------------ storage
    def save(self, folder: str | Path) -> Path:
        """Write ``scene.json`` and the backgrounds into ``folder`` (``scene.json`` last)."""
        from toolkit.io import atomic_write_png, atomic_write_text

        folder = Path(folder)
        for name, b in self.backgrounds.items():
            atomic_write_png(folder / "background" / f"{name}.png", np.clip(b.image + 0.5, 0, 255).astype(np.uint8))
            atomic_write_png(folder / "confidence" / f"{name}.png",
                             np.clip(np.rint(b.confidence * 255), 0, 255).astype(np.uint8))
        info = {"sources": self.rig.names, "samples": {n: b.samples for n, b in self.backgrounds.items()},
                "proxy": self.proxy.to_json(), "evidence": self.evidence}
        return atomic_write_text(folder / "scene.json", json.dumps(info, indent=2, allow_nan=True))

    @classmethod
    def load(cls, folder: str | Path, rig: Rig) -> "SceneModel":
        """The model saved in ``folder`` for the cameras ``rig`` (the run's calibration)."""
        from toolkit.io.frames import read_png

        folder = Path(folder)
        path = folder / "scene.json"
        try:
            info = json.loads(path.read_text())
        except (OSError, ValueError) as e:
            raise InputError(str(path), "a scene model's scene.json", str(e)) from e
        if sorted(info.get("sources", [])) != sorted(rig.names):
            raise InputError(f"{path}: sources", f"the run's cameras {rig.names}", repr(info.get("sources")))
        bgs = {}
        for cam in rig:
            img = read_png(folder / "background" / f"{cam.name}.png")
            conf = read_png(folder / "confidence" / f"{cam.name}.png")
            bgs[cam.name] = SourceBackground(np.asarray(img, np.float32), np.asarray(conf, np.float32) / 255.0,
                                             int(info.get("samples", {}).get(cam.name, 0)))
        return cls(rig, bgs, SceneProxy.from_json(info.get("proxy", {}), str(path)), info.get("evidence"))
