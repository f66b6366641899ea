"""People over time: the groups of :mod:`toolkit.multiview.association` linked frame to frame.

Each frame's people (groups of detections across views, with their keypoints
triangulated) are matched to the tracks of the previous frames by the median
distance of their 3D keypoints (Hungarian assignment, ``scipy.optimize``).  A
match is allowed when that distance is at most
``gate_m + max_speed_m_s * dt`` (``dt``: seconds since the track was last
seen), so a person who walks stays the same person and one who is hidden for a
few frames is found again.  A person nobody matches starts a track (someone
entering); a track unseen for ``max_gap_s`` ends (someone leaving).  Tracks
seen in fewer than ``min_frames`` frames (or than the frames in which anyone
is seen, when those are fewer) are dropped: a chance meeting of rays
of two different people (a "ghost") rarely lasts; so are tracks that cameras
with them in sight do not show (``FrameAssociation.unexplained``) in more than
:data:`MAX_UNEXPLAINED_SHARE` of their frames: a ghost that lasts (two
bystanders standing still, each seen by one camera) floats where the other
cameras see nobody.

:func:`track_people` returns, per person, the detection it used in each view
and frame, so that each person can be triangulated on its own keypoints
(:meth:`PeopleTracks.keypoints`); :func:`main_person` is the person most
cameras agree on (the single-person choice).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.multiview.association import AssociationConfig, FrameAssociation, associate_frame
from toolkit.observe import Observer, as_observer

__all__ = ["TRACK_GATE_M", "MAX_SPEED_M_S", "MAX_GAP_S", "MIN_TRACK_FRAMES", "TrackingConfig", "PeopleTracks",
           "track_people", "main_person", "person_keypoints", "frame_detections"]

#: A track and a new group match when their keypoints are at most this far apart (median, metres) ...
TRACK_GATE_M = 0.3
#: ... plus this speed times the time since the track was last seen (a sprint is 8 m/s; the
#: median of a body's keypoints moves at walking and running speeds, 1.5-4 m/s).
MAX_SPEED_M_S = 4.0
#: A track unseen for longer than this ends (seconds).
MAX_GAP_S = 1.0
#: Tracks seen in fewer frames than this are dropped (chance meetings of rays).
MIN_TRACK_FRAMES = 3
#: Tracks that a camera with them in sight does not show in more than this share of their frames
#: are dropped (a person missed by the detector without an occluder in front is rare).
MAX_UNEXPLAINED_SHARE = 0.5
#: Frame rate assumed by :class:`TrackingConfig` when none is given.
DEFAULT_FPS = 30.0


@dataclass(frozen=True)
class TrackingConfig:
    """Options of :func:`track_people`.

    Parameters
    ----------
    association : AssociationConfig
        How detections are grouped within a frame.
    fps : float
        Frame rate, Hz (turns frames into seconds).
    gate_m, max_speed_m_s, max_gap_s : float
        The matching gate and the longest gap (see the module docstring).
    min_frames : int
        Shortest track kept, frames (a sequence in which fewer frames than that hold anyone seen by two
        cameras keeps the tracks seen in all of those frames).
    max_unexplained_share : float
        Tracks unexplained by a camera in sight in more than this share of their frames
        are dropped (:data:`MAX_UNEXPLAINED_SHARE`).
    """

    association: AssociationConfig = field(default_factory=AssociationConfig)
    fps: float = DEFAULT_FPS
    gate_m: float = TRACK_GATE_M
    max_speed_m_s: float = MAX_SPEED_M_S
    max_gap_s: float = MAX_GAP_S
    min_frames: int = MIN_TRACK_FRAMES
    max_unexplained_share: float = MAX_UNEXPLAINED_SHARE

    def __post_init__(self):
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise InputError("TrackingConfig.fps", "a positive frame rate", repr(self.fps))
        if self.gate_m < 0 or self.max_speed_m_s < 0 or self.max_gap_s < 0 or self.min_frames < 1:
            raise InputError("TrackingConfig", "non-negative gate, speed and gap, min_frames >= 1",
                             f"{self.gate_m}, {self.max_speed_m_s}, {self.max_gap_s}, {self.min_frames}")


@dataclass(frozen=True, eq=False)
class PeopleTracks:
    """The people of a sequence.

    Attributes
    ----------
    assignment : ndarray of shape (n_people, T, n_views) of int
        The detection of each person in each frame and view (its index in that frame's
        detections), -1 where the view does not see it.  People are sorted by the number
        of (frame, view) detections they hold, most first.
    joints3d : ndarray of shape (n_people, T, K, 3)
        The association's triangulation of each person's keypoints (closest points, no
        offsets), metres; NaN where absent.
    cost : ndarray of shape (n_people, T)
        Mean ray distance of the person's detections, metres; NaN where absent.
    frames : list of FrameAssociation
        Each frame's groups (before tracking).
    """

    assignment: np.ndarray
    joints3d: np.ndarray
    cost: np.ndarray
    frames: list

    @property
    def n_people(self) -> int:
        return len(self.assignment)

    @property
    def views(self) -> np.ndarray:
        """(n_people, T) number of cameras that see each person."""
        return (self.assignment >= 0).sum(-1)

    def keypoints(self, detections, person: int) -> np.ndarray:
        """One person's keypoints, every view and frame.

        Parameters
        ----------
        detections : sequence over frames of list over views of ndarray (P, K, 3)
            The detections given to :func:`track_people`.
        person : int

        Returns
        -------
        ndarray of shape (n_views, T, K, 3)
            ``(x, y, confidence)``; NaN and confidence 0 where the view does not see it.
        """
        return person_keypoints(detections, self.assignment[person], self.joints3d.shape[2])


def person_keypoints(detections, assignment: np.ndarray, n_keypoints: int) -> np.ndarray:
    """(n_views, T, K, 3) keypoints picked by a (T, n_views) assignment (see :class:`PeopleTracks`)."""
    T, V = assignment.shape
    out = np.full((V, T, n_keypoints, 3), np.nan)
    out[..., 2] = 0.0
    for t, v in zip(*np.nonzero(assignment >= 0)):
        out[v, t] = detections[t][v][assignment[t, v]]
    return out


def frame_detections(cameras, frames: np.ndarray, n_keypoints: int) -> list:
    """Every camera's detections, frame by frame.

    Parameters
    ----------
    cameras : sequence of CameraDetections
        Per camera (``toolkit.io.keypoint_files``), its ``frames`` (T_c,) and ``people``
        (per frame a (P, K, 3) array).
    frames : ndarray of shape (T,) of int
        The frame numbers wanted (a camera without an entry for one gives no detection).
    n_keypoints : int

    Returns
    -------
    list over T of list over n_views of ndarray of shape (P, K, 3)
    """
    pos = [{int(n): t for t, n in enumerate(c.frames)} for c in cameras]
    empty = np.zeros((0, n_keypoints, 3))
    out = []
    for n in np.asarray(frames).tolist():
        out.append([np.asarray(c.people[p[int(n)]], float).reshape(-1, n_keypoints, 3) if int(n) in p else empty
                    for c, p in zip(cameras, pos)])
    return out


def _distance(a: np.ndarray, b: np.ndarray) -> float:
    d = np.linalg.norm(a - b, axis=-1)
    return float(np.nanmedian(d)) if np.isfinite(d).any() else np.inf


def track_people(detections, rig: Rig, config: TrackingConfig = TrackingConfig(), *,
                 observer: Observer | None = None) -> PeopleTracks:
    """Associate detections across views, frame by frame, and link them over time.

    Parameters
    ----------
    detections : sequence over T frames of list over n_views of ndarray of shape (P, K, 3)
        Every person each camera detected in each frame, ``(x, y, confidence)`` pixels (NaN /
        0 where a keypoint is missing); ``P`` varies with the view and frame.
    rig : Rig
    config : TrackingConfig
    observer : Observer, optional
        Receives per frame a ``scalar`` ``people/count`` and a ``text`` ``people/groups``.

    Returns
    -------
    PeopleTracks

    Raises
    ------
    InputError
        A frame without one list of detections per camera, or detections of the wrong shape.
    """
    obs = as_observer(observer)
    T, V = len(detections), len(rig)
    per_frame: list[FrameAssociation] = []
    tracks: list[dict] = []  # {"rows": {t: p}, "last": t, "X": (K, 3)}
    K = 0
    for t in range(T):
        fa = associate_frame(detections[t], rig, config.association)
        per_frame.append(fa)
        K = max(K, fa.joints3d.shape[1])
        live = [k for k, tr in enumerate(tracks) if (t - tr["last"]) / config.fps <= config.max_gap_s]
        matched = set()
        if live and fa.n_people:
            cost = np.full((len(live), fa.n_people), np.inf)
            for a, k in enumerate(live):
                gate = config.gate_m + config.max_speed_m_s * (t - tracks[k]["last"]) / config.fps
                for p in range(fa.n_people):
                    d = _distance(tracks[k]["X"], fa.joints3d[p])
                    if d <= gate:
                        cost[a, p] = d
            big = 1e6
            rows, cols = linear_sum_assignment(np.where(np.isfinite(cost), cost, big))
            for a, p in zip(rows, cols):
                if np.isfinite(cost[a, p]):
                    tr = tracks[live[a]]
                    tr["rows"][t], tr["last"] = p, t
                    tr["X"] = np.where(np.isfinite(fa.joints3d[p]), fa.joints3d[p], tr["X"])
                    matched.add(p)
        for p in range(fa.n_people):
            if p not in matched:
                tracks.append({"rows": {t: p}, "last": t, "X": fa.joints3d[p].copy()})
        obs.report("scalar", name="people/count", value=float(fa.n_people), frame=t)
        if fa.n_people or fa.unassigned:
            obs.report("text", name="people/groups", frame=t, text="; ".join(
                [", ".join(f"{rig[v].name}#{i}" for v, i in enumerate(g) if i >= 0) + f" ({1000 * c:.0f} mm)"
                 for g, c in zip(fa.groups, fa.cost)]
                + [f"one view only: {rig[v].name}#{i}" for v, i in fa.unassigned]))
    # a sequence in which people are seen in fewer frames than that keeps those seen in all of them (frames
    # where nobody is seen by two cameras cannot hold a track: counting them dropped everyone)
    shortest = min(config.min_frames, max(sum(fa.n_people > 0 for fa in per_frame), 1))
    kept = [tr for tr in tracks if len(tr["rows"]) >= shortest
            and np.mean([per_frame[t].unexplained[p] > 0 for t, p in tr["rows"].items()])
            <= config.max_unexplained_share]
    n = len(kept)
    assignment = np.full((n, T, V), -1)
    joints = np.full((n, T, K, 3), np.nan)
    cost = np.full((n, T), np.nan)
    for k, tr in enumerate(kept):
        for t, p in tr["rows"].items():
            fa = per_frame[t]
            assignment[k, t] = fa.groups[p]
            joints[k, t, :fa.joints3d.shape[1]] = fa.joints3d[p]
            cost[k, t] = fa.cost[p]
    order = np.argsort(-(assignment >= 0).sum(axis=(1, 2)), kind="stable")
    return PeopleTracks(assignment[order], joints[order], cost[order], per_frame)


def main_person(detections, rig: Rig, config: TrackingConfig = TrackingConfig()) -> np.ndarray:
    """The keypoints of the person most cameras agree on, every view and frame.

    The person of :func:`track_people` holding the most (frame, view) detections.  When no
    view holds more than one detection in any frame, the detections as given (nobody to
    choose between; the triangulation's robust mode drops a view that disagrees).

    Parameters
    ----------
    detections : sequence over T frames of list over n_views of ndarray of shape (P, K, 3)
    rig : Rig
    config : TrackingConfig

    Returns
    -------
    ndarray of shape (n_views, T, K, 3)
        ``(x, y, confidence)``; NaN / 0 where the person is not seen (all of it when
        nobody is seen by two cameras).
    """
    K = next((np.asarray(d).shape[1] for fr in detections for d in fr if len(d)), 0)
    if all(len(d) <= 1 for fr in detections for d in fr):
        single = np.array([[len(d) == 1 for d in fr] for fr in detections], bool).reshape(len(detections), len(rig))
        return person_keypoints(detections, np.where(single, 0, -1), K)
    tracks = track_people(detections, rig, config)
    if tracks.n_people == 0:
        out = np.full((len(rig), len(detections), K, 3), np.nan)
        out[..., 2] = 0.0
        return out
    return person_keypoints(detections, tracks.assignment[0], K)
