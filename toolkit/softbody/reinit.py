"""3D joints from 2D keypoints detected in calibrated views: where the soft body starts or starts again.

A stereo sequence needs 14 joints of one frame to scale and pose the model
(:func:`toolkit.softbody.model_from_joints`), and a tracker that has lost the
person needs a pose near the truth to find them again.  Both come from the
images themselves here: a 2D keypoint detector (the project's BlazePose,
:mod:`toolkit.detection`, run by :mod:`toolkit.pipeline.soft_body_sources`)
on one camera per stereo head, mapped to the 14 joints, and triangulated
across the heads (:func:`toolkit.cameras.triangulation.triangulate_linear`).

A detector's commonest mistake in a side view is a limb pair labelled the
wrong way round (the left knee called right): one view's swapped labels make
rays that do not meet, so each view's arms and legs are tried both ways and
the labelling whose triangulation reprojects best is kept
(:func:`triangulate_views`).  Swapping every view's labels reprojects as well
(a mirrored labelling of the same points).  Two heads at one height tell
a swap poorly (their epipolar lines run along the image rows: swapped arms
hanging beside the trunk triangulate inside the body), so the previous pose,
when there is one, weighs in (joints moved further than ``REACH_M`` cost)
and makes the mirrored choice (the labelling nearest to it); without one the
cloud (joints off the body cost), the left and right bones' lengths and the
anatomy (hips and shoulders agreeing on the left side, knees bending forward:
:func:`toolkit.multiview.anatomy.chirality_score`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from toolkit.cameras.triangulation import reprojection_errors, triangulate_linear
from toolkit.errors import InputError
from toolkit.multiview.selection import flip_permutation
from toolkit.skeleton import SKELETON_14

__all__ = ["ViewJoints", "triangulate_views", "fill_hanging_limbs", "LIMB_GROUPS", "MAX_REPROJECTION_PX", "MIN_CONFIDENCE"]

#: Limb pairs whose left and right labels a detector may swap together, per view.
LIMB_GROUPS = {"arms": ("shoulder", "elbow", "wrist"), "legs": ("hip", "knee", "ankle")}
#: A keypoint with a lower detector confidence is left out of the triangulation.
MIN_CONFIDENCE = 0.3
#: A triangulated joint whose median reprojection error (pixels) is larger is dropped (NaN): a keypoint
#: the views do not agree on (about 5 cm at 3 m on 320 x 240 images).
MAX_REPROJECTION_PX = 12.0
#: Reprojection errors above this (pixels) count as this much in the choice of the labelling (one wild
#: keypoint must not decide it).
_ERROR_CLIP_PX = 40.0
#: A joint lies inside the body: up to this far from the nearest point of the body's cloud (metres) ...
INSIDE_M = 0.1
#: ... and further out, or a left bone longer than its right one, costs this many pixels per metre.
PX_PER_M = 200.0
#: A joint may have moved this far from the previous pose (metres) at no cost: the limbs' swing over a few
#: frames.  Heads at one height see swapped arms hanging beside the trunk as well as the right ones (their
#: epipolar lines run along the image rows and the points land inside the body): the previous pose decides.
REACH_M = 0.2
#: A joint's distance off the body or move beyond :data:`REACH_M` counts as at most this (metres), as
#: :data:`_ERROR_CLIP_PX` for the reprojection errors: one wild joint must not decide the labelling.
_EXCESS_CAP_M = 0.5


def _swap_index(groups) -> np.ndarray:
    """Joint order (14,) with the left and right joints of ``groups`` (names of :data:`LIMB_GROUPS`) swapped."""
    idx = np.arange(SKELETON_14.n_joints)
    for g in groups:   # the groups' joints are disjoint: the order does not matter
        idx = idx[flip_permutation(SKELETON_14, g)]
    return idx


_SWAPS = {combo: _swap_index(combo) for n in range(3) for combo in itertools.combinations(LIMB_GROUPS, n)}


@dataclass(frozen=True)
class ViewJoints:
    """Joints triangulated from detections in several views (:func:`triangulate_views`).

    Attributes
    ----------
    joints : ndarray of shape (14, 3)
        Metres, world, ``SKELETON_14`` order; NaN where fewer than two views agree.
    reprojection_px : ndarray of shape (14,)
        Median reprojection error of each joint over the views that saw it, pixels (NaN where dropped).
    swapped : tuple of tuple of str
        Per view, the limb groups whose labels were swapped.
    """

    joints: np.ndarray
    reprojection_px: np.ndarray
    swapped: tuple

    @property
    def complete(self) -> bool:
        """Whether every joint was triangulated (what :func:`toolkit.softbody.model_from_joints` needs)."""
        return bool(np.isfinite(self.joints).all())

    def __bool__(self) -> bool:
        return self.complete


def _labelling_cost(cameras, pts: np.ndarray, tree=None, previous=None) -> tuple[float, np.ndarray, np.ndarray]:
    """Cost (pixels) of one labelling: clipped reprojection errors, the joints' distance outside the cloud's
    body, the left/right difference of the limb bones and how far the joints moved from ``previous`` beyond
    :data:`REACH_M`; with the triangulated joints and errors."""
    X = triangulate_linear(list(cameras), pts)
    err = reprojection_errors(list(cameras), X, pts)   # NaN where the joint or the keypoint is missing
    given = np.isfinite(pts).all(-1)
    # every keypoint given counts (one whose joint is not triangulated costs the clip): hiding a keypoint
    # by pairing it with a missing one is no cheaper
    cost = float(np.sum(np.minimum(np.where(np.isfinite(err), err, _ERROR_CLIP_PX), _ERROR_CLIP_PX)[given]))
    ok = np.isfinite(X).all(-1)
    if tree is not None and ok.any():
        # two views' rays nearly meet for swapped labels too (the epipolar lines of heads at one height run
        # along the image rows): such a joint lands off the body, where the cloud has no point
        d, _ = tree.query(X[ok])
        cost += PX_PER_M * float(np.sum(np.minimum(np.maximum(d - INSIDE_M, 0.0), _EXCESS_CAP_M)))
    if previous is not None and ok.any():
        moved = np.linalg.norm(X[ok] - previous[ok], axis=-1)
        cost += PX_PER_M * float(np.sum(np.minimum(np.maximum(moved - REACH_M, 0.0), _EXCESS_CAP_M)))
    L = SKELETON_14.bone_lengths(X)
    for a, b in SKELETON_14.symmetric_bones:
        if np.isfinite(L[a]) and np.isfinite(L[b]):
            cost += PX_PER_M * abs(L[a] - L[b])
    return cost, X, err


def _anatomy_score(X: np.ndarray) -> float:
    """Higher for labels the right way round: hips and shoulders agreeing on the left side (metres of
    agreement), knees forward and elbows back (:func:`toolkit.multiview.anatomy.chirality_score`)."""
    from toolkit.multiview.anatomy import chirality_score

    j = {n: X[SKELETON_14.index(n)] for n in ("l_hip", "r_hip", "l_shoulder", "r_shoulder")}
    agree = float(np.dot(j["l_hip"] - j["r_hip"], j["l_shoulder"] - j["r_shoulder"]))
    return (agree if np.isfinite(agree) else 0.0) + float(chirality_score(np.nan_to_num(X)))


def triangulate_views(points2d, confidence, cameras, *, previous=None, cloud=None, min_confidence: float = MIN_CONFIDENCE,
                      max_error_px: float = MAX_REPROJECTION_PX) -> ViewJoints:
    """14 joints triangulated from one detection per view, each view's limb labels tried both ways.

    Parameters
    ----------
    points2d : array_like of shape (C, 14, 2)
        Pixels per view (``SKELETON_14`` order, e.g. :func:`toolkit.skeleton.mappings.to_skeleton14` of a
        detector's keypoints); NaN where a view has no keypoint.
    confidence : array_like of shape (C, 14)
        The detector's confidence per keypoint in [0, 1]; keypoints under ``min_confidence`` are left out.
    cameras : sequence of C toolkit.cameras.Camera
        Calibrated, in the world frame of the result; at least two.
    previous : array_like of shape (14, 3), optional
        Joints of a nearby frame (metres): the mirrored labellings are told apart by it.
    cloud : array_like of shape (N, 3), optional
        The frame's points of the body (metres, world): a labelling whose joints lie off it costs more.
    min_confidence : float
    max_error_px : float
        Joints whose median reprojection error exceeds this are dropped (NaN).

    Returns
    -------
    ViewJoints
        Falsy when some joint could not be triangulated.

    Raises
    ------
    InputError
        Arrays of the wrong shape, fewer than two cameras.
    """
    pts = np.array(points2d, float)
    conf = np.asarray(confidence, float)
    n_views = len(cameras)
    if n_views < 2:
        raise InputError("cameras", "at least two calibrated views", f"{n_views}")
    if pts.shape != (n_views, SKELETON_14.n_joints, 2):
        raise InputError("points2d", f"shape ({n_views}, 14, 2) (one row of 14 joints per camera), pixels",
                         f"shape {pts.shape}")
    if conf.shape != pts.shape[:2]:
        raise InputError("confidence", f"shape {pts.shape[:2]}", f"shape {conf.shape}")
    pts[~(conf >= min_confidence)] = np.nan
    prev = None if previous is None else np.asarray(previous, float)
    if prev is not None and (prev.shape != (SKELETON_14.n_joints, 3) or not np.isfinite(prev).all()):
        raise InputError("previous", "finite joints of shape (14, 3), metres", f"shape {prev.shape}")
    names = list(_SWAPS)
    tree = None
    if cloud is not None and len(cloud):
        from scipy.spatial import cKDTree

        tree = cKDTree(np.asarray(cloud, float).reshape(-1, 3))
    best = None
    # every view's arms and legs tried both ways (without a previous pose, the first view's labels stand:
    # the mirrored labellings are told apart below)
    first = names if prev is not None else [()]
    for combo in itertools.product(first, *[names] * (n_views - 1)):
        trial = np.stack([pts[c][_SWAPS[s]] for c, s in enumerate(combo)])
        cost, X, err = _labelling_cost(cameras, trial, tree, prev)
        if best is None or cost < best[0] - 1e-9:
            best = (cost, combo, X, err)
    _, swapped, X, err = best
    # the same points under each group's mirrored labels in every view: told apart by the previous pose or
    # by the anatomy
    options = []
    for s in names:
        Xs = X[_SWAPS[s]]
        if prev is not None:
            moved = np.linalg.norm(Xs - prev, axis=-1)
            score = -float(np.mean(moved[np.isfinite(moved)])) if np.isfinite(moved).any() else 0.0
        else:
            score = _anatomy_score(Xs)
        options.append((score, s))
    score, s = max(options, key=lambda o: o[0])
    X, err = X[_SWAPS[s]], err[:, _SWAPS[s]]
    swapped = tuple(tuple(sorted(set(v) ^ set(s))) for v in swapped)
    n_seen = np.isfinite(err).sum(axis=0)
    med = np.full(len(n_seen), np.inf)
    for j in np.flatnonzero(n_seen >= 2):
        med[j] = float(np.median(err[np.isfinite(err[:, j]), j]))
    X = np.where((med <= max_error_px)[:, None], X, np.nan)
    return ViewJoints(X, np.where(med <= max_error_px, med, np.nan), swapped)


#: Limb chains (parent, child) filled by :func:`fill_hanging_limbs`, with the median body's bone length as a
#: share of stature (used when the other side's bone is missing too).
_CHAINS = (("shoulder", "elbow", 0.186), ("elbow", "wrist", 0.146), ("hip", "knee", 0.245), ("knee", "ankle", 0.246))


def fill_hanging_limbs(joints, stature: float = 1.75) -> np.ndarray:
    """Missing elbows, wrists, knees and ankles placed straight below their parent joint.

    A detector misses an arm or a leg hidden behind the body; the start of a fit needs every joint.  The
    missing joint hangs below its parent (world z up) at the other side's bone length, or the median
    body's for ``stature``; the fit to the points and silhouettes then moves it.

    Parameters
    ----------
    joints : array_like of shape (14, 3)
        Metres, world, ``SKELETON_14`` order, NaN where missing.
    stature : float
        Metres.

    Returns
    -------
    ndarray of shape (14, 3)
        NaN only where a head, neck, shoulder or hip was missing (or a limb's parent).
    """
    j = np.array(joints, float)
    if j.shape != (SKELETON_14.n_joints, 3):
        raise InputError("joints", "shape (14, 3), metres", f"shape {j.shape}")
    ok = lambda name: np.isfinite(j[SKELETON_14.index(name)]).all()  # noqa: E731
    for parent, child, share in _CHAINS:
        for side, other in (("l_", "r_"), ("r_", "l_")):
            if ok(side + child) or not ok(side + parent):
                continue
            length = share * stature
            if ok(other + parent) and ok(other + child):
                length = float(np.linalg.norm(j[SKELETON_14.index(other + child)] - j[SKELETON_14.index(other + parent)]))
            j[SKELETON_14.index(side + child)] = j[SKELETON_14.index(side + parent)] - [0.0, 0.0, length]
    return j
