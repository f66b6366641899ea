"""Labelled marker trajectories from a capture of unlabelled 2D blobs (source 004, §3.1.1).

:func:`label_capture` chains the three steps of the source:

1. **reconstruction** of every frame by trinocular matching
   (:mod:`toolkit.markers.reconstruct`);
2. **identification** in the first frame where (nearly) all markers are
   reconstructed, among the first ``identify_within`` frames: the marker set's
   template fitted to them (:mod:`toolkit.markers.identify`), or a user
   labelling file; two-view reconstructions are added to that frame only when
   too few trinocular markers are found;
3. **tracking** forwards to the end and backwards to the first frame with the
   4-frame window, 2D tracking and bridging (:mod:`toolkit.markers.track`),
   then swapped labels within nearly rigid groups repaired frame by frame
   against the identification pose (:func:`~toolkit.markers.track.repair_swaps`).

Markers that cannot be identified in that frame keep the state ``MISSING``
until the tracker recovers them from their segment's motion; when too few
markers are ever reconstructed in the first frames, an :class:`InputError`
says so (the source: "any marker not present in the first frame is lost").
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.markers.identify import (IdentifyConfig, Identification, fit_template, identify_from_labelling, kabsch,
                                      read_labelling)
from toolkit.markers.marker_sets import MarkerSet
from toolkit.markers.reconstruct import (FrameMarkers, ReconstructionConfig, RigGeometry, normalise_blobs,
                                         reconstruct_frame)
from toolkit.markers.track import TrackConfig, Tracker, TrackState, repair_swaps, rigid_mates
from toolkit.markers.trajectories import STATE_NAMES, TRINOCULAR, MarkerTrajectories
from toolkit.observe import as_observer

#: Stature of the generic person the template is built on, metres (scaled by the fit).
TEMPLATE_STATURE_M = 1.75
#: RGB of each marker state in reports (missing, trinocular, two-view, bridged, from file).
STATE_COLORS = np.array([[128, 128, 128], [40, 200, 80], [250, 180, 30], [80, 140, 255], [200, 200, 200]],
                        np.uint8)
#: The 2D blobs in the camera views: screen points (negative: rerun's UI points, readable at any zoom), colour.
BLOB_RADIUS_UI = -2.5
BLOB_COLOR = np.array([230, 60, 20], np.uint8)


@dataclass(frozen=True)
class LabelConfig:
    """Settings of :func:`label_capture`.

    Attributes
    ----------
    reconstruction : ReconstructionConfig
    identify : IdentifyConfig
    track : TrackConfig
    identify_within : int
        Frames searched for the identification frame (the first frames).
    min_seen_fraction : float
        Share of the marker set that must be reconstructed (and identified) in
        the identification frame.
    labelling_tolerance_m : float
        Largest distance between a labelling file's position and its marker.
    """

    reconstruction: ReconstructionConfig = field(default_factory=ReconstructionConfig)
    identify: IdentifyConfig = field(default_factory=IdentifyConfig)
    track: TrackConfig = field(default_factory=TrackConfig)
    identify_within: int = 30
    min_seen_fraction: float = 0.8
    labelling_tolerance_m: float = 0.03


def _camera_blobs(capture, names, f) -> list[np.ndarray]:
    return [np.asarray(capture.detections(name, f), float).reshape(-1, 2) for name in names]


def reconstruct_capture(capture, config: ReconstructionConfig = ReconstructionConfig()):
    """Blobs and trinocular reconstructions of every frame.

    Returns
    -------
    geom : RigGeometry
    blobs : list over frames of list over cameras of ndarray (n, 2)
    recon : list over frames of FrameMarkers
    """
    geom = RigGeometry.of(capture.rig)
    names = capture.rig.names
    blobs, recon = [], []
    for f in range(int(capture.n_frames)):
        b = _camera_blobs(capture, names, f)
        blobs.append(b)
        recon.append(reconstruct_frame(geom, b, config, xy=normalise_blobs(capture.rig, b)))
    return geom, blobs, recon


def choose_identification_frame(recon: list[FrameMarkers], n_markers: int, config: LabelConfig) -> int:
    """The first frame with all markers reconstructed, else the one with the most, among the first frames.

    Raises
    ------
    InputError
        When no frame among the first ``identify_within`` shows ``min_seen_fraction`` of the markers.
    """
    window = recon[:max(1, config.identify_within)]
    counts = np.array([len(r) for r in window])
    full = np.flatnonzero(counts >= n_markers)
    f0 = int(full[0]) if full.size else int(np.argmax(counts))
    if counts[f0] < config.min_seen_fraction * n_markers:
        return -1
    return f0


def _identify(points, marker_set, config, labelling, frame) -> Identification:
    joints = BodyProportions.from_height(TEMPLATE_STATURE_M).rest_pose()
    template = marker_set.positions(joints)
    ident = fit_template(points, template, joints, marker_set.segments, config.identify)
    if labelling is None:
        return ident
    file_frame, given = labelling
    from_file = identify_from_labelling(points, marker_set.labels, given, config.labelling_tolerance_m)
    idx = [marker_set.index(k) for k in given]
    found = [k for k, i in zip(given, idx) if from_file[i] >= 0]
    if len(found) < 0.5 * len(given):
        missed = [k for k in given if k not in found]
        raise InputError(f"labelling file: {', '.join(missed[:5])}",
                         f"a reconstructed marker within {config.labelling_tolerance_m} m in frame {frame} "
                         f"(for at least half the labels)", f"none for {len(missed)} of {len(given)}")
    fitted = ident.fitted.copy()
    fitted[idx] = np.array([given[k] for k in given])  # where the user saw them: the tracker's hint
    sure = [i for i in idx if from_file[i] >= 0]
    agree = np.mean(ident.point_of_marker[sure] == from_file[sure])
    match = from_file.copy()
    if agree >= 0.9:  # the template fit agrees with the user: keep its labels for the others
        taken = set(from_file[from_file >= 0].tolist())
        for i in np.flatnonzero(match < 0):
            p = ident.point_of_marker[i]
            if p >= 0 and p not in taken and marker_set.labels[i] not in given:
                match[i] = p
    return Identification(match, fitted, ident.residual_m, ident.scale, ident.heading_deg, ident.rejected)


def local_hints(fitted: np.ndarray, measured: np.ndarray, segments) -> np.ndarray:
    """Where the markers not identified should be: the fitted template's marker moved with its rigid mates.

    The template is fitted to the whole body at once (one scale and rigid
    motion), so a limb posed otherwise than the template's (an arm swinging
    in a walk) puts its unseen markers far off: a hand's by 14 cm in the walk
    of seed 101, beyond any tracking gate, so it was never found.  Each marker
    whose rigid mates (:func:`~toolkit.markers.track.rigid_mates`: its
    segment's other markers, a one-marker hand's forearm) are measured, at
    least three, is placed by the rigid motion (Kabsch) taking their fitted
    template positions to their measured ones.

    Parameters
    ----------
    fitted : ndarray of shape (M, 3)
        The fitted template's markers, metres.
    measured : ndarray of shape (M, 3)
        The identification frame's labelled markers, NaN where not identified.
    segments : sequence of str (M,)

    Returns
    -------
    ndarray of shape (M, 3)
        ``fitted`` with each marker placed from its measured rigid mates where it has three.
    """
    out = np.asarray(fitted, float).copy()
    seen = np.isfinite(measured).all(axis=1) & np.isfinite(out).all(axis=1)
    for i, mates in enumerate(rigid_mates(segments)):
        mates = mates[seen[mates]]
        if seen[i] or mates.size < 3 or not np.isfinite(out[i]).all():
            continue
        a, b = out[mates], measured[mates]
        R = kabsch(a, b)
        out[i] = (out[i] - a.mean(axis=0)) @ R.T + b.mean(axis=0)
    return out


def label_capture(capture, marker_set: MarkerSet, *, config: LabelConfig = LabelConfig(), labelling=None,
                  observer=None) -> MarkerTrajectories:
    """Labelled 3D marker trajectories of a capture.

    Parameters
    ----------
    capture : MarkerCapture
        ``rig`` (at least 3 cameras), ``fps``, ``n_frames`` and
        ``detections(camera_name, frame) -> (n, 2)`` pixels
        (:func:`toolkit.markers.capture.load_marker_capture`).
    marker_set : MarkerSet
        The markers the performer wears (labels, segments, template).
    config : LabelConfig
    labelling : str or PathLike, optional
        A user labelling file (:func:`toolkit.markers.identify.read_labelling`):
        its frame is the identification frame and its labels win.
    observer : Observer, optional
        Receives ``points2d`` (blobs per camera), ``points3d``
        (``markers/reconstructed``, ``markers/labelled`` coloured by state)
        per frame and a ``text`` summary.

    Returns
    -------
    MarkerTrajectories
        (T, M) with the state of every marker-frame; ``segments`` from the marker set.

    Raises
    ------
    InputError
        Fewer than 3 cameras; no frame among the first ones with enough
        markers; a bad labelling file or one whose markers are not found.
    """
    obs = as_observer(observer)
    geom, blobs, recon = reconstruct_capture(capture, config.reconstruction)
    T, M = len(recon), marker_set.n_markers
    if T == 0:
        raise InputError("capture", "at least one frame", "0 frames")
    given = None
    if labelling is not None:
        given = read_labelling(labelling, marker_set.labels)
        f0 = given[0]
        if not 0 <= f0 < T:
            raise InputError(f"{labelling}: frame", f"a frame in [0, {T})", str(f0))
    else:
        f0 = choose_identification_frame(recon, M, config)
    if f0 < 0 or len(recon[f0]) < config.min_seen_fraction * M:
        f1 = max(f0, 0) if labelling is not None else 0
        candidates = [f1] if labelling is not None else range(min(T, config.identify_within))
        for f in candidates:  # the source's second stereo pass: add two-view reconstructions
            recon[f] = reconstruct_frame(geom, blobs[f], config.reconstruction, two_view=True)
        f0 = f1 if labelling is not None else choose_identification_frame(recon, M, config)
    if f0 < 0:
        best = max(len(r) for r in recon[:config.identify_within])
        raise InputError(f"capture: first {min(T, config.identify_within)} frames",
                         f"a frame with at least {config.min_seen_fraction:.0%} of the {M} markers reconstructed",
                         f"at most {best} markers")
    ident = _identify(recon[f0].points, marker_set, config, given, f0)
    found = ident.point_of_marker >= 0
    if found.sum() < config.min_seen_fraction * M:
        raise InputError(f"capture: frame {f0}",
                         f"at least {config.min_seen_fraction:.0%} of the {M} markers identified",
                         f"{int(found.sum())} (template fit residual median "
                         f"{np.nanmedian(ident.residual_m) * 1000:.0f} mm)")
    track = TrackState.empty(T, marker_set.segments)
    track.point[f0] = ident.point_of_marker
    track.positions[f0, found] = recon[f0].points[ident.point_of_marker[found]]
    track.state[f0, found] = recon[f0].state[ident.point_of_marker[found]]
    track.hint[~found] = local_hints(ident.fitted, track.positions[f0], marker_set.segments)[~found]
    track.hint_frame[~found] = f0
    hint, hint_frame = track.hint.copy(), track.hint_frame.copy()
    tracker = Tracker(geom, lambda f: blobs[f], lambda f: recon[f], track, config.track)
    tracker.run(list(range(f0, T)))
    track.hint, track.hint_frame = hint, hint_frame
    tracker.run(list(range(f0, -1, -1)))
    reference = np.where(found[:, None], track.positions[f0], ident.fitted)
    def spare(f):  # trinocular reconstructions that carry no label
        rec = recon[f]
        free = (rec.state == TRINOCULAR) & ~np.isin(np.arange(len(rec)), track.point[f])
        return rec.points[free]

    repair_swaps(track, reference, spare=spare)
    traj = MarkerTrajectories(marker_set.labels, track.positions, track.state, float(capture.fps),
                              marker_set.segments, getattr(capture, "source", "<capture>"))
    if observer is not None:
        _report(obs, capture.rig.names, blobs, recon, traj, f0, ident, marker_set)
    return traj


def _report(obs, names, blobs, recon, traj: MarkerTrajectories, f0, ident, marker_set) -> None:
    counts = {STATE_NAMES[s]: int(np.sum(traj.state == s)) for s in STATE_NAMES}
    rejected = [marker_set.labels[i] for i in ident.rejected]
    obs.report("text", text=f"markers identified in frame {f0} (heading {ident.heading_deg:.0f} deg, "
                            f"scale {ident.scale:.2f}, rejected {rejected}); states {counts}",
               name="markers/log", static=True)
    for f in range(traj.n_frames):
        for name, b in zip(names, blobs[f]):
            obs.report("points2d", camera=name, points=b, name="markers/blobs", frame=f, radii=BLOB_RADIUS_UI,
                       colors=np.tile(BLOB_COLOR, (len(b), 1)))
        obs.report("points3d", points=recon[f].points, name="markers/reconstructed", frame=f,
                   colors=STATE_COLORS[recon[f].state])
        ok = traj.state[f] != 0
        obs.report("points3d", points=traj.positions[f, ok], name="markers/labelled", frame=f,
                   colors=STATE_COLORS[traj.state[f, ok]])
