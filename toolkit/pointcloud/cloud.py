"""Depth maps to point clouds, the gravity-aligned view frame, centroid and principal direction.

Every stage after the input works in the **view frame**: the depth camera's
frame turned about its x axis so that its y axis points down along gravity
(x right, y down, z forward and horizontal; OpenCV-like).  With a known camera
pose the true gravity is used; without one the camera is assumed level (the
view frame is then the camera frame).  Heights are ``-y``; with a known pose
the ground plane is ``y = camera height``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.cameras import Camera
from toolkit.errors import InputError

__all__ = [
    "UserCloud",
    "ViewFrame",
    "depth_to_points",
    "open3d_points_from_depth",
    "pixel_rays",
    "principal_direction",
    "to_open3d_pointcloud",
    "user_cloud",
]


@dataclass(frozen=True, eq=False)
class ViewFrame:
    """The gravity-aligned frame the tracker works in.

    Attributes
    ----------
    camera : Camera
        The depth camera (its ``cam_from_world`` is only meaningful if ``pose_known``).
    view_from_cam : ndarray of shape (3, 3)
        Rotation from camera to view coordinates.
    pose_known : bool
        Whether world coordinates (z up, ground z = 0) are available.
    """

    camera: Camera
    view_from_cam: np.ndarray
    pose_known: bool

    @classmethod
    def from_camera(cls, camera: Camera, pose_known: bool = True) -> ViewFrame:
        """The view frame of ``camera``; level camera assumed when ``pose_known`` is False."""
        if not pose_known:
            return cls(camera, np.eye(3), False)
        up_c = camera.R @ np.array([0.0, 0.0, 1.0])
        y = -up_c
        x = np.array([1.0, 0.0, 0.0]) - y[0] * y
        if np.linalg.norm(x) < 1e-6:  # camera looking straight up or down
            raise InputError(f"camera {camera.name!r}: cam_from_world", "a camera whose x axis is not vertical",
                             "a camera looking straight along gravity")
        x /= np.linalg.norm(x)
        z = np.cross(x, y)
        return cls(camera, np.stack([x, y, z]), True)

    @property
    def ground_y(self) -> float | None:
        """View-frame y of the ground plane (None without a known pose)."""
        return float(self.camera.center[2]) if self.pose_known else None

    def from_camera_points(self, points_cam: np.ndarray) -> np.ndarray:
        """Camera coordinates (..., 3) to view coordinates."""
        return np.asarray(points_cam, float) @ self.view_from_cam.T

    def to_camera(self, points_view: np.ndarray) -> np.ndarray:
        """View coordinates (..., 3) to camera coordinates."""
        return np.asarray(points_view, float) @ self.view_from_cam

    def to_world(self, points_view: np.ndarray) -> np.ndarray:
        """View coordinates (..., 3) to world coordinates (camera coordinates if the pose is unknown)."""
        pc = self.to_camera(points_view)
        if not self.pose_known:
            return pc
        T = self.camera.world_from_cam
        return pc @ T[:3, :3].T + T[:3, 3]

    def from_world(self, points_world: np.ndarray) -> np.ndarray:
        """World coordinates (..., 3) to view coordinates."""
        pc = self.camera.to_cam(points_world) if self.pose_known else np.asarray(points_world, float)
        return self.from_camera_points(pc)

    def project(self, points_view: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) of view-frame points (pinhole, no distortion; NaN behind the camera)."""
        pc = self.to_camera(points_view)
        z = pc[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.stack([pc[..., 0] / z, pc[..., 1] / z], -1)
        K = self.camera.K
        uv = uv * np.array([K[0, 0], K[1, 1]]) + np.array([K[0, 2], K[1, 2]])
        uv[z <= 1e-6] = np.nan
        return uv


_RAYS: dict = {}


def pixel_rays(camera: Camera) -> np.ndarray:
    """Per-pixel ray directions ``(x/z, y/z, 1)`` in the camera frame, (H, W, 3), distortion undone.

    Cached per camera model (one entry).
    """
    key = (camera.K.tobytes(), camera.dist.tobytes(), camera.size)
    r = _RAYS.get(key)
    if r is None:
        w, h = camera.size
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        if camera.has_distortion:
            n = camera.undistort_points(np.stack([u, v], -1))
        else:
            K = camera.K
            n = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]], -1)
        r = np.concatenate([n, np.ones((h, w, 1))], -1).astype(np.float32)
        _RAYS.clear()
        _RAYS[key] = r
    return r


def _check_depth(depth: np.ndarray, camera: Camera, name: str = "depth") -> np.ndarray:
    d = np.asarray(depth)
    w, h = camera.size
    if d.shape != (h, w):
        raise InputError(name, f"a depth map of shape ({h}, {w}) for camera {camera.name!r}", f"shape {d.shape}")
    if not np.issubdtype(d.dtype, np.floating):
        raise InputError(name, "float metres (NaN = no reading)", f"dtype {d.dtype}")
    return d


def depth_to_points(depth: np.ndarray, camera: Camera, mask: np.ndarray | None = None):
    """Back-project depth pixels to camera-frame points.

    Parameters
    ----------
    depth : ndarray of shape (H, W)
        Camera-frame z, metres, NaN or <= 0 = no reading.
    camera : Camera
    mask : ndarray of shape (H, W), bool, optional
        Pixels to use (default: all valid ones).

    Returns
    -------
    points : ndarray of shape (N, 3), float64
        Camera frame, metres.
    rows, cols : ndarray of shape (N,), int
        Pixel of each point.
    """
    d = _check_depth(depth, camera)
    valid = np.isfinite(d) & (d > 0)
    if mask is not None:
        m = np.asarray(mask, bool)
        if m.shape != d.shape:
            raise InputError("mask", f"a boolean image of shape {d.shape}", f"shape {m.shape}")
        valid &= m
    rows, cols = np.nonzero(valid)
    z = d[rows, cols].astype(np.float64)
    rays = pixel_rays(camera)[rows, cols].astype(np.float64)
    return rays * z[:, None], rows, cols


def principal_direction(points: np.ndarray, up=(0.0, -1.0, 0.0)):
    """Centroid and principal axes of a point set (PCA).

    Parameters
    ----------
    points : ndarray of shape (N, 3)
    up : array_like of shape (3,)
        The first axis is signed to point along ``up`` (default: view-frame up).

    Returns
    -------
    centroid : ndarray of shape (3,)
    axes : ndarray of shape (3, 3)
        Rows are the principal directions, by decreasing variance.
    variances : ndarray of shape (3,)
    """
    P = np.asarray(points, float)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < 3:
        raise InputError("points", "an array of shape (N, 3) with N >= 3", f"shape {P.shape}")
    c = P.mean(0)
    C = np.cov((P - c).T)
    w, V = np.linalg.eigh(C)
    order = np.argsort(w)[::-1]
    axes = V[:, order].T
    if axes[0] @ np.asarray(up, float) < 0:
        axes[0] = -axes[0]
    if np.linalg.det(axes) < 0:
        axes[2] = -axes[2]
    return c, axes, w[order]


@dataclass(frozen=True)
class UserCloud:
    """The user's points in the view frame with their statistics.

    Attributes
    ----------
    points : ndarray of shape (N, 3)
        View frame, metres.
    rows, cols : ndarray of shape (N,), int
        Source pixels.
    normals : ndarray of shape (N, 3) or None
        Unit normals in the view frame (NaN where unknown).
    centroid : ndarray of shape (3,)
    principal_axis : ndarray of shape (3,)
        Direction of largest spread, signed upwards.
    variances : ndarray of shape (3,)
        PCA variances, m^2, decreasing.
    touches_border : tuple of bool
        Whether the user's mask touches the (left, right, top, bottom) image border.
    """

    points: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    normals: np.ndarray | None
    centroid: np.ndarray
    principal_axis: np.ndarray
    variances: np.ndarray
    touches_border: tuple

    @property
    def n_points(self) -> int:
        return len(self.points)


def user_cloud(depth: np.ndarray, mask: np.ndarray, frame: ViewFrame, normals: np.ndarray | None = None,
               border_px: int = 2, with_pca: bool = True) -> UserCloud | None:
    """The user's point cloud in the view frame, or None when fewer than 3 points remain.

    Parameters
    ----------
    depth : ndarray of shape (H, W)
        Metres, NaN = no reading.
    mask : ndarray of shape (H, W), bool
        User pixels.
    frame : ViewFrame
    normals : ndarray of shape (H, W, 3), optional
        Camera-frame normal map (see :func:`toolkit.pointcloud.normals.normal_map`).
    border_px : int
        Mask pixels this close to an image side count as touching it.
    with_pca : bool
        Compute the principal direction (NaN otherwise; the tracker needs it to initialise only).
    """
    pts, rows, cols = depth_to_points(depth, frame.camera, mask)
    if len(pts) < 3:
        return None
    pv = frame.from_camera_points(pts)
    nv = None
    if normals is not None:
        nv = frame.from_camera_points(np.asarray(normals)[rows, cols].astype(np.float64))
    if with_pca:
        c, axes, var = principal_direction(pv)
    else:
        c, axes, var = pv.mean(0), np.full((3, 3), np.nan), np.full(3, np.nan)
    w, h = frame.camera.size
    touches = (bool(cols.min() < border_px), bool(cols.max() >= w - border_px),
               bool(rows.min() < border_px), bool(rows.max() >= h - border_px))
    return UserCloud(pv, rows, cols, nv, c, axes[0], var, touches)


def to_open3d_pointcloud(points: np.ndarray, normals: np.ndarray | None = None, colors: np.ndarray | None = None):
    """An ``open3d.geometry.PointCloud`` of points (N, 3), optional normals and colours in [0, 1]."""
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, np.float64)))
    if normals is not None:
        pc.normals = o3d.utility.Vector3dVector(np.nan_to_num(np.asarray(normals, np.float64)))
    if colors is not None:
        pc.colors = o3d.utility.Vector3dVector(np.asarray(colors, np.float64))
    return pc


def open3d_points_from_depth(depth: np.ndarray, camera: Camera) -> np.ndarray:
    """Camera-frame points of a depth map through Open3D's ``PointCloud.create_from_depth_image``.

    Open3D puts the principal point at pixel centres like OpenCV does, so this
    agrees with :func:`depth_to_points` (no distortion); used as a cross-check.

    Returns
    -------
    ndarray of shape (N, 3)
    """
    import open3d as o3d

    d = _check_depth(depth, camera)
    w, h = camera.size
    K = camera.K
    intr = o3d.camera.PinholeCameraIntrinsic(w, h, K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    img = o3d.geometry.Image(np.ascontiguousarray(np.nan_to_num(d, nan=0.0).astype(np.float32)))
    pc = o3d.geometry.PointCloud.create_from_depth_image(img, intr, depth_scale=1.0, depth_trunc=1e6)
    return np.asarray(pc.points)
