"""Initialisation of the soft body in one frame: a rough scaling of the skeleton and an approximate pose.

Source 002 initialises interactively: key joints clicked in two images and
triangulated.  Here the joints come either as 3D positions (the project's own
stage 1 or depth tracker, :func:`model_from_joints`) or as 2D positions in two
calibrated images (:func:`init_from_2d`, triangulated with
:func:`toolkit.cameras.triangulation.triangulate_linear`).  Segment lengths
are measured on the joints, the stature estimated from them sets the
reference metaball radii, the angles come from
:func:`toolkit.motion.inverse_kinematics` and are then refined by a least-squares
fit of the model's joints to the given ones (``scipy.optimize.least_squares``
with the model's analytic joint Jacobian).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from toolkit.anthropometry.proportions import STATURE_RATIOS, BodyProportions
from toolkit.cameras.triangulation import triangulate_linear
from toolkit.errors import InputError
from toolkit.motion.kinematics import Pose14, inverse_kinematics
from toolkit.skeleton import SKELETON_14
from toolkit.softbody.model import (LENGTH_NAMES, LENGTHS, N_POSE, STATURE_CHAIN, SYMMETRIC_LENGTHS, TRUNK_POSTURE,
                                    WIDTH_GROUPS, SoftBodyModel, SoftBodyParams, pose_bounds)
from toolkit.softbody.residuals import one_blas_thread

__all__ = ["params_from_pose14", "model_from_joints", "init_from_2d", "fit_pose_to_joints", "STATURE_LIMITS",
           "RefineConfig", "refine_on_cloud", "refine_initial_model", "stature_of", "SYMMETRIC_LENGTHS"]

_J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
#: Statures the estimate from the joints is clipped to (metres): the metaball radii scale with it.
STATURE_LIMITS = (1.3, 2.1)
#: Head centre above the floor as a fraction of stature, minus the ankle height.
_HEAD_ABOVE_ANKLE = (STATURE_RATIOS["neck_height"] - STATURE_RATIOS["ankle_height"]
                     + STATURE_RATIOS["neck_to_head"])
#: Default pull of the trunk's bend and twist towards 0 when the model is posed on given joints, metres per
#: radian (:func:`fit_pose_to_joints`); see :func:`model_from_joints`.
POSTURE_WEIGHT = 0.2


def params_from_pose14(pose: Pose14, t: int, lengths, widths=None) -> SoftBodyParams:
    """Soft-body parameters of frame ``t`` of a :class:`~toolkit.motion.Pose14`.

    Parameters
    ----------
    pose : Pose14
    t : int
        Frame index.
    lengths : array_like of shape (13,)
        Metres, :data:`~toolkit.softbody.LENGTH_NAMES`.
    widths : array_like of shape (7,), optional
        Default 1.

    Returns
    -------
    SoftBodyParams
        The trunk's lateral bend is 0 (the motion library has none).
    """
    rv = Rotation.from_matrix(pose.pelvis_rotation()[t]).as_rotvec()
    ang = [pose.lean[t], 0.0, pose.twist[t], pose.head_pitch[t], pose.head_roll[t]]
    for side in (0, 1):
        ang += [*pose.shoulder[t, side], pose.elbow[t, side]]
    for side in (0, 1):
        ang += [*pose.hip[t, side], pose.knee[t, side]]
    w = np.ones(len(WIDTH_GROUPS)) if widths is None else widths
    return SoftBodyParams.build(np.r_[rv, pose.root[t], ang], lengths, w)


def _lengths_from_joints(j: np.ndarray, pose: Pose14) -> np.ndarray:
    g = {n: j[i] for n, i in _J.items()}
    dist = lambda a, b: float(np.linalg.norm(g[a] - g[b]))  # noqa: E731
    mid_hip = 0.5 * (g["l_hip"] + g["r_hip"])
    Rt = pose.trunk_rotation()[0]
    drop = [-(Rt.T @ (g[f"{s}_shoulder"] - g["neck"]))[2] for s in "lr"]
    v = {"neck_to_head": dist("neck", "head"), "shoulder_half_width": 0.5 * dist("l_shoulder", "r_shoulder"),
         "shoulder_drop": max(float(np.mean(drop)), 0.005), "torso": float(np.linalg.norm(g["neck"] - mid_hip)),
         "hip_half_width": 0.5 * dist("l_hip", "r_hip")}
    for s in "lr":
        v.update({f"{s}_upper_arm": dist(f"{s}_shoulder", f"{s}_elbow"),
                  f"{s}_forearm": dist(f"{s}_elbow", f"{s}_wrist"),
                  f"{s}_thigh": dist(f"{s}_hip", f"{s}_knee"), f"{s}_shank": dist(f"{s}_knee", f"{s}_ankle")})
    return np.maximum(np.array([v[n] for n in LENGTH_NAMES]), 1e-3)


def fit_pose_to_joints(model: SoftBodyModel, params: SoftBodyParams, joints: np.ndarray, *,
                       fit_lengths: bool = False, posture_weight: float = 0.0) -> SoftBodyParams:
    """Refine the pose (and optionally the lengths) so that the model's joints meet ``joints``.

    Parameters
    ----------
    model : SoftBodyModel
    params : SoftBodyParams
        Start.
    joints : ndarray of shape (14, 3)
        Metres, world.
    fit_lengths : bool
    posture_weight : float
        Pull of the trunk's lateral bend and axial twist relative to the
        pelvis towards 0, metres (of joint residual) per radian; 0: none.
        For joints with errors of a few centimetres (clicks, a tracker's
        hips): see :func:`model_from_joints`.

    Returns
    -------
    SoftBodyParams
    """
    target = np.asarray(joints, float)
    cols = np.r_[np.arange(N_POSE), np.arange(LENGTHS.start, LENGTHS.stop) if fit_lengths else []].astype(int)
    lo, hi = pose_bounds()
    lo = np.r_[lo, np.full(len(cols) - N_POSE, 0.01)]
    hi = np.r_[hi, np.full(len(cols) - N_POSE, 2.0)]
    x0 = np.clip(params.vector[cols], lo + 1e-9, hi - 1e-9)

    def full(x):
        v = params.vector.copy()
        v[cols] = x
        return SoftBodyParams(v)

    if not (np.isfinite(posture_weight) and posture_weight >= 0):
        raise InputError("posture_weight", "a finite weight >= 0 (metres per radian)", repr(posture_weight))
    prior = np.zeros((len(TRUNK_POSTURE), len(cols)))
    prior[np.arange(len(TRUNK_POSTURE)), TRUNK_POSTURE] = posture_weight  # pose entries come first in cols

    def fun(x):
        return np.r_[(model.joints(full(x)) - target).ravel(), prior @ x]

    def jac(x):
        return np.vstack([model.joints_jacobian(full(x)).reshape(42, -1)[:, cols], prior])

    with one_blas_thread():
        res = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, max_nfev=100)
    return full(res.x)


def stature_of(lengths) -> float:
    """Stature (metres, unclipped) from the vertical chain of segment lengths (13,): shank + thigh (means of the
    two sides) + torso + neck-to-head, with the anthropometric ratios."""
    return float(STATURE_CHAIN @ np.asarray(lengths, float) / _HEAD_ABOVE_ANKLE)


def model_from_joints(joints, *, stature: float | None = None, girth: float = 1.0,
                      posture_weight: float = POSTURE_WEIGHT) -> tuple[SoftBodyModel, SoftBodyParams]:
    """A soft body scaled and posed on 3D joints (the initialisation of source 002).

    Parameters
    ----------
    joints : array_like of shape (14, 3)
        Metres, world, z up, order of ``SKELETON_14`` (e.g. stage 1's or the depth tracker's output).
    stature : float, optional
        Metres; default estimated from the vertical chain (shank + thigh + torso
        + neck-to-head) with the anthropometric ratios, clipped to :data:`STATURE_LIMITS`.
    girth : float
        Radial size multiplier of the reference radii.
    posture_weight : float
        Pull of the trunk's lateral bend and axial twist (relative to the
        pelvis) towards 0 in the pose's least-squares fit, metres per radian
        (:func:`fit_pose_to_joints`).  The pelvis's roll and yaw rest on the
        two hip joints alone, 0.2 m apart and the hardest joints to click or
        track: with 3 px of click noise (about 3 cm at 3 m) the clicked hips
        gave the trunk 8-28 degrees of bend and up to 31 degrees of twist
        against the pelvis (16 trinocular runs of seeds 13000 and 14000, none
        in the true poses), and neither tracking nor the global fit moved them
        (the trunk's and thighs' surface hides the pelvis's roll): one hip
        ended 40-50 mm high, the other as low.  At 0.2 m/rad (a prior of
        about 8 degrees' spread against hips of about 3 cm error) the trunk,
        seen on shoulders, neck and hips together, sets the pelvis; a real
        bend or twist still shows where the joints agree on it.  0: the
        joints alone (exact joints).

    Returns
    -------
    model : SoftBodyModel
        Reference radii of a median person of that stature.
    params : SoftBodyParams
        Lengths measured on the joints (shoulder offsets symmetric), widths 1,
        pose from inverse kinematics refined by least squares.

    Raises
    ------
    InputError
        If ``joints`` is not a finite (14, 3) array, its bone lengths give an
        implausible stature (not metres), or ``stature`` is out of range.
    """
    j = np.asarray(joints, float)
    if j.shape != (14, 3) or not np.all(np.isfinite(j)):
        raise InputError("joints", "a finite array of shape (14, 3), metres (SKELETON_14 order)",
                         f"shape {j.shape}" + ("" if j.shape != (14, 3) else " with NaN/inf"))
    pose = inverse_kinematics(j)
    lengths = _lengths_from_joints(j, pose)
    if stature is None:
        h = stature_of(lengths)
        if not 0.5 * STATURE_LIMITS[0] <= h <= 2.0 * STATURE_LIMITS[1]:
            raise InputError("joints", "the joints of a person in metres (a stature of "
                             f"{0.5 * STATURE_LIMITS[0]:.2f}-{2.0 * STATURE_LIMITS[1]:.1f} m from the bone lengths)",
                             f"a stature of {h:.3g} m (millimetres? mixed-up joints?)")
        stature = float(np.clip(h, *STATURE_LIMITS))
    elif not (np.isfinite(stature) and 1.0 <= stature <= 2.5):
        raise InputError("stature", "a stature between 1.0 and 2.5 metres", repr(stature))
    model = SoftBodyModel(BodyProportions.from_height(stature), girth=girth)
    params = params_from_pose14(pose, 0, lengths)
    return model, fit_pose_to_joints(model, params, j, posture_weight=posture_weight)


def init_from_2d(points2d_a, points2d_b, cam_a, cam_b, *, stature: float | None = None,
                 posture_weight: float = POSTURE_WEIGHT) -> tuple[SoftBodyModel, SoftBodyParams]:
    """The soft body from 2D joints clicked (or given) in two calibrated images.

    Parameters
    ----------
    points2d_a, points2d_b : array_like of shape (14, 2)
        Pixels in each camera's image, ``SKELETON_14`` order.
    cam_a, cam_b : toolkit.cameras.Camera
    stature, posture_weight : float, optional
        See :func:`model_from_joints`.

    Returns
    -------
    model, params
        As :func:`model_from_joints` on the triangulated joints.

    Raises
    ------
    InputError
        If an array has the wrong shape or a joint is missing (NaN) in either image.
    """
    pts = []
    for name, p in (("points2d_a", points2d_a), ("points2d_b", points2d_b)):
        a = np.asarray(p, float)
        if a.shape != (14, 2) or not np.all(np.isfinite(a)):
            raise InputError(name, "a finite array of shape (14, 2), pixels (every joint clicked)", f"shape {a.shape}")
        pts.append(a)
    joints = triangulate_linear([cam_a, cam_b], np.stack(pts))
    if not np.all(np.isfinite(joints)):
        raise InputError("cam_a, cam_b", "two cameras that triangulate every joint", "a degenerate pair")
    return model_from_joints(joints, stature=stature, posture_weight=posture_weight)



@dataclass(frozen=True)
class RefineConfig:
    """Settings of :func:`refine_on_cloud` (the initial model fitted to the first frame's points).

    Attributes
    ----------
    enabled : bool
        Whether the run refines a clicked start (:mod:`toolkit.pipeline.soft_body`).  Off by default:
        it makes tracking better and less sensitive to the clicks, but the global fit from the refined
        start ended worse on the seen stereo seed 9300 (2 draws: MPJPE median 36.6 against 31.2 mm,
        bones 15.4 against 11.1 mm; ``docs/benchmarks.md``, soft-body section (the earlier runs: its git history)).
    click_px : float
        Where the clicks' Cauchy loss turns robust, pixels (the clicks' noise, 3 px in the benchmark),
        so that one click far off (a wrong joint, a slip) pulls weakly.
    click_weight : float
        Weight of the click block against the points (each click residual is the reprojection error
        turned into metres at the joint's depth).  Over the 48 seen stereo starts (12 scenes x 4 draws
        of 3 px noise) the median frame-0 MPJPE was 31.8 mm at 1, 29.6 at 3, 32.0 at 10, 39.6 at 30 and
        35.8 at 0.3 (46 mm for the triangulated clicks); 1 because two clicks 12-14 px off
        (``tests/softbody/test_init_refine.py``) then leave their joints 22-23 mm off, against 47-63
        mm at 3.
    loss, f_scale : str, float
        Robust loss of the point-to-surface block and where it turns robust, metres.
    symmetry_weight : float
        Pull of each left length towards its right one, metre per metre (people are symmetric
        to a few millimetres; one bad click is then shared by the two sides).
    length_weight : float
        Pull of every length towards the start's, metre per metre (lengths the points and clicks do
        not show stay).
    prior_weight : float
        Pull of the pose towards the start, metres per radian (and metre per metre for the root).
    silhouette_weight : float
        Weight of the cameras' silhouettes when given (0: not used).
    max_points : int
        Points fitted (an even subsample).
    max_nfev : int
        Evaluations of the least-squares fit.
    restature : float or None
        :func:`refine_initial_model`: the model is rebuilt when the refined stature differs from its own
        by more than this fraction; None: never.  Off by default: on the seen stereo scenes the refined
        stature was closer to the truth (within 4 cm, the clicked one up to 12 cm off) but tracking from
        the rebuilt model was 1.5-4 mm worse on 5 of 8 starts measured (crouches 5334, 8234, 8634).
    """

    enabled: bool = False
    click_px: float = 3.0
    click_weight: float = 1.0
    loss: str = "soft_l1"
    f_scale: float = 0.02
    symmetry_weight: float = 1.0
    length_weight: float = 0.3
    prior_weight: float = 0.01
    silhouette_weight: float = 1.0
    max_points: int = 1000
    max_nfev: int = 60
    restature: float | None = None

    def __post_init__(self):
        for name in ("click_px", "f_scale"):
            if not getattr(self, name) > 0:
                raise InputError(f"RefineConfig.{name}", "a positive number", repr(getattr(self, name)))
        for name in ("click_weight", "symmetry_weight", "length_weight", "prior_weight", "silhouette_weight"):
            if not getattr(self, name) >= 0:
                raise InputError(f"RefineConfig.{name}", "a weight >= 0", repr(getattr(self, name)))


def _click_residuals(model: SoftBodyModel, st, clicks, cols: np.ndarray, scale_px: float):
    """Clicks' reprojection errors in metres at each joint's depth (Cauchy loss at ``scale_px``), and Jacobian."""
    from toolkit.softbody.residuals import robust
    from toolkit.softbody.silhouette import project_jacobian

    joints = st.nodes[:14]
    dj = model.joints_jacobian(None, st)[:, :, cols]           # (14, 3, C)
    rs, Js = [], []
    for cam, uv_click in clicks:
        uv, duv, z = project_jacobian(cam, joints)
        f = float(cam.K[0, 0])
        ok = np.isfinite(uv_click).all(axis=1) & (z > 1e-6)
        m = np.where(ok, z / f, 0.0)                          # metres per pixel at each joint
        r = (uv - np.where(ok[:, None], uv_click, uv)) * m[:, None]
        J = np.einsum("nij,njc->nic", duv, dj) * m[:, None, None]
        # robust per coordinate, the scale the clicks' noise in metres at the joint
        for k in range(2):
            s = np.maximum(scale_px * m, 1e-6)
            rk, Jk = robust(r[:, k] / s, J[:, k] / s[:, None], "cauchy", 1.0)
            rs.append(rk * s)
            Js.append(Jk * s[:, None])
    return np.concatenate(rs), np.vstack(Js)


def refine_on_cloud(model: SoftBodyModel, params: SoftBodyParams, cloud, *, clicks=None, silhouettes=None,
                    config: RefineConfig = RefineConfig(), observer=None, frame: int = 0) -> SoftBodyParams:
    """The initial model's pose and lengths fitted to the first frame's points, silhouettes and clicks.

    The clicked joints of :func:`init_from_2d` carry the clicks' noise (3 px at 3 m: 3-5 cm per
    joint, 10 cm for an unlucky one) into every bone length, and tracking keeps those lengths; here
    the clicks become soft observations (their reprojection error, robust) next to the frame's
    points (robust point-to-surface distances) and the cameras' silhouettes, so the surface
    decides what it shows (the body's extent, where a limb ends) and the clicks what it does not
    (where a knee lies along a straight leg).  Left and right lengths are pulled together.

    Parameters
    ----------
    model : SoftBodyModel
    params : SoftBodyParams
        Start (e.g. from :func:`init_from_2d`).
    cloud : array_like of shape (N, 3)
        The frame's points, metres, world (the subject's; a few outliers are tolerated).
    clicks : sequence of (Camera, ndarray of shape (14, 2)), optional
        The clicked joints in each camera, pixels, ``SKELETON_14`` order (NaN: not clicked).
    silhouettes : list of SilhouetteView, optional
        The frame's camera silhouettes.
    config : RefineConfig
    observer : Observer, optional
        Receives ``joints3d`` ``softbody/init/start_joints`` (the start's joints), ``scalar``
        ``softbody/init/click_error_px`` (the clicks' median reprojection error after the fit) and a
        ``text`` line (that error before and after, the largest length change).
    frame : int
        The frame of the reports.

    Returns
    -------
    SoftBodyParams
        Pose and lengths refined, widths as given.  With fewer than 30 points the start is returned.
    """
    from toolkit.softbody.distance import check_points
    from toolkit.softbody.residuals import data_residuals
    from toolkit.softbody.silhouette import SilhouetteBlock
    from toolkit.softbody.track import subsample

    pts = subsample(check_points(cloud, "cloud"), config.max_points)
    if len(pts) < 30:
        return params
    cols = np.r_[np.arange(N_POSE), np.arange(LENGTHS.start, LENGTHS.stop)]
    lo, hi = pose_bounds()
    lo, hi = np.r_[lo, np.full(len(LENGTH_NAMES), 0.01)], np.r_[hi, np.full(len(LENGTH_NAMES), 2.0)]
    x0 = np.clip(params.vector[cols], lo + 1e-9, hi - 1e-9)
    nl = len(LENGTH_NAMES)
    wp = np.r_[np.full(N_POSE, config.prior_weight), np.full(nl, config.length_weight)]
    S = np.zeros((len(SYMMETRIC_LENGTHS), len(cols)))
    for i, (a, b) in enumerate(SYMMETRIC_LENGTHS):
        S[i, N_POSE + a], S[i, N_POSE + b] = 1.0, -1.0
    S *= np.sqrt(config.symmetry_weight)
    sil = (SilhouetteBlock(model, params, silhouettes) if silhouettes and config.silhouette_weight > 0 else None)
    ws, wc = np.sqrt(config.silhouette_weight), np.sqrt(config.click_weight)
    cache = {}

    def evaluate(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            v = params.vector.copy()
            v[cols] = x
            p = SoftBodyParams(v)
            st = model.state(p)
            r, J = data_residuals(model, p, pts, st, cols, config.loss, config.f_scale)
            r, J = [r, wp * (x - x0), S @ x], [J, np.diag(wp), S]
            if clicks and config.click_weight > 0:
                rc, Jc = _click_residuals(model, st, clicks, cols, config.click_px)
                r, J = r + [wc * rc], J + [wc * Jc]
            if sil is not None:
                rs, Js = sil.residuals(p, st, cols)
                r, J = r + [ws * rs], J + [ws * Js]
            cache[key] = (np.concatenate(r), np.vstack(J))
        return cache[key]

    with one_blas_thread():
        res = least_squares(lambda x: evaluate(x)[0], x0, jac=lambda x: evaluate(x)[1], bounds=(lo, hi),
                            method="trf", loss="linear", max_nfev=config.max_nfev, x_scale="jac")
    v = params.vector.copy()
    v[cols] = res.x
    out = SoftBodyParams(v)
    if observer is not None:
        _report_refine(observer, model, params, out, clicks, frame)
    return out


def refine_initial_model(model: SoftBodyModel, params: SoftBodyParams, cloud, *, clicks=None, silhouettes=None,
                         config: RefineConfig = RefineConfig(), observer=None, frame: int = 0
                         ) -> tuple[SoftBodyModel, SoftBodyParams]:
    """:func:`refine_on_cloud`, then (``config.restature``) the model's stature re-estimated from the
    refined lengths.

    The metaball radii scale with the stature that the start's joints gave (the clicked chain was
    up to 12 cm off on the seen stereo scenes, the refined one within 4 cm): when the refined
    stature differs by more than ``config.restature`` the model is rebuilt for it and the pose and
    lengths refined once more.

    Parameters and reports as :func:`refine_on_cloud`.

    Returns
    -------
    model : SoftBodyModel
    params : SoftBodyParams
    """
    out = refine_on_cloud(model, params, cloud, clicks=clicks, silhouettes=silhouettes, config=config)
    h = float(np.clip(stature_of(out.lengths), *STATURE_LIMITS))
    if (config.restature is not None and out is not params
            and abs(h / model.proportions.height - 1.0) > config.restature):
        model = SoftBodyModel(BodyProportions.from_height(h), girth=model.girth)
        out = refine_on_cloud(model, out, cloud, clicks=clicks, silhouettes=silhouettes, config=config)
    if observer is not None:
        _report_refine(observer, model, params, out, clicks, frame)
    return model, out


def click_error_px(model: SoftBodyModel, params: SoftBodyParams, clicks) -> float:
    """Median distance (pixels) between the model's joints projected and the clicks (NaN without clicks)."""
    j = model.joints(params)
    d = [np.linalg.norm(cam.project(j) - np.asarray(uv, float), axis=1) for cam, uv in (clicks or [])]
    d = np.concatenate(d) if d else np.zeros(0)
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else float("nan")


def _report_refine(observer, model: SoftBodyModel, start: SoftBodyParams, out: SoftBodyParams, clicks,
                   frame: int) -> None:
    before, after = click_error_px(model, start, clicks), click_error_px(model, out, clicks)
    change = 1000 * (out.lengths - start.lengths)
    k = int(np.argmax(np.abs(change)))
    observer.report("joints3d", joints=model.joints(start), name="softbody/init/start_joints", frame=frame)
    observer.report("scalar", name="softbody/init/click_error_px", value=after, frame=frame)
    observer.report("text", text=f"initial model refined on the frame's points: clicks' median reprojection "
                    f"error {before:.1f} -> {after:.1f} px, largest length change {LENGTH_NAMES[k]} "
                    f"{change[k]:+.0f} mm", frame=frame)
