"""View-dependent blending of articulated billboards (source 000 §4, eqs. 7-10).

One frame is rendered fan by fan, back to front:

1. per fan, the camera weights of :mod:`toolkit.rendering.weights` (omega,
   attenuation f, grazing fade);
2. each billboard of the fan is warped into the view (a :data:`Warper`: the
   CPU compositor uses a plane-induced homography, the Open3D renderer
   rasterises a textured quad), giving ``V_j(p)`` and ``alpha_j(p)`` (the
   fade is folded into alpha);
3. per pixel, ``w_j = alpha_j omega_j f_j`` (eq. 9), colour
   ``V = sum V_j w_j / sum w_j`` (eq. 8) and alpha by eq. 10: the nearest
   camera's alpha where that camera covers the pixel, else
   ``sum alpha_j w_j / sum alpha_j omega_j``;
4. the fan is composited *over* the fans behind it (fans occlude each other,
   billboards of one fan blend);
5. the discontinuities met on the way (the subject's border against the
   background; fan borders against another fan and places where another
   camera takes over, where the colour jumps there by more than
   ``smoothing_min_jump``) are recorded and smoothed afterwards with a small
   Gaussian, only there.  The smoothing
   strength is the attenuation ``1 - exp(-d^2/2 sigma^2)`` of the view, so a
   virtual camera on a source camera still reproduces that image exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import cv2
import numpy as np

from toolkit.billboards.model import Billboard, BillboardModel
from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.observe import Observer, as_observer
from toolkit.rendering.config import LATERAL_JOINTS, BlendConfig
from toolkit.rendering.weights import (CameraWeights, attenuation, back_view_angles, camera_weights, foreshortening,
                                      grazing_fade, omega)

#: A warp of one billboard into a view: ``(billboard, camera, pose) -> (rgb, alpha, roi)`` with
#: rgb (h, w, 3) float32 0..255, alpha (h, w) float32 and roi (x0, y0, x1, y1) in the view, or None if
#: the billboard does not reach the image; ``pose`` is None or a rigid (4, 4) world transform to apply to
#: the billboard first (:func:`facing_pose`).
Warper = Callable[[Billboard, Camera, "np.ndarray | None"], "tuple[np.ndarray, np.ndarray, tuple] | None"]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two 3-vectors (np.cross costs ~20x more on single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def facing_pose(billboard: Billboard, eye: np.ndarray, free_deg: float = 0.0) -> np.ndarray | None:
    """Rigid transform (4, 4) that turns a planar billboard about its bone until it faces ``eye``.

    The billboard of a source camera holds the bone and faces that camera;
    seen from another view it is foreshortened across the bone by the cosine
    of the angle between them (a torso seen 50 degrees off its source is drawn
    64 % as wide), while a limb, round about its bone, is not.  Turned about
    the bone by the smallest angle that makes it face the view, front or back
    (at most 90 degrees: a view behind the plane still sees its back face, so
    left and right stay where they are), it keeps its width from every
    direction around the bone.  At its own source camera the turn is zero.

    Parameters
    ----------
    billboard : Billboard
        A planar billboard with its bone (``axis``).
    eye : ndarray of shape (3,)
        Centre of the view, metres.
    free_deg : float
        Turn only by the part of the angle beyond this, degrees: a billboard
        seen at most ``free_deg`` off its normal (about the bone) stays where
        it is, one seen farther off is turned until it is ``free_deg`` off, so
        no billboard is foreshortened across its bone below ``cos(free_deg)``.

    Returns
    -------
    ndarray of shape (4, 4) or None
        None when there is nothing to turn: no bone, not a plane, or the view
        on the bone's line.
    """
    if billboard.axis is None or billboard.surface != "plane":
        return None
    x0 = billboard.axis[0]
    b = billboard.axis[1] - x0
    if np.linalg.norm(b) < 1e-9:
        return None
    b = b / np.linalg.norm(b)
    n0 = billboard.normal - (billboard.normal @ b) * b
    to_eye = np.asarray(eye, float) - x0
    n1 = to_eye - (to_eye @ b) * b
    if np.linalg.norm(n1) < 1e-9 or np.linalg.norm(n0) < 1e-9:
        return None
    n0 /= np.linalg.norm(n0)
    n1 /= np.linalg.norm(n1)
    if n0 @ n1 < 0:  # seen from behind: turn the back face towards the view
        n1 = -n1
    c, s = float(n0 @ n1), float(_cross(n0, n1) @ b)
    if free_deg > 0:
        phi = np.arctan2(s, c)
        phi = np.sign(phi) * max(abs(phi) - np.radians(free_deg), 0.0)
        c, s = float(np.cos(phi)), float(np.sin(phi))
    K = np.array([[0, -b[2], b[1]], [b[2], 0, -b[0]], [-b[1], b[0], 0]])
    R = np.eye(3) + s * K + (1.0 - c) * K @ K  # Rodrigues: rotation by atan2(s, c) about b
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = x0 - R @ x0
    return T

#: ``RenderResult.status`` values.
STATUS_OK = "ok"
STATUS_EMPTY_MODEL = "empty model: no billboards"
STATUS_ALL_BEHIND = "every billboard is behind the virtual camera or faces away from it"


@dataclass(frozen=True, eq=False)
class RenderResult:
    """A rendered subject layer.

    Attributes
    ----------
    rgb : ndarray of shape (H, W, 3), float32
        Colour premultiplied by ``alpha``, 0..255.
    alpha : ndarray of shape (H, W), float32
        Coverage in [0, 1].
    fan : ndarray of shape (H, W), uint8
        Part id of the fan on top at each pixel (0 = none).
    dominant : ndarray of shape (H, W), int8
        Rig index of the camera with the largest weight there (-1 = none).
    discontinuities : ndarray of shape (H, W), bool
        Pixels found while rendering where smoothing applies.
    smoothed : ndarray of shape (H, W), bool
        Pixels actually changed by the smoothing (dilated discontinuities, strength > 0).
    weights : CameraWeights
        Per fan (model order) and camera (rig order).
    order : tuple of int
        Part ids in drawing order (back to front).
    status : str
        :data:`STATUS_OK` or why the layer is empty.
    """

    rgb: np.ndarray
    alpha: np.ndarray
    fan: np.ndarray
    dominant: np.ndarray
    discontinuities: np.ndarray
    smoothed: np.ndarray
    weights: CameraWeights | None
    order: tuple
    status: str = STATUS_OK

    @property
    def ok(self) -> bool:
        return self.status == STATUS_OK

    def over(self, background: np.ndarray) -> np.ndarray:
        """Composite over a background (H, W, 3) (uint8 or float 0..255): uint8 RGB."""
        bg = np.asarray(background, np.float32)
        if bg.shape != self.rgb.shape:
            raise InputError("RenderResult.over: background", f"shape {self.rgb.shape}", f"shape {bg.shape}")
        out = self.rgb + (1.0 - self.alpha[..., None]) * bg
        return np.clip(out + 0.5, 0, 255).astype(np.uint8)


#: Back faces are drawn under a part (``BlendConfig.back_underlay``) only when at most this many of its
#: billboards pass the fade from the front: one source's segment gives the part's outline from its side
#: alone, two or more fill each other's gaps through eq. 10.  Under every part, a 4-camera broadcast
#: scene (zoo seed 57, z00) lost 0.6 dB (back faces of a kit whose back differs, limbs posed wrong
#: drawn twice); gated so, it loses 0.2 dB there and the real and studio views gain 0.2-1 dB.
UNDERLAY_MAX_FRONT = 1


def _fan_billboards(model: BillboardModel):
    """The billboards of every fan, by fan and camera.

    Parameters
    ----------
    model : BillboardModel
        ``F`` fans, ``C`` cameras.

    Returns
    -------
    anchors : ndarray of shape (F, 3)
        Middle of each fan's axis, metres.
    normals : ndarray of shape (F, C, 3)
        Billboard normals (``(0, 0, 1)`` where a camera has no billboard).
    points : ndarray of shape (F, C, 3)
        Billboard centres (the anchor where a camera has none), metres.
    present : ndarray of shape (F, C), bool
        A camera has a billboard in the fan.
    borrowed : ndarray of shape (F, C), bool
        The billboard is a stand-in borrowed from another source.
    """
    names = model.rig.names
    n_f, n_c = len(model.fans), len(names)
    anchors = np.array([f.axis.mean(axis=0) for f in model.fans]).reshape(n_f, 3)
    normals = np.zeros((n_f, n_c, 3))
    points = np.repeat(anchors[:, None], n_c, axis=1)
    present = np.zeros((n_f, n_c), bool)
    borrowed = np.zeros((n_f, n_c), bool)
    for i, f in enumerate(model.fans):
        for b in f.billboards:
            j = names.index(b.camera)
            normals[i, j] = b.normal
            points[i, j] = b.center
            present[i, j] = True
            borrowed[i, j] = bool(getattr(b, "borrowed", False))
    normals[~present] = (0.0, 0.0, 1.0)
    return anchors, normals, points, present, borrowed


def fan_weights(model: BillboardModel, camera: Camera, config: BlendConfig = BlendConfig()) -> CameraWeights:
    """Camera weights (eqs. 5, 7, fade) of every fan of ``model`` for the view ``camera``.

    Cameras without a billboard in a fan get zero fade (no contribution).  Per
    fan, by the evidence each billboard holds of the side of the part V sees:

    * the billboards V sees from the front fade with :func:`grazing_fade`;
    * when none of them passes the fade but V sees some from the front all the
      same, edge-on (``config.grazing_front``: a back view whose nearest source is
      80-90 degrees away), those are drawn: the least foreshortened one (largest
      :func:`~toolkit.rendering.weights.foreshortening` ratio) is the fan's
      nearest and opaque, the others weigh their ratio over its ratio;
    * when V sees none of them from the front (a reverse angle: every billboard
      faces a source on the other side), their back faces are drawn instead
      (``config.back_faces``), weighted by
      :func:`~toolkit.rendering.weights.back_view_angles`;
    * the back faces V sees of the billboards not drawn from the front (borrowed
      stand-ins excepted) are drawn under every fan that at most
      :data:`UNDERLAY_MAX_FRONT` billboard passes the fade for
      (``config.back_underlay`` > 0, with ``back_faces``): omega
      ``back_underlay x omega(mirrored angle)`` over the fan's best back face,
      never the nearest, so eq. 10 takes the alpha of the billboards seen from
      the front where they cover and the back faces' elsewhere: they fill the
      part's outline where the one source seeing it saw it narrow, occluded or
      posed wrong, and tint its colour a little;
    * with ``config.normalise_fade``, the fan's nearest camera is the one with
      the largest faded weight ``omega * fade`` and the fades are divided by
      its fade: the billboard eq. 10 takes its alpha from is opaque, the
      others fade relative to it, so a part seen only at grazing angles (two
      cameras far apart, a high view) is not drawn half transparent; a fan seen exactly
      edge-on by every billboard keeps the least foreshortened one.

    ``omega`` of the result is relative to each fan's nearest camera (1 there).
    """
    n_f, n_c = len(model.fans), len(model.rig.names)
    anchors, normals, points, present, borrowed = _fan_billboards(model)
    src, eye = model.rig.centers, camera.center
    w = camera_weights(anchors, eye, src, angle_sigma=config.angle_sigma,
                       attenuation_sigma_m=config.attenuation_sigma_m)
    ratio = foreshortening(normals, points, eye, src)
    fade = np.where(present, grazing_fade(normals, points, eye, src, config.fade_low, config.fade_high), 0.0)
    beta = w.beta
    rows = np.arange(n_f)
    none = ~np.any(fade > 0, axis=1)  # (F,): no billboard passes the fade from the front
    n_front = np.count_nonzero(fade > 0, axis=1)
    graze = present & none[:, None] & (ratio > 0) if config.grazing_front else np.zeros((n_f, n_c), bool)
    by_graze = np.any(graze, axis=1)
    fade = np.where(graze, 1.0, fade)
    back = np.zeros((n_f, n_c), bool)
    fade_b = np.zeros((n_f, n_c))
    beta_b = beta
    if config.back_faces:
        fade_b = np.where(present, grazing_fade(normals, points, eye, src, config.fade_low, config.fade_high,
                                                side="back"), 0.0)
        beta_b = back_view_angles(anchors, normals, points, eye, src)
        back = (fade_b > 0) & (none & ~by_graze)[:, None]
        fade = np.where(back, fade_b, fade)
        beta = np.where(back, beta_b, beta)
    om = omega(beta, config.angle_sigma)
    # the nearest camera among those that draw in the fan (else among those that have a billboard)
    usable = np.where(np.any(fade > 0, axis=1, keepdims=True), fade > 0, present)
    if config.normalise_fade:
        # the camera with the largest faded weight is the fan's nearest, and opaque (eq. 10 takes its alpha)
        nearest = np.argmax(np.where(usable, om * fade, -1.0), axis=1)
        top = fade[rows, nearest][:, None]
        fade = np.where(top > 0, np.clip(fade / np.maximum(top, 1e-12), 0.0, 1.0), fade)
    else:
        nearest = np.argmax(np.where(usable, om, -1.0), axis=1)
    # eqs. 8-10 are ratios of omega within a fan: relative to the nearest camera's, so that a fan seen
    # only by cameras far from V (omega ~ 1e-13 at 140 degrees) is not lost to the "no weight" threshold
    om = om / np.maximum(om[rows, nearest], 1e-300)[:, None]
    if by_graze.any():  # edge-on billboards: the least foreshortened one is the nearest, the others by ratio
        r_g = np.where(graze, ratio, 0.0)
        best = np.argmax(r_g, axis=1)
        nearest = np.where(by_graze, best, nearest)
        om = np.where(by_graze[:, None], r_g / np.maximum(r_g[rows, best], 1e-12)[:, None], om)
    if config.back_faces and config.back_underlay > 0:
        under = (fade <= 0) & (fade_b > 0) & ~borrowed  # a stand-in's outline is another source's
        under[rows, nearest] = False
        under &= (n_front <= UNDERLAY_MAX_FRONT)[:, None]
        if under.any():
            ob = np.where(under, omega(beta_b, config.angle_sigma), 0.0)
            ob = ob / np.maximum(ob.max(axis=1, keepdims=True), 1e-300)
            om = np.where(under, config.back_underlay * ob, om)
            fade = np.where(under, fade_b, fade)
            beta = np.where(under, beta_b, beta)
            back |= under
    dist = np.linalg.norm(src[nearest] - eye, axis=1)
    att = np.repeat(attenuation(dist, config.attenuation_sigma_m)[:, None], n_c, axis=1)
    att[rows, nearest] = 1.0
    return CameraWeights(beta, om, att, fade, nearest, dist, back if back.any() else None)


#: Width (radians) of the fade of a borrowed billboard (:class:`toolkit.rendering.fans.BorrowedBillboard`)
#: near its source: ``1 - omega(beta, BORROW_FADE_SIGMA)``, 0 on the source, > 0.5 beyond 7 degrees (with
#: the blend's 0.32 the stand-in was half gone 20 degrees off and thresholded away: a view 15-20 degrees from
#: a 2-camera broadcast source lost 2-9 % coverage).
BORROW_FADE_SIGMA = 0.1
#: The far-side copy of a billboard is drawn only when it sits at least this far behind it, in pixels
#: of the view (nearer, it hides behind the billboard anyway).
MIN_BACK_PX = 0.5
#: Ridge weight on the (B, C) terms of the elliptic cross-section fit of :func:`view_widths`.
WIDTH_RIDGE = 0.1
#: A part is drawn at most this many times as wide as the widest segment its sources saw.
WIDTH_GROWTH_MAX = 1.5
#: ... and at least this many times as wide as the narrowest.
WIDTH_SHRINK_MIN = 0.7


def part_depth(fan) -> float:
    """Thickness of a part across its bone, metres: the narrowest of its billboards' segments.

    Each billboard's segment width across the bone (columns of its texture
    with alpha >= 0.5, times the texel width) is the part's width seen from
    that source; the narrowest of them stands for the part's depth.
    """
    widths = []
    for b in fan.billboards:
        cols = int(np.count_nonzero((b.alpha >= 0.5).any(axis=0)))
        widths.append(cols * float(np.linalg.norm(b.corners[1] - b.corners[0])) / b.size[0])
    return min(widths) if widths else 0.0


def behind_pose(pose: np.ndarray, billboard: Billboard, eye: np.ndarray, depth_m: float) -> np.ndarray:
    """``pose`` followed by a shift of ``depth_m`` metres away from ``eye`` along the turned billboard's normal."""
    n = pose[:3, :3] @ billboard.normal
    if n @ (np.asarray(eye, float) - (pose[:3, :3] @ billboard.center + pose[:3, 3])) > 0:
        n = -n
    T = pose.copy()
    T[:3, 3] += depth_m * n
    return T


def segment_width(billboard: Billboard) -> float:
    """Width of a billboard's segment across its bone, metres (texture columns with alpha >= 0.5 x texel width)."""
    cols = int(np.count_nonzero((billboard.alpha >= 0.5).any(axis=0)))
    return cols * float(np.linalg.norm(billboard.corners[1] - billboard.corners[0])) / billboard.size[0]


def view_widths(fan, centers: dict, eye: np.ndarray, ridge: float = WIDTH_RIDGE) -> dict:
    """Width of a part seen from ``eye``, from the widths its sources saw, with an elliptic cross-section.

    An ellipse seen from the angle theta about its axis is ``w`` wide with
    ``(w/2)^2 = A + B cos 2 theta + C sin 2 theta``: linear in (A, B, C).
    The segment widths of the fan's billboards (:func:`segment_width`) at
    their cameras' angles about the bone give (A, B, C) by least squares,
    with a ridge on (B, C) (one camera: a circle; two: the roundest ellipse
    through both), and so the width from ``eye``, clipped to
    [:data:`WIDTH_SHRINK_MIN`, :data:`WIDTH_GROWTH_MAX`] x the widths seen.

    Parameters
    ----------
    fan : BillboardFan
    centers : dict of str -> ndarray (3,)
        Source camera centres by name.
    eye : ndarray of shape (3,)
        The view's centre.
    ridge : float
        Weight of ``B^2 + C^2`` against the squared residuals (dimensionless).

    Returns
    -------
    dict of str -> float
        Per source camera of the fan: the width from ``eye`` divided by the width that camera saw
        (1 where it is unknown).
    """
    b = fan.axis[1] - fan.axis[0]
    if not fan.billboards or np.linalg.norm(b) < 1e-9:
        return {}
    b = b / np.linalg.norm(b)
    mid = fan.axis.mean(axis=0)
    ref = fan.billboards[0].normal - (fan.billboards[0].normal @ b) * b
    if np.linalg.norm(ref) < 1e-9:
        return {bb.camera: 1.0 for bb in fan.billboards}
    ref = ref / np.linalg.norm(ref)
    side = _cross(b, ref)

    def angle(p):
        d = np.asarray(p, float) - mid
        return float(np.arctan2(d @ side, d @ ref))

    w = np.array([segment_width(bb) for bb in fan.billboards])
    if not np.all(w > 0):
        return {bb.camera: 1.0 for bb in fan.billboards}
    th = np.array([angle(centers[bb.camera]) for bb in fan.billboards])
    X = np.column_stack([np.ones_like(th), np.cos(2 * th), np.sin(2 * th)])
    y = (w / 2) ** 2
    reg = np.diag([0.0, ridge, ridge]) * len(w)  # (B, C) have the units of y: a dimensionless weight
    c = np.linalg.solve(X.T @ X + reg + 1e-12 * np.eye(3), X.T @ y)
    tv = angle(eye)
    yv = float(c @ [1.0, np.cos(2 * tv), np.sin(2 * tv)])
    wv = 2 * np.sqrt(max(yv, 0.0))
    wv = float(np.clip(wv, WIDTH_SHRINK_MIN * w.min(), WIDTH_GROWTH_MAX * w.max()))
    return {bb.camera: wv / wj for bb, wj in zip(fan.billboards, w)}


#: Weight of the depth/breadth prior against one source's width in :func:`section_widths` (dimensionless).
SECTION_PRIOR_WEIGHT = 0.5
#: A part is drawn at most this many times as wide as the widest segment its sources saw when its
#: cross-section is known (:func:`section_widths`): 1 / 0.6 for a torso seen only from the side.
SECTION_GROWTH_MAX = 1.7


def section_widths(fan, centers: dict, eye: np.ndarray, joints: np.ndarray, ratio: float,
                   prior: float = SECTION_PRIOR_WEIGHT) -> dict:
    """Width of a flat part seen from ``eye``: an elliptic cross-section oriented by the skeleton.

    The torso is not round about its bone: it is broad from the front and
    shallow from the side, and the skeleton says which way it faces (the
    shoulder and hip lines).  Its cross-section is taken as an ellipse with
    semi-axes ``a`` along the left-right direction and ``b`` front to back;
    seen from an angle theta off the front (about the bone) it is
    ``w = 2 sqrt(a^2 cos^2 theta + b^2 sin^2 theta)`` wide, linear in
    ``(a^2, b^2)``.  Each source's segment width (:func:`segment_width`) is
    one equation, the prior ``b = ratio x a`` one more (weight ``prior`` per
    source), solved by least squares: two sources far apart fix the ellipse,
    one source (or two that both saw the side) gets the rest from the ratio.
    Unlike :func:`view_widths` (orientation and shape from the widths alone:
    underdetermined with two cameras), the orientation comes from the joints.

    Parameters
    ----------
    fan : BillboardFan
        A part listed in :data:`LATERAL_JOINTS`.
    centers : dict of str -> ndarray (3,)
        Source camera centres by name.
    eye : ndarray of shape (3,)
        The view's centre.
    joints : ndarray of shape (14, 3)
        The joints the model was built on (``SKELETON_14``), metres.
    ratio : float
        Depth / breadth of the cross-section prior (0 < ratio <= 1).
    prior : float
        Weight of the prior equation relative to one source's.

    Returns
    -------
    dict of str -> float
        Per source camera of the fan: the width from ``eye`` (at most :data:`SECTION_GROWTH_MAX` x the widest
        seen) over the width that camera saw where it is wider than every source saw it, else 1 (billboards
        are only widened, and only where no source saw that much of the part); empty when the
        part's orientation is unknown (non-finite joints, bone along the shoulder line, view along the bone).
    """
    from toolkit.skeleton import SKELETON_14

    name = SKELETON_14.parts[fan.part - 1].name if 1 <= fan.part <= len(SKELETON_14.parts) else None
    pairs = LATERAL_JOINTS.get(name)
    J = np.asarray(joints, float)
    if pairs is None or not fan.billboards or J.shape != (14, 3):
        return {}
    idx = SKELETON_14.joint_names.index
    lat = sum(J[idx(left)] - J[idx(right)] for left, right in pairs)
    b = fan.axis[1] - fan.axis[0]
    if not np.all(np.isfinite(lat)) or np.linalg.norm(b) < 1e-9:
        return {}
    b = b / np.linalg.norm(b)
    lat = lat - (lat @ b) * b
    if np.linalg.norm(lat) < 1e-6:
        return {}
    lat = lat / np.linalg.norm(lat)
    fwd = _cross(b, lat)
    mid = fan.axis.mean(axis=0)

    def cos_sin2(p):
        d = np.asarray(p, float) - mid
        d = d - (d @ b) * b
        n = float(np.linalg.norm(d))
        if n < 1e-9:
            return None
        return (float(d @ fwd) / n) ** 2, (float(d @ lat) / n) ** 2

    w = np.array([segment_width(bb) for bb in fan.billboards])
    rows = [cos_sin2(centers[bb.camera]) for bb in fan.billboards]
    view = cos_sin2(eye)
    if view is None or not np.all(w > 0) or any(r is None for r in rows):
        return {}
    X = np.array(rows + [(np.sqrt(prior) * ratio ** 2, -np.sqrt(prior))])
    y = np.r_[(w / 2) ** 2, 0.0]
    (A, B), *_ = np.linalg.lstsq(X, y, rcond=None)
    if not (A > 0 and B > 0):  # inconsistent widths: the prior's shape through their mean
        A = float(np.mean(y[:-1] / (X[:-1, 0] + ratio ** 2 * X[:-1, 1])))
        B = ratio ** 2 * A
    wv = 2 * np.sqrt(A * view[0] + B * view[1])
    wv = min(wv, SECTION_GROWTH_MAX * float(w.max()))
    if wv <= w.max():
        # a source saw the part at least that wide: its billboard covers it (widening the narrower ones
        # drew the torso over the arms between two cameras 100 degrees apart, -0.46 dB); and never
        # narrowed: a segment wider than the ellipse says holds what the fit does not know (an arm
        # labelled torso, a loose shirt; narrowed, a studio view lost 11 % coverage)
        return {bb.camera: 1.0 for bb in fan.billboards}
    return {bb.camera: wv / wj for bb, wj in zip(fan.billboards, w)}


def stretch_across(pose: np.ndarray, billboard: Billboard, factor: float) -> np.ndarray:
    """``pose`` followed by a stretch of the turned billboard across its bone by ``factor`` (about the bone)."""
    u = pose[:3, :3] @ billboard.axes[0]  # across the bone, unit
    S = np.eye(4)
    S[:3, :3] += (factor - 1.0) * np.outer(u, u)
    S[:3, 3] = -(factor - 1.0) * (u @ billboard.axis[0]) * u
    return S @ pose


def _steeper(billboard: Billboard, source: np.ndarray, eye: np.ndarray) -> float:
    """``1 - |cos(bone, source)| / |cos(bone, view)|`` clipped to [0, 1]: how much more along its bone a view
    looks than the billboard's source (0 when not more: the source's segment already shows that much of the
    part's far side; -> 1 looking down the bone)."""
    if billboard.axis is None:
        return 0.0
    b = billboard.axis[1] - billboard.axis[0]
    b = b / max(np.linalg.norm(b), 1e-12)
    mid = billboard.axis.mean(axis=0)

    def along(p):
        d = np.asarray(p, float) - mid
        return abs(float(d @ b)) / max(float(np.linalg.norm(d)), 1e-12)

    return float(np.clip(1.0 - along(source) / max(along(eye), 1e-6), 0.0, 1.0))


def _front_over_back(front, back):
    """Merge two warps ``(rgb, alpha, roi)`` of one billboard: ``front`` where it covers, else ``back``."""
    if back is None:
        return front
    if front is None:
        return back
    (fc, fa, fr), (bc, ba, br) = front, back
    x0, y0, x1, y1 = min(fr[0], br[0]), min(fr[1], br[1]), max(fr[2], br[2]), max(fr[3], br[3])
    rgb = np.zeros((y1 - y0, x1 - x0, 3), np.float32)
    alpha = np.zeros((y1 - y0, x1 - x0), np.float32)
    for c, a, r in ((bc, ba, br), (fc, fa, fr)):
        sl = (slice(r[1] - y0, r[3] - y0), slice(r[0] - x0, r[2] - x0))
        take = a >= np.maximum(alpha[sl], 0.5) if c is fc else a > alpha[sl]
        rgb[sl] = np.where(take[..., None], c, rgb[sl])
        alpha[sl] = np.maximum(alpha[sl], a)
    return rgb, alpha, (x0, y0, x1, y1)


def _edges(labels: np.ndarray) -> np.ndarray:
    """Pixels whose 4-neighbourhood holds a different label."""
    e = np.zeros(labels.shape, bool)
    d = labels[1:] != labels[:-1]
    e[1:] |= d
    e[:-1] |= d
    d = labels[:, 1:] != labels[:, :-1]
    e[:, 1:] |= d
    e[:, :-1] |= d
    return e


def _jump(rgb: np.ndarray) -> np.ndarray:
    """Largest colour difference (max over channels, 0..255) of each pixel to its 4-neighbours."""
    j = np.zeros(rgb.shape[:2], np.float32)
    d = np.abs(rgb[1:] - rgb[:-1]).max(axis=-1)
    j[1:] = np.maximum(j[1:], d)
    j[:-1] = np.maximum(j[:-1], d)
    d = np.abs(rgb[:, 1:] - rgb[:, :-1]).max(axis=-1)
    j[:, 1:] = np.maximum(j[:, 1:], d)
    j[:, :-1] = np.maximum(j[:, :-1], d)
    return j


def _fan_layers(model: BillboardModel, i: int, camera: Camera, warper: Warper, cw: CameraWeights,
                config: BlendConfig, centers: dict, free_deg: dict, sections: dict, px_per_m_i: float) -> list:
    """The billboards of fan ``i`` brought into the view, each with its camera index.

    Parameters
    ----------
    model : BillboardModel
    i : int
        The fan.
    camera : Camera
        The view.
    warper : Warper
    cw : CameraWeights
        The fans' camera weights for the view.
    config : BlendConfig
    centers : dict of str to ndarray of shape (3,)
        The source cameras' centres by name, metres.
    free_deg : dict of int to float
        Free turning angle per part, degrees.
    sections : dict of int to ndarray
        Cross-section ratios of the parts that have them.
    px_per_m_i : float
        Image scale at the fan, pixels per metre.

    Returns
    -------
    list of (int, tuple)
        ``(camera index, (rgb, alpha, (x0, y0, x1, y1)))`` per billboard drawn (the warper's output).
    """
    fan = model.fans[i]
    names = model.rig.names
    weight = cw.weight  # (F, C): omega * f (fade folded into alpha below)
    eye = camera.center
    layers = []
    depth_m = config.thickness * part_depth(fan) if config.face_view and config.thickness > 0 else 0.0
    widths = view_widths(fan, centers, eye) if config.face_view and config.view_width else {}
    ratio = sections.get(fan.part)
    if config.face_view and ratio is not None:
        widths = section_widths(fan, centers, eye, model.joints, ratio) or widths
    for b in fan.billboards:
        j = names.index(b.camera)
        if cw.fade[i, j] <= 0 or (weight[i, j] <= 0 and j != cw.nearest[i]):
            continue
        pose = facing_pose(b, eye, free_deg.get(b.part, config.turn_free_deg)) if config.face_view else None
        if pose is not None and widths:  # the part's width from this view, not the source's
            k = 1.0 + (widths.get(b.camera, 1.0) - 1.0) * (1.0 - float(omega(cw.beta[i, j], config.angle_sigma)))
            pose = stretch_across(pose, b, k)
        got = warper(b, camera, pose)
        back_m = depth_m * _steeper(b, model.rig.centers[j], eye) if pose is not None else 0.0
        if back_m * px_per_m_i >= MIN_BACK_PX:  # the part's far side, seen by a view steeper than the source
            got = _front_over_back(got, warper(b, camera, behind_pose(pose, b, eye, back_m)))
        if got is None:
            continue
        if getattr(b, "borrowed", False):  # a stand-in its source did not see: faded out near that source,
            keep = np.float32(1.0 - float(omega(cw.beta[i, j], BORROW_FADE_SIGMA)))
            got = (got[0], got[1] * keep, got[2])
            if b.original is not None:  # under what that source did see of the limb
                o = b.original
                po = facing_pose(o, eye, free_deg.get(o.part, config.turn_free_deg)) if config.face_view else None
                got = _front_over_back(warper(o, camera, po), got)
            if got is None:
                continue
        layers.append((j, got))
    return layers


def _blend_fan(layers: list, i: int, cw: CameraWeights, config: BlendConfig):
    """Blend the layers of fan ``i``: colour by eq. 8, alpha by eq. 10, weights eq. 9.

    Parameters
    ----------
    layers : list of (int, tuple)
        From :func:`_fan_layers` (not empty).
    i : int
        The fan.
    cw : CameraWeights
    config : BlendConfig

    Returns
    -------
    box : tuple of int
        ``(x0, y0, x1, y1)`` of the blend in the view, pixels.
    colour : ndarray of shape (h, w, 3), float32
    a_v : ndarray of shape (h, w), float32
        Alpha 0..1.
    dom : ndarray of shape (h, w), int8
        The camera of the largest weight per pixel (-1 none).
    """
    x0 = min(g[2][0] for _, g in layers)
    y0 = min(g[2][1] for _, g in layers)
    x1 = max(g[2][2] for _, g in layers)
    y1 = max(g[2][3] for _, g in layers)
    shape = (y1 - y0, x1 - x0)
    num = np.zeros(shape + (3,), np.float32)
    den = np.zeros(shape, np.float32)
    a_num = np.zeros(shape, np.float32)
    a_den = np.zeros(shape, np.float32)
    a_near = np.zeros(shape, np.float32)
    best = np.zeros(shape, np.float32)
    dom = np.full(shape, -1, np.int8)
    for j, (c, a, (lx0, ly0, lx1, ly1)) in layers:
        sl = (slice(ly0 - y0, ly1 - y0), slice(lx0 - x0, lx1 - x0))
        if config.binary_alpha:
            a = (a >= 0.5).astype(np.float32)
        a = a * np.float32(cw.fade[i, j])
        wj = a * np.float32(cw.omega[i, j] * cw.attenuation[i, j])  # eq. 9
        num[sl] += c * wj[..., None]
        den[sl] += wj
        a_num[sl] += a * wj
        a_den[sl] += a * np.float32(cw.omega[i, j])
        if j == cw.nearest[i]:
            a_near[sl] = a
        better = wj > best[sl]
        best[sl] = np.where(better, wj, best[sl])
        dom[sl] = np.where(better, j, dom[sl])
    colour = num / np.maximum(den, 1e-12)[..., None]  # eq. 8
    a_v = np.where(a_near > 0, a_near, a_num / np.maximum(a_den, 1e-12))  # eq. 10
    a_v = np.where(den > 1e-12, np.clip(a_v, 0.0, 1.0), 0.0).astype(np.float32)
    return (x0, y0, x1, y1), colour, a_v, dom


def _discontinuities(rgb: np.ndarray, alpha: np.ndarray, top: np.ndarray, dominant: np.ndarray, drawn_box: tuple,
                     model: BillboardModel, camera: Camera, config: BlendConfig) -> tuple[np.ndarray, np.ndarray]:
    """The discontinuities of the render and their smoothing (``rgb`` and ``alpha`` changed in place).

    Parameters
    ----------
    rgb : ndarray of shape (H, W, 3), float32
    alpha : ndarray of shape (H, W), float32
    top : ndarray of shape (H, W), uint8
        Top fan's part per pixel (0 none).
    dominant : ndarray of shape (H, W), int8
        Camera of the largest weight per pixel.
    drawn_box : tuple of int
        ``(x0, y0, x1, y1)`` of everything drawn, one pixel wider, clipped to the image.
    model : BillboardModel
    camera : Camera
        The view.
    config : BlendConfig

    Returns
    -------
    disc : ndarray of shape (H, W), bool
        The discontinuities.
    smoothed : ndarray of shape (H, W), bool
        The band smoothed around them.
    """
    h_img, w_img = top.shape
    bx0, by0, bx1, by1 = drawn_box
    box = (slice(by0, by1), slice(bx0, bx1))
    disc = np.zeros((h_img, w_img), bool)
    smoothed = np.zeros_like(disc)
    # subject against background: always; between fans or where another camera takes over: only where
    # the colour actually jumps (a visible seam), so the inside of a part stays sharp
    t_box = top[box]
    inner = (_edges(t_box) & (t_box > 0)) | (_edges(dominant[box]) & (t_box > 0))
    disc[box] = _edges(t_box > 0) | (inner & (_jump(rgb[box]) > config.smoothing_min_jump))
    # smoothing strength: 0 on a source camera (exact reproduction), -> 1 far from all of them
    strength = float(attenuation(np.min(np.linalg.norm(model.rig.centers - camera.center, axis=1)),
                                 config.attenuation_sigma_m))
    if config.smoothing and strength > 0 and disc[box].any():
        pad = config.smoothing_band_px + int(np.ceil(3 * config.smoothing_sigma_px)) + 1
        sl = (slice(max(by0 - pad, 0), min(by1 + pad, h_img)), slice(max(bx0 - pad, 0), min(bx1 + pad, w_img)))
        k = 2 * config.smoothing_band_px + 1
        band = cv2.dilate(disc[sl].astype(np.uint8), np.ones((k, k), np.uint8)) > 0
        stack = np.dstack([rgb[sl], alpha[sl]])
        blur = cv2.GaussianBlur(stack, (0, 0), config.smoothing_sigma_px, borderType=cv2.BORDER_REPLICATE)
        mix = (band * np.float32(strength))[..., None]
        stack = stack + mix * (blur - stack)
        rgb[sl] = stack[..., :3]
        alpha[sl] = stack[..., 3]
        smoothed[sl] = band
    return disc, smoothed


def composite(model: BillboardModel, camera: Camera, warper: Warper, config: BlendConfig = BlendConfig(),
              observer: Observer | None = None, frame: int | None = None) -> RenderResult:
    """Render the billboard model into ``camera`` with view-dependent blending.

    Parameters
    ----------
    model : BillboardModel
    camera : Camera
        The view (virtual, or a source camera as ``model.rig`` holds it: corrected by stage 1's offsets).
    warper : Warper
        How one billboard is brought into the view.
    config : BlendConfig
    observer : Observer, optional
        Receives ``mask`` (discontinuities), ``labels`` (top fan per pixel) and a
        ``scalar`` per camera weight of the view.
    frame : int, optional
        Frame index for the reports.

    Returns
    -------
    RenderResult
        Empty (alpha 0, ``status`` saying why) when nothing can be drawn.
    """
    w_img, h_img = camera.size
    rgb = np.zeros((h_img, w_img, 3), np.float32)
    alpha = np.zeros((h_img, w_img), np.float32)
    top = np.zeros((h_img, w_img), np.uint8)
    dominant = np.full((h_img, w_img), -1, np.int8)
    if not model.fans or not model.billboards:
        z = np.zeros((h_img, w_img), bool)
        return RenderResult(rgb, alpha, top, dominant, z, z, None, (), STATUS_EMPTY_MODEL)
    names = model.rig.names
    cw = fan_weights(model, camera, config)
    depth = camera.depth_of(np.array([f.axis.mean(axis=0) for f in model.fans]))
    px_per_m = float(camera.K[0, 0]) / np.maximum(depth, 1e-6)  # image scale at each fan
    order = [i for i in np.argsort(-depth, kind="stable") if depth[i] > 0]
    drawn = []
    centers = dict(zip(names, model.rig.centers))
    free_deg = config.free_angles_deg()
    sections = config.section_ratio_ids()
    bx0, by0, bx1, by1 = w_img, h_img, 0, 0  # box of everything drawn
    for i in order:
        fan = model.fans[i]
        layers = _fan_layers(model, i, camera, warper, cw, config, centers, free_deg, sections, px_per_m[i])
        if not layers:
            continue
        (x0, y0, x1, y1), colour, a_v, dom = _blend_fan(layers, i, cw, config)
        bx0, by0, bx1, by1 = min(bx0, x0), min(by0, y0), max(bx1, x1), max(by1, y1)
        sl = (slice(y0, y1), slice(x0, x1))
        rgb[sl] = colour * a_v[..., None] + rgb[sl] * (1.0 - a_v[..., None])  # fans occlude: "over"
        alpha[sl] = a_v + alpha[sl] * (1.0 - a_v)
        on = a_v >= 0.5
        top[sl] = np.where(on, np.uint8(fan.part), top[sl])
        dominant[sl] = np.where(on, dom, dominant[sl])
        drawn.append(fan.part)
    if not drawn:
        z = np.zeros((h_img, w_img), bool)
        return RenderResult(rgb, alpha, top, dominant, z, z, cw, (), STATUS_ALL_BEHIND)
    # discontinuities, inside the box of what was drawn (one pixel more for the background border)
    bx0, by0, bx1, by1 = max(bx0 - 1, 0), max(by0 - 1, 0), min(bx1 + 1, w_img), min(by1 + 1, h_img)
    disc, smoothed = _discontinuities(rgb, alpha, top, dominant, (bx0, by0, bx1, by1), model, camera, config)
    result = RenderResult(rgb, alpha, top, dominant, disc, smoothed, cw, tuple(drawn))
    obs = as_observer(observer)
    extra = {} if frame is None else {"frame": frame}
    obs.report("mask", camera=camera.name, mask=disc, name="render/discontinuities", **extra)
    obs.report("labels", camera=camera.name, labels=top, name="render/fans", **extra)
    for j, n in enumerate(names):
        obs.report("scalar", name=f"render/{camera.name}/weight/{n}",
                   value=float(np.mean(cw.weight[:, j])), **extra)
    return result


def composite_subjects(layers: list, depths, background: np.ndarray) -> np.ndarray:
    """Composite several rendered subjects over a background, farthest first.

    Parameters
    ----------
    layers : list of RenderResult
        One per subject, all of the same view.
    depths : sequence of float
        Each subject's distance along the view's optical axis (e.g. the depth of its pelvis), metres.
    background : ndarray of shape (H, W, 3)
        uint8 or float 0..255.

    Returns
    -------
    ndarray of shape (H, W, 3), uint8
    """
    bg = np.asarray(background, np.float32)
    if len(layers) != len(depths):
        raise InputError("composite_subjects: depths", f"{len(layers)} depths (one per layer)", f"{len(depths)}")
    out = bg.copy()
    for i in np.argsort(-np.asarray(depths, float), kind="stable"):
        r = layers[i]
        if r.rgb.shape != out.shape:
            raise InputError(f"composite_subjects: layers[{i}]", f"shape {out.shape}", f"shape {r.rgb.shape}")
        out = r.rgb + (1.0 - r.alpha[..., None]) * out
    return np.clip(out + 0.5, 0, 255).astype(np.uint8)
