"""The subject's points in a cloud that holds other bodies too (a second person touching the subject, the floor).

A foreground mask (the depth camera's user mask, a stereo head's foreground)
cuts the subject out of the scene, but a second person touching the subject,
or the floor under its feet, is one blob with it.  The tracked model tells
them apart: its prediction for the frame is close to the subject's points and
far from everybody else's.  With ``d`` the distance of a point to the
predicted model's surface (negative inside):

* ``d < near``: the subject's (``near`` covers the model's misfit plus the
  error of the motion prediction over one frame);
* ``d >= gate``: not the subject (nothing of the subject is that far outside
  its prediction);
* in between: undecided.  Undecided points connected to each other
  (neighbours closer than ``link``) form pieces; a piece is the subject's when
  it touches the subject's points and holds no point beyond the gate (a hand
  that moved faster than predicted, continuous with its arm); a piece that
  reaches beyond the gate is another body's (the near side of a second person,
  continuous with its far side; the floor around the feet); a piece that
  touches neither is stray (clutter, another person's foot standing apart):
  not fitted, but counted against the fit's inlier fraction as before.

``contact`` then says how much of the subject's surface touches the other
bodies: the fraction of the kept points with another body's point within
``link``.  A large contact means the two cannot be told apart by distance
(people overlapping in the view, a hug): the tracker's state ``"crowded"``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from toolkit.softbody.distance import distance, primitive_distances
from toolkit.softbody.model import SoftBodyModel, SoftBodyParams

__all__ = ["Separation", "separate_subject", "link_distance", "linked_pieces", "NEAR_PERCENTILE"]

#: The near margin is widened by this percentile of the distances of the points within the gate to the
#: predicted surface: when the prediction is off (a rough start, a fast turn), the subject's own points
#: lie further from it and the margin follows them (a low percentile: another body may hold up to
#: three quarters of the points within the gate without widening it).
NEAR_PERCENTILE = 25.0


@dataclass(frozen=True)
class Separation:
    """Which points of a cloud are the subject's.

    Attributes
    ----------
    keep : ndarray of shape (N,), bool
        The subject's points (near the model, or undecided pieces shown to be the subject's).
    other : ndarray of shape (N,), bool
        Points of other bodies: beyond the gate, or pieces reaching beyond it (or near the
        previous frame's other bodies).
    stray : ndarray of shape (N,), bool
        Pieces within the gate that touch neither: clutter, a part standing apart
        (``keep | other | stray`` is every point).
    contact : float
        Fraction of the kept points with a point of ``other`` within ``link`` (0 when none is kept).
    link : float
        The neighbour distance used, metres.
    near : float
        The near margin used, metres (``near``, or more for a poor prediction).
    undecided : float
        Fraction of the kept points further than ``near`` from the predicted surface
        (pieces of the subject that moved more than predicted, or another body that
        could not be told apart: all of it within the gate).
    near_points : ndarray of shape (N,), bool
        The points within ``near`` of the predicted surface (the subject's beyond doubt).
    distance : ndarray of shape (N,)
        Each point's distance to the predicted surface, metres (negative inside).
    """

    keep: np.ndarray
    other: np.ndarray
    stray: np.ndarray
    contact: float
    link: float
    near: float
    undecided: float
    near_points: np.ndarray
    distance: np.ndarray


def linked_pieces(points: np.ndarray, link: float) -> np.ndarray:
    """The piece of each point (M,) int: points closer than ``link`` (metres) are linked, and linked
    points are one piece (connected components)."""
    pts = np.asarray(points, float).reshape(-1, 3)
    pairs = cKDTree(pts).query_pairs(link, output_type="ndarray")
    g = coo_matrix((np.ones(len(pairs), bool), (pairs[:, 0], pairs[:, 1])), shape=(len(pts), len(pts)))
    return connected_components(g, directed=False)[1]


def link_distance(points: np.ndarray, floor: float, ceiling: float = 0.1) -> float:
    """Neighbour distance of a cloud, metres: twice the 90th percentile of its nearest-neighbour
    spacing, within ``[floor, ceiling]``."""
    if len(points) < 2:
        return float(floor)
    d, _ = cKDTree(points).query(points, k=2)
    return float(np.clip(2.0 * np.percentile(d[:, 1], 90), floor, max(floor, ceiling)))


def separate_subject(model: SoftBodyModel, params: SoftBodyParams, points: np.ndarray, *, near: float,
                     gate: float, link: float, others: np.ndarray | None = None, reach=None) -> Separation:
    """Split a cloud into the subject's points and other bodies' (see the module docstring).

    Parameters
    ----------
    model : SoftBodyModel
    params : SoftBodyParams
        The predicted pose of the frame.
    points : ndarray of shape (N, 3)
        Metres, world.
    near, gate : float
        Distances outside the predicted surface, metres (``near < gate``); ``near`` is widened by
        the :data:`NEAR_PERCENTILE` th percentile of the distances of the points within the gate, to at
        most ``gate / 2``.
    link : float
        Points closer than this are neighbours, metres.
    others : ndarray of shape (M, 3), optional
        The other bodies' points of the previous frame: undecided points within ``link``
        of them count as beyond the gate (a second person standing close enough to be
        all within the gate in this frame, once seen further out).
    reach : float or ndarray of shape (P,), optional
        How far the subject's surface may lie beyond the near margin, per metaball
        (the motion the prediction may have missed), metres: an undecided point
        further than ``near + reach`` of its nearest metaball counts as beyond the
        gate.  Default: the gate alone.

    Returns
    -------
    Separation
    """
    n = len(points)
    if n == 0:
        e = np.zeros(0, bool)
        return Separation(e, e, e, 0.0, float(link), float(near), 0.0, e, np.zeros(0))
    d = distance(model, params, points)
    within = d < gate
    if within.any():   # a prediction off by more than the margin (a bad start, a lost track) widens it
        near = min(near + float(np.percentile(np.abs(d[within]), NEAR_PERCENTILE)), 0.5 * gate)
    subject = d < near
    seed = ~within                                    # certainly not the subject's
    if reach is not None and (within & ~subject).any():
        u = np.flatnonzero(within & ~subject)
        k = np.argmin(primitive_distances(model.state(params), points[u]), axis=1)
        seed[u[d[u] >= near + np.broadcast_to(np.asarray(reach, float), (model.n_prims,))[k]]] = True
    if others is not None and len(others) and (within & ~subject).any():
        u = np.flatnonzero(within & ~subject)
        dn, _ = cKDTree(np.asarray(others, float).reshape(-1, 3)).query(points[u], k=1, distance_upper_bound=link)
        seed[u[np.isfinite(dn)]] = True
    keep, other, stray = subject.copy(), seed.copy(), np.zeros(n, bool)
    idx = np.flatnonzero(~subject)                    # the pieces: undecided and seed points, linked
    if len(idx):
        lab = linked_pieces(points[idx], link)
        body = np.zeros(lab.max() + 1, bool)
        body[lab[seed[idx]]] = True
        touches = np.zeros(lab.max() + 1, bool)
        if subject.any():
            dn, _ = cKDTree(points[subject]).query(points[idx], k=1, distance_upper_bound=link)
            touches[lab[np.isfinite(dn)]] = True
        other[idx] = body[lab]
        keep[idx] = touches[lab] & ~body[lab]
        stray[idx] = ~touches[lab] & ~body[lab]
    contact = 0.0
    if keep.any() and other.any():
        dn, _ = cKDTree(points[other]).query(points[keep], k=1, distance_upper_bound=link)
        contact = float(np.mean(np.isfinite(dn)))
    undecided = float(np.mean(d[keep] >= near)) if keep.any() else 0.0
    return Separation(keep, other, stray, contact, float(link), float(near), undecided, subject, d)
