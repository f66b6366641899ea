"""Scenes with several players: the ``[players]`` spec, per-person ground truth, crossings, the zoo."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from toolkit.anthropometry import BodyProportions
from toolkit.body.model import BodyModel, BodyShape
from toolkit.errors import InputError
from toolkit.io import Dataset
from toolkit.motion import generate_motion
from toolkit.skeleton import SKELETON_14
from toolkit.synthetic import build_scene, generate_scene, load_spec, parse_spec
from toolkit.synthetic.environment import make_environment
from toolkit.synthetic.generator import RNG_STREAMS, make_renderer
from toolkit.synthetic.players import (CAMERA_CLEARANCE_M, MIN_CLEARANCE_M, MIN_CROSSING_CLEARANCE_M,
                                       draw_players, group_extent, player_streams, players_zoo)
from toolkit.synthetic.render import Raycaster
from toolkit.synthetic.rigs import make_rig, novel_rig, perturb_rig
from tests.synthetic.conftest import TINY_SPEC

#: Two people crossing a studio, tiny images (the fast end-to-end scene of this module).
PLAYERS_SPEC = """
seed = 3
frames = 3
fps = 25
[subject]
height_m = 1.75
motion = "walk"
[cameras]
count = 2
layout = "studio"
resolution = [160, 120]
calibration_error_px = 1.0
[players]
count = 2
[novel]
count = 1
"""
#: A joint lies inside its own body: where another person covers it, that person's surface is nearer
#: the camera than the joint by more than this (metres; own-body surfaces are within ~0.15 m).
OCCLUDER_MARGIN_M = 0.1
#: Depth PNGs hold whole millimetres.
DEPTH_TOL_M = 0.0006
_J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}


def _pelvis_neck(joints: np.ndarray) -> np.ndarray:
    """(T, 2, 3): the hip centre and the neck."""
    pelvis = 0.5 * (joints[:, _J["l_hip"]] + joints[:, _J["r_hip"]])
    return np.stack([pelvis, joints[:, _J["neck"]]], 1)


@pytest.fixture(scope="module")
def players_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("players") / "scene"
    generate_scene(parse_spec(PLAYERS_SPEC, "players.toml"), out, progress=False).close()
    return out


# ------------------------------------------------------------------ spec
def test_spec_parses_with_defaults():
    spec = parse_spec(PLAYERS_SPEC, "players.toml")
    ps = spec.players
    assert (ps.count, ps.path, ps.motion, ps.kits, ps.players) == (2, "cross", "walk", "random", ())
    b = parse_spec(PLAYERS_SPEC.replace('"studio"', '"broadcast"').replace('motion = "walk"', 'motion = "wave"'))
    assert b.players.kits == "teams" and b.players.motion == "walk"  # an in-place subject: the others walk
    s = parse_spec(PLAYERS_SPEC.replace("count = 2\n[novel]", 'count = 3\npath = "spots"\n[[players.player]]\n'
                                        'motion = "kick"\nheight_m = 1.9\n[novel]'))
    assert s.players.motion == "idle" and s.players.override(1).motion == "kick"
    assert s.players.override(1).height_m == 1.9 and s.players.override(2).motion is None
    assert parse_spec(TINY_SPEC).players is None


def test_example_specs_parse():
    from pathlib import Path
    root = Path(__file__).resolve().parents[2] / "datasets_synthetic"
    pb, ps = load_spec(root / "players_broadcast.toml"), load_spec(root / "players_studio.toml")
    assert (pb.players.count, pb.camera_count, pb.resolution, pb.frames, pb.players.kits) == \
        (4, 3, (1280, 720), 24, "teams")
    assert (ps.players.count, ps.camera_count, ps.layout) == (3, 4, "studio")


@pytest.mark.parametrize("old, new, field", [
    ("count = 2\n[novel]", "count = 0\n[novel]", "players.count"),
    ("count = 2\n[novel]", "count = 7\n[novel]", "players.count"),
    ("count = 2\n[novel]", 'count = "two"\n[novel]', "players.count"),
    ("count = 2\n[novel]", 'count = 2\npath = "zigzag"\n[novel]', "players.path"),
    ("count = 2\n[novel]", 'count = 2\nkits = "stripes"\n[novel]', "players.kits"),
    ("count = 2\n[novel]", 'count = 2\nmotion = "moonwalk"\n[novel]', "players.motion"),
    ("count = 2\n[novel]", "count = 2\nteam_shirts = [[1, 0, 0], [0, 0, 1]]\n[novel]", "players.team_shirts"),
    ("count = 2\n[novel]", 'count = 2\nkits = "teams"\nteam_shirts = [[1, 0, 0]]\n[novel]', "players.team_shirts"),
    ("count = 2\n[novel]", 'count = 2\nkits = "teams"\nteam_shirts = [[1, 0, 0], [0, 2, 1]]\n[novel]',
     "players.team_shirts[1]"),
    ("count = 2\n[novel]", "count = 2\nheight_m = [1.2, 1.8]\n[novel]", "players.height_m"),
    ("count = 2\n[novel]", "count = 2\nspread_m = 0.1\n[novel]", "players.spread_m"),
    ("count = 2\n[novel]", "count = 2\nteams = 2\n[novel]", "unknown keys"),
    ("count = 2\n[novel]", "count = 2\n[[players.player]]\n[[players.player]]\n[novel]", "players.player"),
    ("count = 2\n[novel]", '[[players.player]]\nmotion = "fly"\n[novel]', "players.count"),
    ("count = 2\n[novel]", 'count = 2\n[[players.player]]\nmotion = "fly"\n[novel]', "players.player[0].motion"),
    ("count = 2\n[novel]", "count = 2\n[[players.player]]\nheight_m = 2.5\n[novel]", "players.player[0].height_m"),
    ("count = 2\n[novel]", "count = 2\n[[players.player]]\nshirt_rgb = [1, 1]\n[novel]",
     "players.player[0].shirt_rgb"),
    ("count = 2\n[novel]", "count = 2\n[[players.player]]\nspeed = 3\n[novel]", "unknown keys"),
    ("count = 2\n[novel]", "count = 2\n[depth_camera]\n[novel]", "players"),
])
def test_bad_values_name_the_field(old, new, field):
    text = PLAYERS_SPEC.replace(old, new, 1)
    assert text != PLAYERS_SPEC
    with pytest.raises(InputError) as e:
        parse_spec(text, "scene.toml")
    assert field in str(e.value) and "scene.toml" in str(e.value)


# ------------------------------------------------------------------ one person: unchanged
def _streams(seed: int) -> dict:
    seqs = np.random.SeedSequence(seed).spawn(len(RNG_STREAMS))
    return {name: np.random.default_rng(s) for name, s in zip(RNG_STREAMS, seqs)}


def _reference_scene(spec):
    """The one-person scene as :func:`build_scene` drew it before ``[players]`` existed."""
    rngs = _streams(spec.seed)
    props = BodyProportions.sample(spec.height_m, rngs["body"])
    body = BodyModel(BodyShape.sample(props, rngs["body"]), rngs["body"])
    joints = generate_motion(spec.motion, props, spec.frames, spec.fps, rngs["motion"])
    centre = np.r_[np.nanmean(joints[:, 1, :2], axis=0), 0.0]
    rig = make_rig(spec.layout, spec.camera_count, spec.resolution, spec.height_m, rngs["cameras"], centre=centre)
    measured, _ = perturb_rig(rig, spec.calibration_error_px, joints.reshape(-1, 3), rngs["calibration"])
    novel = novel_rig(spec.layout, rig, spec.novel_count, spec.height_m, rngs["novel"], centre=centre)
    az = rngs["light"].uniform(0, 2 * np.pi)
    el = rngs["light"].uniform(np.radians(35), np.radians(70))
    light = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return body, joints, rig, measured, novel, light, rngs


def test_one_person_scene_unchanged(tiny_dataset):
    spec = parse_spec(TINY_SPEC)
    body, joints, rig, measured, novel, light, rngs = _reference_scene(spec)
    scene = build_scene(spec)
    assert scene.players == () and scene.crossing is None
    np.testing.assert_array_equal(scene.joints, joints)
    np.testing.assert_array_equal(scene.light_dir, light)
    for a, b in zip((*scene.rig, *scene.measured_rig, *scene.novel), (*rig, *measured, *novel)):
        np.testing.assert_array_equal(a.K, b.K)
        np.testing.assert_array_equal(a.cam_from_world, b.cam_from_world)
    # a frame through the old loop: one body rendered and cast alone
    t = 1
    mesh = body.mesh(joints[t])
    env = make_environment(spec.layout, rngs["environment"])
    renderer = make_renderer(spec, env)
    renderer.set_bodies([(mesh, mesh.shaded_colors(light))])
    caster = Raycaster(env)
    ds = Dataset.open(tiny_dataset)
    cam = novel[0]
    np.testing.assert_array_equal(ds.novel_image(cam.name, t), renderer.render(cam))
    for cam in rig:
        labels, subject, _ = caster.cast(cam, [mesh])
        np.testing.assert_array_equal(ds.gt_parts(cam.name, t), labels)
        np.testing.assert_array_equal(ds.gt_mask(cam.name, t), subject > 0)
        # no per-person files; the reader treats it as one person
        np.testing.assert_array_equal(ds.gt_instances(cam.name, t), (subject > 0).astype(np.uint8))
    assert ds.people_count == 1 and not ds.layout.people.exists()
    assert not (ds.layout.groundtruth / "instances").exists()
    np.testing.assert_array_equal(ds.gt_people_joints3d(), joints[None])
    assert "players" not in json.loads((ds.layout.groundtruth / "scene_info.json").read_text())


# ------------------------------------------------------------------ per-person ground truth
def test_people_and_instances_agree_with_masks_and_joints(players_dataset):
    ds = Dataset.open(players_dataset)
    people = ds.gt_people_joints3d()
    assert ds.people_count == 2 and people.shape == (2, 3, 14, 3)
    np.testing.assert_array_equal(people[0], ds.gt_joints3d())
    assert np.isfinite(people).all()
    own = np.zeros(2, int)
    for cam in ds.gt_rig:
        for t in range(ds.n_frames):
            ids, mask, parts = ds.gt_instances(cam.name, t), ds.gt_mask(cam.name, t), ds.gt_parts(cam.name, t)
            depth = ds.gt_depth(cam.name, t)
            np.testing.assert_array_equal(ids > 0, mask)      # the mask is the union of the people
            np.testing.assert_array_equal(parts > 0, mask)    # parts: the front-most body's labels
            assert set(np.unique(ids)) <= {0, 1, 2}
            for k in range(2):
                for x in _pelvis_neck(people[k])[t]:
                    u, v = np.round(cam.project(x)).astype(int)
                    assert 0 <= u < cam.width and 0 <= v < cam.height
                    assert ids[v, u] != 0                          # the joint is inside a body
                    if ids[v, u] == k + 1:
                        own[k] += 1
                    else:                                           # another person in front of it
                        assert depth[v, u] < cam.depth_of(x) - OCCLUDER_MARGIN_M
    assert (own > 0).all()
    for cam in ds.novel_rig:
        for t in range(ds.n_frames):
            np.testing.assert_array_equal(ds.novel_instances(cam.name, t) > 0, ds.novel_mask(cam.name, t))
    info = json.loads((ds.layout.groundtruth / "scene_info.json").read_text())
    assert [p["index"] for p in info["players"]] == [0, 1]
    assert set(info["players"][1]["subject_height_px"]) == set(ds.camera_names)
    assert info["players"][0]["stature_m"] == 1.75


def test_crossing_pair_occludes_in_the_first_camera(players_dataset):
    """At the crossing frame the first camera sees one player partly in front of the other."""
    scene = build_scene(parse_spec(PLAYERS_SPEC, "players.toml"))
    c = scene.crossing
    assert c is not None and (c.first, c.second) == (0, 1) and c.frame == 1
    ds = Dataset.open(players_dataset)
    cam = ds.gt_rig[0]
    ids, depth = ds.gt_instances(cam.name, c.frame), ds.gt_depth(cam.name, c.frame)
    assert {1, 2} <= set(np.unique(ids))                       # both seen
    z = [cam.depth_of(_pelvis_neck(p.joints)[c.frame, 0]) for p in scene.players]
    front, back = (0, 1) if z[0] < z[1] else (1, 0)
    assert np.median(depth[ids == front + 1]) < np.median(depth[ids == back + 1])
    # the one behind, cast alone, covers pixels where the one in front is seen: an occlusion
    alone = Raycaster().cast(cam, [scene.players[back].body.mesh(scene.players[back].joints[c.frame])])[1] > 0
    assert (alone & (ids == front + 1)).sum() > 0
    assert (alone & (ids == back + 1)).sum() > 0                # and it is only partly hidden
    info = json.loads((ds.layout.groundtruth / "scene_info.json").read_text())
    assert info["crossing"]["front"] == front and info["crossing"]["camera"] == cam.name


def test_people_are_clear_of_each_other_and_in_view():
    for spec in players_zoo(5, 12, frames=12):
        scene = build_scene(spec)
        assert len(scene.players) == spec.players.count
        hips = [0.5 * (p.joints[:, _J["l_hip"], :2] + p.joints[:, _J["r_hip"], :2]) for p in scene.players]
        pair = {scene.crossing.first, scene.crossing.second} if scene.crossing else set()
        for a in range(len(hips)):
            for b in range(a + 1, len(hips)):
                need = MIN_CROSSING_CLEARANCE_M if {a, b} == pair else MIN_CLEARANCE_M
                assert np.linalg.norm(hips[a] - hips[b], axis=-1).min() >= need - 1e-9, spec.source
        joints = scene.people_joints.reshape(-1, 3)
        for cam in (*scene.rig, *scene.novel):
            uv = cam.project(joints)
            assert cam.in_image(uv).all(), (spec.source, cam.name)


def test_long_walks_in_a_studio_stay_in_view():
    """Walks too long for the studio ring push the cameras back; trinocular heads stay rigid."""
    text = PLAYERS_SPEC.replace("frames = 3", "frames = 100").replace("count = 2\n[novel]", "count = 4\n[novel]")
    scene = build_scene(parse_spec(text))
    centre, radius = group_extent(list(scene.players))
    joints = scene.people_joints.reshape(-1, 3)
    for cam in (*scene.rig, *scene.novel):
        assert np.linalg.norm(cam.center[:2] - centre[:2]) >= radius + CAMERA_CLEARANCE_M - 1e-9
        assert cam.in_image(cam.project(joints)).all()
    tri = build_scene(parse_spec(text.replace('count = 2\nlayout = "studio"', 'count = 6\nlayout = "trinocular"')))
    ref = build_scene(parse_spec(text.replace('count = 2\nlayout = "studio"', 'count = 6\nlayout = "trinocular"')
                                 .replace("[players]\ncount = 4\n", "")))
    for k in range(0, 6, 3):
        head, ref_head = tri.rig[k:k + 3], ref.rig[k:k + 3]
        for c in head[1:]:
            np.testing.assert_allclose(c.K, head[0].K)
            np.testing.assert_allclose(c.R, head[0].R, atol=1e-12)
        for i in (1, 2):  # the baselines of the head as drawn
            assert np.linalg.norm(head[i].center - head[0].center) == pytest.approx(
                np.linalg.norm(ref_head[i].center - ref_head[0].center), abs=1e-9)


def test_overriding_a_player_leaves_the_others():
    base = parse_spec(PLAYERS_SPEC.replace("count = 2\n[novel]", "count = 3\n[novel]"))
    other = parse_spec(PLAYERS_SPEC.replace("count = 2\n[novel]", 'count = 3\n[[players.player]]\n'
                                            '[[players.player]]\nmotion = "run"\nheight_m = 1.6\n[novel]'))
    assert len(player_streams(base.seed)["players"]) >= 3
    a, _, _ = draw_players(base, _streams(base.seed))
    b, _, _ = draw_players(other, _streams(other.seed))
    np.testing.assert_array_equal(a[1].joints, b[1].joints)
    np.testing.assert_array_equal(a[1].body.shape.colours, b[1].body.shape.colours)
    assert b[2].motion == "run" and b[2].proportions.height == 1.6 and a[2].motion == "walk"


# ------------------------------------------------------------------ reader checks
def _copy(src, tmp_path):
    dst = tmp_path / "copy"
    shutil.copytree(src, dst)
    return dst


def test_reader_rejects_bad_people(players_dataset, tmp_path):
    root = _copy(players_dataset, tmp_path)
    people = root / "groundtruth" / "people.npz"
    z = dict(np.load(people))
    np.savez(people, joints=z["joints"][:, :2], names=z["names"])
    with pytest.raises(InputError, match="people.npz"):
        Dataset.open(root)
    np.savez(people, joints=z["joints"][::-1], names=z["names"])   # person 0 must be joints3d.npz
    with pytest.raises(InputError, match=r"joints\[0\]"):
        Dataset.open(root)
    np.savez(people, joints=z["joints"])
    with pytest.raises(InputError, match="names"):
        Dataset.open(root)


def test_reader_rejects_bad_instances(players_dataset, tmp_path):
    from toolkit.io.frames import read_png
    from toolkit.io.atomic import atomic_write_png
    root = _copy(players_dataset, tmp_path)
    ds = Dataset.open(root)
    cam = ds.camera_names[0]
    path = ds.layout.instances(cam, 0)
    ids = read_png(path, channels=1, dtype=np.uint8)
    ids[0, 0] = 3
    atomic_write_png(path, ids)
    with pytest.raises(InputError, match="person ids"):
        ds.gt_instances(cam, 0)
    (root / "groundtruth" / "instances" / "nobody").mkdir()
    with pytest.raises(InputError, match="nobody"):
        Dataset.open(root)


def test_writer_refuses_bad_people(tmp_path):
    from toolkit.io import DatasetWriter
    w = DatasetWriter(tmp_path / "w", 25)
    with pytest.raises(InputError, match="write_people"):
        w.write_people(np.zeros((2, 3, 14)), SKELETON_14.joint_names)
    with pytest.raises(InputError, match="names"):
        w.write_people(np.zeros((2, 3, 14, 3)), ["a"])


# ------------------------------------------------------------------ the zoo
def test_zoo_is_varied_and_reproducible():
    specs = players_zoo(0, 12)
    assert [s.text for s in specs] == [s.text for s in players_zoo(0, 12)]
    assert [s.text for s in specs] != [s.text for s in players_zoo(1, 12)]
    first = specs[:10]
    assert {(s.players.count, s.layout) for s in first} == {(n, lay) for n in range(2, 7)
                                                           for lay in ("broadcast", "studio")}
    assert {s.camera_count for s in specs} <= {2, 3, 4}
    for s in specs:
        assert s.players is not None and 2 <= s.players.count <= 6
        if s.layout == "broadcast":
            assert s.players.kits == "teams" and 100 <= s.subject_px[0] <= 300
    many = players_zoo(0, 40)
    assert any(s.outfit == "like_background" for s in many)
    assert {s.players.path for s in many} == {"cross", "spots"}
    assert len({s.source for s in many}) == 40
    with pytest.raises(InputError, match="count"):
        players_zoo(0, -1)
