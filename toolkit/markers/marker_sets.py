"""Marker sets: which markers a performer wears and where they sit on the body.

A :class:`MarkerSet` names its markers, the body segment each one is fixed
to, and a :class:`Placement` per marker in that segment's frame.  The
segment frames are built from the 14-joint skeleton
(:data:`toolkit.skeleton.SKELETON_14`) and its joint angles
(:class:`toolkit.motion.Pose14`, recovered by inverse kinematics when only
joint positions are known), so :meth:`MarkerSet.positions` gives the marker
positions for any pose: the ground truth of a synthetic capture and the
identification template of a real one.

Segment frames
--------------
Every segment frame has, at the rest pose, the body axes of
:mod:`toolkit.motion.kinematics`: x = the person's right, y = forward,
z = up.  Origins: ``pelvis`` the mid-hip point, ``thorax`` the neck, ``head``
the head joint, limbs their proximal joint (``*_thigh`` the hip, ``*_shank``
the knee, ``*_foot`` the ankle, ``*_upperarm`` the shoulder, ``*_forearm`` the
elbow, ``*_hand`` the wrist); limbs hang along -z.  The foot turns about the
ankle's x axis relative to the shank by an optional ankle angle (the
14-joint skeleton has no foot joint; without the angle the foot is rigid
with the shank).  The hand is always rigid with the forearm (no wrist angle).

Skin
----
A marker's place is given anatomically (a point on the segment's axis and
a direction); the marker centre is put where a ray along that direction
meets the skin of the body mesh of :class:`toolkit.body.model.BodyModel`
(posed at a neutral stance with the arms and legs slightly apart, so no
other limb is in the way), plus the marker radius :data:`MARKER_RADIUS_M`
along the surface normal.  Cluster markers sit on rigid plates
:data:`PLATE_STANDOFF_M` off the skin.  The placements are computed once per
body size and cached.

Plug-in Gait labels follow the Vicon Plug-in Gait convention (``LASI``,
``RASI``, ``LPSI``, ``RPSI``, ``LTHI``, ``LKNE``, ``LTIB``, ``LANK``, ``LHEE``,
``LTOE``, ``C7``, ``T10``, ``CLAV``, ``STRN``, ``RBAK``, ``LSHO``, ``LUPA``,
``LELB``, ``LFRM``, ``LWRA``, ``LWRB``, ``LFIN``, ``LFHD``, ``RFHD``,
``LBHD``, ``RBHD`` and the ``R`` mirror of the sided ones).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion.kinematics import Pose14, forward_kinematics, inverse_kinematics, rot_x, rot_y, rot_z
from toolkit.skeleton import SKELETON_14

__all__ = ["MARKER_RADIUS_M", "PLATE_STANDOFF_M", "SEGMENTS", "SEGMENT_ORIGINS", "SEGMENT_PARTS", "Placement",
           "MarkerSet", "MARKER_SETS", "get_marker_set", "segment_rotations", "segment_origins", "proportions_from_joints"]

#: Radius of a marker (14 mm spheres): the marker centre is this far off the skin.
MARKER_RADIUS_M = 0.007
#: Distance from the skin to a cluster plate's surface, metres (plates on 3-5 cm stand-offs).
PLATE_STANDOFF_M = 0.04
#: Body segments a marker can be fixed to.
SEGMENTS = ("pelvis", "thorax", "head", "l_thigh", "r_thigh", "l_shank", "r_shank", "l_foot", "r_foot",
            "l_upperarm", "r_upperarm", "l_forearm", "r_forearm", "l_hand", "r_hand")
#: Origin of each segment frame: a joint name, or a pair of joints averaged.
SEGMENT_ORIGINS = {
    "pelvis": ("l_hip", "r_hip"), "thorax": ("neck",), "head": ("head",),
    **{f"{s}_{seg}": (f"{s}_{j}",) for s in "lr" for seg, j in
       (("thigh", "hip"), ("shank", "knee"), ("foot", "ankle"), ("upperarm", "shoulder"),
        ("forearm", "elbow"), ("hand", "wrist"))},
}
#: Body-mesh parts (:data:`toolkit.skeleton.PARTS_14` names) whose skin a segment's markers are placed on.
SEGMENT_PARTS = {
    "pelvis": ("torso",), "thorax": ("torso", "head"), "head": ("head",),
    **{f"{s}_{seg}": (f"{s}_{part}",) for s in "lr" for seg, part in
       (("thigh", "thigh"), ("shank", "shank"), ("foot", "shank"), ("upperarm", "upper_arm"),
        ("forearm", "forearm"), ("hand", "forearm"))},
}
#: Segment length each placement's ``along`` is a fraction of, and the axis direction (local).
_AXES = {"pelvis": ("torso", +1.0), "thorax": ("torso", -1.0), "head": ("neck_to_head", +1.0),
         "thigh": ("thigh", -1.0), "shank": ("shank", -1.0), "foot": (None, -1.0),
         "upperarm": ("upper_arm", -1.0), "forearm": ("forearm", -1.0), "hand": (None, -1.0)}
#: Stature of the reference body the ``offset`` of a placement is given for.
_REFERENCE_STATURE_M = 1.75
#: Sum of the vertical-chain stature ratios below the head joint (ankle height excluded),
#: used to estimate stature from bone lengths.
_CHAIN_RATIO = 0.926 - 0.042
_J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}


@dataclass(frozen=True)
class Placement:
    """Where one marker sits on its segment (given for the right side; the left mirrors x).

    Attributes
    ----------
    along : float
        Point on the segment's long axis, as a fraction of its length from
        the origin (limbs and thorax downwards, pelvis and head upwards).
    offset : tuple of float
        Further offset of the aim point, segment frame, metres for a
        1.75 m person (scaled with stature).
    direction : tuple of float
        Direction (segment frame) from the aim point out to the skin.
    plate : tuple of float or None
        Cluster markers: position on the plate, metres (along the segment's
        axis, across it); the plate's centre is where the ray meets the
        skin, :data:`PLATE_STANDOFF_M` out.  None for a skin marker.
    """

    along: float
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    plate: tuple[float, float] | None = None


@dataclass(frozen=True)
class MarkerSet:
    """A named marker set.

    Attributes
    ----------
    name : str
    labels : tuple of str
        Marker labels (M).
    segments : tuple of str
        Segment of each marker (names of :data:`SEGMENTS`).
    placements : tuple of Placement
        Placement of each marker in its segment frame.
    """

    name: str
    labels: tuple[str, ...]
    segments: tuple[str, ...]
    placements: tuple[Placement, ...]

    def __post_init__(self):
        if not (len(self.labels) == len(self.segments) == len(self.placements)):
            raise InputError(f"marker set {self.name}", "as many segments and placements as labels",
                             f"{len(self.labels)} labels, {len(self.segments)} segments, "
                             f"{len(self.placements)} placements")
        if len(set(self.labels)) != len(self.labels):
            raise InputError(f"marker set {self.name}: labels", "unique labels", str(self.labels))
        bad = sorted(set(self.segments) - set(SEGMENTS))
        if bad:
            raise InputError(f"marker set {self.name}: segments", f"names of {SEGMENTS}", str(bad))

    @property
    def n_markers(self) -> int:
        return len(self.labels)

    @property
    def segment_names(self) -> tuple[str, ...]:
        """The segments that carry markers, in :data:`SEGMENTS` order."""
        return tuple(s for s in SEGMENTS if s in self.segments)

    def index(self, label: str) -> int:
        """Index of a marker by label."""
        try:
            return self.labels.index(label)
        except ValueError:
            raise InputError("label", f"one of the {self.name} labels {self.labels}", repr(label)) from None

    def markers_of(self, segment: str) -> list[int]:
        """Indices of the markers fixed to ``segment``."""
        return [i for i, s in enumerate(self.segments) if s == segment]

    def local_points(self, proportions: BodyProportions, girth: float = 1.0) -> np.ndarray:
        """Marker centres in their segment frames, metres.

        Parameters
        ----------
        proportions : BodyProportions
        girth : float
            Build of the body (:attr:`toolkit.body.model.BodyShape.girth`).

        Returns
        -------
        ndarray of shape (M, 3)
        """
        return _local_points(self, proportions, float(girth)).copy()

    def positions(self, joints14: np.ndarray, shape=None, *, pose: Pose14 | None = None,
                  ankle: np.ndarray | None = None, local_offsets: np.ndarray | None = None) -> np.ndarray:
        """Marker positions for a skeleton pose (the identification template).

        Parameters
        ----------
        joints14 : ndarray of shape (T, 14, 3) or (14, 3)
            Joints of :data:`SKELETON_14`, metres, world (z up).
        shape : toolkit.body.model.BodyShape, optional
            The body (radii and proportions); by default a body of average
            build with the proportions of ``joints14``.
        pose : Pose14, optional
            Joint angles of ``joints14`` (they fix the axial rotation of
            straight limbs); by default :func:`inverse_kinematics` of the joints.
        ankle : ndarray of shape (T, 2), optional
            Foot rotation about the ankle relative to the shank, radians,
            (left, right), > 0 lifts the toes (dorsiflexion).  Default 0.
        local_offsets : ndarray of shape (T, M, 3), optional
            Displacement of each marker in its segment frame, metres (soft
            tissue motion).

        Returns
        -------
        ndarray of shape (T, M, 3) or (M, 3)
            Metres, world; (M, 3) when ``joints14`` is (14, 3).

        Raises
        ------
        InputError
            Joints of the wrong shape or not finite, offsets of the wrong shape.
        """
        j = np.asarray(joints14, float)
        single = j.ndim == 2
        j = j[None] if single else j
        if j.ndim != 3 or j.shape[1:] != (14, 3):
            raise InputError("joints14", "an array of shape (T, 14, 3) or (14, 3)", f"shape {np.shape(joints14)}")
        if not np.all(np.isfinite(j)):
            raise InputError("joints14", "finite joint positions", "NaN or inf values")
        T = len(j)
        if shape is None:
            props, girth = proportions_from_joints(j), 1.0
        else:
            props, girth = shape.proportions, shape.girth
        local = np.broadcast_to(_local_points(self, props, float(girth)), (T, self.n_markers, 3))
        if local_offsets is not None:
            off = np.asarray(local_offsets, float)
            if off.shape != (T, self.n_markers, 3):
                raise InputError("local_offsets", f"an array of shape ({T}, {self.n_markers}, 3)",
                                 f"shape {off.shape}")
            local = local + off
        if pose is None:
            pose = inverse_kinematics(j)
        elif pose.n_frames != T:
            raise InputError("pose", f"joint angles over {T} frames", f"{pose.n_frames} frames")
        rots = segment_rotations(pose, ankle)
        origins = segment_origins(j)
        out = np.empty((T, self.n_markers, 3))
        for seg in self.segment_names:
            idx = self.markers_of(seg)
            out[:, idx] = origins[seg][:, None] + np.einsum("tij,tmj->tmi", rots[seg], local[:, idx])
        return out[0] if single else out


# ------------------------------------------------------------------ frames
def _limb(R_parent, angles, side):
    s = 1.0 if side == 0 else -1.0
    return R_parent @ rot_x(angles[:, 0]) @ rot_y(s * angles[:, 1]) @ rot_z(-s * angles[:, 2])


def segment_rotations(pose: Pose14, ankle: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """World rotation of every segment frame (columns: the segment's x, y, z axes).

    The rotations are those of :func:`toolkit.motion.forward_kinematics`.

    Parameters
    ----------
    pose : Pose14
        Joint angles over T frames.
    ankle : ndarray of shape (T, 2), optional
        Foot rotation about the ankle's x axis relative to the shank, radians (left, right).

    Returns
    -------
    dict of str to ndarray of shape (T, 3, 3)
    """
    T = pose.n_frames
    if ankle is None:
        ankle = np.zeros((T, 2))
    ankle = np.asarray(ankle, float)
    if ankle.shape != (T, 2):
        raise InputError("ankle", f"an array of shape ({T}, 2)", f"shape {ankle.shape}")
    Rp = pose.pelvis_rotation()
    Rt = pose.trunk_rotation()
    out = {"pelvis": Rp, "thorax": Rt, "head": Rt @ rot_x(-pose.head_pitch) @ rot_y(pose.head_roll)}
    for side, s in ((0, "l"), (1, "r")):
        Ru = _limb(Rt, pose.shoulder[:, side], side)
        Rf = Ru @ rot_x(pose.elbow[:, side])
        Rth = _limb(Rp, pose.hip[:, side], side)
        Rs = Rth @ rot_x(-pose.knee[:, side])
        out.update({f"{s}_upperarm": Ru, f"{s}_forearm": Rf, f"{s}_hand": Rf, f"{s}_thigh": Rth,
                    f"{s}_shank": Rs, f"{s}_foot": Rs @ rot_x(ankle[:, side])})
    return out


def segment_origins(joints14: np.ndarray) -> dict[str, np.ndarray]:
    """Origin of every segment frame, world, metres.

    Parameters
    ----------
    joints14 : ndarray of shape (T, 14, 3)

    Returns
    -------
    dict of str to ndarray of shape (T, 3)
    """
    j = np.asarray(joints14, float)
    return {seg: j[:, [_J[n] for n in names]].mean(axis=1) for seg, names in SEGMENT_ORIGINS.items()}


def proportions_from_joints(joints14: np.ndarray) -> BodyProportions:
    """Body proportions whose bones match ``joints14`` (median over frames).

    Parameters
    ----------
    joints14 : ndarray of shape (T, 14, 3) or (14, 3)

    Returns
    -------
    BodyProportions
        Stature estimated from the vertical chain (ankle height excluded).
    """
    j = np.asarray(joints14, float).reshape(-1, 14, 3)
    d = lambda a, b: float(np.median(np.linalg.norm(j[:, _J[a]] - j[:, _J[b]], axis=-1)))  # noqa: E731
    mid = 0.5 * (j[:, _J["l_hip"]] + j[:, _J["r_hip"]])
    torso = float(np.median(np.linalg.norm(j[:, _J["neck"]] - mid, axis=-1)))
    shw = 0.5 * d("l_shoulder", "r_shoulder")
    neck_sh = 0.5 * (d("neck", "l_shoulder") + d("neck", "r_shoulder"))
    thigh = 0.5 * (d("l_hip", "l_knee") + d("r_hip", "r_knee"))
    shank = 0.5 * (d("l_knee", "l_ankle") + d("r_knee", "r_ankle"))
    nh = d("neck", "head")
    height = float(np.clip((thigh + shank + torso + nh) / _CHAIN_RATIO, 1.0, 2.5))
    return BodyProportions(
        height=height, neck_to_head=nh, shoulder_half_width=shw,
        shoulder_drop=float(np.sqrt(max(neck_sh ** 2 - shw ** 2, 0.0))),
        upper_arm=0.5 * (d("l_shoulder", "l_elbow") + d("r_shoulder", "r_elbow")),
        forearm=0.5 * (d("l_elbow", "l_wrist") + d("r_elbow", "r_wrist")),
        torso=torso, hip_half_width=0.5 * d("l_hip", "r_hip"), thigh=thigh, shank=shank,
        ankle_height=0.042 * height)


# --------------------------------------------------------------- placement
def _neutral_pose() -> Pose14:
    """Standing, arms 35 degrees and legs 6 degrees apart, elbows and knees slightly bent."""
    p = Pose14.neutral(1)
    sh = np.zeros((1, 2, 3))
    sh[:, :, 1] = np.deg2rad(35.0)
    hip = np.zeros((1, 2, 3))
    hip[:, :, 1] = np.deg2rad(6.0)
    return Pose14(root=p.root, yaw=p.yaw, pitch=p.pitch, roll=p.roll, lean=p.lean, twist=p.twist,
                  head_pitch=p.head_pitch, head_roll=p.head_roll, shoulder=sh, elbow=np.full((1, 2), 0.1),
                  hip=hip, knee=np.full((1, 2), 0.07))


@functools.lru_cache(maxsize=64)
def _local_points(mset: MarkerSet, props: BodyProportions, girth: float) -> np.ndarray:
    import open3d as o3d

    from toolkit.body.model import BodyModel, BodyShape

    pose = _neutral_pose()
    joints = forward_kinematics(props, pose)
    mesh = BodyModel(BodyShape(proportions=props, girth=girth), rng=0).mesh(joints[0])
    rots = {k: v[0] for k, v in segment_rotations(pose).items()}
    origins = {k: v[0] for k, v in segment_origins(joints).items()}
    part_id = {name: i + 1 for i, name in enumerate(SKELETON_14.part_names)}
    scale = props.height / _REFERENCE_STATURE_M
    tri_normals = np.cross(mesh.vertices[mesh.triangles[:, 1]] - mesh.vertices[mesh.triangles[:, 0]],
                           mesh.vertices[mesh.triangles[:, 2]] - mesh.vertices[mesh.triangles[:, 0]])
    tri_normals /= np.maximum(np.linalg.norm(tri_normals, axis=1, keepdims=True), 1e-12)
    scenes = {}
    out = np.empty((mset.n_markers, 3))
    for m, (label, seg, pl) in enumerate(zip(mset.labels, mset.segments, mset.placements)):
        parts = SEGMENT_PARTS[seg]
        if parts not in scenes:
            keep = np.flatnonzero(np.isin(mesh.triangle_parts, [part_id[p] for p in parts]))
            sc = o3d.t.geometry.RaycastingScene()
            sc.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                             o3d.core.Tensor(mesh.triangles[keep].astype(np.uint32)))
            scenes[parts] = (sc, keep)
        sc, keep = scenes[parts]
        mirror = np.array([-1.0 if seg.startswith("l_") or label.startswith("L") and seg in
                           ("pelvis", "thorax", "head") else 1.0, 1.0, 1.0])
        kind = seg[2:] if seg[:2] in ("l_", "r_") else seg
        length_name, axis_sign = _AXES[kind]
        length = getattr(props, length_name) if length_name else 0.0
        aim = np.array([0.0, 0.0, axis_sign * pl.along * length]) + mirror * np.asarray(pl.offset) * scale
        direction = mirror * np.asarray(pl.direction, float)
        direction /= np.linalg.norm(direction)
        R, o = rots[seg], origins[seg]
        aim_w, dir_w = o + R @ aim, R @ direction
        ray = np.r_[aim_w + 0.6 * dir_w, -dir_w].astype(np.float32)[None]
        hit = sc.cast_rays(o3d.core.Tensor(ray))
        t_hit = float(hit["t_hit"].numpy()[0])
        if not np.isfinite(t_hit):
            raise InputError(f"marker set {mset.name}: {label}", "a placement that meets the skin",
                             "a ray that misses the body")
        skin = aim_w + (0.6 - t_hit) * dir_w
        normal = tri_normals[keep[int(hit["primitive_ids"].numpy()[0])]]
        if normal @ dir_w < 0:
            normal = -normal
        if pl.plate is None:
            world = skin + MARKER_RADIUS_M * normal
        else:
            centre = skin + (PLATE_STANDOFF_M + MARKER_RADIUS_M) * normal
            axis = R @ np.array([0.0, 0.0, axis_sign])
            u = axis - normal * (axis @ normal)
            u /= np.linalg.norm(u)
            v = np.cross(normal, u)
            world = centre + pl.plate[0] * u + pl.plate[1] * v
        out[m] = R.T @ (world - o)
    out.setflags(write=False)
    return out


# ------------------------------------------------------------------- sets
_LAT, _FWD, _BACK, _UP = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)


def _dir(deg_from_front: float, up: float = 0.0) -> tuple[float, float, float]:
    """Horizontal direction ``deg_from_front`` degrees from forward towards the right (+ a z part)."""
    a = np.deg2rad(deg_from_front)
    return (float(np.sin(a)), float(np.cos(a)), float(up))


#: Right-side and midline Plug-in Gait markers: (label, segment, placement); "R" labels are mirrored to "L".
_PIG = (
    ("RASI", "pelvis", Placement(0.12, direction=_dir(50.0))),
    ("RPSI", "pelvis", Placement(0.14, offset=(0.045, 0.0, 0.0), direction=_BACK)),
    ("RTHI", "r_thigh", Placement(0.62, direction=_dir(85.0))),
    ("RKNE", "r_thigh", Placement(1.0, direction=_LAT)),  # lateral epicondyle, on the flexion axis
    ("RTIB", "r_shank", Placement(0.55, direction=_dir(80.0))),
    ("RANK", "r_shank", Placement(0.99, direction=_LAT)),
    ("RHEE", "r_foot", Placement(0.0, offset=(0.0, 0.0, -0.032), direction=_BACK)),
    ("RTOE", "r_foot", Placement(0.0, offset=(0.0, 0.135, -0.03), direction=_UP)),
    ("C7", "thorax", Placement(0.0, offset=(0.0, 0.0, 0.005), direction=_BACK)),
    ("T10", "thorax", Placement(0.42, direction=_BACK)),
    ("CLAV", "thorax", Placement(0.04, direction=_FWD)),
    ("STRN", "thorax", Placement(0.34, direction=_FWD)),
    ("RBAK", "thorax", Placement(0.25, offset=(0.075, 0.0, 0.0), direction=_BACK)),
    ("RSHO", "thorax", Placement(0.0, offset=(0.18, 0.0, -0.07), direction=_UP)),
    ("RUPA", "r_upperarm", Placement(0.5, direction=_dir(110.0))),
    ("RELB", "r_upperarm", Placement(0.98, direction=_dir(100.0))),
    ("RFRM", "r_forearm", Placement(0.45, direction=_dir(120.0))),
    ("RWRA", "r_forearm", Placement(0.97, direction=_FWD)),
    ("RWRB", "r_forearm", Placement(0.97, direction=_BACK)),
    ("RFIN", "r_hand", Placement(0.0, offset=(0.0, 0.0, -0.13), direction=_BACK)),
    ("RFHD", "head", Placement(0.0, offset=(0.0, 0.0, 0.07), direction=_dir(35.0))),
    ("RBHD", "head", Placement(0.0, offset=(0.0, 0.0, 0.07), direction=_dir(145.0))),
)
#: Plate positions of 4- and 3-marker clusters (irregular, so every marker of a plate is distinguishable).
_PLATE4 = ((0.045, 0.035), (0.05, -0.03), (-0.045, 0.04), (-0.035, -0.035))
_PLATE3 = ((0.04, 0.03), (0.035, -0.03), (-0.045, 0.005))
_CLUSTER_PLATES = (("TH", "thigh", Placement(0.5, direction=_dir(70.0)), _PLATE4),
                   ("SK", "shank", Placement(0.45, direction=_dir(75.0)), _PLATE4),
                   ("UA", "upperarm", Placement(0.5, direction=_dir(95.0)), _PLATE3),
                   ("FA", "forearm", Placement(0.5, direction=_dir(120.0)), _PLATE3))
_CLUSTER_SKIN = ("RASI", "RPSI", "C7", "T10", "CLAV", "STRN", "RBAK", "RSHO", "RHEE", "RTOE", "RFHD", "RBHD")
_CLUSTER_EXTRA = (("RMT5", "r_foot", Placement(0.0, offset=(0.02, 0.09, -0.03), direction=_LAT)),)


def _mirror(entries) -> list:
    """Left and right markers from right-side entries, left first; midline ones once."""
    out = []
    for label, seg, pl in entries:
        if seg.startswith("r_") or (seg in ("pelvis", "thorax", "head") and label[0] == "R" and label != "RBAK"):
            lseg = "l_" + seg[2:] if seg.startswith("r_") else seg
            out.append(("L" + label[1:], lseg, pl))
        out.append((label, seg, pl))
    return out


def _build(name: str, entries) -> MarkerSet:
    labels, segs, pls = zip(*entries)
    return MarkerSet(name=name, labels=tuple(labels), segments=tuple(segs), placements=tuple(pls))


def _cluster_entries() -> list:
    pig = {lab: (lab, seg, pl) for lab, seg, pl in _PIG}
    entries = [pig[lab] for lab in _CLUSTER_SKIN] + list(_CLUSTER_EXTRA)
    for code, seg, pl, plate in _CLUSTER_PLATES:
        for k, xy in enumerate(plate):
            entries.append((f"R{code}{k + 1}", f"r_{seg}", Placement(pl.along, pl.offset, pl.direction, xy)))
    return _mirror(entries)


#: The marker sets by name.
MARKER_SETS: dict[str, MarkerSet] = {
    "plug-in-gait": _build("plug-in-gait", _mirror(_PIG)),
    "cluster": _build("cluster", _cluster_entries()),
}


def get_marker_set(name: str) -> MarkerSet:
    """The marker set called ``name``.

    Raises
    ------
    InputError
        Unknown name (the known names are listed).
    """
    try:
        return MARKER_SETS[name]
    except (KeyError, TypeError):
        raise InputError("marker set", f"one of {sorted(MARKER_SETS)}", repr(name)) from None

