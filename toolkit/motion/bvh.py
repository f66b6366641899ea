"""BVH motion files: reading, forward kinematics, mapping to the 14-joint skeleton, writing.

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

Writing (:func:`write_bvh`) uses the hierarchy described in ``docs/motion.md``:
the root is the neck, every bone of the 14-joint skeleton gets its own
rotating joint, and the twist of each bone is the *minimal* (swing-only)
rotation from where its parent carries it, so that a re-import reproduces the
joint positions exactly when bone lengths are constant.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion.kinematics import align_to_ground, bone_lengths14, resample, set_bone_lengths
from toolkit.skeleton import SKELETON_14, Skeleton
from toolkit.skeleton.mappings import CMU_BVH_TO_14

__all__ = ["CMU_UNIT_M", "BvhMotion", "read_bvh", "parse_bvh", "bvh_to_skeleton14", "write_bvh",
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


def parse_bvh(text: str, source: str = "<bvh>") -> BvhMotion:
    """Parse BVH text; see :func:`read_bvh`."""
    tk = _Tokens(text, source)
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
    # frame data: one line per frame
    rest = tk.items[tk.i:]
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


# ------------------------------------------------------------------- writing
def _rest_directions(skeleton: Skeleton) -> dict:
    """Unit rest directions (BVH axes: x = person's left, y up, z forward) of the 14-joint bones."""
    d = {}
    for name in skeleton.joint_names:
        if name == "head":
            d[name] = (0.0, 1.0, 0.0)
        elif name.endswith("shoulder"):
            d[name] = (1.0 if name.startswith("l_") else -1.0, -0.35, 0.0)
        elif name.endswith("hip"):
            d[name] = (0.15 if name.startswith("l_") else -0.15, -1.0, 0.0)
        else:
            d[name] = (0.0, -1.0, 0.0)
    return {k: np.array(v) / np.linalg.norm(v) for k, v in d.items()}


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Minimal rotations (T, 3, 3) taking unit vectors a (T, 3) to unit vectors b (T, 3).

    Opposite vectors turn by 180 degrees about an axis perpendicular to ``a``
    (the one closest to x, then z).
    """
    v = np.cross(a, b)
    c = np.sum(a * b, -1)
    T = len(a)
    R = np.broadcast_to(np.eye(3), (T, 3, 3)).copy()
    ok = c > -1 + 1e-12
    k = np.zeros((T, 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    f = np.where(ok, 1.0 / np.where(ok, 1 + c, 1.0), 0.0)
    R = R + k + (k @ k) * f[:, None, None]
    if not np.all(ok):
        bad = ~ok
        ax = np.cross(a[bad], np.array([1.0, 0, 0]))
        small = np.linalg.norm(ax, axis=-1) < 1e-6
        ax[small] = np.cross(a[bad][small], np.array([0, 0, 1.0]))
        ax /= np.linalg.norm(ax, axis=-1, keepdims=True)
        R[bad] = 2 * ax[:, :, None] * ax[:, None, :] - np.eye(3)
    return R


def _torso_frame(g: dict) -> np.ndarray:
    """Rotation (T, 3, 3) of the torso in BVH axes: columns (left, up, forward)."""
    mid_hip = 0.5 * (g["l_hip"] + g["r_hip"])
    up = g["neck"] - mid_hip
    up /= np.linalg.norm(up, axis=-1, keepdims=True)
    left = (g["l_hip"] - g["r_hip"]) + (g["l_shoulder"] - g["r_shoulder"])
    left = left - np.sum(left * up, -1, keepdims=True) * up
    n = np.linalg.norm(left, axis=-1, keepdims=True)
    if np.any(n < 1e-9):
        raise InputError("joints", "a torso with distinct left and right joints", "coincident hips and shoulders")
    left /= n
    fwd = np.cross(left, up)
    return np.stack([left, up, fwd], -1)


def _fmt(values) -> str:
    return " ".join(f"{v:.9f}" for v in values)


def write_bvh(path: str | os.PathLike, joints: np.ndarray, fps: float, skeleton: Skeleton = SKELETON_14,
              units: float = 0.01, rest: str = "median") -> None:
    """Export a 14-joint sequence as BVH (Y-up, ZYX Euler channels).

    The hierarchy (see ``docs/motion.md``): ``ROOT neck`` (6 channels,
    position + torso orientation), for every bone ``neck -> X`` a zero-offset
    joint ``neck_to_X`` that turns that bone, then one joint per 14-joint
    joint, each turning its outgoing bone; leaves carry an ``End Site``.
    Rest offsets point along a standing pose with lengths from ``rest``.
    Bone twist convention: each joint's local rotation is the minimal
    rotation (no twist about the bone) that takes the bone from where its
    parent's frame carries it to its measured direction; the root's
    orientation is the torso frame (up = mid-hip to neck, left = hip and
    shoulder lines).  Re-reading gives the joint positions back exactly when
    bone lengths are constant.

    Parameters
    ----------
    path : str or PathLike
        Written atomically (temporary file + ``os.replace``).
    joints : ndarray of shape (T, 14, 3)
        Metres, world, z up; finite.
    fps : float
        Frames per second.
    skeleton : Skeleton
        Must be :data:`SKELETON_14` (the only layout this writer knows).
    units : float
        Metres per file unit (default centimetres).
    rest : {"median", "first"}
        Bone lengths of the rest offsets: median over frames, or the first frame.
    """
    if skeleton is not SKELETON_14 and skeleton != SKELETON_14:
        raise InputError("skeleton", "SKELETON_14", getattr(skeleton, "name", repr(skeleton)))
    j = SKELETON_14.check_joints(joints)
    if j.ndim != 3 or j.shape[-1] != 3 or j.shape[0] < 1:
        raise InputError("joints", "an array of shape (T, 14, 3) with T >= 1", f"shape {j.shape}")
    if not np.all(np.isfinite(j)):
        raise InputError("joints", "finite joint positions", "NaN or inf values")
    if not (np.isfinite(fps) and fps > 0):
        raise InputError("fps", "a positive frame rate", repr(fps))
    if not (np.isfinite(units) and units > 0):
        raise InputError("units", "a positive number of metres per file unit", repr(units))
    if rest not in ("median", "first"):
        raise InputError("rest", "'median' or 'first'", repr(rest))
    # world (z up, metres) -> file (y up, units)
    M = UP_AXES["y"]
    q = (j @ M) / units            # inverse rotation: M is orthogonal, x_file = M^T x_world
    names = SKELETON_14.joint_names
    g = {n: q[:, i] for i, n in enumerate(names)}
    lengths = SKELETON_14.bone_lengths(q)
    L = np.median(lengths, 0) if rest == "median" else lengths[0]
    bone_len = {names[c]: L[b] for b, (_, c) in enumerate(SKELETON_14.bones)}
    rest_dir = _rest_directions(SKELETON_14)
    T = len(q)
    R_root = _torso_frame(g)
    R_global = {"neck": R_root}
    local = {"neck": R_root}
    order = []       # (name, parent name, offset, is_helper)
    for c in SKELETON_14.children(SKELETON_14.index("neck")):
        cn = names[c]
        helper = f"neck_to_{cn}"
        want = g[cn] - g["neck"]
        want = want / np.linalg.norm(want, axis=-1, keepdims=True)
        have = np.einsum("tij,j->ti", R_root, rest_dir[cn])
        Rg = _swing(have, want) @ R_root
        R_global[helper] = Rg
        local[helper] = np.einsum("tji,tjk->tik", R_root, Rg)
        order.append((helper, "neck", np.zeros(3)))
        order.append((cn, helper, rest_dir[cn] * bone_len[cn]))
    # chains below the neck's children
    queue = [names[c] for c in SKELETON_14.children(SKELETON_14.index("neck"))]
    parent_frame = {n: R_global[f"neck_to_{n}"] for n in queue}
    while queue:
        n = queue.pop(0)
        kids = SKELETON_14.children(SKELETON_14.index(n))
        Rp = parent_frame[n]
        if kids:
            (c,) = kids
            cn = names[c]
            want = g[cn] - g[n]
            want = want / np.linalg.norm(want, axis=-1, keepdims=True)
            have = np.einsum("tij,j->ti", Rp, rest_dir[cn])
            Rg = _swing(have, want) @ Rp
            order.append((cn, n, rest_dir[cn] * bone_len[cn]))
            parent_frame[cn] = Rg
            queue.append(cn)
        else:
            Rg = Rp
        local[n] = np.einsum("tji,tjk->tik", Rp, Rg)
        R_global[n] = Rg
    children_of: dict = {}
    offsets = {"neck": np.zeros(3)}
    for name, parent, off in order:
        children_of.setdefault(parent, []).append(name)
        offsets[name] = off
    lines = ["HIERARCHY"]
    columns = []

    def emit(name, depth):
        ind = "\t" * depth
        kw = "ROOT" if name == "neck" else "JOINT"
        lines.append(f"{ind}{kw} {name}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}\tOFFSET {_fmt(offsets[name])}")
        if name == "neck":
            lines.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation")
            columns.append(g["neck"])
        else:
            lines.append(f"{ind}\tCHANNELS 3 Zrotation Yrotation Xrotation")
        columns.append(matrix_to_euler(local[name]))
        kids = children_of.get(name, [])
        for k in kids:
            emit(k, depth + 1)
        if not kids:
            tip = rest_dir[name] * 0.25 * bone_len[name] if name in bone_len else np.zeros(3)
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET {_fmt(tip)}")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    emit("neck", 0)
    data = np.concatenate(columns, axis=1)
    lines += ["MOTION", f"Frames: {T}", f"Frame Time: {1.0 / fps:.10f}"]
    lines += [_fmt(row) for row in data]
    _atomic_write_text(Path(path), "\n".join(lines) + "\n")


def _atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, then rename it over ``path``."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.tmp-", suffix=path.suffix)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


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
