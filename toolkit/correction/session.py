"""The state behind the correction page: a run's 2D poses, the user's edits, re-triangulation, undo, commit.

A :class:`CorrectionSession` opens the output folder of
``recipes/pose_from_silhouettes.py`` (``poses2d.npz``, ``poses3d.npz``,
``offsets.npz``) or of ``recipes/free_viewpoint.py`` (``frames/NNNNNN.json``),
with the cameras the run used (``RUN/calibration.toml``) and its dataset (the
folder named in that file's metadata, or given).  Per frame it holds every
camera's 2D joints in image pixels (what the viewer shows: the positions
before the multi-view step's per-view offsets), the 3D joints and the
multi-view cost.

Moving a joint (:meth:`CorrectionSession.move_joint`) replaces that joint,
re-triangulates the frame exactly as stage 1 does with corrected poses
(:func:`toolkit.multiview.select_multiview` with the corrected 2D poses as the
only candidates, no flips, starting from the frame's offsets), and rewrites
``RUN/edits.toml`` atomically in the format of
:mod:`toolkit.silhouettes.edits`, so ``pose_from_silhouettes.py --edits
RUN/edits.toml`` applies the same corrections.  :meth:`~CorrectionSession.undo`
takes back the frame's last move.  :meth:`~CorrectionSession.commit` adds the
frame's poses, each with the view's silhouette, to the silhouette database
and saves it atomically (source 000 claim 7); the frame's edits are then
marked ``add_to_database = false`` so that a later ``--edits`` run does not
add them a second time.

Only two files are ever written: ``RUN/edits.toml`` and the database file.

A ``free_viewpoint.py`` run does not store its stage-1 2D poses: its 2D joints
are the projections of the stage-1 3D joints minus the offsets (the positions
that the selection's rays went through), and its cost is not known until a
joint is moved (``None``).
"""

from __future__ import annotations

import json
import math
import os
import threading
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14

#: File the session writes the corrections to, inside the run folder.
EDITS_FILE = "edits.toml"
#: Run kinds: stage 1 (``pose_from_silhouettes.py``) or the whole pipeline (``free_viewpoint.py``).
RUN_KINDS = ("pose_from_silhouettes", "free_viewpoint")
#: Normalised joints closer than this (fraction of the silhouette box) count as the same database pose.
SAME_POSE_TOLERANCE = 1e-3

_J = SKELETON_14.n_joints
_NAMES = SKELETON_14.joint_names


class NotFound(LookupError):
    """An unknown frame, camera or joint (the page's API answers 404 with the message)."""


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _xy_dict(pose: np.ndarray) -> dict[str, list[float] | None]:
    """``{joint: [x, y]}`` of a (14, 2) array; ``None`` for a missing joint."""
    return {n: ([float(p[0]), float(p[1])] if np.isfinite(p).all() else None) for n, p in zip(_NAMES, pose)}


@dataclass
class FrameState:
    """One frame's current estimate.

    Attributes
    ----------
    poses2d : ndarray of shape (n_cams, 14, 2)
        Image pixels (before offsets); NaN = missing.
    offsets : ndarray of shape (n_cams, 2)
        Pixels added to the 2D joints before triangulation; NaN for a view not used.
    joints3d : ndarray of shape (14, 3)
        Metres, world frame.
    cost : float
        Mean ray distance of the triangulation, metres (NaN: unknown).
    history : list of (int, int, ndarray of shape (2,), bool)
        Moves to undo: camera index, joint index, previous position, whether it was edited before.
    edited : ndarray of shape (n_cams, 14) of bool
        Joints the user set.
    """

    poses2d: np.ndarray
    offsets: np.ndarray
    joints3d: np.ndarray
    cost: float
    edited: np.ndarray
    history: list = field(default_factory=list)
    committed: np.ndarray | None = None  # (n_cams,) bool: views whose pose is in the database as it is


class CorrectionSession:
    """A run folder opened for correction.

    Parameters
    ----------
    run : path
        Output folder of ``pose_from_silhouettes.py`` or ``free_viewpoint.py``.
    dataset : path, optional
        The dataset the run was made from (default: the folder of the
        calibration named in ``RUN/calibration.toml``'s metadata).
    database : path, optional
        Silhouette database file that commits grow (default: the cached
        default database that the recipes use without ``--db``).
    foreground : {"median", "mog2", "knn", "chroma"}
        How the silhouettes added to the database are cut (as the recipes'
        ``--foreground``).

    Raises
    ------
    InputError
        A folder that is not such a run, unreadable results, no dataset, an
        existing ``RUN/edits.toml`` that is not valid.
    """

    def __init__(self, run: str | os.PathLike, dataset: str | os.PathLike | None = None,
                 database: str | os.PathLike | None = None, foreground: str = "median"):
        from toolkit.calibration import refined_cameras
        from toolkit.io import Dataset, read_calibration, read_calibration_metadata
        from toolkit.silhouettes import Stage1Config, default_database_path

        self.run = Path(run)
        if not self.run.is_dir():
            raise InputError(str(self.run), "a run folder of pose_from_silhouettes.py or free_viewpoint.py",
                             "no such folder")
        cal = self.run / "calibration.toml"
        if not cal.is_file():
            raise InputError(str(cal), "the calibration the run used (written by the recipes)", "no such file")
        self.rig = read_calibration(cal)
        self.camera_names: list[str] = list(self.rig.names)
        if dataset is None:
            source = read_calibration_metadata(cal).get("source", "")
            if not source:
                raise InputError(f"{cal}: metadata.source", "the dataset's calibration path (or give --dataset)",
                                 "nothing")
            dataset = Path(source).parent
        self.dataset = Dataset.open(dataset, check_sizes=False)
        missing = [c for c in self.camera_names if c not in self.dataset.camera_names]
        if missing:
            raise InputError(str(dataset), f"a dataset with the run's cameras {self.camera_names}",
                             f"no camera {missing}")
        self.database_path = Path(database) if database is not None else default_database_path()
        if foreground not in ("median", "mog2", "knn", "chroma"):
            raise InputError("foreground", "one of median, mog2, knn, chroma", repr(foreground))
        self.foreground = foreground
        self.multiview = replace(Stage1Config().with_refined_cameras(refined_cameras(self.run)).multiview,
                                 flips=())
        from toolkit.anthropometry import AnthropometricConstraints
        self.constraints = self.multiview.constraints or AnthropometricConstraints()
        self.lock = threading.RLock()
        self._extractors: dict = {}
        self.kind, self._frames = self._load()
        self._apply_edits_file()

    # ------------------------------------------------------------------ loading
    def _load(self) -> tuple[str, dict[int, FrameState]]:
        n_cams = len(self.camera_names)
        p2 = self.run / "poses2d.npz"
        if p2.is_file():
            return "pose_from_silhouettes", self._load_stage1(p2, n_cams)
        folder = self.run / "frames"
        files = sorted(folder.glob("*.json")) if folder.is_dir() else []
        if files:
            return "free_viewpoint", self._load_fvv(files, n_cams)
        raise InputError(str(self.run), "poses2d.npz (pose_from_silhouettes.py) or frames/*.json "
                         "(free_viewpoint.py)", "neither")

    def _load_stage1(self, p2: Path, n_cams: int) -> dict[int, FrameState]:
        from toolkit.io.stage_outputs import read_stage1_output
        from toolkit.silhouettes.estimate import FRAME_NOT_PROCESSED

        s1 = read_stage1_output(self.run, cameras=self.camera_names)
        missing = [c for c in self.camera_names if c not in s1.poses2d]
        if missing:
            raise InputError(str(p2), f"a (T, {_J}, 2) array per camera {list(self.camera_names)}", f"no {missing}")
        for name, file in (("state", "poses3d.npz"), ("cost", "poses3d.npz")):
            if getattr(s1, name) is None:
                raise InputError(str(self.run / file), f"an array '{name}' (T,)", "none")
        if not (self.run / "offsets.npz").is_file():
            raise InputError(str(self.run / "offsets.npz"), "an existing .npz file", "no such file")
        stack = np.stack([s1.poses2d[c] for c in self.camera_names], axis=1)  # (T, C, 14, 2)
        return {t: FrameState(stack[t].astype(float), s1.offsets[t].astype(float), s1.joints[t].astype(float),
                              float(s1.cost[t]), np.zeros((n_cams, _J), bool))
                for t in range(s1.n_frames) if s1.state[t] != FRAME_NOT_PROCESSED}

    def _load_fvv(self, files: list[Path], n_cams: int) -> dict[int, FrameState]:
        out = {}
        for f in files:
            try:
                rec = json.loads(f.read_text(encoding="utf-8"))
                t = int(rec["frame"])
                joints = np.asarray(rec["joints_stage1"], float).reshape(_J, 3)
                offsets = np.asarray(rec["offsets"], float).reshape(n_cams, 2)
            except (OSError, ValueError, KeyError, TypeError) as e:
                raise InputError(str(f), f"a frame record with frame, joints_stage1 ({_J}, 3) and offsets "
                                 f"({n_cams}, 2)", f"{type(e).__name__}: {e}") from None
            proj = self.rig.project(joints) - np.where(np.isfinite(offsets), offsets, 0.0)[:, None]
            out[t] = FrameState(proj, offsets, joints, float("nan"), np.zeros((n_cams, _J), bool))
        return out

    def _apply_edits_file(self) -> None:
        """Corrections already in ``RUN/edits.toml`` (an earlier session) applied and re-triangulated."""
        from toolkit.silhouettes import read_edits

        path = self.run / EDITS_FILE
        if not path.is_file():
            return
        edits = read_edits(path, self.camera_names)
        for t in sorted(edits.frames):
            if t not in self._frames:
                continue
            st = self._frames[t]
            for cam, e in edits.for_frame(t).items():
                v = self.camera_names.index(cam)
                for name, xy in e.joints:
                    j = SKELETON_14.index(name)
                    st.poses2d[v, j] = xy
                    st.edited[v, j] = True
            self._retriangulate(t)

    # --------------------------------------------------------------- queries
    @property
    def frames(self) -> list[int]:
        """Frames with an estimate, increasing."""
        return sorted(self._frames)

    def _frame(self, t: int) -> FrameState:
        if t not in self._frames:
            raise NotFound(f"frame {t} is not in the run {self.run} (frames {self._span()})")
        return self._frames[t]

    def _span(self) -> str:
        f = self.frames
        return f"{f[0]}..{f[-1]}" if f else "none"

    def _camera(self, camera: str) -> int:
        if camera not in self.camera_names:
            raise NotFound(f"camera {camera!r} is not a camera of the run (cameras {self.camera_names})")
        return self.camera_names.index(camera)

    @staticmethod
    def _joint(joint: str) -> int:
        if joint not in _NAMES:
            raise NotFound(f"joint {joint!r} is not a joint of the skeleton (joints {list(_NAMES)})")
        return SKELETON_14.index(joint)

    def reprojections(self, t: int) -> np.ndarray:
        """The 3D joints seen in every view, image pixels (n_cams, 14, 2): projection minus offset."""
        st = self._frame(t)
        off = np.where(np.isfinite(st.offsets), st.offsets, 0.0)
        return self.rig.project(st.joints3d) - off[:, None]

    def violations(self, t: int) -> list[dict]:
        """Broken anthropometric rules of the frame's 3D joints, with the joints they involve."""
        st = self._frame(t)
        if not np.isfinite(st.joints3d).any():
            return []
        out = []
        for v in self.constraints.violations(st.joints3d):
            if v.kind == "non_finite":
                continue
            joints = [n for n in _NAMES if n in _split_names(v.what)]
            out.append({"kind": v.kind, "what": v.what, "joints": joints, "text": str(v)})
        return out

    def frame_json(self, t: int) -> dict:
        """The frame as the API returns it (see ``docs/correction.md``)."""
        with self.lock:
            st = self._frame(t)
            reproj = self.reprojections(t)
            return {
                "frame": int(t),
                "cameras": {c: _xy_dict(st.poses2d[v]) for v, c in enumerate(self.camera_names)},
                "joints3d": {n: ([float(x) for x in p] if np.isfinite(p).all() else None)
                             for n, p in zip(_NAMES, st.joints3d)},
                "cost": _finite_or_none(st.cost),
                "reprojections": {c: _xy_dict(reproj[v]) for v, c in enumerate(self.camera_names)},
                "offsets": {c: ([float(x) for x in st.offsets[v]] if np.isfinite(st.offsets[v]).all() else None)
                            for v, c in enumerate(self.camera_names)},
                "edited": {c: [n for n, e in zip(_NAMES, st.edited[v]) if e] for v, c in enumerate(self.camera_names)},
                "violations": self.violations(t),
                "undo": len(st.history),
            }

    def info(self) -> dict:
        """Run-level facts the page needs once: cameras and image sizes, skeleton, files."""
        return {"run": str(self.run), "kind": self.kind, "dataset": str(self.dataset.root),
                "database": str(self.database_path), "frames": self.frames,
                "cameras": {c.name: {"size": [int(c.size[0]), int(c.size[1])]} for c in self.rig},
                "joints": list(_NAMES), "bones": [[_NAMES[a], _NAMES[b]] for a, b in SKELETON_14.bones]}

    # ----------------------------------------------------------------- edits
    def move_joint(self, t: int, camera: str, joint: str, xy) -> dict:
        """Set one joint of one view, re-triangulate the frame, rewrite ``RUN/edits.toml``.

        Parameters
        ----------
        t : int
        camera, joint : str
        xy : sequence of 2 float
            Image pixels (the viewer's coordinates, centre of the top-left pixel at 0, 0).

        Returns
        -------
        dict
            The frame as :meth:`frame_json`.

        Raises
        ------
        NotFound
            Unknown frame, camera or joint.
        InputError
            ``xy`` not two finite numbers.
        """
        with self.lock:
            st = self._frame(t)
            v, j = self._camera(camera), self._joint(joint)
            p = np.asarray(xy, float)
            if p.shape != (2,) or not np.isfinite(p).all():
                raise InputError("xy", "two finite pixel coordinates [x, y]", repr(xy))
            st.history.append((v, j, st.poses2d[v, j].copy(), bool(st.edited[v, j])))
            st.poses2d[v, j] = p
            st.edited[v, j] = True
            st.committed = None
            self._retriangulate(t)
            self._write_edits()
            return self.frame_json(t)

    def undo(self, t: int) -> dict:
        """Take back the frame's last move (nothing when there is none); returns the frame."""
        with self.lock:
            st = self._frame(t)
            if st.history:
                v, j, old, was_edited = st.history.pop()
                st.poses2d[v, j] = old
                st.edited[v, j] = was_edited
                st.committed = None
                self._retriangulate(t)
                self._write_edits()
            return self.frame_json(t)

    def _retriangulate(self, t: int) -> None:
        """Triangulate the frame's 2D poses as stage 1 does with corrections (offsets refitted)."""
        from toolkit.multiview import select_multiview

        st = self._frames[t]
        init = np.where(np.isfinite(st.offsets), st.offsets, 0.0)
        views = np.isfinite(st.poses2d).all(-1).any(-1)
        if views.sum() < 2:
            st.joints3d, st.cost = np.full((_J, 3), np.nan), float("nan")
            return
        sel = select_multiview(st.poses2d[:, None], self.rig, self.multiview, initial_offsets=init,
                               previous_joints3d=st.joints3d if np.isfinite(st.joints3d).all() else None)
        if sel.success:
            st.joints3d = np.asarray(sel.joints3d, float)
            st.offsets = np.where(sel.views_used[:, None], sel.offsets, np.nan)
            st.cost = float(sel.cost)
        else:
            st.joints3d, st.cost = np.full((_J, 3), np.nan), float("nan")

    def _edit_tables(self) -> list[dict]:
        out = []
        for t in self.frames:
            st = self._frames[t]
            for v, cam in enumerate(self.camera_names):
                js = np.flatnonzero(st.edited[v])
                if len(js):
                    out.append({"frame": t, "camera": cam,
                                "add_to_database": not (st.committed is not None and st.committed[v]),
                                "joints": {_NAMES[j]: st.poses2d[v, j] for j in js}})
        return out

    def _write_edits(self) -> None:
        """``RUN/edits.toml`` with every edited joint (atomic: temporary file and rename)."""
        from toolkit.io import atomic_write_text

        lines = [f"# Corrections made with recipes/correct_poses.py on {self.run.name}",
                 "# Joint positions in pixels of each camera's image (top-left pixel centre = 0, 0);",
                 f"# apply with: recipes/pose_from_silhouettes.py DATASET --out OUT --edits {EDITS_FILE}", ""]
        for e in self._edit_tables():
            lines += ["[[edit]]", f"frame = {e['frame']}", f"camera = {json.dumps(e['camera'])}"]
            if not e["add_to_database"]:
                lines.append("add_to_database = false   # already added by the correction page")
            lines.append("[edit.joints]")
            lines += [f"{n} = [{xy[0]:.3f}, {xy[1]:.3f}]" for n, xy in e["joints"].items()]
            lines.append("")
        atomic_write_text(self.run / EDITS_FILE, "\n".join(lines))

    # ---------------------------------------------------------------- commit
    def silhouette(self, camera: str, t: int) -> np.ndarray:
        """The camera's silhouette in frame ``t`` (H, W) bool, cut as stage 1 cuts it."""
        from toolkit.foreground import BackgroundConfig, ForegroundConfig, ForegroundExtractor
        from toolkit.io import VideoReader

        ex = self._extractors.get(camera)
        if ex is None:
            cfg = ForegroundConfig(method="chroma") if self.foreground == "chroma" else \
                ForegroundConfig(background=replace(BackgroundConfig(), method=self.foreground))
            plate = self.dataset.background(camera)
            if plate is not None:
                ex = ForegroundExtractor(cfg).fit([plate])
            else:
                reader = VideoReader(self.dataset.video_path(camera))
                try:
                    ex = ForegroundExtractor(cfg).fit(reader)
                finally:
                    reader.close()
            self._extractors[camera] = ex
        return np.asarray(ex.extract(self.dataset.frame(camera, t)).mask, bool)

    def commit(self, t: int) -> dict:
        """Add the frame's poses, with their silhouettes, to the database and save it atomically.

        Every view whose 14 joints are known and whose silhouette is not empty
        is added (entries of motion ``"user"``), unless the same pose of that
        view is already in the database from an earlier commit.

        Returns
        -------
        dict
            ``added`` (entries added), ``database`` (its path), ``size``
            (entries now), ``skipped`` ({camera: reason}).
        """
        from toolkit.silhouettes import SilhouetteDatabase
        from toolkit.silhouettes.database import USER_MOTION, DatabaseEntry

        with self.lock:
            st = self._frame(t)
            if not self.database_path.is_file():
                raise InputError(str(self.database_path), "an existing silhouette database to add the poses to",
                                 "no such file")
            db = SilhouetteDatabase.load(self.database_path)
            n0 = len(db)
            skipped: dict[str, str] = {}
            committed = np.zeros(len(self.camera_names), bool)
            for v, cam in enumerate(self.camera_names):
                pose = st.poses2d[v]
                if not np.isfinite(pose).all():
                    skipped[cam] = "not all 14 joints known"
                    continue
                mask = self.silhouette(cam, t)
                if not mask.any():
                    skipped[cam] = "empty silhouette"
                    continue
                source = f"{self.run.name} {cam} frame {t}"
                entry = DatabaseEntry.from_silhouette(mask, pose, motion=USER_MOTION, frame=t, source=source)
                same = np.flatnonzero(np.asarray(db.source) == source)
                if any(np.abs(np.asarray(db.joints[i], float) - entry.joints).max() < SAME_POSE_TOLERANCE
                       for i in same):
                    skipped[cam] = "already in the database"
                    committed[v] = True
                    continue
                db.add(entry)
                committed[v] = True
            if len(db) > n0:
                db.save(self.database_path)
            st.committed = committed
            if st.edited.any():
                self._write_edits()
            return {"added": len(db) - n0, "database": str(self.database_path), "size": len(db),
                    "skipped": skipped}

    def image(self, camera: str, t: int) -> np.ndarray:
        """The camera's frame ``t`` (H, W, 3) uint8 RGB."""
        with self.lock:  # one video reader per camera, not thread-safe
            self._frame(t)
            self._camera(camera)
            return self.dataset.frame(camera, t)

    def close(self) -> None:
        self.dataset.close()


def _split_names(what: str) -> set[str]:
    """Joint names in a violation's ``what`` (``"l_knee"``, ``"l_hip-l_knee"``, ``"l_hip-l_knee / r_hip-r_knee"``)."""
    out = set()
    for tok in what.replace("/", " ").replace(",", " ").replace("(", " ").replace(")", " ").split():
        for part in tok.split("-"):
            if part in _NAMES:
                out.add(part)
    return out
