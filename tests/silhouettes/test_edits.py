"""The user's edits file (claim 7): parsing, validation, application, the template."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.silhouettes import Edits, JointEdit, edits_template, parse_edits, read_edits
from toolkit.skeleton import SKELETON_14

TOML = """
[[edit]]
frame = 2
camera = "cam0"
joints = { l_wrist = [81.0, 44.5], r_knee = [79, 61] }

[[edit]]
frame = 2
camera = "cam0"
add_to_database = false
[edit.joints]
l_wrist = [90.0, 40.0]

[[edit]]
frame = 3
camera = "cam1"
[edit.joints]
head = [10.0, 5.0]
"""


def test_read_toml_and_json(tmp_path):
    p = tmp_path / "edits.toml"
    p.write_text(TOML)
    e = read_edits(p, ["cam0", "cam1"], n_frames=5)
    assert len(e) == 3 and e.frames == {2, 3} and e.path == str(p)
    assert e.edits[0] == JointEdit(2, "cam0", (("l_wrist", (81.0, 44.5)), ("r_knee", (79.0, 61.0))), True)
    j = tmp_path / "edits.json"
    j.write_text(json.dumps(tomllib.loads(TOML)))
    assert read_edits(j).edits == e.edits


def test_for_frame_merges_in_file_order():
    e = parse_edits(tomllib.loads(TOML))
    f2 = e.for_frame(2)
    assert set(f2) == {"cam0"}
    assert dict(f2["cam0"].joints) == {"l_wrist": (90.0, 40.0), "r_knee": (79.0, 61.0)}
    assert f2["cam0"].add_to_database is False
    assert e.for_frame(0) == {}


def test_apply_replaces_only_the_named_joints():
    pose = np.arange(28, dtype=float).reshape(14, 2)
    edit = JointEdit(0, "cam0", (("l_wrist", (1.5, 2.5)),))
    out = edit.apply(pose)
    i = SKELETON_14.index("l_wrist")
    np.testing.assert_array_equal(out[i], [1.5, 2.5])
    np.testing.assert_array_equal(np.delete(out, i, 0), np.delete(pose, i, 0))
    assert pose[i, 0] == 2 * i  # the input is not modified


@pytest.mark.parametrize("text, where", [
    ('[[edit]]\nframe = 1\ncamera = "cam0"\njoints = { nose = [1, 2] }', "joints.nose"),
    ('[[edit]]\nframe = 1\ncamera = "camX"\njoints = { head = [1, 2] }', "camera"),
    ('[[edit]]\nframe = 9\ncamera = "cam0"\njoints = { head = [1, 2] }', "frame"),
    ('[[edit]]\nframe = -1\ncamera = "cam0"\njoints = { head = [1, 2] }', "frame"),
    ('[[edit]]\nframe = 1\ncamera = "cam0"\njoints = { head = [1] }', "joints.head"),
    ('[[edit]]\nframe = 1\ncamera = "cam0"\njoints = { head = [1, nan] }', "joints.head"),
    ('[[edit]]\nframe = 1\ncamera = "cam0"\njoints = { head = ["a", 2] }', "joints.head"),
    ('[[edit]]\nframe = 1\ncamera = "cam0"', "edit[0].joints"),
    ('[[edit]]\nframe = 1\ncamera = "cam0"\njoints = { head = [1, 2] }\ncolour = 3', "edit[0]"),
    ('[[edit]]\nframe = 1\ncamera = "cam0"\njoints = { head = [1, 2] }\nadd_to_database = 1', "add_to_database"),
    ('[edits]\nframe = 1', "edits.toml"),
    ('[[edit]\nframe = 1', "edits.toml"),
])
def test_bad_edits_name_the_field(tmp_path, text, where):
    p = tmp_path / "edits.toml"
    p.write_text(text)
    with pytest.raises(InputError) as info:
        read_edits(p, ["cam0", "cam1"], n_frames=5)
    assert str(p) in info.value.where and where in info.value.where


def test_bad_paths(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_edits(tmp_path / "missing.toml")
    (tmp_path / "edits.yaml").write_text("edit: []")
    with pytest.raises(InputError, match=".yaml"):
        read_edits(tmp_path / "edits.yaml")


def test_template_reads_back_as_edits():
    rng = np.random.default_rng(0)
    poses = {"cam0": rng.uniform(0, 500, (4, 14, 2)), "cam 1": rng.uniform(0, 500, (4, 14, 2))}
    poses["cam 1"][2, 5] = np.nan
    text = edits_template(poses, [2, 3])
    e = parse_edits(tomllib.loads(text), "template")
    assert len(e) == 4 and isinstance(e, Edits)
    got = e.for_frame(2)["cam 1"]
    assert len(got.joints) == 13 and "r_shoulder" not in got.joint_names
    np.testing.assert_allclose(got.apply(poses["cam 1"][2]), np.where(np.isnan(poses["cam 1"][2]), np.nan,
                                                                      poses["cam 1"][2]), atol=0.05, equal_nan=True)
