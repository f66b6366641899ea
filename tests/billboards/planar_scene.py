"""Synthetic fixtures for the billboard tests.

``planar_scene``: the left forearm is a flat textured plank lying in the plane
through the bone that faces every camera (all camera centres lie in the plane
spanned by the bone and the plank normal), so every camera's billboard
coincides with the plank: the perfectly aligned configuration of the score.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.anthropometry import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.skeleton import SKELETON_14

#: Part id (1-based) of the plank: the left forearm.
PLANK_PART = 1 + SKELETON_14.part_names.index("l_forearm")
PLANK_HALF_WIDTH_M = 0.05
PLANK_OVERHANG_M = 0.02


@dataclass
class PlanarScene:
    images: dict
    labels: dict
    rig: Rig
    joints: np.ndarray
    part: int
    corners: np.ndarray
    texture: np.ndarray


def textured(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A smooth, colourful random texture (h, w, 3) uint8."""
    small = rng.uniform(0, 255, (max(h // 8, 2), max(w // 8, 2), 3)).astype(np.float32)
    return np.clip(cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC), 0, 255).astype(np.uint8)


def render_quad(camera: Camera, corners: np.ndarray, texture: np.ndarray):
    """Draw a textured world quad (corners TL, TR, BR, BL) into a camera: rgb (H, W, 3) and mask (H, W)."""
    h, w = texture.shape[:2]
    src = np.float32([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    dst = camera.project(corners).astype(np.float32)
    H = cv2.getPerspectiveTransform(src, dst)
    W_, H_ = camera.size
    rgb = cv2.warpPerspective(texture, H, (W_, H_), flags=cv2.INTER_LINEAR)
    mask = cv2.warpPerspective(np.full((h, w), 255, np.uint8), H, (W_, H_), flags=cv2.INTER_LINEAR) >= 128
    return rgb, mask


def make_planar_scene(n_cams: int = 3, size=(640, 360), seed: int = 0, elevations_deg=(-20.0, 15.0, 40.0),
                      distance: float = 4.0) -> PlanarScene:
    rng = np.random.default_rng(seed)
    J = BodyProportions.from_height(1.75).rest_pose()
    e, wr = J[SKELETON_14.index("l_elbow")], J[SKELETON_14.index("l_wrist")]
    b = (wr - e) / np.linalg.norm(wr - e)
    n = np.array([0.0, 1.0, 0.0])
    n = n - (n @ b) * b
    n /= np.linalg.norm(n)
    e_u = np.cross(n, b)
    tl = e - PLANK_HALF_WIDTH_M * e_u - PLANK_OVERHANG_M * b
    tr = e + PLANK_HALF_WIDTH_M * e_u - PLANK_OVERHANG_M * b
    br = wr + PLANK_HALF_WIDTH_M * e_u + PLANK_OVERHANG_M * b
    bl = wr - PLANK_HALF_WIDTH_M * e_u + PLANK_OVERHANG_M * b
    corners = np.stack([tl, tr, br, bl])
    texture = textured(rng, 240, 80)
    mid = 0.5 * (e + wr)
    cams, images, labels = [], {}, {}
    for i in range(n_cams):
        phi = np.radians(elevations_deg[i])
        eye = mid + distance * (np.cos(phi) * n + np.sin(phi) * (-b))
        cam = Camera.look_at(f"cam{i}", eye, mid, size=size, fov_x_deg=20.0)
        cams.append(cam)
        bg = textured(rng, size[1], size[0]) // 3
        rgb, mask = render_quad(cam, corners, texture)
        images[cam.name] = np.where(mask[..., None], rgb, bg).astype(np.uint8)
        labels[cam.name] = np.where(mask, PLANK_PART, 0).astype(np.uint8)
    return PlanarScene(images, labels, Rig(tuple(cams)), J, PLANK_PART, corners, texture)
