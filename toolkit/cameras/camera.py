"""Pinhole camera with lens distortion in OpenCV convention.

Axes inside the toolkit are OpenCV's: x right, y down, z forward (camera frame);
the world frame is z up with the ground plane at z = 0.  Poses are
``cam_from_world`` 4x4 matrices mapping world points (metres) to camera points.
Pixel coordinates put the centre of the top-left pixel at (0, 0).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from toolkit.errors import InputError, check_shape


def distort_to_pixels(points_cam: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Pixels of camera-frame points through OpenCV's lens model, as ``cv2.projectPoints`` computes them.

    The rational model with thin-prism terms (up to 12 coefficients ``k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3
    s4``) is evaluated in NumPy with OpenCV's order of operations: the same values bit for bit, about
    fifteen times faster on the millions of points of an image's rays (``cv2.projectPoints`` loops point
    by point).  A tilted sensor (14 coefficients with ``tauX`` or ``tauY`` not 0) goes to OpenCV.

    Parameters
    ----------
    points_cam : ndarray of shape (N, 3)
        Points in the camera frame, metres (``z`` > 0 for a meaningful pixel).
    K : ndarray of shape (3, 3)
        Intrinsics; as in OpenCV, the skew ``K[0, 1]`` is not used.
    dist : ndarray of shape (D,)
        OpenCV distortion coefficients, ``D`` in 4, 5, 8, 12, 14.

    Returns
    -------
    ndarray of shape (N, 2)
        Pixels (float64).
    """
    pc = np.asarray(points_cam, np.float64).reshape(-1, 3)
    d = np.asarray(dist, np.float64).ravel()
    if d.size > 12 and np.any(d[12:] != 0):
        uv, _ = cv2.projectPoints(pc.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, d)
        return uv.reshape(-1, 2)
    k = np.zeros(12)
    k[:d.size] = d[:12]
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(pc[:, 2] != 0, 1.0 / pc[:, 2], 1.0)
    x, y = pc[:, 0] * z, pc[:, 1] * z
    r2 = x * x + y * y
    r4 = r2 * r2
    r6 = r4 * r2
    a1 = 2 * x * y
    a2 = r2 + 2 * x * x
    a3 = r2 + 2 * y * y
    cd = 1 + k[0] * r2 + k[1] * r4 + k[4] * r6
    ic = 1.0 / (1 + k[5] * r2 + k[6] * r4 + k[7] * r6)
    # x * cdist * icdist2 in OpenCV's order: (x * cdist) * icdist2
    xd = x * cd * ic + k[2] * a1 + k[3] * a2 + k[8] * r2 + k[9] * r4
    yd = y * cd * ic + k[2] * a3 + k[3] * a1 + k[10] * r2 + k[11] * r4
    return np.stack([xd * K[0, 0] + K[0, 2], yd * K[1, 1] + K[1, 2]], axis=1)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=np.float64, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Camera:
    """A calibrated pinhole camera.

    Parameters
    ----------
    name : str
        Camera name, unique in a rig.
    K : ndarray of shape (3, 3)
        Intrinsic matrix in pixels.
    dist : ndarray of shape (D,)
        OpenCV distortion coefficients (k1, k2, p1, p2[, k3, ...]); zeros if none.
    size : tuple of int
        Image ``(width, height)`` in pixels.
    cam_from_world : ndarray of shape (4, 4)
        Rigid transform from world (metres) to camera coordinates.
    """

    name: str
    K: np.ndarray
    dist: np.ndarray
    size: tuple[int, int]
    cam_from_world: np.ndarray

    def __post_init__(self):
        K = np.asarray(self.K, dtype=np.float64)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise InputError(f"camera {self.name!r}: K", "a finite 3x3 matrix with fx, fy > 0",
                             f"{K.tolist() if K.size <= 9 else K.shape}")
        dist = np.asarray(self.dist, dtype=np.float64).ravel()
        if dist.size not in (0, 4, 5, 8, 12, 14) or not np.all(np.isfinite(dist)):
            raise InputError(f"camera {self.name!r}: dist", "0, 4, 5, 8, 12 or 14 finite coefficients",
                             f"{dist.tolist()}")
        if dist.size == 0:
            dist = np.zeros(5)
        T = np.asarray(self.cam_from_world, dtype=np.float64)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InputError(f"camera {self.name!r}: cam_from_world", "a finite 4x4 matrix", f"shape {T.shape}")
        R = T[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise InputError(f"camera {self.name!r}: cam_from_world", "a rotation in the upper 3x3 block",
                             "a non-orthonormal or reflecting matrix")
        w, h = (int(v) for v in self.size)
        if w <= 0 or h <= 0:
            raise InputError(f"camera {self.name!r}: size", "positive (width, height)", f"{self.size}")
        object.__setattr__(self, "K", _frozen(K))
        object.__setattr__(self, "dist", _frozen(dist))
        object.__setattr__(self, "cam_from_world", _frozen(T))
        object.__setattr__(self, "size", (w, h))

    # ------------------------------------------------------------------ basics
    @classmethod
    def from_rt(cls, name, K, dist, size, rvec, tvec) -> "Camera":
        """Build a camera from a Rodrigues rotation and translation (world to camera)."""
        R, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = np.asarray(tvec, dtype=np.float64).ravel()
        return cls(name, K, dist, size, T)

    @classmethod
    def look_at(cls, name: str, eye, target, up=(0.0, 0.0, 1.0), *, size=(1280, 720),
                fov_x_deg: float | None = None, focal_px: float | None = None, dist=None) -> "Camera":
        """A camera at ``eye`` looking at ``target`` with the image y axis pointing down along ``-up``.

        Exactly one of ``fov_x_deg`` and ``focal_px`` must be given.
        """
        eye = np.asarray(eye, float)
        target = np.asarray(target, float)
        z = target - eye
        if np.linalg.norm(z) < 1e-9:
            raise InputError("look_at: target", "a point different from eye", f"{target.tolist()}")
        z /= np.linalg.norm(z)
        up = np.asarray(up, float)
        x = np.cross(z, up)
        if np.linalg.norm(x) < 1e-9:  # looking straight along up: pick any x
            x = np.cross(z, [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        R = np.stack([x, y, z])  # rows: camera axes in world
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = -R @ eye
        w, h = size
        if (fov_x_deg is None) == (focal_px is None):
            raise InputError("look_at", "exactly one of fov_x_deg and focal_px", f"{fov_x_deg=}, {focal_px=}")
        f = focal_px if focal_px is not None else 0.5 * w / np.tan(np.radians(fov_x_deg) / 2)
        K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
        return cls(name, K, np.zeros(5) if dist is None else dist, (w, h), T)

    @property
    def R(self) -> np.ndarray:
        """Rotation world to camera, (3, 3)."""
        return self.cam_from_world[:3, :3]

    @property
    def t(self) -> np.ndarray:
        """Translation world to camera, (3,) metres."""
        return self.cam_from_world[:3, 3]

    @property
    def rvec(self) -> np.ndarray:
        """Rodrigues vector of :attr:`R`, (3,)."""
        return cv2.Rodrigues(self.R)[0].ravel()

    @property
    def world_from_cam(self) -> np.ndarray:
        """Inverse of :attr:`cam_from_world`, (4, 4)."""
        T = np.eye(4)
        T[:3, :3] = self.R.T
        T[:3, 3] = -self.R.T @ self.t
        return T

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates, (3,) metres."""
        return -self.R.T @ self.t

    @property
    def forward(self) -> np.ndarray:
        """Viewing direction (optical axis) in world coordinates, unit (3,)."""
        return self.R[2].copy()

    @property
    def width(self) -> int:
        return self.size[0]

    @property
    def height(self) -> int:
        return self.size[1]

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0))

    @property
    def projection_matrix(self) -> np.ndarray:
        """P = K [R | t], (3, 4); ignores distortion."""
        return self.K @ self.cam_from_world[:3, :]

    def replace(self, **changes) -> "Camera":
        """A copy with some fields replaced."""
        fields = dict(name=self.name, K=self.K, dist=self.dist, size=self.size,
                      cam_from_world=self.cam_from_world)
        fields.update(changes)
        return Camera(**fields)

    def scaled(self, factor: float) -> "Camera":
        """The same camera with its image resized by ``factor`` (pixel-centre convention kept)."""
        K = self.K.copy()
        K[0, 0] *= factor
        K[1, 1] *= factor
        K[0, 1] *= factor
        K[0, 2] = (K[0, 2] + 0.5) * factor - 0.5
        K[1, 2] = (K[1, 2] + 0.5) * factor - 0.5
        w, h = self.size
        return self.replace(K=K, size=(int(round(w * factor)), int(round(h * factor))))

    # ------------------------------------------------------------- geometry
    def to_cam(self, points_world: np.ndarray) -> np.ndarray:
        """World points (..., 3) to camera coordinates (..., 3)."""
        p = np.asarray(points_world, dtype=np.float64)
        return p @ self.R.T + self.t

    def project(self, points_world: np.ndarray) -> np.ndarray:
        """Project world points to pixels, with distortion.

        Parameters
        ----------
        points_world : ndarray of shape (..., 3)
            Points in metres; NaN rows stay NaN.

        Returns
        -------
        ndarray of shape (..., 2)
            Pixel coordinates; NaN for NaN input and for points behind the camera.
        """
        p = np.asarray(points_world, dtype=np.float64)
        if p.shape[-1] != 3:
            raise InputError("project: points_world", "an array of shape (..., 3)", f"shape {p.shape}")
        shape = p.shape[:-1]
        pc = self.to_cam(p.reshape(-1, 3))
        out = np.full((pc.shape[0], 2), np.nan)
        ok = np.isfinite(pc).all(axis=1) & (pc[:, 2] > 1e-9)
        sel = slice(None) if ok.all() else ok  # all in front of the camera: the same values without the gathers
        if ok.any():
            out[sel] = self.project_cam(pc[sel])
        return out.reshape(*shape, 2)

    def project_cam(self, points_cam: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of points (N, 3) given in this camera's frame, in front of it (what :meth:`project`
        does after its ``to_cam``), with distortion (:func:`distort_to_pixels`)."""
        pc = np.asarray(points_cam, np.float64).reshape(-1, 3)
        if self.has_distortion:
            return distort_to_pixels(pc, self.K, self.dist)
        q = pc @ self.K.T
        return q[:, :2] / q[:, 2:3]

    def undistort_points(self, pixels: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) to normalised image coordinates (x/z, y/z), (..., 2)."""
        uv = np.asarray(pixels, dtype=np.float64)
        if uv.shape[-1] != 2:
            raise InputError("undistort_points: pixels", "an array of shape (..., 2)", f"shape {uv.shape}")
        shape = uv.shape[:-1]
        flat = uv.reshape(-1, 2)
        out = np.full_like(flat, np.nan)
        ok = np.isfinite(flat).all(axis=1)
        if ok.any():
            if self.has_distortion:
                n = cv2.undistortPoints(flat[ok].reshape(-1, 1, 2), self.K, self.dist, None, None, None,
                                        (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12))
                out[ok] = n.reshape(-1, 2)
            else:  # invert the upper-triangular K directly (fast path for large pixel grids)
                fx, s, cx = self.K[0]
                fy, cy = self.K[1, 1], self.K[1, 2]
                y = (flat[ok, 1] - cy) / fy
                out[ok, 1] = y
                out[ok, 0] = (flat[ok, 0] - cx - s * y) / fx
        return out.reshape(*shape, 2)

    def rays(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Back-project pixels to world rays.

        Parameters
        ----------
        pixels : ndarray of shape (..., 2)

        Returns
        -------
        origins : ndarray of shape (..., 3)
            The camera centre, repeated.
        directions : ndarray of shape (..., 3)
            Unit directions in world coordinates; NaN for NaN pixels.
        """
        n = self.undistort_points(pixels)
        d_cam = np.concatenate([n, np.ones(n.shape[:-1] + (1,))], axis=-1)
        d = d_cam @ self.R  # R^T d for row vectors
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        o = np.broadcast_to(self.center, d.shape).copy()
        return o, d

    def backproject(self, pixels: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) with camera-frame z depth (...) in metres to world points (..., 3)."""
        n = self.undistort_points(pixels)
        z = np.asarray(depth, dtype=np.float64)[..., None]
        pc = np.concatenate([n * z, z], axis=-1)
        return (pc - self.t) @ self.R

    def depth_of(self, points_world: np.ndarray) -> np.ndarray:
        """Camera-frame z (...,) of world points (..., 3), metres."""
        return self.to_cam(points_world)[..., 2]

    def in_image(self, pixels: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean (...,) mask of pixels inside the image (pixel centres from 0 to size-1)."""
        uv = np.asarray(pixels)
        w, h = self.size
        return ((uv[..., 0] >= -0.5 + margin) & (uv[..., 0] <= w - 0.5 - margin)
                & (uv[..., 1] >= -0.5 + margin) & (uv[..., 1] <= h - 0.5 - margin))


@dataclass(frozen=True)
class Rig:
    """An ordered set of cameras with unique names.

    Parameters
    ----------
    cameras : tuple of Camera
    """

    cameras: tuple[Camera, ...] = field(default_factory=tuple)

    def __post_init__(self):
        cams = tuple(self.cameras)
        names = [c.name for c in cams]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise InputError("rig: camera names", "unique names", f"duplicates {sorted(dup)}")
        object.__setattr__(self, "cameras", cams)

    def __len__(self) -> int:
        return len(self.cameras)

    def __iter__(self):
        return iter(self.cameras)

    def __getitem__(self, key) -> Camera:
        if isinstance(key, str):
            for c in self.cameras:
                if c.name == key:
                    return c
            raise KeyError(f"no camera named {key!r} in rig (have {self.names})")
        return self.cameras[key]

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.cameras]

    @property
    def centers(self) -> np.ndarray:
        """Camera centres, (n_cams, 3) metres."""
        return np.array([c.center for c in self.cameras]).reshape(-1, 3)

    def project(self, points_world: np.ndarray) -> np.ndarray:
        """Project (..., 3) world points into every camera: (n_cams, ..., 2)."""
        return np.stack([c.project(points_world) for c in self.cameras])


def camera_with_offset(camera: Camera, offset) -> Camera:
    """The camera whose projection is ``camera``'s plus a 2D pixel offset.

    Shifting the principal point shifts every projected pixel by exactly the
    offset (also with lens distortion, which acts before ``K``), and every
    ray by the same correction: the camera *is* the corrected camera, no
    consumer needs the offset beside it.

    Parameters
    ----------
    camera : Camera
    offset : array_like of shape (2,)
        Pixels (x right, y down): ``result.project(X) == camera.project(X) + offset``.

    Returns
    -------
    Camera
    """
    d = np.asarray(offset, float)
    if d.shape != (2,) or not np.isfinite(d).all():
        raise InputError("camera_with_offset: offset", "a finite (2,) pixel offset", f"{d!r}")
    K = camera.K.copy()
    K[0, 2] += d[0]
    K[1, 2] += d[1]
    return camera.replace(K=K)


def plane_homography(src: Camera, dst: Camera, plane_normal, plane_point) -> np.ndarray:
    """Homography from ``src`` pixels to ``dst`` pixels induced by a world plane.

    Ignores lens distortion (apply it to the images first).

    Parameters
    ----------
    src, dst : Camera
    plane_normal : array_like of shape (3,)
        Plane normal in world coordinates (need not be unit).
    plane_point : array_like of shape (3,)
        A point on the plane, metres.

    Returns
    -------
    ndarray of shape (3, 3)
        ``dst_from_src`` with ``H[2, 2] == 1`` (x_dst ~ H x_src).
    """
    check_shape("plane_normal", plane_normal, (3,))
    check_shape("plane_point", plane_point, (3,))
    n_w = np.asarray(plane_normal, float)
    n_w = n_w / np.linalg.norm(n_w)
    X0 = np.asarray(plane_point, float)
    # plane in src camera coords: n_s . X = d_s
    n_s = src.R @ n_w
    d_s = float(n_s @ (src.R @ X0 + src.t))
    if abs(d_s) < 1e-12:
        raise InputError("plane_homography: plane", "a plane not through the source camera centre",
                         "a plane through it")
    T = dst.cam_from_world @ src.world_from_cam
    R, t = T[:3, :3], T[:3, 3]
    H = dst.K @ (R + np.outer(t, n_s) / d_s) @ np.linalg.inv(src.K)
    return H / H[2, 2]
