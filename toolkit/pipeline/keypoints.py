"""Stage 1 from a detector's 2D keypoints instead of the silhouette database (source 000 claim 8).

A dataset may carry 2D keypoints of any detector under ``keypoints/<camera>/``
(``docs/dataset_layout.md``; ``recipes/import_pose2sim.py`` puts a Pose2Sim
trial's there).  :func:`estimate_from_keypoints` triangulates them with the
keypoint rules of :mod:`toolkit.multiview.keypoint_sequence` (labels trusted
unless a per-view flip is decisive; one offset per camera kept only when it
generalises across joints) and yields, frame by frame, what the silhouette
stage yields (:func:`toolkit.silhouettes.pipeline.estimate_dataset`): a
:class:`~toolkit.silhouettes.estimate.FrameEstimate` and the silhouettes, so
stages 2-4 (:class:`toolkit.pipeline.frame.FrameProcessor`) run
unchanged.

Silhouettes come from, in this order (``silhouettes="auto"``): masks given
(``masks_dir``: ``<dir>/<camera>/NNNNNN.png``, non-zero = subject), the
dataset's clean plates (background subtraction), or a segmentation seeded by the
keypoints (:mod:`toolkit.foreground.seeded`: footage without a plate and a
subject that barely moves, e.g. a treadmill).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.observe import Observer, as_observer

__all__ = ["KeypointStage1Config", "KeypointStage1", "read_dataset_keypoints", "triangulate_dataset_keypoints",
           "triangulate_keypoints", "SeededSilhouettes",
           "estimate_from_keypoints", "SILHOUETTE_SOURCES", "read_mask", "choose_silhouettes", "declared_format"]

#: A joint missing in a frame is taken from frames at most this far away (:meth:`KeypointStage1.filled_joints`).
MAX_FILL_FRAMES = 12
#: Where silhouettes come from: ``auto`` picks the first available of ``masks``, ``background`` (clean plates),
#: ``seeded`` (keypoint-seeded segmentation).
SILHOUETTE_SOURCES = ("auto", "masks", "background", "seeded")


@dataclass(frozen=True)
class KeypointStage1Config:
    """Options of the keypoint stage 1.

    Parameters
    ----------
    keypoint : toolkit.multiview.keypoint_sequence.KeypointConfig
        Labels (flips) and offsets rules, the triangulation's options.
    fmt : str, optional
        Keypoint format (``toolkit.io.keypoint_formats``); default: found from the files.
    min_confidence : float
        Keypoints below this detector confidence are missing.
    min_view_confidence : float
        A view whose kept keypoints' mean confidence is below this is left out of a frame.
    person : str
        How one person is picked per frame (``toolkit.pipeline.keypoint_session.open_keypoint_session``).
    """

    keypoint: object = field(default_factory=lambda: _default_keypoint_config())
    fmt: str | None = None
    min_confidence: float = 0.3
    min_view_confidence: float = 0.3
    person: str = "consensus"


def _default_keypoint_config():
    from toolkit.multiview.keypoint_sequence import KeypointConfig

    return KeypointConfig()


@dataclass(frozen=True, eq=False)
class KeypointStage1:
    """The keypoints of a dataset's cameras, triangulated.

    Attributes
    ----------
    rig : Rig
        The cameras triangulated, in the order of the arrays.
    sources : tuple of Path
        Per camera its keypoint folder or file.
    matching : str
        How sources were matched to cameras.
    format : str
        The keypoint format and why.
    frames : ndarray of shape (T,) int
        Dataset frame index of each row.
    sequence : toolkit.multiview.keypoint_sequence.KeypointSequence
    """

    rig: Rig
    sources: tuple
    matching: str
    format: str
    frames: np.ndarray
    sequence: object

    def row(self, frame: int) -> int | None:
        """Row of dataset frame ``frame`` (None when the keypoints have none)."""
        hit = np.flatnonzero(self.frames == int(frame))
        return int(hit[0]) if hit.size else None

    def filled_joints(self, r: int) -> np.ndarray:
        """Row ``r``'s 3D joints (14, 3), a joint no view pair saw taken from the frames around it.

        A joint missing in a frame the sequence triangulated (an arm hidden from all but one
        camera) is interpolated between the nearest frames that have it, or held from the
        nearest one, when they lie within :data:`MAX_FILL_FRAMES`; otherwise it stays NaN (and
        the frame has no 3D pose for the later stages).
        """
        seq = self.sequence
        J = np.asarray(seq.joints3d, float)
        out = J[r].copy()
        if not bool(seq.success[r]):
            return out
        rows = np.arange(len(J))
        for j in np.flatnonzero(~np.isfinite(out).all(-1)):
            known = rows[np.isfinite(J[:, j]).all(-1) & np.asarray(seq.success, bool)]
            before, after = known[known < r], known[known > r]
            p = before[-1] if before.size and r - before[-1] <= MAX_FILL_FRAMES else None
            n = after[0] if after.size and after[0] - r <= MAX_FILL_FRAMES else None
            if p is not None and n is not None:
                w = (r - p) / (n - p)
                out[j] = (1 - w) * J[p, j] + w * J[n, j]
            elif p is not None or n is not None:
                out[j] = J[p if p is not None else n, j]
        return out

    def estimate(self, frame: int):
        """The stage-1 estimate of one dataset frame.

        Returns
        -------
        toolkit.silhouettes.estimate.FrameEstimate
            ``poses2d`` are the keypoints used (flips applied) in image pixels,
            ``offsets`` the pixels added to them to meet the calibration
            (the silhouette stage's convention); state "too few views" where
            the frame has no triangulation.
        """
        from toolkit.silhouettes.estimate import FRAME_OK, FRAME_TOO_FEW_VIEWS, FrameEstimate

        V = len(self.rig)
        r = self.row(frame)
        seq = self.sequence
        ok = r is not None and bool(seq.success[r])
        nan2 = np.full((V, 14, 2), np.nan)
        return FrameEstimate(
            frame=int(frame), state=FRAME_OK if ok else FRAME_TOO_FEW_VIEWS,
            view_states=np.zeros(V, np.uint8), bboxes=np.full((V, 4), np.nan), candidates=(None,) * V,
            candidates_px=np.full((V, 1, 14, 2), np.nan),
            poses2d=seq.poses2d_raw[:, r].copy() if r is not None else nan2,
            offsets=seq.offsets[r].copy() if r is not None else np.full((V, 2), np.nan),
            joints3d=self.filled_joints(r) if r is not None else np.full((14, 3), np.nan),
            cost=float(seq.cost[r]) if r is not None else float("nan"), edited=np.zeros(V, bool))


def read_dataset_keypoints(keypoints: str | os.PathLike, camera_names: Sequence[str], rig: Rig,
                           fmt: str | None = None, person: str = "consensus", fps: float | None = None):
    """Read the keypoints of ``rig``'s cameras from a keypoints folder of a dataset.

    Parameters
    ----------
    keypoints : path-like
        One sub-folder (a JSON file per frame) or one JSON file per camera.
    camera_names : sequence of str
        All the dataset's cameras: the sources are matched to them (by name, number or order,
        :func:`toolkit.io.keypoint_files.match_cameras`), then ``rig``'s are kept, so a
        held-out camera's keypoints are never read.
    rig : Rig
        The cameras to read (a subset of ``camera_names``).
    fmt : str, optional
    person : str
        ``"consensus"`` (the person the cameras agree on) or a per-view policy.
    fps : float, optional
        For the person tracking's motion model.

    Returns
    -------
    sources : tuple of Path
    matching : str
    data : toolkit.io.keypoint_formats.KeypointInput
        Keypoints of ``rig``'s cameras, rig order.

    Raises
    ------
    InputError
        No such folder, sources that do not match the cameras, unreadable files.
    """
    from toolkit.io.keypoint_files import camera_sources, match_cameras
    from toolkit.io.keypoint_formats import read_keypoints

    root = Path(keypoints)
    srcs = camera_sources(root)
    order, matching = match_cameras(list(camera_names), srcs, f"{root}: keypoint sources")
    by_name = dict(zip(camera_names, (srcs[i] for i in order)))
    missing = [c for c in rig.names if c not in by_name]
    if missing:
        raise InputError("rig", f"cameras of {list(camera_names)}", f"{missing}")
    sources = tuple(by_name[c] for c in rig.names)
    data = read_keypoints(list(sources), fmt, "format",
                          person="most_confident" if person == "consensus" else person)
    if data.keypoints.ndim < 3 or data.keypoints.shape[2] == 0:
        raise InputError(f"{root}", "keypoints of at least one person in some frame of the cameras used",
                         "nobody in any file (the detector found no one: people too small, or not in view)")
    if person == "consensus":
        from toolkit.multiview.tracking import DEFAULT_FPS, TrackingConfig, frame_detections, main_person

        dets = frame_detections(data.cameras, data.frames, data.keypoints.shape[2])
        data = replace(data, keypoints=main_person(dets, rig, TrackingConfig(fps=fps or DEFAULT_FPS)))
    return sources, matching, data


def triangulate_dataset_keypoints(keypoints: str | os.PathLike, camera_names: Sequence[str], rig: Rig,
                                  n_frames: int, config: KeypointStage1Config = KeypointStage1Config(), *,
                                  fps: float | None = None, observer: Observer | None = None) -> KeypointStage1:
    """Triangulate a dataset's keypoints over the whole sequence (flips and offsets are sequence decisions).

    Parameters
    ----------
    keypoints : path-like
    camera_names : sequence of str
        All the dataset's cameras (see :func:`read_dataset_keypoints`).
    rig : Rig
        The cameras used.
    n_frames : int
        The dataset's frame count; keypoint frame numbers are dataset frame indices, and
        numbers outside ``[0, n_frames)`` are refused.
    config : KeypointStage1Config
    fps : float, optional
    observer : Observer, optional

    Returns
    -------
    KeypointStage1
    """
    sources, matching, data = read_dataset_keypoints(keypoints, camera_names, rig, config.fmt, config.person, fps)
    return triangulate_keypoints(data.keypoints, data, rig, n_frames, config, str(keypoints), sources=sources,
                                 matching=matching, observer=observer)


def triangulate_keypoints(kp: np.ndarray, data, rig: Rig, n_frames: int, config: KeypointStage1Config,
                          where: str, *, sources: tuple = (), matching: str = "",
                          observer: Observer | None = None) -> KeypointStage1:
    """Triangulate one person's keypoints over the sequence.

    Parameters
    ----------
    kp : ndarray of shape (n_views, T, K, 3)
        The person's ``(x, y, confidence)`` per view and frame, in ``data``'s format.
    data : toolkit.io.keypoint_formats.KeypointInput
        Where they were read from (frame numbers, format).
    rig : Rig
    n_frames : int
        The dataset's frame count (keypoint frame numbers outside it are refused).
    config : KeypointStage1Config
    where : str
        For messages: the keypoints' folder.
    sources, matching : optional
        Kept in the result.
    observer : Observer, optional

    Returns
    -------
    KeypointStage1
    """
    from toolkit.multiview import keypoints_to_candidates
    from toolkit.multiview.keypoint_sequence import triangulate_keypoint_sequence
    from toolkit.skeleton.mappings import to_skeleton14

    frames = np.asarray(data.frames, int)
    bad = frames[(frames < 0) | (frames >= n_frames)]
    if bad.size:
        raise InputError(where, f"keypoint frame numbers in [0, {n_frames}) (the dataset's video frames)",
                         f"{bad[:5].tolist()}" + (" ..." if bad.size > 5 else ""))
    kp14 = to_skeleton14(kp, data.format.fmt, confidence=True, min_confidence=config.min_confidence)
    cand = [keypoints_to_candidates(kp14[:, t], config.min_confidence, config.min_view_confidence)
            for t in range(kp14.shape[1])]
    V = len(rig)
    pts = np.stack([c[0][:, 0] for c in cand], axis=1) if cand else np.full((V, 0, 14, 2), np.nan)
    wts = np.stack([c[1][:, 0] for c in cand], axis=1) if cand else np.zeros((V, 0, 14))
    seq = triangulate_keypoint_sequence(pts, rig, config.keypoint, weights=wts, observer=observer, frames=frames)
    return KeypointStage1(rig, tuple(sources), matching, f"{data.format.fmt} ({data.format.reason})", frames, seq)


def declared_format(root: str | os.PathLike) -> str | None:
    """The keypoint format a dataset declares: ``pose_model`` of its ``import.json``
    (written by ``recipes/import_pose2sim.py``), or None (found from the files)."""
    import json

    p = Path(root) / "import.json"
    if not p.is_file():
        return None
    try:
        fmt = json.loads(p.read_text()).get("pose_model")
    except (ValueError, OSError) as e:
        raise InputError(str(p), "a JSON object (written by recipes/import_pose2sim.py)", f"unreadable: {e}")
    return fmt if isinstance(fmt, str) and fmt else None


def read_mask(folder: str | os.PathLike, camera: str, frame: int, size: tuple[int, int]) -> np.ndarray | None:
    """A given silhouette: ``folder/<camera>/NNNNNN.png`` (non-zero = subject), or None when absent.

    Raises
    ------
    InputError
        A mask of another size than the camera's ``(width, height)``.
    """
    from toolkit.io.frames import frame_filename, read_png

    p = Path(folder) / camera / frame_filename(frame)
    if not p.exists():
        return None
    m = read_png(p)
    m = m[..., 0] if m.ndim == 3 else m
    if m.shape != (size[1], size[0]):
        raise InputError(str(p), f"a {size[0]}x{size[1]} mask (the camera's size)", f"{m.shape[1]}x{m.shape[0]}")
    return m > 0


def choose_silhouettes(source: str, masks_dir, has_plates: bool) -> str:
    """Resolve ``silhouettes="auto"``: masks given, else clean plates, else keypoint-seeded.

    Raises
    ------
    InputError
        An unknown source, ``"masks"`` without a folder.
    """
    if source not in SILHOUETTE_SOURCES:
        raise InputError("silhouettes", f"one of {SILHOUETTE_SOURCES}", repr(source))
    if source == "masks" and masks_dir is None:
        raise InputError("--silhouettes masks", "a masks folder (--masks DIR, or the dataset's masks/)", "none")
    if source != "auto":
        return source
    if masks_dir is not None:
        return "masks"
    if has_plates:
        return "background"
    return "seeded"


class SeededSilhouettes:
    """Per frame, every camera's subject mask seeded by the stage-1 pose (:mod:`toolkit.foreground.seeded`).

    Each camera is segmented by GrabCut seeded with the 3D joints projected into it through its
    camera corrected by the view's stage-1 offset (so they sit where the keypoints are); then each mask is carved by the
    visual hull of the other views' masks around the 3D pose
    (:meth:`toolkit.foreground.seeded.SeededSegmenter.segment_views`), which drops bystanders
    and floor patches.

    Parameters
    ----------
    rig : Rig
    config : toolkit.foreground.seeded.SeededConfig, optional
    observer : Observer, optional
    """

    def __init__(self, rig: Rig, config=None, observer: Observer | None = None):
        from toolkit.foreground.seeded import SeededSegmenter

        self.rig = rig
        self.segmenter = SeededSegmenter(config, observer=observer)
        self.observer = observer
        self.previous: dict = {}

    def segment_frame(self, frame: int, images: dict, estimate, others: dict | None = None) -> list:
        """Masks of one frame, rig order (None where a camera has no image or no pose).

        Parameters
        ----------
        frame : int
        images : dict of str -> ndarray (H, W, 3) uint8 or None
        estimate : toolkit.silhouettes.estimate.FrameEstimate
        others : dict of str -> list of ndarray (14, 2), optional
            Other people's joints per camera (pixels): kept out of this person's mask.
        """
        from toolkit.multiview import corrected_rig

        J = np.asarray(estimate.joints3d, float)
        corrected = corrected_rig(self.rig, estimate.offsets)
        use3d = np.isfinite(J).all(-1).sum() >= 6
        imgs, joints2d, weights = {}, {}, {}
        for v, cam in enumerate(self.rig):
            if images.get(cam.name) is None:
                continue
            # the 3D joints projected through the corrected camera sit where its keypoints are;
            # without a 3D pose, the view's own keypoints.  (The carving below still uses the
            # uncorrected cameras, as before the offset convention changed.)
            j2 = corrected[v].project(J) if use3d else np.asarray(estimate.poses2d[v], float)
            imgs[cam.name], joints2d[cam.name] = images[cam.name], j2
            weights[cam.name] = np.isfinite(j2).all(-1).astype(float)
        masks, self.previous = self.segmenter.segment_views(
            imgs, joints2d, weights, rig=Rig(tuple(c for c in self.rig if c.name in imgs)),
            joints3d=J if use3d else None, previous=self.previous, frame=frame, others=others)
        return [masks.get(c) if c in masks and masks[c].any() else None for c in self.rig.names]


def _silhouette_models(source: str, names: Sequence[str], plates: dict, readers: dict, foreground, rig: Rig,
                       observer: Observer | None):
    """Build the silhouette models a source needs: background extractors or the seeded segmenter.

    Parameters
    ----------
    source : str
        One of :data:`SILHOUETTE_SOURCES` but ``auto``.
    names : sequence of str
        The cameras, rig order.
    plates : dict of str to ndarray (H, W, 3)
        Clean plates of the cameras that have one.
    readers : dict of str to VideoReader
        Video readers of (at least) the cameras without a plate, when ``source == "background"``.
    foreground : toolkit.foreground.ForegroundConfig or None
        Background subtraction's options.
    rig : Rig
    observer : Observer or None

    Returns
    -------
    extractors : dict of str to ForegroundExtractor or None
        Per camera, fitted to its plate or its video (``source == "background"``).
    seeded : SeededSilhouettes or None
        The keypoint-seeded segmenter (``source == "seeded"``).
    """
    extractors = seeded = None
    if source == "background":
        from toolkit.foreground import ForegroundExtractor

        extractors = {c: ForegroundExtractor(foreground).fit([plates[c]] if c in plates else readers[c])
                      for c in names}
    elif source == "seeded":
        seeded = SeededSilhouettes(rig, observer=observer)
    return extractors, seeded


def _frame_images(t: int, names: Sequence[str], shared, readers: dict, obs, log_images: bool) -> dict:
    """Each camera's image of frame ``t``, None where it cannot be read.

    Parameters
    ----------
    t : int
        The frame.
    names : sequence of str
        The cameras, rig order.
    shared : callable or None
        ``dataset.frame(camera, t)``; None to read through ``readers``.
    readers : dict of str to VideoReader
        Per camera, its video reader (used when ``shared`` is None).
    obs : Observer
        Told each image read when ``log_images``.
    log_images : bool

    Returns
    -------
    dict of str to (ndarray (H, W, 3) or None)
    """
    images = {}
    for c in names:
        try:
            images[c] = shared(c, t) if shared is not None else readers[c].read(t)
        except (InputError, IndexError):
            images[c] = None
        if log_images and images[c] is not None:
            obs.report("image", camera=c, image=images[c], frame=t)
    return images


def _frame_masks(t: int, source: str, names: Sequence[str], images: dict, est, rig: Rig, masks_dir,
                 extractors: dict | None, seeded, previous: dict, obs, log_images: bool) -> list:
    """Each camera's silhouette of frame ``t`` from the chosen source.

    Parameters
    ----------
    t : int
        The frame.
    source : str
        ``masks``, ``background`` or ``seeded``.
    names : sequence of str
        The cameras, rig order.
    images : dict of str to (ndarray (H, W, 3) or None)
        This frame's images.
    est : toolkit.silhouettes.estimate.FrameEstimate
        This frame's keypoint estimate (seeds the ``seeded`` source).
    rig : Rig
    masks_dir : path-like or None
        Masks given (``source == "masks"``).
    extractors : dict of str to ForegroundExtractor or None
        Background extractors (``source == "background"``).
    seeded : SeededSilhouettes or None
        The seeded segmenter (``source == "seeded"``).
    previous : dict of str to ((image, mask) or None)
        Per camera, the previous frame's usable image and mask (``source == "background"``);
        updated in place for the next frame.
    obs : Observer
        Told each seeded mask when ``log_images``.
    log_images : bool

    Returns
    -------
    list of (ndarray (H, W) bool or None)
        Rig order.
    """
    masks: list = []
    if source == "masks":
        masks = [read_mask(masks_dir, c, t, rig[c].size) if images[c] is not None else None for c in names]
    elif source == "background":
        for c in names:
            if images[c] is None:
                masks.append(None)
                previous[c] = None
                continue
            sil = extractors[c].extract(images[c], previous[c])
            previous[c] = (images[c], sil.mask) if sil.usable else None
            masks.append(sil.mask)
    else:
        masks = seeded.segment_frame(t, images, est)
        if log_images:
            for c, m in zip(names, masks):
                if m is not None:
                    obs.report("mask", camera=c, mask=m, name="stage1/silhouette", frame=t)
    return masks


def estimate_from_keypoints(dataset, keypoints: str | os.PathLike, rig: Rig | None = None,
                            config: KeypointStage1Config = KeypointStage1Config(), *,
                            frames: Sequence[int] | None = None, silhouettes: str = "auto",
                            masks_dir: str | os.PathLike | None = None, foreground=None,
                            observer: Observer | None = None, log_images: bool = True,
                            stage1: KeypointStage1 | None = None) -> Iterator[tuple]:
    """Stage 1 from keypoints, frame by frame, in the silhouette stage's shape.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    keypoints : path-like
        The keypoints folder (``dataset/keypoints`` or ``--keypoints DIR``).
    rig : Rig, optional
        The cameras to use (default the dataset's): a subset leaves cameras out (their
        keypoints and images are never read).
    config : KeypointStage1Config
    frames : sequence of int, optional
        Frames to yield, increasing (default all).  The triangulation itself runs over the
        whole sequence once (its flip and offset decisions are the sequence's).
    silhouettes : {"auto", "masks", "background", "seeded"}
        See the module docstring.
    masks_dir : path-like, optional
        Masks given, ``<dir>/<camera>/NNNNNN.png``.
    foreground : toolkit.foreground.ForegroundConfig, optional
        Background subtraction's options (``silhouettes="background"``).
    observer : Observer, optional
    log_images : bool
    stage1 : KeypointStage1, optional
        An earlier triangulation of the same keypoints and cameras (skips it).

    Yields
    ------
    estimate : toolkit.silhouettes.estimate.FrameEstimate
        With ``timings["foreground"]`` and ``timings["keypoints"]`` (this frame's share of
        the sequence triangulation), and ``timings["stage1"]`` (all of this frame's stage 1: those two
        and its share of building the silhouette models).
    masks : list of (ndarray (H, W) bool or None)
        Rig order.
    """
    from toolkit.io import VideoReader

    obs = as_observer(observer)
    rig = dataset.rig if rig is None else rig
    names = rig.names
    todo = list(range(dataset.n_frames)) if frames is None else [int(t) for t in frames]
    t0 = time.perf_counter()
    if stage1 is None:
        stage1 = triangulate_dataset_keypoints(keypoints, dataset.camera_names, rig, dataset.n_frames, config,
                                               fps=getattr(dataset, "fps", None), observer=observer)
    t_kp = (time.perf_counter() - t0) / max(len(stage1.frames), 1)
    plates = {c: p for c in names if (p := dataset.background(c)) is not None}
    source = choose_silhouettes(silhouettes, masks_dir, len(plates) == len(names))
    obs.report("text", name="stage1/keypoints", text=(
        f"keypoints {stage1.format}, cameras matched {stage1.matching}; offsets: "
        f"{stage1.sequence.offset_decision.reason}; silhouettes: {source}"))
    # a background model without a plate learns from a pass over the video on its own decoder; the frames
    # themselves are read through the dataset, whose reader keeps the last one (the caller's
    # dataset.frame(c, t) after this yields frame t decodes nothing again)
    shared = getattr(dataset, "frame", None)  # a Dataset; any object with video_path() works too
    t_setup = time.perf_counter()
    readers = {c: VideoReader(dataset.video_path(c)) for c in names
               if (source == "background" and c not in plates) or shared is None}
    try:
        extractors, seeded = _silhouette_models(source, names, plates, readers, foreground, rig, observer)
        previous: dict = {c: None for c in names}
        setup = (time.perf_counter() - t_setup) / max(len(todo), 1)  # each frame's share of the silhouette models
        for t in todo:
            t1 = time.perf_counter()
            est = stage1.estimate(t)
            images = _frame_images(t, names, shared, readers, obs, log_images)
            masks = _frame_masks(t, source, names, images, est, rig, masks_dir, extractors, seeded, previous, obs,
                                 log_images)
            est.timings["foreground"] = time.perf_counter() - t1
            est.timings["keypoints"] = t_kp
            est.timings["stage1"] = time.perf_counter() - t1 + t_kp + setup
            yield est, masks
    finally:
        for r in readers.values():
            r.close()
