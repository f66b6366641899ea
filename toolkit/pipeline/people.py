"""Several people in one free-viewpoint run: each through stages 1-4, drawn in depth order.

Stage 1 from keypoints (:mod:`toolkit.pipeline.keypoints`) follows one person.
With ``people="all"`` a run follows every *participant*: the people of
:func:`toolkit.multiview.tracking.track_people` (seen by two cameras or more, in
the capture volume, tracked over time) followed in at least
:data:`PARTICIPANT_MIN_SHARE` of the frames (passers-by are left to the scene
model).  :func:`triangulate_people` triangulates each participant's own
keypoints over the sequence, as the one-person stage does.

:func:`estimate_people` then yields per frame a :class:`PeopleFrame`: each
person's stage-1 estimate and silhouettes.  The silhouettes are made
*exclusive* (:func:`exclusive_masks`): a pixel two people's silhouettes both
claim belongs to the one nearer to that camera, and a pixel of a shared
silhouette (masks given, background subtraction) to the person whose projected
bones are nearest; so a person partly hidden in a source view is not textured
with the one in front.  Each person then goes through stages 2-4 on its own
(:class:`toolkit.pipeline.frame.FrameProcessor`), and
:func:`toolkit.rendering.freeviewpoint.render_views` draws the people far to
near in every view.

Without keypoints (synthetic scenes, a studio with clean plates),
:func:`locate_silhouette_people` finds where every person stands from the
cameras' foreground alone (:mod:`toolkit.silhouettes.people`: ground-plane
occupancy chosen greedily, ghosts explained away), and
:func:`estimate_people_silhouettes` gives each person its share of the
foreground and a silhouette-database estimator of its own; once every person
has a pose, :func:`depth_ordered_shares` shares each camera's foreground again
by their posed templates, nearest surface first, for stages 2-4.  A scene in
which no probed frame holds two people runs the one-person stage unchanged.

People keep the index of their track over the whole run (``person_0`` is the
one followed longest); ``OUT/people3d.npz`` holds their joints.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Iterator

import cv2
import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.observe import as_observer

__all__ = ["PeopleFrame", "triangulate_people", "estimate_people", "exclusive_masks", "PARTICIPANT_MIN_SHARE",
           "PEOPLE_CHOICES", "locate_silhouette_people", "estimate_people_silhouettes", "people_foreground",
           "depth_ordered_shares", "SHARE_REACH_SHARE"]

#: A person followed in at least this share of the frames is a participant (drawn); the others are passers-by.
PARTICIPANT_MIN_SHARE = 0.25
#: ``people`` options of a run: every participant, or only the main person (the one-person stage).
PEOPLE_CHOICES = ("all", "main")
#: A pixel within this share of a person's image height of its bones may be that person's (half a body's width).
BODY_HALF_WIDTH_SHARE = 0.12


@dataclass
class PeopleFrame:
    """Stage 1 of one frame with several people.

    Attributes
    ----------
    frame : int
    estimates : list of FrameEstimate
        One per person (the run's people order).
    masks : list of list of (ndarray (H, W) bool or None)
        Per person, its exclusive silhouette per camera (rig order).
    names : list of str
    timings : dict of str -> float
        The frame's stage-1 seconds (all people).
    """

    frame: int
    estimates: list
    masks: list
    names: list
    timings: dict = field(default_factory=dict)

    @property
    def offsets(self):
        """The first person's stage-1 offsets (the run's record keeps them)."""
        return self.estimates[0].offsets


def triangulate_people(keypoints, camera_names, rig: Rig, n_frames: int, config, *, fps: float | None = None,
                       min_share: float = PARTICIPANT_MIN_SHARE, observer=None) -> tuple[list, list]:
    """Every participant's keypoints triangulated over the sequence.

    Parameters
    ----------
    keypoints : path-like
        The keypoints folder (every person detected, per camera and frame).
    camera_names : sequence of str
        All the dataset's cameras.
    rig : Rig
        The cameras used (a held-out camera's keypoints are never read).
    n_frames : int
    config : toolkit.pipeline.keypoints.KeypointStage1Config
    fps : float, optional
    min_share : float
        A person followed in fewer frames than this share is not a participant.
    observer : Observer, optional

    Returns
    -------
    stages : list of KeypointStage1
        One per participant, the one followed longest first; the one-person stage's
        consensus person when nobody is followed long enough.
    summary : list of dict
        Per participant: ``person`` (``person_<track>``), ``frames`` followed, ``share``.
    """
    from toolkit.multiview.tracking import DEFAULT_FPS, TrackingConfig, frame_detections, track_people
    from toolkit.pipeline.keypoints import read_dataset_keypoints, triangulate_dataset_keypoints, triangulate_keypoints

    _, _, data = read_dataset_keypoints(keypoints, camera_names, rig, config.fmt, person="most_confident", fps=fps)
    dets = frame_detections(data.cameras, data.frames, data.keypoints.shape[2])
    tracks = track_people(dets, rig, TrackingConfig(fps=fps or DEFAULT_FPS))
    seen = tracks.views > 0 if tracks.n_people else np.zeros((0, len(data.frames)), bool)
    order = sorted(range(tracks.n_people), key=lambda k: -int(seen[k].sum()))
    stages, summary = [], []
    for k in order:
        share = float(seen[k].mean()) if seen.shape[1] else 0.0
        if share < min_share:
            continue
        stages.append(triangulate_keypoints(tracks.keypoints(dets, k), data, rig, n_frames, config, str(keypoints),
                                            observer=observer if not stages else None))
        summary.append({"person": f"person_{k}", "frames": int(seen[k].sum()), "share": round(share, 3)})
    if not stages:
        stages = [triangulate_dataset_keypoints(keypoints, camera_names, rig, n_frames, config, fps=fps,
                                                observer=observer)]
        summary = [{"person": "person_0", "frames": int(np.sum(stages[0].sequence.success)),
                    "share": round(float(np.mean(stages[0].sequence.success)), 3) if len(stages[0].frames) else 0.0}]
    return stages, summary


def _depth(cam, joints: np.ndarray) -> float:
    """Distance (metres) from a camera to a person's joints (their median depth; inf without joints)."""
    J = np.asarray(joints, float)
    ok = np.isfinite(J).all(-1)
    return float(np.median(cam.depth_of(J[ok]))) if ok.any() else float("inf")


def _bone_distance(cam, joints: np.ndarray, size: tuple) -> np.ndarray:
    """Per pixel, the distance (pixels) to the person's bones projected into ``cam`` (inf without joints)."""
    from toolkit.skeleton import SKELETON_14

    w, h = size
    uv = cam.project(np.asarray(joints, float))
    canvas = np.full((h, w), 255, np.uint8)
    drawn = False
    for a, b in SKELETON_14.bones:
        if np.isfinite(uv[[a, b]]).all():
            p, q = (np.round(uv[a]).astype(int), np.round(uv[b]).astype(int))
            if max(abs(p).max(), abs(q).max()) < 10 * max(w, h):
                cv2.line(canvas, tuple(int(v) for v in p), tuple(int(v) for v in q), 0, 1)
                drawn = True
    if not drawn:
        return np.full((h, w), np.inf, np.float32)
    return cv2.distanceTransform(canvas, cv2.DIST_L2, 3)


def _height_px(cam, joints: np.ndarray) -> float:
    """A person's height in ``cam``'s image (pixels; 0 without joints)."""
    v = cam.project(np.asarray(joints, float))[:, 1]
    v = v[np.isfinite(v)]
    return float(np.ptp(v)) if v.size else 0.0


def exclusive_masks(masks: list, joints: list, rig: Rig) -> list:
    """Each pixel of the people's silhouettes given to one person.

    Parameters
    ----------
    masks : list over people of list over cameras of (ndarray (H, W) bool or None)
        Each person's silhouette per camera (rig order); the same array for several people
        when the silhouette is shared (masks given, background subtraction).
    joints : list over people of ndarray of shape (14, 3)
        Their 3D joints this frame (NaN: unknown).
    rig : Rig
        The cameras (as stage 1 corrected them or not: only the order of the people matters).

    Returns
    -------
    list over people of list over cameras of (ndarray (H, W) bool or None)
        A pixel claimed by several people goes to the nearest to the camera among those
        whose bones pass within a body's width of it, else to the one whose bones are
        nearest; pixels nobody claims stay unclaimed.
    """
    P = len(masks)
    if P <= 1:
        return masks
    out = [[None] * len(rig) for _ in range(P)]
    for v, cam in enumerate(rig):
        claimed = [masks[k][v] for k in range(P)]
        have = [k for k in range(P) if claimed[k] is not None and claimed[k].any()]
        if not have:
            continue
        size = cam.size
        dist = np.stack([_bone_distance(cam, joints[k], size) for k in range(P)])
        reach = np.array([max(8.0, BODY_HALF_WIDTH_SHARE * _height_px(cam, joints[k])) for k in range(P)])
        reach = reach[:, None, None]
        depth = np.array([_depth(cam, joints[k]) for k in range(P)])
        # the nearest person among those whose bones reach the pixel, else the one whose bones are nearest
        near = dist <= reach
        key = np.where(near, depth[:, None, None], np.inf)
        owner = np.where(near.any(0), np.argmin(key, 0), np.argmin(dist, 0))
        for k in range(P):
            if claimed[k] is None:
                continue
            out[k][v] = claimed[k] & (owner == k)
    return out


#: A foreground pixel that no person's template covers goes to the person whose template is nearest in the
#: image within this share of that person's image height (arms and legs the pose misses); beyond it, or
#: where stage 1 gave it to a person without a pose, it stays with the person stage 1 gave it to.
SHARE_REACH_SHARE = 0.25
#: The templates are drawn with the person at most this tall (pixels) in a camera, then brought back to its size.
SHARE_WORK_HEIGHT_PX = 300.0


def _template_view(template, joints: np.ndarray, mesh, cam, box: tuple) -> tuple[np.ndarray, np.ndarray, float] | None:
    """A person's template seen by ``cam`` inside ``box`` (x0, y0, x1, y1; pixels, end excluded):
    covered (h, w) bool, surface depth (h, w) float32 metres (inf where not covered) and the person's
    image height (pixels); None when the person has no usable pose or is behind the camera.

    The template is ray-cast with the person at most :data:`SHARE_WORK_HEIGHT_PX` tall and brought back
    to the camera's size (nearest neighbour)."""
    if mesh is None or np.any(cam.depth_of(joints) <= 0):
        return None
    h_px = _height_px(cam, joints)
    if h_px <= 0:
        return None
    x0, y0, x1, y1 = box
    scale = min(1.0, SHARE_WORK_HEIGHT_PX / h_px)
    labels, depth = template.render(joints, cam if scale == 1.0 else cam.scaled(scale), mesh=mesh)
    if scale != 1.0:
        w, h = cam.size
        labels = cv2.resize(labels, (w, h), interpolation=cv2.INTER_NEAREST)
        depth = cv2.resize(depth, (w, h), interpolation=cv2.INTER_NEAREST)
    covered = labels[y0:y1, x0:x1] > 0
    return covered, np.where(covered, depth[y0:y1, x0:x1], np.inf).astype(np.float32), h_px


def depth_ordered_shares(masks: list, joints: list, rigs: list, template) -> list:
    """Each person's share of the cameras' foreground from every person's posed template, nearest first.

    Per camera, the foreground is every person's stage-1 silhouette together.  A pixel that one or more
    people's templates (posed on their stage-1 joints, :meth:`toolkit.template.Template.render`) cover
    goes to the one whose template surface is nearest the camera there: a person behind another keeps
    what the one in front leaves visible, and its pixels are never the one in front's.  A pixel no
    template covers stays with the person whose silhouette held it when that person has no pose, else
    goes to the person whose template is nearest in the image within :data:`SHARE_REACH_SHARE` of its
    height, else stays where it was.

    Parameters
    ----------
    masks : list over people of list over cameras of (ndarray (H, W) bool or None)
        Each person's stage-1 silhouette per camera (rig order; None: no frame or not seen).
    joints : list over people of ndarray of shape (14, 3)
        Their 3D joints this frame, metres (NaN: unknown; such a person keeps the pixels of its
        silhouette that no other person's template covers).
    rigs : list over people of Rig
        Each person's cameras as its stage 1 corrected them (:func:`toolkit.multiview.corrected_rig`).
    template : toolkit.template.Template

    Returns
    -------
    list over people of list over cameras of (ndarray (H, W) bool or None)
        Exclusive shares: no pixel in two of them; None where the person's stage-1 silhouette was None.
    """
    P = len(masks)
    if P <= 1:
        return masks
    V = len(rigs[0])
    J = [np.asarray(j, float) for j in joints]
    meshes = [template.mesh(j) if j.shape == (14, 3) and np.isfinite(j).all() else None for j in J]
    out = [[None] * V for _ in range(P)]
    for v in range(V):
        have = [k for k in range(P) if masks[k][v] is not None]
        fg = np.logical_or.reduce([np.asarray(masks[k][v], bool) for k in have]) if have else None
        if fg is None or not fg.any():
            for k in have:
                out[k][v] = np.zeros_like(fg)
            continue
        # everything happens in the foreground's box, grown by the farthest reach
        h, w = fg.shape
        ys, xs = np.nonzero(fg)
        pad = 2 + int(np.ceil(SHARE_REACH_SHARE * max((_height_px(rigs[k][v], J[k]) for k in range(P)
                                                        if meshes[k] is not None), default=0.0)))
        x0, y0 = max(int(xs.min()) - pad, 0), max(int(ys.min()) - pad, 0)
        x1, y1 = min(int(xs.max()) + 1 + pad, w), min(int(ys.max()) + 1 + pad, h)
        crop = fg[y0:y1, x0:x1]
        stage1 = np.full(crop.shape, -1, np.int32)  # the person stage 1 gave the pixel to (the first, if several)
        for k in reversed(have):
            stage1[np.asarray(masks[k][v], bool)[y0:y1, x0:x1]] = k
        depth = np.full((P,) + crop.shape, np.inf, np.float32)
        dist = np.full((P,) + crop.shape, np.inf, np.float32)
        for k in range(P):
            seen = _template_view(template, J[k], meshes[k], rigs[k][v], (x0, y0, x1, y1))
            if seen is None or not seen[0].any():
                continue
            covered, depth[k], h_px = seen
            d = cv2.distanceTransform((~covered).astype(np.uint8), cv2.DIST_L2, 3)
            dist[k] = np.where(d <= SHARE_REACH_SHARE * h_px, d, np.inf)
        # covered: the nearest surface; else the nearest template within reach, unless stage 1 gave the
        # pixel to a person without a pose (nobody else's template explains it)
        posed = np.array([m is not None for m in meshes] + [True])  # [-1]: nobody's pixel
        keep = ~posed[stage1] | ~np.isfinite(dist.min(0))
        owner = np.where(np.isfinite(depth.min(0)), np.argmin(depth, 0), np.where(keep, stage1, np.argmin(dist, 0)))
        owner[~crop] = -1
        for k in have:
            share = np.zeros((h, w), bool)
            share[y0:y1, x0:x1] = owner == k
            out[k][v] = share
    return out


def estimate_people(dataset, keypoints, rig: Rig, config, *, frames=None, silhouettes: str = "auto",
                    masks_dir=None, foreground=None, observer=None, min_share: float = PARTICIPANT_MIN_SHARE,
                    log=None) -> Iterator[PeopleFrame]:
    """Stage 1 of every participant, frame by frame (see the module docstring).

    Parameters are those of :func:`toolkit.pipeline.keypoints.estimate_from_keypoints`, and
    ``min_share`` (:func:`triangulate_people`) and ``log`` (told how many people are followed).

    Yields
    ------
    PeopleFrame
    """
    from toolkit.pipeline.keypoints import SeededSilhouettes, choose_silhouettes, estimate_from_keypoints

    obs = as_observer(observer)
    t0 = time.perf_counter()
    stages, summary = triangulate_people(keypoints, dataset.camera_names, rig, dataset.n_frames, config,
                                         fps=getattr(dataset, "fps", None), min_share=min_share, observer=observer)
    names = [s["person"] for s in summary]
    t_kp = (time.perf_counter() - t0) / max(len(stages[0].frames), 1)
    if log is not None:
        log(f"people: {len(stages)} followed (" + ", ".join(f"{s['person']} in {s['frames']} frames"
                                                         for s in summary) + ")")
    obs.report("text", name="stage1/people", text=str(summary))
    if len(stages) == 1:
        for est, masks in estimate_from_keypoints(dataset, keypoints, rig, config, frames=frames,
                                                  silhouettes=silhouettes, masks_dir=masks_dir,
                                                  foreground=foreground, observer=observer, stage1=stages[0]):
            yield PeopleFrame(est.frame, [est], [masks], names, dict(est.timings))
        return
    plates = {c: p for c in rig.names if (p := dataset.background(c)) is not None}
    source = choose_silhouettes(silhouettes, masks_dir, len(plates) == len(rig.names))
    if source != "seeded":
        # a shared silhouette (masks given, background subtraction) split between the people
        gens = estimate_from_keypoints(dataset, keypoints, rig, config, frames=frames, silhouettes=silhouettes,
                                       masks_dir=masks_dir, foreground=foreground, observer=observer,
                                       stage1=stages[0])
        for est, masks in gens:
            t1 = time.perf_counter()
            ests = [est] + [s.estimate(est.frame) for s in stages[1:]]
            shared = [masks] * len(stages)
            excl = exclusive_masks(shared, [e.joints3d for e in ests], rig)
            timings = dict(est.timings)
            timings["stage1"] = timings.get("stage1", 0.0) + time.perf_counter() - t1 + t_kp * (len(stages) - 1)
            yield PeopleFrame(est.frame, ests, excl, names, timings)
        return
    todo = list(range(dataset.n_frames)) if frames is None else [int(t) for t in frames]
    seeded = [SeededSilhouettes(rig, observer=observer if k == 0 else None) for k in range(len(stages))]
    for t in todo:
        t1 = time.perf_counter()
        ests = [s.estimate(t) for s in stages]
        images = {}
        for c in rig.names:
            try:
                images[c] = dataset.frame(c, t)
            except (InputError, IndexError):
                images[c] = None
            if images[c] is not None:
                obs.report("image", camera=c, image=images[c], frame=t)
        masks = []
        for k, e in enumerate(ests):
            others = {}
            for v, cam in enumerate(rig):
                others[cam.name] = [cam.project(np.asarray(o.joints3d, float)) for j, o in enumerate(ests)
                                    if j != k and np.isfinite(np.asarray(o.joints3d, float)).all(-1).sum() >= 6]
            masks.append(seeded[k].segment_frame(t, images, e, others=others))
        excl = exclusive_masks(masks, [e.joints3d for e in ests], rig)
        for k, person in enumerate(excl):
            for c, m in zip(rig.names, person):
                if m is not None:
                    obs.report("mask", camera=c, mask=m, name=f"stage1/silhouette/{names[k]}", frame=t)
        dt = time.perf_counter() - t1
        timings = {"foreground": dt, "keypoints": t_kp * len(stages), "stage1": dt + t_kp * len(stages)}
        for e in ests:
            e.timings.update(timings)
        yield PeopleFrame(t, ests, excl, names, timings)


def combined_labels(results: list, rig: Rig) -> dict:
    """Every person's part labels in one image per camera, the nearest person's where they overlap.

    Parameters
    ----------
    results : list of FrameResult
        One per person (their ``labels`` per camera name).
    rig : Rig

    Returns
    -------
    dict of str -> ndarray (H, W) uint8
    """
    out = {}
    for cam in rig:
        order = sorted(range(len(results)), key=lambda k: -_depth(cam, results[k].joints))
        lab = None
        for k in order:
            mine = results[k].labels.get(cam.name)
            if mine is None:
                continue
            lab = mine.copy() if lab is None else np.where(mine > 0, mine, lab)
        if lab is not None:
            out[cam.name] = lab
    return out


def people_foreground(dataset, rig: Rig, foreground=None) -> dict:
    """Per camera of ``rig`` a fitted foreground extractor that keeps every blob: on the dataset's clean
    plate where it has one (as the one-person stage does), else on the camera's video."""
    from dataclasses import replace

    from toolkit.foreground import ForegroundConfig, ForegroundExtractor
    from toolkit.io import VideoReader

    foreground = foreground or ForegroundConfig()
    # every person's blob: none of the one-person clean-up that keeps the largest component
    foreground = replace(foreground, morphology=replace(foreground.morphology, keep_components=0,
                                                        min_component_fraction=0.0))
    out = {}
    for c in rig.names:
        plate = getattr(dataset, "background", lambda _c: None)(c)
        if plate is not None:
            out[c] = ForegroundExtractor(foreground).fit([plate])
            continue
        reader = VideoReader(dataset.video_path(c))
        try:
            out[c] = ForegroundExtractor(foreground).fit(reader)
        finally:
            reader.close()
    return out


def _frame_masks(dataset, rig: Rig, extractors: dict, t: int) -> tuple[dict, list]:
    """Frame ``t``'s images (camera -> image or None) and foreground masks (rig order, None: no frame)."""
    images, masks = {}, []
    for c in rig.names:
        try:
            images[c] = dataset.frame(c, t)
        except (InputError, IndexError):
            images[c] = None
        masks.append(None if images[c] is None else extractors[c].extract(images[c]).mask)
    return images, masks


def _raw_masks(dataset, rig: Rig, extractors: dict, t: int) -> list:
    """Frame ``t``'s foreground per camera before the clean-up, opened by 3 px (quick; None: no frame)."""
    out = []
    for c in rig.names:
        try:
            img = dataset.frame(c, t)
        except (InputError, IndexError):
            out.append(None)
            continue
        raw = extractors[c].raw_mask(img).astype(np.uint8)
        out.append(cv2.morphologyEx(raw, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)) > 0)
    return out


def _several_blobs(masks: list, share: float = 0.3, min_px: int = 50) -> bool:
    """Whether a camera shows two foreground blobs or more, each at least ``share`` of the camera's
    largest and ``min_px`` pixels.  One camera is enough: with two or three cameras the people who
    stand apart in one of them often overlap in the others (the search that follows still needs
    two people on the ground before the scene is taken for several people's)."""
    for m in masks:
        if m is None:
            continue
        k, _, stats, _ = cv2.connectedComponentsWithStats(np.asarray(m, np.uint8), connectivity=8)
        areas = stats[1:, cv2.CC_STAT_AREA]
        if len(areas) and np.sum(areas >= max(share * areas.max(), min_px)) >= 2:
            return True
    return False


def locate_silhouette_people(dataset, rig: Rig, *, foreground=None, config=None, probe_frames: int = 8,
                             log=None, extractors: dict | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """Where every participant stands in every frame, from the cameras' foreground alone.

    First ``probe_frames`` frames spread over the sequence are looked at: if in none of them a
    camera shows two large foreground blobs, or none holds two people on the ground, the scene is one
    person's (None: the one-person stage runs unchanged).  Otherwise every
    frame is searched and the positions are tracked
    (:func:`toolkit.silhouettes.people.track_positions`).

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    rig : Rig
    foreground : toolkit.foreground.ForegroundConfig, optional
    config : toolkit.silhouettes.people.PeopleSilhouettesConfig, optional
    probe_frames : int
    log : callable, optional
    extractors : dict, optional
        :func:`people_foreground`'s extractors (made here when not given; a run makes them once for
        this search and :func:`estimate_people_silhouettes`).

    Returns
    -------
    (positions (P, T, 2) metres, found (P, T) bool) or None
    """
    from toolkit.silhouettes.people import (
        PeopleSilhouettesConfig,
        ground_grid,
        locate_people,
        refine_positions,
        track_positions,
    )

    config = config or PeopleSilhouettesConfig()
    T = dataset.n_frames
    extractors = extractors or people_foreground(dataset, rig, foreground)
    grid = ground_grid(rig, config)
    found: dict[int, np.ndarray] = {}

    def locate(t):
        masks = _frame_masks(dataset, rig, extractors, t)[1]
        return refine_positions(masks, rig, locate_people(masks, grid, config)[0], config)

    probe = sorted({int(round(x)) for x in np.linspace(0, T - 1, min(probe_frames, T))})
    if not any(_several_blobs(_raw_masks(dataset, rig, extractors, t)) for t in probe):
        return None  # one blob per camera everywhere: one person (the cheap test spares the search)
    for t in probe:
        found[t] = locate(t)
    if max(len(p) for p in found.values()) < 2:
        return None
    for t in range(T):
        if t not in found:
            found[t] = locate(t)
    positions, seen = track_positions([found[t] for t in range(T)], config)
    if len(positions) < 2:
        return None
    if log is not None:
        log(f"people from silhouettes: {len(positions)} followed ("
            + ", ".join(f"person_{k} in {int(s.sum())} frames" for k, s in enumerate(seen)) + ")")
    return positions, seen


def _mirrored(est):
    """A stage-1 estimate with left and right swapped in 3D and in every view (its mirror image: the same
    rays), its selection dropped."""
    from dataclasses import replace

    from toolkit.multiview.selection import flip_permutation
    from toolkit.skeleton import SKELETON_14

    perm = flip_permutation(SKELETON_14, "all")
    return replace(est, joints3d=np.asarray(est.joints3d)[perm], poses2d=np.asarray(est.poses2d)[:, perm],
                   candidates_px=np.asarray(est.candidates_px)[..., perm, :], selection=None)


def estimate_people_silhouettes(dataset, database, rig: Rig, located, s1config=None, *, frames=None,
                                foreground=None, config=None, observer=None, extractors: dict | None = None,
                                template_height_m: float = 1.75) -> Iterator[PeopleFrame]:
    """Stage 1 of every participant from silhouettes, frame by frame.

    The cameras' foreground is split between the people by where they stand
    (:func:`toolkit.silhouettes.people.split_masks`) and each person has a silhouette-database
    estimator of its own (:class:`toolkit.silhouettes.pipeline.SilhouettePoseEstimator`); a person
    moving whose hips face backwards takes its mirror image
    (:func:`toolkit.silhouettes.people.faces_backwards`).  The silhouettes handed on to stages 2-4
    are then shared again by every person's posed template, nearest first
    (:func:`depth_ordered_shares`): a person partly hidden in a camera keeps only what the people in
    front leave visible, and is never labelled or textured with their pixels.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    database : SilhouetteDatabase
    rig : Rig
    located : tuple
        :func:`locate_silhouette_people`'s positions and found flags.
    s1config : Stage1Config, optional
    frames : sequence of int, optional
        Increasing frame indices (default: all).
    foreground : toolkit.foreground.ForegroundConfig, optional
    config : toolkit.silhouettes.people.PeopleSilhouettesConfig, optional
    observer : Observer, optional
    extractors : dict, optional
        :func:`people_foreground`'s extractors (those of :func:`locate_silhouette_people`).
    template_height_m : float
        Stature of the template whose posed copies share the foreground (metres; the segmentation's).

    Yields
    ------
    PeopleFrame
        ``masks``: each person's share per camera (:func:`depth_ordered_shares`).
    """
    from toolkit.multiview import corrected_rig
    from toolkit.silhouettes.pipeline import SilhouettePoseEstimator
    from toolkit.silhouettes.people import PeopleSilhouettesConfig, faces_backwards, ground_velocities, split_masks
    from toolkit.skeleton import SKELETON_14
    from toolkit.template import Template

    config = config or PeopleSilhouettesConfig()
    obs = as_observer(observer)
    positions, _ = located
    velocity = ground_velocities(positions, getattr(dataset, "fps", None) or 25.0)
    hips = (SKELETON_14.joint_names.index("l_hip"), SKELETON_14.joint_names.index("r_hip"))
    names = [f"person_{k}" for k in range(len(positions))]
    t0 = time.perf_counter()
    extractors = extractors or people_foreground(dataset, rig, foreground)
    todo = list(range(dataset.n_frames)) if frames is None else [int(t) for t in frames]
    setup = (time.perf_counter() - t0) / max(len(todo), 1)
    estimators = [SilhouettePoseEstimator(rig, database, s1config, observer if k == 0 else None)
                  for k in range(len(positions))]
    template = Template(template_height_m)
    for t in todo:
        t1 = time.perf_counter()
        images, masks = _frame_masks(dataset, rig, extractors, t)
        for c, img in images.items():
            if img is not None:
                obs.report("image", camera=c, image=img, frame=t)
        t_fg = time.perf_counter() - t1
        person_masks, usable = split_masks(masks, rig, positions[:, t], config)
        ests = [est.step([m if ok else None for m, ok in zip(own, oks)], t)
                for est, own, oks in zip(estimators, person_masks, usable)]
        ests = [_mirrored(e) if faces_backwards(e.joints3d, velocity[k, t], *hips) else e for k, e in enumerate(ests)]
        # stages 2-4 take each person's share by depth among everyone's posed templates
        person_masks = depth_ordered_shares(
            person_masks, [e.joints3d if e.ok else np.full((14, 3), np.nan) for e in ests],
            [corrected_rig(rig, e.offsets) for e in ests], template)
        for k, person in enumerate(person_masks):
            for c, m in zip(rig.names, person):
                if m is not None:
                    obs.report("mask", camera=c, mask=m, name=f"stage1/silhouette/{names[k]}", frame=t)
        timings = {"foreground": t_fg, "stage1": time.perf_counter() - t1 + setup}
        for e in ests:
            e.timings.update(timings)
        yield PeopleFrame(t, ests, person_masks, names, timings)
