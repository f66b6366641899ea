"""SilhouetteDatabase: construction, growth, save / load round trip, errors on bad files."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.io import atomic_save_npz
from toolkit.silhouettes import FORMAT_NAME, FORMAT_VERSION, DatabaseEntry, SilhouetteDatabase
from toolkit.silhouettes.database import FLOW_SIZE


def random_db(n=20, seed=0, flows=False) -> SilhouetteDatabase:
    rng = np.random.default_rng(seed)
    f = rng.normal(0, 0.05, (n, FLOW_SIZE)) if flows else None
    if flows:
        f[1] = np.nan  # an entry without flow
    return SilhouetteDatabase(rng.random((n, 1280)), rng.random((n, 14, 2)),
                              motion=[f"m{i % 3}" for i in range(n)], azimuth_deg=rng.uniform(-180, 180, n),
                              elevation_deg=rng.uniform(0, 35, n), frame=np.arange(n),
                              source=[f"seq {i}" for i in range(n)], flows=f)


def assert_same(a: SilhouetteDatabase, b: SilhouetteDatabase):
    assert len(a) == len(b)
    np.testing.assert_array_equal(a.descriptors, b.descriptors)
    np.testing.assert_array_equal(a.joints, b.joints)
    np.testing.assert_array_equal(a.motion, b.motion)
    np.testing.assert_array_equal(a.azimuth_deg, b.azimuth_deg)
    np.testing.assert_array_equal(a.elevation_deg, b.elevation_deg)
    np.testing.assert_array_equal(a.frame, b.frame)
    np.testing.assert_array_equal(a.source, b.source)
    if a.flows is None:
        assert b.flows is None
    else:
        np.testing.assert_array_equal(a.flows, b.flows)


def test_arrays_are_quantised_and_read_only():
    db = random_db()
    assert db.descriptors.dtype == np.uint8 and db.descriptors.shape == (20, 1280)
    assert db.joints.shape == (20, 14, 2)
    with pytest.raises(ValueError):
        db.descriptors[0, 0] = 3
    assert len(db.joint_names) == 14


@pytest.mark.parametrize("flows", [False, True])
def test_save_load_round_trip(tmp_path, flows):
    db = random_db(flows=flows)
    path = db.save(tmp_path / "db.npz")
    assert_same(db, SilhouetteDatabase.load(path))


def test_empty_database_round_trip(tmp_path):
    db = SilhouetteDatabase.empty()
    assert len(db) == 0
    assert len(SilhouetteDatabase.load(db.save(tmp_path / "empty.npz"))) == 0


def test_add_entry_from_silhouette_and_extend():
    db = random_db(5)
    mask = np.zeros((60, 40), bool)
    mask[10:50, 12:30] = True
    joints = np.column_stack([np.linspace(12, 29, 14), np.linspace(10, 49, 14)])
    entry = DatabaseEntry.from_silhouette(mask, joints, frame=7, source="cam_01 frame 7")
    i = db.add(entry)
    assert i == 5 and len(db) == 6
    np.testing.assert_array_equal(db.descriptors[i], 255)
    np.testing.assert_allclose(db.joints[i, 0], [(12 - 11.5) / 18, (10 - 9.5) / 40], atol=1e-6)
    assert db.motion[i] == "user" and db.frame[i] == 7
    e = db.entry(i)
    assert e.source == "cam_01 frame 7" and np.isnan(e.azimuth_deg)
    other = random_db(3, seed=1)
    db.extend(other)
    assert len(db) == 9
    np.testing.assert_array_equal(db.descriptors[6:], other.descriptors)
    sub = db.subset([0, 8])
    np.testing.assert_array_equal(sub.joints[1], other.joints[2])


def test_bad_entries_are_refused():
    db = random_db(3)
    with pytest.raises(InputError, match="entry.joints"):
        db.add(DatabaseEntry(np.zeros(1280), np.full((14, 2), np.nan)))
    with pytest.raises(InputError, match="entry.descriptor"):
        db.add(DatabaseEntry(np.zeros(100), np.zeros((14, 2))))
    with pytest.raises(InputError, match="joints"):
        SilhouetteDatabase(np.zeros((2, 1280)), np.zeros((3, 14, 2)))
    assert len(db) == 3


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        SilhouetteDatabase.load(tmp_path / "nothing.npz")
    bad = tmp_path / "garbage.npz"
    bad.write_bytes(b"this is not a zip archive")
    with pytest.raises(InputError, match="garbage.npz"):
        SilhouetteDatabase.load(bad)


def _fields(db: SilhouetteDatabase, tmp_path) -> dict:
    with np.load(db.save(tmp_path / "ok.npz")) as z:
        return {k: z[k] for k in z.files}


@pytest.mark.parametrize("change, field", [
    (lambda f: f.update(format=np.array("something else")), "format"),
    (lambda f: f.update(version=np.array(FORMAT_VERSION + 1)), "version"),
    (lambda f: f.update(grid=np.array([40, 32])), "grid"),
    (lambda f: f.pop("joints"), "joints"),
    (lambda f: f.update(joints=f["joints"][:, :10]), "joints"),
    (lambda f: f.update(descriptors=f["descriptors"].astype(np.float32)), "descriptors"),
    (lambda f: f.update(joint_names=f["joint_names"][::-1]), "joint_names"),
    (lambda f: f.update(motion=f["motion"][:3]), "motion"),
])
def test_bad_files_name_the_file_and_field(tmp_path, change, field):
    fields = _fields(random_db(), tmp_path)
    change(fields)
    path = atomic_save_npz(tmp_path / "bad.npz", **fields)
    with pytest.raises(InputError) as info:
        SilhouetteDatabase.load(path)
    assert "bad.npz" in info.value.where and field in info.value.where


def test_file_layout_is_documented(tmp_path):
    path = random_db().save(tmp_path / "db.npz")
    with zipfile.ZipFile(path) as z:
        names = {n[:-4] for n in z.namelist()}
    assert {"format", "version", "grid", "levels", "joint_names", "descriptors", "joints", "motion", "azimuth_deg",
            "elevation_deg", "frame", "source"} <= names
    with np.load(path, allow_pickle=False) as z:
        assert str(z["format"]) == FORMAT_NAME
