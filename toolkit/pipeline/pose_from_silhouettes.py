"""Stage 1 from silhouettes as a run: 2D poses, 3D joints and offsets of a whole dataset.

:func:`run` is what ``recipes/pose_from_silhouettes.py`` calls (its docstring
lists the outputs).  Per frame: foreground silhouettes per camera -> the k
best database silhouettes per view -> multi-view selection with per-view 2D
offsets (:func:`toolkit.silhouettes.pipeline.estimate_dataset`).  The stacked
arrays are written every :data:`CHECKPOINT_FRAMES` frames and when the run
ends, also when Ctrl-C or SIGTERM stops it early, except over the complete
results of an earlier run (:func:`_held`), which stay, with their recording,
until a run has estimated every frame (:func:`~toolkit.pipeline.run.whole_run`).

The run is identified (``OUT/run.json``: the dataset, the config less its
runtime fields, the database, the edits' content) like every run of
:mod:`toolkit.pipeline.run`, so an output folder of other options is never
overwritten; but it is not resumed frame by frame: the temporal term ties each
frame to the one before, so a run always goes through the frames from the
first one.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.io.stage_outputs import STAGE1_FILES, Stage1Output
from toolkit.pipeline.run import RunResult, check_frames_held, open_run, whole_run
from toolkit.silhouettes.estimate import Stage1Config

#: Frames between two writes of the partial results.
CHECKPOINT_FRAMES = 50
#: Background models of the foreground stage, and chroma keying.
FOREGROUNDS = ("median", "mog2", "knn", "chroma")
#: The files written, ``OUT/<name>.npz`` (:func:`toolkit.io.stage_outputs.write_stage1`).
OUTPUTS = tuple(f.removesuffix(".npz") for f in STAGE1_FILES)


@dataclass(frozen=True)
class PoseFromSilhouettesConfig:
    """Options of a stage-1 run from silhouettes (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    stage1 : Stage1Config
        The estimator (``[stage1]``, ``[stage1.query]`` tables in TOML: k,
        metric, flow weight, ...).  Its offset priors of refined cameras are
        set by the run.
    db : Path, optional
        Silhouette database ``.npz``, built there if missing (default: the cached default database).
    edits : Path, optional
        Joint corrections (``.toml`` or ``.json``, docs/correction.md).
    foreground : str
        One of :data:`FOREGROUNDS`.
    plates : Path, optional
        Folder of clean plates ``<camera>.png`` to learn the backgrounds from (default: each video).
    check_sizes : bool
        Refuse videos whose size differs from the calibration.
    refine_calibration : bool
        Refine the cameras on the dataset's field lines.
    max_frames : int, optional
        Only the first N frames.
    log_images : bool
        Put the camera images into the recording.
    recording : bool
        Write ``recording.rrd``.
    replace_stale : bool
        Move another run's results aside instead of refusing them.
    progress : bool
        Show a progress bar.
    """

    stage1: Stage1Config = field(default_factory=Stage1Config)
    db: Path | None = None
    edits: Path | None = None
    foreground: str = "median"
    plates: Path | None = None
    check_sizes: bool = True
    refine_calibration: bool = True
    max_frames: int | None = None
    log_images: bool = True
    recording: bool = True
    replace_stale: bool = False
    progress: bool = True

    #: Fields that do not change the results (left out of the run identity).
    RUNTIME = ("max_frames", "log_images", "recording", "replace_stale", "progress")

    def __post_init__(self):
        if self.foreground not in FOREGROUNDS:
            raise InputError("PoseFromSilhouettesConfig.foreground", f"one of {FOREGROUNDS}", repr(self.foreground))
        if self.max_frames is not None and int(self.max_frames) < 1:
            raise InputError("PoseFromSilhouettesConfig.max_frames", "a positive number of frames",
                             repr(self.max_frames))


def _database(config: PoseFromSilhouettesConfig, log):
    """The silhouette database (built once when missing) and its file; an empty one is refused."""
    from toolkit.silhouettes import SilhouetteDatabase, default_database, default_database_path

    path = Path(config.db) if config.db is not None else default_database_path()
    if path.exists():
        db = SilhouetteDatabase.load(path)
        log(f"silhouette database: {path} ({len(db)} entries)")
    else:
        log(f"building the silhouette database into {path} (once, about a minute) ...")
        t0 = time.perf_counter()
        db, path = default_database(path)
        log(f"silhouette database: {path} ({len(db)} entries, built in {time.perf_counter() - t0:.0f} s)")
    if len(db) == 0:
        raise InputError(str(path), "a silhouette database with at least one entry", "an empty database")
    return db, path


def _identity(config: PoseFromSilhouettesConfig, db_path: Path) -> tuple[tuple, dict]:
    """Config fields left out of the identity, and what stands for them (files by name and content)."""
    from toolkit.io.runs import file_fingerprint
    from toolkit.silhouettes import default_database_path

    extra = {"db": default_database_path().name if config.db is None else str(db_path.resolve()),
             "edits": None if config.edits is None else
             {"file": str(Path(config.edits).resolve()), "content": file_fingerprint(config.edits)},
             "plates": None if config.plates is None else str(Path(config.plates).resolve())}
    return PoseFromSilhouettesConfig.RUNTIME + ("db", "edits", "plates"), extra


def _held(out: Path) -> tuple[int, bool]:
    """Frames of the stage-1 results an earlier run left in ``out``, and whether every one was estimated
    ((0, False) when none or unreadable)."""
    import numpy as np

    from toolkit.silhouettes.pipeline import FRAME_NOT_PROCESSED

    f = out / "poses3d.npz"
    if not f.is_file():
        return 0, False
    try:
        with np.load(f, allow_pickle=False) as z:
            state = np.asarray(z["state"])
    except (OSError, ValueError, KeyError):
        return 0, False
    return len(state), bool(len(state)) and not bool((state == FRAME_NOT_PROCESSED).any())


def _write(out: Path, output: Stage1Output, dataset, n_done: int) -> None:
    """The stage-1 files and ``edits_template.toml`` (the estimates so far) written to ``OUT``."""
    from toolkit.io import atomic_write_text
    from toolkit.io.stage_outputs import write_stage1
    from toolkit.silhouettes import edits_template

    write_stage1(out, output)
    atomic_write_text(out / "edits_template.toml",
                      edits_template(output.poses2d, range(n_done),
                                     header=f"Edits for {dataset} (pose_from_silhouettes.py)"))


def _observer(out: Path, names: list, recording_id: str | None):
    """The rerun observer of the run, ``OUT/recording.rrd``, written in parts (one per frame: a run killed
    outright leaves the finished frames' recording complete; a dropped one leaves the earlier file)."""
    from toolkit.skeleton import SKELETON_14
    from toolkit.viz import RerunObserver

    observer = RerunObserver(application_id="pose_from_silhouettes", path=out / "recording.rrd",
                             recording_id=recording_id, camera_names=names, parts=True)
    observer.report("skeleton", skeleton=SKELETON_14)
    return observer


def _open(config: PoseFromSilhouettesConfig, ds, db_path: Path, n: int, out: Path, log) -> bool:
    """Open the run folder (its identity checked); whether it holds an earlier run's complete results.

    Raises
    ------
    InputError
        ``out`` holds another run's results, or complete results of more frames than ``n``.
    """
    exclude, extra = _identity(config, db_path)
    folder = open_run(out, "pose_from_silhouettes", ds.root, config, n, exclude=exclude, extra=extra,
                      replace_stale=config.replace_stale, recording=False, log=log)
    held, complete = _held(out) if folder.resumed else (0, False)
    if complete:
        check_frames_held(out, n, held, what="complete stage-1 results")
    return complete


def run(config: PoseFromSilhouettesConfig, *, dataset, out, observer=None, log=print) -> RunResult:
    """Run stage 1 (silhouette database, multi-view selection) over a dataset into ``out``.

    Ctrl-C or SIGTERM stops the run quietly (``stopped``); the frames
    estimated so far are written (the others ``FRAME_NOT_PROCESSED``), but
    never over the complete results of an earlier run of the same identity,
    which stay with their recording (:func:`~toolkit.pipeline.run.whole_run`).

    Parameters
    ----------
    config : PoseFromSilhouettesConfig
    dataset : path
        Dataset folder (``docs/dataset_layout.md``).
    out : path
        Output folder (``recipes/pose_from_silhouettes.py`` lists what it holds).
    observer : Observer, optional
        Receives every intermediate; default: a rerun recording ``OUT/recording.rrd`` (``config.recording``).
    log : callable or None
        Receives notes (the database, calibration refinement, database growth).

    Returns
    -------
    RunResult
        ``metrics``: ``states`` (frames per ``FRAME_*`` code, str keys) and ``ok``
        (frames with a 3D estimate); ``extra``: ``db`` (the database file) and
        ``earlier`` (the complete results of an earlier run were kept).

    Raises
    ------
    InputError
        Bad dataset, options, database, edits, or an output folder of another run.
    """
    import numpy as np
    from tqdm import tqdm

    from toolkit.calibration import cameras_for_run, refined_cameras
    from toolkit.foreground import BackgroundConfig, ForegroundConfig
    from toolkit.io import Dataset, read_png
    from toolkit.io.runs import run_recording
    from toolkit.silhouettes import read_edits, stack_estimates
    from toolkit.silhouettes.pipeline import FRAME_OK, estimate_dataset

    log = log or (lambda *_: None)
    out = Path(out)
    with Dataset.open(dataset, check_sizes=config.check_sizes) as ds:
        names = ds.camera_names
        edits = read_edits(config.edits, names, ds.n_frames) if config.edits is not None else None
        db, db_path = _database(config, log)
        fg = ForegroundConfig(method="chroma") if config.foreground == "chroma" else \
            ForegroundConfig(background=replace(BackgroundConfig(), method=config.foreground))
        plates = None if config.plates is None else \
            {c: [read_png(Path(config.plates) / f"{c}.png", channels=3, dtype=np.uint8)] for c in names}
        n = ds.frames_to_process(config.max_frames)
        earlier = _open(config, ds, db_path, n, out, log)
        own = observer is None and config.recording
        obs = _observer(out, names, run_recording(out, False)[1]) if own else observer
        n_db, k = len(db), config.stage1.query.k
        estimates = []
        t0 = time.perf_counter()
        with whole_run(out, obs, own=own, earlier=earlier) as state:
            rig = cameras_for_run(ds, out, refine=config.refine_calibration, observer=obs, log=log)
            s1config = config.stage1.with_refined_cameras(refined_cameras(out))  # tight offset prior where refined
            if obs is not None:
                obs.report("rig", rig=rig)
            try:
                frames = estimate_dataset(ds, db, s1config, foreground=fg, frames=range(n), edits=edits,
                                          backgrounds=plates, rig=rig, observer=obs, log_images=config.log_images)
                for est, _ in tqdm(frames, total=n, desc="stage 1", unit="frame", disable=not config.progress):
                    estimates.append(est)
                    state.checkpoint()
                    if not earlier and len(estimates) % CHECKPOINT_FRAMES == 0:
                        with state.writing():
                            _write(out, stack_estimates(estimates, n, names, k), dataset, len(estimates))
            finally:
                if len(estimates) == n or not earlier:  # never partial results over complete ones
                    with state.writing():
                        _write(out, stack_estimates(estimates, n, names, k), dataset, len(estimates))
                if len(db) > n_db:
                    db.save(db_path)
                    log(f"added {len(db) - n_db} corrected pose(s) to {db_path} ({len(db)} entries)")
    states = stack_estimates(estimates, n, names, k).state[:len(estimates)]
    metrics = {"ok": int((states == FRAME_OK).sum()),
               "states": {str(c): int(v) for c, v in sorted(Counter(states.tolist()).items())}}
    kept = bool(state.stopped) and earlier and len(estimates) < n
    recording = out / "recording.rrd" if kept and own and (out / "recording.rrd").is_file() else state.recording
    return RunResult(out, n, len(estimates), len(estimates), 0, state.stopped, time.perf_counter() - t0, metrics,
                     recording, {"db": db_path, "earlier": kept})


def summary_lines(result: RunResult) -> list:
    """What a stage-1 run says when it ends (the recipe prints these)."""
    from toolkit.silhouettes.pipeline import FRAME_OK, FRAME_STATES

    out, m, done, dt = result.out, result.metrics, result.finished, result.seconds
    lines = [f"{'stopped early (' + result.stopped + '): ' if result.stopped else ''}{done} of {result.frames} "
             f"frames in {dt:.1f} s ({dt / max(done, 1):.2f} s/frame); 3D estimate in {m['ok']}"]
    if result.extra.get("earlier"):
        return lines + [f"  not written: the complete results of the earlier run are kept in {out} (and its "
                        "recording); run the same command again to estimate every frame"]
    lines += [f"  {v} frame(s): {FRAME_STATES[int(c)]}" for c, v in m["states"].items() if int(c) != FRAME_OK]
    lines += [f"  2D poses:  {out / 'poses2d.npz'}  (one (T, 14, 2) array per camera, pixels)",
              f"  3D joints: {out / 'poses3d.npz'}  (joints (T, 14, 3) metres, names, state)",
              f"  offsets:   {out / 'offsets.npz'}  (offsets (T, cameras, 2) pixels)",
              f"  cameras:   {out / 'calibration.toml'}  (the calibration used: refined on field lines or measured)",
              f"  edits:     {out / 'edits_template.toml'}  (copy the frames to correct into an edits file)"]
    if result.recording is not None:
        lines.append(f"  recording: {result.recording}   (open with: rerun {result.recording})")
    return lines
