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
  next frame, so its identity comes back when it reappears.

Every candidate and every blob goes to at most one marker (Hungarian
assignment, blobs marked used), so two labels never share a marker; this is
checked at the end of each frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from toolkit.errors import InputError
from toolkit.markers.identify import SEGMENT_TREE, kabsch
from toolkit.markers.reconstruct import (FrameMarkers, RigGeometry, project_all, triangulate_dlt,
                                         used_blob_masks)
from toolkit.markers.trajectories import BRIDGED, MISSING, TRINOCULAR, TWO_VIEW

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
    bridge_min_mates : int
        Segment mates seen both now and when the marker was last measured
        needed to bridge it (3 fix a rigid motion).
    bridge_rms_m : float
        Largest residual of the mates' rigid fit for a bridge, metres.
    bridge_max_frames : int
        Longest gap bridged, frames.
    """

    window: int = 4
    gate_m: float = 0.04
    gap_gate_growth_m: float = 0.02
    max_gate_m: float = 0.12
    continuation_cap_m: float = 0.03
    track_px: float = 6.0
    match_px: float = 3.5
    two_view_gate_m: float = 0.02
    bridge_min_mates: int = 3
    bridge_rms_m: float = 0.012
    bridge_max_frames: int = 300

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
        for i in np.flatnonzero(~have1):  # lost: the last position (or the template hint), a growing gate
            last, gap = self._last_known(order, k, i)
            if last is not None:
                pred[i] = last
                gate[i] = min(c.gate_m + c.gap_gate_growth_m * gap, c.max_gate_m)
            else:
                pred[i] = np.nan
        return pred, gate, vel

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
        return out

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
                same = same if same.size >= c.bridge_min_mates else usable
                if same.size < c.bridge_min_mates:
                    return None
                a, b = t.positions[r, same], t.positions[f, same]
                R = kabsch(a, b)
                moved = (a - a.mean(axis=0)) @ R.T + b.mean(axis=0)
                if np.sqrt(np.mean(np.sum((moved - b) ** 2, axis=1))) > c.bridge_rms_m:
                    return None
                return (ref - a.mean(axis=0)) @ R.T + b.mean(axis=0), t.state[r, i] in (TRINOCULAR, TWO_VIEW)
        return None

    # ------------------------------------------------------------ one frame
    def step(self, order: list[int], k: int) -> None:
        """Label frame ``order[k]`` (``order[k-1]`` already labelled)."""
        t, f = self.t, order[k]
        pred, gate, vel = self.predict(order, k)
        point = self.assign_candidates(order, k, pred, gate, vel)
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
        for i in np.flatnonzero(t.state[f] == MISSING):
            out = self.bridge(order, k, i)
            if out is None:
                continue
            X, seen_before = out
            if seen_before:
                t.positions[f, i] = X
                t.state[f, i] = BRIDGED
            else:  # never measured: the template's prediction, a hint only
                t.hint[i], t.hint_frame[i] = X, f
        labelled = t.point[f][t.point[f] >= 0]
        assert np.unique(labelled).size == labelled.size, "two labels on one reconstructed marker"

    def run(self, order: list[int]) -> None:
        """Label ``order[1:]`` from the labelled ``order[0]``."""
        for k in range(1, len(order)):
            self.step(order, k)


def nearest_neighbour_config(config: TrackConfig = TrackConfig()) -> TrackConfig:
    """The same settings with the nearest-neighbour window (the baseline of the tests and benchmark)."""
    from dataclasses import replace
    return replace(config, window=2)


__all__ = ["TrackConfig", "TrackState", "Tracker", "FrameMarkers", "nearest_neighbour_config"]
