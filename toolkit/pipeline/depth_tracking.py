"""The depth system's run: one sequence of depth frames tracked into a 13-point skeleton (source 001).

:func:`run` is what ``recipes/depth_tracking.py`` calls (its docstring lists
the outputs).  One run is one sequence: the input is opened by
:func:`~toolkit.io.depth_readers.open_depth_input` (a dataset folder with
``depth_camera/`` or a folder of depth frames), every frame goes through
:class:`~toolkit.depth.DepthTracker` (:func:`~toolkit.depth.track_sequence`),
and ``skeleton.npz`` (plus ``metrics.json`` with ground truth) is written at
the end.  Several sequences are several runs, each in its own output folder.

The run is identified like every run of :mod:`toolkit.pipeline.run`
(``OUT/run.json``: the input's frames, camera and background by content, and
the config less its runtime fields), so a folder of another input or other
options is refused (or moved aside with ``replace_stale``); it is not resumed
frame by frame: the tracker carries its state from frame to frame, so a run
always tracks from the first frame and replaces the earlier results.  Ctrl-C
keeps the frames tracked so far (``skeleton.npz`` with ``status``
"interrupted"), but never in place of a complete run's results (nor its
recording: :func:`~toolkit.pipeline.run.close_run_recording`); an unreadable
frame is tracked as a frame without depth and named (``unreadable``); a rerun
of fewer frames (``max_frames``) than a complete ``skeleton.npz`` holds is
refused.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from toolkit.depth.tracker_state import TrackerConfig
from toolkit.errors import InputError
from toolkit.pipeline.parallel import ParallelConfig, map_tasks
from toolkit.pipeline.run import (STOPPED_INTERRUPTED, RunResult, check_frames_held, close_run_recording,
                                  deferred_interrupts, open_run, terminate_as_interrupt)

#: Depth file readers (``"auto"``: by suffix).
READERS = ("auto", "png", "raw", "open3d", "npy")
#: Frames per part of the recording (a killed run's finished parts open: docs/parallel.md).
RECORDING_PART_FRAMES = 30


@dataclass(frozen=True)
class DepthTrackingRunConfig:
    """Options of a depth-tracking run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    tracker : TrackerConfig
        The tracker (``[tracker]`` table in TOML, nested ``[tracker.orus]`` ...;
        the recipe's ``--fps``, ``--output`` and ``--bin-size`` set ``fps``,
        ``output`` and ``orus.bin_size_m``).
    size : tuple of int, optional
        Image size (W, H) of raw frames and of the default camera (default 640 x 480).
    focal : float, optional
        Focal length in pixels of the default camera.
    intrinsics : Path, optional
        ``intrinsics.toml`` for a folder of frames.
    reader : str
        One of :data:`READERS`.
    background : Path, optional
        Depth file of the empty scene.
    independent : bool
        Track each frame on its own (unrelated still frames).
    seed : int
        Seed of the key-point clustering.
    max_frames : int, optional
        Track at most this many frames (the first ones).
    images : Path, optional
        Write the skeleton over each depth frame into this folder.
    recording : bool
        Write ``recording.rrd``.
    replace_stale : bool
        Move another run's results aside instead of refusing them.
    progress : bool
        Show a progress bar.
    workers : int
        Several sequences (:func:`run_sequences`) in parallel on a local Dask
        cluster of this many worker processes (1: one after the other, here).
    scheduler : str, optional
        Several sequences on a running Dask cluster, ``tcp://HOST:PORT``.
    """

    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    size: tuple[int, int] | None = None
    focal: float | None = None
    intrinsics: Path | None = None
    reader: str = "auto"
    background: Path | None = None
    independent: bool = False
    seed: int = 0
    max_frames: int | None = None
    images: Path | None = None
    recording: bool = True
    replace_stale: bool = False
    progress: bool = True
    workers: int = 1
    scheduler: str | None = None

    #: Fields that do not change the results (left out of the run identity).
    RUNTIME = ("max_frames", "images", "recording", "replace_stale", "progress", "workers", "scheduler")

    def __post_init__(self):
        if self.reader not in READERS:
            raise InputError("DepthTrackingRunConfig.reader (--reader)", f"one of {READERS}", repr(self.reader))
        if self.size is not None and (len(self.size) != 2 or min(int(s) for s in self.size) < 1):
            raise InputError("DepthTrackingRunConfig.size (--size)", "two positive integers W H", repr(self.size))
        if self.max_frames is not None and int(self.max_frames) < 0:
            raise InputError("DepthTrackingRunConfig.max_frames (--frames)", "a number of frames >= 0",
                             repr(self.max_frames))
        ParallelConfig(self.workers, self.scheduler)  # checked


def input_identity(inp) -> dict:
    """What a depth input's results depend on: its frame files, camera and background, by content.

    Parameters
    ----------
    inp : DepthInput

    Returns
    -------
    dict
        ``frames`` (SHA-256 over every frame file's name and content), ``camera``
        (K, size, ``cam_from_world``, whether the pose is known), ``background``
        (SHA-256 of the array, or None), ``kind``.
    """
    from toolkit.io.runs import file_fingerprint

    h = hashlib.sha256()
    for p in inp.frames:
        h.update(Path(p).name.encode())
        h.update(file_fingerprint(p).encode())
    cam = inp.camera
    bg = None if inp.background is None else hashlib.sha256(np.ascontiguousarray(inp.background).tobytes()).hexdigest()
    return {"kind": inp.kind, "frames": h.hexdigest(), "n_frames": len(inp.frames), "background": bg,
            "camera": {"K": np.asarray(cam.K).tolist(), "size": list(cam.size),
                       "cam_from_world": np.asarray(cam.cam_from_world).tolist(), "pose_known": bool(inp.pose_known)},
            "reader": inp.reader, "raw_size": list(inp.size), "units_per_metre": float(inp.units_per_metre)}


class _Images:
    """The skeleton drawn over each depth frame (``config.images``), in the input's frame order."""

    def __init__(self, folder: Path | None, inp, tracker):
        self.folder, self.inp, self.tracker, self.depths = folder, inp, tracker, {}

    def keep(self, i: int, depth: np.ndarray) -> None:
        if self.folder is not None:
            self.depths[i] = depth

    def draw(self, r) -> None:
        from toolkit.depth.evaluate import draw_skeleton
        from toolkit.io import atomic_write_png

        if self.folder is None:
            return
        d = self.depths.pop(r.index)
        uv = self.tracker.frame.project(r.joints_view)
        lo, hi = np.nanpercentile(d, [1, 99]) if np.isfinite(d).any() else (0.5, 4.5)
        img = draw_skeleton(d, uv, r.observed, f"{self.inp.frames[r.index].name} {r.state_name}", scale=0.5,
                            depth_range=(float(lo), float(hi) + 0.3))
        atomic_write_png(Path(self.folder) / f"skeleton_{r.index:03d}.png", img)  # frame order of the input


@dataclass
class _Tracked:
    """What :func:`_track` got through: the frames tracked, those unreadable, and whether Ctrl-C stopped it."""

    result: object
    unreadable: list
    interrupted: bool


def _track(config: DepthTrackingRunConfig, inp, n: int, observer, log) -> _Tracked:
    """Track the first ``n`` frames of ``inp``; keep what was tracked when Ctrl-C stops it.

    A frame that cannot be read (a damaged file) is tracked as a frame
    without any reading (the tracker loses the person there and recovers
    after), named in a warning and in ``unreadable``; it does not end the run.
    """
    from tqdm import tqdm

    from toolkit.depth import STATE_NAMES, DepthTracker, track_sequence
    from toolkit.depth.tracker import TrackResult

    tracker = DepthTracker(inp.camera, inp.pose_known, config.tracker, background=inp.background, rng=config.seed,
                           observer=observer)
    images = _Images(config.images, inp, tracker)
    bar = tqdm(total=n, unit="frame", disable=not config.progress)
    done, unreadable = [], []
    w, h = inp.camera.size

    def frames():
        for i in range(n):
            try:
                d = inp.read(i)
            except InputError as e:
                unreadable.append(i)
                log(f"warning: frame {i} unreadable, tracked as a frame without depth: {e}")
                d = np.full((h, w), np.nan, np.float32)
            images.keep(i, d)
            yield d

    checkpoint = getattr(observer, "checkpoint", None)

    def step(r):
        done.append(r)
        bar.update(1)
        if callable(checkpoint) and (r.index + 1) % RECORDING_PART_FRAMES == 0:
            checkpoint()
        bar.set_postfix(state=STATE_NAMES[r.state])
        images.draw(r)

    try:
        with terminate_as_interrupt():
            res = track_sequence(tracker, frames(), independent=config.independent, progress=step)
        interrupted = False
    except KeyboardInterrupt:
        res = TrackResult(done, config.tracker.output if tracker.frame.pose_known else "camera")
        interrupted = True
    finally:
        bar.close()
    if n and len(unreadable) == n:
        raise InputError(str(Path(inp.frames[0]).parent), "at least one readable depth frame",
                         f"{n} unreadable frames (the first: {inp.frames[0].name})")
    return _Tracked(res, unreadable, interrupted)


def _held(out: Path) -> tuple[int, str]:
    """Frames of the ``skeleton.npz`` an earlier run left in ``out`` and its status (0, "" when none)."""
    f = out / "skeleton.npz"
    if not f.is_file():
        return 0, ""
    try:
        with np.load(f, allow_pickle=False) as z:
            return len(z["frames"]), str(z["status"]) if "status" in z.files else "complete"
    except (OSError, ValueError, KeyError):
        return 0, ""


def _write(out: Path, tracked: _Tracked, inp) -> dict | None:
    """``skeleton.npz`` and, with ground truth in world coordinates, ``metrics.json`` (returned)."""
    from toolkit.depth import STATE_NAMES
    from toolkit.depth.evaluate import summarise
    from toolkit.io import atomic_save_npz, atomic_write_text
    from toolkit.skeleton import SKELETON_13

    res = tracked.result
    n = len(res.frames)
    unreadable = np.zeros(n, bool)
    unreadable[[i for i in tracked.unreadable if i < n]] = True
    atomic_save_npz(out / "skeleton.npz", joints=res.joints, names=np.array(SKELETON_13.joint_names),
                    state=res.states, state_names=np.array(STATE_NAMES), observed=res.observed,
                    explained=res.explained, supported=res.supported, reason=res.reasons,
                    frames=np.array([p.name for p in inp.frames[:n]]), coordinates=np.array(res.coordinates),
                    unreadable=unreadable, status=np.array("interrupted" if tracked.interrupted else "complete"))
    if inp.truth is None or res.coordinates != "world":
        return None
    s = summarise(res.joints, inp.truth["joints"][:n], res.states,
                  inp.truth["visible"][:n] if "visible" in inp.truth else None)
    metrics = {"mpjpe_mm": 1000 * s.mpjpe_m, "mpjpe_visible_mm": 1000 * s.mpjpe_visible_m,
               "mpjpe_unoccluded_mm": 1000 * s.mpjpe_unoccluded_m, "tracked_share": s.tracked_share,
               "estimated_share": s.estimated_share, "frames": s.n_frames,
               "status": "interrupted" if tracked.interrupted else "complete",
               "per_point_mm": {k: 1000 * float(v) for k, v in zip(SKELETON_13.joint_names, s.per_point_m)}}
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=2) + "\n")
    return metrics


def _earlier_recording(out: Path, kept: bool) -> Path | None:
    """The recording of the complete results an interrupted run kept (None: none, or results replaced)."""
    path = out / "recording.rrd"
    return path if kept and path.is_file() else None


def _recording(out: Path, recording_id: str):
    from toolkit.viz import RerunObserver

    return RerunObserver(application_id="depth_tracking", path=out / "recording.rrd", recording_id=recording_id,
                         parts=True)


def run(config: DepthTrackingRunConfig, *, dataset, out, observer=None, log=print) -> RunResult:
    """Track one sequence of depth frames into ``out``.

    Parameters
    ----------
    config : DepthTrackingRunConfig
    dataset : path
        A dataset folder with ``depth_camera/``, or a folder of depth frames.
    out : path
        Output folder (``recipes/depth_tracking.py`` lists what it holds).
    observer : Observer, optional
        Receives every intermediate; default: ``OUT/recording.rrd`` (``config.recording``).
    log : callable or None
        Receives notes (a stale folder moved aside).

    Returns
    -------
    RunResult
        ``metrics``: ``states`` (frames per state name), ``cpu_ms_median`` and,
        with ground truth, the scores of ``metrics.json``; ``extra``: ``input``,
        ``kind``, ``size``, ``coordinates``, ``skeleton`` (the file), ``images``.

    Raises
    ------
    InputError
        Bad input or options, or an output folder of another run.
    """
    from toolkit.depth import STATE_NAMES
    from toolkit.io.runs import run_recording

    out = Path(out)
    log = log or (lambda *_: None)
    inp = _open(config, dataset)
    n = len(inp) if config.max_frames is None else min(len(inp), max(int(config.max_frames), 0))
    folder = open_run(out, "depth_tracking", dataset, config, n, exclude=DepthTrackingRunConfig.RUNTIME,
                      extra={"input": input_identity(inp)}, replace_stale=config.replace_stale, recording=False,
                      log=log)
    held, held_status = _held(out) if folder.resumed else (0, "")
    if held_status == "complete":
        check_frames_held(out, n, held, what="a complete skeleton.npz")
    own = observer is None and config.recording
    obs = _recording(out, run_recording(out, False)[1]) if own else observer
    t0 = time.perf_counter()
    tracked = recording = None
    try:
        tracked = _track(config, inp, n, obs, log)
    finally:
        if own:  # the recording replaces the earlier one only together with the results it shows
            recording = close_run_recording(obs, out, keep=held_status != "complete" or (
                tracked is not None and not tracked.interrupted))
    wall = time.perf_counter() - t0
    res, done = tracked.result, len(tracked.result.frames)
    keep = tracked.interrupted and held_status == "complete"  # never replace complete results by partial ones
    if keep:
        log(f"{out}: interrupted after {done} of {n} frames; the complete results of the earlier run are kept")
    if keep:
        scores = None
    else:
        with deferred_interrupts():  # skeleton.npz and metrics.json together: a stop never leaves one old
            scores = _write(out, tracked, inp)
    metrics = {"states": {name: int((res.states == k).sum()) for k, name in enumerate(STATE_NAMES)},
               "cpu_ms_median": float(np.nanmedian(res.timings("total")) * 1000) if done else float("nan"),
               "lost_reasons": _lost_reasons(res),
               "unreadable_frames": [inp.frames[i].name for i in tracked.unreadable], **(scores or {})}
    return RunResult(out, n, done, done, 0, STOPPED_INTERRUPTED if tracked.interrupted else "", wall, metrics,
                     recording if recording is not None else _earlier_recording(out, keep),
                     {"input": str(dataset), "kind": inp.kind, "size": tuple(inp.camera.size),
                      "coordinates": res.coordinates, "skeleton": out / "skeleton.npz", "images": config.images,
                      "has_groundtruth": scores is not None})


def _lost_reasons(res) -> dict:
    """Frames without joints (lost) per reason, most frequent first (``"no person: a flat surface"``: 8)."""
    from collections import Counter

    from toolkit.depth import LOST

    return dict(Counter(r for r, s in zip(res.reasons.tolist(), res.states.tolist()) if s == LOST).most_common())


def _lost_line(reasons: dict) -> str | None:
    """The summary's line on the frames without joints, or None when there are none."""
    if not reasons:
        return None
    said = [f"{k} frames without a person ({r.removeprefix('no person: ')})" if r.startswith("no person: ")
            else f"{k} frames lost ({r})" for r, k in reasons.items()]
    return f"  no joints written for {sum(reasons.values())} frames: " + ", ".join(said)


def _one_sequence(config: DepthTrackingRunConfig, dataset: Path, out: Path) -> RunResult:
    """One sequence of :func:`run_sequences` (a task), without progress bar or notes."""
    return run(replace(config, progress=False, workers=1, scheduler=None), dataset=dataset, out=out, log=None)


def run_sequences(config: DepthTrackingRunConfig, *, datasets, out, log=print) -> list:
    """Track several sequences, each into ``out/<its folder's name>/``, in parallel where asked.

    Parameters
    ----------
    config : DepthTrackingRunConfig
        ``workers`` / ``scheduler`` say where the sequences run
        (:mod:`toolkit.pipeline.parallel`); each one is a :func:`run` of its own,
        with its own ``run.json`` and recording.
    datasets : sequence of path
        Inputs of :func:`run`; their folder names must differ.
    out : path
        Parent folder of the sequences' output folders.
    log : callable or None
        Receives one line per sequence as it finishes (in the inputs' order).

    Returns
    -------
    list of RunResult
        In the inputs' order.

    Raises
    ------
    InputError
        Two inputs of the same name, or a sequence's own error (bad input, stale folder).
    """
    datasets = [Path(d) for d in datasets]
    names = [d.resolve().name for d in datasets]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError("inputs", "sequences in folders of different names (each gets OUT/<name>/)",
                         f"{twice} given more than once")
    results: list = []

    def done(i: int, r: RunResult) -> None:
        results.append(r)
        if log is not None:
            log(f"[{i + 1}/{len(datasets)}] {names[i]}: {r.frames} frames in {r.seconds:.1f} s -> {r.out}")

    map_tasks(_one_sequence, ((config, d, Path(out) / n) for d, n in zip(datasets, names)),
              parallel=ParallelConfig(config.workers, config.scheduler), on_result=done, total=len(datasets),
              progress=config.progress, desc="sequences", unit="sequence")
    return results


def _open(config: DepthTrackingRunConfig, dataset):
    from toolkit.io.depth_readers import open_depth_input

    return open_depth_input(dataset, size=config.size, focal_px=config.focal, intrinsics=config.intrinsics,
                            reader=config.reader, background=config.background)


def summary_lines(result: RunResult) -> list:
    """What a depth-tracking run says when it ends (the recipe prints these)."""
    m, x, out = result.metrics, result.extra, result.out
    w, h = x["size"]
    lines = [f"tracked {result.processed} frames of {x['input']} ({x['kind']}, {w}x{h}) in {result.seconds:.1f} s: "
             + ", ".join(f"{v} {k}" for k, v in m["states"].items())
             + f"; median {m['cpu_ms_median']:.1f} ms CPU per frame",
             f"  skeleton ({x['coordinates']} coordinates): {x['skeleton']}"]
    if _lost_line(m.get("lost_reasons", {})):
        lines.append(_lost_line(m["lost_reasons"]))
    if result.stopped:
        lines.append(f"  {result.stopped}: {result.processed} of {result.frames} frames tracked (Ctrl-C)")
    if m.get("unreadable_frames"):
        lines.append(f"  warning: {len(m['unreadable_frames'])} unreadable frames tracked as frames without depth: "
                     + ", ".join(m["unreadable_frames"][:5]) + (" ..." if len(m["unreadable_frames"]) > 5 else ""))
    if result.recording is not None:
        lines.append(f"  recording:                  {result.recording}  (open with: rerun {result.recording})")
    if x["has_groundtruth"]:
        lines.append(f"  metrics:                    {out / 'metrics.json'}  (MPJPE {m['mpjpe_mm']:.1f} mm, "
                     f"{100 * m['tracked_share']:.0f} % of frames tracked)")
    if x["images"] is not None:
        lines.append(f"  images:                     {x['images']}/")
    return lines
