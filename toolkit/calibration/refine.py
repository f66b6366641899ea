"""Refine a broadcast camera's orientation and zoom on the pitch's field lines.

Two or three far cameras with a few pixels of calibration error leave the
subject's absolute position undetermined: stage 1's per-view 2D offsets
(claim 6 of the source) absorb the error, but a translation of the whole
body shifts every view alike, so with two views most of the offset is
confused with moving the skeleton (``docs/stage1_multiview.md``).  The
static background resolves that: the painted lines have known positions
(:class:`~toolkit.io.field_model.FieldModel`), so the error of each
camera can be measured on them before any person is looked at.

Model.  The camera centre is kept (a broadcast camera's position is
surveyed once; its pan, tilt, roll and zoom drift), and four unknowns are
fitted per camera: a small rotation ``omega`` (axis-angle, radians) applied
before the measured rotation, ``R' = Rodrigues(omega) R``, and a log-scale
``s`` of the focal length, ``f' = f exp(s)``.  Lens distortion and the
principal point stay as measured.

Fit.  Iterative closest point with point-to-line residuals: the field lines
are sampled every ``step_m`` metres and projected; each projected point is
paired with the nearest detected centre-line point
(:func:`~toolkit.calibration.lines.detect_line_points`) within a gate that
shrinks over the rounds; the residual is the distance along that point's
line normal, in pixels.  Each round is a robust ``scipy.optimize.least_squares``
(soft-L1 loss, 1 px scale) with the pairings fixed, plus weak priors that
keep directions the visible lines do not constrain (a single straight line
says nothing about zoom) at the measured values.  The refined camera is
accepted only with enough paired points, a small final residual and more
inliers than the measured camera had; otherwise the measured camera is kept
and the reason reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from toolkit.io.field_model import FieldModel
from toolkit.calibration.lines import LineDetectorConfig, LinePoints, detect_line_points
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.foreground.background import check_rgb
from toolkit.observe import as_observer


@dataclass(frozen=True)
class RefineConfig:
    """Parameters of :func:`refine_camera`.

    Attributes
    ----------
    detector : LineDetectorConfig
    step_m : float
        Spacing of the samples along the model's lines, metres.
    gates_px : tuple of float
        Pairing gate per ICP round, pixels (largest first; the first must
        exceed the expected calibration error).
    refine_focal : bool
        Fit the zoom (focal length scale) as well as the orientation.
    prior_rotation_px : float
        Standard deviation of the rotation prior, expressed as the image
        shift it causes (pixels); large = weak.
    prior_focal : float
        Standard deviation of the focal-length prior (relative).
    min_points : int
        Fewest paired points for a refinement to be accepted.
    max_rms_px : float
        Largest root-mean-square point-to-line residual of the inliers (within
        ``inlier_px``) for a refinement to be accepted.
    inlier_px : float
        Residual below which a paired point is an inlier.
    margin_px : float
        Projected model points closer than this to the image border are not used.
    """

    detector: LineDetectorConfig = field(default_factory=LineDetectorConfig)
    step_m: float = 0.05
    gates_px: tuple = (40.0, 20.0, 10.0, 5.0, 3.0, 3.0, 2.0)
    refine_focal: bool = True
    prior_rotation_px: float = 50.0
    prior_focal: float = 0.05
    min_points: int = 80
    max_rms_px: float = 1.0
    inlier_px: float = 2.0
    margin_px: float = 3.0

    def __post_init__(self):
        if not (np.isfinite(self.step_m) and self.step_m > 0):
            raise InputError("RefineConfig.step_m", "a finite positive spacing in metres", repr(self.step_m))
        g = tuple(float(x) for x in self.gates_px)
        if not g or any(not (np.isfinite(x) and x > 0) for x in g) or any(b > a for a, b in zip(g, g[1:])):
            raise InputError("RefineConfig.gates_px", "a non-empty sequence of positive pixel gates, largest first",
                             repr(self.gates_px))
        if not (np.isfinite(self.margin_px) and self.margin_px >= 0):
            raise InputError("RefineConfig.margin_px", "a finite value >= 0", repr(self.margin_px))
        object.__setattr__(self, "gates_px", g)
        for name in ("prior_rotation_px", "prior_focal", "max_rms_px", "inlier_px"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"RefineConfig.{name}", "a finite value > 0", repr(v))
        if not (isinstance(self.min_points, int) and self.min_points >= 4):
            raise InputError("RefineConfig.min_points", "an integer >= 4", repr(self.min_points))


@dataclass(frozen=True)
class Refinement:
    """What :func:`refine_camera` found for one camera.

    Attributes
    ----------
    camera : Camera
        The refined camera when ``accepted``, else the measured one.
    accepted : bool
    reason : str
        Why the refinement was rejected ("" when accepted).
    rotation : ndarray of shape (3,)
        Fitted correction ``omega`` (axis-angle, radians, world-to-camera side).
    focal_scale : float
        Fitted focal-length factor.
    n_lines : int
        Detected centre-line points in the image.
    n_paired : int
        Model points paired in the last round.
    rms_before_px, rms_after_px : float
        RMS point-to-line residual of the inliers for the measured and the refined camera.
    inliers_before, inliers_after : int
        Model points within ``inlier_px`` of a detected line.
    singular_values : ndarray of shape (n_params,)
        Of the data Jacobian at the solution, in pixels per prior standard
        deviation: small values flag directions the lines do not constrain.
    """

    camera: Camera
    accepted: bool
    reason: str
    rotation: np.ndarray
    focal_scale: float
    n_lines: int
    n_paired: int
    rms_before_px: float
    rms_after_px: float
    inliers_before: int
    inliers_after: int
    singular_values: np.ndarray

    @property
    def rotation_deg(self) -> float:
        """Size of the rotation correction, degrees."""
        return float(np.degrees(np.linalg.norm(self.rotation)))


def apply_correction(camera: Camera, omega: np.ndarray, log_focal: float = 0.0) -> Camera:
    """The camera rotated by ``omega`` about its centre and zoomed by ``exp(log_focal)``.

    Parameters
    ----------
    camera : Camera
    omega : ndarray of shape (3,)
        Axis-angle (radians), applied as ``R' = Rodrigues(omega) @ R``.
    log_focal : float
        Natural log of the focal-length factor (fx and fy alike).
    """
    dR, _ = cv2.Rodrigues(np.asarray(omega, np.float64).reshape(3, 1))
    R = dR @ camera.R
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ camera.center
    K = camera.K.copy()
    K[0, 0] *= np.exp(log_focal)
    K[1, 1] *= np.exp(log_focal)
    K[0, 1] *= np.exp(log_focal)
    return camera.replace(cam_from_world=T, K=K)


def _visible(camera: Camera, pts: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    uv = camera.project(pts)
    ok = np.isfinite(uv).all(1)
    ok[ok] = camera.in_image(uv[ok], margin)
    return uv, ok


def _pair(uv: np.ndarray, tree: cKDTree, gate: float):
    """Nearest detected line point of each projected model point within ``gate`` pixels: (found, index)."""
    d, j = tree.query(uv, distance_upper_bound=gate)
    return np.isfinite(d), j


def _point_to_line(uv, lines: LinePoints, j):
    return np.einsum("ij,ij->i", uv - lines.points[j], lines.normals[j])


def _inlier_stats(camera, pts, tree, lines, config) -> tuple[float, int]:
    uv, vis = _visible(camera, pts, config.margin_px)
    if not vis.any() or len(lines) == 0:
        return float("nan"), 0
    ok, j = _pair(uv[vis], tree, config.inlier_px * 2)
    r = np.abs(_point_to_line(uv[vis][ok], lines, j[ok]))
    r = r[r <= config.inlier_px]
    return (float(np.sqrt(np.mean(r ** 2))) if r.size else float("nan")), int(r.size)


def _corrected(camera: Camera, th: np.ndarray) -> Camera:
    """The camera corrected by parameters ``th``.

    Parameters
    ----------
    camera : Camera
    th : ndarray of shape (3,) or (4,)
        Axis-angle rotation (radians), then the natural log of the focal-length factor if given.

    Returns
    -------
    Camera
    """
    return apply_correction(camera, th[:3], th[3] if len(th) == 4 else 0.0)


def _fit_rounds(camera: Camera, pts: np.ndarray, tree: cKDTree, lines: LinePoints, prior_sd: np.ndarray,
                config: RefineConfig):
    """Pair model points with detected line points and fit the correction, once per gate of ``config.gates_px``.

    Parameters
    ----------
    camera : Camera
        The measured camera.
    pts : ndarray of shape (N, 3)
        Model line samples, world frame, metres.
    tree : scipy.spatial.cKDTree
        Over ``lines.points``.
    lines : LinePoints
        Detected centre-line points, pixels.
    prior_sd : ndarray of shape (n_par,)
        Prior standard deviations of the parameters (radians, log focal); ``n_par`` is 3 or 4.
    config : RefineConfig

    Returns
    -------
    theta : ndarray of shape (n_par,)
        The correction.
    history : list of float
        RMS of the gated residuals per round, pixels.
    paired : int
        Model points paired in the last round.
    sv : ndarray of shape (n_par,)
        Singular values of the last round's prior-scaled Jacobian (pixels per prior SD).
    failure : str
        Why the fit stopped early (too few pairs), or "".
    """
    n_par = len(prior_sd)
    theta = np.zeros(n_par)
    history, paired, sv = [], 0, np.zeros(n_par)
    for gate in config.gates_px:  # RefineConfig checks there is at least one
        cam = _corrected(camera, theta)
        uv, vis = _visible(cam, pts, config.margin_px)
        ok, j = _pair(uv[vis], tree, gate)
        P, J = pts[vis][ok], j[ok]
        paired = int(P.shape[0])
        if paired < config.min_points:
            return theta, history, paired, sv, (f"only {paired} model points within {gate:g} px of a detected line "
                                                f"(need {config.min_points})")

        def residuals(th, P=P, J=J):
            r = _point_to_line(_corrected(camera, th).project(P), lines, J)
            r = np.where(np.isfinite(r), r, gate)
            return np.concatenate([r, th / prior_sd])

        sol = least_squares(residuals, theta, method="trf", loss="soft_l1", f_scale=1.0, x_scale=prior_sd,
                            diff_step=1e-3)
        theta = sol.x
        r = sol.fun[:-n_par]
        history.append(float(np.sqrt(np.mean(np.minimum(np.abs(r), gate) ** 2))))
        Jd = sol.jac[:-n_par] * prior_sd[None, :]
        sv = np.linalg.svd(Jd, compute_uv=False)
    return theta, history, paired, sv, ""


def _report_model_lines(obs, camera: Camera, refined: Camera, field_model: FieldModel, step_m: float,
                        where: dict) -> None:
    """Report the model lines projected with the measured and the refined camera (``lines2d``).

    Parameters
    ----------
    obs : Observer
    camera, refined : Camera
        The measured and the refined camera.
    field_model : FieldModel
    step_m : float
        Sample spacing along the lines, metres.
    where : dict
        Camera name and timeline position of the reports.
    """
    for name, cam, col in (("calibration/model_before", camera, (255, 200, 0)),
                           ("calibration/model_after", refined, (0, 220, 255))):
        strips = [s for p in field_model.polylines if (s := _strip(cam, p, step_m)) is not None]
        strips = [s for piece in strips for s in piece]
        if strips:
            obs.report("lines2d", name=name, strips=strips,
                       colors=np.tile(np.array([col], np.uint8), (len(strips), 1)), **where)


def refine_camera(camera: Camera, image: np.ndarray, field_model: FieldModel,
                  config: RefineConfig = RefineConfig(), *, region: np.ndarray | None = None,
                  observer=None, frame: int | None = None) -> Refinement:
    """Correct a camera's orientation (and zoom) so the field lines project onto the image's lines.

    Parameters
    ----------
    camera : Camera
        The measured camera.
    image : ndarray of shape (H, W, 3) uint8
        RGB image of the scene from this camera without people in front of
        the lines (a clean plate or a background learned from the video).
    field_model : FieldModel
        The lines, world frame, metres.
    config : RefineConfig
    region : ndarray of shape (H, W) bool, optional
        Where lines may be detected (default: everywhere).
    observer : Observer, optional
        Receives, for ``camera.name``: the detected centre-line points
        (``points2d`` "calibration/lines"), the model lines projected with the
        measured and the refined camera (``lines2d`` "calibration/model_before",
        "calibration/model_after"), the residual per round (``series``
        "calibration/<cam>/rms_px") and a summary (``text``).
    frame : int, optional
        Timeline position for the reports (default: static).

    Returns
    -------
    Refinement
    """
    obs = as_observer(observer)
    img = check_rgb(image, f"refine_camera({camera.name}): image", (camera.height, camera.width))
    lines = detect_line_points(img, config.detector, region)
    pts, _ = field_model.samples(config.step_m)
    f0 = float(camera.K[0, 0])
    n_par = 4 if config.refine_focal else 3
    prior_sd = np.array([config.prior_rotation_px / f0] * 3 + [config.prior_focal])[:n_par]
    when = {"frame": frame} if frame is not None else {"static": True}
    where = dict(camera=camera.name) | when

    def reject(reason, rms_b=float("nan"), inl_b=0, n_paired=0):
        obs.report("text", name=f"calibration/{camera.name}/summary", text=f"{camera.name}: kept the measured "
                   f"camera: {reason}", level="WARN", **when)
        return Refinement(camera, False, reason, np.zeros(3), 1.0, len(lines), n_paired, rms_b, rms_b, inl_b, inl_b,
                          np.zeros(n_par))

    if len(lines) < config.min_points:
        return reject(f"only {len(lines)} line points detected (need {config.min_points})")
    tree = cKDTree(lines.points)
    rms_b, inl_b = _inlier_stats(camera, pts, tree, lines, config)
    _, vis0 = _visible(camera, pts, config.margin_px)
    if vis0.sum() < config.min_points:
        return reject(f"only {int(vis0.sum())} model line points project into the image (need {config.min_points})",
                      rms_b, inl_b)

    theta, history, paired, sv, failure = _fit_rounds(camera, pts, tree, lines, prior_sd, config)
    if failure:
        return reject(failure, rms_b, inl_b, paired)
    refined = _corrected(camera, theta)
    rms_a, inl_a = _inlier_stats(refined, pts, tree, lines, config)
    obs.report("series", name=f"calibration/{camera.name}/rms_px", values=np.array(history), **when)
    obs.report("points2d", name="calibration/lines", points=lines.points,
               colors=np.tile(np.array([[255, 60, 60]], np.uint8), (len(lines), 1)), **where)
    if observer is not None:  # the projected model lines are only drawn
        _report_model_lines(obs, camera, refined, field_model, config.step_m, where)
    summary = (f"{camera.name}: rotation {np.degrees(np.linalg.norm(theta[:3])):.4f} deg, focal x"
               f"{np.exp(theta[3]) if n_par == 4 else 1.0:.4f}; inliers {inl_b} -> {inl_a}, RMS "
               f"{rms_b:.2f} -> {rms_a:.2f} px; {len(lines)} line points, {paired} paired")
    if not np.isfinite(rms_a) or inl_a < config.min_points:
        return reject(f"only {inl_a} inliers after fitting ({summary})", rms_b, inl_b, paired)
    if rms_a > config.max_rms_px:
        return reject(f"residual {rms_a:.2f} px above {config.max_rms_px} px ({summary})", rms_b, inl_b, paired)
    if inl_a < inl_b:
        return reject(f"fewer inliers than the measured camera ({summary})", rms_b, inl_b, paired)
    obs.report("text", name=f"calibration/{camera.name}/summary", text=summary, **when)
    return Refinement(refined, True, "", theta[:3].copy(), float(np.exp(theta[3])) if n_par == 4 else 1.0,
                      len(lines), paired, rms_b, rms_a, inl_b, inl_a, sv)


def _strip(camera: Camera, polyline: np.ndarray, step_m: float):
    """Projected pieces (list of (K, 2)) of a polyline that fall inside the image, or None."""
    model = FieldModel((polyline,))
    pts, _ = model.samples(step_m * 4)
    uv, ok = _visible(camera, pts, 0.0)
    if not ok.any():
        return None
    pieces, start = [], None
    for i, v in enumerate(np.append(ok, False)):
        if v and start is None:
            start = i
        elif not v and start is not None:
            if i - start >= 2:
                pieces.append(uv[start:i])
            start = None
    return pieces or None


def refine_rig(rig: Rig, images: Mapping[str, np.ndarray], field_model: FieldModel,
               config: RefineConfig = RefineConfig(), *, observer=None) -> tuple[Rig, dict[str, Refinement]]:
    """Refine every camera of a rig that has an image; the others are kept.

    Parameters
    ----------
    rig : Rig
        Measured cameras.
    images : mapping of str to ndarray of shape (H, W, 3) uint8
        Per camera name, an image of the empty scene (clean plate or learned background).
    field_model : FieldModel
    config : RefineConfig
    observer : Observer, optional

    Returns
    -------
    rig : Rig
        The refined cameras (measured ones where refinement was rejected or had no image).
    results : dict of str to Refinement
        Per camera with an image.
    """
    unknown = sorted(set(images) - set(rig.names))
    if unknown:
        raise InputError("refine_rig: images", f"images of the rig's cameras {rig.names}", f"also {unknown}")
    results = {c.name: refine_camera(c, images[c.name], field_model, config, observer=observer)
               for c in rig if c.name in images}
    return Rig(tuple(results[c.name].camera if c.name in results else c for c in rig)), results


def calibration_error_px(measured: Camera, truth: Camera, points: np.ndarray) -> float:
    """Mean distance (pixels) between points projected by two calibrations of one camera.

    The measure the scene generator's perturbation is set by
    (:func:`toolkit.synthetic.rigs.perturb_rig`), for evaluating a refinement.
    """
    p = np.asarray(points, float).reshape(-1, 3)
    p = p[np.isfinite(p).all(1)]
    return float(np.nanmean(np.linalg.norm(measured.project(p) - truth.project(p), axis=1)))
