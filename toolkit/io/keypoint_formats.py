"""The keypoint format of detections, found from the files, and one person per camera and frame.

The keypoint format (:data:`~toolkit.skeleton.mappings.DETECTOR_FORMATS`) is found from the
keypoint names when a file gives them, else from the count of keypoints per person
(17 COCO-17, 18 COCO-18, 26 HALPE-26, 133 COCO-WholeBody); 25 is OpenPose's BODY_25 or
BODY_25B, told apart by where keypoint 1 and the heels lie (:func:`body25_evidence`).  Anything else
raises :class:`~toolkit.errors.InputError` naming the file and the counts.
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.keypoint_files import (LAYOUTS, PER_FRAME_LAYOUTS, CameraDetections, camera_sources,
                                       match_cameras, normalise_name, read_camera_detections)
from toolkit.io.openpose import PERSON_POLICIES
from toolkit.skeleton.mappings import DETECTOR_FORMATS, KEYPOINTS, MAPPINGS

__all__ = ["LAYOUTS", "PER_FRAME_LAYOUTS", "CameraDetections", "KeypointInput", "FormatChoice",
           "read_camera_detections", "camera_sources", "match_cameras", "keypoint_count", "body25_evidence",
           "detect_format", "select_person", "read_keypoints"]

#: BODY_25 versus BODY_25B: the median log ratio of :func:`body25_evidence` must pass this
#: (a factor 3 either way; the Pose2Sim demo's BODY_25B detections measure +1.7 to +2.5, the
#: same detections rewritten as BODY_25 about -4.6, docs/keypoint_formats.md).
BODY25_LOG_RATIO = float(np.log(3.0))
#: Pixels added to both distances of a relation (a keypoint written exactly at a midpoint
#: is strong evidence, not a division by zero).
BODY25_EPS_PX = 1.0
#: ... on at least this many detections with the keypoints it needs,
BODY25_MIN_DETECTIONS = 3
#: ... and this share of them must agree in sign.
BODY25_MIN_AGREEMENT = 0.8


@dataclass(frozen=True)
class FormatChoice:
    """The keypoint format used and why.

    Attributes
    ----------
    fmt : str
        One of :data:`~toolkit.skeleton.mappings.DETECTOR_FORMATS`.
    reason : str
        How it was chosen (declared, names, count, geometry), for the log and the metadata.
    """

    fmt: str
    reason: str


@dataclass(frozen=True, eq=False)
class KeypointInput:
    """The keypoints of every camera, aligned on frame numbers, one person per frame.

    Attributes
    ----------
    cameras : tuple of CameraDetections
        In the order of the calibration cameras they were matched to (or of the sources).
    frames : ndarray of shape (T,) of int
        The union of the cameras' frame numbers, sorted.
    keypoints : ndarray of shape (n_cams, T, K, 3)
        ``(x, y, confidence)``; NaN / 0 where missing.
    format : FormatChoice
    missing : ndarray of shape (n_cams, T) of bool
        The camera has no file (or no entry) for the frame.
    empty : ndarray of shape (n_cams, T) of bool
        The camera's file for the frame holds nobody.
    """

    cameras: tuple[CameraDetections, ...]
    frames: np.ndarray
    keypoints: np.ndarray
    format: FormatChoice
    missing: np.ndarray
    empty: np.ndarray


# --------------------------------------------------------------------------- the format

def keypoint_count(cameras: list[CameraDetections]) -> int | None:
    """The keypoints per person, the same in every file.

    Returns
    -------
    int or None
        ``None`` when no camera detected anybody.

    Raises
    ------
    InputError
        A person with another count than most, naming its file and both counts.
    """
    counts = Counter()
    for cam in cameras:
        for people in cam.people:
            for person in people:
                counts[len(person)] += 1
    if not counts:
        return None
    k, n = counts.most_common(1)[0]
    if len(counts) > 1:
        for cam in cameras:
            for t, people in enumerate(cam.people):
                for i, person in enumerate(people):
                    if len(person) != k:
                        raise InputError(f"{cam.where(t)}: person {i} (frame {int(cam.frames[t])})",
                                         f"{k} keypoints per person like the other detections ({n} persons)",
                                         f"{len(person)} keypoints (counts found: {dict(counts)})")
    return k


#: Relations telling BODY_25 from BODY_25B: (a, b, c, d) with |a - b| small in BODY_25 and
#: |c - d| small in BODY_25B (a tuple is the mean of its keypoints).  1 is BODY_25's neck
#: (between the shoulders 2 and 5) or BODY_25B's left eye (next to the nose 0); the heels
#: 24 and 21 are next to BODY_25's ankles 11 and 14 or BODY_25B's ankles 16 and 15; 8 is
#: BODY_25's mid-hip (between the hips 9 and 12), 17 BODY_25B's upper neck (just above the
#: middle of the shoulders 5 and 6).
BODY25_RELATIONS = ((1, (2, 5), 1, 0), (24, 11, 24, 16), (21, 14, 21, 15), (8, (9, 12), 17, (5, 6)))


def body25_evidence(cameras: list[CameraDetections]) -> np.ndarray:
    """Per detection of 25 keypoints, the median of log((|a - b| + e) / (|c - d| + e)) over
    :data:`BODY25_RELATIONS` (``e`` = :data:`BODY25_EPS_PX`).

    Negative when the keypoints sit like BODY_25's (keypoint 1 half-way between the
    shoulders, heels next to keypoints 11 and 14), positive when they sit like BODY_25B's
    (keypoint 1 next to the nose, heels next to 16 and 15).

    Returns
    -------
    ndarray of shape (N,)
        One value per detection where the keypoints of at least one relation are present.
    """
    def point(p, i):
        idx = list(i) if isinstance(i, tuple) else [i]
        return None if not (p[idx, 2] > 0).all() else p[idx, :2].mean(axis=0)

    out = []
    for cam in cameras:
        for people in cam.people:
            for p in people:
                if len(p) != 25:
                    continue
                vals = []
                for a, b, c, d in BODY25_RELATIONS:
                    pts = [point(p, i) for i in (a, b, c, d)]
                    if any(q is None for q in pts):
                        continue
                    num, den = np.linalg.norm(pts[0] - pts[1]), np.linalg.norm(pts[2] - pts[3])
                    vals.append(np.log((num + BODY25_EPS_PX) / (den + BODY25_EPS_PX)))
                if vals:
                    out.append(float(np.median(vals)))
    return np.array(out)


def _body25_verdict(cameras) -> tuple[str | None, str]:
    ev = body25_evidence(cameras)
    if len(ev) < BODY25_MIN_DETECTIONS:
        return None, (f"only {len(ev)} detections with the keypoints that tell BODY_25 from BODY_25B "
                      f"(need {BODY25_MIN_DETECTIONS})")
    med = float(np.median(ev))
    agree = float(np.mean(np.sign(ev) == np.sign(med)))
    text = (f"layout evidence {med:+.2f} (< 0 BODY_25, > 0 BODY_25B) over {len(ev)} detections, "
            f"{agree:.0%} agree")
    if abs(med) < BODY25_LOG_RATIO or agree < BODY25_MIN_AGREEMENT:
        return None, text
    return ("body_25" if med < 0 else "body_25b"), text


def _names_match(fmt: str, names: tuple[str, ...]) -> bool:
    ours = KEYPOINTS[fmt]
    if len(ours) != len(names):
        return False
    used = {n for alts in MAPPINGS[fmt].values() for alt in alts for n in alt}
    return all(normalise_name(ours[i]) == normalise_name(names[i]) for i, n in enumerate(ours) if n in used)


def detect_format(cameras: list[CameraDetections], declared: str | None = None,
                  declared_by: str = "--format") -> FormatChoice:
    """The keypoint format of the detections, checked against a declared one.

    Parameters
    ----------
    cameras : list of CameraDetections
    declared : str, optional
        A format of :data:`~toolkit.skeleton.mappings.DETECTOR_FORMATS` given by the user
        or a Pose2Sim ``Config.toml``; ``None`` to find it from the files.
    declared_by : str
        Where ``declared`` comes from, for messages.

    Returns
    -------
    FormatChoice

    Raises
    ------
    InputError
        Counts that differ between persons, a count or names matching no format (or not the
        declared one), BODY_25 and BODY_25B not told apart, or the files contradicting the
        declared format; each names a file and what was found.
    """
    if declared is not None and declared not in DETECTOR_FORMATS:
        raise InputError(declared_by, f"one of {list(DETECTOR_FORMATS)}", repr(declared))
    k = keypoint_count(cameras)
    first = next((c for c in cameras if any(len(p) for p in c.people)), cameras[0] if cameras else None)
    where = str(first.source) if first is not None else "keypoints"
    named = next((c for c in cameras if c.names), None)
    if named is not None and k is not None and len(named.names) != k:
        raise InputError(f"{named.source}: keypoint names", f"{k} names, one per keypoint", f"{len(named.names)}")
    if declared is not None:
        n = len(KEYPOINTS[declared])
        if k is not None and k != n:
            w = next(f"{c.where(t)}: person {i} (frame {int(c.frames[t])})" for c in cameras
                     for t, pp in enumerate(c.people) for i, p in enumerate(pp) if len(p) != n)
            raise InputError(w, f"{n} keypoints per person for {declared} (declared by {declared_by})",
                             f"{k}")
        if named is not None and not _names_match(declared, named.names):
            raise InputError(f"{named.source}: keypoint names", f"those of {declared} (declared by {declared_by})",
                             f"{list(named.names[:6])}...")
        if declared in ("body_25", "body_25b"):
            verdict, text = _body25_verdict(cameras)
            if verdict is not None and verdict != declared:
                raise InputError(where, f"{declared} keypoints (declared by {declared_by})",
                                 f"keypoints laid out like {verdict}: {text}")
        return FormatChoice(declared, f"declared by {declared_by}")
    if k is None:
        raise InputError(where, "at least one detected person to tell the keypoint format (or give --format)",
                         "nobody in any file")
    if named is not None:
        hits = [f for f in DETECTOR_FORMATS if _names_match(f, named.names)]
        if len(hits) == 1:
            return FormatChoice(hits[0], f"keypoint names in {named.source.name}")
        raise InputError(f"{named.source}: keypoint names", f"the names of one of {list(DETECTOR_FORMATS)}",
                         f"{k} names {list(named.names[:6])}...")
    by_count = [f for f in DETECTOR_FORMATS if len(KEYPOINTS[f]) == k]
    if not by_count:
        counts = sorted({len(KEYPOINTS[f]) for f in DETECTOR_FORMATS})
        raise InputError(where, f"a keypoint count of a known format {counts} ({list(DETECTOR_FORMATS)})",
                         f"{k} keypoints per person")
    if len(by_count) == 1:
        return FormatChoice(by_count[0], f"{k} keypoints per person")
    verdict, text = _body25_verdict(cameras)
    if verdict is None:
        raise InputError(where, "25 keypoints laid out clearly like BODY_25 or BODY_25B (else give --format)",
                         text)
    return FormatChoice(verdict, f"25 keypoints per person, {text}")


# --------------------------------------------------------------------------- one person

def select_person(people: np.ndarray, n_keypoints: int, policy: str = "most_confident") -> np.ndarray:
    """One person of a frame.

    Parameters
    ----------
    people : ndarray of shape (P, K, 3)
    n_keypoints : int
        ``K``, for the all-missing answer when ``P = 0``.
    policy : str
        ``"most_confident"`` (largest summed confidence) or ``"first"``.

    Returns
    -------
    ndarray of shape (K, 3)
    """
    if policy not in PERSON_POLICIES:
        raise InputError("person", f"one of {list(PERSON_POLICIES)}", repr(policy))
    if len(people) == 0:
        out = np.full((n_keypoints, 3), np.nan)
        out[:, 2] = 0.0
        return out
    if policy == "first":
        return np.asarray(people[0], float)
    return np.asarray(max(people, key=lambda a: float(np.nansum(np.asarray(a, float)[:, 2]))), float)


def _span(frames) -> str:
    """``frames first-last`` of a camera's frame numbers (``no frames`` when it has none)."""
    f = np.asarray(frames)
    return f"frames {int(f.min())}-{int(f.max())}" if f.size else "no frames"


def read_keypoints(sources: list[str | os.PathLike], fmt: str | None = None, declared_by: str = "--format",
                   person: str = "most_confident", max_frames: int | None = None,
                   frame_offsets: list[int] | None = None) -> KeypointInput:
    """Keypoints of every camera, in the given order, aligned on frame numbers.

    Parameters
    ----------
    sources : list of path-like
        Per camera a folder of per-frame files or a whole-sequence file
        (:func:`camera_sources`, ordered like the calibration by :func:`match_cameras`).
    fmt : str, optional
        The declared format; ``None`` finds it (:func:`detect_format`).
    declared_by : str
        Where ``fmt`` comes from, for messages.
    person : str
        How to pick one person of a frame (:func:`select_person`).
    max_frames : int, optional
        Keep only the first ``max_frames`` frame numbers of the union.
    frame_offsets : list of int, optional
        Per source, frames it started late (``sync.json``, toolkit.detection.sync): its frame ``f``
        is frame ``f + offset`` of the common timeline (the cameras' ``frames`` are shifted so).

    Returns
    -------
    KeypointInput

    Raises
    ------
    InputError
        See :func:`read_camera_detections` and :func:`detect_format`.
    """
    cams = [read_camera_detections(s, max_frames) for s in sources]
    if frame_offsets is not None:
        if len(frame_offsets) != len(cams):
            raise InputError("frame_offsets", f"one offset per source ({len(cams)})", f"{len(frame_offsets)}")
        cams = [replace(c, frames=np.asarray(c.frames) + int(o)) if o else c for c, o in zip(cams, frame_offsets)]
    choice = detect_format(cams, fmt, declared_by)
    n_kp = len(KEYPOINTS[choice.fmt])
    frames = np.unique(np.concatenate([c.frames for c in cams])) if cams else np.zeros(0, int)
    if max_frames is not None:
        frames = frames[:max_frames]
    kp = np.full((len(cams), len(frames), n_kp, 3), np.nan)
    kp[..., 2] = 0.0
    missing = np.ones((len(cams), len(frames)), bool)
    empty = np.zeros((len(cams), len(frames)), bool)
    pos = {n: i for i, n in enumerate(frames.tolist())}
    for c, cam in enumerate(cams):
        for t, n in enumerate(cam.frames.tolist()):
            if n in pos:
                missing[c, pos[n]] = False
                empty[c, pos[n]] = len(cam.people[t]) == 0
                kp[c, pos[n]] = select_person(cam.people[t], n_kp, person)
    if len(cams) >= 2 and len(frames) and not ((~missing).sum(axis=0) >= 2).any():
        ranges = ", ".join(f"{Path(s).name} {_span(c.frames)}" for s, c in zip(sources, cams))
        raise InputError(f"{Path(sources[0]).parent}: keypoint files",
                         "files of two cameras or more for the same frame numbers (frames are matched by the "
                         "number in their names, shifted by sync.json where there is one)",
                         f"no frame number in two cameras ({ranges}); renumber the files or give the offsets")
    return KeypointInput(cameras=tuple(cams), frames=frames, keypoints=kp, format=choice, missing=missing,
                         empty=empty)


