"""Static surroundings of a synthetic scene: a textured ground plane and backdrop.

``"broadcast"`` is a grass pitch with mowing stripes and field lines inside a
ring of stands (a crowd texture); ``"studio"`` is a wooden floor inside four
textured walls.  Everything is plain arrays (vertices, triangles, texture
coordinates and an RGB texture per surface) so that the Open3D renderer and the
ray caster see exactly the same geometry.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.calibration.field import soccer_pitch
from toolkit.errors import InputError


@dataclass(frozen=True)
class Surface:
    """A textured triangle mesh.

    Attributes
    ----------
    name : str
    vertices : ndarray of shape (V, 3)
        World coordinates, metres.
    triangles : ndarray of shape (F, 3)
    uvs : ndarray of shape (V, 2)
        Texture coordinates in [0, 1], v downwards in the texture image.
    texture : ndarray of shape (H, W, 3) or None
        uint8 RGB, or None for a vertex-coloured surface.
    vertex_colors : ndarray of shape (V, 3) or None
        RGB in [0, 1] when the surface is vertex-coloured.
    """

    name: str
    vertices: np.ndarray
    triangles: np.ndarray
    uvs: np.ndarray | None
    texture: np.ndarray | None
    vertex_colors: np.ndarray | None = None


def _unit_noise(rng, size, blur):
    """Blurred Gaussian noise of unit standard deviation, (h, w, 1) float32."""
    h, w = size
    n = rng.normal(0, 1, (h, w, 1)).astype(np.float32)
    n = cv2.GaussianBlur(n, (0, 0), blur)[..., None]
    n /= max(float(n.std()), 1e-6)
    return n


def _noise_texture(rng, size, base, amp, blur=1.5):
    n = _unit_noise(rng, size, blur)
    tex = np.asarray(base, np.float32)[None, None, :] * (1 + amp * n)
    return tex


def _quad(name, corners, texture):
    V = np.asarray(corners, float)
    T = np.array([[0, 1, 2], [0, 2, 3]])
    UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float)
    return Surface(name, V, T, UV, texture)


#: Base colours (RGB in [0, 1]) of the surroundings' textures: grass; studio walls and floor.
GRASS_RGB = (0.20, 0.50, 0.18)
STUDIO_WALL_RGB = (0.62, 0.64, 0.68)
STUDIO_FLOOR_RGB = (0.55, 0.42, 0.30)
#: What a subject is seen against per layout (``[subject] outfit = "like_background"`` dresses it in these).
SURROUNDING_COLOURS = {"broadcast": (GRASS_RGB,), "studio": (STUDIO_WALL_RGB, STUDIO_FLOOR_RGB),
                       "trinocular": (STUDIO_WALL_RGB, STUDIO_FLOOR_RGB)}

#: Half-size of the broadcast grass, metres (the field lines lie PITCH_MARGIN_M inside it).
PITCH_HALF_X, PITCH_HALF_Y = 60.0, 40.0
#: Grass around the painted field lines on every side, metres.
PITCH_MARGIN_M = 5.0


def _pitch(rng, res=4096):
    half_x, half_y = PITCH_HALF_X, PITCH_HALF_Y
    w = res
    h = int(res * half_y / half_x)
    n = _unit_noise(rng, (h, w), 1.2)
    # mowing stripes every 5 m along x
    x = np.linspace(-half_x, half_x, w)
    stripes = np.where(np.floor(x / 5.0) % 2 == 0, np.float32(1.12), np.float32(0.92))[None, :]
    # per channel, in place: the values of clip(base * (1 + 0.18 n) * stripe * 255) in float32, as the
    # whole (h, w, 3) expression gave them, without its five temporaries of 130 MB
    m = n[..., 0] * np.float32(0.18)
    m += np.float32(1)
    img = np.empty((h, w, 3), np.uint8)
    t = np.empty((h, w), np.float32)
    for c, base in enumerate(np.asarray(GRASS_RGB, np.float32)):
        np.multiply(m, base, out=t)
        t *= stripes
        t *= np.float32(255)
        np.clip(t, 0, 255, out=t)
        img[..., c] = t
    px, py = w / (2 * half_x), h / (2 * half_y)  # texels per metre

    white = (235, 235, 235)
    t = max(1, int(round(0.12 * px)))
    # the painted lines are those of the field model written into broadcast datasets
    for line in field_model("broadcast").polylines:
        uv = np.stack([(line[:, 0] + half_x) * px, (half_y - line[:, 1]) * py], axis=1) - 0.5  # texel centres
        cv2.polylines(img, [np.round(uv * 16).astype(np.int32)], False, white, t, cv2.LINE_8, shift=4)
    corners = [[-half_x, -half_y, 0], [half_x, -half_y, 0], [half_x, half_y, 0], [-half_x, half_y, 0]]
    return _quad("ground", corners, img)


def _ring_wall(name, rng, radius, z0, z1, n_seg, texture_fn, tex_size):
    """A vertical cylinder wall, vertex-coloured from a texture sampled on a dense grid.

    (Textured walls made Open3D 0.20's software-Vulkan renderer stall for
    minutes with some textures, so walls carry their pattern as vertex colours.)
    """
    tex = texture_fn(rng, tex_size)
    rows, cols = tex.shape[:2]
    th = np.linspace(0, 2 * np.pi, cols + 1)
    z = np.linspace(z1, z0, rows)
    TH, Z = np.meshgrid(th, z)
    V = np.stack([radius * np.cos(TH), radius * np.sin(TH), Z], -1).reshape(-1, 3)
    C = np.concatenate([tex, tex[:, :1]], axis=1).reshape(-1, 3).astype(np.float64) / 255.0
    n = cols + 1
    r = np.arange(rows - 1)[:, None]
    c = np.arange(cols)[None, :]
    a = r * n + c
    T = np.concatenate([np.stack([a, a + n, a + 1], -1).reshape(-1, 3),
                        np.stack([a + 1, a + n, a + n + 1], -1).reshape(-1, 3)])
    return Surface(name, V, T, None, None, C)


def _crowd(rng, size):
    h, w = size
    tex = rng.uniform(0.1, 0.95, (h, w, 3)).astype(np.float32)
    rows = np.linspace(0.55, 1.0, h)[:, None, None]
    return np.clip(tex * rows * 255, 0, 255).astype(np.uint8)


def _studio_wall(rng, size):
    h, w = size
    tex = _noise_texture(rng, (h, w), list(STUDIO_WALL_RGB), 0.08, 2.0)
    img = np.clip(tex * 255, 0, 255).astype(np.uint8)
    for k in range(12):  # posters and panels as texture for background subtraction realism
        x0, y0 = int(rng.uniform(0, w - w // 20)), int(rng.uniform(0, h - h // 4))
        col = tuple(int(c) for c in rng.integers(30, 230, 3))
        cv2.rectangle(img, (x0, y0), (x0 + int(rng.uniform(w / 100, w / 30)), y0 + int(rng.uniform(h / 10, h / 4))),
                      col, -1)
    return img


def _floor(rng, half=8.0, res=2048):
    tex = _noise_texture(rng, (res, res), list(STUDIO_FLOOR_RGB), 0.10, 1.0)
    # planks 0.2 m wide
    x = np.linspace(-half, half, res)
    plank = (np.floor(x / 0.2) % 3)[None, :, None]
    tex = tex * (0.92 + 0.06 * plank)
    img = np.clip(tex * 255, 0, 255).astype(np.uint8)
    corners = [[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]]
    return _quad("ground", corners, img)


def make_environment(layout: str, rng: np.random.Generator | int | None = None) -> list[Surface]:
    """Surfaces of the surroundings for a camera ``layout``.

    Parameters
    ----------
    layout : {"broadcast", "studio"}
    rng : numpy.random.Generator or int or None

    Returns
    -------
    list of Surface
    """
    rng = np.random.default_rng(rng)
    if layout == "broadcast":
        return [
            _pitch(rng),
            _ring_wall("stands", rng, 62.0, 0.0, 22.0, 96, _crowd, (60, 1200)),
        ]
    if layout in ("studio", "trinocular"):  # stereo heads stand in the studio
        walls = _ring_wall("walls", rng, 7.5, 0.0, 5.0, 48, _studio_wall, (120, 900))
        return [_floor(rng), walls]
    raise InputError("layout", "'broadcast' or 'studio'", repr(layout))


def field_model(layout: str):
    """The painted lines of a layout's ground as a :class:`~toolkit.calibration.FieldModel`, or None.

    The broadcast pitch paints :func:`toolkit.calibration.soccer_pitch` (110 x 70 m
    inside 120 x 80 m of grass); the studio floor has no lines.
    """
    if layout == "broadcast":
        return soccer_pitch(2 * (PITCH_HALF_X - PITCH_MARGIN_M), 2 * (PITCH_HALF_Y - PITCH_MARGIN_M))
    if layout in ("studio", "trinocular"):
        return None
    raise InputError("layout", "'broadcast' or 'studio'", repr(layout))


#: Background (sky / ceiling) colour per layout, RGB in [0, 1].
BACKGROUND_COLOUR = {"broadcast": (0.55, 0.70, 0.90), "studio": (0.30, 0.30, 0.32),
                     "trinocular": (0.30, 0.30, 0.32)}
