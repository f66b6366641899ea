"""User corrections of 2D joints (source 000 claim 7 and §2.1).

The source lets a person drag joints over the source image and adds every
corrected pose, with its silhouette, to the database.  Here the correction
is a small edits file the pipeline applies after its automatic estimate:

.. code-block:: toml

    # edits.toml: joint positions in pixels of the camera's image
    [[edit]]
    frame = 12
    camera = "cam_01"
    joints = { l_wrist = [812.0, 440.5], r_knee = [790.0, 610.0] }

    [[edit]]
    frame = 13
    camera = "cam_02"
    add_to_database = false          # optional, default true
    [edit.joints]
    head = [1020.0, 233.0]

The same as JSON: ``{"edit": [{"frame": 12, "camera": "cam_01", "joints":
{"l_wrist": [812.0, 440.5]}}]}``.  Joint names are those of ``SKELETON_14``;
pixels follow the toolkit's convention (centre of the top-left pixel at
(0, 0)) and are image positions (what the viewer shows under the camera's
image), not offset-corrected ones.  Joints not named keep the automatic
estimate.  :func:`edits_template` writes the automatic estimate of chosen
frames in this format, ready to be corrected.  See ``docs/stage1_silhouettes.md``
for the workflow.
"""

from __future__ import annotations

import json
import math
import os
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14

#: Suffixes of edits files and their formats.
EDIT_FORMATS = {".toml": "toml", ".json": "json"}


@dataclass(frozen=True)
class JointEdit:
    """Corrected joints of one frame and camera.

    Attributes
    ----------
    frame : int
    camera : str
    joints : tuple of (str, (float, float))
        Joint name and pixel position, in file order.
    add_to_database : bool
        Add the corrected pose, with its silhouette, to the database.
    """

    frame: int
    camera: str
    joints: tuple[tuple[str, tuple[float, float]], ...]
    add_to_database: bool = True

    def apply(self, pose_px: np.ndarray) -> np.ndarray:
        """The pose (14, 2) pixels with the edited joints replaced (a new array)."""
        p = np.array(pose_px, dtype=np.float64, copy=True)
        if p.shape != (SKELETON_14.n_joints, 2):
            raise InputError("pose_px", f"an array of shape ({SKELETON_14.n_joints}, 2)", f"shape {p.shape}")
        for name, xy in self.joints:
            p[SKELETON_14.index(name)] = xy
        return p

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(n for n, _ in self.joints)


@dataclass(frozen=True)
class Edits:
    """All corrections of an edits file.

    Attributes
    ----------
    edits : tuple of JointEdit
        In file order; a later edit of the same frame and camera overrides
        the joints it names.
    path : str
        The file they came from ('' when built in code).
    """

    edits: tuple[JointEdit, ...] = ()
    path: str = ""

    def __len__(self) -> int:
        return len(self.edits)

    @property
    def frames(self) -> set[int]:
        return {e.frame for e in self.edits}

    def for_frame(self, frame: int) -> dict[str, JointEdit]:
        """Edits of one frame by camera (several edits of one camera merged in order)."""
        out: dict[str, JointEdit] = {}
        for e in self.edits:
            if e.frame != frame:
                continue
            if e.camera in out:
                prev = out[e.camera]
                merged = dict(prev.joints)
                merged.update(dict(e.joints))
                out[e.camera] = JointEdit(frame, e.camera, tuple(merged.items()),
                                          prev.add_to_database and e.add_to_database)
            else:
                out[e.camera] = e
        return out


def parse_edits(data: Mapping, where: str = "edits", camera_names: Sequence[str] | None = None,
                n_frames: int | None = None) -> Edits:
    """Validate edits given as a parsed mapping (``{"edit": [...]}``).

    Parameters
    ----------
    data : mapping
    where : str
        Name of the source, used in error messages.
    camera_names : sequence of str, optional
        When given, every ``camera`` must be one of them.
    n_frames : int, optional
        When given, every ``frame`` must be in ``[0, n_frames)``.

    Returns
    -------
    Edits

    Raises
    ------
    InputError
        Naming the source, the edit (``edit[i]``) and the field.
    """
    if not isinstance(data, Mapping):
        raise InputError(where, "a table with an 'edit' array", type(data).__name__)
    unknown = set(data) - {"edit"}
    if unknown:
        raise InputError(where, "only an 'edit' array of tables", f"keys {sorted(unknown)}")
    items = data.get("edit", [])
    if not isinstance(items, list):
        raise InputError(f"{where}: edit", "an array of tables ([[edit]])", type(items).__name__)
    edits = []
    for i, item in enumerate(items):
        at = f"{where}: edit[{i}]"
        if not isinstance(item, Mapping):
            raise InputError(at, "a table with frame, camera and joints", type(item).__name__)
        extra = set(item) - {"frame", "camera", "joints", "add_to_database"}
        if extra:
            raise InputError(at, "fields frame, camera, joints, add_to_database", f"unknown {sorted(extra)}")
        for key in ("frame", "camera", "joints"):
            if key not in item:
                raise InputError(f"{at}.{key}", f"a '{key}' field", "nothing")
        frame = item["frame"]
        if isinstance(frame, bool) or not isinstance(frame, int) or frame < 0 \
                or (n_frames is not None and frame >= n_frames):
            bound = f" below {n_frames}" if n_frames is not None else ""
            raise InputError(f"{at}.frame", f"a frame index >= 0{bound}", repr(frame))
        camera = item["camera"]
        if not isinstance(camera, str) or (camera_names is not None and camera not in camera_names):
            exp = f"one of the cameras {list(camera_names)}" if camera_names is not None else "a camera name"
            raise InputError(f"{at}.camera", exp, repr(camera))
        joints = item["joints"]
        if not isinstance(joints, Mapping) or not joints:
            raise InputError(f"{at}.joints", "a non-empty table of joint name = [x, y] pixels", repr(joints))
        pairs = []
        for name, xy in joints.items():
            if name not in SKELETON_14.joint_names:
                raise InputError(f"{at}.joints.{name}", f"a joint of {list(SKELETON_14.joint_names)}", repr(name))
            ok = isinstance(xy, (list, tuple)) and len(xy) == 2 and all(
                isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in xy)
            if not ok:
                raise InputError(f"{at}.joints.{name}", "[x, y] finite pixels", repr(xy))
            pairs.append((name, (float(xy[0]), float(xy[1]))))
        add = item.get("add_to_database", True)
        if not isinstance(add, bool):
            raise InputError(f"{at}.add_to_database", "true or false", repr(add))
        edits.append(JointEdit(frame, camera, tuple(pairs), add))
    return Edits(tuple(edits), where)


def read_edits(path: str | os.PathLike, camera_names: Sequence[str] | None = None,
               n_frames: int | None = None) -> Edits:
    """Read and validate an edits file (``.toml`` or ``.json``); see the module docstring.

    Raises
    ------
    InputError
        A missing file, another suffix, a syntax error, or a bad field (named).
    """
    p = Path(path)
    fmt = EDIT_FORMATS.get(p.suffix.lower())
    if fmt is None:
        raise InputError(str(p), f"an edits file ending in one of {list(EDIT_FORMATS)}", repr(p.suffix))
    if not p.is_file():
        raise InputError(str(p), "an existing edits file", "no such file")
    text = p.read_text(encoding="utf-8")
    try:
        data = tomllib.loads(text) if fmt == "toml" else json.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as e:
        raise InputError(str(p), f"valid {fmt.upper()}", f"{type(e).__name__}: {e}") from None
    return parse_edits(data, str(p), camera_names, n_frames)


def _fmt(v: float) -> str:
    return f"{v:.1f}"


def edits_template(poses2d: Mapping[str, np.ndarray], frames: Sequence[int],
                   header: str = "Edits for recipes/pose_from_silhouettes.py") -> str:
    """TOML text listing the estimated joints of some frames, ready to be corrected.

    Parameters
    ----------
    poses2d : mapping of str to ndarray of shape (T, 14, 2)
        Per camera, pixels (NaN joints are left out).
    frames : sequence of int
    header : str
        First comment line.

    Returns
    -------
    str
        One ``[[edit]]`` table per frame and camera with every finite joint;
        delete the joints that are right and correct the others.
    """
    lines = [f"# {header}", "# Joint positions in pixels of each camera's image (top-left pixel centre = 0, 0).",
             "# Keep only the joints you correct; the pose is then added to the silhouette database.", ""]
    for t in frames:
        for cam, poses in poses2d.items():
            p = np.asarray(poses, float)
            if not 0 <= t < len(p) or not np.isfinite(p[t]).any():
                continue
            lines += ["[[edit]]", f"frame = {int(t)}", f"camera = {json.dumps(cam)}", "[edit.joints]"]
            for name, xy in zip(SKELETON_14.joint_names, p[t]):
                if np.isfinite(xy).all():
                    lines.append(f"{name} = [{_fmt(xy[0])}, {_fmt(xy[1])}]")
            lines.append("")
    return "\n".join(lines)
