"""Tracking labelled markers with the source's 4-frame window (source 004, §3.1.1; Malik et al. 1993).

Starting from the labels of one frame, each frame ``f`` is labelled from the
previous ones:

* **predict** every marker from ``f-1`` (and ``f-2``) to ``f`` with constant
  velocity; a marker seen only at ``f-1`` is predicted where it was, with a
  wider gate;
* **confirm** each candidate (a trinocular reconstruction of frame ``f``
  within the gate) by continuing the motion it implies into ``f+1`` and
  ``f+2``: the candidate's displacement predicts ``f+1``, the nearest
  reconstruction there and the displacement ``f -> f+1`` predict ``f+2``;
  the cost of "marker i is candidate k" is the prediction error at ``f`` plus
  the (capped) continuation errors at ``f+1`` and ``f+2``.  One Hungarian
  assignment over all markers and candidates picks the hypothesis set whose
  continuation is most consistent: this is what keeps two markers whose paths
  cross apart (a nearest-neighbour tracker, ``window=2``, swaps them);
* **2D tracking** for markers without a trinocular candidate: the prediction
  is projected into every camera and the nearest unused blob within
  ``track_px`` is taken in each; two agreeing views give a ``TWO_VIEW``
  marker (the source's 2D tracking "to accelerate 3D reconstruction");
* **bridging** with the skeleton: a marker still lost is carried by the rigid
  motion (Kabsch) of the other markers of its segment since it was last
  measured (state ``BRIDGED``); its bridged position is the prediction of the
  next frame, so its identity comes back when it reappears.  Mates nearly
  collinear and far from the marker (a forearm's ``FRM`` with the upper
  arm's two, 27 cm from the wrist) leave their rotation about their line to
  the noise: such a motion neither bridges a marker nor carries a lost one
  beyond the mates' translation (:meth:`Tracker.rigid_carry`);
* **swaps across segments**: two markers of different segments that pass a
  few millimetres apart (a hand brushing the thigh) can leave with each
  other's labels, which no window tells apart.  Once they have moved apart,
  each label sits off the distances to its rigid mates (its segment's other
  markers; a hand's one marker: its forearm's) and fits at the other's place:
  the labels are swapped back in this frame and the earlier ones where that
  fits better (:meth:`Tracker.undo_cross_swaps`).  Two labels with one
  measured mate each (a sphere, met by chance) must fit swapped for a few
  frames in a row; a measured label off its mates whose marker fits an
  unmeasured label of another segment (the finger unseen, its label on the
  thigh marker, the thigh's bridged beside it) gives that label the marker
  (:meth:`Tracker.cross_claim`), and a bridge carried from a place the
  label's mates refuse is not made;
* **markers never measured** (missed by the identification) are predicted
  from the fitted template carried by their segment and take a free
  reconstruction near it that the window continues
  (:meth:`Tracker.claim_from_hints`); the first step after the labelled
  frame, where no marker has a velocity, gates at ``first_gate_m`` (a foot
  at 50 fps moves 8 cm per frame), and a marker found again takes its
  segment's velocity.

Every candidate and every blob goes to at most one marker (Hungarian
assignment, blobs marked used), so two labels never share a marker; this is
checked at the end of each frame.

The gate grows with the marker's last displacement (a fast limb accelerates
more between frames); a lost marker is searched for where the markers of its
segment and the adjacent ones carried it, and when found again it must keep
its distances to its segment mates.  After tracking, :func:`repair_swaps`
checks each nearly rigid group of markers (a segment, or a shank with its
foot) frame by frame against the identification pose: a labelling of the
same points that fits much better replaces a swapped one, and a missing
label takes an unlabelled reconstruction that fits the group rigidly.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from toolkit.errors import InputError
from toolkit.markers.identify import SEGMENT_TREE, kabsch
from toolkit.markers.reconstruct import RigGeometry, project_all, triangulate_dlt, used_blob_masks
from toolkit.markers.trajectories import BRIDGED, MISSING, TRINOCULAR, TWO_VIEW

__all__ = ["TrackConfig", "TrackState", "Tracker", "repair_swaps", "SWAP_GROUPS"]

_FAR = 1e3  # cost of a pair outside the gate (metres; never chosen over a "no partner" column)
_NONE = 1e2  # cost of leaving a marker without a candidate


@dataclass(frozen=True)
class TrackConfig:
    """Settings of the tracker.

    Attributes
    ----------
    window : int
        4: predict ``f-1 -> f`` and confirm at ``f+1``, ``f+2`` (the source);
        3: constant-velocity prediction only; 2: nearest neighbour to the
        previous position (the baseline the tests compare against).
    gate_m : float
        Largest distance between a prediction and its candidate, metres.
    gap_gate_growth_m : float
        Gate added per frame without velocity (after a gap), metres ...
    max_gate_m : float
        ... up to this.
    speed_gate : float
        Gate added per metre of the marker's last displacement (a fast limb
        accelerates more between frames), up to ``max_gate_m``.
    continuation_cap_m : float
        Cap on each continuation error at ``f+1``, ``f+2`` (a missing
        continuation costs this much, not more), metres.
    track_px : float
        2D gate around a projected prediction, pixels.
    match_px : float
        Largest reprojection error of a 2D-tracked marker, pixels.
    two_view_gate_m : float
        Largest distance between a prediction and a marker seen in two views
        only (two views always agree along the epipolar line), metres.
    segment_tolerance : float
        A marker found again after a gap must keep its distances to its
        labelled segment mates within this relative tolerance ...
    segment_floor_m : float
        ... plus this much, metres.
    bridge_min_mates : int
        Segment mates seen both now and when the marker was last measured
        needed to bridge it (3 fix a rigid motion); a segment with fewer
        markers than this borrows those of the adjacent segments.
    bridge_rms_m : float
        Largest residual of the mates' rigid fit for a bridge, metres.
    bridge_max_frames : int
        Longest gap bridged, frames.
    carry_rms_m : float
        A lost marker is searched for where its segment and the adjacent
        ones carried it, when their markers moved rigidly within this residual, metres.
    carry_noise_m : float
        Noise of the mates that carry or bridge a marker, metres: their
        rotation carries a marker only when this noise, levered to the
        marker, stays within ``gate_m`` (:meth:`Tracker.rigid_carry`);
        otherwise a lost marker is carried by their translation and not
        bridged.
    cross_min_m : float
        Two measured markers of different segments whose labels are both
        off their rigid mates' distances (summed median deviation, see
        :meth:`Tracker.undo_cross_swaps`) above this, metres, ...
    cross_fit_m : float
        ... and each of which fits the other's mates within this, metres ...
    cross_ratio : float
        ... with the swapped deviations below this share of the current
        ones, have their labels swapped.
    cross_back_frames : int
        The swap is carried back over at most this many earlier frames, as
        long as it fits there better too (back to where the two passed each other).
    cross_persist_frames : int
        Two markers of which neither has two measured rigid mates have their
        labels swapped only when the swap fitted in this many frames before
        as well (a single mate's distance fits by chance now and then).
    hint_reach_m : float
        A marker never measured yet (identification missed it; its
        prediction is the fitted template's, carried by its segment) takes a
        trinocular reconstruction no label took within this of the
        prediction, metres, when the window continues it into the next two
        frames and no other label's prediction is within ``gate_m`` of it
        (:meth:`Tracker.claim_from_hints`): the template's generic limb
        puts a hand's marker up to 15 cm off.
    first_gate_m : float
        The gate of the first step after the labelled frame, where no marker
        has a velocity yet, metres (the window's continuation tells the
        candidates apart): a swinging foot filmed at 50 fps moves 8 cm per
        frame, beyond ``gate_m + gap_gate_growth_m``.
    """

    window: int = 4
    gate_m: float = 0.04
    gap_gate_growth_m: float = 0.02
    max_gate_m: float = 0.15
    speed_gate: float = 0.5
    continuation_cap_m: float = 0.03
    track_px: float = 6.0
    match_px: float = 3.5
    two_view_gate_m: float = 0.02
    segment_tolerance: float = 0.15
    segment_floor_m: float = 0.015
    bridge_min_mates: int = 3
    bridge_rms_m: float = 0.012
    bridge_max_frames: int = 300
    carry_rms_m: float = 0.04
    carry_noise_m: float = 0.003
    cross_min_m: float = 0.025
    cross_fit_m: float = 0.012
    cross_ratio: float = 0.4
    cross_back_frames: int = 50
    cross_persist_frames: int = 5
    hint_reach_m: float = 0.25
    first_gate_m: float = 0.15

    def __post_init__(self):
        if self.window not in (2, 3, 4):
            raise InputError("TrackConfig.window", "2, 3 or 4 frames", f"{self.window!r}")


@dataclass
class TrackState:
    """The labelled trajectories being built (arrays filled in place).

    Attributes
    ----------
    positions : ndarray of shape (T, M, 3)
        Metres, NaN where missing.
    state : ndarray of shape (T, M) int8
    point : ndarray of shape (T, M) int
        Index of the frame's reconstruction carrying each label, -1 if none.
    segments : tuple of str (M,)
    hint : ndarray of shape (M, 3)
        A prediction for markers never measured yet (the fitted template), NaN if none.
    hint_frame : ndarray of shape (M,) int
        The frame the hint belongs to, -1 if none.
    """

    positions: np.ndarray
    state: np.ndarray
    point: np.ndarray
    segments: tuple
    hint: np.ndarray
    hint_frame: np.ndarray

    @staticmethod
    def empty(n_frames: int, segments) -> "TrackState":
        M = len(segments)
        return TrackState(np.full((n_frames, M, 3), np.nan), np.zeros((n_frames, M), np.int8),
                          -np.ones((n_frames, M), int), tuple(segments), np.full((M, 3), np.nan),
                          -np.ones(M, int))

    def measured(self, f: int) -> np.ndarray:
        s = self.state[f]
        return (s == TRINOCULAR) | (s == TWO_VIEW)


def seen_before(t: "TrackState", r: int, i: int) -> bool:
    """Whether marker ``i`` was measured (not bridged or hinted) in frame ``r``."""
    return bool(t.state[r, i] in (TRINOCULAR, TWO_VIEW))


def _segment_mates(segments) -> list[np.ndarray]:
    """Per marker, the other markers of its segment, then those of its parent and children segments."""
    seg = np.asarray(segments)
    out = []
    for i, s in enumerate(seg):
        same = np.flatnonzero((seg == s) & (np.arange(seg.size) != i))
        near = {SEGMENT_TREE.get(s, (None, None))[1]} | {c for c, (_, p) in SEGMENT_TREE.items() if p == s}
        adjacent = np.flatnonzero(np.isin(seg, [n for n in near if n is not None]))
        out.append(np.concatenate([same, adjacent]))
    return out


def rigid_mates(segments) -> list[np.ndarray]:
    """Per marker, the markers expected to keep their distances to it: the others of its segment, or, for
    a segment of one marker (Plug-in Gait's hand), those of the nearly rigid group it belongs to
    (:data:`SWAP_GROUPS`, e.g. forearm and hand)."""
    seg = np.asarray(segments)
    out = []
    for i, s in enumerate(seg):
        others = np.arange(seg.size) != i
        same = np.flatnonzero((seg == s) & others)
        if same.size == 0:
            joined = [x for g in SWAP_GROUPS if s in g and len(g) > 1 for x in g]
            same = np.flatnonzero(np.isin(seg, joined) & others)
        out.append(same)
    return out


def reference_distances(track: TrackState, pairs: np.ndarray | None = None) -> np.ndarray:
    """Distances (M, M) between markers of one segment (or the ``pairs`` (M, M) bool given) where both are
    measured, median over the labelled frames so far (NaN for other pairs or never seen together)."""
    P = track.positions[track.state.max(axis=1) > 0]
    seg = np.asarray(track.segments)
    d = np.linalg.norm(P[:, :, None] - P[:, None], axis=3)
    with warnings.catch_warnings():  # pairs never seen together: an all-NaN median, NaN is the answer
        warnings.simplefilter("ignore", RuntimeWarning)
        ref = np.nanmedian(d, axis=0) if len(P) else np.full((seg.size, seg.size), np.nan)
    return np.where(seg[:, None] == seg[None, :] if pairs is None else pairs, ref, np.nan)


def _finite_median(dev: np.ndarray) -> np.ndarray:
    """Median over axis 1 of the finite entries of ``dev`` (A, K, B) (inf marks none), NaN where none
    (a sort, not ``np.nanmedian``, which is slow on the small arrays of every frame)."""
    dev = np.sort(dev, axis=1)
    n = np.sum(np.isfinite(dev), axis=1)  # (A, B)
    lo = np.take_along_axis(dev, (np.maximum(n - 1, 0) // 2)[:, None], axis=1)[:, 0]
    hi = np.take_along_axis(dev, np.minimum(n // 2, dev.shape[1] - 1)[:, None], axis=1)[:, 0]
    with np.errstate(invalid="ignore"):
        return np.where(n > 0, 0.5 * (lo + np.where(n > 1, hi, lo)), np.nan)


class Tracker:
    """Labels frames one after the other (forwards or backwards) from already labelled ones.

    Parameters
    ----------
    geom : RigGeometry
    blobs : callable (frame) -> list of ndarray (n_c, 2)
        The blobs of each camera in a frame, pixels.
    recon : callable (frame) -> FrameMarkers
        The trinocular reconstructions of a frame.
    track : TrackState
        Holds at least one labelled frame.
    config : TrackConfig
    """

    def __init__(self, geom: RigGeometry, blobs, recon, track: TrackState, config: TrackConfig = TrackConfig()):
        self.geom, self.blobs, self.recon, self.t, self.config = geom, blobs, recon, track, config
        self.mates = _segment_mates(track.segments)
        seg = np.asarray(track.segments)
        self.same = [np.flatnonzero((seg == s) & (np.arange(seg.size) != i)) for i, s in enumerate(seg)]
        self.n_same = [m.size for m in self.same]
        self.ref_dist = reference_distances(track)
        rigid = rigid_mates(track.segments)
        self.rigid = np.zeros((seg.size, seg.size), bool)
        for i, m in enumerate(rigid):
            self.rigid[i, m] = True
        self.rigid_ref = reference_distances(track, self.rigid)
        width = max([m.size for m in rigid] + [1])
        self._mate_idx = np.array([np.pad(m, (0, width - m.size)) for m in rigid], int).reshape(seg.size, width)
        self._mate_ok = np.array([np.arange(width) < m.size for m in rigid]).reshape(seg.size, width)
        self._weak, self._weak_frame = {}, -10  # swaps of one-mate labels: frames in a row they fitted

    # ------------------------------------------------------------ prediction
    def predict(self, order: list[int], k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Prediction (M, 3), gate (M,) and velocity (M, 3) of frame ``order[k]``."""
        c, t = self.config, self.t
        prev = t.positions[order[k - 1]]
        prev2 = t.positions[order[k - 2]] if k >= 2 else np.full_like(prev, np.nan)
        have1 = np.isfinite(prev).all(axis=1)
        have2 = have1 & np.isfinite(prev2).all(axis=1)
        vel = np.where(have2[:, None], prev - prev2, 0.0)
        if c.window == 2:
            vel[:] = 0.0
        pred = prev + vel
        gate = np.where(have2 | (c.window == 2), c.gate_m, c.gate_m + c.gap_gate_growth_m)
        if c.window > 2 and k == 1:  # the first step: no marker has a velocity yet, a limb may move fast
            gate[:] = c.first_gate_m
        elif c.window > 2:  # found again one frame ago: its segment's velocity
            for i in np.flatnonzero(have1 & ~have2):
                moving = self.same[i][have2[self.same[i]]]
                if moving.size:
                    vel[i] = np.median(vel[moving], axis=0)
                    pred[i] = prev[i] + vel[i]
                    gate[i] = c.gate_m
        gate = np.minimum(gate + c.speed_gate * np.linalg.norm(vel, axis=1), c.max_gate_m)
        self.hinted = np.zeros(pred.shape[0], bool)  # predicted from the template's hint (never measured)
        for i in np.flatnonzero(~have1):  # lost: the last position (or the template hint), a growing gate
            last, gap = self._last_known(order, k, i)
            if last is not None:
                r = order[k - gap]
                self.hinted[i] = r == t.hint_frame[i] and not np.isfinite(t.positions[r, i]).all()
                pred[i] = last
                gate[i] = min(c.gate_m + c.gap_gate_growth_m * gap, c.max_gate_m)
                carried = self._carried(order, k, i, gap, last)
                if carried is not None:  # moved with its neighbours since: a better guess, same gate
                    pred[i] = carried
            else:
                pred[i] = np.nan
        return pred, gate, vel

    def _carried(self, order, k, i, gap, last):
        """``last`` (seen ``gap`` frames before ``order[k]``) moved by the rigid motion of marker ``i``'s
        segment and adjacent segments' markers from then to ``order[k-1]``; None if too few or too bent."""
        t, c = self.t, self.config
        r, p = order[k - gap], order[k - 1]
        if r == p:
            return None
        mates = self.mates[i]
        ok = np.isfinite(t.positions[r, mates]).all(axis=1) & np.isfinite(t.positions[p, mates]).all(axis=1)
        if ok.sum() < c.bridge_min_mates:
            return None
        a, b = t.positions[r, mates[ok]], t.positions[p, mates[ok]]
        X, determined = self.rigid_carry(a, b, last, c.carry_rms_m)
        if X is None or determined:
            return X
        return last + b.mean(axis=0) - a.mean(axis=0)  # the rotation undetermined: their translation only

    def rigid_carry(self, a: np.ndarray, b: np.ndarray, x: np.ndarray, max_rms_m: float):
        """Point ``x`` (3,) moved by the rigid motion taking mates ``a`` (K, 3) to ``b`` (K, 3), metres.

        Returns ``(X, determined)``: ``X`` is None when the mates moved less
        rigidly than ``max_rms_m`` (rms residual); ``determined`` is False
        when the rotation is too poorly fixed to carry ``x``: its error
        grows with ``x``'s distance from the mates (the lever) over their
        spread across their main axis (second singular value), and the
        mates' noise of ``carry_noise_m`` would move ``x`` by more than
        ``gate_m``.  Three nearly collinear mates (a forearm's ``FRM`` with
        the upper arm's ``UPA`` and ``ELB``: 3 mm across, the wrist 27 cm
        away) turn 5 mm of noise into 5-9 cm at the wrist (rom seed 112).
        """
        c = self.config
        ca, cb = a.mean(axis=0), b.mean(axis=0)
        R = kabsch(a, b)
        if np.sqrt(np.mean(np.sum(((a - ca) @ R.T + cb - b) ** 2, axis=1))) > max_rms_m:
            return None, False
        spread = np.linalg.svd(a - ca, compute_uv=False)[1] / np.sqrt(a.shape[0])
        determined = bool(c.carry_noise_m * np.linalg.norm(x - ca) <= c.gate_m * spread)
        return (x - ca) @ R.T + cb, determined

    def _last_known(self, order, k, i):
        t = self.t
        for back in range(1, min(k, self.config.bridge_max_frames) + 1):
            p = t.positions[order[k - back], i]
            if np.all(np.isfinite(p)):
                return p, back
            if order[k - back] == t.hint_frame[i]:
                return t.hint[i], back
        return None, 0

    # ------------------------------------------------------------ assignment
    def _window_cost(self, order, k, cand, vel, pairs_i, pairs_k):
        """Continuation errors at f+1 and f+2 of the hypotheses (marker pairs_i -> candidate pairs_k)."""
        cap = self.config.continuation_cap_m
        extra = np.zeros(pairs_i.size)
        prev = self.t.positions[order[k - 1]]
        step = np.where(np.isfinite(prev[pairs_i]).all(axis=1)[:, None], cand[pairs_k] - prev[pairs_i], 0.0)
        here = cand[pairs_k]
        for j in (1, 2):
            if k + j >= len(order):
                break
            nxt = self.recon(order[k + j]).points
            q = here + step
            if nxt.shape[0] == 0:
                extra += cap
                step = step.copy()
                here = q
                continue
            d = np.linalg.norm(q[:, None, :] - nxt[None], axis=2)
            best = np.argmin(d, axis=1)
            dmin = d[np.arange(best.size), best]
            found = dmin < cap
            extra += np.minimum(dmin, cap)
            new_here = np.where(found[:, None], nxt[best], q)
            step = new_here - here
            here = new_here
        return extra

    def assign_candidates(self, order, k, pred, gate, vel) -> np.ndarray:
        """Point index (M,) of each marker among the frame's reconstructions, -1 if none."""
        f = order[k]
        rec = self.recon(f)
        ok = rec.state == TRINOCULAR
        cand_idx = np.flatnonzero(ok)
        cand = rec.points[cand_idx]
        M = pred.shape[0]
        out = -np.ones(M, int)
        has = np.isfinite(pred).all(axis=1)
        if cand.shape[0] == 0 or not has.any():
            return out
        d = np.linalg.norm(pred[:, None, :] - cand[None], axis=2)
        d[~has] = np.inf
        inside = d < gate[:, None]
        cost = np.where(inside, d, _FAR)
        if self.config.window == 4:
            pi, pk = np.nonzero(inside)
            if pi.size:
                cost[pi, pk] += self._window_cost(order, k, cand, vel, pi, pk)
        full = np.concatenate([cost, np.full((M, M), _NONE)], axis=1)
        rows, cols = linear_sum_assignment(full)
        good = (cols < cand.shape[0])
        good[good] &= inside[rows[good], cols[good]]
        out[rows[good]] = cand_idx[cols[good]]
        moving = np.isfinite(self.t.positions[order[k - 1]]).all(axis=1)
        for i in np.flatnonzero((out >= 0) & ~moving):  # found again after a gap: must fit its segment
            if not self.fits_segment(i, rec.points[out[i]], rec.points, out):
                out[i] = -1
        return out

    def claim_from_hints(self, order, k, pred, point) -> np.ndarray:
        """Markers never measured yet take free trinocular reconstructions near their hint; ``point`` (M,) updated.

        A marker the identification missed is predicted from the fitted
        template, carried by its segment; the generic template can be far
        from the performer's limb (a walk's swinging hand 14 cm off), beyond
        any tracking gate.  Such a marker takes a trinocular reconstruction
        that no label took, within ``hint_reach_m`` of its prediction (one
        assignment over all of them, nearest first), when the window
        continues the reconstruction into the next two frames (a ghost is
        not seen again), none of its rigid mates is lost in this frame and no
        other label's prediction lies within ``gate_m`` of it (it may be a
        lost marker's).  Its reference distances to its rigid mates are then
        taken from this frame (:meth:`step`, once the frame is labelled);
        the markers that claimed are in ``self.claimed``.
        """
        c, t = self.config, self.t
        self.claimed = []
        want = self.hinted & (point < 0) & np.isfinite(pred).all(axis=1)
        if not want.any():
            return point
        lost = (point < 0) & ~self.hinted  # tracked before, not found in this frame (yet)
        want = np.flatnonzero(want & ~(self.rigid & lost[None]).any(axis=1))  # a free point may be a lost mate's
        if want.size == 0:
            return point
        rec = self.recon(order[k])
        free = np.flatnonzero((rec.state == TRINOCULAR) & ~np.isin(np.arange(len(rec)), point))
        if free.size == 0:
            return point
        cand = rec.points[free]
        others = np.flatnonzero(np.isfinite(pred).all(axis=1) & ~self.hinted)
        clear = np.linalg.norm(cand[:, None] - pred[others][None], axis=2).min(axis=1, initial=np.inf) > c.gate_m
        d = np.linalg.norm(pred[want][:, None] - cand[None], axis=2)
        inside = (d < c.hint_reach_m) & clear[None]
        pi, pk = np.nonzero(inside)
        if pi.size == 0:
            return point
        cont = self._window_cost(order, k, cand, None, want[pi], pk)
        inside[pi, pk] = cont < c.continuation_cap_m  # seen again near where its motion leads
        rows, cols = linear_sum_assignment(np.where(inside, d, _FAR))
        point = point.copy()
        for r, col in zip(rows, cols):
            if inside[r, col]:
                i = want[r]
                point[i] = free[col]
                self.claimed.append(int(i))
        return point

    def _learn_references(self, i: int, f: int, X: np.ndarray) -> None:
        """Marker ``i``'s reference distances to its rigid and segment mates measured in frame ``f`` (it at ``X``)."""
        t = self.t
        meas = t.measured(f) & np.isfinite(t.positions[f]).all(axis=1)
        for table, mask in ((self.rigid_ref, self.rigid[i]), (self.ref_dist, np.isin(np.arange(len(meas)),
                                                                                      self.same[i]))):
            m = np.flatnonzero(mask & meas & ~np.isfinite(table[i]))
            table[i, m] = table[m, i] = np.linalg.norm(t.positions[f, m] - X, axis=1)

    def fits_segment(self, i: int, X: np.ndarray, points: np.ndarray, point_of: np.ndarray) -> bool:
        """Whether ``X`` keeps marker ``i``'s distances to its labelled segment mates (reference: ``ref_dist``)."""
        c = self.config
        mates = [j for j in self.same[i] if point_of[j] >= 0 and np.isfinite(self.ref_dist[i, j])]
        if not mates:
            return True
        d = np.linalg.norm(points[point_of[mates]] - X, axis=1)
        ref = self.ref_dist[i, mates]
        return bool(np.all(np.abs(d - ref) < c.segment_tolerance * ref + c.segment_floor_m))

    # ------------------------------------------------------------ 2D tracking
    def track_2d(self, f: int, pred: np.ndarray, gate: np.ndarray, missing: np.ndarray, used: list[np.ndarray]):
        """Markers found from blobs near their projected prediction: (marker, X, n_views) tuples."""
        c = self.config
        blobs = self.blobs(f)
        idx = np.flatnonzero(missing & np.isfinite(pred).all(axis=1))
        if idx.size == 0:
            return []
        uv = project_all(self.geom, pred[idx])  # (C, n, 2)
        found = []
        for n, i in enumerate(idx):
            views = -np.ones(len(blobs), int)
            for cam, b in enumerate(blobs):
                if b.shape[0] == 0 or not np.all(np.isfinite(uv[cam, n])):
                    continue
                dist = np.linalg.norm(b - uv[cam, n], axis=1)
                dist[used[cam]] = np.inf
                j = int(np.argmin(dist))
                if dist[j] < c.track_px:
                    views[cam] = j
            X, views = self._triangulate_views(blobs, views)
            if X is None:
                continue
            if np.linalg.norm(X - pred[i]) > (gate[i] if (views >= 0).sum() >= 3 else c.two_view_gate_m):
                continue
            for cam in np.flatnonzero(views >= 0):
                used[cam][views[cam]] = True
            found.append((i, X, int((views >= 0).sum())))
        return found

    def _triangulate_views(self, blobs, views):
        """DLT from the chosen views, dropping the worst view while one disagrees; (None, views) if < 2."""
        while (views >= 0).sum() >= 2:
            cams = np.flatnonzero(views >= 0)
            xy = np.zeros((1, len(blobs), 2))
            for cam in cams:
                xy[0, cam] = self.geom.rig[cam].undistort_points(blobs[cam][views[cam]])
            X = triangulate_dlt(self.geom.P, xy, (views >= 0)[None])[0]
            if not np.all(np.isfinite(X)):
                return None, views
            uv = project_all(self.geom, X[None])[:, 0]
            err = np.array([np.linalg.norm(uv[cam] - blobs[cam][views[cam]]) if views[cam] >= 0 else -1.0
                            for cam in range(len(blobs))])
            if np.nanmax(err) < self.config.match_px:
                return X, views
            views = views.copy()
            views[int(np.nanargmax(err))] = -1
        return None, views

    # ------------------------------------------------------------ bridging
    def bridge(self, order, k, i) -> np.ndarray | None:
        """Marker ``i`` at frame ``order[k]`` carried by its segment mates since it was last measured."""
        c, t = self.config, self.t
        f = order[k]
        now = t.measured(f)
        for back in range(1, min(k, c.bridge_max_frames) + 1):
            r = order[k - back]
            if t.state[r, i] in (TRINOCULAR, TWO_VIEW) or r == t.hint_frame[i]:
                ref = t.positions[r, i] if t.state[r, i] in (TRINOCULAR, TWO_VIEW) else t.hint[i]
                mates = self.mates[i]
                usable = mates[now[mates] & np.isfinite(t.positions[r, mates]).all(axis=1)]
                same = usable[np.asarray(t.segments)[usable] == t.segments[i]]
                if not seen_before(t, r, i) or self.n_same[i] + 1 < c.bridge_min_mates:
                    # a hint, or a segment with too few markers to fix its motion: adjacent segments carry it
                    same = same if same.size >= c.bridge_min_mates else usable
                if same.size < c.bridge_min_mates:
                    return None
                X, determined = self.rigid_carry(t.positions[r, same], t.positions[f, same], ref, c.bridge_rms_m)
                if X is None or not determined:  # bent, or nearly collinear mates far from it: no bridge
                    return None
                return X, t.state[r, i] in (TRINOCULAR, TWO_VIEW)
        return None

    # ------------------------------------------------------------ swaps across segments
    def deviations(self, f: int, at: np.ndarray | None = None) -> np.ndarray:
        """How far each label would be off its rigid mates at each marker's place in frame ``f``.

        Parameters
        ----------
        f : int
        at : ndarray of int, optional
            The markers whose places are tried (default: all).

        Returns
        -------
        ndarray of shape (M, len(at))
            Entry ``[i, x]``: the median over marker ``i``'s measured rigid
            mates (:func:`rigid_mates`, other than ``at[x]``) of the
            difference between their distance to marker ``at[x]``'s position
            and their reference distance to ``i``, metres; NaN where
            ``at[x]`` is not measured or ``i`` has no measured mate.
        """
        t = self.t
        P, meas = t.positions[f], t.measured(f)
        at = np.arange(P.shape[0]) if at is None else np.asarray(at, int)
        mi = self._mate_idx
        ref = np.take_along_axis(self.rigid_ref, mi, axis=1)  # (M, K)
        ok = self._mate_ok & meas[mi] & np.isfinite(ref)
        d = np.linalg.norm(P[mi][:, :, None, :] - P[at][None, None], axis=3)  # (M, K, X)
        dev = np.abs(d - ref[:, :, None])
        dev[~(ok[:, :, None] & (mi[:, :, None] != at) & meas[at])] = np.inf
        return _finite_median(dev)

    def cross_swap(self, f: int):
        """The pair of measured markers of different segments whose swapped labels fit best, or None.

        Both labels must be off (summed deviation above ``cross_min_m``),
        each must fit at the other's place within ``cross_fit_m``, and the
        swap must cut the summed deviation below ``cross_ratio`` of it.  When
        neither has two measured mates (Plug-in Gait's thighs, shanks, feet
        and upper arms: one mate each), one mate's distance only says the
        marker lies on a sphere about it, and two such markers (both knees,
        each with its ``THI``) meet their spheres by chance as the legs
        move, for a frame or two: their swap must also have fitted in each
        of the ``cross_persist_frames`` frames before (a swap persists, a
        chance meeting does not).
        """
        c, t = self.config, self.t
        M = t.positions.shape[1]
        first = f != self._weak_frame  # once per frame: the weak pairs' counts
        if first:
            if abs(f - self._weak_frame) != 1:
                self._weak = {}
            self._weak_frame = f
        own, n_mates = self.own_deviation(f)
        if not np.nanmax(own, initial=0.0) > 0.5 * c.cross_min_m:  # nobody off: the usual frame, cheap
            if first:
                self._weak = {}
            return None
        E = self.deviations(f)
        meas = t.measured(f)
        now, swapped = own[:, None] + own[None], E + E.T
        with np.errstate(invalid="ignore"):
            ok = (meas[:, None] & meas[None] & ~self.rigid & ~self.rigid.T & ~np.eye(M, dtype=bool)
                  & (now > c.cross_min_m) & (np.fmax(E, E.T) < c.cross_fit_m) & (swapped < c.cross_ratio * now))
        weak = ok & (np.maximum(n_mates[:, None], n_mates[None]) < 2)
        if first:
            self._weak = {(int(i), int(j)): self._weak.get((int(i), int(j)), 0) + 1
                          for i, j in zip(*np.nonzero(np.triu(weak)))}
        for i, j in zip(*np.nonzero(weak)):
            ok[i, j] = self._weak.get((min(i, j), max(i, j)), 0) > c.cross_persist_frames
        if not ok.any():
            return None
        i, j = np.unravel_index(np.argmin(np.where(ok, swapped - now, np.inf)), ok.shape)
        return int(i), int(j)

    def own_deviation(self, f: int) -> tuple[np.ndarray, np.ndarray]:
        """Each label's deviation (M,) from its rigid mates at its own place in frame ``f`` (the diagonal of
        :meth:`deviations`), metres, NaN where unmeasured or without a measured mate; and the number (M,) of
        its measured mates with a reference distance."""
        t = self.t
        P, meas = t.positions[f], t.measured(f)
        mi = self._mate_idx
        ref = np.take_along_axis(self.rigid_ref, mi, axis=1)
        ok = self._mate_ok & meas[mi] & np.isfinite(ref) & meas[:, None]
        dev = np.where(ok, np.abs(np.linalg.norm(P[mi] - P[:, None], axis=2) - ref), np.inf)
        return _finite_median(dev[:, :, None])[:, 0], ok.sum(axis=1)

    def off_mates(self, f: int, i: int, X: np.ndarray) -> tuple[float, int]:
        """How far ``X`` would put label ``i`` off its rigid mates measured in frame ``f`` (median deviation from
        their reference distances, metres, NaN if none) and the number of those mates."""
        t = self.t
        mates = self._mate_idx[i][self._mate_ok[i]]
        mates = mates[t.measured(f)[mates] & np.isfinite(self.rigid_ref[i, mates])]
        if mates.size == 0:
            return float("nan"), 0
        dev = np.abs(np.linalg.norm(t.positions[f, mates] - X, axis=1) - self.rigid_ref[i, mates])
        return float(np.median(dev)), int(mates.size)

    def cross_claim(self, order: list[int], k: int):
        """A measured marker whose label is off its rigid mates and that fits an unmeasured label of another
        segment, as ``(i, j)`` (the marker labelled ``i`` belongs to ``j``), or None.

        Label ``i`` must be off by more than ``cross_min_m`` with at least two
        measured mates (one mate's distance is only a sphere); label ``j``
        (bridged or missing, of a segment not rigid with ``i``'s) must fit
        at the marker's place within ``cross_fit_m`` and below
        ``cross_ratio`` of ``i``'s deviation, and its bridged (or last
        known) place must lie within ``max_gate_m`` of the marker.  This is
        a swap whose other half was never measured: the hand's label took
        the thigh marker while the finger itself went unseen, and the thigh's
        label was bridged beside it.
        """
        c, t, f = self.config, self.t, order[k]
        own, n_mates = self.own_deviation(f)
        with np.errstate(invalid="ignore"):
            off = np.flatnonzero((own > c.cross_min_m) & (n_mates >= 2))
        free = np.flatnonzero(~t.measured(f))
        if off.size == 0 or free.size == 0:
            return None
        E = self.deviations(f, at=off)  # (M, len(off)): each label at each off marker's place
        best = None
        for x, i in enumerate(off):
            with np.errstate(invalid="ignore"):
                fit = free[~self.rigid[i, free] & (E[free, x] < c.cross_fit_m)
                           & (E[free, x] < c.cross_ratio * own[i])]
            for j in fit[np.argsort(E[fit, x])]:
                near = t.positions[f, j] if np.isfinite(t.positions[f, j]).all() else \
                    self._last_known(order, k, j)[0]
                if near is not None and np.linalg.norm(near - t.positions[f, i]) < c.max_gate_m:
                    if best is None or E[j, x] < best[0]:
                        best = (E[j, x], int(i), int(j))
                    break
        return None if best is None else best[1:]

    def _give(self, f: int, i: int, j: int) -> None:
        """The marker labelled ``i`` in frame ``f`` goes to label ``j``; ``i`` becomes missing."""
        t = self.t
        for arr in (t.positions, t.state, t.point):
            arr[f, j] = arr[f, i]
        t.positions[f, i], t.state[f, i], t.point[f, i] = np.nan, MISSING, -1

    def _swap(self, f: int, i: int, j: int) -> None:
        t = self.t
        for arr in (t.positions, t.state, t.point):
            arr[f, [i, j]] = arr[f, [j, i]]

    def undo_cross_swaps(self, order: list[int], k: int) -> int:
        """Swap back labels that two markers of different segments exchanged (a hand brushing the thigh).

        The tracker's window cannot tell two markers apart that pass a few
        millimetres from each other, and :func:`repair_swaps` only relabels
        within a group.  Once the two have moved apart, each label sits off
        its rigid mates' distances and fits at the other's place
        (:meth:`cross_swap`): the labels of frame ``order[k]`` are swapped,
        and those of the earlier frames too, back as long as the swap fits
        there better (at most ``cross_back_frames``), so that the velocities
        predicting the next frame are the markers' own.  Returns the number
        of pairs swapped in ``order[k]``.
        """
        c, t, f = self.config, self.t, order[k]
        n = 0
        for _ in range(3):  # a few pairs at most in one frame
            pair = self.cross_swap(f)
            if pair is None:
                break
            i, j = pair
            self._swap(f, i, j)
            n += 1
            for back in range(1, min(k, c.cross_back_frames) + 1):
                g = order[k - back]
                if not t.measured(g)[[i, j]].all():
                    break
                E = self.deviations(g)
                if not E[i, j] + E[j, i] < E[i, i] + E[j, j]:
                    break
                self._swap(g, i, j)
        for _ in range(3):  # swaps whose other half was never measured
            claim = self.cross_claim(order, k)
            if claim is None:
                break
            i, j = claim
            self._give(f, i, j)
            n += 1
            carried = []  # frames where i was bridged from the measurement before them
            for back in range(1, min(k, c.cross_back_frames) + 1):
                g = order[k - back]
                if t.state[g, i] == BRIDGED:
                    carried.append(g)
                    continue
                meas = t.measured(g)
                if not meas[i]:
                    continue
                if meas[j] or not self.off_mates(g, j, t.positions[g, i])[0] < \
                        self.off_mates(g, i, t.positions[g, i])[0]:
                    break
                self._give(g, i, j)
                for h in carried:  # carried from a place that was not its own
                    t.positions[h, i], t.state[h, i], t.point[h, i] = np.nan, MISSING, -1
                carried = []
            out = self.bridge(order, k, i)  # from its last measurement before the claim
            if out is not None and out[1]:
                t.positions[f, i], t.state[f, i] = out[0], BRIDGED
        return n

    # ------------------------------------------------------------ one frame
    def step(self, order: list[int], k: int) -> None:
        """Label frame ``order[k]`` (``order[k-1]`` already labelled)."""
        t, f = self.t, order[k]
        pred, gate, vel = self.predict(order, k)
        point = self.assign_candidates(order, k, pred, gate, vel)
        point = self.claim_from_hints(order, k, pred, point)
        rec = self.recon(f)
        ok = point >= 0
        t.point[f] = point
        t.positions[f, ok] = rec.points[point[ok]]
        t.state[f, ok] = rec.state[point[ok]]
        blobs = self.blobs(f)
        # blobs of any trinocular reconstruction belong to some marker: not for 2D tracking
        used = used_blob_masks(rec.views[(rec.state == TRINOCULAR) | np.isin(np.arange(len(rec)), point)],
                               [b.shape[0] for b in blobs])
        for i, X, n_views in self.track_2d(f, pred, gate, ~ok, used):
            t.positions[f, i] = X
            t.state[f, i] = TRINOCULAR if n_views >= 3 else TWO_VIEW
        for i in self.claimed:  # first measured: its distances to its mates from now on
            self._learn_references(i, f, t.positions[f, i])
        for i in np.flatnonzero(t.state[f] == MISSING):
            out = self.bridge(order, k, i)
            if out is None:
                continue
            X, seen_before = out
            if seen_before and self.off_mates(f, i, X)[0] > self.config.cross_min_m:
                continue  # carried from a place that was not its own: nowhere its mates allow
            if seen_before:
                t.positions[f, i] = X
                t.state[f, i] = BRIDGED
            else:  # never measured: the template's prediction, a hint only
                t.hint[i], t.hint_frame[i] = X, f
        self.undo_cross_swaps(order, k)
        labelled = t.point[f][t.point[f] >= 0]
        assert np.unique(labelled).size == labelled.size, "two labels on one reconstructed marker"

    def run(self, order: list[int]) -> None:
        """Label ``order[1:]`` from the labelled ``order[0]``."""
        for k in range(1, len(order)):
            self.step(order, k)



#: Segment groups whose markers are checked together for swapped labels: a limb's distal pair of
#: segments (nearly rigid, a joint of small range between them) when they carry at most 6 markers,
#: and every segment alone.
SWAP_GROUPS = (("l_shank", "l_foot"), ("r_shank", "r_foot"), ("l_forearm", "l_hand"), ("r_forearm", "r_hand"),
               ("pelvis",), ("thorax",), ("head",), ("l_thigh",), ("r_thigh",), ("l_upperarm",), ("r_upperarm",),
               ("l_shank",), ("r_shank",), ("l_foot",), ("r_foot",), ("l_forearm",), ("r_forearm",),
               ("l_hand",), ("r_hand",))


def _rigid_rms(A: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Rms (n_maps,) of the best rigid fit of reference points A (n_maps, k, 3) to points P (k, 3)."""
    a0 = A - A.mean(axis=1, keepdims=True)
    b0 = P - P.mean(axis=0)
    H = np.einsum("pki,kj->pij", a0, b0)
    S = np.linalg.svd(H, compute_uv=False)
    d = np.sign(np.linalg.det(H))
    res = np.sum(a0 ** 2, axis=(1, 2)) + np.sum(b0 ** 2) - 2 * (S[:, 0] + S[:, 1] + d * S[:, 2])
    return np.sqrt(np.maximum(res, 0) / P.shape[0])


def repair_swaps(track: TrackState, reference: np.ndarray, *, min_rms_m: float = 0.025, ratio: float = 0.6,
                 max_markers: int = 6, spare=None, fill_rms_m: float = 0.015, spare_reach_m: float = 0.3) -> int:
    """Undo label swaps within nearly rigid marker groups, frame by frame.

    In each frame and group (:data:`SWAP_GROUPS`), the labelled points are
    compared with their labels' ``reference`` configuration (the
    identification frame): when another labelling of the same points with
    the group's labels (any label, also one missing in the frame) fits the
    reference rigidly much better (rms below ``ratio`` times that of the
    tracked labelling, which is above ``min_rms_m``), the points are
    relabelled.  Relabelling one frame's points within a group never
    creates a duplicate.

    Parameters
    ----------
    track : TrackState
        Changed in place (positions, state, point).
    reference : ndarray of shape (M, 3)
        Every marker in one pose (NaN if unknown).
    spare : callable (frame) -> ndarray (K, 3), optional
        Reconstructions of a frame that carry no label: a group missing a
        label takes one when it fits the group rigidly within ``fill_rms_m``
        (and lies within ``spare_reach_m`` of the group's points).

    Returns
    -------
    int
        Number of marker-frames relabelled or filled.
    """
    from itertools import permutations

    seg = np.asarray(track.segments)
    changed = 0
    for group in SWAP_GROUPS:
        idx = np.flatnonzero(np.isin(seg, group) & np.isfinite(reference).all(axis=1))
        n = idx.size
        if not 3 <= n <= max_markers:
            continue
        maps = {k: np.array(list(permutations(range(n), k))) for k in range(3, n + 1)}
        for f in range(track.positions.shape[0]):
            here = np.flatnonzero(np.isfinite(track.positions[f, idx]).all(axis=1))
            if here.size < 3:
                continue
            m = maps[here.size]  # (P, k): the label (within the group) of each present point
            P = track.positions[f, idx[here]]
            rms = _rigid_rms(reference[idx][m], P)
            now = int(np.flatnonzero(np.all(m == here, axis=1))[0])
            best = int(np.argmin(rms))
            if rms[now] > min_rms_m and rms[best] < ratio * rms[now]:
                changed += _relabel(track, f, idx, here, m[best])
                here = np.flatnonzero(np.isfinite(track.positions[f, idx]).all(axis=1))
                rms_now = rms[best]
            else:
                rms_now = rms[now]
            if spare is None or here.size == n:
                continue
            extra = spare(f)
            if len(extra) == 0:
                continue
            P = track.positions[f, idx[here]]
            near = extra[np.linalg.norm(extra - P.mean(axis=0), axis=1) < spare_reach_m]
            missing = np.setdiff1d(np.arange(n), here)
            best_fill = None
            for x in near:
                for lab in missing:
                    r = _rigid_rms(reference[idx][np.append(here, lab)][None], np.vstack([P, x]))[0]
                    if r < max(fill_rms_m, 1.2 * rms_now) and (best_fill is None or r < best_fill[0]):
                        best_fill = (r, lab, x)
            if best_fill is not None:
                _, lab, x = best_fill
                track.positions[f, idx[lab]] = x
                track.state[f, idx[lab]] = TRINOCULAR
                changed += 1
    return changed


def _relabel(track: TrackState, f: int, idx: np.ndarray, here: np.ndarray, labels: np.ndarray) -> int:
    """Give the group ``idx``'s present points (``here``) the group labels ``labels`` in frame ``f``."""
    src, dst = idx[here], idx[labels]
    vals = [arr[f, src].copy() for arr in (track.positions, track.state, track.point)]
    track.positions[f, idx] = np.nan
    track.state[f, idx] = MISSING
    track.point[f, idx] = -1
    for arr, v in zip((track.positions, track.state, track.point), vals):
        arr[f, dst] = v
    return int(np.sum(src != dst))
