"""BVH and glTF of an estimate: a rest pose from its bone lengths, the motion as joint rotations.

An estimate's bones change length from frame to frame (noise, a missed
joint); an animation skeleton's do not.  :func:`rest_pose_joints` first fills
short gaps (linear interpolation over time, ends held), then gives every bone
its median length while keeping its direction in each frame
(:func:`toolkit.motion.kinematics.set_bone_lengths`, from the neck outward).
Both exports encode that sequence; a re-import gives it back to floating-point
precision (tests: BVH through :func:`toolkit.motion.read_bvh`, glTF through
pygltflib).

* BVH: :func:`toolkit.motion.write_bvh`, the motion library's writer (Y up,
  centimetres, ZYX channels, a helper joint per bone leaving the neck).
* glTF 2.0 binary (``.glb``), written here with numpy and :mod:`json` (the
  format is a JSON header and one binary buffer; no library needed to write
  it): one node per joint of the 14-joint skeleton (root ``neck``), a skin
  over them with its inverse bind matrices, a small octahedron per joint
  skinned to it (so viewers have something to draw), and one animation with
  a rotation channel per joint, the root's translation, and the translation
  of the neck's children (shoulders, hips, head: their offsets from the neck
  turn with the trunk's bending, which one root rotation cannot express).
  Axes: glTF's Y up, +Z forward, metres.
"""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from toolkit.errors import InputError
from toolkit.io.atomic import atomic_write_bytes
from toolkit.motion import set_bone_lengths, write_bvh
from toolkit.motion.bvh import UP_AXES
from toolkit.skeleton import SKELETON_14

#: Rest direction of the bone ending at each joint, in file axes (x = the person's left, y up, z forward).
REST_DIRECTIONS = {
    "head": (0.0, 1.0, 0.0), "l_shoulder": (1.0, -0.35, 0.0), "r_shoulder": (-1.0, -0.35, 0.0),
    "l_hip": (0.15, -1.0, 0.0), "r_hip": (-0.15, -1.0, 0.0),
}
#: Half-size of the octahedron drawn at each joint, metres.
JOINT_MARKER_SIZE_M = 0.02


def fill_gaps(joints: np.ndarray) -> tuple[np.ndarray, int]:
    """Joints with missing samples filled by linear interpolation over time (ends: nearest sample).

    Parameters
    ----------
    joints : ndarray of shape (T, J, 3)

    Returns
    -------
    filled : ndarray of shape (T, J, 3)
    n_filled : int
        Joint samples (frame, joint) that were missing.

    Raises
    ------
    InputError
        A joint missing in every frame.
    """
    j = np.array(joints, float)
    missing = ~np.all(np.isfinite(j), -1)
    never = np.all(missing, 0)
    if never.any():
        raise InputError("joints", "every joint seen in at least one frame",
                         f"joints {list(np.flatnonzero(never))} never seen")
    t = np.arange(len(j))
    for k in np.flatnonzero(missing.any(0)):
        ok = ~missing[:, k]
        for d in range(3):
            j[:, k, d] = np.interp(t, t[ok], j[ok, k, d])
    return j, int(missing.sum())


def rest_pose_joints(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The 14-joint sequence with constant bone lengths (median of the estimate's).

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3)
        Metres, world (z up), NaN = missing.

    Returns
    -------
    joints : ndarray of shape (T, 14, 3)
        Gaps filled, every bone at its median length.
    lengths : ndarray of shape (13,)
        Metres, in the order of ``SKELETON_14.bones``.
    n_filled : int
        Joint samples filled in.
    """
    j = SKELETON_14.check_joints(joints)
    if j.ndim != 3 or j.shape[-1] != 3 or len(j) < 1:
        raise InputError("joints", "an array of shape (T, 14, 3) with T >= 1", f"shape {j.shape}")
    filled, n = fill_gaps(j)
    lengths = np.median(SKELETON_14.bone_lengths(filled), 0)
    return set_bone_lengths(filled, lengths), lengths, n


def export_bvh(path: str | os.PathLike, joints: np.ndarray, fps: float) -> np.ndarray:
    """Write a BVH of a 14-joint estimate (rest pose from its median bone lengths).

    Parameters
    ----------
    path : path
    joints : ndarray of shape (T, 14, 3)
        Metres, world, NaN = missing.
    fps : float

    Returns
    -------
    ndarray of shape (T, 14, 3)
        The joints the file encodes (:func:`rest_pose_joints`).
    """
    rest, _, _ = rest_pose_joints(joints)
    write_bvh(path, rest, fps)
    return rest


# --------------------------------------------------------------------- glTF
def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Minimal rotations (T, 3, 3) taking unit vectors ``a`` to unit vectors ``b`` (T, 3)."""
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=-1)
    c = np.sum(a * b, -1)
    angle = np.arctan2(s, c)
    safe = np.where(s[:, None] > 1e-12, axis / np.maximum(s, 1e-300)[:, None], 0.0)
    flip = (s <= 1e-12) & (c < 0)     # opposite vectors: half a turn about an axis normal to a
    if flip.any():
        ortho = np.cross(a[flip], [1.0, 0.0, 0.0])
        weak = np.linalg.norm(ortho, axis=-1) < 1e-6
        ortho[weak] = np.cross(a[flip][weak], [0.0, 0.0, 1.0])
        safe[flip] = ortho / np.linalg.norm(ortho, axis=-1, keepdims=True)
        angle[flip] = np.pi
    return Rotation.from_rotvec(safe * angle[:, None]).as_matrix()


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def skeleton_animation(joints: np.ndarray) -> dict:
    """Rest offsets and per-frame local rotations and translations of the 14 joints (file axes).

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3)
        Metres, world (z up), finite, constant bone lengths (:func:`rest_pose_joints`).

    Returns
    -------
    dict
        ``offsets`` (14, 3) rest translation of each joint in its parent (the
        root's: 0), ``rotations`` (T, 14, 3, 3) local rotations,
        ``translations`` (T, 14, 3) local translations (the rest offset
        except for the root and the neck's children), file axes (Y up), metres.
    """
    q = np.asarray(joints, float) @ UP_AXES["y"]          # x_file = M^T x_world
    names, parents = SKELETON_14.joint_names, SKELETON_14.parents
    root = parents.index(-1)
    bone = {c: b for b, (_, c) in enumerate(SKELETON_14.bones)}
    lengths = SKELETON_14.bone_lengths(q)[0]
    rest_dir = {n: _unit(np.array(REST_DIRECTIONS.get(n, (0.0, -1.0, 0.0)))) for n in names}
    offsets = np.zeros((14, 3))
    for c, b in bone.items():
        offsets[c] = rest_dir[names[c]] * lengths[b]
    T = len(q)
    G = np.zeros((T, 14, 3, 3))
    mid_hip = 0.5 * (q[:, names.index("l_hip")] + q[:, names.index("r_hip")])
    up = _unit(q[:, root] - mid_hip)
    left = (q[:, names.index("l_hip")] - q[:, names.index("r_hip")]
            + q[:, names.index("l_shoulder")] - q[:, names.index("r_shoulder")])
    left = _unit(left - np.sum(left * up, -1, keepdims=True) * up)
    G[:, root] = np.stack([left, up, np.cross(left, up)], -1)
    order = [root]
    for j in order:                      # breadth first: parents before children
        order += SKELETON_14.children(j)
    for j in order[1:]:
        p = parents[j]
        kids = SKELETON_14.children(j)
        if len(kids) == 1:
            c = kids[0]
            have = np.einsum("tij,j->ti", G[:, p], rest_dir[names[c]])
            G[:, j] = _swing(have, _unit(q[:, c] - q[:, j])) @ G[:, p]
        else:
            G[:, j] = G[:, p]
    rotations = np.empty_like(G)
    translations = np.broadcast_to(offsets, (T, 14, 3)).copy()
    for j in range(14):
        p = parents[j]
        if p < 0:
            rotations[:, j] = G[:, j]
            translations[:, j] = q[:, j]
            continue
        rotations[:, j] = np.einsum("tji,tjk->tik", G[:, p], G[:, j])
        if p == root:
            translations[:, j] = np.einsum("tji,tj->ti", G[:, p], q[:, j] - q[:, p])
    return {"offsets": offsets, "rotations": rotations, "translations": translations}


def _octahedron(size: float):
    v = size * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return v, f


class _Glb:
    """Accumulates the binary buffer, buffer views and accessors of a glTF file."""

    def __init__(self):
        self.blob = bytearray()
        self.views, self.accessors = [], []

    def add(self, array: np.ndarray, kind: str, component: int, minmax: bool = False) -> int:
        data = np.ascontiguousarray(array)
        while len(self.blob) % 4:
            self.blob += b"\0"
        self.views.append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": data.nbytes})
        self.blob += data.tobytes()
        acc = {"bufferView": len(self.views) - 1, "componentType": component, "count": len(data), "type": kind}
        if minmax:
            flat = data.reshape(len(data), -1)
            acc["min"], acc["max"] = flat.min(0).tolist(), flat.max(0).tolist()
        self.accessors.append(acc)
        return len(self.accessors) - 1


_FLOAT, _UBYTE, _USHORT = 5126, 5121, 5123


def gltf_document(joints: np.ndarray, fps: float) -> tuple[dict, bytes]:
    """The glTF JSON and binary buffer of a 14-joint sequence with constant bone lengths.

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3)
        Metres, world, finite, constant bone lengths (:func:`rest_pose_joints`).
    fps : float

    Returns
    -------
    gltf : dict
    blob : bytes
    """
    anim = skeleton_animation(joints)
    names, parents = SKELETON_14.joint_names, SKELETON_14.parents
    T = len(joints)
    glb = _Glb()
    rest_global = np.zeros((14, 3))
    for j in range(14):                    # rest position: the offsets summed up the chain to the root
        k, pos = j, np.zeros(3)
        while k >= 0:
            pos += anim["offsets"][k]
            k = parents[k]
        rest_global[j] = pos
    ibm = np.tile(np.eye(4), (14, 1, 1))
    ibm[:, :3, 3] = -rest_global
    ibm_acc = glb.add(ibm.transpose(0, 2, 1).reshape(14, 16).astype(np.float32), "MAT4", _FLOAT)
    verts, faces, jidx = [], [], []
    ov, of = _octahedron(JOINT_MARKER_SIZE_M)
    for j in range(14):
        faces.append(of + len(verts) * 6)
        verts.append(ov + rest_global[j])
        jidx.append(np.full(6, j))
    verts = np.concatenate(verts).astype(np.float32)
    joints0 = np.zeros((len(verts), 4), np.uint8)
    joints0[:, 0] = np.concatenate(jidx)
    weights0 = np.zeros((len(verts), 4), np.float32)
    weights0[:, 0] = 1.0
    prim = {"attributes": {"POSITION": glb.add(verts, "VEC3", _FLOAT, minmax=True),
                           "JOINTS_0": glb.add(joints0, "VEC4", _UBYTE),
                           "WEIGHTS_0": glb.add(weights0, "VEC4", _FLOAT)},
            "indices": glb.add(np.concatenate(faces).reshape(-1).astype(np.uint16), "SCALAR", _USHORT)}
    nodes = []
    for j, n in enumerate(names):
        node = {"name": n, "translation": anim["offsets"][j].tolist()}
        kids = SKELETON_14.children(j)
        if kids:
            node["children"] = kids
        nodes.append(node)
    nodes.append({"name": "joint_markers", "mesh": 0, "skin": 0})
    root = parents.index(-1)
    times = glb.add((np.arange(T) / float(fps)).astype(np.float32), "SCALAR", _FLOAT, minmax=True)
    samplers, channels = [], []
    quats = Rotation.from_matrix(anim["rotations"].reshape(-1, 3, 3)).as_quat().reshape(T, 14, 4)
    for j in range(14):
        samplers.append({"input": times, "output": glb.add(quats[:, j].astype(np.float32), "VEC4", _FLOAT),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": j, "path": "rotation"}})
        if j == root or parents[j] == root:
            samplers.append({"input": times, "interpolation": "LINEAR",
                             "output": glb.add(anim["translations"][:, j].astype(np.float32), "VEC3", _FLOAT)})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": j, "path": "translation"}})
    gltf = {
        "asset": {"version": "2.0", "generator": "toolkit.biomech.export"},
        "scene": 0, "scenes": [{"nodes": [root, len(nodes) - 1]}], "nodes": nodes,
        "skins": [{"name": SKELETON_14.name, "joints": list(range(14)), "skeleton": root,
                   "inverseBindMatrices": ibm_acc}],
        "meshes": [{"name": "joint_markers", "primitives": [prim]}],
        "animations": [{"name": "estimate", "samplers": samplers, "channels": channels}],
        "buffers": [{"byteLength": 0}], "bufferViews": glb.views, "accessors": glb.accessors,
    }
    while len(glb.blob) % 4:
        glb.blob += b"\0"
    gltf["buffers"][0]["byteLength"] = len(glb.blob)
    return gltf, bytes(glb.blob)


def export_gltf(path: str | os.PathLike, joints: np.ndarray, fps: float) -> np.ndarray:
    """Write a binary glTF (``.glb``) of a 14-joint estimate with an animated skeleton.

    Parameters
    ----------
    path : path
        Written atomically.
    joints : ndarray of shape (T, 14, 3)
        Metres, world (z up), NaN = missing.
    fps : float

    Returns
    -------
    ndarray of shape (T, 14, 3)
        The joints the file encodes (:func:`rest_pose_joints`), world axes.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise InputError("fps", "a positive frame rate", repr(fps))
    rest, _, _ = rest_pose_joints(joints)
    gltf, blob = gltf_document(rest, fps)
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    body = (struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob)
    atomic_write_bytes(Path(path), struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
    return rest
