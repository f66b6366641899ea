"""Stage 3 as a run: 3D joints optimised by the billboard position score, frame by frame, resumable.

:func:`run` is what ``recipes/optimize_joints.py`` calls (its docstring lists
the inputs and outputs).  Per frame: the start (stage 1's joints, or the
ground truth displaced by seeded noise), the source images, the part labels
and depth (a stage-2 run's files, or ground truth) -> the stage-3 chain
(:func:`toolkit.pipeline.stage3.optimize_frame`) -> one record per frame in
``OUT/frames/``; at the end ``joints3d.npz`` and, with ground truth,
``metrics.json``.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.optimize import OptimizeConfig
from toolkit.pipeline.parallel import ParallelConfig, drop_cached, worker_cache
from toolkit.pipeline.run import FrameRecords, RunResult, open_run, run_frames

#: ``joints3d.npz`` ``status`` of a frame without a finite start.
NO_START = "no initial joints"
#: ... of a frame the run did not reach (stopped early).
NOT_PROCESSED = "not processed"


@dataclass(frozen=True)
class OptimizeJointsConfig:
    """Options of a stage-3 run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    optimize : OptimizeConfig
        The joint search (an ``[optimize]`` table in TOML; ``--sweeps`` is its ``max_sweeps``).
    poses : Path, optional
        Stage-1 output folder (``poses3d.npz``, ``offsets.npz``, ``calibration.toml``);
        without it the ground-truth joints displaced by ``noise_cm`` are the start.
    parts : Path, optional
        Stage-2 output folder (``parts/``, ``depth/``); without it the ground-truth labels and depth.
    noise_cm : float
        Without ``poses``: RMS 3D displacement of the ground-truth start, cm.
    seed : int
        Seed of that displacement.
    seams : bool
        Seams from the depth maps (False: none).
    max_frames : int, optional
        Only the first N frames.
    recording : bool
        Write ``recording.rrd``.
    replace_stale : bool
        Move another run's results aside instead of refusing them.
    workers : int
        Frames at once, each a task on a local Dask cluster of this many worker
        processes (1: in this process; ``docs/parallel.md``).  Frames are
        independent here (no state carried from one frame to the next), so the
        outputs are those of one worker.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://HOST:PORT``) to run the frames on.
    progress : bool
        A progress bar over the frames.
    """

    optimize: OptimizeConfig = field(default_factory=OptimizeConfig)
    poses: Path | None = None
    parts: Path | None = None
    noise_cm: float = 0.0
    seed: int = 0
    seams: bool = True
    max_frames: int | None = None
    recording: bool = True
    replace_stale: bool = False
    workers: int = 1
    scheduler: str | None = None
    progress: bool = False

    #: Fields that do not change the results (left out of the run identity).
    RUNTIME = ("max_frames", "recording", "replace_stale", "workers", "scheduler", "progress")

    def __post_init__(self):
        if not (np.isfinite(self.noise_cm) and self.noise_cm >= 0):
            raise InputError("OptimizeJointsConfig.noise_cm", "a non-negative distance in cm", repr(self.noise_cm))
        if self.max_frames is not None and int(self.max_frames) < 1:
            raise InputError("OptimizeJointsConfig.max_frames", "a positive number of frames", repr(self.max_frames))
        ParallelConfig(self.workers, self.scheduler)  # checked


@dataclass(frozen=True, eq=False)
class _Start:
    """Where the run starts: joints (T, 14, 3), the cameras, each frame's cameras (t -> Rig, corrected
    by stage 1's offsets), what it is."""

    joints: np.ndarray
    rig: object
    cameras: Callable
    source: str


def _start(ds, config: OptimizeJointsConfig, n: int) -> _Start:
    from toolkit.pipeline.stage_inputs import read_stage1

    if config.poses is not None:
        s1 = read_stage1(ds, config.poses)  # the cameras stage 1 used (refined on field lines or measured)
        start = _Start(s1.joints, s1.rig, s1.cameras, f"stage 1 ({config.poses})")
    elif not ds.has_groundtruth:
        raise InputError("--poses", "a stage-1 output folder (the dataset has no ground truth)", "none")
    else:
        gt = ds.gt_joints3d()
        rng = np.random.default_rng(config.seed)
        init = gt + rng.normal(0.0, config.noise_cm / 100.0 / np.sqrt(3.0), gt.shape)
        start = _Start(init, ds.rig, lambda t: ds.rig, f"ground truth + {config.noise_cm:g} cm noise")
    if start.joints.shape[1:] != (14, 3) or start.joints.shape[0] < n:
        raise InputError("initial joints", f"(>= {n}, 14, 3)", f"shape {start.joints.shape}")
    if config.parts is None and not ds.has_groundtruth:
        raise InputError("--parts", "a stage-2 output folder (the dataset has no ground-truth parts)", "none")
    return start


def _labels_and_depth(ds, config: OptimizeJointsConfig, t: int) -> tuple[dict, dict]:
    """Part labels and depth maps of frame ``t`` per camera (a stage-2 run's files, or ground truth)."""
    from toolkit.io import frame_filename, mm_to_depth, read_png

    labels, depth = {}, {}
    for c in ds.camera_names:
        if config.parts is not None:
            parts = Path(config.parts)
            labels[c] = read_png(parts / "parts" / c / frame_filename(t), channels=1, dtype=np.uint8)
            dp = parts / "depth" / c / frame_filename(t)
            if dp.exists():
                depth[c] = mm_to_depth(read_png(dp, channels=1, dtype=np.uint16))
        else:
            labels[c] = ds.gt_parts(c, t)
            depth[c] = ds.gt_depth(c, t)
    return labels, depth


@dataclass(frozen=True)
class _FrameTask:
    """One frame of the run as a task (picklable: a Dask worker opens the dataset itself, once per run).

    ``task(t, J0, cameras, observer=None)``: the stage-3 chain of frame ``t``
    from ``J0`` (14, 3) m with that frame's cameras (a Rig), its record written
    into ``out`` (``frames/NNNNNN.json``, the frame is then finished).  Nothing
    is carried from one frame to the next (the constraints are fixed, the
    search borrows nothing), so frames run in any order and on any worker.
    """

    token: str
    dataset: Path
    out: Path
    n: int
    config: OptimizeJointsConfig

    def __call__(self, t: int, J0: np.ndarray, cameras, observer=None) -> None:
        FrameRecords(self.out, self.n).write(t, self._record(t, J0, cameras, observer))

    def warm(self):
        """This process's dataset of the run (opened on first use)."""
        from toolkit.io import Dataset

        return worker_cache(self.token, lambda: Dataset.open(self.dataset))

    def _record(self, t: int, J0: np.ndarray, cameras, observer) -> dict:
        from toolkit.anthropometry import AnthropometricConstraints
        from toolkit.pipeline.stage3 import optimize_frame
        from toolkit.skeleton import SKELETON_14

        if not np.all(np.isfinite(J0)):
            return {"frame": t, "status": NO_START}
        ds = self.warm()
        images = {c: ds.frame(c, t) for c in ds.camera_names}
        labels, depth = _labels_and_depth(ds, self.config, t)
        if observer is not None:
            observer.report("joints3d", name="optimize/initial", joints=J0, skeleton=SKELETON_14, frame=t)
        res = optimize_frame(images, labels, cameras, J0, depths=depth if self.config.seams else None,
                             constraints=AnthropometricConstraints(),
                             config=self.config.optimize, billboards=1 if observer is not None else None,
                             borrow=False, observer=observer, frame=t)
        s = res.search
        return {"frame": t, "status": "converged" if s.converged else "max sweeps", "joints": s.joints.tolist(),
                "scores": s.scores[-1].tolist(), "n_evaluations": int(s.n_evaluations), "seconds": float(s.seconds),
                "n_sweeps": int(s.n_sweeps), "outcome": res.outcome}


def _line(record: dict, start: _Start, gt) -> str:
    """A finished frame's log line."""
    from toolkit.skeleton import mpjpe

    t = record["frame"]
    if "joints" not in record:
        return f"frame {t}: no initial joints, skipped"
    line = (f"frame {t}: {record['n_sweeps']} sweeps, {record['n_evaluations']} evaluations, "
            f"{record['seconds']:.1f} s; joints " + ", ".join(f"{k} {v}" for k, v in sorted(record["outcome"].items())))
    if gt is not None:
        line += (f", MPJPE {mpjpe(start.joints[t], gt[t]) * 100:.1f} -> "
                 f"{mpjpe(np.asarray(record['joints']), gt[t]) * 100:.1f} cm")
    return line


def _finish(out: Path, records: list, n: int, start: _Start, gt, config: OptimizeJointsConfig) -> dict:
    """``joints3d.npz`` of every finished frame and, with ground truth, ``metrics.json``; the metrics."""
    from toolkit.io import atomic_save_npz, atomic_write_text
    from toolkit.skeleton import SKELETON_14, mpjpe

    joints, scores = np.full((n, 14, 3), np.nan), np.full((n, 14), np.nan)
    n_eval, secs, status = np.zeros(n, int), np.zeros(n), [NOT_PROCESSED] * n
    outcome = Counter()  # how the search ended per joint, summed over frames (PoseResult.outcome_counts)
    for r in (r for r in records if r["frame"] < n):
        t = r["frame"]
        status[t] = r["status"]
        if "joints" in r:
            joints[t], scores[t], n_eval[t], secs[t] = r["joints"], r["scores"], r["n_evaluations"], r["seconds"]
            outcome.update(r["outcome"])
    init = start.joints[:n]
    atomic_save_npz(out / "joints3d.npz", joints=joints, initial=init, scores=scores, n_evaluations=n_eval,
                    seconds=secs, status=np.array(status), names=np.array(SKELETON_14.joint_names))
    if gt is None:
        return {}
    ok = np.all(np.isfinite(joints), axis=(1, 2))
    metrics = {"start": start.source, "frames": int(ok.sum()),
               "mpjpe_before_m": mpjpe(init[ok], gt[:n][ok]) if ok.any() else None,
               "mpjpe_after_m": mpjpe(joints[ok], gt[:n][ok]) if ok.any() else None,
               "evaluations_per_frame": float(n_eval[ok].mean()) if ok.any() else None,
               "seconds_per_frame": float(secs[ok].mean()) if ok.any() else None,
               "part_labels": "stage 2" if config.parts else "ground truth", "joint_outcomes": dict(outcome)}
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=2) + "\n")
    return metrics


def run(config: OptimizeJointsConfig, *, dataset, out, observer=None, log=print) -> RunResult:
    """Optimise the 3D joints of a dataset's frames by the position score into ``out``, resuming finished frames.

    Parameters
    ----------
    config : OptimizeJointsConfig
    dataset : path
        Dataset folder (``docs/dataset_layout.md``).
    out : path
        Output folder (``recipes/optimize_joints.py`` lists what it holds).
    observer : Observer, optional
        Receives every intermediate (and the stage-3 billboards); default: a
        rerun recording in ``out`` (``config.recording``), one part per resumed run.
    log : callable or None
        Receives the start, and one line per frame.

    Returns
    -------
    RunResult
        ``metrics``: those of ``metrics.json`` (empty without ground truth);
        ``extra``: ``start`` (where the start came from).

    Raises
    ------
    InputError
        Bad dataset, options, input folders, or an output folder of another run.
    """
    import uuid

    from toolkit.io import Dataset

    log = log or (lambda *_: None)
    out = Path(out)
    with Dataset.open(dataset) as ds:
        n = ds.frames_to_process(config.max_frames)
        gt = ds.gt_joints3d() if ds.has_groundtruth else None
        start = _start(ds, config, n)
        log(f"start: {start.source}; part labels: "
            f"{'stage 2 (' + str(config.parts) + ')' if config.parts else 'ground truth (no --parts given)'}")
        extra = {k: None if getattr(config, k) is None else str(Path(getattr(config, k)).resolve())
                 for k in ("poses", "parts")}
        folder = open_run(out, "optimize_joints", ds.root, config, n,
                          exclude=OptimizeJointsConfig.RUNTIME + ("poses", "parts"), extra=extra,
                          replace_stale=config.replace_stale, recording=config.recording and observer is None,
                          log=log)
        own = observer is None
        obs = observer
        if own and folder.recording is not None:
            from toolkit.skeleton import SKELETON_14
            from toolkit.viz import RerunObserver

            # in parts, one per frame: a run killed outright leaves the finished frames' recording complete
            obs = RerunObserver(application_id="optimize_joints", path=folder.recording,
                                recording_id=folder.recording_id, camera_names=ds.camera_names, parts=True)
            obs.report("rig", rig=start.rig)
            obs.report("skeleton", skeleton=SKELETON_14)
        todo = folder.records.todo()
        task = _FrameTask(uuid.uuid4().hex, ds.root, out, n, config)

        def logged(i: int) -> None:
            log(_line(json.loads(folder.records.path(todo[i]).read_text(encoding="utf-8")), start, gt))

        try:
            processed, stopped, seconds = run_frames(
                task, ((t, start.joints[t], start.cameras(t)) for t in todo), total=len(todo),
                parallel=ParallelConfig(config.workers, config.scheduler), observer=obs, progress=config.progress,
                desc="optimize joints", on_frame=logged)
        finally:
            drop_cached(task.token)
            if own and obs is not None:
                obs.close()
        records = folder.records.read_all()
        metrics = _finish(out, records, n, start, gt, config)
    return RunResult(out, n, len(records), processed, n - len(todo), stopped, seconds, metrics,
                     obs.saved if own and obs is not None else None, {"start": start.source})


def summary_lines(result: RunResult) -> list:
    """What a stage-3 run says when it ends (the recipe prints these)."""
    m = result.metrics
    lines = []
    if m.get("mpjpe_before_m") is not None:
        lines.append(f"MPJPE {m['mpjpe_before_m'] * 100:.1f} -> {m['mpjpe_after_m'] * 100:.1f} cm over "
                     f"{m['frames']} frame(s)")
    lines.append(f"{'stopped early (' + result.stopped + '): ' if result.stopped else ''}{result.processed} "
                 f"frame(s) in {result.seconds:.1f} s"
                 + (f" ({result.earlier} already finished)" if result.earlier else "")
                 + f"; joints: {result.out / 'joints3d.npz'}")
    if result.recording is not None:
        lines.append(f"  recording: {result.recording}   (open with: rerun {result.recording})")
    return lines
