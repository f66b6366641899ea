"""A synthetic depth camera (Kinect-v1-like) and the ground truth of the depth tracker.

A scene spec with a ``[depth_camera]`` table makes the generator call
:func:`render_depth_camera`, which writes::

    <root>/depth_camera/intrinsics.toml        K, size, cam_from_world (see toolkit.io.depth_readers)
    <root>/depth_camera/depth/NNNNNN.png       uint16 millimetres, 0 = no reading
    <root>/depth_camera/background.png         the empty scene seen by the sensor (same noise)
    <root>/groundtruth/skeleton13.npz          joints (T, 13, 3) metres, world; names (13,); visible (T, 13)
                                               (seen: not hidden, in the image and the sensor's range)
    <root>/groundtruth/skeleton17.npz          joints (T, 17, 3) metres, world; names (17,); visible (T, 17)
    <root>/groundtruth/depth_camera/masks/NNNNNN.png   uint8 255 where the tracked person is seen

Depth is ray cast exactly (self-occlusion and occlusion by a second person come
for free) and then degraded like a structured-light sensor:

1. **axial noise** growing with the square of the distance,
   ``sigma(z) = a + b (z - z0)^2`` (:data:`KINECT_AXIAL_NOISE`, Nguyen, Izadi and
   Lovell 2012, for Kinect v1 at incidence below 60 degrees);
2. **disparity quantisation**: depth is measured through disparity, so the
   representable depths are ``1 / (k * step)``, spaced ``step * z^2`` apart
   (:data:`KINECT_DISPARITY_STEP`; about 2.6 cm at 3 m and 7 cm at 5 m, as
   Khoshelham and Elberink 2012 report);
3. **projector shadows**: surfaces that the projector, :data:`KINECT_BASELINE_M`
   to the right of the camera, cannot see get no reading (a band left of every
   foreground edge);
4. **edge dropouts**: pixels at depth discontinuities lose their reading with
   probability :data:`EDGE_DROPOUT_PROBABILITY` (a jump over :data:`EDGE_JUMP_M`
   and :data:`EDGE_JUMP_RELATIVE` of the depth within 3 x 3 pixels), others with
   :data:`RANDOM_DROPOUT_PROBABILITY`;
5. readings outside :data:`KINECT_RANGE_M` are 0.

Control points of the depth skeletons (source 001, figure 1) are derived from the
14-joint skeleton and the body geometry of :class:`toolkit.body.model.BodyModel`:

=============================  ==========================================================
control point                  definition
=============================  ==========================================================
head (13, 17)                  centre of the head ellipsoid: ``head + 0.02 s up``
shoulders, elbows, hips, knees the 14-joint joints
hands (13)                     centre of the hand volume: ``wrist + 0.075 s f``
wrists (17)                    the 14-joint wrists
hands (17)                     the tip of the hand: ``wrist + (0.075 + 0.085) s f``
feet (13)                      centre of the foot: ``ankle + 0.065 s w + 0.031 s d``
ankles (17)                    the 14-joint ankles
feet (17)                      the tip of the toes: foot centre ``+ 0.125 s w``
=============================  ==========================================================

with ``s = stature / 1.75``, ``up`` the neck-to-head direction, ``f`` the
elbow-to-wrist direction, ``d`` the knee-to-ankle direction and ``w`` the foot's
forward direction, exactly as the body mesh is built (the constants live in
:mod:`toolkit.body.control_points` and mirror ``BodyModel.mesh``; a test checks them
against the mesh).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.body.control_points import control_points
from toolkit.errors import InputError
from toolkit.io import (
    atomic_save_npz,
    atomic_write_png,
    atomic_write_text,
    depth_to_mm,
    frame_filename,
)
from toolkit.observe import as_observer
from toolkit.skeleton import JOINTS_13, JOINTS_17, SKELETON_13, SKELETON_14, SKELETON_17
from toolkit.synthetic.depth_spec import KINECT_FOV_X_DEG, KINECT_RANGE_M, DepthCameraSpec, SecondPerson

__all__ = [
    "EDGE_DROPOUT_PROBABILITY",
    "EDGE_JUMP_M",
    "KINECT_AXIAL_NOISE",
    "KINECT_BASELINE_M",
    "KINECT_DISPARITY_STEP",
    "KINECT_FOV_X_DEG",
    "KINECT_RANGE_M",
    "RANDOM_DROPOUT_PROBABILITY",
    "DepthCameraOutput",
    "DepthCameraSpec",
    "DepthSequence",
    "SecondPerson",
    "apply_sensor_noise",
    "control_point_visibility",
    "control_points",
    "depth_camera_for",
    "iter_depth_frames",
    "make_second_person",
    "render_depth_camera",
    "render_depth_sequence",
]

#: Axial noise of Kinect v1, ``sigma(z) = a + b (z - z0)^2`` metres: (a, b, z0)
#: (Nguyen, Izadi and Lovell 2012, angles below 60 degrees).
KINECT_AXIAL_NOISE = (0.0012, 0.0019, 0.4)
#: Disparity quantisation step of Kinect v1 in 1/m: depth steps are ``step * z^2``
#: (7 cm at 5 m, Khoshelham and Elberink 2012).
KINECT_DISPARITY_STEP = 2.85e-3
#: Distance from the camera to the projector along the camera's +x axis, metres.
KINECT_BASELINE_M = 0.075
#: A 3 x 3 neighbourhood spanning more than this depth range is a depth edge, metres.
EDGE_JUMP_M = 0.05
#: ... or more than this fraction of the depth (grazing surfaces are not edges).
EDGE_JUMP_RELATIVE = 0.04
#: Probability that a pixel at a depth edge loses its reading.
EDGE_DROPOUT_PROBABILITY = 0.5
#: Probability that any other pixel loses its reading.
RANDOM_DROPOUT_PROBABILITY = 0.002
#: Disparity tolerance (pixels) before a surface counts as hidden from the projector.
SHADOW_TOLERANCE_PX = 0.5
#: Half the side of the bare floor of ``environment = "floor"``, metres.
FLOOR_HALF_SIZE_M = 10.0

_J14 = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
#: Part ids (1 + index of PARTS_14) whose surface a control point may be seen through.
_PART_ID = {n: i + 1 for i, n in enumerate(SKELETON_14.part_names)}


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-9)


# ------------------------------------------------------- control points
def _visible_parts(names) -> list[set[int]]:
    sets = []
    for n in names:
        if n == "head":
            sets.append({_PART_ID["head"]})
            continue
        side, what = n.split("_", 1)
        ua, fa = _PART_ID[f"{side}_upper_arm"], _PART_ID[f"{side}_forearm"]
        th, sh = _PART_ID[f"{side}_thigh"], _PART_ID[f"{side}_shank"]
        torso = _PART_ID["torso"]
        sets.append({"shoulder": {torso, ua}, "elbow": {ua, fa}, "wrist": {fa}, "hand": {fa},
                     "hip": {torso, th}, "knee": {th, sh}, "ankle": {sh}, "foot": {sh}}[what])
    return sets


_VIS13 = _visible_parts(JOINTS_13)
_VIS17 = _visible_parts(JOINTS_17)


def control_point_visibility(points: np.ndarray, camera: Camera, labels: np.ndarray, subject: np.ndarray,
                             names=JOINTS_13, subject_id: int = 1, depth: np.ndarray | None = None,
                             range_m=None) -> np.ndarray:
    """Which control points the camera sees.

    A control point is visible when it projects inside the image onto a pixel
    of the same person showing one of the body parts around that point (the
    hand onto its forearm-and-hand part, the hip onto the torso or its thigh,
    ...), that is when no other part or person hides it, and, if ``depth`` and
    ``range_m`` are given, when that surface lies within the sensor's range.

    Parameters
    ----------
    points : ndarray of shape (n, 3)
        World, metres.
    camera : Camera
    labels, subject : ndarray of shape (H, W)
        Ray-cast part ids and subject ids (see ``Raycaster.cast``).
    names : sequence of str
        Control point names (``JOINTS_13`` or ``JOINTS_17``).
    subject_id : int
    depth : ndarray of shape (H, W), optional
        Exact depth of the ray cast, metres.
    range_m : tuple of float, optional
        The sensor's (near, far) range.

    Returns
    -------
    ndarray of shape (n,), bool
    """
    sets = _VIS13 if tuple(names) == JOINTS_13 else _VIS17 if tuple(names) == JOINTS_17 else _visible_parts(names)
    uv = camera.project(points)
    z = camera.depth_of(points)
    w, h = camera.size
    out = np.zeros(len(points), bool)
    for i, ((u, v), zi) in enumerate(zip(uv, z)):
        if not (np.isfinite(u) and np.isfinite(v) and zi > 0):
            continue
        c, r = int(round(u)), int(round(v))
        if 0 <= c < w and 0 <= r < h and subject[r, c] == subject_id and labels[r, c] in sets[i]:
            out[i] = depth is None or range_m is None or bool(range_m[0] <= depth[r, c] <= range_m[1])
    return out


# ---------------------------------------------------------------- camera
def _facing(joints14: np.ndarray) -> np.ndarray:
    """Unit horizontal forward direction of a pose (14, 3)."""
    J = joints14
    r = (J[_J14["r_shoulder"]] - J[_J14["l_shoulder"]]) + (J[_J14["r_hip"]] - J[_J14["l_hip"]])
    f = np.array([-r[1], r[0], 0.0])
    n = np.linalg.norm(f)
    return f / n if n > 1e-9 else np.array([0.0, 1.0, 0.0])


def _centre_xy(joints: np.ndarray) -> np.ndarray:
    pelvis = 0.5 * (joints[:, _J14["l_hip"]] + joints[:, _J14["r_hip"]])
    return pelvis[:, :2].mean(0)


def depth_camera_for(spec: DepthCameraSpec, joints14: np.ndarray) -> Camera:
    """The depth camera of a spec for a person moving as ``joints14`` (T, 14, 3)."""
    J = np.asarray(joints14, float)
    c = _centre_xy(J)
    fwd = _facing(J[0])
    a = np.radians(spec.azimuth_deg)
    fwd = np.array([np.cos(a) * fwd[0] - np.sin(a) * fwd[1], np.sin(a) * fwd[0] + np.cos(a) * fwd[1], 0.0])
    eye = np.array(spec.position) if spec.position is not None else \
        np.array([c[0] + spec.distance_m * fwd[0], c[1] + spec.distance_m * fwd[1], spec.height_m])
    target = np.array(spec.target) if spec.target is not None else np.array([c[0], c[1], spec.target_height_m])
    return Camera.look_at(spec.name, eye, target, size=spec.resolution, fov_x_deg=spec.fov_deg)


# ----------------------------------------------------------------- noise
def apply_sensor_noise(depth: np.ndarray, camera: Camera, rng: np.random.Generator,
                       range_m=KINECT_RANGE_M) -> np.ndarray:
    """Degrade an exact depth map like a structured-light sensor (see the module docstring).

    Parameters
    ----------
    depth : ndarray of shape (H, W)
        Exact camera-frame z, metres, NaN = nothing hit.
    camera : Camera
        Gives the focal length for the projector shadows.
    rng : numpy.random.Generator
    range_m : tuple of float
        Valid range (near, far).

    Returns
    -------
    ndarray of shape (H, W), float32
        Metres, NaN = no reading.
    """
    z = np.asarray(depth, np.float64)
    valid = np.isfinite(z) & (z > 0)
    zz = np.where(valid, z, 0.0)
    a, b, z0 = KINECT_AXIAL_NOISE
    sigma = a + b * (zz - z0) ** 2
    noisy = zz + rng.standard_normal(z.shape) * sigma
    noisy = np.maximum(noisy, 1e-3)
    inv = np.round(1.0 / noisy / KINECT_DISPARITY_STEP) * KINECT_DISPARITY_STEP
    out = np.where(valid & (inv > 0), 1.0 / np.maximum(inv, 1e-12), np.nan)
    # projector shadows: projector column u_p = u - f b / z must increase along a row
    f = camera.K[0, 0]
    w = z.shape[1]
    up = np.where(valid, np.arange(w)[None, :] - f * KINECT_BASELINE_M / np.where(valid, zz, 1.0), np.inf)
    right_min = np.minimum.accumulate(up[:, ::-1], axis=1)[:, ::-1]
    right_min = np.concatenate([right_min[:, 1:], np.full((z.shape[0], 1), np.inf)], axis=1)
    shadow = valid & (up > right_min + SHADOW_TOLERANCE_PX)
    # edges: 3x3 depth range over EDGE_JUMP_M (background counted as far away)
    import cv2

    zf = np.where(valid, zz, 100.0).astype(np.float32)
    k = np.ones((3, 3), np.uint8)
    edge = (cv2.dilate(zf, k) - cv2.erode(zf, k)) > np.maximum(EDGE_JUMP_M, EDGE_JUMP_RELATIVE * zf)
    drop = np.where(edge, rng.random(z.shape) < EDGE_DROPOUT_PROBABILITY,
                    rng.random(z.shape) < RANDOM_DROPOUT_PROBABILITY)
    out[shadow | drop] = np.nan
    out[(out < range_m[0]) | (out > range_m[1])] = np.nan
    return out.astype(np.float32)


def _clip_range(depth: np.ndarray, range_m) -> np.ndarray:
    d = np.asarray(depth, np.float32).copy()
    d[~np.isfinite(d) | (d < range_m[0]) | (d > range_m[1])] = np.nan
    return d


# --------------------------------------------------------- second person
def _yaw_of(joints14_frame: np.ndarray) -> float:
    f = _facing(joints14_frame)
    return float(np.arctan2(f[1], f[0]))


def make_second_person(spec: SecondPerson, subject_joints: np.ndarray, fps: float,
                       rng: np.random.Generator | int | None = None, detail: float = 0.6):
    """A second body and its motion placed beside the tracked person.

    Parameters
    ----------
    spec : SecondPerson
    subject_joints : ndarray of shape (T, 14, 3)
        The tracked person's motion (position and facing are taken from it).
    fps : float
    rng : numpy.random.Generator or int or None
    detail : float
        Mesh detail of the second body.

    Returns
    -------
    body_model : BodyModel
    joints : ndarray of shape (T, 14, 3)
    """
    from toolkit.motion import generate_motion
    from toolkit.body.model import BodyModel

    rng = np.random.default_rng(rng)
    S = np.asarray(subject_joints, float)
    props = BodyProportions.sample(spec.height_m, rng)
    model = BodyModel.sample(props, rng, detail=detail)
    J = generate_motion(spec.motion, props, S.shape[0], fps, rng)
    fwd = _facing(S[0])
    right = np.array([fwd[1], -fwd[0], 0.0])
    c = _centre_xy(S)
    goal = c + spec.offset_m[0] * right[:2] + spec.offset_m[1] * fwd[:2]
    yaw = _yaw_of(S[0]) - _yaw_of(J[0])
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    c2 = _centre_xy(J)
    J = (J - np.array([c2[0], c2[1], 0.0])) @ R.T + np.array([goal[0], goal[1], 0.0])
    return model, J


# ------------------------------------------------------------- rendering
@dataclass(frozen=True)
class DepthSequence:
    """A rendered depth sequence held in memory (for tests and benchmarks).

    Attributes
    ----------
    camera : Camera
        The depth camera (true pose).
    depth : ndarray of shape (T, H, W), float32
        Sensor depth, metres, NaN = no reading.
    subject : ndarray of shape (T, H, W), uint8
        Exact person id per pixel (0 none, 1 tracked person, 2 second person).
    background : ndarray of shape (H, W), float32
        The empty scene through the same sensor model.
    joints13, joints17 : ndarray of shape (T, 13, 3) and (T, 17, 3)
        Ground-truth control points, world metres.
    visible13, visible17 : ndarray of shape (T, 13) and (T, 17), bool
    """

    camera: Camera
    depth: np.ndarray
    subject: np.ndarray
    background: np.ndarray
    joints13: np.ndarray
    joints17: np.ndarray
    visible13: np.ndarray
    visible17: np.ndarray

    @property
    def n_frames(self) -> int:
        return self.depth.shape[0]


@dataclass(frozen=True)
class DepthFrame:
    """One rendered frame: sensor depth, exact subject ids, ground-truth control points."""

    index: int
    depth: np.ndarray
    subject: np.ndarray
    labels: np.ndarray
    joints13: np.ndarray
    joints17: np.ndarray
    visible13: np.ndarray
    visible17: np.ndarray


def _check_joints(joints, name="joints"):
    J = np.asarray(joints, float)
    if J.ndim != 3 or J.shape[1:] != (14, 3) or J.shape[0] == 0 or not np.all(np.isfinite(J)):
        raise InputError(name, "a finite array of shape (T, 14, 3) with T > 0", f"shape {J.shape}")
    return J


def _environment(spec: DepthCameraSpec, rng):
    if spec.environment == "none":
        return []
    if spec.environment == "floor":
        from toolkit.synthetic.environment import Surface

        h = FLOOR_HALF_SIZE_M
        V = np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])
        return [Surface("floor", V, np.array([[0, 1, 2], [0, 2, 3]]), np.array([[0, 1], [1, 1], [1, 0], [0, 0.0]]),
                        np.full((2, 2, 3), 128, np.uint8))]
    from toolkit.synthetic.environment import make_environment

    return make_environment("studio", rng)


def iter_depth_frames(spec: DepthCameraSpec, body_model, joints: np.ndarray, rng, *, camera: Camera,
                      second_person=None, surfaces=()) -> Iterator[DepthFrame]:
    """Render the frames of a depth sequence one by one (see :func:`render_depth_sequence`)."""
    from toolkit.synthetic.render import Raycaster

    J = _check_joints(joints)
    rc = Raycaster(list(surfaces))
    stature = body_model.shape.proportions.height
    j13, j17 = control_points(J, stature)
    J2 = None
    if second_person is not None:
        model2, J2 = second_person
        J2 = _check_joints(J2, "second_person joints")
        if J2.shape[0] != J.shape[0]:
            raise InputError("second_person joints", f"{J.shape[0]} frames", f"{J2.shape[0]}")
    for t in range(J.shape[0]):
        bodies = [body_model.mesh(J[t])]
        if J2 is not None:
            bodies.append(model2.mesh(J2[t]))
        labels, subject, depth = rc.cast(camera, bodies)
        d = apply_sensor_noise(depth, camera, rng, spec.range_m) if spec.noise else _clip_range(depth, spec.range_m)
        v13 = control_point_visibility(j13[t], camera, labels, subject, JOINTS_13, depth=depth, range_m=spec.range_m)
        v17 = control_point_visibility(j17[t], camera, labels, subject, JOINTS_17, depth=depth, range_m=spec.range_m)
        yield DepthFrame(t, d, subject, labels, j13[t], j17[t], v13, v17)


def _background(spec, camera, rng, surfaces):
    from toolkit.synthetic.render import Raycaster

    _, _, depth = Raycaster(list(surfaces)).cast(camera, [])
    return apply_sensor_noise(depth, camera, rng, spec.range_m) if spec.noise else _clip_range(depth, spec.range_m)


def render_depth_sequence(spec: DepthCameraSpec, body_model, joints: np.ndarray,
                          rng: np.random.Generator | int | None = None, *, second_person=None,
                          fps: float = 30.0, camera: Camera | None = None) -> DepthSequence:
    """Render a depth sequence in memory.

    Parameters
    ----------
    spec : DepthCameraSpec
    body_model : BodyModel
        The tracked person.
    joints : ndarray of shape (T, 14, 3)
        Their motion, world metres.
    rng : numpy.random.Generator or int or None
        Sensor noise, environment and second person.
    second_person : tuple of (BodyModel, ndarray (T, 14, 3)), optional
        Made from ``spec.second_person`` when not given.
    fps : float
        Frame rate (only used to generate the second person's motion).
    camera : Camera, optional
        Overrides the camera placement of ``spec``.

    Returns
    -------
    DepthSequence
    """
    rng = np.random.default_rng(rng)
    J = _check_joints(joints)
    cam = camera if camera is not None else depth_camera_for(spec, J)
    surfaces = _environment(spec, rng)
    if second_person is None and spec.second_person is not None:
        second_person = make_second_person(spec.second_person, J, fps, rng)
    frames = list(iter_depth_frames(spec, body_model, J, rng, camera=cam, second_person=second_person,
                                    surfaces=surfaces))
    bg = _background(spec, cam, rng, surfaces)
    return DepthSequence(
        camera=cam,
        depth=np.stack([f.depth for f in frames]),
        subject=np.stack([f.subject for f in frames]),
        background=bg,
        joints13=np.stack([f.joints13 for f in frames]),
        joints17=np.stack([f.joints17 for f in frames]),
        visible13=np.stack([f.visible13 for f in frames]),
        visible17=np.stack([f.visible17 for f in frames]),
    )


@dataclass(frozen=True)
class DepthCameraOutput:
    """What :func:`render_depth_camera` wrote.

    Attributes
    ----------
    camera : Camera
    intrinsics : Path
    depth_dir : Path
    background : Path
    skeleton13, skeleton17 : Path
    n_frames : int
    files : list of Path
        Every file written.
    """

    camera: Camera
    intrinsics: Path
    depth_dir: Path
    background: Path
    skeleton13: Path
    skeleton17: Path
    n_frames: int
    files: list = field(default_factory=list)


def render_depth_camera(root: str | Path, spec: DepthCameraSpec, body_model, joints: np.ndarray,
                        rng: np.random.Generator | int | None = None, observer=None,
                        second_person=None, fps: float = 30.0) -> DepthCameraOutput:
    """Render the depth camera of a take and write it with its ground truth.

    Writes the files listed in the module docstring under ``root`` (every
    write atomic), frame by frame.

    Parameters
    ----------
    root : str or Path
        Dataset folder.
    spec : DepthCameraSpec
    body_model : BodyModel
    joints : ndarray of shape (T, 14, 3)
        World metres.
    rng : numpy.random.Generator or int or None
    observer : Observer, optional
        Receives the depth camera (``rig`` at ``world/depth_cams``), each depth
        map (``depth``) and the ground-truth 13 points (``joints3d``).
    second_person : tuple of (BodyModel, ndarray (T, 14, 3)), optional
        Made from ``spec.second_person`` when not given.
    fps : float

    Returns
    -------
    DepthCameraOutput
    """
    from toolkit.io.depth_readers import depth_intrinsics_text

    root = Path(root)
    rng = np.random.default_rng(rng)
    obs = as_observer(observer)
    J = _check_joints(joints)
    cam = depth_camera_for(spec, J)
    surfaces = _environment(spec, rng)
    if second_person is None and spec.second_person is not None:
        second_person = make_second_person(spec.second_person, J, fps, rng)
    base = root / "depth_camera"
    files = [atomic_write_text(base / "intrinsics.toml", depth_intrinsics_text(
        cam, comment="synthetic depth camera (toolkit.synthetic.depth_sensor)"))]
    obs.report("rig", rig=Rig([cam]), path="world/depth_cams")
    obs.report("skeleton", skeleton=SKELETON_13)
    j13s, j17s, v13s, v17s = [], [], [], []
    for fr in iter_depth_frames(spec, body_model, J, rng, camera=cam, second_person=second_person,
                                surfaces=surfaces):
        name = frame_filename(fr.index)
        files.append(atomic_write_png(base / "depth" / name, depth_to_mm(fr.depth, str(base / "depth" / name))))
        mask = np.where(fr.subject == 1, 255, 0).astype(np.uint8)
        files.append(atomic_write_png(root / "groundtruth" / "depth_camera" / "masks" / name, mask))
        obs.report("depth", camera=cam.name, depth=np.nan_to_num(fr.depth, nan=0.0), name="depth", frame=fr.index)
        obs.report("joints3d", joints=fr.joints13, name="groundtruth/skeleton13", skeleton=SKELETON_13,
                   frame=fr.index)
        j13s.append(fr.joints13)
        j17s.append(fr.joints17)
        v13s.append(fr.visible13)
        v17s.append(fr.visible17)
    bg = _background(spec, cam, rng, surfaces)
    files.append(atomic_write_png(base / "background.png", depth_to_mm(bg)))
    s13 = atomic_save_npz(root / "groundtruth" / "skeleton13.npz", joints=np.stack(j13s),
                          names=np.array(SKELETON_13.joint_names), visible=np.stack(v13s))
    s17 = atomic_save_npz(root / "groundtruth" / "skeleton17.npz", joints=np.stack(j17s),
                          names=np.array(SKELETON_17.joint_names), visible=np.stack(v17s))
    files += [s13, s17]
    return DepthCameraOutput(cam, files[0], base / "depth", base / "background.png", s13, s17, J.shape[0], files)

