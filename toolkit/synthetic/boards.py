"""Rendered calibration boards and people-as-calibration sequences with exact ground truth.

:func:`render_checkerboard` draws a checkerboard through a :class:`~toolkit.cameras.Camera`
(distortion included) by back-projecting every pixel onto the board plane, with
supersampling for anti-aliased edges; :func:`board_corners` gives the exact pixel
positions of its inner corners.  :func:`people_sequence` moves the 14-joint rest
pose of :class:`~toolkit.anthropometry.BodyProportions` through a volume (walking,
turning, arms waving) for extrinsics-from-people tests.
"""

from __future__ import annotations

import numpy as np

from toolkit.anthropometry import BodyProportions
from toolkit.calibration.boards import Board
from toolkit.cameras import Camera

__all__ = ["board_pose", "board_corners", "render_checkerboard", "render_charuco", "pixel_rays", "people_sequence",
           "random_board_poses"]


def board_pose(center, normal_tilt_deg=(0.0, 0.0), spin_deg: float = 0.0, facing=(0.0, 0.0, 1.0)) -> np.ndarray:
    """``world_from_board`` (4, 4): a board centred near ``center`` whose printed side faces ``-facing``.

    Parameters
    ----------
    center : array_like of shape (3,)
        Board origin (first inner corner), metres.
    normal_tilt_deg : tuple of float
        Rotations about the board's x then y axes, degrees.
    spin_deg : float
        Rotation about the board normal, degrees.
    facing : array_like of shape (3,)
        The board's z axis before tilting (OpenCV: z points into the board, away from the viewer).
    """
    z = np.asarray(facing, float)
    z = z / np.linalg.norm(z)
    a = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(a, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z], 1)

    def rot(axis, deg):
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        if axis == 0:
            return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
        if axis == 1:
            return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])

    R = R @ rot(0, normal_tilt_deg[0]) @ rot(1, normal_tilt_deg[1]) @ rot(2, spin_deg)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(center, float)
    return T


def random_board_poses(camera: Camera, board: Board, n: int, rng: np.random.Generator,
                       distance=(0.8, 1.6), max_tilt_deg: float = 40.0) -> list[np.ndarray]:
    """``world_from_board`` poses of a board fully in view of ``camera``, spread over the image.

    Parameters
    ----------
    camera : Camera
    board : Board
    n : int
    rng : numpy.random.Generator
    distance : tuple of float
        Range of distances along the optical axis, metres.
    max_tilt_deg : float

    Returns
    -------
    list of ndarray of shape (4, 4)
    """
    out, tries = [], 0
    w, h = camera.size
    half = np.array([board.cols - 1, board.rows - 1, 0]) * board.square / 2
    while len(out) < n and tries < 200 * n:
        tries += 1
        d = rng.uniform(*distance)
        uv = rng.uniform([0.15 * w, 0.15 * h], [0.85 * w, 0.85 * h])
        centre = camera.backproject(uv[None], np.array([d]))[0]
        Tb = board_pose(centre, rng.uniform(-max_tilt_deg, max_tilt_deg, 2), rng.uniform(-180, 180),
                        facing=camera.forward)
        Tb[:3, 3] = centre - Tb[:3, :3] @ half
        px = board_corners(camera, board, Tb)
        if np.all(np.isfinite(px)) and np.all(camera.in_image(px, margin=0.06 * min(w, h))):
            out.append(Tb)
    return out


def board_corners(camera: Camera, board: Board, world_from_board: np.ndarray) -> np.ndarray:
    """Exact pixels of the board's inner corners, (rows * cols, 2), OpenCV's order."""
    P = board.object_points() @ world_from_board[:3, :3].T + world_from_board[:3, 3]
    return camera.project(P)


def pixel_rays(camera: Camera, supersample: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """World rays ``(origins, directions)`` of a supersampled pixel grid, each (H * s, W * s, 3).

    Computed once per camera and passed to :func:`render_checkerboard` (undistorting every
    sample is the slow part).
    """
    w, h = camera.size
    s = supersample
    u, v = np.meshgrid((np.arange(w * s) + 0.5) / s - 0.5, (np.arange(h * s) + 0.5) / s - 0.5)
    return camera.rays(np.stack([u, v], -1))


def render_checkerboard(camera: Camera, board: Board, world_from_board: np.ndarray, supersample: int = 2,
                        background: int = 110, margin_squares: float = 1.0, rays=None) -> np.ndarray:
    """Grey image (H, W) uint8 of a checkerboard (``rows + 1`` by ``cols + 1`` squares and a white border).

    The square left of and above the first inner corner is black.  Pixels off the board are
    ``background``.  ``rays`` from :func:`pixel_rays` (same ``supersample``) saves their computation.
    """
    w, h = camera.size
    s = supersample
    o, d = rays if rays is not None else pixel_rays(camera, s)
    Tb = np.linalg.inv(world_from_board)
    ob = o @ Tb[:3, :3].T + Tb[:3, 3]
    db = d @ Tb[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = -ob[..., 2] / db[..., 2]
    p = ob + lam[..., None] * db
    gx, gy = p[..., 0] / board.square, p[..., 1] / board.square
    on = np.isfinite(gx) & (lam > 0) & (gx > -1 - margin_squares) & (gx < board.cols + margin_squares) \
        & (gy > -1 - margin_squares) & (gy < board.rows + margin_squares)
    inside = (gx > -1) & (gx < board.cols) & (gy > -1) & (gy < board.rows)
    black = ((np.floor(gx).astype(np.int64) + np.floor(gy).astype(np.int64)) % 2 == 0) & inside
    img = np.where(on, np.where(black, 20.0, 235.0), float(background))
    img = img.reshape(h, s, w, s).mean(axis=(1, 3))
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def people_sequence(n_frames: int, rng: np.random.Generator, height: float = 1.75, radius: float = 1.5,
                    n_people: int = 1) -> np.ndarray:
    """14-joint sequences of people walking through a volume, arms waving.

    Parameters
    ----------
    n_frames : int
    rng : numpy.random.Generator
    height : float
        Stature, metres (every person).
    radius : float
        The people stay within this distance of the origin, metres.
    n_people : int

    Returns
    -------
    ndarray of shape (n_people, n_frames, 14, 3)
        Metres, z up, feet on z = 0 (ankles at the ankle height).
    """
    body = BodyProportions.from_height(height)
    rest = body.rest_pose()
    out = np.zeros((n_people, n_frames, 14, 3))
    for k in range(n_people):
        a0, r0 = rng.uniform(0, 2 * np.pi), rng.uniform(0.3, 0.8) * radius
        phase = rng.uniform(0, 2 * np.pi, 3)
        for t in range(n_frames):
            s = t / max(n_frames - 1, 1)
            ang = a0 + 2 * np.pi * s
            pos = np.array([r0 * np.cos(ang), r0 * np.sin(ang), 0.0])
            yaw = ang + np.pi / 2 + 0.5 * np.sin(3 * np.pi * s + phase[0])
            J = rest.copy()
            # arms raised by an angle that varies (shoulder abduction) so that points fill the volume
            for side, (sh, el, wr) in ((-1, (2, 3, 4)), (1, (5, 6, 7))):
                lift = np.radians(80 + 70 * np.sin(2 * np.pi * 3 * s + phase[1] + side))
                direction = np.array([side * np.sin(lift), 0.0, -np.cos(lift)])
                J[el] = J[sh] + body.upper_arm * direction
                J[wr] = J[el] + body.forearm * direction
            swing = 0.45 * np.sin(2 * np.pi * 4 * s + phase[2])  # legs swing about the hips (radians)
            for hip, knee, ankle, sign in ((8, 9, 10, 1.0), (11, 12, 13, -1.0)):
                cs, ss = np.cos(sign * swing), np.sin(sign * swing)
                for j in (knee, ankle):
                    v = J[j] - J[hip]
                    J[j] = J[hip] + np.array([v[0], cs * v[1] - ss * v[2], ss * v[1] + cs * v[2]])
            c, sn = np.cos(yaw), np.sin(yaw)
            Rz = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1]])
            out[k, t] = J @ Rz.T + pos
    return out


def render_charuco(camera: Camera, board: Board, world_from_board: np.ndarray, px_per_square: int = 60,
                   background: int = 110) -> np.ndarray:
    """Grey image (H, W) uint8 of a ChArUco board (OpenCV's drawing) seen by a camera without distortion.

    The board's first inner corner is at the origin of ``world_from_board`` (as
    :meth:`~toolkit.calibration.boards.Board.object_points`), the board's outer corner one square
    before it in x and y.  Lens distortion is ignored (a homography warp).
    """
    import cv2

    sq = board.square
    w_px, h_px = (board.cols + 1) * px_per_square, (board.rows + 1) * px_per_square
    art = board.charuco().generateImage((w_px, h_px), marginSize=0, borderBits=1)
    # board-image pixel -> board metres (origin at the first inner corner) -> camera pixels
    S = np.array([[sq / px_per_square, 0, -sq + 0.5 * sq / px_per_square],
                  [0, sq / px_per_square, -sq + 0.5 * sq / px_per_square], [0, 0, 1]])
    T = camera.cam_from_world @ world_from_board
    H = camera.K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ S
    w, h = camera.size
    # a white margin of one square around the board (as printed)
    pad = px_per_square
    art = cv2.copyMakeBorder(art, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255)
    shift = np.array([[1, 0, -pad], [0, 1, -pad], [0, 0, 1.0]])
    out = cv2.warpPerspective(art, H @ shift, (w, h), flags=cv2.INTER_AREA, borderMode=cv2.BORDER_CONSTANT,
                              borderValue=background)
    return out
