"""The articulated-billboard system's run: every stage, end to end, frame by frame, resumable.

:func:`run` is what ``recipes/free_viewpoint.py`` calls (its docstring lists
the outputs).  Per frame: stage 1 (the silhouette database, or a detector's
keypoints) -> :class:`~toolkit.pipeline.frame.FrameProcessor`
(segmentation, seams, the stage-3 search, billboards, baselines) -> the novel
cameras, a held-out source camera and three camera paths rendered and scored
-> one record per frame.  At the end: ``poses3d.npz``, the paths' videos and
``metrics.json``.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import time
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.pipeline.parallel import AUTO, Cluster, ParallelConfig, drop_cached, resolve_workers, worker_cache
from toolkit.pipeline.people import PEOPLE_CHOICES
from toolkit.pipeline.run import FrameRecords, RunResult, frame_ranges, open_run, run_frames
from toolkit.rendering.freeviewpoint import FreeViewpointConfig

#: Camera paths rendered for every run (``OUT/paths/<name>/``).
PATHS = ("orbit", "sweep", "birds_eye")
#: Background models of the foreground stage, and chroma keying.
FOREGROUNDS = ("median", "mog2", "knn", "chroma")
#: Renderers of the novel views.
RENDERERS = ("cpu", "open3d")
#: Keypoint formats a detector's files may be in.
KEYPOINT_FORMATS = ("body_25", "body_25b", "coco_17", "coco_18", "halpe_26", "coco_133", "blazepose_33")
#: What the people are drawn over: ``"scene"`` the scene model built from the source videos
#: (:mod:`toolkit.scene`, ``OUT/scene/``), ``"plates"`` the dataset's clean plates (synthetic: the
#: true surroundings of every view; a held-out camera's own plate or its own frame with the person
#: filled in), an evaluation aid that isolates the people's rendering.
BACKGROUNDS = ("scene", "plates")
#: Camera paths' backgrounds are drawn at this share of their size (they are not judged).
PATH_BACKGROUND_SCALE = 0.5
#: Where the silhouettes come from when stage 1 uses keypoints.
SILHOUETTES = ("auto", "masks", "background", "seeded")
#: Parts of a frame's ``total`` (its work after stage 1) in ``seconds_per_frame``: ``views`` the novel (and
#: held-out) views rendered, scored and written, ``paths`` the camera paths' views, ``other`` the rest.
WITHIN_TOTAL = ("segmentation", "optimize", "billboards", "standard_billboards", "visual_hull", "views", "paths")
#: Per-stage timings averaged into ``metrics.json`` ``seconds_per_frame``; ``stage1`` is the frame's stage 1
#: (outside ``total``; ``foreground`` and ``keypoints`` are parts of it).
TIMED = ("total", "stage1", "foreground", "keypoints") + WITHIN_TOTAL + ("other",)


@dataclass(frozen=True)
class FreeViewpointRunConfig:
    """Options of a free-viewpoint run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    frame : FreeViewpointConfig
        The per-frame chain (stage 3 on or off and its search, baselines,
        template, plates); a ``[frame]`` table in TOML.
    db : Path, optional
        Silhouette database ``.npz`` (default: the cached one).
    foreground : str
        One of :data:`FOREGROUNDS`.
    max_frames : int, optional
        Only the first N frames.
    renderer : str
        One of :data:`RENDERERS`.
    refine_calibration : bool
        Refine the cameras on the dataset's field lines.
    recording : bool
        Write ``recording.rrd``.
    jpeg_quality : int, optional
        JPEG quality (1-100) of the recording's images (default: the observer's).
    replace_stale : bool
        Move another run's results aside instead of refusing them.
    keypoints : Path, optional
        A detector's 2D keypoints, one sub-folder per camera (default: the dataset's ``keypoints/``).
    use_keypoints : bool
        False ignores the dataset's keypoints (2D poses from the silhouette database).
    keypoint_format : str, optional
        One of :data:`KEYPOINT_FORMATS` (default: the dataset's ``import.json``, else found from the files).
    masks : Path, optional
        Subject masks from elsewhere (default: the dataset's ``masks/``).
    silhouettes : str
        With keypoints: one of :data:`SILHOUETTES`.
    hold_out : str, optional
        A source camera left out and judged (``OUT/heldout/``).
    background : str
        One of :data:`BACKGROUNDS`.
    people : str
        With keypoints: ``"all"`` follows every participant (:mod:`toolkit.pipeline.people`),
        ``"main"`` the person the cameras agree on.  From the silhouette database: ``"all"``
        follows every person found on the ground in the cameras' foreground
        (:func:`toolkit.pipeline.people.locate_silhouette_people`), ``"main"`` one person.
    progress : bool
        Show a progress bar.
    workers : int or "auto"
        Frames in parallel on a local Dask cluster of this many worker
        processes (1: in this process; ``docs/parallel.md``); ``"auto"`` (the
        default): one per available core (:func:`toolkit.pipeline.parallel.available_cores`),
        no more than the frames to do, so one core or one frame runs in this process.
    scheduler : str, optional
        Frames on a running Dask cluster, ``tcp://HOST:PORT`` (the dataset and
        the output folder on a file system every worker sees).
    """

    frame: FreeViewpointConfig = field(default_factory=FreeViewpointConfig)
    db: Path | None = None
    foreground: str = "median"
    max_frames: int | None = None
    renderer: str = "cpu"
    refine_calibration: bool = True
    recording: bool = True
    jpeg_quality: int | None = None
    replace_stale: bool = False
    keypoints: Path | None = None
    use_keypoints: bool = True
    keypoint_format: str | None = None
    masks: Path | None = None
    silhouettes: str = "auto"
    hold_out: str | None = None
    background: str = "scene"
    people: str = "all"
    progress: bool = True
    workers: int | str = AUTO
    scheduler: str | None = None

    #: Fields that do not change the results (left out of the run identity).
    RUNTIME = ("max_frames", "recording", "jpeg_quality", "replace_stale", "progress", "workers", "scheduler")

    def __post_init__(self):
        for name, allowed in (("foreground", FOREGROUNDS), ("renderer", RENDERERS), ("silhouettes", SILHOUETTES),
                              ("background", BACKGROUNDS), ("people", PEOPLE_CHOICES)):
            if getattr(self, name) not in allowed:
                raise InputError(f"FreeViewpointRunConfig.{name}", f"one of {allowed}", repr(getattr(self, name)))
        if self.keypoint_format is not None and self.keypoint_format not in KEYPOINT_FORMATS:
            raise InputError("FreeViewpointRunConfig.keypoint_format", f"one of {KEYPOINT_FORMATS}",
                             repr(self.keypoint_format))
        if self.jpeg_quality is not None and not 1 <= int(self.jpeg_quality) <= 100:
            raise InputError("FreeViewpointRunConfig.jpeg_quality", "an integer in 1..100", repr(self.jpeg_quality))
        if self.max_frames is not None and int(self.max_frames) < 1:
            raise InputError("FreeViewpointRunConfig.max_frames", "a positive number of frames", repr(self.max_frames))
        ParallelConfig(resolve_workers(self.workers), self.scheduler)  # checked


def _inputs(ds, config: FreeViewpointRunConfig) -> tuple:
    """The keypoints and masks folders the run uses (None: none), checked."""
    kp_dir = None if not config.use_keypoints else (
        config.keypoints if config.keypoints is not None else (ds.root / "keypoints" if ds.has_keypoints else None))
    if kp_dir is not None and not Path(kp_dir).is_dir():
        raise InputError("keypoints (--keypoints)", "a folder with one sub-folder of keypoints per camera", f"{kp_dir}")
    masks_dir = config.masks if config.masks is not None else (ds.root / "masks" if ds.has_masks else None)
    if masks_dir is not None and not Path(masks_dir).is_dir():
        raise InputError("masks (--masks)", "a folder with one sub-folder of masks per camera", f"{masks_dir}")
    if config.hold_out is not None and config.hold_out not in ds.camera_names:
        raise InputError("hold_out (--hold-out)", f"one of the dataset's cameras {ds.camera_names}", repr(config.hold_out))
    return kp_dir, masks_dir


def _identity_exclude(config: FreeViewpointRunConfig, kp_dir, masks_dir) -> tuple[tuple, dict]:
    """Config fields left out of the identity, and what is added (the inputs actually used)."""
    from toolkit.silhouettes import default_database_path

    exclude = FreeViewpointRunConfig.RUNTIME + ("db", "keypoints", "masks")
    extra = {"db": default_database_path().name if config.db is None else str(Path(config.db).resolve()),
             "keypoints": str(Path(kp_dir).resolve()) if kp_dir is not None else None,
             "masks": str(Path(masks_dir).resolve()) if masks_dir is not None else None}
    return exclude, extra


def _camera_paths(rig, n: int) -> dict:
    """The three camera paths of a run (``OUT/paths/``), one camera per frame each."""
    from toolkit.cameras import Rig, closest_point_to_rays
    from toolkit.rendering import birds_eye, orbit_path, source_path

    target = closest_point_to_rays(rig.centers, np.array([c.forward for c in rig]))[0]
    return {"orbit": orbit_path(target, n, radius_m=float(np.median(np.linalg.norm(rig.centers - target, axis=1))),
                                height_m=float(np.median(rig.centers[:, 2])), size=rig[0].size,
                                focal_px=float(rig[0].K[0, 0])),
            # a path between cameras of different sizes (1080 and 1088 px wide) is drawn at the first one's
            "sweep": source_path(Rig(tuple(replace(c, size=rig[0].size) for c in rig)), max(n, 2), closed=True)[:n],
            "birds_eye": [birds_eye(rig, target)] * n}


#: Hidden folder of a run (``OUT/.plates``) where its processes share the fixed cameras' background plates
#: (synthetic scenes); removed when every frame is finished.
PLATE_STORE = ".plates"
#: Hidden folder of a run (``OUT/.views``) where its worker processes share the scene model's views of the
#: fixed cameras; removed when every frame is finished.
VIEW_STORE = ".views"

def _foreground(config: FreeViewpointRunConfig):
    """The foreground stage's options of a run."""
    from toolkit.foreground import BackgroundConfig, ForegroundConfig

    return ForegroundConfig(method="chroma") if config.foreground == "chroma" else \
        ForegroundConfig(background=replace(BackgroundConfig(), method=config.foreground))


#: The run's scene model (``OUT/scene/``, :class:`toolkit.scene.SceneModel`).
SCENE_FOLDER = "scene"


def _scene_model(ds, rig, config: FreeViewpointRunConfig, out: Path, n: int, log, observer=None) -> None:
    """Build the run's scene model from the source videos into ``OUT/scene`` (kept when a resumed run
    finds it made for the same cameras); shown to ``observer``."""
    from toolkit.scene import SceneModel, build_scene_model

    folder = out / SCENE_FOLDER
    if (folder / "scene.json").exists():
        try:
            SceneModel.load(folder, rig).report(observer)
            return
        except InputError:
            shutil.rmtree(folder, ignore_errors=True)
    t0 = time.perf_counter()
    model = build_scene_model(ds, rig, n, foreground=_foreground(config), log=log)
    model.save(folder)
    model.report(observer)
    if log is not None:
        log(f"scene model of {len(rig)} cameras from {len(model.evidence['frames_sampled'])} frames each "
            f"({time.perf_counter() - t0:.1f} s): {folder}")


class _Stage1:
    """Stage 1 of the run: the silhouette database or a detector's keypoints, over the frames to do."""

    def __init__(self, ds, rig, config: FreeViewpointRunConfig, kp_dir, masks_dir, out: Path, observer, log=None):
        self.ds, self.rig, self.config, self.kp_dir, self.masks_dir = ds, rig, config, kp_dir, masks_dir
        self.out, self.observer, self.log = out, observer, log
        self._people = None  # (where the people stand or None, their foreground models), found once

    @property
    def name(self) -> str:
        return "keypoints" if self.kp_dir is not None else "silhouette database"

    def estimates(self, frames: list):
        """Yields ``(estimate, masks)`` per frame of ``frames``."""
        from toolkit.calibration import refined_cameras
        from toolkit.pipeline.keypoints import KeypointStage1Config, declared_format, estimate_from_keypoints
        from toolkit.silhouettes import Stage1Config
        from toolkit.silhouettes.pipeline import estimate_dataset

        c = self.config
        if not frames:
            return iter(())
        fg = _foreground(c)
        if self.kp_dir is not None:
            kconf = KeypointStage1Config(fmt=c.keypoint_format or declared_format(self.ds.root))
            if c.people == "all":
                from toolkit.pipeline.people import estimate_people

                return ((p, None) for p in estimate_people(
                    self.ds, self.kp_dir, self.rig, kconf, frames=frames, silhouettes=c.silhouettes,
                    masks_dir=self.masks_dir, foreground=fg, observer=self.observer, log=self.log))
            return estimate_from_keypoints(self.ds, self.kp_dir, self.rig, kconf, frames=frames,
                                           silhouettes=c.silhouettes, masks_dir=self.masks_dir, foreground=fg,
                                           observer=self.observer)
        db = self._database()
        s1config = Stage1Config().with_refined_cameras(refined_cameras(self.out))  # tight prior where refined
        if c.people == "all":
            from toolkit.pipeline.people import estimate_people_silhouettes, locate_silhouette_people, people_foreground

            if self._people is None:  # the same people (and foreground models) for every part of the run
                extractors = people_foreground(self.ds, self.rig, fg)
                self._people = (locate_silhouette_people(self.ds, self.rig, log=self.log, extractors=extractors),
                                extractors)
            located, extractors = self._people
            if located is not None:
                return ((p, None) for p in estimate_people_silhouettes(
                    self.ds, db, self.rig, located, s1config, frames=frames, observer=self.observer,
                    extractors=extractors))
        return estimate_dataset(self.ds, db, s1config, foreground=fg, frames=frames, rig=self.rig,
                                observer=self.observer)

    def _database(self):
        from toolkit.silhouettes import SilhouetteDatabase, default_database

        db = self.config.db
        if db is None or not Path(db).exists():
            return default_database(db)[0]
        return SilhouetteDatabase.load(db)


class _Only:
    """Passes on the reports made in the given frames (a report's ``frame`` holds for those after it)."""

    def __init__(self, observer, frames: set):
        self.observer, self.frames, self.frame = observer, frames, None

    def report(self, kind: str, **data) -> None:
        if data.get("frame") is not None:
            self.frame = int(data["frame"])
        if self.frame is None or self.frame in self.frames:
            self.observer.report(kind, **data)


def _recording_observer(folder, ds, novel: list, config: FreeViewpointRunConfig):
    """The rerun observer of this part of the run (None without a recording)."""
    if folder.recording is None:
        return None
    from toolkit.skeleton import SKELETON_14
    from toolkit.viz import RerunConfig, RerunObserver

    rconf = RerunConfig() if config.jpeg_quality is None else RerunConfig(jpeg_quality=int(config.jpeg_quality))
    observer = RerunObserver(application_id="free_viewpoint", path=folder.recording,
                             recording_id=folder.recording_id,
                             camera_names=ds.camera_names + [c.name for c in novel], config=rconf, parts=True)
    if novel:
        observer.report("rig", rig=ds.novel_rig)
    observer.report("skeleton", skeleton=SKELETON_14)
    return observer


class _Frames:
    """The per-frame work of a run after stage 1: process, render, score, write the record.

    Built once per process from a :class:`_FrameTask` (on a Dask worker, or in
    the main process with one worker); holds nothing that changes from frame
    to frame, so a frame's outputs do not depend on which process did the
    frames before it.
    """

    def __init__(self, job: "_FrameTask"):
        from toolkit.io import Dataset
        from toolkit.pipeline.frame import FrameProcessor
        from toolkit.pipeline.keypoints import declared_format
        from toolkit.pipeline.views import HeldOutRegions
        from toolkit.rendering import CpuCompositor
        from toolkit.rendering.evaluation import BackgroundPlates

        config = job.config
        self.ds = ds = Dataset.open(job.dataset)
        self.rig, self.novel, self.held, self.out = job.rig, list(job.novel), job.held, Path(job.out)
        self.region_of = None if job.held is None else HeldOutRegions(
            ds, job.held, masks_dir=job.masks_dir, keypoints=job.kp_dir, out=self.out,
            fmt=config.keypoint_format or declared_format(ds.root))
        self.paths = _camera_paths(job.rig, job.n)
        self.processor = FrameProcessor(job.rig, config.frame)
        if config.renderer == "open3d":
            from toolkit.rendering import Open3DRenderer
            self.compositor = Open3DRenderer(job.rig[0].size)
        else:
            self.compositor = CpuCompositor()
        self.scene = None
        if config.background == "scene":
            from toolkit.scene import SceneModel

            self.scene = SceneModel.load(self.out / SCENE_FOLDER, job.rig)
        self.plates = BackgroundPlates(ds.scene_toml, store=self.out / PLATE_STORE) \
            if ds.scene_toml is not None and self.scene is None else None
        self.source_plates = {c: p for c in job.rig.names if (p := ds.background(c)) is not None}
        self.records = FrameRecords(self.out, job.n)
        self.observer = None
        self.share_plates()

    def close(self) -> None:
        self.ds.close()

    def share_plates(self) -> None:
        """Draw the plates of the run's fixed cameras (novel views, bird's-eye view) that no other process of
        the run has claimed: each drawn once per run, not once per worker (:meth:`BackgroundPlates.share`)."""
        if self.plates is not None:
            self.plates.share(self.novel + [self.paths["birds_eye"][0]])

    def prepare_views(self) -> None:
        """The scene model's views of the fixed cameras (novel, held-out, bird's-eye) and their nearest
        source's maps, drawn ahead of the first frame (:meth:`toolkit.scene.SceneModel.prepare`): a Dask
        worker does it while it warms up, each view drawn by one worker for all
        (:meth:`toolkit.scene.SceneModel.share_views`, the run's :data:`VIEW_STORE`); with one worker the
        first frame draws them."""
        if self.scene is not None:
            fixed = self.novel + ([self.held] if self.held is not None else [])
            self.scene.share_views(fixed + [self.paths["birds_eye"][0]], self.out / VIEW_STORE)
            self.scene.prepare(fixed)
            self.scene.prepare([self.paths["birds_eye"][0]], carry=False)

    def _background(self, cam, scale: float = 1.0) -> np.ndarray:
        """What the people are drawn over in view ``cam``: the scene model's view (drawn at ``scale`` of
        the size), the synthetic scene's true surroundings (``background="plates"``), or black."""
        if self.scene is not None:
            if scale == 1.0:
                return self.scene.render(cam)[0]
            import cv2

            return cv2.resize(self.scene.render(cam.scaled(scale))[0], cam.size, interpolation=cv2.INTER_LINEAR)
        if self.plates is not None:
            return self.plates.plate(cam)
        return np.zeros(cam.size[::-1] + (3,), np.float32)

    def _views(self, t: int, res, images: dict, everyone: list) -> list:
        from toolkit.pipeline.views import EvaluationView

        views = []
        several = getattr(self.ds, "people_count", 1) > 1
        for cam in self.novel:
            carried = None
            if self.scene is not None:
                near = self.scene.nearest_source(cam)
                carried = self.scene.carry(cam, near, images[near])
            regions = None
            if several:
                inst = self.ds.novel_instances(cam.name, t)
                regions = [inst == k + 1 for k in range(self.ds.people_count)]
            views.append(EvaluationView(cam, "novel", self._background(cam), self.ds.novel_image(cam.name, t),
                                        self.ds.novel_mask(cam.name, t), carried, regions))
        if self.held is not None:
            people = [r.joints for r in everyone] if len(everyone) > 1 else None
            views.append(self.region_of.view(t, res.joints if res.ok else None, scene=self.scene, images=images,
                                             people=people))
        return views

    def __call__(self, est, masks, images: dict, observer=None) -> None:
        from toolkit.io import atomic_write_png
        from toolkit.io.frames import frame_filename
        from toolkit.multiview import image_offsets
        from toolkit.observe import as_observer
        from toolkit.pipeline.views import render_evaluation
        from toolkit.rendering.freeviewpoint import render_methods

        from toolkit.pipeline.people import PeopleFrame, combined_labels

        t0 = time.perf_counter()
        t = est.frame
        self.observer = observer
        self.processor.observer = as_observer(observer)
        people = list(zip(est.estimates, est.masks)) if isinstance(est, PeopleFrame) else [(est, masks)]
        everyone = [self.processor.process(t, images, m, e, plates=self.source_plates) for e, m in people]
        res = everyone[0]
        labels = res.labels if len(everyone) == 1 else combined_labels(everyone, self.rig)
        for c in self.rig.names:
            if c in labels:
                atomic_write_png(self.out / "parts" / c / frame_filename(t), labels[c])
        drawn = res if len(everyone) == 1 else everyone
        t1 = time.perf_counter()
        scores, heldout = {}, {}
        for v in self._views(t, res, images, everyone):
            for m, sc in render_evaluation(drawn, v, self.out, t, self.compositor, observer=self.observer).items():
                (scores if v.kind == "novel" else heldout).setdefault(m, {})[v.camera.name] = sc
        t2 = time.perf_counter()
        for p, cams in self.paths.items():
            bg = self._background(cams[t], 1.0 if p == "birds_eye" else PATH_BACKGROUND_SCALE)
            img = render_methods(drawn, cams[t], bg, self.compositor, methods=("articulated",))["articulated"]
            atomic_write_png(self.out / "paths" / p / frame_filename(t), img)
        summed = {}
        for r in everyone:
            for k, v in r.timings.items():
                summed[k] = summed.get(k, 0.0) + v
        timings = {**summed, **{k: v for k, v in est.timings.items()
                                     if k in ("stage1", "foreground", "keypoints")},
                   "views": t2 - t1, "paths": time.perf_counter() - t2, "total": time.perf_counter() - t0}
        timings["other"] = timings["total"] - sum(timings.get(k, 0.0) for k in WITHIN_TOTAL)
        record = {"frame": t, "status": res.status, "joints": res.joints.tolist(),
                  "joints_stage1": res.joints_stage1.tolist(), "offsets": image_offsets(est.offsets).tolist(),
                  "scores": scores, "timings": timings, "optimize": res.optimize}
        if isinstance(est, PeopleFrame):
            record["people"] = [{"name": n, "status": r.status, "joints": r.joints.tolist(),
                                 "joints_stage1": r.joints_stage1.tolist(), "optimize": r.optimize}
                                for n, r in zip(est.names, everyone)]
        if self.held is not None:
            record["heldout"] = heldout
            record["heldout_region"] = self.region_of.how.get(t, "")
            record["heldout_offset"] = self.region_of.offsets.get(t, np.zeros(2)).tolist()
        self.records.write(t, record)


@dataclass(frozen=True)
class _FrameTask:
    """One frame of a run as a task (picklable: what a Dask worker needs to build :class:`_Frames`).

    ``task(estimate, masks, images, observer=None)`` processes frame
    ``estimate.frame`` and writes its outputs and record into ``out``.
    """

    token: str
    dataset: Path
    out: Path
    config: FreeViewpointRunConfig
    rig: object
    novel: tuple
    held: object
    n: int
    kp_dir: Path | None
    masks_dir: Path | None

    def __call__(self, est, masks, images: dict, observer=None) -> None:
        self.warm()(est, masks, images, observer)

    def warm(self) -> "_Frames":
        """This process's frame context of the run (built on first use; a warm-up task)."""
        return worker_cache(self.token, lambda: _Frames(self))

    def warm_up(self) -> None:
        """A worker's warm-up task: its frame context, with the fixed cameras' views drawn."""
        self.warm().prepare_views()


#: What a worker imports for a frame (preloaded by the local cluster's fork server, :class:`Cluster`).
_FRAME_MODULES = ("toolkit.pipeline.free_viewpoint", "toolkit.pipeline.frame", "toolkit.pipeline.stage3",
                  "toolkit.pipeline.views", "toolkit.rendering.evaluation", "toolkit.segmentation",
                  "toolkit.synthetic.render", "open3d")


def _warm_imports() -> None:
    """What a worker imports for a frame: a warm-up task while the main process calibrates and starts stage 1."""
    import importlib

    for m in _FRAME_MODULES:
        importlib.import_module(m)


def _match_people(estimated: np.ndarray, truth: np.ndarray) -> list:
    """Each estimated person's true person (Hungarian on the mean joint distance; None when unmatched)
    and joints: ``[(true index or None, (T, 14, 3)), ...]`` for ``estimated`` (P, T, 14, 3)."""
    from scipy.optimize import linear_sum_assignment

    cost = np.full((len(estimated), len(truth)), 1e6)
    for i, E in enumerate(estimated):
        for k, G in enumerate(truth):
            d = np.linalg.norm(E - G, axis=-1)
            if np.isfinite(d).any():
                cost[i, k] = float(np.nanmean(d))
    rows, cols = linear_sum_assignment(cost)
    hit = {int(r): int(c) for r, c in zip(rows, cols) if cost[r, c] < 1e6}
    return [(hit.get(i), E) for i, E in enumerate(estimated)]


class _PeopleJoints:
    """Every followed person's joints over a run, gathered one frame record at a time (``people3d.npz``)."""

    def __init__(self, n: int):
        self.n = n
        self.joints: dict = {}  # name -> (n, 14, 3) metres, in the order the people first appear
        self.drawn: dict = {}

    def add(self, record: dict) -> None:
        for p in record.get("people", []):
            if p["name"] not in self.joints:
                self.joints[p["name"]] = np.full((self.n, 14, 3), np.nan)
                self.drawn[p["name"]] = 0
            self.joints[p["name"]][record["frame"]] = p["joints"]
            self.drawn[p["name"]] += p["status"] == "ok"

    def write(self, out: Path) -> dict:
        """``people3d.npz`` with two people or more; per person the frames drawn (empty otherwise)."""
        import io

        from toolkit.io import atomic_write_bytes
        from toolkit.skeleton import SKELETON_14

        names = list(self.joints)
        if len(names) < 2:
            return {}
        buf = io.BytesIO()
        np.savez(buf, joints=np.stack([self.joints[k] for k in names]), people=np.array(names),
                 names=np.array(SKELETON_14.joint_names))
        atomic_write_bytes(out / "people3d.npz", buf.getvalue())
        return {"names": names, "frames_drawn": dict(self.drawn)}


class _Tally:
    """What the end of a run needs of its frames' records, gathered one record at a time, so that a long run's
    end never holds every record (a few numbers and the scores per frame)."""

    def __init__(self, n: int):
        self.joints = np.full((n, 14, 3), np.nan)
        self.stage1 = np.full((n, 14, 3), np.nan)
        self.status = ["not processed"] * n  # a list: an array of the first string's width would cut longer ones
        self.finished = 0
        self.statuses, self.optimize, self.regions = Counter(), Counter(), Counter()
        self.timings: dict = {k: [] for k in TIMED}
        self.scores, self.heldout, self.offsets = [], [], []
        self.people = _PeopleJoints(n)

    def add(self, r: dict) -> None:
        t = r["frame"]
        self.joints[t], self.stage1[t], self.status[t] = r["joints"], r["joints_stage1"], r["status"]
        self.finished += 1
        self.statuses[r["status"]] += 1
        self.optimize = self.optimize + Counter(r.get("optimize", {}))  # as a sum of Counters (drops zeros)
        for k in TIMED:
            self.timings[k].append(r["timings"].get(k, np.nan))
        self.scores.append(r["scores"])
        self.heldout.append(r.get("heldout", {}))
        self.regions[r.get("heldout_region", "")] += 1
        if "heldout_offset" in r:
            self.offsets.append(r["heldout_offset"])
        self.people.add(r)


def _finish(ds, out: Path, records, n: int, novel: list, held, stage1: str) -> dict:
    """``poses3d.npz``, the paths' videos (when every frame is done) and the metrics (``metrics.json``), from
    the frames' ``records`` (an iterable, read once: :meth:`FrameRecords.each`)."""
    from toolkit.io import atomic_write_text, write_video
    from toolkit.io.frames import frame_filename, read_png
    from toolkit.io.stage_outputs import FreeViewpointPoses, write_free_viewpoint_poses
    from toolkit.pipeline.views import HELDOUT_REGION_DOC
    from toolkit.rendering.evaluation import summarise
    from toolkit.skeleton import SKELETON_14, pose_errors

    tally = _Tally(n)
    for r in records:
        tally.add(r)
    joints, stage1_joints = tally.joints, tally.stage1
    write_free_viewpoint_poses(out, FreeViewpointPoses(joints, stage1_joints, np.array(tally.status),
                                                       SKELETON_14.joint_names))
    people = tally.people.write(out)
    if tally.finished == n:
        shutil.rmtree(out / PLATE_STORE, ignore_errors=True)
        shutil.rmtree(out / VIEW_STORE, ignore_errors=True)
        for p in PATHS:
            write_video(out / "paths" / f"{p}.mp4", (read_png(out / "paths" / p / frame_filename(t))
                                                     for t in range(n)), ds.fps)
    metrics = {"frames": n, "finished": tally.finished, **({"people": people} if people else {}),
               "status": dict(tally.statuses), "failed_frames": _failed_frames(tally.status, tally.statuses),
               "optimize": dict(tally.optimize),
               "stage1": stage1,
               "seconds_per_frame": {k: float(np.mean(v)) for k, v in tally.timings.items()} if tally.finished
               else {}}
    if ds.has_groundtruth:
        gt = ds.gt_joints3d()[:n]
        if people and getattr(ds, "people_count", 1) > 1:  # the main person is judged against its true person
            truth = ds.gt_people_joints3d()[:, :n]
            matched = _match_people(np.load(out / "people3d.npz")["joints"], truth)
            people["pose"] = [{"person": name, "true_person": k, **pose_errors(J, truth[k])} if k is not None
                              else {"person": name, "true_person": None}
                              for name, (k, J) in zip(people["names"], matched)]
            if matched[0][0] is not None:
                gt = truth[matched[0][0]]
        metrics.update({"methods": summarise(tally.scores),
                        "pose": pose_errors(joints, gt), "pose_stage1": pose_errors(stage1_joints, gt),
                        "novel_cameras": [c.name for c in novel]})
    if held is not None:
        offs = tally.offsets
        metrics["heldout"] = {"camera": held.name, "methods": summarise(tally.heldout),
                              "region": dict(tally.regions),
                              "region_definition": HELDOUT_REGION_DOC,
                              "offset_px_median": np.median(offs, axis=0).tolist() if offs else None}
    if ds.has_groundtruth or held is not None:
        atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=2, allow_nan=True))
    return metrics


def run(config: FreeViewpointRunConfig, *, dataset, out, observer=None, log=print) -> RunResult:
    """Run the articulated-billboard system on a dataset into ``out``, resuming finished frames.

    Parameters
    ----------
    config : FreeViewpointRunConfig
    dataset : path
        Dataset folder (``docs/dataset_layout.md``).
    out : path
        Output folder (``recipes/free_viewpoint.py`` lists what it holds).
    observer : Observer, optional
        Receives every intermediate; default: a rerun recording in ``out``
        (``config.recording``), one part per resumed run.
    log : callable or None
        Receives notes (calibration refinement, stale folders).

    Returns
    -------
    RunResult
        ``extra`` holds ``stage1`` (where the 2D poses came from), ``held_out``
        (the camera's name or None) and ``has_groundtruth``.

    Raises
    ------
    InputError
        Bad dataset, options, or an output folder of another run.
    """
    import uuid

    from toolkit.calibration import cameras_for_run
    from toolkit.io import Dataset
    from toolkit.pipeline.views import split_rig

    out = Path(out)
    with Dataset.open(dataset) as ds, contextlib.ExitStack() as stack:
        n = ds.frames_to_process(config.max_frames)
        kp_dir, masks_dir = _inputs(ds, config)
        exclude, extra = _identity_exclude(config, kp_dir, masks_dir)
        folder = open_run(out, "free_viewpoint", ds.root, config, n, exclude=exclude, extra=extra,
                          replace_stale=config.replace_stale, recording=config.recording and observer is None,
                          log=log)
        # the workers start (and import) while this process calibrates and loads stage 1
        todo = folder.records.todo()
        cluster = stack.enter_context(Cluster(ParallelConfig(resolve_workers(config.workers, len(todo)),
                                                             config.scheduler) if todo else ParallelConfig(),
                                              _FRAME_MODULES))
        cluster.warm(_warm_imports)
        novel = list(ds.novel_rig) if ds.has_groundtruth and (ds.root / "groundtruth/novel/calibration.toml").exists() \
            else []
        earlier = folder.records.done()
        own = observer is None
        obs = _recording_observer(folder, ds, novel, config) if own else observer
        todo = folder.records.todo()
        if earlier and log is not None:
            log(f"resuming: {len(earlier)} of {n} frames already finished")
        # frames of this same run are finished: continue with its cameras
        full_rig = cameras_for_run(ds, out, refine=config.refine_calibration, resumed=folder.resumed and bool(earlier),
                                   observer=obs, log=log)
        rig, held = (full_rig, None) if config.hold_out is None else split_rig(full_rig, config.hold_out)
        if obs is not None:
            obs.report("rig", rig=rig)
        if config.background == "scene" and todo:
            _scene_model(ds, rig, config, out, ds.frames_to_process(None), log, obs)
        # a resumed run's stage 1 goes through the finished frames again (not reported): its temporal state
        # at the frames to do is then the one an uninterrupted run had
        wanted = set(todo)
        stage1 = _Stage1(ds, rig, config, kp_dir, masks_dir, out, None if obs is None else _Only(obs, wanted), log)
        todo = list(range(todo[-1] + 1)) if todo else []
        task = _FrameTask(uuid.uuid4().hex, ds.root, out, config, rig, tuple(novel), held, n, kp_dir, masks_dir)
        if wanted:
            cluster.warm(task.warm_up)

        def frames():  # stage 1 in frame order (its temporal term, tracking), here, ahead of the workers
            for est, masks in stage1.estimates(todo):
                if est.frame in wanted:
                    yield est, masks, {c: ds.frame(c, est.frame) for c in rig.names}  # decoded by stage 1 already

        try:
            processed, stopped, seconds = run_frames(
                task, frames(), total=len(wanted), parallel=cluster,
                observer=obs, progress=config.progress, desc="free viewpoint")
        finally:
            drop_cached(task.token)
            cluster.close()
            if own and obs is not None:
                obs.close()
        metrics = _finish(ds, out, folder.records.each(), n, novel, held, stage1.name)
        return RunResult(out, n, metrics["finished"], processed, len(earlier), stopped, seconds,  # a finished file only
                         metrics, obs.saved if own and obs is not None else None,
                         {"stage1": stage1.name, "held_out": None if held is None else held.name,
                          "has_groundtruth": bool(ds.has_groundtruth)})


def _failed_frames(status: list, finished: Counter) -> dict:
    """The frames of each status other than "ok" among those finished: ``{status: [t, ...]}``."""
    from toolkit.rendering.freeviewpoint import STATUS_OK

    return {k: [t for t, s in enumerate(status) if s == k] for k in finished if k != STATUS_OK}


def run_failure(result: RunResult) -> str | None:
    """Why a run that went through is a failure: no finished frame has a 3D pose of anybody (None: some
    have, or it stopped early; with several people, a frame where any of them is drawn has one); one
    line, for the recipe's error."""
    from toolkit.rendering.freeviewpoint import STATUS_OK

    status = result.metrics.get("status") or {}
    drawn = (result.metrics.get("people") or {}).get("frames_drawn") or {}
    if result.stopped or not result.finished or status.get(STATUS_OK, 0) or any(drawn.values()):
        return None
    return (f"no frame has a 3D pose ({result.finished} of {result.frames} frames finished): "
            + "; ".join(f"{v} {k}" for k, v in status.items()) + f" (status in {result.out / 'poses3d.npz'})")


def summary_lines(result: RunResult) -> list:
    """What a free-viewpoint run says when it ends (the recipe prints these)."""
    from toolkit.rendering.freeviewpoint import METHODS, STATUS_OK

    m = result.metrics
    shown = METHODS + ("nearest_source",)
    lines = [f"{'stopped early (' + result.stopped + '): ' if result.stopped else ''}{result.finished} of "
             f"{result.frames} frames finished ({result.processed} this run, {result.seconds:.1f} s)"]
    if result.extra.get("has_groundtruth") and result.finished:
        for meth in shown:
            s = m.get("methods", {}).get(meth)
            if s:
                lines.append(f"  {meth:14s} whole frame {s['psnr_frame']:.2f} dB  box PSNR {s['psnr']:.2f} dB  "
                             f"SSIM {s['ssim']:.3f}  on the subject {s['psnr_subject']:.2f} dB  coverage "
                             f"{s['coverage']:.3f} (worst view {s['coverage_min']:.3f})  ({s['n']} views)")
        lines.append(f"  pose error {m['pose']['mpjpe_m'] * 100:.1f} cm (stage 1: {m['pose_stage1']['mpjpe_m'] * 100:.1f} cm)")
    if m.get("people"):
        err = {p["person"]: p.get("mpjpe_m") for p in m["people"].get("pose", [])}
        lines.append("  people: " + ", ".join(
            f"{k} drawn in {v} frames" + (f" ({100 * err[k]:.1f} cm from its true person)" if err.get(k) is not None
                                          else "") for k, v in m["people"]["frames_drawn"].items())
            + " (people3d.npz)")
    h = m.get("heldout")
    if h and result.finished:
        off = h["offset_px_median"]
        lines.append(f"  held-out camera {h['camera']} (its person's region: "
                     + ", ".join(f"{k} {v} frames" for k, v in h["region"].items())
                     + ("; its calibration corrected by a 2D offset of ({:+.1f}, {:+.1f}) px".format(*off)
                        if off else "") + "):")
        for meth in shown:
            s = h["methods"].get(meth)
            if s:
                each = ("  each person " + " / ".join(f"{v:.2f}" for v in s["psnr_people"]) + " dB") \
                    if s.get("psnr_people") else ""
                lines.append(f"  {meth:14s} whole frame {s['psnr_frame']:.2f} dB  on the person "
                             f"{s['psnr_subject']:.2f} dB{each}  box PSNR {s['psnr']:.2f} dB  SSIM {s['ssim']:.3f}  "
                             f"coverage {s['coverage']:.3f}  ({s['n']} frames)")
    failed = {k: v for k, v in (m.get("status") or {}).items() if k != STATUS_OK}
    if failed:  # e.g. a calibration in the wrong convention: joints behind the cameras, frames not drawn
        lines.append("  frames without a result: " + "; ".join(f"{v} {k}" for k, v in failed.items())
                     + " (poses3d.npz status)")
        lines += [f"    frames {frame_ranges(f)} ({k})" for k, f in (m.get("failed_frames") or {}).items()]
    outcome = m.get("optimize") or {}
    if outcome:  # e.g. two cameras far apart: every joint "few_views", stage 3 changed nothing
        total = sum(outcome.values())
        lines.append("  stage 3 joints: " + ", ".join(f"{k} {100 * v / total:.0f} %" for k, v in
                                                      sorted(outcome.items(), key=lambda kv: -kv[1]))
                     + " (docs/stage3_billboards.md: what each means)")
    out = result.out
    if result.recording is None:  # none written, or not finalised: only the finished files are offered
        earlier = any(out.glob("recording*.rrd"))
        lines.append(f"outputs in {out}" + ((f"; every frame was already finished" if not result.processed else "")
                                            + f"; earlier recordings: rerun {out}/recording*.rrd" if earlier
                                            else ""))
        for parts in sorted(out.glob("recording*.parts")):  # a merge that failed: each finished part opens
            lines.append(f"  recording not merged (a warning said why): rerun {parts}/[0-9]*.rrd")
    elif result.recording.name == "recording.rrd":
        lines.append(f"outputs in {out}; recording: rerun {result.recording}"
                     + (f" (frames of this run only: {result.earlier} earlier ones were made without one)"
                        if result.earlier else ""))
    else:  # the parts of a resumed run share one recording id: the viewer merges them
        lines.append(f"outputs in {out}; this run's recording: {result.recording.name}; all of it: "
                     f"rerun {out}/recording*.rrd")
    return lines
