"""BVH and glTF of an estimate: re-read, they give the joints back."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.biomech.export import export_bvh, export_gltf, fill_gaps, rest_pose_joints
from toolkit.errors import InputError
from toolkit.motion import bvh_to_skeleton14, generate_motion, read_bvh
from toolkit.motion.bvh import UP_AXES
from toolkit.skeleton import SKELETON_14

#: The issue's bar for a round trip, metres.
ROUND_TRIP_M = 1e-3
#: Noise added to the estimate's joints, metres (bone lengths then vary by about this much).
NOISE_M = 0.01


def _estimate(seed: int, n_frames: int = 60) -> np.ndarray:
    """A walking 14-joint sequence with per-frame joint noise and a few missing samples."""
    rng = np.random.default_rng(seed)
    j = generate_motion("walk", BodyProportions.from_height(1.75), n_frames, 30.0, rng=rng)
    j = j + rng.normal(0, NOISE_M, j.shape)
    j[rng.integers(1, n_frames - 1, 3), rng.integers(0, 14, 3)] = np.nan
    return j


def test_rest_pose_has_constant_bones_and_stays_near_the_estimate():
    j = _estimate(0)
    rest, lengths, n = rest_pose_joints(j)
    assert n == 3 and np.all(np.isfinite(rest))
    L = SKELETON_14.bone_lengths(rest)
    np.testing.assert_allclose(L, np.broadcast_to(lengths, L.shape), atol=1e-9)
    seen = np.all(np.isfinite(j), -1)
    err = np.linalg.norm(rest - j, axis=-1)[seen]
    assert np.median(err) < 3 * NOISE_M


@pytest.mark.parametrize("seed", [1, 2])
def test_bvh_round_trips_through_the_projects_reader(tmp_path, seed):
    j = _estimate(seed)
    rest = export_bvh(tmp_path / "a.bvh", j, fps=30.0)
    motion = read_bvh(tmp_path / "a.bvh")
    assert motion.n_frames == len(j) and motion.fps == pytest.approx(30.0)
    mapping = {n: {n: 1.0} for n in SKELETON_14.joint_names}
    back = bvh_to_skeleton14(motion, mapping=mapping, units=0.01, up_axis="y", constant_lengths=False)
    err = np.linalg.norm(back - rest, axis=-1)
    assert err.max() < ROUND_TRIP_M, err.max()


def _gltf_positions(path):
    """World positions (T, 14, 3) of the skin's joints by forward kinematics of the glTF's animation."""
    import pygltflib

    g = pygltflib.GLTF2().load(str(path))
    blob = g.binary_blob()

    def read(i):
        acc = g.accessors[i]
        view = g.bufferViews[acc.bufferView]
        n = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc.type]
        dtype = {5126: np.float32, 5121: np.uint8, 5123: np.uint16}[acc.componentType]
        a = np.frombuffer(blob, dtype, acc.count * n, view.byteOffset or 0)
        return a.reshape(acc.count, n) if n > 1 else a

    skin = g.skins[0]
    anim = g.animations[0]
    times = read(anim.samplers[0].input)
    T = len(times)
    trans = {i: np.tile(np.array(g.nodes[i].translation or [0, 0, 0], float), (T, 1)) for i in skin.joints}
    rot = {i: np.tile(np.array(g.nodes[i].rotation or [0, 0, 0, 1], float), (T, 1)) for i in skin.joints}
    for ch in anim.channels:
        out = read(anim.samplers[ch.sampler].output).astype(float)
        (trans if ch.target.path == "translation" else rot)[ch.target.node] = out
    parent = {c: p for p in skin.joints for c in (g.nodes[p].children or [])}
    G, P = {}, {}

    def world(i):
        if i in P:
            return
        R = Rotation.from_quat(rot[i]).as_matrix()
        if i in parent:
            world(parent[i])
            G[i] = G[parent[i]] @ R
            P[i] = P[parent[i]] + np.einsum("tij,tj->ti", G[parent[i]], trans[i])
        else:
            G[i], P[i] = R, trans[i]

    for i in skin.joints:
        world(i)
    return g, times, np.stack([P[i] for i in skin.joints], 1)


@pytest.mark.parametrize("seed", [3, 4])
def test_gltf_loads_in_pygltflib_with_every_joint_and_frame(tmp_path, seed):
    pytest.importorskip("pygltflib")
    j = _estimate(seed, n_frames=45)
    rest = export_gltf(tmp_path / "a.glb", j, fps=30.0)
    g, times, pos = _gltf_positions(tmp_path / "a.glb")
    assert len(g.skins[0].joints) == 14
    assert [g.nodes[i].name for i in g.skins[0].joints] == list(SKELETON_14.joint_names)
    assert len(times) == 45 and times[-1] == pytest.approx(44 / 30.0)
    world = pos @ UP_AXES["y"].T              # file (y up) -> world (z up)
    err = np.linalg.norm(world - rest, axis=-1)
    assert err.max() < ROUND_TRIP_M, err.max()


def test_gap_filling_and_bad_input():
    j = np.zeros((5, 14, 3))
    j[:, :, 0] = np.arange(5)[:, None]
    j[2, 3] = np.nan
    filled, n = fill_gaps(j)
    assert n == 1 and filled[2, 3, 0] == pytest.approx(2.0)
    j[:, 5] = np.nan
    with pytest.raises(InputError, match="never seen"):
        fill_gaps(j)
    with pytest.raises(InputError, match="joints"):
        rest_pose_joints(np.zeros((5, 13, 3)))
