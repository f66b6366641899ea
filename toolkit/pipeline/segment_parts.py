"""Stage 2 as a run: body-part labels for every camera and frame, resumable.

:func:`run` is what ``recipes/segment_parts.py`` calls (its docstring lists
the outputs).  Per frame and camera: the template fitted to the pose
(:func:`toolkit.segmentation.segment_views`), the part labels written to
``OUT/parts/<camera>/NNNNNN.png``, one record per frame (parts without a
colour model, IoU against ground truth) in ``OUT/frames/``; a frame with a
record is skipped when the run resumes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.pipeline.parallel import ParallelConfig, drop_cached, worker_cache
from toolkit.pipeline.run import FrameRecords, RunResult, open_run, run_frames
from toolkit.segmentation.segment import SegmentationConfig
from toolkit.segmentation.pipeline import TEMPLATE_POSES


@dataclass(frozen=True)
class SegmentPartsConfig:
    """Options of a stage-2 run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    segmentation : SegmentationConfig
        The segmentation (a ``[segmentation]`` table in TOML).
    poses : Path, optional
        Stage-1 output folder (``poses3d.npz``, ``offsets.npz``, ``poses2d.npz``
        with ``template_pose="per_view"``, ``calibration.toml``).
    gt_joints : bool
        Fit the template to the ground-truth joints through the true cameras instead.
    gt_masks : bool
        Use the ground-truth silhouettes instead of foreground extraction
        (median background of the frames processed).
    template_pose : str
        One of :data:`~toolkit.segmentation.TEMPLATE_POSES`: fit to the stage-1
        3D joints projected (``multiview``) or to each view's 2D pose (``per_view``).
    template_height_m : float
        Stature of the generic template, metres.
    max_frames : int, optional
        Only the first N frames (part of the identity: the backgrounds are
        learned from the frames processed).
    recording : bool
        Write ``recording.rrd``.
    replace_stale : bool
        Move another run's results aside instead of refusing them.
    progress : bool
        Show a progress bar.
    workers : int
        Frames at once, each a task on a local Dask cluster of this many worker
        processes (1: in this process; ``docs/parallel.md``).  The silhouettes
        (a motion prior from the previous frame) are extracted here in frame
        order; a frame's segmentation depends on nothing else, so the outputs
        are those of one worker.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://HOST:PORT``) to run the frames on.
    """

    segmentation: SegmentationConfig = field(default_factory=SegmentationConfig)
    poses: Path | None = None
    gt_joints: bool = False
    gt_masks: bool = False
    template_pose: str = "multiview"
    template_height_m: float = 1.75
    max_frames: int | None = None
    recording: bool = True
    replace_stale: bool = False
    progress: bool = True
    workers: int = 1
    scheduler: str | None = None

    #: Fields that do not change the results (left out of the run identity).
    RUNTIME = ("recording", "replace_stale", "progress", "workers", "scheduler")

    def __post_init__(self):
        if self.template_pose not in TEMPLATE_POSES:
            raise InputError("SegmentPartsConfig.template_pose", f"one of {TEMPLATE_POSES}", repr(self.template_pose))
        if self.poses is not None and self.gt_joints:
            raise InputError("SegmentPartsConfig", "poses (a stage-1 folder) or gt_joints, not both",
                             f"poses={self.poses}, gt_joints=True")
        if self.max_frames is not None and int(self.max_frames) < 1:
            raise InputError("SegmentPartsConfig.max_frames", "a positive number of frames", repr(self.max_frames))
        ParallelConfig(self.workers, self.scheduler)  # checked


def _poses(ds, config: SegmentPartsConfig, log):
    """The poses the template is fitted to: stage 1's, the ground truth's, or none (a standing pose)."""
    from toolkit.pipeline.stage_inputs import read_stage1
    from toolkit.segmentation import PoseSource

    if config.gt_joints:
        return PoseSource(ds.gt_rig, ds.gt_joints3d(), ds.gt_joints2d(), name="groundtruth")
    if config.poses is not None:
        s1 = read_stage1(ds, config.poses, poses2d=config.template_pose == "per_view")
        rigs = tuple(s1.cameras(t) for t in range(len(s1.offsets)))
        return PoseSource(s1.rig, s1.joints, s1.poses2d or None, rigs, name=str(config.poses))
    log("no --poses or --gt-joints: the template is a standing pose fitted to each silhouette's box")
    return PoseSource(ds.rig, name="none")


class _FirstFrames:
    """The first ``n`` frames of a camera's video on a decoder of its own: what the background learns from."""

    def __init__(self, path, n: int):
        from toolkit.io import VideoReader

        self.reader = VideoReader(path)
        self.n = n

    def __len__(self) -> int:
        return self.n

    def read(self, i: int) -> np.ndarray:
        return self.reader.read(i)


class _StreamedSilhouettes:
    """``(camera, t) -> (H, W) bool``: the foreground of each camera's frames in order, a frame at a time.

    The background is learned from frames 0..n-1 (a pass on its own decoder);
    the frames are then read through the dataset's reader, which keeps the
    last one, so the segmentation's read of frame ``t`` decodes nothing again.
    Each camera holds its extractor, the previous frame and mask (the motion
    prior) and the last mask: memory is a few frames, not the sequence.
    Frames must be asked for in increasing order per camera (a resumed run
    extracts the finished frames before its first one again, for the prior).
    """

    def __init__(self, ds, n: int):
        self.ds, self.n = ds, n
        self.extractors: dict = {}
        self.state: dict = {}  # camera -> (next frame, (frame, mask) of the previous one or None, (t, mask))

    def __call__(self, camera: str, t: int) -> np.ndarray:
        from toolkit.foreground import ForegroundExtractor

        if camera not in self.extractors:
            frames = _FirstFrames(self.ds.video_path(camera), self.n)
            try:
                self.extractors[camera] = ForegroundExtractor(None).fit(frames)
            finally:
                frames.reader.close()
            self.state[camera] = (0, None, None)
        nxt, prev, last = self.state[camera]
        if last is not None and last[0] == t:
            return last[1]
        if t < nxt:
            raise InputError(f"silhouettes of {camera}", f"frames in increasing order (next {nxt})", f"frame {t}")
        ex = self.extractors[camera]
        while nxt <= t:
            img = self.ds.frame(camera, nxt)
            sil = ex.extract(img, prev)
            prev = (img, sil.mask) if sil.usable else None
            last = (nxt, sil.mask)
            nxt += 1
        self.state[camera] = (nxt, prev, last)
        return last[1]


def _silhouettes(ds, config: SegmentPartsConfig, n: int, todo: list):
    """``(camera, t) -> (H, W) bool``: ground-truth masks, or foreground of a background learned on frames 0..n-1."""
    if config.gt_masks:
        return ds.gt_mask
    return _StreamedSilhouettes(ds, n)


@dataclass(frozen=True)
class _FrameTask:
    """One frame of the run as a task (picklable; a worker builds the template once per run).

    ``task(t, views, observer=None)`` segments frame ``t``: ``views`` maps each
    camera to ``(image (H, W, 3) uint8, silhouette (H, W) bool, camera, joints
    (14, 3) m or None, 2D joints (14, 2) px or None, ground-truth labels (H, W)
    uint8 or None)``; the labels go to ``OUT/parts/<camera>/NNNNNN.png``, then
    the frame's record.  The colour models are fitted per view with a fixed
    seed: nothing is carried from frame to frame.
    """

    token: str
    out: Path
    n: int
    config: SegmentPartsConfig

    def __call__(self, t: int, views: dict, observer=None) -> None:
        from toolkit.io import atomic_write_png, frame_filename
        from toolkit.segmentation import part_iou
        from toolkit.segmentation.segment import segment_frame
        from toolkit.template import Template

        template = worker_cache(self.token, lambda: Template(self.config.template_height_m))
        record = {"frame": t, "missing": {}, "iou": {}}
        for c, (image, silhouette, cam, J, x, gt) in views.items():
            r = segment_frame(image, silhouette, J, cam, template, self.config.segmentation, observer, joints2d=x,
                              frame=t)
            if observer is not None:
                observer.report("image", camera=c, image=image, frame=t)
            atomic_write_png(Path(self.out) / "parts" / c / frame_filename(t), r.labels)
            for p in r.parts_without_model:
                record["missing"][str(p)] = record["missing"].get(str(p), 0) + 1
            if gt is not None:
                record["iou"][c] = part_iou(r.labels, gt).tolist()
        FrameRecords(self.out, self.n).write(t, record)


def _observer(folder, rig, names: list):
    from toolkit.skeleton import SKELETON_14
    from toolkit.viz import RerunObserver

    # in parts, one per frame: a run killed outright leaves the finished frames' recording complete
    observer = RerunObserver(application_id="segment_parts", path=folder.recording,
                             recording_id=folder.recording_id, camera_names=names, parts=True)
    observer.report("rig", rig=rig)
    observer.report("skeleton", skeleton=SKELETON_14)
    return observer


def run(config: SegmentPartsConfig, *, dataset, out, observer=None, log=print) -> RunResult:
    """Segment every camera of every frame of a dataset into body parts, into ``out``, resuming finished frames.

    Parameters
    ----------
    config : SegmentPartsConfig
    dataset : path
        Dataset folder (``docs/dataset_layout.md``).
    out : path
        Output folder (``recipes/segment_parts.py`` lists what it holds).
    observer : Observer, optional
        Receives every intermediate; default: a rerun recording in ``out``
        (``config.recording``), one part per resumed run.
    log : callable or None

    Returns
    -------
    RunResult
        ``metrics``: ``views`` segmented by this run, ``missing`` (part id ->
        views without a colour model) and ``iou`` (mean per part over every
        finished view, with ground truth; else None); ``extra``: ``poses``
        (where the poses came from) and ``cameras``.

    Raises
    ------
    InputError
        Bad dataset, options, stage-1 folder, or an output folder of another run.
    """
    import uuid

    import numpy as np

    from toolkit.io import Dataset

    log = log or (lambda *_: None)
    out = Path(out)
    with Dataset.open(dataset) as ds:
        names = ds.camera_names
        n = ds.frames_to_process(config.max_frames)
        poses = _poses(ds, config, log)
        extra = {"poses": None if config.poses is None else str(Path(config.poses).resolve())}
        folder = open_run(out, "segment_parts", ds.root, config, n, exclude=SegmentPartsConfig.RUNTIME + ("poses",),
                          extra=extra, replace_stale=config.replace_stale,
                          recording=config.recording and observer is None, log=log)
        todo = folder.records.todo()
        silhouette = _silhouettes(ds, config, n, todo)
        own = observer is None
        obs = _observer(folder, poses.rig, names) if own and folder.recording is not None else observer
        task = _FrameTask(uuid.uuid4().hex, out, n, config)

        def frames():  # the silhouettes' motion prior needs the frames in order: here, ahead of the workers
            for t in todo:
                views = {}
                for c in names:
                    cam, J, x = poses.view(c, t)
                    image = ds.frame(c, t)
                    views[c] = (image, silhouette(c, t), cam, J, x, ds.gt_parts(c, t) if ds.has_groundtruth else None)
                yield t, views

        try:
            processed, stopped, seconds = run_frames(
                task, frames(), total=len(todo), parallel=ParallelConfig(config.workers, config.scheduler),
                observer=obs, progress=config.progress, desc="segmentation")
        finally:
            drop_cached(task.token)
            if own and obs is not None:
                obs.close()
        records = folder.records.read_all()
    missing: dict = {}
    for rec in records:
        for p, k in rec["missing"].items():
            missing[int(p)] = missing.get(int(p), 0) + k
    ious = [v for rec in records for v in rec["iou"].values()]
    metrics = {"views": processed * len(names), "missing": dict(sorted(missing.items())),
               "iou": np.nanmean(np.array(ious, float), 0).tolist() if ious else None}
    return RunResult(out, n, len(records), processed, n - len(todo), stopped, seconds, metrics,
                     obs.saved if own and obs is not None else None,  # a finished file only
                     {"poses": poses.name, "cameras": len(names)})


def summary_lines(result: RunResult) -> list:
    """What a stage-2 run says when it ends (the recipe prints these)."""
    import numpy as np

    from toolkit.skeleton import SKELETON_14

    m, dt, count = result.metrics, result.seconds, result.metrics["views"]
    lines = [f"{'stopped early (' + result.stopped + '): ' if result.stopped else ''}segmented {count} views "
             f"({result.processed} frames x {result.extra['cameras']} cameras) in {dt:.1f} s "
             f"({dt / max(count, 1):.2f} s/view); poses: {result.extra['poses']}"]
    if result.earlier:
        lines.append(f"  {result.earlier} frame(s) were already finished (resumed); {result.finished} of "
                     f"{result.frames} now")
    if m["missing"]:
        lines.append("parts without a colour model: " + ", ".join(
            f"{SKELETON_14.part_names[p - 1]} ({k} views)" for p, k in m["missing"].items()))
    if m["iou"] is not None:
        lines.append("IoU against groundtruth/parts: mean {:.3f}; ".format(np.nanmean(m["iou"])) + ", ".join(
            f"{nm} {v:.2f}" for nm, v in zip(SKELETON_14.part_names, m["iou"])))
    lines.append(f"  part labels: {result.out / 'parts'}/<camera>/NNNNNN.png")
    if result.recording is not None:
        lines.append(f"  recording:   {result.recording}   (open with: rerun {result.recording})")
    return lines
