"""An articulated soft-object body: metaballs on the 14-joint skeleton (source 002).

Kinematic chain
---------------
Eleven rigid *frames* (pelvis, trunk, head, upper arms, forearms, thighs,
shanks), each with a pivot joint and a local rotation made of elementary
rotations about its own x (right), y (forward), z (up) axes.  The angle
conventions are those of :mod:`toolkit.motion.kinematics` (so a
:class:`~toolkit.motion.Pose14` maps onto the parameters exactly), plus a
lateral trunk bend (``Ry``, 0 in the motion library):

* pelvis: ``R0 = exp([root_rotvec]x)``, its origin ``root_translation`` the
  mid-hip point; the hips at ``(-/+ hip_half_width, 0, 0)``.
* trunk: ``R0 Rx(-lean) Ry(bend) Rz(twist)`` pivoting at the mid-hip point;
  neck ``(0, 0, torso)``, shoulders ``neck + (-/+ shoulder_half_width, 0,
  -shoulder_drop)``.
* head: ``R_trunk Rx(-head_pitch) Ry(head_roll)``; head ``neck + (0, 0, neck_to_head)``.
* upper arm / thigh: ``R_parent Rx(flexion) Ry(s abduction) Rz(-s rotation)``
  (``s = +1`` left, ``-1`` right), the segment along ``-z``; forearm
  ``Rx(+elbow)``, shank ``Rx(-knee)``.

Parameters (one vector, :class:`SoftBodyParams`): root rotation vector (3,
radians) and translation (3, metres), 21 joint angles (radians), 13 segment
lengths (metres, :data:`LENGTH_NAMES`) and 7 width multipliers
(:data:`WIDTH_GROUPS`, 1 = the reference body).

Metaballs
---------
Each primitive ``i`` is an ellipsoid rigidly attached to one frame: centre
``c_i = J_pivot + R_f (s_i L_f d_f + delta_i)`` (``s_i`` the fraction along
the frame's segment of length ``L_f`` and direction ``d_f``), radii
``(w_g rx_i, w_g ry_i, rz_i)`` in the frame's axes, where ``rz_i = a_i L_f``
for primitives stretched along their segment (so they follow a length
change) and ``w_g rz_i`` otherwise.  Its *ellipsoidal distance* ``e_i(x)`` is
the radial distance ``|p| (1 - 1/sqrt(q))`` with ``p`` the point in the
ellipsoid's axes and ``q = sum (p/r)^2`` (exact for a sphere, metres).  The
density of a primitive falls off as ``exp(-e_i / blend)``; the densities are
summed and the surface is the level set ``sum = 1``.  The distance of
:mod:`toolkit.softbody.distance` is ``-blend * log(sum)``: zero on the
surface, about ``e_i`` near one isolated primitive, at most ``blend * log(2)``
below the smallest ``e_i`` where two primitives blend.

Default radii follow the synthetic bodies of :class:`toolkit.body.BodyModel`
(its capsule and ellipsoid radii as fractions of stature).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14

__all__ = ["FRAMES", "DOF_NAMES", "LENGTH_NAMES", "WIDTH_GROUPS", "N_POSE", "N_PARAMS", "POSE", "LENGTHS",
           "WIDTHS", "SoftBodyParams", "SoftBodyModel", "ModelState", "BLEND_M", "pose_bounds",
           "attached_points_jacobian", "rotvec_to_matrix", "TRUNK_POSTURE", "SYMMETRIC_LENGTHS", "STATURE_CHAIN",
           "canonical_pose", "pose_step", "continuous_poses"]

_J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
PELVIS = 14  #: node index of the mid-hip point (the 15th node after the 14 joints)

#: Rigid frames of the chain, parents before children.
FRAMES = ("pelvis", "trunk", "head", "l_upper_arm", "l_forearm", "r_upper_arm", "r_forearm",
          "l_thigh", "l_shank", "r_thigh", "r_shank")
_FRAME_PARENT = (-1, 0, 1, 1, 3, 1, 5, 0, 7, 0, 9)
_FRAME_PIVOT = (PELVIS, PELVIS, _J["neck"], _J["l_shoulder"], _J["l_elbow"], _J["r_shoulder"], _J["r_elbow"],
                _J["l_hip"], _J["l_knee"], _J["r_hip"], _J["r_knee"])

#: Segment lengths, metres.
LENGTH_NAMES = ("neck_to_head", "shoulder_half_width", "shoulder_drop", "torso", "hip_half_width",
                "l_upper_arm", "l_forearm", "r_upper_arm", "r_forearm", "l_thigh", "l_shank", "r_thigh", "r_shank")
_L = {n: i for i, n in enumerate(LENGTH_NAMES)}
#: Length along each frame's segment (-1: none) and the segment's direction in the frame.
_FRAME_LENGTH = (-1, _L["torso"], _L["neck_to_head"], _L["l_upper_arm"], _L["l_forearm"], _L["r_upper_arm"],
                 _L["r_forearm"], _L["l_thigh"], _L["l_shank"], _L["r_thigh"], _L["r_shank"])
_UP, _DOWN = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])
_FRAME_DIR = np.array([_UP, _UP, _UP] + [_DOWN] * 8)

#: Width groups (one multiplier each, left and right shared).
WIDTH_GROUPS = ("head", "chest", "pelvis", "upper_arm", "forearm", "thigh", "shank")
_G = {n: i for i, n in enumerate(WIDTH_GROUPS)}
#: Left/right pairs of segment lengths (indices into LENGTH_NAMES), (4, 2): the symmetry priors.
SYMMETRIC_LENGTHS = np.array([[LENGTH_NAMES.index(f"l_{n}"), LENGTH_NAMES.index(f"r_{n}")]
                              for n in ("upper_arm", "forearm", "thigh", "shank")])
#: The stature chain (torso, neck to head, the mean of the two legs): weights on LENGTH_NAMES, (13,).
STATURE_CHAIN = np.array([1.0 if n in ("torso", "neck_to_head") else 0.5 if n.endswith(("thigh", "shank")) else 0.0
                          for n in LENGTH_NAMES])

# joint DOFs: frame -> [(name, axis, sign)], rotation R_axis(sign * angle), applied in order
_DOFS = {
    "trunk": [("lean", 0, -1.0), ("bend", 1, 1.0), ("twist", 2, 1.0)],
    "head": [("head_pitch", 0, -1.0), ("head_roll", 1, 1.0)],
}
for _side, _s in (("l", 1.0), ("r", -1.0)):
    _DOFS[f"{_side}_upper_arm"] = [(f"{_side}_shoulder_flexion", 0, 1.0), (f"{_side}_shoulder_abduction", 1, _s),
                                   (f"{_side}_shoulder_rotation", 2, -_s)]
    _DOFS[f"{_side}_forearm"] = [(f"{_side}_elbow", 0, 1.0)]
    _DOFS[f"{_side}_thigh"] = [(f"{_side}_hip_flexion", 0, 1.0), (f"{_side}_hip_abduction", 1, _s),
                               (f"{_side}_hip_rotation", 2, -_s)]
    _DOFS[f"{_side}_shank"] = [(f"{_side}_knee", 0, -1.0)]
_DOF_TABLE = [(FRAMES.index(f), name, axis, sign) for f in FRAMES[1:] for name, axis, sign in _DOFS[f]]

#: Names of the parameter vector's pose entries.
DOF_NAMES = ("root_rx", "root_ry", "root_rz", "root_tx", "root_ty", "root_tz") + tuple(d[1] for d in _DOF_TABLE)
N_POSE = len(DOF_NAMES)  # 27
#: Pose entries of the trunk's lateral bend and axial twist against the pelvis (the posture priors').
TRUNK_POSTURE = np.array([DOF_NAMES.index("bend"), DOF_NAMES.index("twist")])
N_PARAMS = N_POSE + len(LENGTH_NAMES) + len(WIDTH_GROUPS)  # 47
POSE = slice(0, N_POSE)
LENGTHS = slice(N_POSE, N_POSE + len(LENGTH_NAMES))
WIDTHS = slice(LENGTHS.stop, N_PARAMS)

# nodes: (node, base node, frame of the offset, [(length, unit vector)]), in computation order
_NODES = [
    (_J["neck"], PELVIS, 1, [(_L["torso"], _UP)]),
    (_J["head"], _J["neck"], 2, [(_L["neck_to_head"], _UP)]),
]
for _side, _lat in (("l", -1.0), ("r", 1.0)):
    _NODES += [
        (_J[f"{_side}_shoulder"], _J["neck"], 1,
         [(_L["shoulder_half_width"], np.array([_lat, 0, 0.0])), (_L["shoulder_drop"], _DOWN)]),
        (_J[f"{_side}_elbow"], _J[f"{_side}_shoulder"], FRAMES.index(f"{_side}_upper_arm"),
         [(_L[f"{_side}_upper_arm"], _DOWN)]),
        (_J[f"{_side}_wrist"], _J[f"{_side}_elbow"], FRAMES.index(f"{_side}_forearm"),
         [(_L[f"{_side}_forearm"], _DOWN)]),
        (_J[f"{_side}_hip"], PELVIS, 0, [(_L["hip_half_width"], np.array([_lat, 0, 0.0]))]),
        (_J[f"{_side}_knee"], _J[f"{_side}_hip"], FRAMES.index(f"{_side}_thigh"), [(_L[f"{_side}_thigh"], _DOWN)]),
        (_J[f"{_side}_ankle"], _J[f"{_side}_knee"], FRAMES.index(f"{_side}_shank"), [(_L[f"{_side}_shank"], _DOWN)]),
    ]

#: Blend distance of the soft minimum (metres): the density of a primitive
#: falls by e at this distance; two equal primitives bulge by at most
#: ``BLEND_M * log 2`` (7 mm) where they meet.
BLEND_M = 0.01


def _skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices (..., 3, 3) of vectors (..., 3)."""
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def _rot(axis: int, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def rotvec_to_matrix(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation matrix of a rotation vector and its left Jacobian.

    Returns
    -------
    R : ndarray of shape (3, 3)
    Jl : ndarray of shape (3, 3)
        ``d exp(r) / d r_k = [Jl[:, k]]x exp(r)``.
    """
    th = float(np.linalg.norm(r))
    K = _skew(np.asarray(r, float))
    if th < 1e-6:
        a, b, c = 1.0 - th ** 2 / 6, 0.5 - th ** 2 / 24, 1.0 / 6 - th ** 2 / 120
    else:
        a, b, c = np.sin(th) / th, (1 - np.cos(th)) / th ** 2, (th - np.sin(th)) / th ** 3
    return np.eye(3) + a * K + b * K @ K, np.eye(3) + b * K + c * K @ K


@dataclass(frozen=True)
class SoftBodyParams:
    """The state of the soft body: pose, segment lengths and widths.

    Attributes
    ----------
    vector : ndarray of shape (47,)
        ``[root rotation vector (3, rad), root translation (3, m), 21 joint
        angles (rad, :data:`DOF_NAMES`), 13 lengths (m, :data:`LENGTH_NAMES`),
        7 width multipliers (:data:`WIDTH_GROUPS`)]``.
    """

    vector: np.ndarray

    def __post_init__(self):
        v = np.array(self.vector, dtype=float).reshape(-1)
        if v.shape != (N_PARAMS,) or not np.all(np.isfinite(v)):
            raise InputError("SoftBodyParams.vector", f"{N_PARAMS} finite values", f"shape {np.shape(self.vector)}")
        v.setflags(write=False)
        object.__setattr__(self, "vector", v)

    @property
    def pose(self) -> np.ndarray:
        """(27,) root rotation vector, translation and joint angles."""
        return self.vector[POSE]

    @property
    def root_rotvec(self) -> np.ndarray:
        return self.vector[0:3]

    @property
    def root_translation(self) -> np.ndarray:
        return self.vector[3:6]

    @property
    def angles(self) -> np.ndarray:
        """(21,) joint angles, radians."""
        return self.vector[6:N_POSE]

    @property
    def lengths(self) -> np.ndarray:
        """(13,) segment lengths, metres."""
        return self.vector[LENGTHS]

    @property
    def widths(self) -> np.ndarray:
        """(7,) width multipliers."""
        return self.vector[WIDTHS]

    def replace(self, *, pose=None, lengths=None, widths=None) -> "SoftBodyParams":
        """A copy with some blocks replaced."""
        v = self.vector.copy()
        for block, val in ((POSE, pose), (LENGTHS, lengths), (WIDTHS, widths)):
            if val is not None:
                v[block] = val
        return SoftBodyParams(v)

    @classmethod
    def build(cls, pose, lengths, widths) -> "SoftBodyParams":
        return cls(np.concatenate([np.ravel(pose), np.ravel(lengths), np.ravel(widths)]))


@dataclass(frozen=True)
class ModelState:
    """Everything the distance and its derivatives need for one parameter vector.

    Attributes
    ----------
    frame_R : ndarray of shape (11, 3, 3)
        World rotation of each frame (columns: the frame's x, y, z axes).
    nodes : ndarray of shape (15, 3)
        The 14 joints and the mid-hip point, metres.
    dnodes_dlengths : ndarray of shape (15, 13, 3)
    dof_axes, dof_pivots : ndarray of shape (27, 3)
        World rotation axis and pivot of each rotational pose DOF (rows 3..5,
        the translations, are zero).
    dof_frames : ndarray of shape (27,) int
        The frame each DOF turns (with its subtree).
    centres, radii : ndarray of shape (P, 3)
    prim_R : ndarray of shape (P, 3, 3)
    dcentres_dlengths : ndarray of shape (P, 13, 3)
    """

    frame_R: np.ndarray
    nodes: np.ndarray
    dnodes_dlengths: np.ndarray
    dof_axes: np.ndarray
    dof_pivots: np.ndarray
    dof_frames: np.ndarray
    centres: np.ndarray
    radii: np.ndarray
    prim_R: np.ndarray
    dcentres_dlengths: np.ndarray


@dataclass(frozen=True)
class _Primitive:
    frame: int
    s: float  # fraction along the frame's segment
    offset: tuple  # (3,) metres in the frame's axes
    radii: tuple  # (3,) metres: rx, ry, and rz (or the axial fraction of the segment length)
    group: int
    axial: bool  # rz = radii[2] * segment length


#: Chest radii multiplier: the width multipliers fitted to the visible surface of
#: :class:`toolkit.body.BodyModel` bodies (6 people, 6 motions, 3 frames each,
#: 16 viewpoints, poses and lengths known) were 0.97-1.04 for every group but
#: the chest (1.13), whose reference radii are scaled by this.
_CHEST = 1.12


def _primitives(p: BodyProportions, girth: float = 1.0) -> list[_Primitive]:
    """Metaballs approximating :class:`toolkit.body.BodyModel`'s volumes for ``p``."""
    h = p.height / 1.75 * girth
    hh = p.height / 1.75
    prims = []
    t = FRAMES.index
    # pelvis block below the mid-hip point, a waist ball above it, then the trunk from the hips to the neck
    # (the synthetic torso ends about 0.1 m below the hip joints; below that, between the thighs, is a gap).
    # Calibrated with the neck, head and arm balls (0508e32: benchmarks/calibrate_softbody_layout.py
    # --seeds 2000 2200 2400 --fit --groups trunk head arms, after a --groups trunk round): radii, axial extents
    # and places fitted (least_squares, soft-L1 at 1 cm) to the signed distance of the outer-surface vertices
    # (not those buried inside another volume) of the torso, head, arms and the thighs' top 15 cm of 48
    # BodyModel meshes posed on their own joints with their true lengths and girth.  80bd066 fitted two pelvis
    # blocks and three trunk balls to every vertex, the buried ones too; its layout left the band 0-0.1 m above
    # the mid-hip 22 mm too thin on the outer surface (held-out seeds 3000 3200), a gap the waist ball (second
    # below, in place of a small pelvis block at 0.11 m) fills; torso outer-surface mean |d| 7.4 -> 2.5 mm.  The
    # layout before 80bd066 (trunk balls at 0.40 / 0.62 / 0.86 of the trunk) left the waist 20 mm and the top of the
    # chest 17 mm too thin; fitted to the true body's points, the global fit raised the pelvis 30-96 mm.
    pw = p.hip_half_width + 0.07 * h
    sw = p.shoulder_half_width + 0.03 * h
    prims.append(_Primitive(t("pelvis"), 0, (0, 0, 0.003 * hh), (1.036 * pw, 1.051 * 0.105 * h, 1.105 * 0.09 * hh),
                            _G["pelvis"], False))
    prims.append(_Primitive(t("trunk"), 0, (0, 0, 0.09 * hh),
                            (1.045 * (p.hip_half_width + 0.075 * h), 0.991 * 0.11 * h, 0.164 * hh), _G["pelvis"],
                            False))
    # trunk balls: (s along the trunk, half width m, half depth m, axial fraction of the trunk)
    for s, rx, ry, rz in ((0.432, 1.0655 * (p.hip_half_width + 0.065 * h), 0.979 * 0.1 * h, 0.540),
                          (0.757, 0.9826 * 0.5 * (sw + pw), 0.974 * 0.1 * h, 0.3132),
                          (0.967, 0.9224 * sw, 0.968 * 0.1 * h, 0.1112)):
        prims.append(_Primitive(t("trunk"), s, (0, 0, 0), (_CHEST * rx, _CHEST * ry, rz), _G["chest"], True))
    # neck and head (calibrated with the trunk: the neck ball covers the neck's visible top, the rest is in the chest)
    prims.append(_Primitive(t("head"), 0.58, (0, 0, 0), (0.0423 * h, 0.0596 * h, 0.369), _G["head"], True))
    prims.append(_Primitive(t("head"), 1.0, (0, 0, 0.028 * hh), (0.0748 * h, 0.09 * h, 0.1011 * h), _G["head"], False))
    # limb balls: (s along the segment, half width / h, half depth / h, axial fraction of the segment); the arms
    # calibrated with the trunk (from a taper between BodyModel's capsule radii), the legs that taper; the hand and
    # the foot are BodyModel's ellipsoids
    limbs = {"upper_arm": ((0.090, 0.0494, 0.0489, 0.346), (0.473, 0.0460, 0.0443, 0.394),
                           (0.820, 0.0395, 0.0408, 0.338)),
             "forearm": ((0.146, 0.0371, 0.0376, 0.379), (0.534, 0.0346, 0.0345, 0.390),
                         (0.909, 0.0311, 0.0318, 0.226))}
    for name, r0, r1, n in (("thigh", 0.08, 0.055, 4), ("shank", 0.052, 0.038, 3)):
        limbs[name] = tuple(((k + 0.5) / n, r0 + (r1 - r0) * (k + 0.5) / n, r0 + (r1 - r0) * (k + 0.5) / n, 0.8 / n)
                            for k in range(n))
    for side in ("l", "r"):
        for name, balls in limbs.items():
            for s, rx, ry, rz in balls:
                prims.append(_Primitive(t(f"{side}_{name}"), s, (0, 0, 0), (rx * h, ry * h, rz), _G[name], True))
        prims.append(_Primitive(t(f"{side}_forearm"), 1.0, (0, 0, -0.075 * hh), (0.045 * h, 0.022 * h, 0.085 * h),
                                _G["forearm"], False))
        prims.append(_Primitive(t(f"{side}_shank"), 1.0, (0, 0.065 * hh, -0.031 * hh),
                                (0.045 * h, 0.125 * h, 0.038 * h), _G["shank"], False))
    return prims


def _lengths_of(p: BodyProportions) -> np.ndarray:
    v = {"neck_to_head": p.neck_to_head, "shoulder_half_width": p.shoulder_half_width,
         "shoulder_drop": p.shoulder_drop, "torso": p.torso, "hip_half_width": p.hip_half_width}
    for side in ("l", "r"):
        v.update({f"{side}_upper_arm": p.upper_arm, f"{side}_forearm": p.forearm, f"{side}_thigh": p.thigh,
                  f"{side}_shank": p.shank})
    return np.array([v[n] for n in LENGTH_NAMES])


class SoftBodyModel:
    """The metaball layout of one body (radii for width multipliers of 1).

    Parameters
    ----------
    proportions : BodyProportions, optional
        Sets the reference radii (default: median proportions of a 1.75 m person).
    girth : float
        Multiplier of the radial sizes (as :class:`toolkit.body.BodyShape.girth`).
    blend : float
        Blend distance of the soft minimum, metres (:data:`BLEND_M`).
    """

    def __init__(self, proportions: BodyProportions | None = None, *, girth: float = 1.0, blend: float = BLEND_M):
        if not (np.isfinite(girth) and girth > 0):
            raise InputError("girth", "a positive number", repr(girth))
        if not (np.isfinite(blend) and blend > 0):
            raise InputError("blend", "a positive distance in metres", repr(blend))
        self.proportions = proportions if proportions is not None else BodyProportions.from_height(1.75)
        self.girth = float(girth)
        self.blend = float(blend)
        prims = _primitives(self.proportions, self.girth)
        self.prim_frame = np.array([q.frame for q in prims])
        self.prim_s = np.array([q.s for q in prims], float)
        self.prim_offset = np.array([q.offset for q in prims], float)
        self.prim_radii = np.array([q.radii for q in prims], float)
        self.prim_group = np.array([q.group for q in prims])
        self.prim_axial = np.array([q.axial for q in prims])
        self.n_prims = len(prims)
        n_f = len(FRAMES)
        # subtree[f, g] = frame g is f or below f
        sub = np.eye(n_f, dtype=bool)
        for g in range(n_f):
            f = _FRAME_PARENT[g]
            while f >= 0:
                sub[f, g] = True
                f = _FRAME_PARENT[f]
        self.subtree = sub
        self.prim_onehot_frame = np.eye(n_f)[self.prim_frame]  # (P, F)
        self.prim_onehot_group = np.eye(len(WIDTH_GROUPS))[self.prim_group]  # (P, G)
        seg = np.array(_FRAME_LENGTH)[self.prim_frame]
        self.prim_onehot_length = np.zeros((self.n_prims, len(LENGTH_NAMES)))
        rows = np.flatnonzero(self.prim_axial)
        self.prim_onehot_length[rows, seg[rows]] = 1.0

    # ------------------------------------------------------------ parameters
    def default_params(self, root_translation=(0.0, 0.0, 0.0)) -> SoftBodyParams:
        """Rest pose (standing, arms down, facing +y) with this model's proportions."""
        pose = np.zeros(N_POSE)
        pose[3:6] = root_translation
        return SoftBodyParams.build(pose, _lengths_of(self.proportions), np.ones(len(WIDTH_GROUPS)))

    @staticmethod
    def lengths_from_proportions(proportions: BodyProportions) -> np.ndarray:
        """(13,) segment lengths of :data:`LENGTH_NAMES` for ``proportions``."""
        return _lengths_of(proportions)

    # ------------------------------------------------------------ kinematics
    def state(self, params: SoftBodyParams) -> ModelState:
        """Frames, joints, primitives and their derivative building blocks."""
        if not isinstance(params, SoftBodyParams):
            raise InputError("params", "a SoftBodyParams", type(params).__name__)
        v = params.vector
        lengths = v[LENGTHS]
        widths = v[WIDTHS]
        if np.any(lengths <= 0) or np.any(widths <= 0):
            raise InputError("params", "positive lengths and widths", f"lengths {lengths}, widths {widths}")
        n_f = len(FRAMES)
        R = np.empty((n_f, 3, 3))
        R[0], Jl = rotvec_to_matrix(v[0:3])
        axes = np.zeros((N_POSE, 3))
        axes[0:3] = Jl.T
        dof_frames = np.zeros(N_POSE, int)
        k = 6
        for f in range(1, n_f):
            Rf = R[_FRAME_PARENT[f]].copy()
            while k < N_POSE and _DOF_TABLE[k - 6][0] == f:
                _, _, axis, sign = _DOF_TABLE[k - 6]
                axes[k] = sign * Rf[:, axis]
                dof_frames[k] = f
                Rf = Rf @ _rot(axis, sign * v[k])
                k += 1
            R[f] = Rf
        nodes = np.zeros((15, 3))
        nodes[PELVIS] = v[3:6]
        dn = np.zeros((15, len(LENGTH_NAMES), 3))
        for node, base, frame, terms in _NODES:
            nodes[node] = nodes[base]
            dn[node] = dn[base]
            for li, u in terms:
                w = R[frame] @ u
                nodes[node] = nodes[node] + lengths[li] * w
                dn[node, li] += w
        pivots = nodes[np.array(_FRAME_PIVOT)[dof_frames]]
        pivots[3:6] = 0.0
        # primitives
        f = self.prim_frame
        seg = np.array(_FRAME_LENGTH)[f]
        seg_len = np.where(seg >= 0, lengths[np.maximum(seg, 0)], 0.0)
        local = self.prim_s[:, None] * seg_len[:, None] * _FRAME_DIR[f] + self.prim_offset
        prim_R = R[f]
        piv = np.array(_FRAME_PIVOT)[f]
        centres = nodes[piv] + np.einsum("pij,pj->pi", prim_R, local)
        dc = dn[piv].copy()
        own = np.flatnonzero(seg >= 0)
        dc[own, seg[own]] += self.prim_s[own, None] * np.einsum("pij,pj->pi", prim_R[own], _FRAME_DIR[f[own]])
        wg = widths[self.prim_group]
        radii = self.prim_radii * wg[:, None]
        radii[:, 2] = np.where(self.prim_axial, self.prim_radii[:, 2] * seg_len, radii[:, 2])
        return ModelState(R, nodes, dn, axes, pivots, dof_frames, centres, radii, prim_R, dc)

    def joints(self, params: SoftBodyParams) -> np.ndarray:
        """Joint positions (14, 3), metres, order of ``SKELETON_14``."""
        return self.state(params).nodes[:14].copy()

    def joints_jacobian(self, params: SoftBodyParams, state: ModelState | None = None) -> np.ndarray:
        """Derivatives of the joints with respect to the parameters, shape (14, 3, 47)."""
        st = self.state(params) if state is None else state
        return attached_points_jacobian(self, st, st.nodes[:14], _node_frames()[:14], st.dnodes_dlengths[:14])

    def bone_lengths(self, params: SoftBodyParams) -> np.ndarray:
        """(13,) lengths of ``SKELETON_14.bones``, metres."""
        return SKELETON_14.bone_lengths(self.joints(params))


def _node_frames() -> np.ndarray:
    """The frame each node moves with (the frame of its last offset)."""
    out = np.zeros(15, int)
    for node, _, frame, _ in _NODES:
        out[node] = frame
    return out


def attached_points_jacobian(model: SoftBodyModel, st: ModelState, points: np.ndarray, frames: np.ndarray,
                             length_deriv: np.ndarray | None = None) -> np.ndarray:
    """Pose and length derivatives of points moving rigidly with frames.

    Parameters
    ----------
    model : SoftBodyModel
    st : ModelState
    points : ndarray of shape (N, 3)
        Current world positions, metres.
    frames : ndarray of shape (N,) int
        The frame each point is attached to.
    length_deriv : ndarray of shape (N, 13, 3), optional
        Derivatives of the points with respect to the lengths (default: those
        of the pivot of each point's frame, right for points fixed in the
        frame's axes relative to its pivot).

    Returns
    -------
    ndarray of shape (N, 3, 47)
        Width derivatives are zero.
    """
    pts = np.asarray(points, float)
    n = len(pts)
    out = np.zeros((n, 3, N_PARAMS))
    moves = model.subtree[st.dof_frames][:, frames]  # (K, N): DOF k moves point n
    moves[0:3] = True
    arm = pts[None, :, :] - st.dof_pivots[:, None, :]  # (K, N, 3)
    d = np.cross(st.dof_axes[:, None, :], arm) * moves[..., None]
    out[:, :, POSE] = d.transpose(1, 2, 0)
    out[:, :, 3:6] = np.eye(3)[None]
    if length_deriv is None:
        length_deriv = st.dnodes_dlengths[np.array(_FRAME_PIVOT)[frames]]
    out[:, :, LENGTHS] = np.transpose(length_deriv, (0, 2, 1))
    return out


#: Largest flexion of elbows and knees, radians (active ranges of about 145 and 140 degrees, with margin).
FLEXION_LIMITS = {"elbow": 2.7, "knee": 2.6}


def pose_bounds() -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of the 27 pose entries.

    Elbows and knees bend one way only, as in :mod:`toolkit.motion.kinematics`,
    and not further than the body allows (:data:`FLEXION_LIMITS`: a fully
    folded shank lies inside the thigh, a false minimum when the shank has
    no points); every other entry is free (Euler angles are not unique, so
    limits on them would cut off valid poses).

    Returns
    -------
    lo, hi : ndarray of shape (27,)
    """
    lo, hi = np.full(N_POSE, -np.inf), np.full(N_POSE, np.inf)
    for k, name in enumerate(DOF_NAMES):
        if name.endswith(("_elbow", "_knee")):
            lo[k], hi[k] = 0.0, FLEXION_LIMITS[name.split("_")[1]]
    return lo, hi


def _free_angles() -> np.ndarray:
    """Indices of the pose entries that are unbounded angles (every joint angle but elbows and knees)."""
    lo, hi = pose_bounds()
    return np.array([k for k in range(6, N_POSE) if np.isinf(lo[k]) and np.isinf(hi[k])], int)


def _wrap(a):
    return (np.asarray(a, float) + np.pi) % (2 * np.pi) - np.pi


def canonical_pose(pose: np.ndarray) -> np.ndarray:
    """The same pose with its angles in their principal ranges.

    The root rotation vector of angle ``theta > pi`` becomes the equivalent one
    of angle ``2 pi - theta`` about the opposite axis, and every unbounded joint
    angle (an Euler angle: each is ``2 pi``-periodic on its own) is wrapped to
    ``[-pi, pi)``.  The model's joints and surface do not change; the
    parameterisation stays away from ``|r| = 2 pi``, where the rotation
    vector's derivative is singular and a least-squares step can throw the
    body over (a trinocular kick whose root drifted to ``|r| = 6.3`` was lost
    in its third frame).

    Parameters
    ----------
    pose : ndarray of shape (27,) or (T, 27)
        Root rotation vector (rad), root translation (m), joint angles (rad).

    Returns
    -------
    ndarray, same shape
    """
    p = np.array(pose, float)
    one = p.ndim == 1
    p = np.atleast_2d(p)
    r = p[:, 0:3]
    th = np.linalg.norm(r, axis=1)
    big = th > np.pi
    r[big] *= ((th[big] - 2 * np.pi) / th[big])[:, None]
    free = _free_angles()
    p[:, free] = _wrap(p[:, free])
    return p[0] if one else p


def pose_step(pose: np.ndarray, previous: np.ndarray, factor: float) -> np.ndarray:
    """``pose`` moved on by ``factor`` times its change from ``previous`` (constant-speed prediction).

    The root rotation is extrapolated as a rotation (the relative rotation
    ``R(pose) R(previous)^T`` scaled by ``factor``), the free joint angles by
    their wrapped differences, so that two frames on either side of a
    ``2 pi`` or ``pi`` wrap do not predict a turn of a whole revolution.

    Parameters
    ----------
    pose, previous : ndarray of shape (27,)
    factor : float

    Returns
    -------
    ndarray of shape (27,)
    """
    pose, previous = np.array(pose, float), np.array(previous, float)
    d = pose - previous
    free = _free_angles()
    d[free] = _wrap(d[free])
    out = pose + factor * d
    rel = Rotation.from_rotvec(pose[0:3]) * Rotation.from_rotvec(previous[0:3]).inv()
    out[0:3] = (Rotation.from_rotvec(factor * rel.as_rotvec()) * Rotation.from_rotvec(pose[0:3])).as_rotvec()
    return out


def continuous_poses(poses: np.ndarray) -> np.ndarray:
    """A sequence of poses with no ``2 pi`` jumps between consecutive frames (for terms on their differences).

    Each free joint angle is unwrapped along time (``numpy.unwrap``); each
    frame's root rotation vector is replaced by the equivalent one (angle
    ``theta - 2 pi k`` about the same axis) nearest the previous frame's.

    Parameters
    ----------
    poses : ndarray of shape (T, 27)

    Returns
    -------
    ndarray of shape (T, 27)
    """
    p = np.array(poses, float)
    if len(p) < 2:
        return p
    free = _free_angles()
    p[:, free] = np.unwrap(p[:, free], axis=0)
    for t in range(1, len(p)):
        r = p[t, 0:3]
        th = np.linalg.norm(r)
        if th < 1e-9:
            continue
        cands = [r * (th + 2 * np.pi * k) / th for k in (-1, 0, 1)]
        p[t, 0:3] = min(cands, key=lambda c: float(np.linalg.norm(c - p[t - 1, 0:3])))
    return p
