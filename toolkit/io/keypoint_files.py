"""The files of the common 2D keypoint detectors: layouts, one camera's detections, cameras matched.

One camera's detections come either as a folder with one JSON file per frame or
as one JSON file for the whole sequence.  The layouts read (docs/keypoint_formats.md):

``openpose`` (a file per frame)
    ``{"people": [{"pose_keypoints_2d": [x0, y0, c0, x1, ...]}, ...]}`` as OpenPose
    writes it, and Pose2Sim or converters write it for other models (HALPE-26, COCO-17).
``mmpose_frame`` (a file per frame)
    ``[{"keypoints": [[x, y], ...], "keypoint_scores": [s, ...], "bbox": ...}, ...]``:
    what ``MMPoseInferencer(..., pred_out_dir=...)`` writes per image.
``mmpose_video`` (a file per camera)
    ``[{"frame_id": i, "instances": [...]}, ...]`` (``MMPoseInferencer`` on a video), or
    ``{"meta_info": {...}, "instance_info": [...]}`` (MMPose demos with ``--save-predictions``;
    ``meta_info.keypoint_id2name`` names the keypoints).
``coco_results`` (a file per camera)
    ``[{"image_id": i, "category_id": 1, "keypoints": [x0, y0, s0, ...], "score": s}, ...]``,
    the COCO keypoint results format; ``image_id`` is the frame number.
``coco_annotations`` (a file per camera)
    ``{"images": [...], "annotations": [...], "categories": [{"keypoints": [names]}]}``;
    the frame number is the last number of the image's ``file_name``; the visibility flag
    ``v`` becomes confidence 1 (``v > 0``) or missing (``v = 0``).

Keypoints come back as ``(x, y, confidence)`` pixels; NaN coordinates and confidence 0
where not detected (OpenPose's ``(0, 0, 0)``, a NaN confidence or coordinate).  A
negative or infinite confidence is an error naming the file: no detector writes one, so
the file is not what it seems (an infinite weight would also make the triangulation
infinite).  A frame with nobody is an all-missing frame, not an error.

The keypoint format of the detections is found by :mod:`toolkit.io.keypoint_formats`.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.text import load_json
from toolkit.io.openpose import _frame_number, frame_files

__all__ = ["LAYOUTS", "PER_FRAME_LAYOUTS", "CameraDetections", "read_camera_detections", "camera_sources",
           "match_cameras", "normalise_name"]

#: Layouts of keypoint files (module docstring).
LAYOUTS = ("openpose", "mmpose_frame", "mmpose_video", "coco_results", "coco_annotations")
#: Layouts holding one file per frame (the others hold a camera's whole sequence in one file).
PER_FRAME_LAYOUTS = ("openpose", "mmpose_frame")

@dataclass(frozen=True, eq=False)
class CameraDetections:
    """Every person detected by one camera.

    Attributes
    ----------
    source : Path
        The camera's folder (a file per frame) or file (the whole sequence).
    layout : str
        One of :data:`LAYOUTS`.
    files : tuple of str
        Per frame, the file its detections come from (names inside ``source`` for a folder).
    frames : ndarray of shape (T,) of int
        Frame numbers, increasing.
    people : tuple of ndarray of shape (P, K, 3)
        Per frame, ``(x, y, confidence)`` of every person (``P = 0`` when nobody).
    names : tuple of str or None
        Keypoint names given by the file (MMPose ``meta_info``, COCO ``categories``).
    """

    source: Path
    layout: str
    files: tuple[str, ...]
    frames: np.ndarray
    people: tuple[np.ndarray, ...]
    names: tuple[str, ...] | None = None

    def where(self, t: int) -> str:
        """The file of frame index ``t``, for messages."""
        return str(self.source / self.files[t]) if self.layout in PER_FRAME_LAYOUTS else str(self.source)


# --------------------------------------------------------------------------- parsing

def _load_json(path: Path):
    return load_json(path, "a readable keypoint JSON file")


def _clean(arr: np.ndarray, where: str) -> np.ndarray:
    """(K, 3) keypoints with missing ones as NaN / 0; a negative confidence raises."""
    out = np.array(arr, dtype=float)
    conf = out[:, 2]
    neg = np.flatnonzero(conf < 0)
    if neg.size:
        raise InputError(where, "confidences >= 0 (0 = not detected)",
                         f"{conf[neg[0]]:g} at keypoint {int(neg[0])} ({neg.size} negative)")
    inf = np.flatnonzero(np.isinf(conf))
    if inf.size:  # would outweigh every other view and make the triangulation infinite
        raise InputError(where, "finite confidences (0 = not detected)",
                         f"{conf[inf[0]]:g} at keypoint {int(inf[0])} ({inf.size} infinite)")
    missing = ~(conf > 0) | ~np.isfinite(out[:, :2]).all(axis=1)
    out[missing, :2] = np.nan
    out[missing, 2] = 0.0
    return out


def _numbers(value, where: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(where, "a list of numbers", repr(value)[:80]) from None
    return arr


def _flat_triples(value, where: str) -> np.ndarray:
    arr = _numbers(value, where)
    if arr.ndim != 1 or arr.size % 3:
        raise InputError(where, "a flat list of (x, y, c) triples", f"{arr.size} values")
    return _clean(arr.reshape(-1, 3), where)


def _openpose_people(data: dict, where: str) -> list[np.ndarray]:
    people = data.get("people", [])
    if not isinstance(people, list):
        raise InputError(f"{where}: people", "a list of people", type(people).__name__)
    out = []
    for i, pers in enumerate(people):
        kp = pers.get("pose_keypoints_2d") if isinstance(pers, dict) else None
        if kp:  # Pose2Sim writes {} when it associated nobody: no person
            out.append(_flat_triples(kp, f"{where}: people[{i}].pose_keypoints_2d"))
    return out


def _mmpose_instances(instances, where: str) -> list[np.ndarray]:
    if not isinstance(instances, list):
        raise InputError(where, "a list of MMPose instances", type(instances).__name__)
    out = []
    for i, inst in enumerate(instances):
        w = f"{where}[{i}]"
        if not isinstance(inst, dict) or "keypoints" not in inst:
            raise InputError(w, "an MMPose instance with 'keypoints' and 'keypoint_scores'",
                             repr(inst)[:80])
        xy = _numbers(inst["keypoints"], f"{w}.keypoints")
        if xy.size == 0:
            continue
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise InputError(f"{w}.keypoints", "a list of [x, y] pairs (2D keypoints)", f"shape {xy.shape}")
        if "keypoint_scores" not in inst:
            raise InputError(w, "'keypoint_scores' next to 'keypoints'", f"keys {sorted(inst)}")
        sc = _numbers(inst["keypoint_scores"], f"{w}.keypoint_scores").reshape(-1)
        if sc.size != len(xy):
            raise InputError(f"{w}.keypoint_scores", f"{len(xy)} scores, one per keypoint", f"{sc.size}")
        out.append(_clean(np.column_stack([xy, sc]), w))
    return out


def _frame_people(data, where: str) -> tuple[str, list[np.ndarray]]:
    """Layout and people of one per-frame file."""
    if isinstance(data, dict) and ("people" in data or "version" in data):
        return "openpose", _openpose_people(data, where)
    if isinstance(data, list):
        return "mmpose_frame", _mmpose_instances(data, where)
    found = f"keys {sorted(data)[:6]}" if isinstance(data, dict) else type(data).__name__
    raise InputError(where, "an OpenPose ({'people': [...]}) or MMPose ([{'keypoints': ...}]) frame file", found)


def _one_file_layout(data) -> str | None:
    if isinstance(data, dict) and "instance_info" in data:
        return "mmpose_video"
    if isinstance(data, dict) and "annotations" in data:
        return "coco_annotations"
    if isinstance(data, list) and data and all(isinstance(d, dict) for d in data):
        if all("instances" in d for d in data):
            return "mmpose_video"
        if all("image_id" in d for d in data):
            return "coco_results"
    return None


def _frame_of(value, where: str) -> int:
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return int(value)
    if isinstance(value, str):
        n = _frame_number(value)
        if n is not None:
            return n
    raise InputError(where, "an integer frame number (or a name ending in one)", repr(value)[:60])


def _mmpose_names(meta, where: str) -> tuple[str, ...] | None:
    if not isinstance(meta, dict):
        return None
    id2name = meta.get("keypoint_id2name")
    if isinstance(id2name, dict) and id2name:
        try:
            return tuple(str(id2name[k]) for k in sorted(id2name, key=lambda k: int(k)))
        except (TypeError, ValueError):
            raise InputError(f"{where}: meta_info.keypoint_id2name", "integer keypoint ids",
                             repr(list(id2name)[:5])) from None
    return None


def _read_one_file(path: Path, data, layout: str) -> CameraDetections:
    where = str(path)
    by_frame: dict[int, list[np.ndarray]] = {}
    names = None
    if layout == "mmpose_video":
        frames = data["instance_info"] if isinstance(data, dict) else data
        if isinstance(data, dict):
            names = _mmpose_names(data.get("meta_info"), where)
        if not isinstance(frames, list):
            raise InputError(f"{where}: instance_info", "a list of frames", type(frames).__name__)
        for i, fr in enumerate(frames):
            w = f"{where}: frame [{i}]"
            if not isinstance(fr, dict) or "instances" not in fr:
                raise InputError(w, "{'frame_id': ..., 'instances': [...]}", repr(fr)[:80])
            n = _frame_of(fr.get("frame_id", i), f"{w}.frame_id")
            if n in by_frame:
                raise InputError(w, "one entry per frame_id", f"frame_id {n} twice")
            by_frame[n] = _mmpose_instances(fr["instances"], f"{w}.instances")
    elif layout == "coco_results":
        for i, det in enumerate(data):
            w = f"{where}: [{i}]"
            n = _frame_of(det.get("image_id"), f"{w}.image_id")
            people = by_frame.setdefault(n, [])
            if "keypoints" not in det:
                raise InputError(w, "a COCO result with 'keypoints'", f"keys {sorted(det)}")
            people.append(_flat_triples(det["keypoints"], f"{w}.keypoints"))
    else:  # coco_annotations
        images = data.get("images", [])
        if not isinstance(images, list) or not isinstance(data["annotations"], list):
            raise InputError(where, "COCO 'images' and 'annotations' lists", "other types")
        cats = data.get("categories") or []
        if cats and isinstance(cats[0], dict) and cats[0].get("keypoints"):
            names = tuple(str(n) for n in cats[0]["keypoints"])
        ids = {}
        numbered = [(im.get("id"), _frame_number(str(im.get("file_name", "")))) for im in images
                    if isinstance(im, dict)]
        if numbered and all(n is not None for _, n in numbered):
            ids = dict(numbered)
        else:  # no numbers in the file names: frames by image position
            ids = {im_id: k for k, (im_id, _) in enumerate(numbered)}
        for n in ids.values():
            by_frame.setdefault(n, [])
        for i, ann in enumerate(data["annotations"]):
            w = f"{where}: annotations[{i}]"
            if not isinstance(ann, dict) or "keypoints" not in ann:
                raise InputError(w, "a COCO annotation with 'keypoints'", repr(ann)[:80])
            if ann.get("iscrowd", 0) or ann.get("num_keypoints", 1) == 0:
                continue
            if ann.get("image_id") not in ids:
                raise InputError(f"{w}.image_id", "the id of an entry of 'images'", repr(ann.get("image_id")))
            kp = _numbers(ann["keypoints"], f"{w}.keypoints")
            if kp.ndim != 1 or kp.size % 3:
                raise InputError(f"{w}.keypoints", "a flat list of (x, y, v) triples", f"{kp.size} values")
            kp = kp.reshape(-1, 3).copy()
            kp[:, 2] = np.where(kp[:, 2] > 0, 1.0, 0.0)      # visibility flag, not a confidence
            by_frame[ids[ann["image_id"]]].append(_clean(kp, w))
    order = sorted(by_frame)
    return CameraDetections(source=path, layout=layout, files=tuple(path.name for _ in order),
                            frames=np.array(order, int), people=tuple(_stack(by_frame[n]) for n in order),
                            names=names)


def _stack(people: list[np.ndarray]) -> np.ndarray:
    counts = {len(p) for p in people}
    if len(counts) > 1:  # checked with the file name by keypoint_count; keep them apart here
        return np.array(people, dtype=object)
    return np.stack(people) if people else np.zeros((0, 0, 3))


def read_camera_detections(path: str | os.PathLike, max_frames: int | None = None) -> CameraDetections:
    """Every detection of one camera: a folder of per-frame files or one file.

    Parameters
    ----------
    path : path-like
        A folder of JSON files (one per frame, ordered by the last number of their names)
        or one JSON file holding the whole sequence.
    max_frames : int, optional
        Keep only the first frames.

    Returns
    -------
    CameraDetections

    Raises
    ------
    InputError
        A missing path, an empty folder, a file of no known layout, duplicated frame numbers,
        or a malformed file (named, with the field).
    """
    p = Path(path)
    if p.is_dir():
        files, frames = frame_files(p, "keypoint JSON files (*.json), one per frame", max_frames)
        layouts, people = set(), []
        for f in files:
            data = _load_json(f)
            whole = _one_file_layout(data)
            if whole is not None:
                raise InputError(str(f), "one frame per file inside a camera folder",
                                 f"a whole-sequence {whole} file (put it directly in the keypoints folder, "
                                 "one file per camera)")
            layout, pp = _frame_people(data, str(f))
            layouts.add(layout)
            people.append(_stack(pp))
        layout = "openpose" if "openpose" in layouts else "mmpose_frame"
        return CameraDetections(source=p, layout=layout, files=tuple(f.name for f in files), frames=frames,
                                people=tuple(people))
    if p.is_file():
        data = _load_json(p)
        layout = _one_file_layout(data)
        if layout is None:
            raise InputError(str(p), "a whole-sequence keypoint file (MMPose predictions with frame_id/instances, "
                             "COCO results or annotations)",
                             "a per-frame file (put each camera's per-frame files in its own folder)"
                             if isinstance(data, (dict, list)) else type(data).__name__)
        det = _read_one_file(p, data, layout)
        if max_frames is not None:
            det = CameraDetections(det.source, det.layout, det.files[:max_frames], det.frames[:max_frames],
                                   det.people[:max_frames], det.names)
        return det
    raise InputError(str(p), "a folder of per-frame keypoint files or a keypoint JSON file", "no such path")


def camera_sources(root: str | os.PathLike) -> list[Path]:
    """The keypoint source of every camera in ``root``, sorted by name.

    Sub-folders (not hidden) when there are any (one per camera, a file per frame),
    else the JSON files of ``root`` (one per camera, the whole sequence).

    Raises
    ------
    InputError
        No such folder, or neither sub-folders nor JSON files.
    """
    r = Path(root)
    if not r.is_dir():
        raise InputError(str(r), "a folder with one sub-folder (or one JSON file) of keypoints per camera",
                         "no such folder")
    subs = sorted((p for p in r.iterdir() if p.is_dir() and not p.name.startswith(".")), key=lambda p: p.name)
    if subs:
        return subs
    files = sorted((p for p in r.iterdir() if p.is_file() and p.suffix.lower() == ".json"
                    and not p.name.startswith(".")), key=lambda p: p.name)
    if not files:
        raise InputError(str(r), "one sub-folder (a JSON file per frame) or one JSON file of keypoints per camera",
                         "neither sub-folders nor JSON files")
    return files


# --------------------------------------------------------------------------- cameras

def normalise_name(name: str) -> str:
    """A name compared without case, punctuation or spelling of sides: ``left_shoulder`` is ``LShoulder``."""
    return re.sub(r"[^0-9a-z]", "", name.lower().replace("left", "l").replace("right", "r"))


def _name_hits(camera: str, source: str) -> bool:
    c, s = normalise_name(camera), normalise_name(source)
    for m in re.finditer(re.escape(c), s):
        before = s[m.start() - 1] if m.start() else ""
        after = s[m.end()] if m.end() < len(s) else ""
        if not (c[-1:].isdigit() and after.isdigit()) and not (c[:1].isdigit() and before.isdigit()):
            return True
    return False


def _last_number(name: str) -> int | None:
    nums = re.findall(r"\d+", name)
    return int(nums[-1]) if nums else None


def match_cameras(camera_names: list[str], sources: list[Path], what: str) -> tuple[list[int], str]:
    """Which keypoint source belongs to which calibration camera.

    By name when every source name contains exactly one camera name and the reverse
    (``cam01_json`` is ``cam_01``); else by the number in the names when both sides
    are numbered alike (``cam_1`` is ``camera01.json``); else by sorted order when no
    source name mentions any camera.

    Parameters
    ----------
    camera_names : list of str
    sources : list of Path
    what : str
        The keypoints folder, for messages.

    Returns
    -------
    order : list of int
        For each camera, the index of its source.
    how : str
        ``"by name"``, ``"by number"`` or ``"by order"``.

    Raises
    ------
    InputError
        Another count of sources than of cameras, or names that match only in part or
        ambiguously, naming the cameras and sources left over.
    """
    stems = [s.stem if s.is_file() else s.name for s in sources]
    exp = f"{len(camera_names)} entries, one per calibration camera {list(camera_names)}"
    found = f"{len(sources)}: {[s.name for s in sources]}"
    if len(camera_names) != len(sources):
        raise InputError(what, exp, found)
    hits = np.array([[_name_hits(c, s) for s in stems] for c in camera_names], bool)
    if hits.any():
        if (hits.sum(0) == 1).all() and (hits.sum(1) == 1).all():
            return [int(np.flatnonzero(row)[0]) for row in hits], "by name"
        cams_left = [c for c, row in zip(camera_names, hits) if row.sum() != 1]
        srcs_left = [s.name for s, col in zip(sources, hits.T) if col.sum() != 1]
        if cams_left or srcs_left:
            nums_c = [_last_number(c) for c in camera_names]
            nums_s = [_last_number(s) for s in stems]
            if not (None in nums_c or None in nums_s or len(set(nums_c)) < len(nums_c)
                    or sorted(nums_c) != sorted(nums_s) or len(set(nums_s)) < len(nums_s)):
                return [nums_s.index(n) for n in nums_c], "by number"
            raise InputError(what, f"one camera folder or file per calibration camera, matched by name ({exp})",
                             f"cameras without (or with several) matches {cams_left}, sources {srcs_left}")
    nums_c = [_last_number(c) for c in camera_names]
    nums_s = [_last_number(s) for s in stems]
    if None not in nums_c and None not in nums_s and len(set(nums_c)) == len(nums_c) \
            and len(set(nums_s)) == len(nums_s):
        if sorted(nums_c) == sorted(nums_s):
            return [nums_s.index(n) for n in nums_c], "by number"
        raise InputError(what, f"sources numbered like the calibration cameras {list(camera_names)}",
                         f"{[s.name for s in sources]}")
    return list(range(len(sources))), "by order"
