"""The articulated-billboard data model (source 000 §1, claims 9 and 11).

Every body part (bone) of the 14-joint skeleton gets a *fan*: one billboard per
source camera.  The billboard of camera ``j`` for a bone with proximal end
``x`` and unit direction ``b`` lies in the plane through ``x`` spanned by ``b``
and ``b x (c_j - x)`` (``c_j`` the camera centre), so it contains the bone and
faces that camera as much as a plane holding the bone can.

Texture frame of a billboard (all in world metres):

* ``e_v`` = ``b`` (texture rows run from the proximal to the distal end),
* ``normal`` = unit component of ``c_j - x`` orthogonal to ``b`` (towards the
  source camera),
* ``e_u`` = ``normal x e_v`` (texture columns), so that seen from the source
  camera the texture is not mirrored.

``corners`` are the outer corners of the texture, in the order TL, TR, BR, BL
(TL = texel (0, 0) corner, TR = end of row 0, BL = end of column 0).  Texel
centres sit at half-integer fractions: texel ``(u, v)`` (column, row) is the
world point ``TL + (u + 0.5) / w * (TR - TL) + (v + 0.5) / h * (BL - TL)``;
:meth:`Billboard.world_from_texture` is that map as a 3x3 matrix acting on
``(u, v, 1)``.

Calibration offsets (stage 1) are in the cameras: the model's rig holds the
source cameras with their principal points corrected
(:func:`toolkit.multiview.corrected_rig`), so a camera's projection is where
the person appears in its image, and a source view is drawn through its
corrected camera like any other view.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError, check_shape


def _ro(a, dtype=np.float64) -> np.ndarray:
    a = np.array(a, dtype=dtype, copy=True)
    a.setflags(write=False)
    return a


#: Projection surfaces a billboard may carry (source 000 claim 11: planes, ellipsoids, cylinders).
SURFACES = ("plane", "cylinder", "ellipsoid")


@dataclass(frozen=True, eq=False)
class Billboard:
    """One textured billboard: one bone seen by one source camera.

    Parameters
    ----------
    part : int
        1-based part id (1 + index in ``SKELETON_14.parts``).
    camera : str
        Name of the source camera the texture comes from.
    corners : ndarray of shape (4, 3)
        World corners, metres, order TL, TR, BR, BL (see module docstring).
    texture : ndarray of shape (h, w, 3), uint8
        RGB texture sampled from the source image through its corrected camera.
    alpha : ndarray of shape (h, w), float32
        Coverage in [0, 1]: 1 where the source pixel belongs to this part
        (seam pixels included for both adjacent parts), 0 elsewhere.
    normal : ndarray of shape (3,)
        Unit plane normal pointing towards the source camera.
    surface : str
        ``"plane"`` (the source's billboards), ``"cylinder"`` or ``"ellipsoid"``
        (projection surfaces around the bone; the texture then stores the
        source image as projected on that surface, parametrised on the same
        plane frame, see :mod:`toolkit.billboards.surfaces`).
    radius : float
        Radius of the cylinder / equatorial radius of the ellipsoid, metres
        (0 for planes).
    axis : ndarray of shape (2, 3) or None
        Proximal and distal end of the bone, metres; needed by non-planar
        surfaces (their axis), optional for planes.
    """

    part: int
    camera: str
    corners: np.ndarray
    texture: np.ndarray
    alpha: np.ndarray
    normal: np.ndarray
    surface: str = "plane"
    radius: float = 0.0
    axis: np.ndarray | None = None

    def __post_init__(self):
        check_shape("Billboard.corners", self.corners, (4, 3))
        check_shape("Billboard.normal", self.normal, (3,))
        tex = np.asarray(self.texture)
        if tex.ndim != 3 or tex.shape[2] != 3 or tex.dtype != np.uint8 or tex.shape[0] < 1 or tex.shape[1] < 1:
            raise InputError("Billboard.texture", "a non-empty (h, w, 3) uint8 array",
                             f"shape {tex.shape}, dtype {tex.dtype}")
        al = np.asarray(self.alpha, dtype=np.float32)
        if al.shape != tex.shape[:2]:
            raise InputError("Billboard.alpha", f"shape {tex.shape[:2]} (the texture's)", f"shape {al.shape}")
        if self.surface not in SURFACES:
            raise InputError("Billboard.surface", f"one of {SURFACES}", repr(self.surface))
        object.__setattr__(self, "corners", _ro(self.corners))
        object.__setattr__(self, "normal", _ro(self.normal))
        object.__setattr__(self, "texture", _ro(tex, np.uint8))
        object.__setattr__(self, "alpha", _ro(al, np.float32))
        if self.axis is not None:
            check_shape("Billboard.axis", self.axis, (2, 3))
            object.__setattr__(self, "axis", _ro(self.axis))
        elif self.surface != "plane":
            raise InputError("Billboard.axis", f"the bone ends (2, 3) for a {self.surface} surface", "None")

    @property
    def size(self) -> tuple[int, int]:
        """Texture ``(width, height)`` in texels."""
        return int(self.texture.shape[1]), int(self.texture.shape[0])

    @property
    def center(self) -> np.ndarray:
        """Centre of the quad, (3,) metres."""
        return self.corners.mean(axis=0)

    @property
    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """``(e_u, e_v)`` unit world directions of the texture columns and rows."""
        u = self.corners[1] - self.corners[0]
        v = self.corners[3] - self.corners[0]
        return u / np.linalg.norm(u), v / np.linalg.norm(v)

    def world_from_texture(self) -> np.ndarray:
        """Matrix M of shape (3, 3) with ``X = M @ (u, v, 1)`` the world point of texel (u, v)."""
        w, h = self.size
        tl, tr, bl = self.corners[0], self.corners[1], self.corners[3]
        du = (tr - tl) / w
        dv = (bl - tl) / h
        return np.column_stack([du, dv, tl + 0.5 * du + 0.5 * dv])

    def texture_from_world(self, points: np.ndarray) -> np.ndarray:
        """Texel coordinates (..., 2) of world points (..., 3) projected orthogonally onto the plane."""
        p = np.asarray(points, float)
        M = self.world_from_texture()
        d = p - M[:, 2]
        du, dv = M[:, 0], M[:, 1]
        return np.stack([d @ du / (du @ du), d @ dv / (dv @ dv)], axis=-1)

    def view_from_texture(self, camera: Camera) -> np.ndarray:
        """Homography (3, 3) from texel (u, v, 1) to pixels of ``camera``.

        Exact for pinhole cameras; lens distortion of ``camera`` is ignored.
        """
        M = self.world_from_texture()
        A = camera.R @ M
        A[:, 2] += camera.t
        return camera.K @ A

    def rgba(self) -> np.ndarray:
        """Texture and alpha as one (h, w, 4) uint8 RGBA image (for quads in the recording)."""
        a = np.clip(np.rint(self.alpha * 255.0), 0, 255).astype(np.uint8)
        return np.dstack([self.texture, a])


@dataclass(frozen=True, eq=False)
class BillboardFan:
    """The billboards of one bone, one per source camera that sees the part.

    Parameters
    ----------
    part : int
        1-based part id.
    billboards : tuple of Billboard
        At most one per source camera; cameras where the part's segment is
        empty or the bone points at the camera (edge-on) have none.
    axis : ndarray of shape (2, 3)
        Proximal and distal end of the bone, metres.
    """

    part: int
    billboards: tuple[Billboard, ...]
    axis: np.ndarray

    def __post_init__(self):
        check_shape("BillboardFan.axis", self.axis, (2, 3))
        object.__setattr__(self, "axis", _ro(self.axis))
        object.__setattr__(self, "billboards", tuple(self.billboards))
        for b in self.billboards:
            if b.part != self.part:
                raise InputError("BillboardFan.billboards", f"billboards of part {self.part}",
                                 f"a billboard of part {b.part}")

    @property
    def cameras(self) -> list[str]:
        return [b.camera for b in self.billboards]


@dataclass(frozen=True, eq=False)
class BillboardModel:
    """The articulated billboard model of one frame.

    Parameters
    ----------
    fans : tuple of BillboardFan
        One per body part that has at least one billboard, in part order.
    rig : Rig
        The source cameras, corrected by stage 1's offsets
        (:func:`toolkit.multiview.corrected_rig`).
    frame : int
        Frame index.
    joints : ndarray of shape (14, 3)
        The 3D joints the fans were built on, metres.
    """

    fans: tuple[BillboardFan, ...]
    rig: Rig
    frame: int
    joints: np.ndarray = field(default_factory=lambda: np.full((14, 3), np.nan))

    def __post_init__(self):
        object.__setattr__(self, "fans", tuple(self.fans))
        object.__setattr__(self, "joints", _ro(self.joints))

    @property
    def billboards(self) -> list[Billboard]:
        """All billboards of all fans."""
        return [b for f in self.fans for b in f.billboards]

    def fan(self, part: int) -> BillboardFan | None:
        """The fan of a 1-based part id, or None."""
        for f in self.fans:
            if f.part == part:
                return f
        return None
