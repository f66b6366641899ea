"""BVH motion files: reading, forward kinematics, mapping to the 14-joint skeleton, retargeting.

Conventions
-----------
* A joint's ``OFFSET`` is its position in its parent's frame.  Position
  channels, where a joint has them, replace the matching offset components
  (the root of most files has offset 0, so this only matters for files that
  animate the translation of inner joints).
* Rotation channels are applied in the order they are listed: channels
  ``Zrotation Yrotation Xrotation`` with values ``(a, b, c)`` degrees give the
  local rotation ``Rz(a) @ Ry(b) @ Rx(c)`` (column vectors), so a point ``v``
  of the child is at ``parent_global @ (offset + R_local @ ...)``.
* A BVH file has no units and is usually Y-up.  :func:`bvh_to_skeleton14`
  converts to the toolkit's world frame (metres, z up) with a *proper*
  rotation (``x, y, z -> x, -z, y`` for Y-up), so the person's left stays
  their left and the frame stays right-handed.
* The CMU motion-capture BVH conversions are in units of
  ``(1 / 0.45) * 0.0254`` m (:data:`CMU_UNIT_M`).

Writing is in :mod:`toolkit.motion.bvh_write` (:func:`~toolkit.motion.bvh_write.write_bvh`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion.kinematics import align_to_ground, bone_lengths14, resample, set_bone_lengths
from toolkit.skeleton import SKELETON_14
from toolkit.skeleton.mappings import CMU_BVH_TO_14

__all__ = ["CMU_UNIT_M", "BvhMotion", "read_bvh", "parse_bvh", "bvh_to_skeleton14",
           "motion_from_bvh", "euler_to_matrix", "matrix_to_euler", "UP_AXES"]

#: Length of one CMU BVH unit in metres: the CMU ASF/AMC files store lengths
#: in inches divided by 0.45 (the ``length`` scale of their ``:units``).
CMU_UNIT_M = (1.0 / 0.45) * 0.0254

#: Rotations from a file's up axis to the toolkit's z-up world (proper rotations).
UP_AXES = {
    "y": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),   # (x, y, z) -> (x, -z, y)
    "z": np.eye(3),
}

_AXES = {"X": 0, "Y": 1, "Z": 2}
_POS_CHANNELS = ("Xposition", "Yposition", "Zposition")
_ROT_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")


# ----------------------------------------------------------------- rotations
def _axis_rotation(axis: int, angle_rad: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    R = np.zeros(np.shape(angle_rad) + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def euler_to_matrix(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """Rotation matrices from BVH Euler angles.

    Parameters
    ----------
    angles_deg : ndarray of shape (..., len(order))
        Degrees, in the order of ``order``.
    order : str
        Axis letters in channel order, e.g. ``"ZYX"``; the matrix is the
        product of the single-axis rotations in that order.

    Returns
    -------
    ndarray of shape (..., 3, 3)
    """
    a = np.deg2rad(np.asarray(angles_deg, float))
    R = np.broadcast_to(np.eye(3), a.shape[:-1] + (3, 3)).copy()
    for k, ax in enumerate(order.upper()):
        R = R @ _axis_rotation(_AXES[ax], a[..., k])
    return R


def matrix_to_euler(R: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (degrees) with ``R = Rz(a) @ Ry(b) @ Rx(c)``.

    Exact up to rounding everywhere, including gimbal lock (``b = +-90``),
    where ``c`` is set to 0.

    Parameters
    ----------
    R : ndarray of shape (..., 3, 3)

    Returns
    -------
    ndarray of shape (..., 3)
        ``(a, b, c)`` in degrees.
    """
    R = np.asarray(R, float)
    cb = np.hypot(R[..., 0, 0], R[..., 1, 0])
    b = np.arctan2(-R[..., 2, 0], cb)
    regular = cb > 1e-9
    a = np.where(regular, np.arctan2(R[..., 1, 0], R[..., 0, 0]), np.arctan2(-R[..., 0, 1], R[..., 1, 1]))
    c = np.where(regular, np.arctan2(R[..., 2, 1], R[..., 2, 2]), 0.0)
    return np.rad2deg(np.stack([a, b, c], -1))


# ---------------------------------------------------------------------- data
@dataclass(frozen=True)
class BvhMotion:
    """The contents of a BVH file.

    Attributes
    ----------
    joint_names : tuple of str
        Joints in file order (depth first; parents before children).
    parents : tuple of int
        Parent index per joint, -1 for a root.
    offsets : ndarray of shape (J, 3)
        Offset of each joint in its parent's frame, file units.
    channels : tuple of tuple of str
        Channel names per joint, in file order.
    end_sites : tuple of (int, ndarray of shape (3,))
        ``(joint index, offset)`` of each ``End Site``.
    frame_time : float
        Seconds per frame.
    motion : ndarray of shape (T, n_channels)
        Channel values per frame (positions in file units, angles in degrees).
    source : str
        File name, for messages.
    """

    joint_names: tuple
    parents: tuple
    offsets: np.ndarray
    channels: tuple
    end_sites: tuple
    frame_time: float
    motion: np.ndarray
    source: str = "<bvh>"

    @property
    def n_frames(self) -> int:
        return self.motion.shape[0]

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    @property
    def channel_offsets(self) -> np.ndarray:
        """Index of each joint's first channel in :attr:`motion` (J,)."""
        return np.concatenate([[0], np.cumsum([len(c) for c in self.channels])[:-1]]).astype(int)

    def position_names(self, end_sites: bool = False) -> tuple:
        """Names of the rows of :meth:`positions`; end sites are ``<parent>_end``."""
        names = list(self.joint_names)
        if end_sites:
            names += [f"{self.joint_names[j]}_end" for j, _ in self.end_sites]
        return tuple(names)

    def global_transforms(self):
        """Global rotation (T, J, 3, 3) and position (T, J, 3) of every joint, file units."""
        T, J = self.n_frames, self.n_joints
        Rg = np.zeros((T, J, 3, 3))
        pg = np.zeros((T, J, 3))
        starts = self.channel_offsets
        for j in range(J):
            chans = self.channels[j]
            vals = self.motion[:, starts[j]:starts[j] + len(chans)]
            local_t = np.broadcast_to(self.offsets[j], (T, 3)).copy()
            order, rot_cols = "", []
            for k, ch in enumerate(chans):
                if ch in _POS_CHANNELS:
                    local_t[:, _POS_CHANNELS.index(ch)] = vals[:, k]
                else:
                    order += ch[0].upper()
                    rot_cols.append(k)
            R = euler_to_matrix(vals[:, rot_cols], order) if order else np.broadcast_to(np.eye(3), (T, 3, 3))
            p = self.parents[j]
            if p < 0:
                Rg[:, j] = R
                pg[:, j] = local_t
            else:
                Rg[:, j] = Rg[:, p] @ R
                pg[:, j] = pg[:, p] + np.einsum("tij,tj->ti", Rg[:, p], local_t)
        return Rg, pg

    def positions(self, end_sites: bool = False) -> np.ndarray:
        """Global joint positions by forward kinematics.

        Parameters
        ----------
        end_sites : bool
            Append the ``End Site`` points (named ``<parent>_end``).

        Returns
        -------
        ndarray of shape (T, J (+ n_end_sites), 3)
            File units and axes, rows named by :meth:`position_names`.
        """
        Rg, pg = self.global_transforms()
        if not end_sites or not self.end_sites:
            return pg
        ends = [pg[:, j] + np.einsum("tij,j->ti", Rg[:, j], off) for j, off in self.end_sites]
        return np.concatenate([pg, np.stack(ends, 1)], axis=1)


# ------------------------------------------------------------------- reading
class _Tokens:
    """Whitespace tokens with their line numbers."""

    def __init__(self, text: str, source: str):
        self.source = source
        self.items = []
        for n, line in enumerate(text.splitlines(), start=1):
            for tok in line.split():
                self.items.append((tok, n))
        self.i = 0

    def error(self, expected: str, found: str | None = None, line: int | None = None):
        if line is None:
            line = self.items[self.i][1] if self.i < len(self.items) else (self.items[-1][1] if self.items else 1)
        if found is None:
            found = repr(self.items[self.i][0]) if self.i < len(self.items) else "end of file"
        return InputError(f"{self.source}: line {line}", expected, found)

    def peek(self):
        return self.items[self.i][0] if self.i < len(self.items) else None

    def next(self, expected: str = "a token"):
        if self.i >= len(self.items):
            raise self.error(expected, "end of file")
        tok = self.items[self.i]
        self.i += 1
        return tok

    def expect(self, word: str):
        tok, line = self.next(repr(word))
        if tok != word:
            self.i -= 1
            raise self.error(repr(word))
        return line

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        try:
            v = float(tok)
        except ValueError:
            self.i -= 1
            raise self.error(what) from None
        if not np.isfinite(v):
            self.i -= 1
            raise self.error(f"a finite {what}")
        return v


def _parse_hierarchy(tk: _Tokens) -> tuple[list, list, list, list, list]:
    """Parse the ``HIERARCHY`` section: every ``ROOT`` and its joints, depth first.

    Parameters
    ----------
    tk : _Tokens
        At ``HIERARCHY``; left at the token after the last root's ``}``.

    Returns
    -------
    names : list of str
    parents : list of int
        Parent index of each joint (-1 for a root).
    offsets : list of list of float
        Each joint's ``OFFSET`` (3 values, file units).
    channels : list of tuple of str
        Each joint's channel names.
    ends : list of (int, ndarray of shape (3,))
        ``End Site`` offsets with their joint.

    Raises
    ------
    InputError
        Naming the line, what was expected and what was found.
    """
    names, parents, offsets, channels, ends = [], [], [], [], []
    tk.expect("HIERARCHY")

    def joint_block(parent: int):
        tk.expect("{")
        tok, line = tk.next("OFFSET")
        if tok != "OFFSET":
            tk.i -= 1
            raise tk.error("'OFFSET'")
        off = [tk.number("offset value") for _ in range(3)]
        me = len(names) - 1
        offsets.append(off)
        tok, line = tk.next("CHANNELS")
        if tok != "CHANNELS":
            tk.i -= 1
            raise tk.error("'CHANNELS'")
        n_tok, n_line = tk.next("a channel count")
        if not n_tok.isdigit():
            tk.i -= 1
            raise tk.error("a channel count")
        chans = []
        for _ in range(int(n_tok)):
            ch, ch_line = tk.next("a channel name")
            if ch not in _POS_CHANNELS + _ROT_CHANNELS:
                tk.i -= 1
                raise tk.error(f"a channel name in {_POS_CHANNELS + _ROT_CHANNELS}")
            if ch in chans:
                tk.i -= 1
                raise tk.error("each channel at most once per joint")
            chans.append(ch)
        channels.append(tuple(chans))
        while True:
            tok = tk.peek()
            if tok == "JOINT":
                tk.next()
                name, _ = tk.next("a joint name")
                if name in names:
                    tk.i -= 1
                    raise tk.error("a unique joint name", repr(name))
                names.append(name)
                parents.append(me)
                joint_block(me)
            elif tok == "End":
                tk.next()
                tk.expect("Site")
                tk.expect("{")
                tk.expect("OFFSET")
                ends.append((me, np.array([tk.number("offset value") for _ in range(3)])))
                tk.expect("}")
            elif tok == "}":
                tk.next()
                return
            else:
                raise tk.error("'JOINT', 'End Site' or '}'")

    while tk.peek() == "ROOT":
        tk.next()
        name, _ = tk.next("a root name")
        if name in names:
            tk.i -= 1
            raise tk.error("a unique joint name", repr(name))
        names.append(name)
        parents.append(-1)
        joint_block(-1)
    if not names:
        raise tk.error("'ROOT'")
    return names, parents, offsets, channels, ends


def _frame_values(rest: list, n_frames: int, n_ch: int, n_line: int, source: str) -> np.ndarray:
    """The ``MOTION`` values: ``n_ch`` finite numbers per frame, one frame per line.

    Parameters
    ----------
    rest : list of (str, int)
        The tokens after ``Frame Time:`` with their line numbers.
    n_frames : int
        The ``Frames:`` count.
    n_ch : int
        Channels per frame.
    n_line : int
        Line of the ``Frames:`` count.
    source : str
        The file, for messages.

    Returns
    -------
    ndarray of shape (n_frames * n_ch,)

    Raises
    ------
    InputError
        Naming the line: a wrong number of values, a value not a finite number, a frame split over lines.
    """
    # frame data: one line per frame
    if len(rest) != n_frames * n_ch:
        # find the offending line for a helpful message
        by_line: dict[int, int] = {}
        for _, ln in rest:
            by_line[ln] = by_line.get(ln, 0) + 1
        lines = sorted(by_line)
        for k, ln in enumerate(lines):
            if by_line[ln] != n_ch:
                raise InputError(f"{source}: line {ln}", f"{n_ch} channel values per frame",
                                 f"{by_line[ln]} values")
        where = f"{source}: line {lines[-1] if lines else n_line}"
        raise InputError(where, f"{n_frames} frames (the 'Frames:' count)", f"{len(lines)} frames")
    values = np.empty(n_frames * n_ch)
    for k, (tok, ln) in enumerate(rest):
        try:
            values[k] = float(tok)
        except ValueError:
            raise InputError(f"{source}: line {ln}", "a number", repr(tok)) from None
    if not np.all(np.isfinite(values)):
        bad = int(np.flatnonzero(~np.isfinite(values))[0])
        raise InputError(f"{source}: line {rest[bad][1]}", "finite channel values", rest[bad][0])
    # values must also come one frame per line
    if n_frames and n_ch:
        first_lines = [rest[f * n_ch][1] for f in range(n_frames)]
        last_lines = [rest[f * n_ch + n_ch - 1][1] for f in range(n_frames)]
        for f in range(n_frames):
            if first_lines[f] != last_lines[f]:
                raise InputError(f"{source}: line {first_lines[f]}", f"{n_ch} channel values on one line",
                                 "a frame split over several lines")
    return values


def parse_bvh(text: str, source: str = "<bvh>") -> BvhMotion:
    """Parse BVH text; see :func:`read_bvh`."""
    tk = _Tokens(text, source)
    names, parents, offsets, channels, ends = _parse_hierarchy(tk)
    tk.expect("MOTION")
    tk.expect("Frames:")
    n_tok, n_line = tk.next("a frame count")
    if not n_tok.isdigit():
        tk.i -= 1
        raise tk.error("a non-negative integer frame count")
    n_frames = int(n_tok)
    tk.expect("Frame")
    tk.expect("Time:")
    frame_time = tk.number("frame time")
    if frame_time <= 0:
        raise tk.error("a positive frame time", repr(frame_time), line=tk.items[tk.i - 1][1])
    n_ch = sum(len(c) for c in channels)
    values = _frame_values(tk.items[tk.i:], n_frames, n_ch, n_line, source)
    return BvhMotion(joint_names=tuple(names), parents=tuple(parents),
                     offsets=np.array(offsets, float).reshape(-1, 3), channels=tuple(channels),
                     end_sites=tuple(ends), frame_time=float(frame_time),
                     motion=values.reshape(n_frames, n_ch), source=source)


def read_bvh(path: str | os.PathLike) -> BvhMotion:
    """Read a BVH file.

    Parameters
    ----------
    path : str or PathLike

    Returns
    -------
    BvhMotion

    Raises
    ------
    InputError
        Malformed file; the message names the file and the line.
    FileNotFoundError
        No such file.
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8", errors="replace")
    return parse_bvh(text, source=str(path.name))


# ---------------------------------------------------------------- to 14 joints
def bvh_to_skeleton14(motion: BvhMotion, mapping: dict = CMU_BVH_TO_14, units: float = CMU_UNIT_M,
                      up_axis: str = "y", constant_lengths: bool = True) -> np.ndarray:
    """Joint positions of the 14-joint skeleton from a BVH motion.

    Parameters
    ----------
    motion : BvhMotion
    mapping : dict
        ``{joint14: {bvh position name: weight}}`` (weights sum to 1); names
        are those of :meth:`BvhMotion.position_names` with end sites.
        Defaults to the CMU mapping (:data:`toolkit.skeleton.mappings.CMU_BVH_TO_14`).
    units : float
        Metres per file unit (default :data:`CMU_UNIT_M`; 0.01 for centimetres).
    up_axis : {"y", "z"}
        The file's vertical axis.
    constant_lengths : bool
        A bone of the 14-joint skeleton may span several BVH segments (the
        CMU trunk: neck to hip crosses three spine joints), so its length
        changes as those bend.  With ``True`` every bone keeps its direction
        and gets its median length (:func:`set_bone_lengths`, from the neck
        outward); limbs that map onto single BVH segments are unchanged.

    Returns
    -------
    ndarray of shape (T, 14, 3)
        Metres, z up, file's horizontal origin kept.
    """
    if up_axis not in UP_AXES:
        raise InputError("up_axis", f"one of {sorted(UP_AXES)}", repr(up_axis))
    if not (np.isfinite(units) and units > 0):
        raise InputError("units", "a positive number of metres per file unit", repr(units))
    names = motion.position_names(end_sites=True)
    index = {n: i for i, n in enumerate(names)}
    missing = sorted({n for w in mapping.values() for n in w if n not in index})
    if missing:
        raise InputError(f"{motion.source}: joints", f"the joints named by the mapping ({missing})",
                         f"joints {list(motion.joint_names)}")
    if set(mapping) != set(SKELETON_14.joint_names):
        raise InputError("mapping", f"one entry per joint of {SKELETON_14.joint_names}",
                         f"keys {sorted(mapping)}")
    W = np.zeros((14, len(names)))
    for j, jn in enumerate(SKELETON_14.joint_names):
        for n, w in mapping[jn].items():
            W[j, index[n]] = w
    pos = motion.positions(end_sites=True)
    j14 = np.einsum("kn,tnd->tkd", W, pos) * units @ UP_AXES[up_axis].T
    if constant_lengths and len(j14):
        j14 = set_bone_lengths(j14, np.median(SKELETON_14.bone_lengths(j14), axis=0))
    return j14


# ------------------------------------------------------------------ retarget
def motion_from_bvh(path: str | os.PathLike, proportions: BodyProportions | None = None,
                    n_frames: int | None = None, fps: float = 25.0,
                    rng: np.random.Generator | int | None = None, mapping: dict = CMU_BVH_TO_14,
                    units: float = CMU_UNIT_M, up_axis: str = "y") -> np.ndarray:
    """A 14-joint sequence from a BVH file, resampled, optionally retargeted, on the ground.

    Steps: :func:`read_bvh` -> :func:`bvh_to_skeleton14` -> resample to
    ``fps`` -> a window of ``n_frames`` frames starting at a random frame
    (drawn from ``rng``; all frames when ``n_frames`` is None) -> if
    ``proportions`` are given, every bone keeps its direction and gets the
    length of ``proportions`` (forward kinematics from the neck) -> the
    window's mean pelvis position is moved to the origin horizontally and the
    feet are put on the ground (:func:`align_to_ground`, ``"sequence"`` mode).

    Parameters
    ----------
    path : str or PathLike
    proportions : BodyProportions, optional
    n_frames : int, optional
    fps : float
    rng : numpy.random.Generator or int or None
    mapping, units, up_axis
        As for :func:`bvh_to_skeleton14`.

    Returns
    -------
    ndarray of shape (n_frames, 14, 3)
        Metres, world, z up, ground z = 0.

    Raises
    ------
    InputError
        ``n_frames`` longer than the resampled clip, non-positive ``fps`` or
        ``n_frames``, or a malformed file.
    """
    if not (isinstance(fps, (int, float, np.integer, np.floating)) and np.isfinite(fps) and fps > 0):
        raise InputError("fps", "a positive frame rate", repr(fps))
    if n_frames is not None and (isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer))
                                 or n_frames <= 0):
        raise InputError("n_frames", "a positive integer or None", repr(n_frames))
    motion = read_bvh(path)
    j = bvh_to_skeleton14(motion, mapping=mapping, units=units, up_axis=up_axis)
    j = resample(j, motion.fps, fps)
    if n_frames is not None:
        if n_frames > len(j):
            raise InputError("n_frames", f"at most {len(j)} frames ({Path(path).name} at {fps} fps)",
                             repr(n_frames))
        start = int(np.random.default_rng(rng).integers(0, len(j) - n_frames + 1))
        j = j[start:start + n_frames]
    if proportions is not None:
        j = set_bone_lengths(j, bone_lengths14(proportions))
        ankle = proportions.ankle_height
    else:
        ankle = _ankle_height_estimate(j)
    pelvis = 0.5 * (j[:, SKELETON_14.index("l_hip")] + j[:, SKELETON_14.index("r_hip")])
    j = j.copy()
    j[..., :2] -= pelvis[:, :2].mean(0)
    return align_to_ground(j, ankle, mode="sequence")


def _ankle_height_estimate(joints: np.ndarray) -> float:
    """Ankle height (m) of the mapped person: the ANSUR ratio of their median leg and trunk length."""
    from toolkit.anthropometry.proportions import STATURE_RATIOS

    r = STATURE_RATIOS
    chain = SKELETON_14.bone_lengths(joints)
    names = SKELETON_14.bone_names
    leg = np.median(chain[:, names.index("l_hip-l_knee")] + chain[:, names.index("l_knee-l_ankle")])
    # leg (hip to ankle) is (hip_height - ankle_height) of stature
    stature = leg / (r["hip_height"] - r["ankle_height"])
    return float(r["ankle_height"] * stature)

