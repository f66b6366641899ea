"""OpenSim engine: a generic model scaled to the person, markers placed, inverse kinematics.

OpenSim (``pip install opensim``, the 4.6 wheel; the ``opensim`` extra of
this project) ships no musculoskeletal model inside its Python wheel, and the
maintained models (``gait2392``, Rajagopal 2016, Pose2Sim's and OpenCap's)
live in other repositories.  Rather than copying one, the generic model is
built here with OpenSim's own API from the project's median body proportions
(:class:`toolkit.anthropometry.proportions.BodyProportions` at 1.75 m), so it
can be shipped and changed freely:

* bodies ``pelvis`` (6 degrees of freedom to the ground), ``torso`` (lumbar:
  3 rotations, locked unless pelvis markers are given), ``head`` welded to
  it; per side ``femur`` (hip: flexion, adduction, rotation), ``tibia`` (knee:
  flexion), ``foot`` when a toe point exists (ankle: dorsiflexion),
  ``humerus`` (shoulder: flexion, abduction, rotation), ``forearm`` (elbow:
  flexion); with a lateral knee marker (Plug-in Gait's ``KNE``) the knee
  also has adduction and rotation;
* every body frame in the ISB axes of :mod:`toolkit.biomech.segments` (X
  anterior, Y superior, Z right), all coordinates 0 in the upright pose with
  limbs hanging; the rotations in the order Z-X-Y with the axes signed so
  that each coordinate *is* the angle of ``angles.csv`` under the same name
  (``l_knee_flexion`` ...): the two engines' columns line up;
* one marker per joint centre (named as the landmark: ``l_knee`` on the
  femur at the knee) and, when the run has them, the markers of
  :data:`toolkit.biomech.mapping.MARKER_LANDMARKS`.

Scaling: each body's factors (along its axes) are the ratio of the person's
median distance between the joint-centre markers over the trial to the
generic model's (OpenSim's ``Model.scale``, as the Scale tool applies
measurement-based factors).  Markers that are not joint centres are then
placed on their body at their median position in that body's frame (what
the Scale tool's marker placer does with a static pose).  Inverse kinematics:
OpenSim's ``InverseKinematicsSolver`` on every frame (all markers weighted
1), started from the first frame's pelvis pose; the residual of every marker
in every frame is kept.  Where markers off the joint axes frame a segment (a
lateral knee marker for the thigh, and through it the shank and foot; ASIS and
PSIS for the pelvis; C7, T10, CLAV, STRN for the thorax), the segment's frame of
:mod:`toolkit.biomech.segments` is also an orientation target of its body
(OpenSim's ``OrientationsReference``, as OpenSense uses for IMUs; weight
:data:`ORIENTATION_WEIGHT`): joint centres fix a segment's long axis, these
frames its rotation about it, as a marker model defines it.

Axes: OpenSim's ground is Y up; the toolkit's world is Z up.  Points go in as
``(x, z, -y)`` (a proper rotation).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.biomech.angles import JointAngles, cardan_zxy
from toolkit.biomech.segments import foot_pitch_offsets, frame_from_axes, segment_frames
from toolkit.errors import InputError

#: World (z up) -> OpenSim ground (y up): rows give the OpenSim axes.
WORLD_TO_OPENSIM = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
#: Stature of the generic model, metres (its segment lengths: BodyProportions.from_height).
GENERIC_HEIGHT_M = 1.75
#: IK solver accuracy (OpenSim's default, 1e-5, leaves shoulder rotation 5 degrees off where the elbow is
#: nearly straight on exact synthetic data; 1e-7 costs little: 30 frames in about 2 s).
IK_ACCURACY = 1e-7
#: Frames with fewer markers seen are left out of the inverse kinematics (NaN).
MIN_MARKERS = 4


def opensim_available() -> bool:
    """Whether the ``opensim`` package is installed (found, not imported: see :func:`opensim_angles`)."""
    import importlib.util

    return importlib.util.find_spec("opensim") is not None


def _require_opensim():
    try:
        import opensim
    except ImportError:
        raise InputError("--engine opensim", "the opensim package (pip install '.[opensim]' or "
                         "pip install opensim==4.6)", "it is not installed") from None
    return opensim


@dataclass(frozen=True)
class OpenSimResult:
    """Inverse kinematics by OpenSim.

    Attributes
    ----------
    angles : JointAngles
        The model's joint coordinates named as ``angles.csv`` columns, degrees.
    coordinates : dict of str to ndarray of shape (T,)
        Every coordinate (pelvis and lumbar too): degrees, translations metres.
    residuals_m : dict of str to ndarray of shape (T,)
        Per marker, distance between the model's and the data's marker, metres (NaN: not seen).
    scale_factors : dict of str to (3,) list
    files : dict of str to Path
    notes : tuple of str
    """

    angles: JointAngles
    coordinates: dict
    residuals_m: dict
    scale_factors: dict
    files: dict = field(default_factory=dict)
    notes: tuple = ()


def _generic_geometry() -> dict:
    """Joint-centre positions of the generic model in its bodies' frames, metres."""
    from toolkit.anthropometry.proportions import BodyProportions

    b = BodyProportions.from_height(GENERIC_HEIGHT_M)
    g = {"torso": b.torso, "neck_to_head": b.neck_to_head, "shoulder_half": b.shoulder_half_width,
         "shoulder_drop": b.shoulder_drop, "hip_half": b.hip_half_width, "thigh": b.thigh, "shank": b.shank,
         "upper_arm": b.upper_arm, "forearm": b.forearm, "foot": 0.14}
    return g


def _side_sign(side: str) -> float:
    return 1.0 if side == "r" else -1.0


def _custom_joint(osim, name, parent, loc_parent, child, rotations, translations=()):
    """A CustomJoint with rotations [(coordinate, axis)] in order and translations [(coordinate, axis)]."""
    st = osim.SpatialTransform()
    rot_axes = [st.upd_rotation1(), st.upd_rotation2(), st.upd_rotation3()]
    default_rot = [(0, 0, 1), (1, 0, 0), (0, 1, 0)]
    for i, ax in enumerate(rot_axes):
        if i < len(rotations):
            coord, axis = rotations[i]
            names = osim.ArrayStr()
            names.append(coord)
            ax.setCoordinateNames(names)
            ax.setAxis(osim.Vec3(*axis))
            ax.set_function(osim.LinearFunction(1.0, 0.0))
        else:
            ax.setAxis(osim.Vec3(*default_rot[i]))
            ax.set_function(osim.Constant(0.0))
    trans_axes = [st.upd_translation1(), st.upd_translation2(), st.upd_translation3()]
    for i, ax in enumerate(trans_axes):
        ax.setAxis(osim.Vec3(*np.eye(3)[i]))
        if i < len(translations):
            names = osim.ArrayStr()
            names.append(translations[i])
            ax.setCoordinateNames(names)
            ax.set_function(osim.LinearFunction(1.0, 0.0))
        else:
            ax.set_function(osim.Constant(0.0))
    return osim.CustomJoint(name, parent, osim.Vec3(*loc_parent), osim.Vec3(0, 0, 0), child,
                            osim.Vec3(0, 0, 0), osim.Vec3(0, 0, 0), st)


def build_generic_model(landmarks, *, lumbar_free: bool):
    """The generic model (an ``opensim.Model``) with a marker for every landmark it knows.

    Parameters
    ----------
    landmarks : collection of str
        The run's landmarks: which limbs, the foot and which extra markers to include.
    lumbar_free : bool
        Unlock the lumbar joint (only observable with pelvis markers).

    Returns
    -------
    model : opensim.Model
    joint_markers : dict of str to (body name, (3,) location)
        The joint-centre markers, in the generic geometry.
    """
    osim = _require_opensim()
    g = _generic_geometry()
    model = osim.Model()
    model.setName("toolkit_generic")
    model.setGravity(osim.Vec3(0, -9.80665, 0))
    inertia = osim.Inertia(0.01, 0.01, 0.01)
    bodies = {}

    def body(name):
        b = osim.Body(name, 1.0, osim.Vec3(0), inertia)
        model.addBody(b)
        bodies[name] = b
        return b

    pelvis = body("pelvis")
    model.addJoint(_custom_joint(osim, "ground_pelvis", model.getGround(), (0, 0, 0), pelvis,
                                 [("pelvis_tilt", (0, 0, 1)), ("pelvis_list", (1, 0, 0)),
                                  ("pelvis_rotation", (0, 1, 0))], ("pelvis_tx", "pelvis_ty", "pelvis_tz")))
    torso = body("torso")
    model.addJoint(_custom_joint(osim, "lumbar", pelvis, (0, 0, 0), torso,
                                 [("lumbar_extension", (0, 0, 1)), ("lumbar_bending", (1, 0, 0)),
                                  ("lumbar_rotation", (0, 1, 0))]))
    markers = {"neck": ("torso", (0, g["torso"], 0)), "head": ("torso", (0, g["torso"] + g["neck_to_head"], 0))}
    for side in ("l", "r"):
        s = _side_sign(side)
        hip = (0, 0, s * g["hip_half"])
        markers[f"{side}_hip"] = ("pelvis", hip)
        femur = body(f"{side}_femur")
        model.addJoint(_custom_joint(osim, f"{side}_hip", pelvis, hip, femur,
                                     [(f"{side}_hip_flexion", (0, 0, 1)), (f"{side}_hip_adduction", (s, 0, 0)),
                                      (f"{side}_hip_rotation", (0, s, 0))]))
        markers[f"{side}_knee"] = (f"{side}_femur", (0, -g["thigh"], 0))
        tibia = body(f"{side}_tibia")
        knee = [(f"{side}_knee_flexion", (0, 0, -1))]
        if f"{side}_knee_lateral" in landmarks:     # the marker sets the femur's axes: Plug-in Gait's 3 rotations
            knee += [(f"{side}_knee_adduction", (s, 0, 0)), (f"{side}_knee_rotation", (0, s, 0))]
        model.addJoint(_custom_joint(osim, f"{side}_knee", femur, (0, -g["thigh"], 0), tibia, knee))
        markers[f"{side}_ankle"] = (f"{side}_tibia", (0, -g["shank"], 0))
        if f"{side}_toe" in landmarks:
            foot = body(f"{side}_foot")
            model.addJoint(_custom_joint(osim, f"{side}_ankle", tibia, (0, -g["shank"], 0), foot,
                                         [(f"{side}_ankle_dorsiflexion", (0, 0, 1))]))
        shoulder = (0, g["torso"] - g["shoulder_drop"], s * g["shoulder_half"])
        markers[f"{side}_shoulder"] = ("torso", shoulder)
        if f"{side}_elbow" in landmarks:
            humerus = body(f"{side}_humerus")
            model.addJoint(_custom_joint(osim, f"{side}_shoulder", torso, shoulder, humerus,
                                         [(f"{side}_shoulder_flexion", (0, 0, 1)),
                                          (f"{side}_shoulder_abduction", (-s, 0, 0)),
                                          (f"{side}_shoulder_rotation", (0, s, 0))]))
            markers[f"{side}_elbow"] = (f"{side}_humerus", (0, -g["upper_arm"], 0))
            if f"{side}_wrist" in landmarks:
                forearm = body(f"{side}_forearm")
                model.addJoint(_custom_joint(osim, f"{side}_elbow", humerus, (0, -g["upper_arm"], 0), forearm,
                                             [(f"{side}_elbow_flexion", (0, 0, 1))]))
                markers[f"{side}_wrist"] = (f"{side}_forearm", (0, -g["forearm"], 0))
    for name, (b, loc) in markers.items():
        if name in landmarks:
            model.addMarker(osim.Marker(name, bodies[b], osim.Vec3(*loc)))
    if not lumbar_free:
        for c in ("lumbar_extension", "lumbar_bending", "lumbar_rotation"):
            model.updCoordinateSet().get(c).setDefaultLocked(True)
    model.finalizeConnections()
    return model, {k: v for k, v in markers.items() if k in landmarks}


def _median_distance(points, a, b) -> float:
    d = np.linalg.norm(points[a] - points[b], axis=-1)
    return float(np.nanmedian(d)) if np.isfinite(d).any() else math.nan


def scale_factors(points: dict) -> dict:
    """Per body, the (X, Y, Z) scale factors: person's median joint distances over the generic model's.

    Returns
    -------
    dict of str to tuple of 3 float
        Bodies whose factors the data determine (others keep 1).
    """
    g = _generic_geometry()
    p = dict(points)
    p["mid_hip"] = 0.5 * (p["l_hip"] + p["r_hip"])
    f = {}
    hip = _median_distance(p, "l_hip", "r_hip") / (2 * g["hip_half"])
    trunk = _median_distance(p, "mid_hip", "neck") / g["torso"]
    f["pelvis"] = (trunk, trunk, hip)
    if "l_shoulder" in p and "r_shoulder" in p:
        f["torso"] = (trunk, trunk, _median_distance(p, "l_shoulder", "r_shoulder") / (2 * g["shoulder_half"]))
    else:
        f["torso"] = (trunk, trunk, trunk)
    for side in ("l", "r"):
        for body, a, b, length in (("femur", "hip", "knee", "thigh"), ("tibia", "knee", "ankle", "shank"),
                                   ("humerus", "shoulder", "elbow", "upper_arm"),
                                   ("forearm", "elbow", "wrist", "forearm")):
            if f"{side}_{a}" in p and f"{side}_{b}" in p:
                k = _median_distance(p, f"{side}_{a}", f"{side}_{b}") / g[length]
                if np.isfinite(k):
                    f[f"{side}_{body}"] = (k, k, k)
    return {k: v for k, v in f.items() if all(np.isfinite(v))}


#: Landmarks placed on the model from the data -> (model body, our segment frame, origin landmark(s)).
#: The head and shoulders are joint centres of the trunk, which the 14-joint skeleton does not hold
#: rigid: they go where the person has them on average.  A lateral knee marker fixes the femur's axes
#: (the knee then has three rotations, as Plug-in Gait's); lateral ankle markers are left out (the
#: ankle is a hinge whose axis the shank's frame gives; on the real walk they sat 15-23 mm off it).
_PLACED = {
    "asis": ("pelvis", "pelvis", ("l_hip", "r_hip")), "psis": ("pelvis", "pelvis", ("l_hip", "r_hip")),
    "toe": ("foot", "foot", ("ankle",)), "heel": ("foot", "foot", ("ankle",)),
    "knee_lateral": ("femur", "thigh", ("hip",)),
    "head": ("torso", "torso", ("l_hip", "r_hip")), "shoulder": ("torso", "torso", ("l_hip", "r_hip")),
}
#: Landmarks the OpenSim engine does not use (see :data:`_PLACED`).
UNUSED_LANDMARKS = ("l_ankle_lateral", "r_ankle_lateral")

#: Segment of :func:`toolkit.biomech.segments.segment_frames` -> (model body whose orientation it sets,
#: the landmark sets, any one of which makes its frame a marker frame).  Joint centres fix a segment's
#: long axis but hardly its rotation about it (a straight limb; the noisy plane of hip, knee and ankle),
#: which a marker model takes from markers off the axis (Plug-in Gait's knee axis: knee centre to
#: ``KNE``).  A segment whose frame comes from such markers (directly, or through the proximal
#: segment's lateral axis: the shank and the foot) gets its frame as an orientation target; a frame
#: built from the joint centres alone adds nothing the joint-centre markers do not carry, except the
#: blend of :mod:`toolkit.biomech.segments` for a straight limb, and gets none.  The torso's target is
#: the trunk's frame of :func:`_placement_frames`, which its markers are placed in.
ORIENTED_SEGMENTS = {
    "pelvis": ("pelvis", (("l_asis", "r_asis", "l_psis", "r_psis"),)),
    "thorax": ("torso", (("c7", "t10", "clav", "strn"),)),
    **{f"{s}_thigh": (f"{s}_femur", ((f"{s}_knee_lateral",),)) for s in "lr"},
    **{f"{s}_shank": (f"{s}_tibia", ((f"{s}_knee_lateral",),)) for s in "lr"},
    **{f"{s}_foot": (f"{s}_foot", ((f"{s}_knee_lateral",),)) for s in "lr"},
}
#: Weight of every body's orientation target in the inverse kinematics, as of every marker.  OpenSim's
#: solver (as in OpenSense) sums two goals: the markers' weighted mean squared distance (m^2) and the
#: orientations' weighted mean squared angle (rad^2), so with all weights 1 a segment turned by 1 degree
#: costs about as much as every marker 17 mm off (x sqrt(markers / bodies)): the segments' directions
#: lead and the joint centres place them (see docs/joint_angles.md for weaker orientation weights).
ORIENTATION_WEIGHT = 1.0


def _placement_frames(points: dict, foot_offsets: dict | None) -> dict:
    """The segment frames the model's bodies are taken to have: the own engine's, and the torso's."""
    frames = segment_frames(points, foot_offsets=foot_offsets)
    p = points
    frames["torso"] = frame_from_axes(p["neck"] - 0.5 * (p["l_hip"] + p["r_hip"]),
                                      p["r_shoulder"] - p["l_shoulder"] if "r_shoulder" in p and "l_shoulder" in p
                                      else p["r_hip"] - p["l_hip"])
    return frames


def placed_markers(points: dict, foot_offsets: dict | None = None) -> dict:
    """Markers placed from the data: at their median position in their body's frame.

    Parameters
    ----------
    points : dict of str to ndarray of shape (T, 3)
    foot_offsets : dict, optional
        The feet's pitch offsets of a static trial (:func:`toolkit.biomech.segments.foot_pitch_offsets`).

    Returns
    -------
    dict of str to (body name, (3,) ndarray)
        Metres, in the body frame of :func:`build_generic_model` (ISB axes at the body's proximal joint).
    """
    frames = _placement_frames(points, foot_offsets)
    p = points
    out = {}
    for name, v in points.items():
        side, _, kind = name.partition("_")
        if name == "head":
            side, kind = "", "head"
        if kind not in _PLACED or side not in ("l", "r", ""):
            continue
        body, seg, origin = _PLACED[kind]
        seg_key = seg if seg in ("pelvis", "torso") else f"{side}_{seg}"
        if seg_key not in frames:
            continue
        o = np.mean([points[x if seg in ("pelvis", "torso") else f"{side}_{x}"] for x in origin], axis=0)
        local = np.einsum("tji,tj->ti", frames[seg_key], v - o)
        if np.isfinite(local).all(-1).any():
            out[name] = (body if body in ("pelvis", "torso") else f"{side}_{body}", np.nanmedian(local, 0))
    return out


def _labelled(osim, table, names):
    """``table`` (an empty OpenSim time-series table) with ``names`` as its column labels."""
    labels = osim.StdVectorString()
    for n in names:
        labels.append(n)
    table.setColumnLabels(labels)
    return table


def _marker_table(osim, points: dict, names, fps: float):
    T = len(points[names[0]])
    table = _labelled(osim, osim.TimeSeriesTableVec3(), names)
    for t in range(T):
        row = osim.RowVectorVec3(len(names))
        for k, n in enumerate(names):
            x = WORLD_TO_OPENSIM @ points[n][t]
            row[k] = osim.Vec3(*(x if np.all(np.isfinite(x)) else (np.nan,) * 3))
        table.appendRow(t / fps, row)
    table.addTableMetaDataString("DataRate", f"{fps:g}")
    table.addTableMetaDataString("Units", "m")
    return table


def body_orientations(points: dict, foot_offsets: dict | None = None) -> dict:
    """Per model body whose frame markers define (:data:`ORIENTED_SEGMENTS`), its segment's frame in
    OpenSim's ground: the orientation targets of the IK.

    Parameters
    ----------
    points : dict of str to ndarray of shape (T, 3)
        Landmarks (metres, world z up, NaN = missing), as the model's markers are placed from.
    foot_offsets : dict, optional
        The feet's pitch offsets of a static trial (:func:`foot_pitch_offsets`).

    Returns
    -------
    dict of str to ndarray of shape (T, 3, 3)
        Model body name -> rotation whose columns are the body's axes in the ground (Y up); NaN
        where the frame is not defined; empty for joint centres alone.  The frames are those markers are placed in
        (:func:`placed_markers`): the own engine's segment frames, and for the torso the trunk
        (mid-hip to neck) with the shoulder line.
    """
    frames = _placement_frames(points, foot_offsets)
    out = {}
    for seg, (body, marker_sets) in ORIENTED_SEGMENTS.items():
        key = "torso" if body == "torso" else seg
        if key in frames and any(all(m in points for m in ms) for ms in marker_sets):
            out[body] = np.einsum("ij,tjk->tik", WORLD_TO_OPENSIM, frames[key])
    return out


def _orientation_table(osim, orientations: dict, fps: float):
    """OpenSim table of rotations (one column per body) for an ``OrientationsReference``."""
    names = list(orientations)
    T = len(orientations[names[0]])
    table = _labelled(osim, osim.TimeSeriesTableRotation(), names)
    for t in range(T):
        row = osim.RowVectorRotation(len(names))
        for k, n in enumerate(names):
            R = orientations[n][t]
            r = row.updElt(0, k)            # the bindings' row vectors have no item assignment
            if np.all(np.isfinite(R)):
                r.setRotationFromApproximateMat33(osim.Mat33(*(float(x) for x in R.ravel())))
            else:
                r.setRotationToNaN()
        table.appendRow(t / fps, row)
    table.addTableMetaDataString("DataRate", f"{fps:g}")
    return table


def _initial_pelvis(points: dict, t: int) -> dict:
    frames = segment_frames({k: v[t:t + 1] for k, v in points.items()})
    R = WORLD_TO_OPENSIM @ frames["pelvis"][0]
    tilt, lst, rot = np.deg2rad(cardan_zxy(R))
    o = WORLD_TO_OPENSIM @ (0.5 * (points["l_hip"][t] + points["r_hip"][t]))
    return {"pelvis_tilt": tilt, "pelvis_list": lst, "pelvis_rotation": rot,
            "pelvis_tx": o[0], "pelvis_ty": o[1], "pelvis_tz": o[2]}


def _scaled_model(osim, points: dict, foot_offsets: dict | None, pelvis_markers: bool, out: Path):
    """Build the generic model, scale it to the person and place its markers; write both models.

    Parameters
    ----------
    osim : module
        The ``opensim`` module.
    points : dict of str to ndarray of shape (T, 3)
        Landmarks (metres, world z up, NaN = missing), unused ones left out.
    foot_offsets : dict or None
        The feet's pitch offsets from a static trial (:func:`foot_pitch_offsets`).
    pelvis_markers : bool
        Whether both ASIS and PSIS markers are there (the lumbar joint is then free).
    out : Path
        Folder for ``model_generic.osim`` and ``model_scaled.osim``.

    Returns
    -------
    model : opensim.Model
        The scaled model with its markers, connections finalised.
    factors : dict of str to tuple of 3 float
        Per body, its scale factors (:func:`scale_factors`).
    """
    model, joint_markers = build_generic_model(set(points), lumbar_free=pelvis_markers)
    model.printToXML(str(out / "model_generic.osim"))
    state = model.initSystem()
    factors = scale_factors(points)
    scale_set = osim.ScaleSet()
    for body, k in factors.items():
        sc = osim.Scale()
        sc.setSegmentName(body)
        sc.setScaleFactors(osim.Vec3(*k))
        sc.setApply(True)
        scale_set.cloneAndAppend(sc)
    model.scale(state, scale_set, True)
    bodies = {model.getBodySet().get(i).getName() for i in range(model.getBodySet().getSize())}
    for name, (body, loc) in placed_markers(points, foot_offsets).items():
        if body not in bodies:
            continue
        if model.getMarkerSet().contains(name):
            model.updMarkerSet().get(name).set_location(osim.Vec3(*loc))
            if name.endswith("_shoulder") and model.getJointSet().contains(name):
                # the joint goes where its centre marker went (frame 0: the offset frame on the parent)
                model.updJointSet().get(name).upd_frames(0).set_translation(osim.Vec3(*loc))
        else:
            model.addMarker(osim.Marker(name, model.getBodySet().get(body), osim.Vec3(*loc)))
    model.finalizeConnections()
    model.setName("toolkit_scaled")
    model.printToXML(str(out / "model_scaled.osim"))
    return model, factors


def _ik_solver(osim, model, points: dict, names: list, fps: float, orientations: dict):
    """OpenSim's ``InverseKinematicsSolver`` for the markers ``names`` and the bodies' orientation targets.

    Every marker weighs 1, every orientation :data:`ORIENTATION_WEIGHT`; ``orientations`` maps a model
    body to its rotation per frame (T, 3, 3) in the ground, empty for markers only.
    """
    weights = osim.SetMarkerWeights()
    for n in names:
        weights.cloneAndAppend(osim.MarkerWeight(n, 1.0))
    mref = osim.MarkersReference(_marker_table(osim, points, names, fps), weights)
    if not orientations:
        return osim.InverseKinematicsSolver(model, mref, osim.SimTKArrayCoordinateReference(), math.inf)
    oweights = osim.OrientationWeightSet()
    for n in orientations:
        oweights.cloneAndAppend(osim.OrientationWeight(n, ORIENTATION_WEIGHT))
    oref = osim.OrientationsReference(_orientation_table(osim, orientations, fps), oweights)
    return osim.InverseKinematicsSolver(model, mref, oref, osim.SimTKArrayCoordinateReference(), math.inf)


def _inverse_kinematics(osim, model, points: dict, fps: float, orientations: dict | None = None):
    """Track every frame from the first with both hips and the neck seen.

    Parameters
    ----------
    osim : module
        The ``opensim`` module.
    model : opensim.Model
        The scaled model with its markers.
    points : dict of str to ndarray of shape (T, 3)
        Landmarks (metres, world z up, NaN = missing).
    fps : float
        Frames per second.
    orientations : dict of str to ndarray of shape (T, 3, 3), optional
        Model body -> its orientation target per frame, in the ground (:func:`body_orientations`).

    Returns
    -------
    names : list of str
        The model's markers.
    coords : list of str
        The model's coordinates.
    values : ndarray of shape (T, len(coords))
        Per frame, the coordinates (degrees for rotations, metres for translations); NaN where not solved.
    residuals : ndarray of shape (T, len(names))
        Per frame, each marker's distance to its landmark (metres); NaN where not solved or not seen.
    notes : list of str
        The frames left out, and why.
    angle_errors : dict of str to ndarray of shape (T,)
        Per oriented body, the angle between its model and its target orientation, degrees.

    Raises
    ------
    InputError
        No frame with both hips and the neck seen.
    """
    state = model.initSystem()
    mset = model.getMarkerSet()
    names = [mset.get(i).getName() for i in range(mset.getSize())]
    solver = _ik_solver(osim, model, points, names, fps, orientations or {})
    solver.setAccuracy(IK_ACCURACY)
    cset = model.getCoordinateSet()
    coords = [cset.get(i).getName() for i in range(cset.getSize())]
    T = len(points["neck"])
    first = next((t for t in range(T) if all(np.isfinite(points[n][t]).all() for n in ("l_hip", "r_hip", "neck"))),
                 None)
    if first is None:
        raise InputError("points", "a frame with both hips and the neck seen", "none")
    for c, v in _initial_pelvis(points, first).items():
        cset.get(c).setValue(state, float(v))
    values = np.full((T, len(coords)), np.nan)
    residuals = np.full((T, len(names)), np.nan)
    angle_errors = {n: np.full(T, np.nan) for n in (orientations or {})}
    notes = []
    state.setTime(first / fps)
    solver.assemble(state)
    seen = np.sum([np.isfinite(points[n]).all(-1) for n in names], axis=0)
    for t in range(first, T):
        if seen[t] < MIN_MARKERS:
            notes.append(f"frame {t}: {int(seen[t])} markers seen, fewer than {MIN_MARKERS}: left out")
            continue
        state.setTime(t / fps)
        try:
            solver.track(state)
        except RuntimeError as e:          # OpenSim raises RuntimeError when a frame cannot be assembled
            notes.append(f"frame {t}: inverse kinematics failed ({str(e).splitlines()[0][:120]})")
            continue
        for k, c in enumerate(coords):
            q = cset.get(c)
            v = q.getValue(state)
            values[t, k] = math.degrees(v) if q.getMotionType() == 1 else v   # 1 = rotational
        errs = osim.SimTKArrayDouble()
        solver.computeCurrentMarkerErrors(errs)
        for i in range(solver.getNumMarkersInUse()):
            residuals[t, names.index(solver.getMarkerNameForIndex(i))] = errs.getElt(i)
        if angle_errors:
            solver.computeCurrentOrientationErrors(errs)
            for i in range(solver.getNumOrientationSensorsInUse()):
                angle_errors[solver.getOrientationSensorNameForIndex(i)][t] = math.degrees(errs.getElt(i))
    for k, n in enumerate(names):       # OpenSim reports 0 for a marker missing from a frame
        residuals[~np.isfinite(points[n]).all(-1), k] = np.nan
    return names, coords, values, residuals, notes, angle_errors


def _write_mot(osim, coords: list[str], values: np.ndarray, fps: float, path: Path) -> None:
    """Write the coordinates as an OpenSim motion file (``.mot``, degrees).

    Parameters
    ----------
    osim : module
        The ``opensim`` module.
    coords : list of str
        The coordinates' names.
    values : ndarray of shape (T, len(coords))
        Per frame, the coordinates (degrees for rotations, metres for translations).
    fps : float
        Frames per second.
    path : Path
        The file to write.
    """
    mot = _labelled(osim, osim.TimeSeriesTable(), coords)
    for t in range(len(values)):
        row = osim.RowVector(len(coords))
        for k in range(len(coords)):
            row[k] = float(values[t, k])
        mot.appendRow(t / fps, row)
    mot.addTableMetaDataString("inDegrees", "yes")
    osim.STOFileAdapter.write(mot, str(path))


def opensim_angles(points: dict, fps: float, out: str | os.PathLike, *, static: dict | None = None,
                   log=None) -> OpenSimResult:
    """Scale the generic model to the person and run inverse kinematics on every frame, in a process of
    its own.

    OpenSim's Python bindings and ezc3d's are both made by SWIG, and in one process the second one
    imported can no longer convert its arguments (ezc3d's C3D writer fails after ``import opensim``,
    and the reverse): OpenSim therefore never runs in the caller's process.  Parameters, returns and
    errors are those of :func:`opensim_angles_in_process`; ``log`` receives the messages once the child
    is done.
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    if not opensim_available():
        _require_opensim()
    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as pool:
        result, messages = pool.submit(_opensim_child, points, fps, str(out), static).result()
    if log is not None:
        for m in messages:
            log(m)
    return result


def _opensim_child(points: dict, fps: float, out: str, static: dict | None) -> tuple:
    """:func:`opensim_angles_in_process` in the child process: the result and the log messages."""
    import opensim

    opensim.Logger.removeFileSink()  # no opensim.log in the caller's working folder
    messages: list = []
    return opensim_angles_in_process(points, fps, out, static=static, log=messages.append), messages


def opensim_angles_in_process(points: dict, fps: float, out: str | os.PathLike, *, static: dict | None = None,
                              log=None) -> OpenSimResult:
    """Scale the generic model to the person and run inverse kinematics on every frame.

    Parameters
    ----------
    points : dict of str to ndarray of shape (T, 3)
        Landmarks (metres, world z up, NaN = missing); at least the hips, knees, ankles and neck.
    fps : float
    out : path
        Folder for ``model_generic.osim``, ``model_scaled.osim``, ``ik.mot``, ``marker_residuals.json``.
    static : dict of str to ndarray of shape (S, 3), optional
        A static trial's landmarks: the feet's pitch offsets when placing the toe and heel markers.
    log : callable, optional

    Returns
    -------
    OpenSimResult

    Raises
    ------
    InputError
        OpenSim not installed; joints missing.
    """
    osim = _require_opensim()
    from toolkit.biomech.files import write_json

    need = [n for n in ("l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle", "neck") if n not in points]
    if need:
        raise InputError("points", "hips, knees, ankles and the neck", f"no {need}")
    out = Path(out)
    foot_offsets = foot_pitch_offsets(static) if static is not None else None
    points = {k: v for k, v in points.items() if k not in UNUSED_LANDMARKS}
    pelvis_markers = all(f"{s}_{k}" in points for s in "lr" for k in ("asis", "psis"))
    model, factors = _scaled_model(osim, points, foot_offsets, pelvis_markers, out)
    bodies = {model.getBodySet().get(i).getName() for i in range(model.getBodySet().getSize())}
    orient = {b: R for b, R in body_orientations(points, foot_offsets).items() if b in bodies}
    names, coords, values, residuals, notes, angle_errors = _inverse_kinematics(osim, model, points, fps, orient)
    T = len(points["neck"])
    joint_cols = [k for k, c in enumerate(coords) if not c.startswith(("pelvis_", "lumbar_"))]
    angles = JointAngles(time=np.arange(T) / float(fps), names=tuple(coords[k] for k in joint_cols),
                         degrees=values[:, joint_cols], engine="opensim")
    _write_mot(osim, coords, values, fps, out / "ik.mot")
    res = {n: residuals[:, k] for k, n in enumerate(names)}
    summary = {"markers": {n: {"rms_mm": float(np.sqrt(np.nanmean(r ** 2)) * 1e3) if np.isfinite(r).any() else None,
                               "max_mm": float(np.nanmax(r) * 1e3) if np.isfinite(r).any() else None}
                           for n, r in res.items()},
               "all_rms_mm": float(np.sqrt(np.nanmean(residuals ** 2)) * 1e3),
               "orientations_deg": {b: {"rms": float(np.sqrt(np.nanmean(e ** 2))) if np.isfinite(e).any() else None,
                                        "max": float(np.nanmax(e)) if np.isfinite(e).any() else None}
                                    for b, e in angle_errors.items()},
               "orientation_weight": ORIENTATION_WEIGHT,
               "frames_solved": int(np.isfinite(values[:, 0]).sum()), "frames": T,
               "scale_factors": {k: list(v) for k, v in factors.items()}, "lumbar_free": pelvis_markers}
    files = {"model_generic": out / "model_generic.osim", "model_scaled": out / "model_scaled.osim",
             "mot": out / "ik.mot", "residuals": write_json(out / "marker_residuals.json", summary)}
    if log is not None:
        log(f"OpenSim inverse kinematics: {summary['frames_solved']}/{T} frames, marker residual "
            f"{summary['all_rms_mm']:.1f} mm RMS")
    return OpenSimResult(angles, {c: values[:, k] for k, c in enumerate(coords)}, res,
                         {k: list(v) for k, v in factors.items()}, files, tuple(notes))
