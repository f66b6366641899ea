"""A clothed articulated body of smooth volumes on the 14-joint skeleton.

Each body part of :data:`toolkit.skeleton.PARTS_14` is a tapered capsule with
an elliptical cross-section (head and hands and feet are ellipsoids attached to
their part), tessellated densely enough to carry per-vertex clothing colour,
printed patterns, texture noise and baked Lambertian shading.  The same mesh
feeds the Open3D renderer (colour images) and Open3D's ray caster (exact part
labels, masks and depth), so ground truth and images agree.

Sizes are fractions of stature; see :class:`BodyShape`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14

# material ids (per vertex)
SKIN, HAIR, SHIRT, TROUSERS, SHOES = range(5)
MATERIAL_NAMES = ("skin", "hair", "shirt", "trousers", "shoes")

_PART = {name: i + 1 for i, name in enumerate(SKELETON_14.part_names)}
_J = {name: i for i, name in enumerate(SKELETON_14.joint_names)}

#: Palettes (RGB in [0, 1]) the clothing colours are drawn from.
SKIN_TONES = np.array([[0.95, 0.80, 0.69], [0.87, 0.67, 0.53], [0.76, 0.57, 0.42], [0.55, 0.38, 0.26],
                       [0.38, 0.26, 0.18]])
HAIR_COLOURS = np.array([[0.10, 0.07, 0.05], [0.30, 0.20, 0.10], [0.55, 0.40, 0.20], [0.80, 0.68, 0.45],
                         [0.45, 0.45, 0.45]])
SHIRT_COLOURS = np.array([[0.80, 0.10, 0.10], [0.10, 0.25, 0.75], [0.95, 0.95, 0.95], [0.95, 0.80, 0.10],
                          [0.10, 0.55, 0.25], [0.55, 0.15, 0.60], [0.95, 0.45, 0.10], [0.15, 0.15, 0.15]])
TROUSER_COLOURS = np.array([[0.12, 0.14, 0.30], [0.05, 0.05, 0.05], [0.90, 0.90, 0.90], [0.35, 0.30, 0.20],
                            [0.20, 0.35, 0.20], [0.50, 0.10, 0.10]])
SHOE_COLOURS = np.array([[0.05, 0.05, 0.05], [0.95, 0.95, 0.95], [0.60, 0.10, 0.10], [0.20, 0.30, 0.70]])


@dataclass(frozen=True)
class BodyShape:
    """Radii of the body volumes, metres, and clothing appearance.

    Attributes
    ----------
    proportions : BodyProportions
    girth : float
        Multiplier of every radius (1 = average build).
    colours : ndarray of shape (5, 3)
        RGB in [0, 1] per material (skin, hair, shirt, trousers, shoes).
    pattern : ndarray of shape (2, 3)
        Second shirt and trouser colour used by the print pattern.
    pattern_kind : str
        ``"stripes"``, ``"checks"`` or ``"plain"`` (shirt print).
    long_sleeves, long_trousers : bool
    noise_amplitude : float
        Standard deviation of the per-vertex colour noise (fabric texture).
    """

    proportions: BodyProportions
    girth: float = 1.0
    colours: np.ndarray = field(default_factory=lambda: np.array(
        [SKIN_TONES[1], HAIR_COLOURS[1], SHIRT_COLOURS[0], TROUSER_COLOURS[0], SHOE_COLOURS[0]]))
    pattern: np.ndarray = field(default_factory=lambda: np.array([[0.95, 0.95, 0.95], [0.2, 0.2, 0.2]]))
    pattern_kind: str = "stripes"
    long_sleeves: bool = False
    long_trousers: bool = True
    noise_amplitude: float = 0.06

    @classmethod
    def sample(cls, proportions: BodyProportions, rng: np.random.Generator | int | None = None) -> "BodyShape":
        """A random build and outfit (shirt and trousers always differ clearly)."""
        rng = np.random.default_rng(rng)
        skin = SKIN_TONES[rng.integers(len(SKIN_TONES))]
        hair = HAIR_COLOURS[rng.integers(len(HAIR_COLOURS))]
        shirt_i = rng.integers(len(SHIRT_COLOURS))
        shirt = SHIRT_COLOURS[shirt_i]
        trousers = TROUSER_COLOURS[rng.integers(len(TROUSER_COLOURS))]
        while np.abs(trousers - shirt).sum() < 0.6:
            trousers = TROUSER_COLOURS[rng.integers(len(TROUSER_COLOURS))]
        shoes = SHOE_COLOURS[rng.integers(len(SHOE_COLOURS))]
        second = SHIRT_COLOURS[(shirt_i + 1 + rng.integers(len(SHIRT_COLOURS) - 1)) % len(SHIRT_COLOURS)]
        return cls(
            proportions=proportions,
            girth=float(np.clip(rng.normal(1.0, 0.08), 0.85, 1.2)),
            colours=np.array([skin, hair, shirt, trousers, shoes]),
            pattern=np.array([second, trousers * 0.6]),
            pattern_kind=str(rng.choice(["stripes", "checks", "plain"], p=[0.45, 0.35, 0.2])),
            long_sleeves=bool(rng.random() < 0.4),
            long_trousers=bool(rng.random() < 0.8),
            noise_amplitude=float(rng.uniform(0.04, 0.08)),
        )


def dress(shape: BodyShape, *, near: np.ndarray | None = None, shirt_rgb=None, trousers_rgb=None,
          pattern: str | None = None, rng: np.random.Generator | int | None = None) -> BodyShape:
    """The same person in another outfit (the scene spec's ``[subject]`` outfit fields).

    Parameters
    ----------
    shape : BodyShape
    near : array_like of shape (K, 3), optional
        Colours of the surroundings (RGB in [0, 1]); when given, the shirt and its
        print are drawn close to one of them (a kit like the pitch or the backdrop:
        within about 0.1 per channel, the print slightly darker or lighter).
    shirt_rgb, trousers_rgb : array_like of shape (3,), optional
        Explicit colours (override ``near``).
    pattern : {"stripes", "checks", "plain", "checks_all"}, optional
        The shirt's print; ``"checks_all"`` prints the checks on the trousers too.
    rng : numpy.random.Generator or int or None

    Returns
    -------
    BodyShape
    """
    rng = np.random.default_rng(rng)
    colours, second = shape.colours.copy(), shape.pattern.copy()
    if near is not None:
        near = np.asarray(near, float).reshape(-1, 3)
        base = near[rng.integers(len(near))]
        colours[2] = np.clip(base * rng.uniform(0.9, 1.2) + rng.uniform(-0.06, 0.06, 3), 0, 1)
        second[0] = np.clip(colours[2] * rng.choice([0.7, 1.3]) + rng.uniform(-0.04, 0.04, 3), 0, 1)
    if shirt_rgb is not None:
        colours[2] = np.asarray(shirt_rgb, float)
    if trousers_rgb is not None:
        colours[3] = np.asarray(trousers_rgb, float)
        second[1] = colours[3] * 0.6
    return replace(shape, colours=colours, pattern=second,
                   pattern_kind=shape.pattern_kind if pattern is None else str(pattern))


@dataclass(frozen=True)
class BodyMesh:
    """A posed body mesh.

    Attributes
    ----------
    vertices : ndarray of shape (V, 3)
        World coordinates, metres.
    triangles : ndarray of shape (F, 3)
        Vertex indices, counter-clockwise seen from outside.
    colors : ndarray of shape (V, 3)
        Albedo RGB in [0, 1] (shading not applied).
    normals : ndarray of shape (V, 3)
        Unit outward normals.
    triangle_parts : ndarray of shape (F,)
        Part id per triangle (1-based, see ``SKELETON_14.parts``).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    colors: np.ndarray
    normals: np.ndarray
    triangle_parts: np.ndarray

    def shaded_colors(self, light_dir=(0.4, -0.3, 0.85), ambient: float = 0.45) -> np.ndarray:
        """Vertex colours with Lambertian shading from a distant light, (V, 3) in [0, 1]."""
        ld = np.asarray(light_dir, float)
        ld = ld / np.linalg.norm(ld)
        lam = np.clip(self.normals @ ld, 0.0, 1.0)
        sky = 0.5 + 0.5 * self.normals[:, 2]  # soft sky light from above
        k = ambient * (0.75 + 0.25 * sky) + (1 - ambient) * lam
        return np.clip(self.colors * k[:, None], 0.0, 1.0)


def _frame(axis: np.ndarray, lateral_hint: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (x, y) perpendicular to ``axis`` with x close to ``lateral_hint``."""
    x = lateral_hint - axis * (lateral_hint @ axis)
    if np.linalg.norm(x) < 1e-6:
        x = np.cross(axis, [0.0, 0.0, 1.0])
        if np.linalg.norm(x) < 1e-6:
            x = np.cross(axis, [0.0, 1.0, 0.0])
    x = x / np.linalg.norm(x)
    return x, np.cross(axis, x)


def _grid_triangles(n_rings: int, n_around: int, offset: int) -> np.ndarray:
    i = np.arange(n_rings - 1)[:, None]
    j = np.arange(n_around)[None, :]
    a = i * n_around + j
    b = i * n_around + (j + 1) % n_around
    c = (i + 1) * n_around + j
    d = (i + 1) * n_around + (j + 1) % n_around
    t = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return t + offset


@dataclass
class _Builder:
    verts: list = field(default_factory=list)
    normals: list = field(default_factory=list)
    tris: list = field(default_factory=list)
    tri_parts: list = field(default_factory=list)
    # per-vertex local surface coordinates (u around in [0,1), v along in metres) and part
    uv: list = field(default_factory=list)
    vparts: list = field(default_factory=list)
    n: int = 0

    def add(self, v, nrm, tris, part, uv):
        self.verts.append(v)
        self.normals.append(nrm)
        self.tris.append(tris + self.n)
        self.tri_parts.append(np.full(len(tris), part, np.uint8))
        self.uv.append(uv)
        self.vparts.append(np.full(len(v), part, np.uint8))
        self.n += len(v)


def _capsule(b: _Builder, p0, p1, r0, r1, lateral, part, n_around=40, n_along=24, n_cap=8,
             cap0=1.0, cap1=1.0):
    """Tapered capsule with elliptical sections: r0, r1 = (rx, ry) at p0 and p1; caps scaled by cap0/cap1."""
    p0 = np.asarray(p0, float)
    p1 = np.asarray(p1, float)
    axis = p1 - p0
    length = np.linalg.norm(axis)
    if length < 1e-6:
        axis = np.array([0.0, 0.0, 1.0])
        length = 1e-6
    axis = axis / length
    x, y = _frame(axis, lateral)
    th = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    c, s = np.cos(th), np.sin(th)
    # rings: cap at p0 (phi from -pi/2 to 0), body (t from 0 to 1), cap at p1 (phi 0 to pi/2)
    rows = []
    for k in range(n_cap):
        phi = -np.pi / 2 + (np.pi / 2) * (k + 0.5) / n_cap
        rows.append((0.0, np.cos(phi), np.sin(phi) * cap0))
    for k in range(n_along + 1):
        rows.append((k / n_along, 1.0, 0.0))
    for k in range(n_cap):
        phi = (np.pi / 2) * (k + 0.5) / n_cap
        rows.append((1.0, np.cos(phi), np.sin(phi) * cap1))
    r0 = np.asarray(r0, float)
    r1 = np.asarray(r1, float)
    V, N, UV = [], [], []
    for t, ring, ax in rows:
        rx, ry = (1 - t) * r0 + t * r1
        centre = p0 + axis * (t * length)
        rmean = 0.5 * (rx + ry)
        off = ax * rmean
        ring_pts = centre + axis * off + ring * (rx * c[:, None] * x + ry * s[:, None] * y)
        # normal of the ellipse section (approximate for the taper)
        nr = (c[:, None] * x / max(rx, 1e-6) + s[:, None] * y / max(ry, 1e-6))
        nr /= np.linalg.norm(nr, axis=1, keepdims=True)
        nrm = ring * nr + (np.sign(ax) * np.sqrt(max(0.0, 1 - ring ** 2)) if ax != 0 else 0.0) * axis
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        V.append(ring_pts)
        N.append(nrm)
        UV.append(np.stack([th / (2 * np.pi), np.full(n_around, t * length + off)], -1))
    V = np.concatenate(V)
    N = np.concatenate(N)
    UV = np.concatenate(UV)
    tris = _grid_triangles(len(rows), n_around, 0)
    # close the poles with fans
    bottom = len(V)
    top = bottom + 1
    V = np.vstack([V, p0 - axis * (np.mean(r0) * cap0), p1 + axis * (np.mean(r1) * cap1)])
    N = np.vstack([N, -axis, axis])
    UV = np.vstack([UV, [0.0, -np.mean(r0) * cap0], [0.0, length + np.mean(r1) * cap1]])
    j = np.arange(n_around)
    last = (len(rows) - 1) * n_around
    fan0 = np.stack([np.full(n_around, bottom), (j + 1) % n_around, j], -1)
    fan1 = np.stack([np.full(n_around, top), last + j, last + (j + 1) % n_around], -1)
    tris = np.concatenate([tris, fan0, fan1])
    # orientation: make triangles counter-clockwise seen from outside
    tri_n = np.cross(V[tris[:, 1]] - V[tris[:, 0]], V[tris[:, 2]] - V[tris[:, 0]])
    flip = np.einsum("ij,ij->i", tri_n, N[tris].mean(1)) < 0
    tris[flip] = tris[flip][:, ::-1]
    b.add(V, N, tris, part, UV)


def _ellipsoid(b: _Builder, centre, axes, radii, part, n_around=32, n_rings=20):
    """Ellipsoid at ``centre`` with principal ``axes`` (3 rows, unit) and ``radii`` (3,)."""
    A = np.asarray(axes, float)
    r = np.asarray(radii, float)
    th = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    V, N, UV = [], [], []
    for k in range(n_rings):
        phi = -np.pi / 2 + np.pi * (k + 0.5) / n_rings
        unit = np.stack([np.cos(phi) * np.cos(th), np.cos(phi) * np.sin(th), np.full_like(th, np.sin(phi))], -1)
        V.append(centre + (unit * r) @ A)
        nrm = (unit / r) @ A
        N.append(nrm / np.linalg.norm(nrm, axis=1, keepdims=True))
        UV.append(np.stack([th / (2 * np.pi), np.full(n_around, np.sin(phi) * r[2])], -1))
    V = np.concatenate(V)
    N = np.concatenate(N)
    UV = np.concatenate(UV)
    tris = _grid_triangles(n_rings, n_around, 0)
    bottom, top = len(V), len(V) + 1
    V = np.vstack([V, centre - r[2] * A[2], centre + r[2] * A[2]])
    N = np.vstack([N, -A[2], A[2]])
    UV = np.vstack([UV, [0.0, -r[2]], [0.0, r[2]]])
    j = np.arange(n_around)
    last = (n_rings - 1) * n_around
    tris = np.concatenate([tris, np.stack([np.full(n_around, bottom), (j + 1) % n_around, j], -1),
                           np.stack([np.full(n_around, top), last + j, last + (j + 1) % n_around], -1)])
    tri_n = np.cross(V[tris[:, 1]] - V[tris[:, 0]], V[tris[:, 2]] - V[tris[:, 0]])
    flip = np.einsum("ij,ij->i", tri_n, N[tris].mean(1)) < 0
    tris[flip] = tris[flip][:, ::-1]
    b.add(V, N, tris, part, UV)


class BodyModel:
    """Builds posed, coloured body meshes for one person.

    Parameters
    ----------
    shape : BodyShape
    rng : numpy.random.Generator or int or None
        Seeds the fabric noise (fixed per person, so the texture moves with the body).
    detail : float
        Tessellation multiplier (1 = about 25k vertices).
    """

    def __init__(self, shape: BodyShape, rng: np.random.Generator | int | None = None, detail: float = 1.0):
        self.shape = shape
        self.detail = float(detail)
        rng = np.random.default_rng(rng)
        self._noise_seed = int(rng.integers(2**31))
        self._noise = None  # per-vertex noise, created on first build (vertex count fixed per model)

    @classmethod
    def sample(cls, proportions: BodyProportions, rng: np.random.Generator | int | None = None,
               detail: float = 1.0) -> "BodyModel":
        rng = np.random.default_rng(rng)
        return cls(BodyShape.sample(proportions, rng), rng, detail)

    # ------------------------------------------------------------------ sizes
    def radii(self) -> dict[str, tuple]:
        """Cross-section radii (rx, ry) in metres at the two ends of each capsule part."""
        h = self.shape.proportions.height / 1.75 * self.shape.girth
        p = self.shape.proportions
        return {
            "torso": ((p.shoulder_half_width + 0.035 * h, 0.105 * h), (p.hip_half_width + 0.075 * h, 0.11 * h)),
            "upper_arm": ((0.050 * h,) * 2, (0.040 * h,) * 2),
            "forearm": ((0.040 * h,) * 2, (0.030 * h,) * 2),
            "thigh": ((0.080 * h,) * 2, (0.055 * h,) * 2),
            "shank": ((0.052 * h,) * 2, (0.038 * h,) * 2),
            "neck": ((0.050 * h,) * 2, (0.048 * h,) * 2),
        }

    # ------------------------------------------------------------------- mesh
    def mesh(self, joints: np.ndarray) -> BodyMesh:
        """Pose the body on ``joints``.

        Parameters
        ----------
        joints : ndarray of shape (14, 3)
            World coordinates, metres, order of ``SKELETON_14``.

        Returns
        -------
        BodyMesh
        """
        J = np.asarray(joints, float)
        if J.shape != (14, 3) or not np.all(np.isfinite(J)):
            raise InputError("joints", "a finite array of shape (14, 3)", f"shape {J.shape}")
        d = self.detail
        na = lambda n: max(8, int(round(n * d)))  # noqa: E731
        b = _Builder()
        R = self.radii()
        h = self.shape.proportions.height / 1.75
        lateral = (J[_J["r_shoulder"]] - J[_J["l_shoulder"]]) + (J[_J["r_hip"]] - J[_J["l_hip"]])
        lateral /= max(np.linalg.norm(lateral), 1e-9)
        pelvis = 0.5 * (J[_J["l_hip"]] + J[_J["r_hip"]])
        neck = J[_J["neck"]]
        head = J[_J["head"]]
        # torso: from the neck down to below the pelvis
        tdir = pelvis - neck
        tdir /= max(np.linalg.norm(tdir), 1e-9)
        _capsule(b, neck + 0.01 * h * tdir, pelvis + 0.02 * h * tdir, *R["torso"], lateral, _PART["torso"],
                 n_around=na(56), n_along=na(28), n_cap=na(8), cap0=0.35, cap1=0.55)
        # neck cylinder and head ellipsoid
        _capsule(b, neck, head, *R["neck"], lateral, _PART["head"], n_around=na(24), n_along=na(6), n_cap=4)
        up = head - neck
        up /= max(np.linalg.norm(up), 1e-9)
        fwd = np.cross(up, lateral)
        fwd /= max(np.linalg.norm(fwd), 1e-9)
        lat = np.cross(fwd, up)
        _ellipsoid(b, head + 0.02 * h * up, np.stack([lat, fwd, up]), np.array([0.075, 0.090, 0.110]) * h,
                   _PART["head"], n_around=na(40), n_rings=na(28))
        for side in ("l", "r"):
            sh, el, wr = (J[_J[f"{side}_{n}"]] for n in ("shoulder", "elbow", "wrist"))
            hip, kn, an = (J[_J[f"{side}_{n}"]] for n in ("hip", "knee", "ankle"))
            _capsule(b, sh, el, *R["upper_arm"], lateral, _PART[f"{side}_upper_arm"], n_around=na(28), n_along=na(16))
            _capsule(b, el, wr, *R["forearm"], lateral, _PART[f"{side}_forearm"], n_around=na(24), n_along=na(16))
            fa = wr - el
            fa /= max(np.linalg.norm(fa), 1e-9)
            hx, hy = _frame(fa, lateral)
            _ellipsoid(b, wr + 0.075 * h * fa, np.stack([hx, hy, fa]), np.array([0.045, 0.022, 0.085]) * h,
                       _PART[f"{side}_forearm"], n_around=na(20), n_rings=na(12))
            _capsule(b, hip, kn, *R["thigh"], lateral, _PART[f"{side}_thigh"], n_around=na(32), n_along=na(18))
            _capsule(b, kn, an, *R["shank"], lateral, _PART[f"{side}_shank"], n_around=na(28), n_along=na(18))
            # foot: forward of the ankle, flat on the ground when standing
            sk = an - kn
            sk /= max(np.linalg.norm(sk), 1e-9)
            ffwd = np.cross(-sk, lateral)
            ffwd /= max(np.linalg.norm(ffwd), 1e-9)
            flat = np.cross(ffwd, -sk)
            centre = an + 0.065 * h * ffwd + 0.031 * h * sk
            _ellipsoid(b, centre, np.stack([flat, -sk, ffwd]), np.array([0.045, 0.038, 0.125]) * h,
                       _PART[f"{side}_shank"], n_around=na(20), n_rings=na(14))
        V = np.concatenate(b.verts)
        N = np.concatenate(b.normals)
        T = np.concatenate(b.tris).astype(np.int32)
        TP = np.concatenate(b.tri_parts)
        colors = self._colour(V, np.concatenate(b.uv), np.concatenate(b.vparts), J, up, lateral)
        return BodyMesh(V, T, colors, N, TP)

    # ----------------------------------------------------------------- colour
    def _colour(self, V, UV, vparts, J, up, lateral) -> np.ndarray:
        s = self.shape
        n = len(V)
        if self._noise is None or len(self._noise) != n:
            nrng = np.random.default_rng(self._noise_seed)
            self._noise = nrng.normal(0.0, 1.0, (n, 3)) * 0.3 + nrng.normal(0.0, 1.0, (n, 1))
        mat = np.full(n, SHIRT, np.int8)
        name = {i + 1: nm for i, nm in enumerate(SKELETON_14.part_names)}
        for pid, nm in name.items():
            sel = vparts == pid
            if nm in ("l_thigh", "r_thigh", "l_shank", "r_shank"):
                mat[sel] = TROUSERS
            elif nm in ("l_forearm", "r_forearm"):
                mat[sel] = SHIRT if s.long_sleeves else SKIN
            elif nm == "head":
                mat[sel] = SKIN
        head = J[_J["head"]]
        # hair: the head above the ears and the back of the head
        fwd = np.cross(up, lateral)
        rel = V - head
        hair = (vparts == _PART["head"]) & ((rel @ up > 0.015) | ((rel @ fwd < -0.03) & (rel @ up > -0.05)))
        mat[hair] = HAIR
        # hands are skin, feet shoes, short trousers show skin on the shanks
        for side in ("l", "r"):
            wr = J[_J[f"{side}_wrist"]]
            el = J[_J[f"{side}_elbow"]]
            fa = (wr - el) / max(np.linalg.norm(wr - el), 1e-9)
            sel = (vparts == _PART[f"{side}_forearm"]) & ((V - wr) @ fa > -0.01)
            mat[sel] = SKIN
            an = J[_J[f"{side}_ankle"]]
            kn = J[_J[f"{side}_knee"]]
            sk = (an - kn) / max(np.linalg.norm(an - kn), 1e-9)
            sel = (vparts == _PART[f"{side}_shank"]) & ((V - an) @ sk > -0.03)
            mat[sel] = SHOES
            if not s.long_trousers:
                sel = (vparts == _PART[f"{side}_shank"]) & (mat == TROUSERS)
                mat[sel] = SKIN
            if not s.long_sleeves:
                sh = J[_J[f"{side}_shoulder"]]
                ua = (el - sh) / max(np.linalg.norm(el - sh), 1e-9)
                L = np.linalg.norm(el - sh)
                sel = (vparts == _PART[f"{side}_upper_arm"]) & ((V - sh) @ ua > 0.55 * L)
                mat[sel] = SKIN
        col = s.colours[mat].copy()
        # print pattern on the shirt (in the surface coordinates, so it moves with the cloth)
        shirt = mat == SHIRT
        u, v = UV[:, 0], UV[:, 1]
        if s.pattern_kind == "stripes":
            on = (np.floor(v / 0.06) % 2) == 0
        elif s.pattern_kind in ("checks", "checks_all"):
            on = ((np.floor(v / 0.07) + np.floor(u * 10)) % 2) == 0
        else:
            on = np.zeros(n, bool)
        col[shirt & on] = 0.55 * col[shirt & on] + 0.45 * s.pattern[0]
        trousers = mat == TROUSERS
        if s.pattern_kind == "checks_all":  # the whole outfit checked (texture for stereo matching)
            col[trousers & on] = 0.55 * col[trousers & on] + 0.45 * s.pattern[0]
        seam = (np.abs(((u * 4) % 1.0) - 0.5) < 0.04)
        col[trousers & seam] = 0.6 * col[trousers & seam] + 0.4 * s.pattern[1]
        col = col * (1.0 + s.noise_amplitude * self._noise)
        return np.clip(col, 0.0, 1.0)
