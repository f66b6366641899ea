"""Several people and bystanders seen by a ring of cameras, as a 2D detector reports them (no rendering).

:func:`make_crowd` places two or three people in a capture volume (each
with its own body proportions and an in-place motion of the motion library,
on spots at least :data:`MIN_SEPARATION_M` apart), lets all but the first enter
late and leave early, and puts bystanders outside the volume where exactly one
camera sees them.  :func:`detect_crowd` turns every person a camera sees into
a detection with the detector noise model of ``benchmarks/bench_keypoints.py``
(per-joint bias per view, jitter, missed joints, confidences, occasional
left/right swaps), scaled to the person's size in the image, drops a person
from a view now and then (occlusion, so that views hold different counts), and
shuffles each frame's detections.  The truth (which person each detection
shows) comes back alongside for scoring; :func:`score_people` scores
estimated people against it (per person MPJPE, identity switches, missed
frames, false people).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from toolkit.anthropometry import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.motion import generate_motion
from toolkit.skeleton import SKELETON_14
from toolkit.synthetic.rigs import perturb_rig

__all__ = ["CrowdScene", "CrowdDetections", "PeopleScore", "make_crowd", "detect_crowd", "score_people",
           "IN_PLACE_MOTIONS", "MIN_SEPARATION_M"]

#: Motions that stay on their spot (a walk would cross the other people's spots).
IN_PLACE_MOTIONS = ("idle", "wave", "turn", "kick", "crouch", "jump")
#: People stand at least this far apart (metres, between their spots).
MIN_SEPARATION_M = 1.0
#: Spots lie within this radius of the volume's centre (metres).
VOLUME_RADIUS_M = 1.5
#: Cameras stand on a ring of this radius range (metres) and height range (metres).
RING_RADIUS_M = (5.0, 6.5)
RING_HEIGHT_M = (1.4, 2.6)
#: Bystanders stand this far from the centre (metres), outside the volume.
BYSTANDER_RADIUS_M = (3.5, 9.0)
#: A body is in a camera's view (and detected, its joints outside the image missing) when this
#: share of its joints project into the image.
IN_VIEW_SHARE = 0.5
#: Subject size (pixels) the detector noise figures are given for (bench_keypoints.py).
NOISE_REFERENCE_PX = 200.0
#: Frame range a late person enters in and an early one leaves in (shares of the sequence).
ENTER_BY, LEAVE_FROM = 0.3, 0.7


@dataclass(frozen=True, eq=False)
class CrowdScene:
    """People and cameras of a crowd scene.

    Attributes
    ----------
    rig : Rig
        True cameras.
    measured_rig : Rig
        The perturbed calibration the pipeline is given.
    joints : ndarray of shape (n_bodies, T, 14, 3)
        Every body's true joints, metres, world z up; NaN where absent (before entering,
        after leaving).
    roles : tuple of str
        Per body ``"person"`` (in the capture volume) or ``"bystander"`` (seen by one camera).
    fps : float
    """

    rig: Rig
    measured_rig: Rig
    joints: np.ndarray
    roles: tuple[str, ...]
    fps: float

    @property
    def people(self) -> np.ndarray:
        """Indices of the bodies that are people (not bystanders)."""
        return np.array([i for i, r in enumerate(self.roles) if r == "person"], int)


@dataclass(frozen=True, eq=False)
class CrowdDetections:
    """What a detector reports of a crowd scene.

    Attributes
    ----------
    detections : list over T of list over n_views of ndarray of shape (P, 14, 3)
        ``(x, y, confidence)`` pixels of 14-joint keypoints; NaN / 0 where missed; shuffled.
    identity : list over T of list over n_views of ndarray of shape (P,) of int
        The body (index into ``CrowdScene.joints``) of each detection.
    swapped : list over T of list over n_views of ndarray of shape (P,) of bool
        Detections whose left and right were swapped.
    """

    detections: list
    identity: list
    swapped: list

    def counts(self) -> np.ndarray:
        """(T, n_views) detections per frame and view."""
        return np.array([[len(d) for d in fr] for fr in self.detections])


def _ring_rig(n_cams: int, size, rng) -> Rig:
    az = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(n_cams) / n_cams + rng.uniform(-0.2, 0.2, n_cams)
    cams = []
    for i, a in enumerate(az):
        r, h = rng.uniform(*RING_RADIUS_M), rng.uniform(*RING_HEIGHT_M)
        eye = np.array([r * np.cos(a), r * np.sin(a), h])
        target = np.array([0.0, 0.0, 0.95])
        d = np.linalg.norm(eye - target)
        # frame the volume: 2.4 m tall, VOLUME_RADIUS_M + 0.7 m either side
        focal = min(0.5 * size[1] * d / 1.35, 0.5 * size[0] * d / (VOLUME_RADIUS_M + 0.9))
        cams.append(Camera.look_at(f"cam{i:02d}", eye, target, size=size, focal_px=focal))
    return Rig(tuple(cams))


def _in_view(cam: Camera, joints: np.ndarray, share: float = IN_VIEW_SHARE) -> bool:
    ok = np.isfinite(joints).all(-1)
    if not ok.any():
        return False
    X = joints[ok]
    return bool(np.mean((cam.depth_of(X) > 0.3) & cam.in_image(cam.project(X))) >= share)


def _on_spot(joints: np.ndarray, spot: np.ndarray) -> np.ndarray:
    c = np.nanmean(joints[:, :, :2], axis=(0, 1))
    return joints + np.r_[spot - c, 0.0]


def make_crowd(n_people: int = 3, n_bystanders: int = 1, n_cams: int = 4, n_frames: int = 40, fps: float = 25.0,
               calibration_error_px: float = 0.0, size=(1280, 720),
               rng: np.random.Generator | int | None = None) -> CrowdScene:
    """A crowd scene (see the module docstring).

    Parameters
    ----------
    n_people : int
        People in the capture volume (>= 1); the first is present throughout, the others
        enter within the first 30 % of the frames and leave within the last 30 %.
    n_bystanders : int
        Bystanders outside the volume, each seen by exactly one camera, present throughout.
    n_cams : int
        Cameras on a ring around the volume (>= 2).
    n_frames : int
    fps : float
    calibration_error_px : float
        Mean reprojection error of the measured calibration, pixels.
    size : tuple of int
        Image (width, height).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    CrowdScene

    Raises
    ------
    InputError
        Counts out of range, or no place found for a bystander seen by one camera only.
    """
    if n_people < 1 or n_bystanders < 0 or n_cams < 2 or n_frames < 1:
        raise InputError("make_crowd", "n_people >= 1, n_bystanders >= 0, n_cams >= 2, n_frames >= 1",
                         f"{n_people}, {n_bystanders}, {n_cams}, {n_frames}")
    rng = np.random.default_rng(rng)
    rig = _ring_rig(n_cams, size, rng)
    spots = []
    while len(spots) < n_people:
        p = rng.uniform(-VOLUME_RADIUS_M, VOLUME_RADIUS_M, 2)
        if np.linalg.norm(p) <= VOLUME_RADIUS_M and all(np.linalg.norm(p - q) >= MIN_SEPARATION_M for q in spots):
            spots.append(p)
    bodies, roles = [], []
    for k, spot in enumerate(spots):
        props = BodyProportions.sample(float(rng.uniform(1.55, 1.95)), rng)
        j = _on_spot(generate_motion(str(rng.choice(IN_PLACE_MOTIONS)), props, n_frames, fps, rng), spot)
        if k > 0:
            t_in = int(rng.integers(0, max(1, int(ENTER_BY * n_frames))))
            t_out = int(rng.integers(int(LEAVE_FROM * n_frames), n_frames + 1))
            j[:t_in], j[t_out:] = np.nan, np.nan
        bodies.append(j)
        roles.append("person")
    for b in range(n_bystanders):
        props = BodyProportions.sample(float(rng.uniform(1.55, 1.95)), rng)
        base = generate_motion("idle", props, n_frames, fps, rng)
        for _ in range(500):
            a, r = rng.uniform(0, 2 * np.pi), rng.uniform(*BYSTANDER_RADIUS_M)
            j = _on_spot(base, np.array([r * np.cos(a), r * np.sin(a)]))
            seen = [all(_in_view(cam, j[t]) for t in (0, n_frames - 1)) for cam in rig]
            hidden = [not any(_in_view(cam, j[t], 0.01) for t in range(0, n_frames, max(1, n_frames // 8)))
                      for cam in rig]
            if sum(seen) == 1 and sum(hidden) == len(rig) - 1:
                break
        else:
            raise InputError("make_crowd", f"a place for bystander {b} seen by one camera only",
                             "none in 500 draws (try another seed)")
        bodies.append(j)
        roles.append("bystander")
    joints = np.stack(bodies)
    pts = joints[np.isfinite(joints).all(-1)]
    measured, _ = perturb_rig(rig, calibration_error_px, pts, rng)
    return CrowdScene(rig, measured, joints, tuple(roles), float(fps))


def detect_crowd(scene: CrowdScene, rng: np.random.Generator | int | None = None, *, bias_px: float = 3.0,
                 jitter_px: float = 1.5, miss: float = 0.05, swap: float = 0.03, occlusion: float = 0.05,
                 ) -> CrowdDetections:
    """Detections of every body each camera sees, with detector noise (module docstring).

    Parameters
    ----------
    scene : CrowdScene
    rng : numpy.random.Generator or int or None
    bias_px, jitter_px : float
        Per-joint bias (fixed per body and view) and per-frame jitter, pixels for a
        :data:`NOISE_REFERENCE_PX` tall person (scaled with the person's size in the image).
    miss : float
        Share of joints not detected.
    swap : float
        Share of detections with left and right swapped.
    occlusion : float
        Share of (person, view, frame) where a person in view is not detected.

    Returns
    -------
    CrowdDetections
    """
    rng = np.random.default_rng(rng)
    B, T, J = scene.joints.shape[:3]
    V = len(scene.rig)
    bias = rng.normal(0, bias_px, (B, V, J, 2))
    perm = SKELETON_14.flip_permutation
    dets = [[[] for _ in range(V)] for _ in range(T)]
    ids = [[[] for _ in range(V)] for _ in range(T)]
    sw = [[[] for _ in range(V)] for _ in range(T)]
    for b in range(B):
        for v, cam in enumerate(scene.rig):
            uv_all = cam.project(scene.joints[b])
            present = np.isfinite(uv_all).all(-1).any(-1)
            if not present.any():
                continue
            heights = np.nanmax(uv_all[present, :, 1], 1) - np.nanmin(uv_all[present, :, 1], 1)
            s = float(np.median(heights)) / NOISE_REFERENCE_PX
            for t in range(T):
                if not _in_view(cam, scene.joints[b, t]) or rng.random() < occlusion:
                    continue
                uv = uv_all[t] + s * bias[b, v] + rng.normal(0, jitter_px * s, (J, 2))
                c = rng.uniform(0.5, 0.95, J)
                m = (rng.random(J) < miss) | ~cam.in_image(uv_all[t])
                uv[m], c[m] = np.nan, 0.0
                k = np.concatenate([uv, c[:, None]], axis=1)
                swapped = bool(rng.random() < swap)
                dets[t][v].append(k[perm] if swapped else k)
                ids[t][v].append(b)
                sw[t][v].append(swapped)
    for t in range(T):
        for v in range(V):
            order = rng.permutation(len(dets[t][v]))
            dets[t][v] = np.array([dets[t][v][i] for i in order], float).reshape(-1, J, 3)
            ids[t][v] = np.array([ids[t][v][i] for i in order], int)
            sw[t][v] = np.array([sw[t][v][i] for i in order], bool)
    return CrowdDetections(dets, ids, sw)


@dataclass(frozen=True)
class PeopleScore:
    """Estimated people against the truth (:func:`score_people`).

    Attributes
    ----------
    mpjpe_m : ndarray of shape (n_people,)
        Per true person (``CrowdScene.people`` order), the mean joint error over the frames
        an estimate was matched to it, metres (NaN when never matched).
    switches : ndarray of shape (n_people,) of int
        Identity switches: times the estimate matched to the person changes.
    missed : ndarray of shape (n_people,) of int
        Frames where the person is seen by two cameras or more and no estimate matched.
    false_people : int
        Estimated people matched to no true person in any frame (a bystander reported,
        a ghost).
    false_frames : int
        (estimate, frame) pairs with an estimate matched to nobody.
    """

    mpjpe_m: np.ndarray
    switches: np.ndarray
    missed: np.ndarray
    false_people: int
    false_frames: int


#: An estimate matches a true person in a frame when their median joint distance is below this (metres).
MATCH_GATE_M = 0.5


def score_people(estimates: np.ndarray, scene: CrowdScene, detections: CrowdDetections | None = None,
                 gate_m: float = MATCH_GATE_M) -> PeopleScore:
    """Per person MPJPE and identity switches of estimated people.

    Parameters
    ----------
    estimates : ndarray of shape (n_estimates, T, 14, 3)
        Metres, NaN where an estimate has no person.
    scene : CrowdScene
    detections : CrowdDetections, optional
        To count missed frames only where two cameras detected the person.
    gate_m : float
        Largest median joint distance of a match, metres.

    Returns
    -------
    PeopleScore
    """
    est = np.asarray(estimates, float).reshape(-1, *scene.joints.shape[1:])
    people = scene.people
    truth = scene.joints[people]
    P, T = len(people), truth.shape[1]
    errs = [[] for _ in range(P)]
    last = [None] * P
    switches = np.zeros(P, int)
    missed = np.zeros(P, int)
    used = np.zeros(len(est), bool)
    false_frames = 0
    for t in range(T):
        here = [p for p in range(P) if np.isfinite(truth[p, t]).any()]
        cand = [e for e in range(len(est)) if np.isfinite(est[e, t]).any()]
        D = np.full((len(here), len(cand)), np.inf)
        for a, p in enumerate(here):
            for b, e in enumerate(cand):
                d = np.linalg.norm(est[e, t] - truth[p, t], axis=-1)
                if np.isfinite(d).any() and np.nanmedian(d) <= gate_m:
                    D[a, b] = np.nanmedian(d)
        matched_p, matched_e = set(), set()
        if D.size:
            rows, cols = linear_sum_assignment(np.where(np.isfinite(D), D, 1e6))
            for a, b in zip(rows, cols):
                if np.isfinite(D[a, b]):
                    p, e = here[a], cand[b]
                    errs[p].append(float(np.nanmean(np.linalg.norm(est[e, t] - truth[p, t], axis=-1))))
                    if last[p] is not None and last[p] != e:
                        switches[p] += 1
                    last[p] = e
                    used[e] = True
                    matched_p.add(p)
                    matched_e.add(e)
        for p in here:
            if p not in matched_p:
                seen = 2 if detections is None else sum(int((ids == people[p]).any())
                                                        for ids in detections.identity[t])
                missed[p] += int(seen >= 2)
        false_frames += len([e for e in cand if e not in matched_e])
    mp = np.array([np.mean(e) if e else np.nan for e in errs])
    return PeopleScore(mp, switches, missed, int((~used).sum()), false_frames)
