"""A synthetic frame with exact part labels, made without the scene generator (fast)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera
from toolkit.motion import generate_motion
from toolkit.body.model import BodyModel, BodyShape, dress


@dataclass
class Frame:
    image: np.ndarray  # (H, W, 3) uint8
    parts: np.ndarray  # (H, W) uint8 ground truth
    joints3d: np.ndarray  # (14, 3)
    camera: Camera
    plate: np.ndarray = None  # (H, W, 3) uint8: the backdrop alone


def make_frame(seed: int, size=(480, 360), distance: float = 4.5, motion: str = "wave", t: int = 20,
               kit=None) -> Frame:
    """Render a sampled person (its own outfit) by ray casting, with baked shading and a textured backdrop.

    ``kit`` (RGB in [0, 1]): a low-contrast outfit, shirt (with its print) and trousers drawn close to
    this colour, in front of a backdrop of the same colour.
    """
    rng = np.random.default_rng(seed)
    props = BodyProportions.from_height(1.75)
    joints = generate_motion(motion, props, 40, 25.0, rng=rng)[t]
    shape = BodyShape.sample(props, rng)
    if kit is not None:
        kit = np.asarray(kit, float)
        shape = dress(shape, near=kit[None], trousers_rgb=np.clip(0.85 * kit, 0, 1), rng=seed)
    body = BodyModel(shape, rng)
    mesh = body.mesh(joints)
    centre = joints.mean(0)
    ang = rng.uniform(0, 2 * np.pi)
    eye = centre + [distance * np.cos(ang), distance * np.sin(ang), 0.6]
    cam = Camera.look_at("cam", eye=eye, target=centre, size=size, fov_x_deg=45.0)
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    n = cam.undistort_points(np.stack([u, v], -1))
    d = np.concatenate([n, np.ones(n.shape[:-1] + (1,))], -1) @ cam.R
    rays = np.concatenate([np.broadcast_to(cam.center, d.shape), d], -1).astype(np.float32)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                        o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
    ans = scene.cast_rays(o3d.core.Tensor(rays))
    hit = np.isfinite(ans["t_hit"].numpy())
    pid = ans["primitive_ids"].numpy().astype(np.int64)
    parts = np.zeros((h, w), np.uint8)
    parts[hit] = mesh.triangle_parts[pid[hit]]
    shaded = mesh.shaded_colors()
    tri_col = shaded[mesh.triangles].mean(1)
    back = rng.uniform(0.3, 0.7, 3) if kit is None else kit
    img = back + (0.15 if kit is None else 0.05) * rng.standard_normal((h, w, 3))  # noisy backdrop
    plate = np.clip(img * 255, 0, 255).astype(np.uint8)
    img[hit] = tri_col[pid[hit]] + 0.02 * rng.standard_normal((hit.sum(), 3))
    return Frame(np.clip(img * 255, 0, 255).astype(np.uint8), parts, joints, cam, plate)


@pytest.fixture(scope="session")
def frame() -> Frame:
    return make_frame(4)
