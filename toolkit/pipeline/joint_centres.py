"""The marker system's run: joint centres from a marker capture or a C3D file (source 004).

:func:`run` is what ``recipes/joint_centres.py`` calls (its docstring lists the
outputs).  The dataset is either

* a synthetic (or recorded) **marker capture folder** (``markers/calibration.toml``
  and ``markers/detections/<camera>.npz``): its 2D blobs are reconstructed,
  identified and tracked by :func:`toolkit.markers.label.label_capture` into
  labelled trajectories; the marker set is the config's or the one the
  calibration's metadata names;
* or a **C3D file** of 3D markers (:func:`toolkit.io.c3d.read_c3d`, labelled or
  not), which skips those steps.

Then :func:`toolkit.markers.functional.joint_centres` finds the rigid subsets,
the centres of rotation and the scaled skeleton.  One run is one trial; the
run folder is identified like every run (``OUT/run.json``: the input by
content and the options that change the results) and written anew each time
(:func:`toolkit.pipeline.run.whole_run`): the outputs are written together
at the end, so Ctrl-C or SIGTERM (ending the run quietly, ``RunResult.stopped``)
or a full disk (an error naming the file) leave those of an earlier complete
run, and its recording, as they were.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.markers.functional import JointCentresConfig, JointCentresResult
from toolkit.markers.label import LabelConfig
from toolkit.pipeline.run import RunResult, open_run, whole_run

#: Frames logged to the recording at most (longer trials are logged every k-th frame).
RECORD_MAX_FRAMES = 1500
#: Colours of the rigid subsets in the recording (cycled).
SUBSET_COLORS = np.array([[230, 25, 75], [60, 180, 75], [255, 225, 25], [0, 130, 200], [245, 130, 48],
                          [145, 30, 180], [70, 240, 240], [240, 50, 230], [210, 245, 60], [250, 190, 212],
                          [0, 128, 128], [220, 190, 255], [170, 110, 40], [128, 0, 0], [170, 255, 195]],
                         np.uint8)
#: Colour of the centres of rotation and the hinge axes (dark: the 3D view's background is light).
CENTRE_COLOR = np.array([20, 20, 20], np.uint8)
#: Colour of the fitted spheres' wire circles.
SPHERE_COLOR = np.array([110, 110, 110], np.uint8)


@dataclass(frozen=True)
class JointCentresRunConfig:
    """Options of a joint-centres run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    centres : JointCentresConfig
        Subsets, centres of rotation and skeleton (``[centres]`` table).
    label : LabelConfig
        Reconstruction, identification and tracking of a capture folder (``[label]`` table).
    marker_set : str
        The marker set of a capture folder ("" = the one its calibration's
        metadata names); for a C3D file it stands for ``centres.marker_set``
        when that is "auto" (the two may not name different sets).
    labelling : Path, optional
        A user labelling file for a capture folder (:func:`toolkit.markers.identify.read_labelling`).
    record_max_frames : int
        Frames logged to the recording at most (evenly spread).
    recording : bool
        Write ``recording.rrd``.
    replace_stale : bool
        Move another run's results aside instead of refusing them.
    """

    centres: JointCentresConfig = field(default_factory=JointCentresConfig)
    label: LabelConfig = field(default_factory=LabelConfig)
    marker_set: str = ""
    labelling: Path | None = None
    record_max_frames: int = RECORD_MAX_FRAMES
    recording: bool = True
    replace_stale: bool = False

    #: Fields that do not change the results (left out of the run identity).
    RUNTIME = ("record_max_frames", "recording", "replace_stale")


def input_identity(dataset: Path) -> dict:
    """What a run's results depend on in its input: the C3D file, or the capture's calibration and blobs."""
    from toolkit.io.runs import file_fingerprint

    if dataset.suffix.lower() == ".c3d":
        return {"kind": "c3d", "file": file_fingerprint(dataset)}
    h = hashlib.sha256()
    for p in [dataset / "markers" / "calibration.toml", *sorted((dataset / "markers" / "detections").glob("*.npz"))]:
        if p.is_file():
            h.update(p.relative_to(dataset).as_posix().encode())
            h.update(file_fingerprint(p).encode())
    return {"kind": "capture", "files": h.hexdigest()}


def _open_input(config: JointCentresRunConfig, dataset: Path, obs):
    """Labelled trajectories (and the capture's rig, or None) of a capture folder or a C3D file."""
    from toolkit.markers.functional import trajectories_from_c3d

    if dataset.suffix.lower() == ".c3d":
        return trajectories_from_c3d(dataset), None
    if not dataset.is_dir():
        raise InputError(str(dataset), "a marker capture folder (markers/calibration.toml) or a .c3d file",
                         "no such folder" if not dataset.exists() else "a file that is not .c3d")
    from toolkit.io import read_calibration_metadata
    from toolkit.markers.capture import load_marker_capture
    from toolkit.markers.label import label_capture
    from toolkit.markers.marker_sets import get_marker_set

    capture = load_marker_capture(dataset)
    name = config.marker_set or read_calibration_metadata(dataset / "markers" / "calibration.toml").get("marker_set")
    if not name:
        raise InputError(f"{dataset / 'markers' / 'calibration.toml'}: metadata.marker_set",
                         "the capture's marker set (or --marker-set)", "nothing")
    obs.report("rig", rig=capture.rig)
    traj = label_capture(capture, get_marker_set(str(name)), config=config.label, labelling=config.labelling,
                         observer=obs)
    return traj, capture


def _centres_config(config: JointCentresRunConfig, dataset: Path) -> JointCentresConfig:
    """The centres' options; for a C3D file ``config.marker_set`` (--marker-set) names the labels' set."""
    centres, name = config.centres, config.marker_set
    if dataset.suffix.lower() != ".c3d" or not name or name == centres.marker_set:
        return centres
    if centres.marker_set != "auto":
        raise InputError("--marker-set (marker_set)", f"the [centres] table's marker set {centres.marker_set!r} "
                         "or nothing", repr(name))
    from dataclasses import replace

    return replace(centres, marker_set=name)


def _sphere_strips(centre: np.ndarray, radius: float, n: int = 48) -> list[np.ndarray]:
    """Three great circles (n + 1, 3) of a sphere around ``centre`` (metres): a wire sphere."""
    a = np.linspace(0.0, 2 * np.pi, n + 1)
    c, s = radius * np.cos(a), radius * np.sin(a)
    z = np.zeros_like(a)
    return [centre + np.stack(v, axis=1) for v in ((c, s, z), (c, z, s), (z, c, s))]


def report_centres(obs, traj, res: JointCentresResult, *, max_frames: int = RECORD_MAX_FRAMES) -> None:
    """Log the rigid subsets (markers in colours), tracks, fitted spheres and axes, centres and skeleton.

    Parameters
    ----------
    obs : Observer
    traj : MarkerTrajectories
    res : JointCentresResult
    max_frames : int
        Frames logged at most (evenly spread).
    """
    from toolkit.skeleton import SKELETON_14

    t = traj.n_frames
    frames = np.unique(np.linspace(0, t - 1, min(t, max_frames)).astype(int))
    subset_of = np.full(traj.n_markers, -1)
    for k, idx in enumerate(res.subsets.values()):
        for i in idx:
            if subset_of[i] < 0:
                subset_of[i] = k
    colors = np.where((subset_of >= 0)[:, None], SUBSET_COLORS[subset_of % len(SUBSET_COLORS)], 128).astype(np.uint8)
    legend = "; ".join(f"{name}: {[traj.labels[i] for i in idx]}" for name, idx in res.subsets.items())
    obs.report("text", text=f"rigid subsets ({res.marker_set}): {legend}", name="markers/subsets", static=True)
    for m in res.messages:
        obs.report("text", text=m, name="markers/joints", level="WARN", static=True)
    if res.labelled:
        obs.report("skeleton", skeleton=SKELETON_14)
    strips = [traj.positions[frames, i] for i in range(traj.n_markers)]
    strips = [s[np.isfinite(s).all(axis=1)] for s in strips]
    keep = [i for i, s in enumerate(strips) if len(s) >= 2]
    if keep:
        obs.report("lines3d", strips=[strips[i] for i in keep], colors=colors[keep], name="markers/tracks",
                   static=True)
    fits = list(res.fits.items())
    for f in frames:
        ok = np.isfinite(traj.positions[f]).all(axis=1)
        obs.report("points3d", points=traj.positions[f, ok], colors=colors[ok], name="markers/subsets", frame=int(f),
                   radii=0.01)
        obs.report("scalar", name="markers/labelled_markers", value=float(ok.sum()), frame=int(f))
        if fits:
            c = np.array([fit.centre[f] for _, fit in fits])
            obs.report("points3d", points=c, colors=np.tile(CENTRE_COLOR, (len(c), 1)), radii=0.015,
                       name="markers/centres", frame=int(f))
            axes = [np.stack([fit.centre[f] - 0.12 * fit.axis[f], fit.centre[f] + 0.12 * fit.axis[f]])
                    for _, fit in fits if fit.axis is not None and np.isfinite(fit.axis[f]).all()
                    and np.isfinite(fit.centre[f]).all()]
            if axes:
                obs.report("lines3d", strips=axes, name="markers/axes", frame=int(f),
                           colors=np.tile(CENTRE_COLOR, (len(axes), 1)))
            spheres = [_sphere_strips(fit.centre[f], np.nanmax(fit.local_child)) for _, fit in fits
                       if fit.method == "sphere" and np.isfinite(fit.centre[f]).all()]
            if spheres:  # wire spheres: the markers and the centre stay visible inside
                strips = [c for s in spheres for c in s]
                obs.report("lines3d", strips=strips, name="markers/spheres", frame=int(f),
                           colors=np.tile(SPHERE_COLOR, (len(strips), 1)))
        if res.labelled:
            obs.report("joints3d", joints=res.joints[f], skeleton=SKELETON_14, name="skeleton", frame=int(f))


def _write(out: Path, traj, res: JointCentresResult, fps: float) -> dict:
    """``joint_centres.npz``, ``joint_centres.c3d``, ``skeleton.json``, ``trajectories.npz``; their paths."""
    from toolkit.io import atomic_save_npz, atomic_write_text
    from toolkit.io.c3d import write_c3d

    pair_names = [k for k in res.fits if k not in res.names]
    pairs = np.array([res.fits[k].centre for k in pair_names]).reshape(len(pair_names), traj.n_frames, 3)
    atomic_save_npz(out / "joint_centres.npz", joints=res.joints, names=np.array(res.names),
                    method=np.array(res.method), residual_mm=1e3 * res.residual_m, rom_deg=res.rom_deg,
                    fps=np.float64(fps), pair_centres=pairs, pair_names=np.array(pair_names, dtype=str))
    extra_labels, extra = [], []
    if res.labelled:
        for j, name in enumerate(res.names):
            if np.isfinite(res.joints[:, j]).any():
                extra_labels.append(f"{name.upper()}_JC")
                extra.append(res.joints[:, j])
    for k, c in zip(pair_names, pairs):
        extra_labels.append(f"{k.replace('-', '_')}_CR")
        extra.append(c)
    labels = list(traj.labels) + [lab for lab in extra_labels if lab not in traj.labels]
    points = np.concatenate([traj.positions, np.stack(extra, axis=1)], axis=1) if extra else traj.positions
    write_c3d(out / "joint_centres.c3d", labels, points[:, :len(labels)], fps,
              descriptions=[""] * traj.n_markers + ["joint centre"] * (len(labels) - traj.n_markers))
    skeleton = {"height_m": None if not np.isfinite(res.height_m) else round(res.height_m, 4),
                "marker_set": res.marker_set, "labelled": res.labelled,
                "bone_lengths_m": {k: round(v, 4) for k, v in res.lengths.items()},
                "joints": res.summary(),
                "subsets": {k: [traj.labels[i] for i in v] for k, v in res.subsets.items()},
                "messages": res.messages}
    atomic_write_text(out / "skeleton.json", json.dumps(skeleton, indent=2) + "\n")
    traj.save_npz(out / "trajectories.npz")
    return {"joint_centres": out / "joint_centres.npz", "c3d": out / "joint_centres.c3d",
            "skeleton": out / "skeleton.json", "trajectories": out / "trajectories.npz"}


def score_against_truth(dataset: Path, traj, res: JointCentresResult) -> dict | None:
    """Scores of a synthetic capture: labelling (mk-label's score) and joint-centre errors; None without truth.

    Returns
    -------
    dict or None
        ``labelling`` (:func:`toolkit.markers.evaluate.labelling_score` less its details),
        ``joint_error_mm`` (per joint mean over frames where placed), ``joint_error_median_mm``.
    """
    truth_file = dataset / "groundtruth" / "joints3d.npz"
    if dataset.suffix.lower() == ".c3d" or not truth_file.is_file():
        return None
    from toolkit.markers.evaluate import labelling_score

    with np.load(truth_file) as z:
        truth = np.asarray(z["joints"], float)
    if truth.shape != res.joints.shape:
        raise InputError(f"{truth_file}: joints", f"shape {res.joints.shape}", f"{truth.shape}")
    err = np.linalg.norm(res.joints - truth, axis=-1)
    with np.errstate(invalid="ignore"):
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(err, axis=0)
            med = np.nanmedian(err, axis=0)
    sc = labelling_score(traj, dataset)
    keys = ("n", "correct", "wrong", "missing", "share_correct", "share_wrong", "share_missing")
    return {"labelling": {k: sc[k] for k in keys if k in sc},
            "joint_error_mm": {n: None if not np.isfinite(v) else round(1e3 * float(v), 2)
                               for n, v in zip(res.names, mean)},
            "joint_error_median_mm": {n: None if not np.isfinite(v) else round(1e3 * float(v), 2)
                                      for n, v in zip(res.names, med)}}


def run(config: JointCentresRunConfig, *, dataset, out, observer=None, log=print) -> RunResult:
    """Joint centres of one trial into ``out``.

    Parameters
    ----------
    config : JointCentresRunConfig
    dataset : path
        A marker capture folder or a ``.c3d`` file.
    out : path
        Output folder (``recipes/joint_centres.py`` lists what it holds).
    observer : Observer, optional
        Receives every intermediate; default: ``OUT/recording.rrd`` (``config.recording``).
    log : callable or None
        Receives notes (a stale folder moved aside, the result's messages).

    Returns
    -------
    RunResult
        ``metrics``: ``methods`` (joint -> method), ``seconds_per_frame`` and,
        for a synthetic capture, the scores of ``metrics.json``; ``extra``:
        the written files, ``messages``, ``marker_set``, ``labelled``.

    Raises
    ------
    InputError
        Bad input or options, or an output folder of another run.
    """
    from toolkit.io.runs import run_recording
    from toolkit.markers.functional import joint_centres
    from toolkit.observe import MultiObserver, as_observer

    dataset, out = Path(dataset), Path(out)
    if not dataset.exists():
        raise InputError(str(dataset), "a marker capture folder or a .c3d file", "nothing at that path")
    folder = open_run(out, "joint_centres", dataset if dataset.is_dir() else dataset.parent, config, 1,
                      exclude=JointCentresRunConfig.RUNTIME, extra={"input": input_identity(dataset)},
                      replace_stale=config.replace_stale, recording=False, log=log)
    earlier = folder.resumed and (out / "metrics.json").is_file()   # written last: the results are complete
    own = observer is None and config.recording
    rec = None
    if own:
        from toolkit.viz import RerunObserver

        # in parts: a run killed outright leaves its finished parts complete; a dropped one leaves the file as it was
        rec = RerunObserver(application_id="joint_centres", path=out / "recording.rrd",
                            recording_id=run_recording(out, False)[1], parts=True)
        if dataset.suffix.lower() == ".c3d":  # no cameras: the 3D view (the viewer frames it) over the log
            from toolkit.viz.blueprint import make_blueprint

            rec.send_blueprint(make_blueprint([], include_metrics=False))
    obs = as_observer(MultiObserver(rec, observer) if (rec or observer) else None)
    t0 = time.perf_counter()
    done = None
    with whole_run(out, rec, own=own, earlier=earlier) as state:
        traj, _capture = _open_input(config, dataset, obs)
        state.checkpoint()
        t1 = time.perf_counter()
        res = joint_centres(traj, config=_centres_config(config, dataset), observer=obs)
        t2 = time.perf_counter()
        report_centres(obs, traj, res, max_frames=config.record_max_frames)
        state.checkpoint()
        with state.writing():
            done = _write_all(out, dataset, traj, res, _capture is not None, (t0, t1, t2))
    if done is None:   # stopped before its results were written: those of an earlier complete run stay
        return RunResult(out, 0, 0, 0, 0, state.stopped, time.perf_counter() - t0, {}, state.recording,
                         {"input": str(dataset), "earlier": earlier})
    files, metrics, scores = done
    if log is not None:
        for m in res.messages:
            log(f"note: {m}")
    n = traj.n_frames
    return RunResult(out, n, n, n, 0, state.stopped, time.perf_counter() - t0, metrics, state.recording,
                     {"input": str(dataset), **files, "metrics": out / "metrics.json", "messages": res.messages,
                      "marker_set": res.marker_set, "labelled": res.labelled, "height_m": res.height_m,
                      "has_groundtruth": scores is not None})


def _write_all(out: Path, dataset: Path, traj, res: JointCentresResult, labelled_capture: bool, times) -> tuple:
    """Every output file (:func:`_write`, then ``metrics.json`` last); the files, the metrics and the scores."""
    from toolkit.io import atomic_write_text

    t0, t1, t2 = times
    files = _write(out, traj, res, traj.fps)
    scores = score_against_truth(dataset, traj, res)
    n = traj.n_frames
    metrics = {"frames": n, "methods": dict(zip(res.names, res.method)),
               "seconds_per_frame": {"labelling": (t1 - t0) / n if labelled_capture else 0.0,
                                     "centres": (t2 - t1) / n},
               "joints": res.summary(), **(scores or {})}
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=2) + "\n")
    return files, metrics, scores


def summary_lines(result: RunResult) -> list:
    """What a joint-centres run says when it ends (the recipe prints these)."""
    m, x = result.metrics, result.extra
    if not m:   # stopped before the results were written
        kept = "the earlier complete results (and recording) are kept" if x.get("earlier") else "no results written"
        return [f"{result.stopped}: stopped after {result.seconds:.1f} s, before the joint centres of {x['input']} "
                f"were written; {kept}; run the same command again to compute them"]
    lines = [] if not result.stopped else [f"{result.stopped}: stopped after the results were written"]
    lines += [f"joint centres of {x['input']} ({result.frames} frames, marker set {x['marker_set']}) "
             f"in {result.seconds:.1f} s"]
    if x["labelled"]:
        lines.append(f"  stature {x['height_m']:.3f} m; " + ", ".join(f"{k} {v}" for k, v in m["methods"].items()))
    for key in ("joint_centres", "c3d", "skeleton", "metrics"):
        lines.append(f"  {key + ':':16s}{x[key]}")
    if result.recording is not None:
        lines.append(f"  {'recording:':16s}{result.recording}  (open with: rerun {result.recording})")
    if x["has_groundtruth"]:
        lab = m["labelling"]
        err = {k: v for k, v in m["joint_error_mm"].items() if v is not None}
        lines.append(f"  labelled correctly {100 * lab['share_correct']:.1f} %; joint error (mean mm) "
                     + ", ".join(f"{k} {v:.1f}" for k, v in err.items()))
    return lines
