"""A Pose2Sim trial made a dataset, its keypoints detected first when it has none.

:func:`import_trial` is what ``recipes/import_pose2sim.py`` calls: a trial with keypoints
(``pose/``, ``pose-associated/``) is imported as it is (:func:`toolkit.io.import_pose2sim_trial`); a
trial with videos and a calibration but no keypoints has its people detected first
(:func:`toolkit.pipeline.detect_keypoints.detect_videos`, into ``DATASET/detection/``: the detector's
own folder, kept, so a rerun does only the frames missing) and is then imported from there, the
cameras lined up by their late starts when the detection was synchronised (``sync``)::

    DATASET/
      detection/<video>/...json, detection.json, sync.json    the detector's run (toolkit.pipeline.detect_keypoints)
      keypoints/<camera>/                                     links to those files (relative), renumbered when shifted
      videos/, calibration.toml, import.json                  as toolkit.io.pose2sim_import writes them

The detection lives here, above ``toolkit.io`` (which runs no algorithm and may not import
``toolkit.pipeline``).

:func:`prepare_run_input` is what ``recipes/free_viewpoint.py`` calls with its positional argument:
a dataset folder is used as it is; a Pose2Sim trial is imported (as above) into ``OUT/dataset`` and
the run's results go to ``OUT/results`` (a run folder holds only its own results: the run refuses a
folder holding anything else).  An earlier import of the same trial there is reused when it covers
what is asked.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.io.pose2sim import is_pose2sim_trial, read_pose2sim_trial
from toolkit.io.pose2sim_import import IMPORT_JSON, import_pose2sim_trial
from toolkit.pipeline.detect_keypoints import (DetectConfig, DetectResult, detect_videos, read_sync,
                                               summary_lines as detection_lines)

__all__ = ["DATASET_FOLDER", "DETECTION_FOLDER", "RESULTS_FOLDER", "RunInput", "TrialImport", "import_trial",
           "import_lines", "prepare_run_input"]

#: The detector's folder inside a dataset imported from a trial without keypoints.
DETECTION_FOLDER = "detection"
#: Where ``free_viewpoint`` puts the dataset imported from a trial, and its results, inside ``--out``.
DATASET_FOLDER = "dataset"
RESULTS_FOLDER = "results"


@dataclass(frozen=True)
class TrialImport:
    """What :func:`import_trial` did.

    Attributes
    ----------
    dataset : Path
        The dataset folder.
    report : dict
        Its ``import.json`` (``detection``: how the keypoints were detected, None when the trial had them;
        ``frame_offsets``: the late starts applied, None when none).
    detection : DetectResult or None
        The detection run now (None when the trial had keypoints, or an earlier import was reused).
    lines : tuple of str
        What was done, one line each (detection summary, mismatches handled, shifts), to print.
    reused : bool
        An earlier import of the same trial was kept as it is.
    """

    dataset: Path
    report: dict
    detection: DetectResult | None
    lines: tuple[str, ...]
    reused: bool = False


@dataclass(frozen=True)
class RunInput:
    """The dataset a run works on and where its results go (:func:`prepare_run_input`).

    Attributes
    ----------
    dataset : Path
    out : Path
        The run's output folder: the one given for a dataset, ``OUT/results`` for a trial.
    imported : TrialImport or None
        The trial's import (None: a dataset was given).
    """

    dataset: Path
    out: Path
    imported: TrialImport | None = None

    @property
    def lines(self) -> list[str]:
        """What was done before the run, to print (nothing for a dataset)."""
        if self.imported is None:
            return []
        return list(self.imported.lines) + [f"running on the dataset {self.dataset}; results in {self.out}"]


def _check_out(out: Path, overwrite: bool) -> None:
    if out.exists() and not out.is_dir():
        raise InputError(str(out), "a dataset folder to write", "a file")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise InputError(str(out), "a new or empty folder (else overwrite)", "a folder with files")


def _detection_record(result: DetectResult, config: DetectConfig, folder: Path) -> dict:
    """The ``detection`` entry of ``import.json``."""
    rec = {"folder": str(folder.resolve()), "detector": config.detector, "model": result.model,
           "layout": result.layout, "options": config.identity(), "max_frames": config.max_frames,
           "sync": bool(config.sync),
           "people_per_frame": {c: s.get("people_per_frame") for c, s in result.cameras.items()},
           "warnings": list(result.warnings)}
    if result.sync is not None:
        rec["sync_offsets"] = {k: int(v) for k, v in result.sync.offsets.items()}
        rec["sync_trusted"] = {k: bool(v) for k, v in result.sync.trusted.items()}
    return rec


def import_trial(trial: str | os.PathLike, out: str | os.PathLike, *, calibration: str | os.PathLike | None = None,
                 pose: str | None = None, copy: bool = False, overwrite: bool = False,
                 detect_config: DetectConfig | None = None, log=print) -> TrialImport:
    """Import a Pose2Sim trial as a dataset, detecting its keypoints first when it has none.

    Parameters
    ----------
    trial : path-like
        A Pose2Sim trial folder: with keypoints (``pose/``, ``pose-associated/``) or with ``videos/`` and a
        calibration folder only.
    out : path-like
        The dataset folder to write (new or empty unless ``overwrite``).
    calibration : path-like, optional
        A calibration file instead of the trial's (also the one ``sync`` uses).
    pose : {"pose", "pose-associated"}, optional
        The trial's keypoint folder to import (a trial with keypoints).
    copy : bool
        Copy the videos and keypoint files instead of linking to them.
    overwrite : bool
        Write into a non-empty ``out``.
    detect_config : DetectConfig, optional
        The detection's options for a trial without keypoints (default: ``DetectConfig()``).  With
        ``sync``, the offsets found (by where the cameras' rays meet: the calibration is handed to
        the synchronisation) line the cameras up in the dataset.  Unused for a trial with keypoints.
    log : callable
        Receives the detection's progress lines.

    Returns
    -------
    TrialImport

    Raises
    ------
    InputError
        Not a trial (neither keypoints nor videos with a calibration), no calibration, a non-empty
        ``out`` (without ``overwrite``), a video that does not open, and whatever
        :func:`toolkit.io.import_pose2sim_trial` refuses (each names the file or folder).
    """
    trial, out = Path(trial), Path(out)
    if not trial.is_dir():
        raise InputError(str(trial), "a Pose2Sim trial folder", "no such folder")
    info = read_pose2sim_trial(trial) if pose is None else None
    if info is None or info.keypoints is not None:
        res = import_pose2sim_trial(trial, out, calibration=calibration, pose=pose, copy=copy, overwrite=overwrite)
        lines = list(res.messages)
        if detect_config is not None and (detect_config.sync or detect_config.max_frames is not None):
            lines.append(f"sync and max_frames not applied: the trial has its own keypoints "
                         f"({res.report['keypoints']}); they apply to keypoints detected here")
        return TrialImport(res.out, res.report, None, tuple(lines))
    calib = Path(calibration) if calibration is not None else info.calibration
    if calib is None:
        raise InputError(str(trial), "a calibration file in the trial's calibration folder (or one given: "
                                     "--calibration)", "none found")
    _check_out(out, overwrite)
    config = detect_config if detect_config is not None else DetectConfig()
    if config.sync and config.calibration is None:
        config = replace(config, calibration=calib)
    folder = out / DETECTION_FOLDER
    log(f"{trial}: videos and no keypoints: detecting people in {info.videos} into {folder}")
    detected = detect_videos(info.videos, folder, config, log=log)
    offsets = read_sync(folder) if config.sync else None
    res = import_pose2sim_trial(trial, out, calibration=calib, keypoints=folder, keypoint_format=detected.layout,
                                frame_offsets=offsets, detection=_detection_record(detected, config, folder),
                                copy=copy, overwrite=True)
    lines = detection_lines(detected) + list(res.messages)
    if offsets is not None and not any(res.shifts.values()):
        lines.append("sync: every camera at offset 0: nothing shifted")
    return TrialImport(res.out, res.report, detected, tuple(lines))


def import_lines(result: TrialImport) -> list[str]:
    """What ``recipes/import_pose2sim.py`` prints: what was done, then what the dataset holds."""
    rep = result.report
    names = [c["name"] for c in rep["cameras"]]
    det = rep.get("detection")
    source = (f"keypoints detected ({det['detector']}: {det['model']}) into {det['folder']}" if det
              else f"keypoints from {rep['keypoints']}")
    shifted = {c["name"]: c["frames_dropped_at_start"] for c in rep["cameras"] if c.get("frames_dropped_at_start")}
    lines = list(result.lines)
    lines.append(f"{len(names)} cameras {names}, {rep['n_frames']} frames at {rep['fps']:g} fps, {source} "
                 f"({rep['pose_model'] or 'format not stated'}), files {rep['files']}")
    if shifted:
        lines.append("shifted (frames dropped at the start): " + ", ".join(f"{k} {v}" for k, v in shifted.items()))
    lines.append(f"wrote {result.dataset} (report: {result.dataset / IMPORT_JSON})")
    return lines


def _reuse_blocker(dataset: Path, trial: Path, config: DetectConfig) -> str | None:
    """Why the dataset imported earlier into ``dataset`` cannot serve now (None: it can)."""
    path = dataset / IMPORT_JSON
    if not path.is_file():
        return "no earlier import" if not dataset.exists() else f"no {IMPORT_JSON} (an unfinished import)"
    try:
        rep = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        return f"{path} unreadable ({type(e).__name__})"
    if not isinstance(rep, dict) or rep.get("trial") != str(trial.resolve()):
        return f"it holds another trial ({rep.get('trial') if isinstance(rep, dict) else '?'})"
    det = rep.get("detection")
    if det is None:
        return None
    if det.get("options") != config.identity() or bool(det.get("sync")) != bool(config.sync):
        return "it was detected with other options"
    old, new = det.get("max_frames"), config.max_frames
    if old is not None and (new is None or new > old):
        return f"it holds the first {old} frames only"
    return None


def prepare_run_input(source: str | os.PathLike, out: str | os.PathLike, *, max_frames: int | None = None,
                      sync: bool = False, detect_config: DetectConfig | None = None, log=print) -> RunInput:
    """The dataset a run works on: ``source`` itself, or the Pose2Sim trial ``source`` imported.

    Parameters
    ----------
    source : path-like
        A dataset folder (holding ``calibration.toml``, docs/dataset_layout.md) or a Pose2Sim
        trial (with keypoints, or videos and a calibration only).
    out : path-like
        The run's output folder as given (``--out``).
    max_frames : int, optional
        Frames the run processes: a trial without keypoints is detected on these only (unless ``sync``,
        which needs the whole motion).
    sync : bool
        Synchronise the cameras of a trial without keypoints and line them up in the dataset.
    detect_config : DetectConfig, optional
        The detection's options (default: ``DetectConfig()``); ``max_frames`` and ``sync`` are set from the
        arguments above.
    log : callable

    Returns
    -------
    RunInput
        For a dataset: ``(source, out)``.  For a trial: ``(out/dataset, out/results)``, imported now or
        reused from an earlier run with this ``out``.

    Raises
    ------
    InputError
        ``source`` neither a dataset nor a trial; ``out`` holding other files than an earlier run on a
        trial (``dataset/``, ``results/``); whatever :func:`import_trial` refuses.
    """
    source, out = Path(source), Path(out)
    if (source / "calibration.toml").is_file():     # a dataset (Dataset.open checks the rest)
        return RunInput(source, out)
    if not source.is_dir() or not is_pose2sim_trial(source):
        raise InputError(str(source), "a dataset folder (calibration.toml and videos/, docs/dataset_layout.md) or a "
                                      "Pose2Sim trial (videos/ and a calibration folder, or pose/)",
                         "no such folder" if not source.is_dir() else "neither")
    if out.exists() and not out.is_dir():
        raise InputError(str(out), "an output folder", "a file")
    others = sorted(p.name for p in out.iterdir() if p.name not in (DATASET_FOLDER, RESULTS_FOLDER)
                    and not p.name.startswith(f"{RESULTS_FOLDER}.stale-")) if out.is_dir() else []
    if others:
        raise InputError(str(out), f"an empty folder or an earlier run on a trial ({DATASET_FOLDER}/, "
                                   f"{RESULTS_FOLDER}/)", f"other files: {others[:5]}")
    config = detect_config if detect_config is not None else DetectConfig()
    config = replace(config, sync=sync, max_frames=None if sync else (max_frames or config.max_frames))
    dataset = out / DATASET_FOLDER
    blocker = _reuse_blocker(dataset, source, config)
    if blocker is None:
        rep = json.loads((dataset / IMPORT_JSON).read_text(encoding="utf-8"))
        done = TrialImport(dataset, rep, None, (f"{source} is a Pose2Sim trial: using its import in {dataset} "
                                                f"({rep['n_frames']} frames)",), reused=True)
        return RunInput(dataset, out / RESULTS_FOLDER, done)
    if dataset.exists():
        log(f"{dataset}: imported again ({blocker})")
    done = import_trial(source, dataset, overwrite=True, detect_config=config, log=log)
    head = f"{source} is a Pose2Sim trial: imported into {dataset} ({done.report['n_frames']} frames)"
    return RunInput(dataset, out / RESULTS_FOLDER, replace(done, lines=(head,) + done.lines))
