"""How far a tracked frame can be trusted: residuals, coverage, silhouettes and motion of the fitted model.

A tracker that has lost the person still returns a pose, and the tracker's
own inlier fraction alone does not say so: the model may fit the points near
it well (a leg on the other leg's points, the trunk on the near side of the
body) while a whole limb or half the body is elsewhere.  Four measures of
the fitted pose, each a fraction in [0, 1], see different failures:

* **residuals**: the share of the points within ``residual_gate`` of the
  fitted surface that lie within ``inlier_distance`` of it (points the model
  does not explain: it lies beside the body); the tracker passes the points
  it fitted, those it took for the subject's (:mod:`toolkit.softbody.separate`:
  not another person's; a limb the tracker lost and took for another body
  shows in the coverage and the silhouettes);
* **coverage**: the share of the model's surface facing a camera that has a
  point of the cloud within ``coverage_distance`` (model parts where the
  cameras see no body: a limb swung out into empty space);
* **silhouettes**: per camera with a mask, the least of the share of the
  mask's outline rays passing within ``outline_distance`` of the model, of
  those within ``residual_gate`` of it (the person's outline explained;
  another person's outline in the same mask left out) and, per rigid part of the model (trunk, head,
  each limb segment), the share of its unburied surface samples projecting
  into the mask (the part where the camera sees the person; an occluded limb
  still projects into the mask of what hides it); the least over the cameras (one camera that sees the model off the
  person is enough to doubt the frame);
* **missed outline**: per camera, the share of the outline rays within
  ``residual_gate`` of the model passing ``missed_distance`` or further from
  it (those passing near points not taken for the subject's left out:
  another person touching it), the largest over the cameras.  A limb the
  model holds in the wrong place while the true one sticks out of the
  body's outline (arms raised in a jump, swung in a run) leaves 5-18 % of a
  camera's outline rays 0.1-0.25 m from the model while the shares above
  stay at a tracked frame's level.

The silhouette measures come from what the silhouette block of tracking uses
(:mod:`toolkit.softbody.silhouette`), at about a tenth of the cost of drawing
the model's own silhouette.

A fifth measure needs the last trusted frame's joints (``previous``):

* **motion**: the largest move of a joint against the body (the pelvis's
  frame: hips and neck) per frame since the last trusted frame, metres per
  frame.  A tracker can jump a limb with few points of its own (a forearm
  without texture, a hand) onto another limb's or the trunk's points in one
  frame, and then hold it there while every share above stays at a tracked
  frame's level: the jump is what shows.  A fit that comes from the frame's
  own joints (a re-initialisation) is measured without it.

and one more, measured on every fit (those from the frame's own joints too):

* **heading**: how far the body's heading (the horizontal direction it faces, from its hips and
  shoulders: :func:`body_heading`) turned since the last trusted frame (radians).  Front and back look
  alike to one depth camera, and a model facing away from the person fits the side it sees; in its own
  frame the flipped body's joints barely move, so the motion measure does not see it.  A person turns
  at most ``turn_rate`` per frame; beyond ``lost_turn`` plus that the frame is lost.

The frame's **confidence** is the least of the shares, each divided by its
``trusted_*`` level (clipped to 1; the motion's share: ``trusted_step``
over the move; the missed outline's: the explained share over its lost
level, so that it only says lost or not), 1 when every measure reaches its
level.  A frame is **lost** when any measure falls below its ``lost_*``
level (the move above ``lost_step``, the missed outline above
``lost_missed_outline``), and **trusted** otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from toolkit.errors import InputError
from toolkit.softbody.distance import distance
from toolkit.softbody.model import SoftBodyModel, SoftBodyParams

__all__ = ["ConfidenceConfig", "FrameConfidence", "frame_confidence", "body_frame_joints", "joint_steps",
           "largest_step", "body_heading", "heading_change",
           "VERDICTS"]

#: What a frame's confidence says.
VERDICTS = ("trusted", "lost")

#: A metaball's surface sample further than this inside the model (metres) is buried in another metaball:
#: no camera sees it, so it is left out of the silhouette share.
BURIED_DEPTH = 0.01
#: Fewest unburied surface samples a rigid part needs for a silhouette share of its own (fewer: too few to
#: say the part lies out of the mask).
MIN_PART_SAMPLES = 5


@dataclass(frozen=True)
class ConfidenceConfig:
    """Levels of :func:`frame_confidence`.

    Attributes
    ----------
    inlier_distance : float
        A point within this of the fitted surface is explained, metres.
    residual_gate : float
        Points and outline rays further than this from the fitted surface are left out of the residual and
        outline measures, metres (another body, clutter).
    coverage_distance : float
        A model surface sample with a cloud point within this is covered, metres.
    coverage_dirs : int
        Surface samples per metaball.
    outline_distance : float
        A camera ray through the mask's outline passing this close to the model's surface is explained,
        metres.
    mask_margin_px : float
        A model surface sample projecting this close to the mask (pixels) lies in it.
    lost_residual, lost_coverage, lost_silhouette : float
        A frame whose share of explained points, of covered surface or whose least silhouette IoU is below
        this is lost.
    trusted_residual, trusted_coverage, trusted_silhouette : float
        The levels that count as full confidence (1).
    missed_distance : float
        An outline ray within ``residual_gate`` of the model passing this far or further from it (and not
        this near to points taken for other bodies') is missed, metres.
    lost_missed_outline : float
        A frame where more than this share of a camera's outline rays is missed is lost (the measure only
        says lost or not).  Set on the trinocular runs of seed 21000 (``bench_softbody --motions
        walk,run,jump,turn --frames 30``): of the 95 tracked frames within 60 mm of the truth none had more
        than 0.039 of a camera's outline rays missed, 19 of the 25 frames over 60 mm more than 0.05 (the
        jump's raised arms, the run's swung forearm).
    lost_step, trusted_step : float
        A joint moving further than ``lost_step`` against the body per frame since the last trusted frame
        (metres per frame) makes the frame lost; moves up to ``trusted_step`` count as full confidence
        (the same by default: the move only says lost or not, and a fast limb alone does not make a frame
        doubtful).  Set on the runs of seed 21000 (``bench_softbody --motions walk,run,jump,turn --frames
        30``, 25 and 30 fps): the true joints move at most 0.19 m per frame against the body (the ankles of
        the runs; wrists 0.12 m), tracked frames' fits up to 0.22 m; the stereo runner's forearm with few
        points of its own jumped 0.51 m in one frame and stayed off (0.2-0.7 m) at full confidence
        otherwise.
    lost_turn, turn_rate : float
        A frame whose body heading (:func:`body_heading`) turned further than ``lost_turn + turn_rate * n``
        (radians) from the last trusted frame's, ``n`` frames before, is lost (the measure says lost or
        not).  ``turn_rate`` (0.3 rad per frame: 430 degrees per second at 25 fps) is above what a person
        turns (the scene generator's turns reach 3.1 rad/s, its walks and runs 3.8 rad/s: 0.15 rad per
        frame at 25 fps); ``lost_turn`` (0.5 rad) allows for the fit's error in the hips' and shoulders'
        line.  A body flipped front to back (pi) is lost up to 8 frames after the last trusted frame.
        Tried and not kept: 0.15 rad per frame with the re-initialisations also tried turned round (a 300-frame
        depth walk, ``bench_softbody --sources depth --motions walk,run --frames 300 --seed 27000``, took a
        turned-round start 11 frames after its last trusted frame, when the person had turned by 61 degrees
        (the flipped fit 118 degrees from the last trusted one), and kept it: 32.3 -> 300.5 mm).
    other_body_extent : float
        Points not taken for the subject's count as another body's (their outline rays no miss) only in
        pieces (points linked within :data:`OTHER_LINK`) at least this long (the diagonal of their bounding
        box, metres): a second person, the floor.  A smaller piece beyond the tracker's gate is more likely
        the subject's own limb the model left (arms raised in a jump: 53-88 patch centres); its outline
        rays count as missed.  0: every piece is another body's.

    Notes
    -----
    The levels were set on a 30-frame trinocular walk (seed 20500 of ``bench_softbody --motions walk
    --frames 30 --seed 20000``): its tracked frames (36-45 mm from the truth) had 0.97-0.99 of the
    points explained, 0.68-0.78 of the surface covered and silhouettes of 0.87-0.94; the same frames
    fitted from starts moved 0.25-0.4 m or with every angle off by 0.5 rad (59-308 mm from the truth)
    0.48-0.65 covered or silhouettes of 0.30-0.64 (the points stay explained: the fit sits on part of
    the body).
    """

    inlier_distance: float = 0.05
    residual_gate: float = 0.25
    coverage_distance: float = 0.05
    coverage_dirs: int = 24
    outline_distance: float = 0.03
    mask_margin_px: float = 2.0
    lost_residual: float = 0.9
    lost_coverage: float = 0.35
    lost_silhouette: float = 0.6
    trusted_residual: float = 0.97
    trusted_coverage: float = 0.7
    trusted_silhouette: float = 0.8
    missed_distance: float = 0.1
    lost_missed_outline: float = 0.05
    lost_step: float = 0.3
    trusted_step: float = 0.3
    lost_turn: float = 0.5
    turn_rate: float = 0.3
    other_body_extent: float = 1.0

    def __post_init__(self):
        for name in ("inlier_distance", "residual_gate", "coverage_distance", "missed_distance"):
            if not getattr(self, name) > 0:
                raise InputError(f"ConfidenceConfig.{name}", "a positive distance in metres", repr(getattr(self, name)))
        for kind in ("residual", "coverage", "silhouette"):
            lo, hi = getattr(self, f"lost_{kind}"), getattr(self, f"trusted_{kind}")
            if not 0.0 <= lo < hi <= 1.0:
                raise InputError(f"ConfidenceConfig.lost_{kind}/trusted_{kind}", "0 <= lost < trusted <= 1",
                                 f"{lo}, {hi}")
        if not 0.0 <= self.lost_missed_outline < 1.0:
            raise InputError("ConfidenceConfig.lost_missed_outline", "a share in [0, 1)",
                             repr(self.lost_missed_outline))
        if not self.other_body_extent >= 0:
            raise InputError("ConfidenceConfig.other_body_extent", "a length >= 0 in metres",
                             repr(self.other_body_extent))
        if not (self.lost_turn > 0 and self.turn_rate >= 0):
            raise InputError("ConfidenceConfig.lost_turn/turn_rate", "lost_turn > 0 and turn_rate >= 0 (radians, "
                             "radians per frame)", f"{self.lost_turn}, {self.turn_rate}")
        if not 0.0 < self.trusted_step <= self.lost_step:
            raise InputError("ConfidenceConfig.trusted_step/lost_step", "0 < trusted_step <= lost_step (metres per "
                             "frame)", f"{self.trusted_step}, {self.lost_step}")


class FrameConfidence(NamedTuple):
    """One frame's confidence (:func:`frame_confidence`).

    Attributes
    ----------
    residual, coverage, silhouette : float
        The three fractions in [0, 1]; NaN where not measured (no points; no masks).
    confidence : float
        Least of the measured fractions, each divided by its trusted level, clipped to [0, 1]; 0 without points.
    verdict : str
        One of :data:`VERDICTS`.
    step : float
        The largest move of a joint against the body per frame since the last trusted frame, metres per
        frame (:func:`largest_step`); NaN where not measured.
    missed_outline : float
        The largest share over the cameras of the outline rays passing ``missed_distance`` or further from
        the model; NaN without masks.
    turn : float
        How far the body's heading turned since the last trusted frame (:func:`heading_change`), radians in
        [0, pi]; NaN where not measured.
    turned : bool
        The heading measure alone calls the frame lost (a turn no person makes in that time).
    """

    residual: float
    coverage: float
    silhouette: float
    confidence: float
    verdict: str
    step: float = float("nan")
    missed_outline: float = float("nan")
    turn: float = float("nan")
    turned: bool = False


def body_frame_joints(joints) -> np.ndarray:
    """Joints in the body's own frame: origin the mid-hip point, x from the right hip to the left, z towards
    the neck (orthogonalised), y = z x x.

    Parameters
    ----------
    joints : array_like of shape (..., 14, 3)
        Metres, ``SKELETON_14`` order.

    Returns
    -------
    ndarray of shape (..., 14, 3)
        Metres.
    """
    from toolkit.skeleton import SKELETON_14

    j = np.asarray(joints, float)
    lh, rh, neck = (j[..., SKELETON_14.index(n), :] for n in ("l_hip", "r_hip", "neck"))
    mid = 0.5 * (lh + rh)
    x = lh - rh
    x = x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-9)
    z = neck - mid
    z = z - np.sum(z * x, axis=-1, keepdims=True) * x
    z = z / np.maximum(np.linalg.norm(z, axis=-1, keepdims=True), 1e-9)
    R = np.stack([x, np.cross(z, x), z], axis=-2)   # rows: the body's axes in the world
    return np.einsum("...ab,...jb->...ja", R, j - mid[..., None, :])


def joint_steps(joints, previous) -> np.ndarray:
    """Each joint's move against the body from ``previous`` to ``joints`` (metres).

    Parameters
    ----------
    joints, previous : array_like of shape (14, 3)
        Metres, world.

    Returns
    -------
    ndarray of shape (14,)
        Metres.
    """
    return np.linalg.norm(body_frame_joints(joints) - body_frame_joints(previous), axis=-1)


def largest_step(joints, previous, frames: int = 1) -> float:
    """The largest move of a joint against the body from ``previous`` to ``joints``, per frame (metres).

    Parameters
    ----------
    joints, previous : array_like of shape (14, 3)
        Metres, world.
    frames : int
        Frames between the two (>= 1).

    Returns
    -------
    float
        Metres per frame.
    """
    return float(np.max(joint_steps(joints, previous))) / max(int(frames), 1)


#: Points of other bodies closer than this to each other are one piece (:func:`other_bodies`), metres: a
#: second person half hidden behind the subject leaves fragments 0.2-1.0 m long with gaps under this.
OTHER_LINK = 0.25


def other_bodies(points, min_extent: float, link: float = OTHER_LINK) -> np.ndarray:
    """The points of ``points`` in pieces at least ``min_extent`` long: other bodies, not a limb's piece.

    Parameters
    ----------
    points : array_like of shape (M, 3)
        Points not taken for the subject's, metres.
    min_extent : float
        Least extent of a piece (the diagonal of its bounding box), metres; 0 keeps every point.
    link : float
        Points closer than this are linked into one piece, metres.

    Returns
    -------
    ndarray of shape (K, 3)
        Metres.
    """
    from toolkit.softbody.separate import linked_pieces

    pts = np.asarray(points, float).reshape(-1, 3)
    if min_extent <= 0 or len(pts) == 0:
        return pts
    label = linked_pieces(pts, link)
    n = int(label.max()) + 1
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    np.minimum.at(lo, label, pts)
    np.maximum.at(hi, label, pts)
    return pts[np.linalg.norm(hi - lo, axis=1)[label] >= min_extent]


#: A body whose hips' and shoulders' line is shorter than this horizontally (metres; lying, or the line
#: upright) has no heading.
MIN_HEADING_SPAN = 0.05


def body_heading(joints) -> float:
    """The horizontal direction a body faces, from its hips and shoulders (radians, about z).

    Parameters
    ----------
    joints : array_like of shape (14, 3)
        Metres, world, z up, ``SKELETON_14`` order.

    Returns
    -------
    float
        Radians: the angle from the x axis of :func:`toolkit.multiview.anatomy.facing_direction`;
        NaN where the hips' and shoulders' left-to-right line, summed, is shorter than
        :data:`MIN_HEADING_SPAN` horizontally (lying, or that line upright).
    """
    from toolkit.multiview.anatomy import facing_direction
    from toolkit.skeleton import SKELETON_14

    j = np.asarray(joints, float)
    lr = sum(j[SKELETON_14.index("l_" + p)] - j[SKELETON_14.index("r_" + p)] for p in ("hip", "shoulder"))
    f = facing_direction(j)
    if not (np.isfinite(lr).all() and np.isfinite(f).all()) or np.hypot(lr[0], lr[1]) < MIN_HEADING_SPAN:
        return float("nan")
    return float(np.arctan2(f[1], f[0]))


def heading_change(joints, previous) -> float:
    """How far the body's heading (:func:`body_heading`) turned from ``previous`` to ``joints``.

    Parameters
    ----------
    joints, previous : array_like of shape (14, 3)
        Metres, world.

    Returns
    -------
    float
        Radians in [0, pi]; NaN where either has no heading.
    """
    d = float(body_heading(joints) - body_heading(previous))
    return abs(float(np.angle(np.exp(1j * d)))) if np.isfinite(d) else float("nan")


def _coverage(model: SoftBodyModel, params: SoftBodyParams, tree: cKDTree, config: ConfidenceConfig,
              viewpoints) -> float:
    from toolkit.softbody.residuals import coverage_samples

    samples = coverage_samples(model, params, n_dirs=config.coverage_dirs, viewpoints=viewpoints)
    if len(samples) == 0:
        return float("nan")
    d, _ = tree.query(samples.points(model.state(params)))
    return float(np.mean(d < config.coverage_distance))


def _ray_distances(origins: np.ndarray, directions: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Per ray (R,), the distance of the nearest of ``points`` (M, 3) to it, metres (inf without points)."""
    if len(points) == 0:
        return np.full(len(origins), np.inf)
    u = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    rel = points[None, :, :] - origins[:, None, :]                       # (R, M, 3)
    along = np.maximum(np.einsum("rmk,rk->rm", rel, u), 0.0)
    return np.linalg.norm(rel - along[..., None] * u[:, None, :], axis=-1).min(axis=1)


def _silhouette(model: SoftBodyModel, params: SoftBodyParams, views, config: ConfidenceConfig,
                others: np.ndarray | None = None) -> tuple[float, float]:
    """The silhouette share (least over the cameras) and the missed outline share (largest; outline rays
    passing within ``missed_distance`` of ``others``, points not taken for the subject's, left out), NaN
    without a usable mask."""
    from toolkit.softbody.mesh import unit_directions
    from toolkit.softbody.residuals import CoverageSamples
    from toolkit.softbody.silhouette import ray_minimum

    st = model.state(params)
    n_dirs = config.coverage_dirs
    prims = np.repeat(np.arange(model.n_prims), n_dirs)
    surface = CoverageSamples(prims, np.tile(unit_directions(n_dirs), (model.n_prims, 1))).points(st)
    unburied = distance(model, params, surface, state=st) > -BURIED_DEPTH
    surface, part = surface[unburied], np.asarray(model.prim_frame)[prims[unburied]]
    parts = [part == k for k in np.unique(part) if np.count_nonzero(part == k) >= MIN_PART_SAMPLES]
    shares, missed = [], []
    for v in views:
        if v.state != "ok":
            continue
        _, d = ray_minimum(model, params, v.origins, v.directions, state=st)
        near = np.abs(d) < config.residual_gate   # another person's outline in the same mask: left out
        outline = float(np.mean(np.abs(d[near]) < config.outline_distance)) if near.any() else 0.0
        mine = near.copy()   # another person touching the subject (their points known): their outline is no miss
        if others is not None and len(others) and mine.any():
            mine[mine] = _ray_distances(v.origins[mine], v.directions[mine], others) >= config.missed_distance
        missed.append(float(np.mean(np.abs(d[mine]) >= config.missed_distance)) if mine.any() else 0.0)
        uv = v.camera.project(surface)
        ok = np.isfinite(uv).all(axis=1) & v.camera.in_image(uv, margin=0.0) & (v.camera.depth_of(surface) > 0)
        q = np.round(uv[ok]).astype(int)
        inside = np.zeros(len(surface), bool)
        inside[np.flatnonzero(ok)] = v.outside[q[:, 1], q[:, 0]] <= config.mask_margin_px
        # each rigid part on its own: one limb out in the background is a loss however well the rest fits
        shares.append(min([outline] + [float(np.mean(inside[m])) for m in parts]))
    return (float(min(shares)), float(max(missed))) if shares else (float("nan"), float("nan"))


def frame_confidence(model: SoftBodyModel, params: SoftBodyParams, points, *, silhouettes=None, viewpoints=None,
                     config: ConfidenceConfig = ConfidenceConfig(), previous=None,
                     frames_since: int = 1, others=None, reference=None) -> FrameConfidence:
    """How far one fitted frame can be trusted.

    Parameters
    ----------
    model : SoftBodyModel
    params : SoftBodyParams
        The fitted pose.
    points : array_like of shape (N, 3)
        The frame's points (metres, world); may be empty.
    silhouettes : list of SilhouetteView, optional
        The frame's camera silhouettes.
    viewpoints : array_like of shape (V, 3), optional
        Camera centres (metres): coverage only of the surface facing one.
    config : ConfidenceConfig
    previous : array_like of shape (14, 3), optional
        The last trusted frame's joints (metres, world): the motion measure (:func:`largest_step`); None: not
        measured (a first frame, a fit from the frame's own joints).
    frames_since : int
        Frames since that trusted frame.
    others : array_like of shape (M, 3), optional
        Points not fitted as the subject's (other bodies', undecided ones; metres, world): outline rays passing
        within ``missed_distance`` of them are left out of the missed outline.
    reference : array_like of shape (14, 3), optional
        The last trusted frame's joints (metres, world), ``frames_since`` frames before, for the heading
        measure (:func:`heading_change`), also for a fit from the frame's own joints; None: not measured.

    Returns
    -------
    FrameConfidence
    """
    pts = np.asarray(points, float).reshape(-1, 3)
    nan = float("nan")
    if len(pts) == 0:
        return FrameConfidence(0.0, 0.0, nan, 0.0, "lost")
    d = np.abs(distance(model, params, pts))
    near = d < config.residual_gate
    residual = float(np.mean(d[near] < config.inlier_distance)) if near.any() else 0.0
    coverage = _coverage(model, params, cKDTree(pts), config, viewpoints)
    oth = None if others is None else other_bodies(others, config.other_body_extent)
    sil, missed = _silhouette(model, params, silhouettes, config, oth) if silhouettes else (nan, nan)
    measured = [(residual, config.lost_residual, config.trusted_residual),
                (coverage, config.lost_coverage, config.trusted_coverage),
                (sil, config.lost_silhouette, config.trusted_silhouette)]
    measured = [m for m in measured if np.isfinite(m[0])]
    step = nan if previous is None else largest_step(model.joints(params), previous, frames_since)
    if np.isfinite(step):   # as a share: the trusted move over the move (1 at or below it)
        measured.append((config.trusted_step / max(step, 1e-9), config.trusted_step / config.lost_step, 1.0))
    if np.isfinite(missed):   # the outline explained; full confidence at the lost level (says lost or not)
        measured.append((1.0 - missed, 1.0 - config.lost_missed_outline, 1.0 - config.lost_missed_outline))
    turn = nan if reference is None else heading_change(model.joints(params), reference)
    confidence = float(np.clip(min(v / hi for v, _, hi in measured), 0.0, 1.0))
    lost = any(v < lo for v, lo, _ in measured)
    # says lost or not: a turn no person makes in that time (a front/back flip)
    turned = bool(np.isfinite(turn) and turn > config.lost_turn + config.turn_rate * max(int(frames_since), 1))
    return FrameConfidence(residual, coverage, sil, confidence, "lost" if lost or turned else "trusted", step,
                           missed, turn, turned)
