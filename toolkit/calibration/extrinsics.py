"""Camera poses by three methods: a board seen by several cameras, known scene points, the people.

Every method takes cameras with known intrinsics (poses ignored) and returns an
:class:`ExtrinsicsResult`: the rig in a world frame with z up and the floor at
``z = 0``, the reprojection errors per camera and the warnings of
:mod:`toolkit.calibration.checks`.

* :func:`extrinsics_from_boards`: per camera and view the board pose (``solvePnP``);
  camera-to-camera poses chained over the views two cameras share (rotations averaged),
  then a bundle adjustment of the camera poses and the rigid board poses.  The world is
  the board of the first view the first camera sees, turned so that z points out of
  its printed side (a board on the floor defines the floor).
* :func:`extrinsics_from_scene_points`: ``solvePnP`` (SQPnP, then Levenberg-Marquardt)
  of each camera on points of known coordinates; a fit that is much better with one
  axis flipped says the coordinates are left-handed.
* :func:`extrinsics_from_people`: the keypoints of people moving through the volume are
  the calibration object.  Which detections of different cameras show the same person is
  found first (:mod:`toolkit.calibration.people_matching`: RANSAC over detection pairs,
  before any pose is known); from the camera pairs sharing most of them, an essential
  matrix (RANSAC) and PnP of the other cameras give first poses; a sparse bundle
  adjustment with a robust loss refines all poses and points; then every frame's
  detections are grouped into people with the poses and adjusted again.  The start whose
  people agree in most observations is kept.  The scale comes from the person's height or
  measured bone lengths (else the median stature, with a warning), the floor from where
  the ankles rest and the up direction from the body's trunk.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from toolkit.anthropometry import BodyProportions
from toolkit.calibration.boards import Board
from toolkit.calibration.bundle import Observations, bundle_adjust
from toolkit.calibration.people_matching import (
    associate_detections,
    group_observations,
    group_pair_matches,
    match_camera_pair,
    triangulate_normalised,
)
from toolkit.calibration.checks import (
    boards_seen_from_behind,
    cameras_under_floor,
    mirrored_person_warning,
    reprojection_summary,
)
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.io.keypoint_files import normalise_name
from toolkit.observe import as_observer
from toolkit.skeleton import JOINTS_14
from toolkit.skeleton.mappings import to_skeleton14

__all__ = ["ExtrinsicsResult", "PeopleConfig", "extrinsics_from_boards", "extrinsics_from_scene_points",
           "extrinsics_from_people", "similarity_align", "DEFAULT_STATURE_M", "STATURE_SPREAD"]

#: Stature assumed when neither a height nor bone lengths are given (ANSUR II male median, metres).
DEFAULT_STATURE_M = 1.755
#: Relative spread of adult stature around the median (ANSUR II p5-p95 half range over the median).
STATURE_SPREAD = 0.07
#: Board views whose PnP error exceeds this are dropped before chaining (pixels).
MAX_BOARD_VIEW_RMS_PX = 3.0
#: A scene-point fit this much better with one axis flipped flags left-handed coordinates.
MIRROR_RATIO = 0.5


@dataclass(frozen=True, eq=False)
class ExtrinsicsResult:
    """A calibrated rig and how well it is supported.

    Attributes
    ----------
    rig : Rig
        World z up, floor at z = 0 (boards: the reference board's plane), metres.
    points : ndarray of shape (N, 3)
        The 3D points used (board corners, scene points, keypoints), world frame.
    reprojection : dict of str to dict
        Per camera ``n``, ``median_px``, ``rms_px``, ``p95_px`` (:func:`reprojection_summary`).
    warnings : list of str
    method : str
        ``board``, ``scene`` or ``people``.
    details : dict
        Method-specific figures (scale source, floor fit, views used, ...).
    """

    rig: Rig
    points: np.ndarray
    reprojection: dict
    warnings: list = field(default_factory=list)
    method: str = ""
    details: dict = field(default_factory=dict)


def _set_pose(cam: Camera, T: np.ndarray) -> Camera:
    T = np.asarray(T, float).copy()
    U, _, Vt = np.linalg.svd(T[:3, :3])
    T[:3, :3] = U @ Vt
    return cam.replace(cam_from_world=T)


def _mean_rotation(Rs: list[np.ndarray]) -> np.ndarray:
    U, _, Vt = np.linalg.svd(np.sum(Rs, axis=0))
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R = U @ np.diag([1, 1, -1]) @ Vt
    return R


def _report(obs, result: ExtrinsicsResult, residuals=None, cam_index=None):
    """Report the rig, the points, the warnings and the sorted residuals per camera to an observer."""
    o = as_observer(obs)
    o.report("rig", rig=result.rig, path="world/calibration/cams")
    if len(result.points):
        o.report("points3d", points=result.points, name=f"calibration/{result.method}/points")
    for w in result.warnings:
        o.report("text", name=f"calibration/{result.method}", text=w, level="WARN")
    if residuals is not None:
        for c, cam in enumerate(result.rig):
            o.report("series", name=f"calibration/{result.method}/residuals_px/{cam.name}",
                     values=np.sort(residuals[cam_index == c]))


# --------------------------------------------------------------------------- boards

def _board_view_poses(cameras: list[Camera], detections: list[dict], O: np.ndarray) -> dict:
    """The board pose of every view each camera sees well (``solvePnP``, IPPE).

    Parameters
    ----------
    cameras : list of Camera
    detections : list of dict of str to BoardDetection
    O : ndarray of shape (N, 3)
        The board's corner coordinates, metres.

    Returns
    -------
    dict of (int, str) to ndarray of shape (4, 4)
        ``(camera index, view) -> cam_from_board`` for views of at least 4 corners reprojecting within
        :data:`MAX_BOARD_VIEW_RMS_PX`.

    Raises
    ------
    InputError
        A camera with no such view.
    """
    pnp = {}  # (c, view) -> cam_from_board
    for c, (cam, dets) in enumerate(zip(cameras, detections)):
        for view, d in dets.items():
            if len(d.ids) < 4:
                continue
            xy = cam.undistort_points(d.corners)
            ok, r, t = cv2.solvePnP(O[d.ids], xy, np.eye(3), None, flags=cv2.SOLVEPNP_IPPE)
            if not ok:
                continue
            T = np.eye(4)
            T[:3, :3] = cv2.Rodrigues(r)[0]
            T[:3, 3] = t.ravel()
            uv = cam.replace(cam_from_world=T).project(O[d.ids])
            if np.sqrt(np.mean(np.sum((uv - d.corners) ** 2, 1))) <= MAX_BOARD_VIEW_RMS_PX:
                pnp[(c, view)] = T
    for c, cam in enumerate(cameras):
        if not any(k[0] == c for k in pnp):
            raise InputError(f"camera {cam.name}: board views", "at least one view with the board",
                             f"none of {len(detections[c])} usable")
    return pnp


def _chain_cameras(cameras: list[Camera], pnp: dict) -> dict:
    """Camera poses relative to camera 0, chained over shared views breadth first (rotations averaged).

    Parameters
    ----------
    cameras : list of Camera
    pnp : dict of (int, str) to ndarray of shape (4, 4)
        ``(camera index, view) -> cam_from_board``.

    Returns
    -------
    dict of int to ndarray of shape (4, 4)
        ``camera index -> cam_from_cam0``.

    Raises
    ------
    InputError
        Cameras not connected to camera 0 through shared views.
    """
    C = len(cameras)
    # chain cameras over shared views (breadth first from camera 0)
    pose = {0: np.eye(4)}
    frontier = [0]
    while frontier:
        a = frontier.pop(0)
        for b in range(C):
            if b in pose:
                continue
            shared = [v for (c, v) in pnp if c == a and (b, v) in pnp]
            if not shared:
                continue
            rel = [pnp[(b, v)] @ np.linalg.inv(pnp[(a, v)]) for v in shared]  # cam_b_from_cam_a
            T = np.eye(4)
            T[:3, :3] = _mean_rotation([m[:3, :3] for m in rel])
            T[:3, 3] = np.median([m[:3, 3] for m in rel], axis=0)
            pose[b] = T @ pose[a]
            frontier.append(b)
    missing = [cameras[c].name for c in range(C) if c not in pose]
    if missing:
        raise InputError("board views", "every camera sharing a view with another (synchronised names)",
                         f"cameras {missing} share no view with {cameras[0].name}")
    return pose


def extrinsics_from_boards(cameras: list[Camera], detections: list[dict], board: Board,
                           observer=None) -> ExtrinsicsResult:
    """Camera poses from a board seen by several cameras at once.

    Parameters
    ----------
    cameras : list of Camera
        Intrinsics (poses ignored).
    detections : list of dict of str to BoardDetection
        Per camera, its detections by view name; the same name in two cameras is the same
        moment (synchronised images or the same frame number).
    board : Board
    observer : Observer, optional

    Returns
    -------
    ExtrinsicsResult

    Raises
    ------
    InputError
        A camera with no view, or cameras not connected through shared views.
    """
    C = len(cameras)
    if len(detections) != C:
        raise InputError("detections", f"one dict of board views per camera ({C})", f"{len(detections)}")
    O = board.object_points()
    pnp = _board_view_poses(cameras, detections, O)
    pose = _chain_cameras(cameras, pnp)
    # world: the first view of camera 0, z out of the printed side
    ref_view = sorted(v for (c, v) in pnp if c == 0)[0]
    flip = np.diag([1.0, -1.0, -1.0, 1.0])
    world_from_board0 = flip  # board0 coordinates -> world (z up out of the printed side)
    cam0_from_world = pnp[(0, ref_view)] @ np.linalg.inv(world_from_board0)
    cams = [_set_pose(cameras[c], pose[c] @ cam0_from_world) for c in range(C)]
    views = sorted({v for (_, v) in pnp})
    vidx = {v: i for i, v in enumerate(views)}
    board_poses = []
    for v in views:
        c = min(c for (c, vv) in pnp if vv == v)
        board_poses.append(cams[c].world_from_cam @ pnp[(c, v)])
    oc, op, oco, uv = [], [], [], []
    for (c, v) in pnp:
        d = detections[c][v]
        oc += [c] * len(d.ids)
        op += [vidx[v]] * len(d.ids)
        oco += list(d.ids)
        uv.append(d.corners)
    obs = Observations.from_pixels(cams, oc, op, np.concatenate(uv), oco)
    ba = bundle_adjust(cams, obs, board_poses=np.array(board_poses), board_points=O, fixed_cameras=(),
                       loss="linear")
    # re-anchor the world to the reference board (the adjustment moved everything together)
    W = np.linalg.inv(ba.board_poses[vidx[ref_view]] @ np.linalg.inv(world_from_board0))
    cams = [_set_pose(cam, T @ np.linalg.inv(W)) for cam, T in zip(cams, ba.cam_from_world)]
    bposes = np.array([W @ T for T in ba.board_poses])
    rig = Rig(tuple(cams))
    cam_from_board = {(cameras[c].name, v): cams[c].cam_from_world @ bposes[vidx[v]] for (c, v) in pnp}
    warnings = boards_seen_from_behind(cam_from_board) + cameras_under_floor(rig)
    pts = np.concatenate([O @ T[:3, :3].T + T[:3, 3] for T in bposes])
    result = ExtrinsicsResult(rig, pts, reprojection_summary(rig.names, obs.cam, ba.residuals_px), warnings,
                              "board", {"views": views, "reference_view": ref_view,
                                        "board_poses": bposes, "pnp_views": len(pnp)})
    _report(observer, result, ba.residuals_px, obs.cam)
    return result


# --------------------------------------------------------------------------- scene points

#: Scene points farther than this from their reprojection (and 4x the median) are outliers, pixels.
SCENE_OUTLIER_PX = 5.0


def _pnp(cam: Camera, X: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """Pose, RMS error of the inliers (pixels) and inlier mask; RANSAC first when there are 6 points or more."""
    xy = cam.undistort_points(uv)
    f = cam.K[0, 0]
    inl = np.ones(len(X), bool)
    if len(X) >= 6:
        ok, r, t, idx = cv2.solvePnPRansac(X, xy, np.eye(3), None, reprojectionError=2 * SCENE_OUTLIER_PX / f,
                                           iterationsCount=200, flags=cv2.SOLVEPNP_SQPNP)
        if ok and idx is not None and len(idx) >= 4:
            inl = np.zeros(len(X), bool)
            inl[idx.ravel()] = True
    ok, r, t = cv2.solvePnP(X[inl], xy[inl], np.eye(3), None, flags=cv2.SOLVEPNP_SQPNP)
    if not ok:
        return np.eye(4), np.inf, inl
    r, t = cv2.solvePnPRefineLM(X[inl], xy[inl], np.eye(3), None, r, t)
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(r)[0]
    T[:3, 3] = t.ravel()
    e = np.linalg.norm(cam.replace(cam_from_world=T).project(X) - uv, axis=1)
    if not np.all(np.isfinite(e)):
        return T, np.inf, inl
    inl = e <= max(SCENE_OUTLIER_PX, 4 * float(np.median(e)))
    if inl.sum() >= 4 and not inl.all():
        r, t = cv2.solvePnPRefineLM(X[inl], xy[inl], np.eye(3), None, r, t)
        T[:3, :3] = cv2.Rodrigues(r)[0]
        T[:3, 3] = t.ravel()
        e = np.linalg.norm(cam.replace(cam_from_world=T).project(X) - uv, axis=1)
    return T, float(np.sqrt(np.mean(e[inl] ** 2))), inl


def extrinsics_from_scene_points(cameras: list[Camera], points: np.ndarray, pixels: np.ndarray,
                                 names: list[str] | None = None, observer=None) -> ExtrinsicsResult:
    """Camera poses from points of known world coordinates seen in the images.

    Parameters
    ----------
    cameras : list of Camera
        Intrinsics (poses ignored).
    points : ndarray of shape (N, 3)
        World coordinates, metres (z up, the floor at z = 0 for the floor checks).
    pixels : ndarray of shape (n_cams, N, 2)
        Their pixel positions; NaN where a camera does not see a point.
    names : list of str, optional
        Point names for messages.
    observer : Observer, optional

    Returns
    -------
    ExtrinsicsResult

    Raises
    ------
    InputError
        A camera seeing fewer than 4 points, or shapes that do not match.
    """
    X = np.asarray(points, float)
    P = np.asarray(pixels, float)
    if X.ndim != 2 or X.shape[1] != 3 or P.shape != (len(cameras), len(X), 2):
        raise InputError("scene points", f"points (N, 3) and pixels ({len(cameras)}, N, 2)",
                         f"points {X.shape}, pixels {P.shape}")
    names = names or [f"p{i}" for i in range(len(X))]
    cams, warnings, res, ci = [], [], [], []
    mirror = np.diag([1.0, 1.0, -1.0])
    for c, cam in enumerate(cameras):
        ok = np.all(np.isfinite(P[c]), 1)
        if ok.sum() < 4:
            raise InputError(f"scene points: camera {cam.name}", "at least 4 points with pixel positions",
                             f"{int(ok.sum())}")
        T, rms, inl = _pnp(cam, X[ok], P[c, ok])
        _, rms_m, inl_m = _pnp(cam, X[ok] @ mirror, P[c, ok])
        if rms_m < MIRROR_RATIO * rms and inl_m.sum() >= inl.sum() and rms > 2.0:
            warnings.append(f"camera {cam.name}: the scene points fit with an RMS error of {rms_m:.2g} px with one "
                            f"axis flipped against {rms:.3g} px as given: the coordinates are probably left-handed "
                            "(e.g. a y-up file read as z-up); the solution is mirrored")
        cams.append(_set_pose(cam, T))
        e = np.linalg.norm(cams[-1].project(X[ok]) - P[c, ok], axis=1)
        for i in np.flatnonzero(~inl):
            warnings.append(f"camera {cam.name}: point {names[np.flatnonzero(ok)[i]]} is {e[i]:.1f} px from its "
                            "reprojection (left out of the fit): a mis-clicked point or a wrong coordinate")
        res.append(e)
        ci += [c] * len(e)
    rig = Rig(tuple(cams))
    warnings += cameras_under_floor(rig)
    ci = np.array(ci)
    r = np.concatenate(res)
    result = ExtrinsicsResult(rig, X, reprojection_summary(rig.names, ci, r), warnings, "scene",
                              {"n_points": len(X)})
    _report(observer, result, r, ci)
    return result


# --------------------------------------------------------------------------- people

#: Median reprojection error (pixels) of two detections triangulated together within which they are
#: the same person.  On ``pose2sim_multiperson`` (BlazePose, calibrated from its people): pairs of one
#: person median 5.7 px (90 % within 19 px), pairs of two people median 129 px, 1.1 % within 10 px
#: (chance pairs in one epipolar plane, which a third camera rejects).
MATCH_PX = 10.0
#: A camera in fewer groups (people-frames it shares with another camera) than this is not placed.
MIN_CAMERA_GROUPS = 5
#: Camera pairs tried as the start (those sharing most keypoints of matched people); the solution
#: whose people agree in most observations is kept (a start on one person seen by two cameras can
#: settle in a mirrored rig whose people no third camera confirms).
START_PAIRS = 3
#: Times the detections are grouped again with the adjusted poses (and adjusted again).
ASSOCIATION_PASSES = 2


@dataclass(frozen=True)
class PeopleConfig:
    """Settings of :func:`extrinsics_from_people`.

    Attributes
    ----------
    min_confidence : float
        Keypoints below this detection confidence are not used.
    ransac_px : float
        Essential-matrix and PnP RANSAC threshold, pixels.
    f_scale_px : float
        Where the bundle adjustment's robust loss (soft L1) flattens, pixels.
    outlier_px : float
        Observations farther than this from their reprojection after a first adjustment are
        dropped before the second.
    match_px : float
        Two detections of two cameras are the same person when, triangulated together, their
        keypoints reproject within this (median, pixels); in a group of three cameras or more each
        detection must stay within twice this of the group's triangulation.
    scale_bones : tuple of str
        Segments (of :class:`BodyProportions`) whose lengths give the scale.
    """

    min_confidence: float = 0.3
    ransac_px: float = 4.0
    f_scale_px: float = 2.0
    outlier_px: float = 12.0
    match_px: float = MATCH_PX
    scale_bones: tuple = ("upper_arm", "forearm", "thigh", "shank")


#: 14-joint bones measured for the scale: (segment of BodyProportions, joint pairs).
_BONES = {"upper_arm": (("l_shoulder", "l_elbow"), ("r_shoulder", "r_elbow")),
          "forearm": (("l_elbow", "l_wrist"), ("r_elbow", "r_wrist")),
          "thigh": (("l_hip", "l_knee"), ("r_hip", "r_knee")),
          "shank": (("l_knee", "l_ankle"), ("r_knee", "r_ankle"))}


#: The lowest ankles define the floor plane when they spread this far in two directions (a walk), metres.
WALK_SPAN_M = 0.3
#: A frame is "upright" when the thigh-shank line and the trunk are within this angle, degrees.
STRAIGHT_BODY_DEG = 10.0


def _body_up(J: np.ndarray, jidx: dict) -> tuple[np.ndarray, str]:
    """The up direction from a body's upright frames: ankle to mid-shoulders when the body is straight.

    A leaning trunk (balancing, picking something up) is not vertical, but a straight body
    (hip on the ankle-shoulder line) stands upright; the median direction over those frames is up.
    Fewer than 5 such frames: the median trunk direction (hips to shoulders).
    """
    sh = 0.5 * (J[:, jidx["l_shoulder"]] + J[:, jidx["r_shoulder"]])
    dirs = []
    for side in ("l", "r"):
        hip, ank = J[:, jidx[f"{side}_hip"]], J[:, jidx[f"{side}_ankle"]]
        leg, trunk = hip - ank, sh - hip
        with np.errstate(invalid="ignore", divide="ignore"):
            c = np.einsum("ti,ti->t", leg, trunk) / (np.linalg.norm(leg, axis=1) * np.linalg.norm(trunk, axis=1))
            body = (sh - ank) / np.linalg.norm(sh - ank, axis=1, keepdims=True)
        ok = np.isfinite(c) & (c > np.cos(np.radians(STRAIGHT_BODY_DEG))) & np.isfinite(body).all(1)
        dirs.append(body[ok])
    dirs = np.concatenate(dirs)
    if len(dirs) >= 5:
        up = np.median(dirs, axis=0)
        return up / np.linalg.norm(up), f"up from {len(dirs)} upright poses (ankle to shoulders)"
    trunk = sh - 0.5 * (J[:, jidx["l_hip"]] + J[:, jidx["r_hip"]])
    trunk = trunk[np.isfinite(trunk).all(1)]
    if len(trunk) == 0:
        raise InputError("keypoints", "shoulders and hips seen in 2 cameras (the up direction)", "none")
    up = np.median(trunk / np.linalg.norm(trunk, axis=1, keepdims=True), axis=0)
    return up / np.linalg.norm(up), "up from the trunk (no upright pose found)"


def _matched_groups(cameras, xy, seen, f, cfg: "PeopleConfig", rng) -> tuple[np.ndarray, np.ndarray]:
    """Detections of the same person in several cameras, from the detection pairs every camera pair matches.

    Returns the groups (G, C) of detection indices (-1: none) and their frames (G,).
    """
    C = len(cameras)
    matches = [m for a in range(C) for b in range(a + 1, C)
               if (m := match_camera_pair(xy, seen, a, b, (f[a], f[b]), cfg.ransac_px, cfg.match_px, rng))
               is not None and m.inliers >= 8]
    if not matches:
        shared = max((int((seen[a][:, :, None] & seen[b][:, None]).sum(-1).max(axis=(1, 2)).sum())
                      for a in range(C) for b in range(a + 1, C)), default=0)
        raise InputError("keypoints", "at least 8 keypoints seen by two cameras at once (the same person in both)",
                         f"none that agree, of at most {shared} seen by two cameras")
    return group_pair_matches(matches, C)


def _start_pairs(seen: np.ndarray, n: int) -> list[tuple[int, int]]:
    """The ``n`` camera pairs sharing most of the (C, N) observations, most first."""
    C = len(seen)
    common = [(int(np.sum(seen[a] & seen[b])), a, b) for a in range(C) for b in range(a + 1, C)]
    return [(a, b) for k, a, b in sorted(common, reverse=True)[:n] if k >= 8]


def _initial_poses(cameras, xy: np.ndarray, seen: np.ndarray, f: np.ndarray, cfg: "PeopleConfig",
                   a: int, b: int) -> list:
    """First poses from associated (C, N, 2) observations: the essential matrix of the camera pair
    ``a``, ``b``, then PnP camera by camera on the triangulated points (unit baseline, ``a`` at the origin).
    """
    C = len(cameras)
    m = seen[a] & seen[b]
    thr = cfg.ransac_px / np.sqrt(f[a] * f[b])
    E, inl = cv2.findEssentialMat(xy[a, m], xy[b, m], np.eye(3), cv2.RANSAC, 0.999, thr)
    if E is None:
        raise InputError("keypoints", "keypoints from which an essential matrix can be estimated",
                         f"none for cameras {cameras[a].name}, {cameras[b].name}")
    _, R, t, _ = cv2.recoverPose(E[:3], xy[a, m], xy[b, m], np.eye(3), mask=inl.copy())
    poses = np.tile(np.eye(4), (C, 1, 1))
    poses[b, :3, :3], poses[b, :3, 3] = R, t.ravel()
    registered = np.zeros(C, bool)
    registered[[a, b]] = True

    def tri():
        obs = np.where((seen & registered[:, None])[..., None], xy, np.nan)
        X = triangulate_normalised(poses, obs)
        for c in np.flatnonzero(registered):
            z = np.where(np.isfinite(X), X, 0.0) @ poses[c, 2, :3] + poses[c, 2, 3]
            X[seen[c] & (z <= 0)] = np.nan
        return X

    X = tri()
    while not registered.all():
        cands = np.flatnonzero(~registered)
        counts = [np.sum(seen[c] & np.isfinite(X).all(1)) for c in cands]
        c = cands[int(np.argmax(counts))]
        mm = seen[c] & np.isfinite(X).all(1)
        if mm.sum() < 6:
            raise InputError("keypoints", f"camera {cameras[c].name} seeing at least 6 keypoints the others see",
                             f"{int(mm.sum())}")
        ok, r, tt, _ = cv2.solvePnPRansac(X[mm], xy[c, mm], np.eye(3), None,
                                          reprojectionError=cfg.ransac_px / f[c], iterationsCount=500,
                                          flags=cv2.SOLVEPNP_SQPNP)
        if not ok:
            raise InputError("keypoints", f"keypoints placing camera {cameras[c].name}", "a failed PnP")
        poses[c, :3, :3], poses[c, :3, 3] = cv2.Rodrigues(r)[0], tt.ravel()
        registered[c] = True
        X = tri()
    return [_set_pose(cam, T) for cam, T in zip(cameras, poses)]


def _solve(cur: list, a: int, groups: np.ndarray, gframes: np.ndarray, xy: np.ndarray, seen: np.ndarray,
           f: np.ndarray, cfg: "PeopleConfig") -> tuple:
    """Adjust the first poses on the first groups; then, with the poses, every frame's detections grouped
    into people again and adjusted again (until the groups stay the same, :data:`ASSOCIATION_PASSES` at most).

    Returns the cameras, the points (G * K, 3), the residuals (pixels), their cameras, the groups and frames.
    """
    C = len(cur)
    gx, gs = group_observations(groups, gframes, xy, seen)
    cur, X, residuals, res_cam = adjust_observations(cur, gx.reshape(C, -1, 2), gs.reshape(C, -1), a, cfg)
    for _ in range(ASSOCIATION_PASSES):
        g, gf, _ = associate_detections(np.stack([c.cam_from_world for c in cur]), xy, seen, f, cfg.match_px)
        if not len(g) or (g.shape == groups.shape and np.array_equal(g, groups) and np.array_equal(gf, gframes)):
            break
        groups, gframes = g, gf
        gx, gs = group_observations(groups, gframes, xy, seen)
        cur, X, residuals, res_cam = adjust_observations(cur, gx.reshape(C, -1, 2), gs.reshape(C, -1), a, cfg)
    return cur, X, residuals, res_cam, groups, gframes


def adjust_observations(cur: list, xy: np.ndarray, seen: np.ndarray, fixed: int, cfg: "PeopleConfig"):
    """Two rounds of bundle adjustment of (C, N, 2) observations, the second without gross outliers.

    ``xy`` are normalised (undistorted) image points per camera and point, ``seen`` (C, N) where they
    are observed; camera ``fixed`` holds the gauge; ``cfg`` gives ``f_scale_px`` and ``outlier_px``.

    Returns the cameras, the points (N, 3) (NaN where not adjusted), the residuals (pixels) and their cameras.
    """
    seen = seen.copy()
    poses = np.stack([c.cam_from_world for c in cur])
    X = triangulate_normalised(poses, np.where(seen[..., None], xy, np.nan))
    keep = np.isfinite(X).all(1)
    for round_ in range(2):
        pid = -np.ones(len(X), int)
        pid[keep] = np.arange(keep.sum())
        oc, op = np.nonzero(seen[:, keep])
        op_global = np.flatnonzero(keep)[op]
        obs = Observations(oc, pid[op_global], xy[oc, op_global])
        ba = bundle_adjust(cur, obs, points=X[keep], fixed_cameras=(fixed,), loss="soft_l1",
                           f_scale_px=cfg.f_scale_px, max_nfev=100)
        cur = [_set_pose(cam, T) for cam, T in zip(cur, ba.cam_from_world)]
        X = np.full_like(X, np.nan)
        X[keep] = ba.points
        if round_ == 0:
            bad = ba.residuals_px > cfg.outlier_px
            seen[oc[bad], op_global[bad]] = False
            keep &= seen.sum(0) >= 2
    return cur, X, ba.residuals_px, obs.cam


def extrinsics_from_people(cameras: list[Camera], keypoints: np.ndarray, keypoint_names, fmt: str | None = None,
                           height_m: float | None = None, bone_lengths_m: dict | None = None,
                           config: PeopleConfig | None = None, rng: np.random.Generator | None = None,
                           observer=None) -> ExtrinsicsResult:
    """Camera poses from 2D keypoints of people moving through the volume.

    The detections need not be associated across cameras.  Every camera pair matches its
    detections by RANSAC over detection pairs (:func:`~toolkit.calibration.people_matching.match_camera_pair`)
    and the matches of all pairs are joined into people-frames.  From each of the
    :data:`START_PAIRS` camera pairs sharing most of them: an essential matrix and PnP of the other
    cameras give first poses, a bundle adjustment refines them, and (up to
    :data:`ASSOCIATION_PASSES` times) every frame's detections are grouped into people with the
    poses (:func:`~toolkit.calibration.people_matching.associate_detections`) and adjusted again.
    The solution with most observations within ``outlier_px`` is kept.

    Parameters
    ----------
    cameras : list of Camera
        Intrinsics (poses ignored); at least 2.
    keypoints : ndarray of shape (n_cams, T, K, 3) or (n_cams, T, P, K, 3)
        ``(x, y, confidence)`` pixels in synchronised frames; NaN / confidence 0 missing.  Either one
        detection per camera and frame (e.g. each camera's most confident person: a frame where
        the cameras picked different people gives one group per person seen by two or more), or
        up to ``P`` detections per camera and frame in any order (every person the detector found:
        :func:`toolkit.calibration.people_matching.detections_array`).  Detections no other camera
        agrees with (bystanders seen by one camera) are left out.
    keypoint_names : sequence of str
        The K keypoint names (e.g. ``toolkit.skeleton.mappings.KEYPOINTS[fmt]``).
    fmt : str, optional
        Format of the keypoints for the 14-joint mapping (scale and floor); ``"skeleton14"`` when the
        keypoints already are the 14 joints.
    height_m : float, optional
        The people's stature, metres (the scale).
    bone_lengths_m : dict of str to float, optional
        Measured segment lengths (``upper_arm``, ``forearm``, ``thigh``, ``shank``), metres; override
        the stature's proportions.
    config : PeopleConfig, optional
    rng : numpy.random.Generator, optional
        Draws the RANSAC samples and seeds OpenCV's RANSAC (``cv2.setRNGSeed``): repeatable results.
    observer : Observer, optional

    Returns
    -------
    ExtrinsicsResult
        ``details`` holds ``scale`` (metres per unit of the first reconstruction), ``scale_from``,
        ``bone_scales``, ``floor_from``, the number of observations, ``groups`` (people-frames used)
        and ``groups_by_views``, ``detections_unmatched`` (detections with keypoints in no group),
        and ``keypoints3d`` (T, K, 3): per frame the group seen by most cameras, adjusted, in the
        world frame (NaN where none).

    Raises
    ------
    InputError
        Fewer than 2 cameras, wrong shapes, or too few agreeing keypoints to start or to place a camera.
    """
    cfg = config or PeopleConfig()
    names, kp = _people_keypoints(cameras, keypoints, keypoint_names)
    rng = np.random.default_rng(rng)
    cv2.setRNGSeed(int(rng.integers(0, 2 ** 31 - 1)))
    T_, K_ = kp.shape[1], kp.shape[3]
    xy, seen, f = _normalised_detections(cameras, kp, cfg)
    a, cur, X, residuals, res_cam, groups, gframes = _best_start(cameras, xy, seen, f, cfg, rng)
    G = len(groups)
    unmatched = _unmatched_detections(groups, gframes, seen)
    # ---- scale, up and floor from the body
    P3 = X.reshape(G, K_, 3)
    J = P3 if fmt in (None, "skeleton14") and K_ == 14 else to_skeleton14(P3, fmt)
    jidx = {n: i for i, n in enumerate(JOINTS_14)}
    stature = height_m if height_m is not None else DEFAULT_STATURE_M
    prior = BodyProportions.from_height(stature)
    scale, scale_from, bone_scales, warnings = _body_scale(J, jidx, prior, height_m, bone_lengths_m, cfg)
    Xs = X * scale
    Js = J * scale
    up, floor, floor_from, ankles = _up_and_floor(Js, jidx, prior)
    R_wr, W = _world_from_recon(cur[0], scale, ankles, up, floor)
    rig = _rig_in_world(cur, scale, W)
    Xw = Xs @ R_wr.T + W[:3, 3]
    Xg = Xw.reshape(G, K_, 3)
    named = {normalise_name(n): Xg[:, i] for i, n in enumerate(names)}
    warnings += mirrored_person_warning(named) + cameras_under_floor(rig)
    per_frame = np.full((T_, K_, 3), np.nan)
    fr, first = np.unique(gframes, return_index=True)  # within a frame, the group seen by most cameras comes first
    per_frame[fr] = Xg[first]
    views = (groups >= 0).sum(1)
    details = {"scale": scale, "scale_from": scale_from, "bone_scales": bone_scales, "floor_from": floor_from,
               "start_camera": cameras[a].name, "observations": int(len(residuals)),
               "points": int(np.isfinite(Xw).all(1).sum()), "groups": G,
               "groups_by_views": {int(v): int((views == v).sum()) for v in np.unique(views)},
               "detections_unmatched": unmatched, "keypoints3d": per_frame}
    result = ExtrinsicsResult(rig, Xw[np.isfinite(Xw).all(1)], reprojection_summary(rig.names, res_cam, residuals),
                              warnings, "people", details)
    _report(observer, result, residuals, res_cam)
    return result


def _people_keypoints(cameras: list[Camera], keypoints, keypoint_names) -> tuple[list, np.ndarray]:
    """Check the keypoints and their names.

    Parameters
    ----------
    cameras : list of Camera
    keypoints : array_like of shape (n_cams, T, K, 3) or (n_cams, T, P, K, 3)
    keypoint_names : sequence of str

    Returns
    -------
    names : list of str
        The K names.
    kp : ndarray of shape (n_cams, T, P, K, 3)
        The keypoints as floats, with a person axis of length 1 added to 4-D input.

    Raises
    ------
    InputError
        Fewer than 2 cameras, a shape other than the above, or a number of names other than K.
    """
    kp = np.asarray(keypoints, float)
    C = len(cameras)
    if kp.ndim == 4:
        kp = kp[:, :, None]
    if C < 2 or kp.ndim != 5 or kp.shape[0] != C or kp.shape[-1] != 3:
        raise InputError("keypoints", f"an array (n_cams={C} >= 2, T, [P,] K, 3) of (x, y, confidence)",
                         f"shape {np.shape(keypoints)}")
    names = list(keypoint_names)
    if len(names) != kp.shape[3]:
        raise InputError("keypoint_names", f"{kp.shape[3]} names", f"{len(names)}")
    return names, kp


def _normalised_detections(cameras: list[Camera], kp: np.ndarray,
                           cfg: "PeopleConfig") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Undistorted normalised image coordinates of the confident keypoints.

    Parameters
    ----------
    cameras : list of Camera
    kp : ndarray of shape (n_cams, T, P, K, 3)
        ``(x, y, confidence)``, pixels.
    cfg : PeopleConfig

    Returns
    -------
    xy : ndarray of shape (n_cams, T, P, K, 2)
        Normalised coordinates (NaN where not seen).
    seen : ndarray of bool, shape (n_cams, T, P, K)
        Confidence at least ``min_confidence`` and finite pixels.
    f : ndarray of shape (n_cams,)
        Focal lengths, pixels.
    """
    uv = kp[..., :2].copy()
    seen = (kp[..., 2] >= cfg.min_confidence) & np.isfinite(uv).all(-1)
    uv[~seen] = np.nan
    xy = np.stack([cam.undistort_points(uv[c]) for c, cam in enumerate(cameras)])
    f = np.array([cam.K[0, 0] for cam in cameras])
    return xy, seen, f


def _best_start(cameras: list[Camera], xy: np.ndarray, seen: np.ndarray, f: np.ndarray, cfg: "PeopleConfig",
                rng: np.random.Generator):
    """The same person in several cameras (before any pose), first poses from each of the camera pairs sharing
    most of them, and the solution whose people agree in the most observations.

    Parameters
    ----------
    cameras : list of Camera
    xy : ndarray of shape (n_cams, T, P, K, 2)
        Normalised coordinates.
    seen : ndarray of bool, shape (n_cams, T, P, K)
    f : ndarray of shape (n_cams,)
        Focal lengths, pixels.
    cfg : PeopleConfig
    rng : numpy.random.Generator

    Returns
    -------
    a : int
        The start camera (fixed in the adjustment).
    cur : list of Camera
        Cameras with the adjusted poses (unscaled reconstruction frame).
    X : ndarray of shape (G * K, 3)
        The adjusted points (NaN where not adjusted).
    residuals : ndarray of shape (M,)
        Reprojection errors, pixels.
    res_cam : ndarray of int, shape (M,)
        The camera of each residual.
    groups : ndarray of int, shape (G, n_cams)
        The detection of each camera in each people-frame (-1 none).
    gframes : ndarray of int, shape (G,)
        The frame of each group.

    Raises
    ------
    InputError
        No camera pair to start from, or a camera seeing fewer than :data:`MIN_CAMERA_GROUPS` people-frames.
    """
    C = len(cameras)
    groups0, gframes0 = _matched_groups(cameras, xy, seen, f, cfg, rng)
    gx, gs = group_observations(groups0, gframes0, xy, seen)
    best, failure = None, None
    for a, b in _start_pairs(gs.reshape(C, -1), START_PAIRS):
        try:
            first = _initial_poses(cameras, gx.reshape(C, -1, 2), gs.reshape(C, -1), f, cfg, a, b)
        except InputError as e:
            failure = e
            continue
        sol = _solve(first, a, groups0, gframes0, xy, seen, f, cfg)
        if best is None or np.sum(sol[2] <= cfg.outlier_px) > np.sum(best[1][2] <= cfg.outlier_px):
            best = (a, sol)
    if best is None:
        raise failure or InputError("keypoints", "two cameras sharing at least 8 keypoints of one person", "none")
    a, (cur, X, residuals, res_cam, groups, gframes) = best
    per_cam = (groups >= 0).sum(0)
    if per_cam.min() < MIN_CAMERA_GROUPS:
        c = int(np.argmin(per_cam))
        raise InputError("keypoints", f"camera {cameras[c].name} seeing at least {MIN_CAMERA_GROUPS} "
                         "people-frames that other cameras see too (give every detection of every frame when "
                         "several people are in view, not one person per camera)", f"{int(per_cam[c])}")
    return a, cur, X, residuals, res_cam, groups, gframes


def _unmatched_detections(groups: np.ndarray, gframes: np.ndarray, seen: np.ndarray) -> int:
    """Detections with keypoints in no group.

    Parameters
    ----------
    groups : ndarray of int, shape (G, n_cams)
    gframes : ndarray of int, shape (G,)
    seen : ndarray of bool, shape (n_cams, T, P, K)

    Returns
    -------
    int
    """
    C = seen.shape[0]
    used = np.zeros(seen.shape[:3], bool)
    for c in range(C):
        k = groups[:, c] >= 0
        used[c, gframes[k], groups[k, c]] = True
    return int((seen.any(-1) & ~used).sum())


def _body_scale(J: np.ndarray, jidx: dict, prior: BodyProportions, height_m: float | None,
                bone_lengths_m: dict | None, cfg: "PeopleConfig") -> tuple[float, str, dict, list[str]]:
    """Metres per unit of the reconstruction, from the median ratio of known to reconstructed bone lengths.

    Parameters
    ----------
    J : ndarray of shape (G, 14, 3)
        The 14 joints of each people-frame, reconstruction units.
    jidx : dict of str to int
        Index of each of :data:`~toolkit.skeleton.JOINTS_14`.
    prior : BodyProportions
        Proportions of the stature.
    height_m : float or None
    bone_lengths_m : dict of str to float or None
    cfg : PeopleConfig

    Returns
    -------
    scale : float
    scale_from : str
    bone_scales : dict of str to float
        The scale each bone gives.
    warnings : list of str
        An assumed stature, or bones that disagree by more than 25 %.

    Raises
    ------
    InputError
        No limb seen often enough for the scale.
    """
    bone_scales = {}
    for bone in cfg.scale_bones:
        target = (bone_lengths_m or {}).get(bone, getattr(prior, bone))
        lens = np.concatenate([np.linalg.norm(J[:, jidx[p]] - J[:, jidx[q]], axis=1) for p, q in _BONES[bone]])
        lens = lens[np.isfinite(lens)]
        if len(lens) >= 3:
            bone_scales[bone] = float(target / np.median(lens))
    warnings = []
    if not bone_scales:
        raise InputError("keypoints", "limbs (shoulder-elbow-wrist, hip-knee-ankle) seen in 2 cameras for the scale",
                         "none")
    scale = float(np.median(list(bone_scales.values())))
    spread = (max(bone_scales.values()) - min(bone_scales.values())) / scale
    if height_m is None and not bone_lengths_m:
        scale_from = f"assumed stature {DEFAULT_STATURE_M} m (bone length priors)"
        warnings.append(f"scale ambiguous: no --height or bone lengths given, a {DEFAULT_STATURE_M} m person assumed; "
                        f"distances may be off by about {STATURE_SPREAD:.0%} (adult stature spread)")
    else:
        scale_from = "measured bone lengths" if bone_lengths_m else f"stature {height_m} m (bone length priors)"
    if spread > 0.25:
        warnings.append(f"scale ambiguous: the bones disagree by {spread:.0%} "
                        f"({', '.join(f'{k} {v:.3g}' for k, v in bone_scales.items())}); the keypoints may not be "
                        "one person, or the detector's joints are biased")
    return scale, scale_from, bone_scales, warnings


def _up_and_floor(Js: np.ndarray, jidx: dict, prior: BodyProportions) -> tuple[np.ndarray, float, str, np.ndarray]:
    """The up direction (trunk, or the plane of the standing ankles) and the floor height under the ankles.

    Parameters
    ----------
    Js : ndarray of shape (G, 14, 3)
        The 14 joints of each people-frame, metres (scaled reconstruction frame).
    jidx : dict of str to int
    prior : BodyProportions
        Gives the ankle height above the floor.

    Returns
    -------
    up : ndarray of shape (3,)
        Unit up direction.
    floor : float
        Height of the floor along ``up``, metres.
    floor_from : str
        How ``up`` and the floor were found.
    ankles : ndarray of shape (N, 3)
        The finite ankle positions, metres.

    Raises
    ------
    InputError
        Fewer than 10 ankles seen.
    """
    up, up_from = _body_up(Js, jidx)
    la, ra = Js[:, jidx["l_ankle"]], Js[:, jidx["r_ankle"]]
    ankles = np.concatenate([la, ra])
    ankles = ankles[np.isfinite(ankles).all(1)]
    floor_from = f"{up_from}; floor under the lowest ankles"
    if len(ankles) < 10:
        raise InputError("keypoints", "ankles seen in 2 cameras (the floor)", f"{len(ankles)}")
    # the standing foot of each frame: the lower ankle (the one that rests while walking)
    both = np.isfinite(la).all(1) & np.isfinite(ra).all(1)
    low = np.where(((la @ up) <= (ra @ up))[:, None], la, ra)[both]
    if len(low) >= 10:
        centred = low - low.mean(0)
        ev, evec = np.linalg.eigh(centred.T @ centred / len(low))
        if ev[1] > WALK_SPAN_M ** 2 and ev[0] < 0.03 ** 2:  # the standing feet span a plane: its normal is up
            n = evec[:, 0] * np.sign(evec[:, 0] @ up)
            if n @ up > np.cos(np.radians(20)):
                up, floor_from = n, f"plane of the standing ankles of {len(low)} frames"
    h = ankles @ up
    floor = float(np.percentile(h, 10)) - prior.ankle_height
    return up, floor, floor_from, ankles


def _world_from_recon(cam0: Camera, scale: float, ankles: np.ndarray, up: np.ndarray,
                      floor: float) -> tuple[np.ndarray, np.ndarray]:
    """The world frame: z = up, origin under the mean resting feet, x towards the first camera's side.

    Parameters
    ----------
    cam0 : Camera
        The first camera, unscaled reconstruction frame.
    scale : float
        Metres per reconstruction unit.
    ankles : ndarray of shape (N, 3)
        Metres, scaled reconstruction frame.
    up : ndarray of shape (3,)
    floor : float
        Metres along ``up``.

    Returns
    -------
    R_wr : ndarray of shape (3, 3)
        world_from_recon rotation.
    W : ndarray of shape (4, 4)
        world_from_recon transform (scaled reconstruction to world, metres).
    """
    c0 = -cam0.R.T @ cam0.t * scale
    origin = ankles.mean(0)
    origin = origin - (origin @ up - floor) * up
    x = np.cross(up, c0 - origin)
    x = np.cross(x, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(up, [1.0, 0, 0])
    x /= np.linalg.norm(x)
    y = np.cross(up, x)
    R_wr = np.stack([x, y, up])  # world_from_recon rotation
    W = np.eye(4)
    W[:3, :3] = R_wr
    W[:3, 3] = -R_wr @ origin
    return R_wr, W


def _rig_in_world(cur: list[Camera], scale: float, W: np.ndarray) -> Rig:
    """The cameras scaled to metres and moved into the world frame.

    Parameters
    ----------
    cur : list of Camera
        Poses in the unscaled reconstruction frame.
    scale : float
        Metres per reconstruction unit.
    W : ndarray of shape (4, 4)
        world_from_recon (scaled).

    Returns
    -------
    Rig
    """
    Winv = np.linalg.inv(W)
    cams = []
    for cam in cur:
        T = cam.cam_from_world.copy()
        T[:3, 3] *= scale  # scaled reconstruction
        cams.append(_set_pose(cam, T @ Winv))
    return Rig(tuple(cams))


# --------------------------------------------------------------------------- comparison

def similarity_align(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Scale, rotation and translation mapping ``src`` points onto ``dst`` (Umeyama, least squares).

    Parameters
    ----------
    src, dst : ndarray of shape (N, 3)

    Returns
    -------
    s : float
    R : ndarray of shape (3, 3)
    t : ndarray of shape (3,)
        ``dst ~ s * R @ src + t``.
    """
    src, dst = np.asarray(src, float), np.asarray(dst, float)
    ms, md = src.mean(0), dst.mean(0)
    A, B = src - ms, dst - md
    U, D, Vt = np.linalg.svd(B.T @ A / len(src))
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1
    R = U @ S @ Vt
    s = float(np.trace(np.diag(D) @ S) / (A ** 2).sum(1).mean())
    return s, R, md - s * R @ ms
