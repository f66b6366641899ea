"""Writing BVH files of 14-joint motions (:func:`write_bvh`; reading and retargeting: :mod:`toolkit.motion.bvh`).

The hierarchy is described in ``docs/motion.md``: the root is the neck, every
bone of the 14-joint skeleton gets its own rotating joint, and the twist of
each bone is the *minimal* (swing-only) rotation from where its parent carries
it, so that a re-import reproduces the joint positions exactly when bone
lengths are constant.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.atomic import atomic_write_text
from toolkit.motion.bvh import UP_AXES, matrix_to_euler
from toolkit.skeleton import SKELETON_14, Skeleton

__all__ = ["write_bvh"]


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


def _checked_joints(skeleton: Skeleton, joints, fps: float, units: float, rest: str) -> np.ndarray:
    """Check the arguments of :func:`write_bvh`.

    Parameters
    ----------
    skeleton, joints, fps, units, rest
        As :func:`write_bvh`.

    Returns
    -------
    ndarray of shape (T, 14, 3)
        The joints, metres.

    Raises
    ------
    InputError
        Another skeleton, a wrong shape, non-finite joints, or a bad ``fps``, ``units`` or ``rest``.
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
    return j


def _local_rotations(g: dict, rest_dir: dict, bone_len: dict) -> tuple[dict, list]:
    """Each joint's local rotation (no twist about its bone) and the hierarchy below the root ``neck``.

    Parameters
    ----------
    g : dict of str to ndarray of shape (T, 3)
        Joint positions, file frame and units.
    rest_dir : dict of str to ndarray of shape (3,)
        Rest direction of the bone ending at each joint.
    bone_len : dict of str to float
        Rest length of the bone ending at each joint, file units.

    Returns
    -------
    local : dict of str to ndarray of shape (T, 3, 3)
        Local rotation of every joint (helpers ``neck_to_X`` included).
    order : list of (str, str, ndarray of shape (3,))
        ``(name, parent, rest offset)`` of every joint below the root, parents first.
    """
    names = SKELETON_14.joint_names
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
    return local, order


def _hierarchy(order: list, g: dict, local: dict, rest_dir: dict, bone_len: dict) -> tuple[list, list]:
    """The ``HIERARCHY`` section's lines and the motion's channel columns, depth first from the root.

    Parameters
    ----------
    order : list of (str, str, ndarray of shape (3,))
        From :func:`_local_rotations`.
    g : dict of str to ndarray of shape (T, 3)
        Joint positions, file frame and units.
    local : dict of str to ndarray of shape (T, 3, 3)
    rest_dir : dict of str to ndarray of shape (3,)
    bone_len : dict of str to float

    Returns
    -------
    lines : list of str
    columns : list of ndarray of shape (T, 3)
        The channels of every joint in file order (root position first).
    """
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
    return lines, columns


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
    j = _checked_joints(skeleton, joints, fps, units, rest)
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
    local, order = _local_rotations(g, rest_dir, bone_len)
    lines, columns = _hierarchy(order, g, local, rest_dir, bone_len)
    data = np.concatenate(columns, axis=1)
    lines += ["MOTION", f"Frames: {T}", f"Frame Time: {1.0 / fps:.10f}"]
    lines += [_fmt(row) for row in data]
    atomic_write_text(Path(path), "\n".join(lines) + "\n")

