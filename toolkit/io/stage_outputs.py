"""Typed stage outputs: one writer and one reader per output folder kind.

A stage's results reach the next stage as a frozen dataclass of arrays, and
as files only through the writer and the reader here (issue 16 item 2):

* :class:`Stage1Output`: stage 1 from silhouettes
  (``recipes/pose_from_silhouettes.py``): ``poses3d.npz``, ``offsets.npz``,
  ``poses2d.npz``; :func:`write_stage1` and :func:`read_stage1_output`.
* :class:`FreeViewpointPoses`: the joints of ``recipes/free_viewpoint.py``
  (``poses3d.npz``); :func:`write_free_viewpoint_poses` and
  :func:`read_free_viewpoint_poses`.

The files and their keys are the ones the runs wrote before these types
existed, so older folders stay readable.  The cameras stage 1 used
(``calibration.toml``) are written and read by :mod:`toolkit.io.calibration`
and :func:`toolkit.calibration.stage_rig`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.skeleton.skeleton import JOINTS_14

#: The files of a stage-1 folder (:func:`write_stage1`).
STAGE1_FILES = ("poses2d.npz", "poses3d.npz", "offsets.npz")
#: Per-view arrays of ``poses2d.npz`` besides one pose array per camera (they may not be camera names).
STAGE1_VIEW_KEYS = ("view_state", "bbox", "candidates", "candidate_errors", "candidate_index", "edited")
_NOT_CAMERAS = frozenset(STAGE1_VIEW_KEYS + ("cameras", "names"))
_N_JOINTS = len(JOINTS_14)


def _shaped(where: str, a, shape: tuple, sizes: dict, dtype=None) -> np.ndarray:
    """``a`` as an array of ``shape`` (ints, or names bound in ``sizes`` on first use), else InputError."""
    a = np.asarray(a) if dtype is None else np.asarray(a, dtype)
    want = []
    for s in shape:
        want.append(sizes.setdefault(s, None) if isinstance(s, str) else s)
    ok = a.ndim == len(shape) and all(w is None or w == n for w, n in zip(want, a.shape))
    if not ok:
        text = ", ".join(str(s if not isinstance(s, str) or sizes[s] is None else f"{s}={sizes[s]}") for s in shape)
        raise InputError(where, f"an array of shape ({text})", f"shape {a.shape}")
    for s, n in zip(shape, a.shape):
        if isinstance(s, str) and sizes[s] is None:
            sizes[s] = n
    return a


@dataclass(frozen=True, eq=False)
class Stage1Output:
    """What stage 1 from silhouettes hands on: 3D joints, offsets, 2D poses and states of a sequence.

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3)
        World frame, metres, NaN = no estimate (``poses3d.npz`` ``joints``).
    cameras : tuple of str
        The views, in the order of the offsets' and per-view arrays' second axis (``cameras``).
    offsets : ndarray of shape (T, n_cams, 2)
        Image-space corrections in the one offset convention (docs/architecture.md):
        pixels, x right, y down, *added to the detected 2D joints*, so a world point appears at
        ``camera.project(X) - offset``; consumers take the corrected cameras
        (``toolkit.multiview.corrected_rig``).  NaN for a view that took no part.
    poses2d : dict of str -> ndarray of shape (T, 14, 2)
        Each view's chosen 2D pose, image pixels (``poses2d.npz``, one array per camera);
        empty when not read.
    state : ndarray of shape (T,) uint8, optional
        Per-frame state code (``toolkit.silhouettes.pipeline.FRAME_*``, named by
        ``FRAME_STATES``); None when the folder has none.
    cost : ndarray of shape (T,), optional
        Multi-view selection cost per frame, metres.
    joint_names : tuple of str
        The 14 joints' names (``names``).
    view_state : ndarray of shape (T, n_cams) uint8, optional
        Per-view state code (``toolkit.silhouettes.descriptor.STATE_*``).
    bbox : ndarray of shape (T, n_cams, 4), optional
        Each view's silhouette box, pixels.
    candidates : ndarray of shape (T, n_cams, k, 14, 2), optional
        The k database candidates per view, image pixels.
    candidate_errors : ndarray of shape (T, n_cams, k), optional
    candidate_index : ndarray of shape (T, n_cams, k) int64, optional
        Database entries of the candidates, -1 = none.
    edited : ndarray of shape (T, n_cams) bool, optional
        Views whose pose a user edit set.

    Raises
    ------
    InputError
        A field of another shape than the one above (the field named).
    """

    joints: np.ndarray
    cameras: tuple
    offsets: np.ndarray
    poses2d: dict = field(default_factory=dict)
    state: np.ndarray | None = None
    cost: np.ndarray | None = None
    joint_names: tuple = tuple(JOINTS_14)
    view_state: np.ndarray | None = None
    bbox: np.ndarray | None = None
    candidates: np.ndarray | None = None
    candidate_errors: np.ndarray | None = None
    candidate_index: np.ndarray | None = None
    edited: np.ndarray | None = None

    #: Optional fields and their shapes (T frames, C cameras, k candidates).
    SHAPES = {"state": ("T",), "cost": ("T",), "view_state": ("T", "C"), "bbox": ("T", "C", 4),
              "candidates": ("T", "C", "k", _N_JOINTS, 2), "candidate_errors": ("T", "C", "k"),
              "candidate_index": ("T", "C", "k"), "edited": ("T", "C")}

    def __post_init__(self):
        cams = tuple(str(c) for c in self.cameras)
        object.__setattr__(self, "cameras", cams)
        object.__setattr__(self, "joint_names", tuple(str(n) for n in self.joint_names))
        clash = _NOT_CAMERAS & set(cams)
        if clash or len(set(cams)) != len(cams):
            raise InputError("Stage1Output.cameras", f"distinct names other than {sorted(_NOT_CAMERAS)}",
                             f"{list(cams)}")
        if len(self.joint_names) != _N_JOINTS:
            raise InputError("Stage1Output.joint_names", f"{_N_JOINTS} names", f"{len(self.joint_names)}")
        sizes = {"C": len(cams)}
        for name, shape in (("joints", ("T", _N_JOINTS, 3)), ("offsets", ("T", "C", 2))):
            object.__setattr__(self, name, _shaped(f"Stage1Output.{name}", getattr(self, name), shape, sizes))
        unknown = set(self.poses2d) - set(cams)
        if unknown:
            raise InputError("Stage1Output.poses2d", f"poses of the cameras {list(cams)}", f"{sorted(unknown)}")
        object.__setattr__(self, "poses2d", {c: _shaped(f"Stage1Output.poses2d[{c!r}]", p, ("T", _N_JOINTS, 2), sizes)
                                             for c, p in self.poses2d.items()})
        for name, shape in self.SHAPES.items():
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _shaped(f"Stage1Output.{name}", getattr(self, name), shape, sizes))

    @property
    def n_frames(self) -> int:
        return int(np.shape(self.joints)[0])

    def arrays(self) -> dict[str, dict[str, np.ndarray]]:
        """The arrays of each file (``poses2d``, ``poses3d``, ``offsets``) as :func:`write_stage1` writes them."""
        cams = np.array(self.cameras)
        p2 = dict(self.poses2d)
        p2.update({k: getattr(self, k) for k in STAGE1_VIEW_KEYS if getattr(self, k) is not None})
        p2["cameras"] = cams
        p3 = {"joints": self.joints, "names": np.array(self.joint_names)}
        p3.update({k: getattr(self, k) for k in ("state", "cost") if getattr(self, k) is not None})
        off = {"offsets": self.offsets, "cameras": cams}
        if self.state is not None:
            off["state"] = self.state
        return {"poses2d": p2, "poses3d": p3, "offsets": off}


def write_stage1(folder, output: Stage1Output) -> list[Path]:
    """Write a stage-1 output into ``folder``: ``poses2d.npz``, ``poses3d.npz``, ``offsets.npz`` (atomic).

    Parameters
    ----------
    folder : path
        Created if missing.
    output : Stage1Output

    Returns
    -------
    list of Path
        The files written.

    Notes
    -----
    Keys: ``poses2d.npz``: one (T, 14, 2) array per camera, the per-view arrays
    present (:data:`STAGE1_VIEW_KEYS`), ``cameras``; ``poses3d.npz``: ``joints``,
    ``names``, ``state`` and ``cost`` when present; ``offsets.npz``: ``offsets``,
    ``cameras``, ``state`` when present.
    """
    from toolkit.io.atomic import atomic_save_npz

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [atomic_save_npz(folder / f"{name}.npz", **arrays) for name, arrays in output.arrays().items()]


def _load(path: Path, required: bool) -> dict | None:
    from toolkit.io.layout import load_npz

    if not required and not path.exists():
        return None
    return load_npz(path)


def _key(data: dict, path: Path, key: str, what: str) -> np.ndarray:
    if key not in data:
        raise InputError(str(path), f"an array '{key}' ({what})", f"arrays {sorted(data)}")
    return data[key]


def _names(data: dict | None, path: Path) -> tuple | None:
    if data is None or "cameras" not in data:
        return None
    return tuple(str(c) for c in _shaped(f"{path}:cameras", data["cameras"], ("C",), {}))


def read_stage1_output(folder, *, cameras=None, poses2d: bool = True) -> Stage1Output:
    """Read a stage-1 output folder written by :func:`write_stage1` (or by hand with its keys).

    Parameters
    ----------
    folder : path
        ``poses3d.npz`` (required: ``joints``), ``offsets.npz`` (optional:
        offsets 0 without it), ``poses2d.npz`` (read with ``poses2d``).
    cameras : sequence of str, optional
        The cameras the folder must hold, in order (e.g. the dataset's); needed
        when no file names them (``cameras`` in ``offsets.npz`` or ``poses2d.npz``).
    poses2d : bool
        Also read ``poses2d.npz`` (each view's 2D pose and per-view arrays; missing file: none).

    Returns
    -------
    Stage1Output

    Raises
    ------
    InputError
        A missing ``poses3d.npz`` or ``joints``; an array of another shape than
        :class:`Stage1Output` documents (the file and key named); files naming
        other cameras than each other or than ``cameras``; no camera names at all.
    """
    folder = Path(folder)
    p3_path, off_path, p2_path = (folder / f for f in ("poses3d.npz", "offsets.npz", "poses2d.npz"))
    p3 = _load(p3_path, True)
    off = _load(off_path, False)
    p2 = _load(p2_path, False) if poses2d else None
    names = {str(p): n for p, n in ((off_path, _names(off, off_path)), (p2_path, _names(p2, p2_path))) if n}
    if cameras is not None:
        names["the given cameras"] = tuple(str(c) for c in cameras)
    if not names:
        raise InputError(str(folder), "camera names ('cameras' in offsets.npz or poses2d.npz, or given)", "none")
    (src, cams), *rest = names.items()
    for other, n in rest:
        if n != cams:
            raise InputError(other, f"the cameras {list(cams)} ({src})", f"{list(n)}")
    sizes = {"C": len(cams)}
    joints = _shaped(f"{p3_path}:joints", _key(p3, p3_path, "joints", "the 3D joints (T, 14, 3)"),
                     ("T", _N_JOINTS, 3), sizes, float)
    kw = {}
    if "names" in p3:
        kw["joint_names"] = tuple(str(n) for n in _shaped(f"{p3_path}:names", p3["names"], (_N_JOINTS,), sizes))
    for key in ("state", "cost"):
        src = p3 if key in p3 else off if key == "state" and off is not None and key in off else None
        if src is not None:
            kw[key] = _shaped(f"{p3_path if src is p3 else off_path}:{key}", src[key], ("T",), sizes)
    if off is not None:
        offsets = _shaped(f"{off_path}:offsets", _key(off, off_path, "offsets", "pixels (T, n_cams, 2)"),
                          ("T", "C", 2), sizes, float)
    else:
        offsets = np.zeros((joints.shape[0], len(cams), 2))
    views = {}
    if p2 is not None:
        views = {c: _shaped(f"{p2_path}:{c}", p2[c], ("T", _N_JOINTS, 2), sizes) for c in cams if c in p2}
        for key in STAGE1_VIEW_KEYS:
            if key in p2:
                kw[key] = _shaped(f"{p2_path}:{key}", p2[key], Stage1Output.SHAPES[key], sizes)
    return Stage1Output(joints, cams, offsets, views, **kw)


@dataclass(frozen=True, eq=False)
class FreeViewpointPoses:
    """The joints of a free-viewpoint run (``recipes/free_viewpoint.py``, ``poses3d.npz``).

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3)
        Stage 3's joints, world frame, metres, NaN = none.
    joints_stage1 : ndarray of shape (T, 14, 3)
        Stage 1's joints the run started from, metres.
    status : ndarray of shape (T,) str
        How each frame went (``FrameResult.status``; ``"not processed"``).
    joint_names : tuple of str
    """

    joints: np.ndarray
    joints_stage1: np.ndarray
    status: np.ndarray
    joint_names: tuple = tuple(JOINTS_14)

    def __post_init__(self):
        object.__setattr__(self, "joint_names", tuple(str(n) for n in self.joint_names))
        if len(self.joint_names) != _N_JOINTS:
            raise InputError("FreeViewpointPoses.joint_names", f"{_N_JOINTS} names", f"{len(self.joint_names)}")
        sizes = {}
        for f in fields(self)[:3]:
            object.__setattr__(self, f.name, _shaped(f"FreeViewpointPoses.{f.name}", getattr(self, f.name),
                                                     ("T",) if f.name == "status" else ("T", _N_JOINTS, 3), sizes))


def write_free_viewpoint_poses(folder, poses: FreeViewpointPoses) -> Path:
    """Write ``folder/poses3d.npz``: ``joints``, ``names``, ``joints_stage1``, ``status`` (atomic)."""
    from toolkit.io.atomic import atomic_save_npz

    return atomic_save_npz(Path(folder) / "poses3d.npz", joints=poses.joints, names=np.array(poses.joint_names),
                           joints_stage1=poses.joints_stage1, status=poses.status)


def read_free_viewpoint_poses(folder) -> FreeViewpointPoses:
    """Read ``folder/poses3d.npz`` of a free-viewpoint run.

    Raises
    ------
    InputError
        A missing file or key, or an array of another shape (the file and key named).
    """
    path = Path(folder) / "poses3d.npz"
    data = _load(path, True)
    sizes = {}
    joints = _shaped(f"{path}:joints", _key(data, path, "joints", "(T, 14, 3) metres"), ("T", _N_JOINTS, 3), sizes)
    s1 = _shaped(f"{path}:joints_stage1", _key(data, path, "joints_stage1", "(T, 14, 3) metres"),
                 ("T", _N_JOINTS, 3), sizes)
    status = _shaped(f"{path}:status", _key(data, path, "status", "(T,) str"), ("T",), sizes)
    names = _shaped(f"{path}:names", data["names"], (_N_JOINTS,), sizes) if "names" in data else JOINTS_14
    return FreeViewpointPoses(joints, s1, status, tuple(str(n) for n in names))
