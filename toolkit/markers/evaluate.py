"""Scores of labelled marker trajectories against a synthetic capture's ground truth.

A marker-frame is **correct** when the trajectory has a position for the
label, the true marker of that label is the nearest true marker to it and it
lies within ``tolerance_m`` of it; **wrong** when it has a position that is
not correct (another marker's, a ghost's, or a bridge gone astray);
**missing** when it has none.  Shares are given over all true marker-frames
and over the *observable* ones (the true marker produced a blob in at least
two cameras, so some reconstruction was possible).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.markers.trajectories import STATE_NAMES, MarkerTrajectories

#: Default distance within which a labelled position counts as its true marker, metres
#: (well above the reconstruction error at 1 px noise, well below the 6-7 cm between markers).
SCORE_TOLERANCE_M = 0.02


def _load(path: Path, keys) -> dict:
    if not path.is_file():
        raise InputError(str(path), "a ground-truth .npz file", "no such file")
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in keys if k not in z.files]
            if missing:
                raise InputError(str(path), f"fields {list(keys)}", f"missing {missing}")
            return {k: z[k] for k in keys}
    except (OSError, ValueError) as e:
        raise InputError(str(path), "a readable .npz archive", str(e)) from None


def observed_views(capture_dir: str | Path, n_frames: int, n_markers: int) -> np.ndarray:
    """Number of cameras (T, M) that produced a blob of each true marker in each frame."""
    root = Path(capture_dir)
    gt_dir = root / "groundtruth" / "marker_detections"
    files = sorted(gt_dir.glob("*.npz"))
    if not files:
        raise InputError(str(gt_dir), "one .npz of true blob identities per camera", "none")
    count = np.zeros((n_frames, n_markers), int)
    for gt in files:
        marker = _load(gt, ["marker"])["marker"].astype(int)
        frame = _load(root / "markers" / "detections" / gt.name, ["frame"])["frame"].astype(int)
        if frame.shape != marker.shape:
            raise InputError(str(gt), f"'marker' of the shape of the detections' frame {frame.shape}",
                             f"shape {marker.shape}")
        ok = (marker >= 0) & (frame < n_frames)
        seen = np.zeros((n_frames, n_markers), bool)
        seen[frame[ok], marker[ok]] = True
        count += seen
    return count


def labelling_score(traj: MarkerTrajectories, capture_dir: str | Path, *,
                    tolerance_m: float = SCORE_TOLERANCE_M) -> dict:
    """Share of true marker-frames labelled correctly, wrong labels and missing ones.

    Parameters
    ----------
    traj : MarkerTrajectories
        (T, M) labelled trajectories of the capture.
    capture_dir : str or Path
        The synthetic capture folder (``groundtruth/markers3d.npz``,
        ``groundtruth/marker_detections/<camera>.npz``, ``markers/detections/<camera>.npz``).
    tolerance_m : float

    Returns
    -------
    dict
        ``n`` (true marker-frames), ``correct``, ``wrong``, ``missing`` (counts),
        ``share_correct``, ``share_wrong``, ``share_missing`` (over all),
        ``n_observable`` and ``share_correct_observable``, ``by_state``
        (state name -> {correct, wrong}), ``wrong_labels`` (label -> count, the
        worst ten), ``position_error_mm`` (median and 90th percentile of the
        correct ones).

    Raises
    ------
    InputError
        Missing ground truth, labels of ``traj`` absent from it, a different frame count.
    """
    root = Path(capture_dir)
    gt = _load(root / "groundtruth" / "markers3d.npz", ["labels", "positions"])
    gt_labels = [str(x) for x in gt["labels"]]
    true = np.asarray(gt["positions"], float)
    if true.shape[0] != traj.n_frames:
        raise InputError(str(root / "groundtruth" / "markers3d.npz"),
                         f"{traj.n_frames} frames (as the trajectories)", f"{true.shape[0]}")
    unknown = [x for x in traj.labels if x not in gt_labels]
    if unknown:
        raise InputError("traj.labels", "labels of the ground truth", f"unknown {unknown[:5]}")
    own = np.array([gt_labels.index(x) for x in traj.labels])
    pos = traj.positions
    has = np.isfinite(pos).all(axis=2)
    d = np.linalg.norm(pos[:, :, None, :] - true[:, None, :, :], axis=3)  # (T, M, M_true)
    d = np.where(np.isfinite(d), d, np.inf)
    nearest = np.argmin(d, axis=2)
    d_own = np.take_along_axis(d, own[None, :, None].repeat(traj.n_frames, 0), axis=2)[..., 0]
    correct = has & (nearest == own[None]) & (d_own < tolerance_m)
    wrong = has & ~correct
    n = has.size
    views = observed_views(root, traj.n_frames, len(gt_labels))[:, own]
    observable = views >= 2
    by_state = {STATE_NAMES[s]: {"correct": int(np.sum(correct & (traj.state == s))),
                                 "wrong": int(np.sum(wrong & (traj.state == s)))} for s in STATE_NAMES}
    per_label = wrong.sum(axis=0)
    worst = np.argsort(-per_label)[:10]
    err = d_own[correct] * 1000
    return {
        "n": int(n), "correct": int(correct.sum()), "wrong": int(wrong.sum()), "missing": int((~has).sum()),
        "share_correct": float(correct.sum() / n), "share_wrong": float(wrong.sum() / n),
        "share_missing": float((~has).sum() / n),
        "n_observable": int(observable.sum()),
        "share_correct_observable": float((correct & observable).sum() / max(observable.sum(), 1)),
        "by_state": by_state,
        "wrong_labels": {traj.labels[i]: int(per_label[i]) for i in worst if per_label[i] > 0},
        "position_error_mm": {"median": float(np.median(err)) if err.size else float("nan"),
                              "p90": float(np.percentile(err, 90)) if err.size else float("nan")},
    }


def label_and_score(capture_dir: str | Path, *, config=None, marker_set=None) -> tuple[MarkerTrajectories, dict]:
    """Label a synthetic capture and score it (the benchmark's entry point for the labelling).

    Parameters
    ----------
    capture_dir : str or Path
        A synthetic marker capture folder.
    config : LabelConfig, optional
    marker_set : MarkerSet, optional
        Default: the capture's ``marker_set`` (``markers/calibration.toml`` metadata, else
        ``groundtruth/marker_capture.json``).

    Returns
    -------
    traj : MarkerTrajectories
    score : dict
        :func:`labelling_score` plus ``ms_per_frame`` (wall clock) and ``cpu_ms_per_frame``
        (process time) of :func:`~toolkit.markers.label.label_capture`.
    """
    import json
    import time

    from toolkit.markers.capture import load_marker_capture
    from toolkit.markers.label import LabelConfig, label_capture
    from toolkit.markers.marker_sets import get_marker_set

    root = Path(capture_dir)
    capture = load_marker_capture(root)
    if marker_set is None:
        from toolkit.io import read_calibration_metadata

        name = read_calibration_metadata(root / "markers" / "calibration.toml").get("marker_set")
        if name is None and (root / "groundtruth" / "marker_capture.json").is_file():
            name = json.loads((root / "groundtruth" / "marker_capture.json").read_text()).get("marker_set")
        if name is None:
            raise InputError(str(root), "a capture that names its marker set", "none")
        marker_set = get_marker_set(str(name))
    wall, cpu = time.perf_counter(), time.process_time()
    traj = label_capture(capture, marker_set, config=config or LabelConfig())
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    score = labelling_score(traj, root)
    score["ms_per_frame"] = 1000 * wall / max(traj.n_frames, 1)
    score["cpu_ms_per_frame"] = 1000 * cpu / max(traj.n_frames, 1)
    return traj, score
