"""What a careless user or a damaged disk hands the readers: each a clear InputError or the right reading."""

from __future__ import annotations

import json
import os
import warnings

import numpy as np
import pytest

from tests.io.test_io_dataset import make_truth, write_dataset
from toolkit.errors import InputError
from toolkit.io.calibration import read_calibration, write_calibration
from toolkit.io.dataset import Dataset
from toolkit.io.depth_readers import list_depth_frames, read_depth, read_depth_intrinsics
from toolkit.io.keypoint_files import read_camera_detections
from toolkit.io.keypoint_formats import read_keypoints
from toolkit.io.runs import check_out_folder, dataset_fingerprint, staged_folder, start_run
from toolkit.io.text import load_json, load_toml
from toolkit.pipeline.run import load_config

BOM = "\ufeff".encode()
#: Nesting deeper than Python's parsers recurse (they raise RecursionError at about 1000 levels).
DEEP = 100_000


def openpose_file(path, conf=0.9, n=25):
    kp = np.tile([100.0, 50.0, conf], n)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"version": 1.3, "people": [{"pose_keypoints_2d": kp.tolist()}]}))
    return path


# ------------------------------------------------------------ text files
def test_bom_is_read_as_the_same_file(tmp_path, make_rig):
    rig = make_rig(np.random.default_rng(0), n_cams=2)
    plain = write_calibration(tmp_path / "a.toml", rig)
    bom = tmp_path / "b.toml"
    bom.write_bytes(BOM + plain.read_bytes())
    assert read_calibration(bom).names == read_calibration(plain).names
    kp = openpose_file(tmp_path / "cam01" / "cam01.0000.json")
    kp.write_bytes(BOM + kp.read_bytes())
    det = read_camera_detections(kp.parent)
    assert det.people[0].shape == (1, 25, 3)
    cfg = tmp_path / "c.toml"
    cfg.write_bytes(BOM + b"seed = 5\n")
    assert load_toml(cfg) == {"seed": 5}


@pytest.mark.parametrize("text,reader", [("a = " + "[" * DEEP + "]" * DEEP, load_toml),
                                         ("[" * DEEP + "]" * DEEP, load_json)], ids=["toml", "json"])
def test_deep_nesting_is_an_input_error(tmp_path, text, reader):
    f = tmp_path / "deep.txt"
    f.write_text(text)
    with pytest.raises(InputError, match="nested too deep") as e:
        reader(f)
    assert str(f) in str(e.value)


def test_deep_calibration_and_config(tmp_path):
    cal = tmp_path / "calib.toml"
    cal.write_text("[cam]\nmatrix = " + "[" * DEEP + "]" * DEEP + "\n")
    with pytest.raises(InputError, match="nested too deep"):
        read_calibration(cal)
    from toolkit.pipeline.depth_tracking import DepthTrackingRunConfig

    with pytest.raises(InputError, match="nested too deep"):
        load_config(DepthTrackingRunConfig, cal)


def test_folder_missing_and_binary_text(tmp_path):
    with pytest.raises(InputError, match="a folder"):
        load_json(tmp_path)
    with pytest.raises(InputError, match="no such file"):
        load_toml(tmp_path / "nope.toml")
    (tmp_path / "bin.json").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(InputError, match="UTF-8"):
        load_json(tmp_path / "bin.json")
    big = tmp_path / "big.json"
    big.write_text("[" + "1," * 20 + "1]")
    with pytest.raises(InputError, match="at most 10 bytes"):
        load_json(big, max_bytes=10)


# ------------------------------------------------------------ keypoints
@pytest.mark.parametrize("conf", [float("inf"), 1e400])
def test_infinite_confidence_is_an_error(tmp_path, conf):
    """Infinite confidences were taken as weights and gave infinite joints reported as success."""
    f = openpose_file(tmp_path / "cam01" / "cam01.0000.json", conf=conf)
    with pytest.raises(InputError, match="finite confidences") as e:
        read_camera_detections(f.parent)
    assert "cam01.0000.json" in str(e.value)


def test_nan_confidence_is_missing(tmp_path):
    f = openpose_file(tmp_path / "cam01" / "cam01.0000.json", conf=float("nan"))
    det = read_camera_detections(f.parent)
    assert (det.people[0][..., 2] == 0).all() and np.isnan(det.people[0][..., :2]).all()


def test_frame_numbers_that_never_meet(tmp_path):
    """Two cameras numbered 0-2 and 10-12 gave no estimate and no word; now an error naming both ranges."""
    for t in range(3):
        openpose_file(tmp_path / "cam01" / f"cam01.{t:04d}.json")
        openpose_file(tmp_path / "cam02" / f"cam02.{t + 10:04d}.json")
    with pytest.raises(InputError, match="no frame number in two cameras") as e:
        read_keypoints([tmp_path / "cam01", tmp_path / "cam02"], "body_25")
    assert "frames 0-2" in str(e.value) and "frames 10-12" in str(e.value)
    # overlapping in part: read, aligned by number
    openpose_file(tmp_path / "cam02" / "cam02.0002.json")
    kin = read_keypoints([tmp_path / "cam01", tmp_path / "cam02"], "body_25")
    assert kin.frames.tolist() == [0, 1, 2, 10, 11, 12]
    assert (~kin.missing).sum(axis=0).tolist() == [1, 1, 2, 1, 1, 1]


# ------------------------------------------------------------ dataset layout
def test_stray_os_files_are_skipped_with_a_warning(tmp_path, make_rig):
    """A Thumbs.db in a masks folder refused the whole dataset."""
    root = tmp_path / "ds"
    write_dataset(root, make_truth(np.random.default_rng(11), make_rig)).close()
    (root / "groundtruth" / "masks" / "cam_a" / "Thumbs.db").write_bytes(b"\x00" * 64)
    (root / "groundtruth" / "masks" / "desktop.ini").write_text("[.ShellClassInfo]\n")
    with pytest.warns(UserWarning, match="Thumbs.db"):
        ds = Dataset.open(root)
    assert ds.n_frames == 3
    ds.close()
    (root / "groundtruth" / "masks" / "cam_a" / "000099.png").write_bytes(b"x")
    with pytest.raises(InputError, match="000099.png"):  # a real stray frame is still an error
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            Dataset.open(root)


def test_fingerprint_covers_every_input_read(tmp_path, make_rig):
    """A changed background/, field_model.json, scene.toml or groundtruth/ resumed into a stale mix."""
    root = tmp_path / "ds"
    write_dataset(root, make_truth(np.random.default_rng(11), make_rig)).close()
    base = dataset_fingerprint(root)
    (root / "Thumbs.db").write_bytes(b"\x01")
    (root / ".hidden.tmp-1").write_bytes(b"\x01")
    (root / "scene.rrd").write_bytes(b"\x01")
    (root / "out").mkdir()
    (root / "out" / "run.json").write_text("{}")
    assert dataset_fingerprint(root, exclude=(root / "out",)) == base  # none of these is read
    seen = set()
    for rel in ("background/cam_a.png", "field_model.json", "scene.toml", "groundtruth/joints3d.npz",
                "groundtruth/masks/cam_a/000001.png", "keypoints/cam_a/cam_a_000000.json"):
        f = root / rel
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_bytes((f.read_bytes() if f.exists() else b"") + b"changed")
        fp = dataset_fingerprint(root, exclude=(root / "out",))
        assert fp not in seen | {base}, rel
        seen.add(fp)


# ------------------------------------------------------------ output folders
def test_out_that_is_a_file_or_under_one(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    for out in (f, f / "sub"):
        with pytest.raises(InputError, match="a file"):
            start_run(out, {"recipe": "x"})
        with pytest.raises(InputError, match="a file"):
            check_out_folder(out)


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="permissions do not bind root")
def test_read_only_out(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(InputError, match="can write"):
            start_run(ro / "out", {"recipe": "x"})
    finally:
        ro.chmod(0o755)


def test_unwritable_out_is_an_input_error(tmp_path, monkeypatch):
    # the same path as a read-only disk, for a user whose permissions always bind (root's do not)
    import toolkit.io.runs as runs

    def refuse(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(runs, "temp_path", refuse)
    with pytest.raises(InputError, match="can write") as e:
        check_out_folder(tmp_path / "o")
    assert "Permission denied" in str(e.value)


def test_staged_folder_replaces_only_when_complete(tmp_path):
    out = tmp_path / "ds"
    out.mkdir()
    (out / "old.txt").write_text("old")
    with pytest.raises(InputError, match="--overwrite"):
        with staged_folder(out):
            pass
    with pytest.raises(RuntimeError):
        with staged_folder(out, overwrite=True, log=None) as stage:
            (stage / "new.txt").write_text("half")
            raise RuntimeError("disk full")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]     # no staging folder left
    assert (out / "old.txt").read_text() == "old"
    with staged_folder(out, overwrite=True, log=None) as stage:
        (stage / "new.txt").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["new.txt"]      # no mix of old and new
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]


# ------------------------------------------------------------ depth
def test_float_millimetre_depth_is_refused(tmp_path):
    """A float .npy in millimetres was read as metres (a person 1.5 km away) without a word."""
    np.save(tmp_path / "mm.npy", np.full((48, 64), 1500.0, np.float32))
    with pytest.raises(InputError, match="millimetres") as e:
        read_depth(tmp_path / "mm.npy")
    assert "mm.npy" in str(e.value)
    np.save(tmp_path / "m.npy", np.full((48, 64), 1.5, np.float32))
    assert float(np.nanmedian(read_depth(tmp_path / "m.npy"))) == pytest.approx(1.5)


@pytest.mark.parametrize("content", [b"", b"\x93NUMPY garbage", os.urandom(200)])
def test_corrupt_npy_is_an_input_error(tmp_path, content):
    (tmp_path / "f.npy").write_bytes(content)
    with pytest.raises(InputError, match="f.npy"):
        read_depth(tmp_path / "f.npy")


def test_stray_files_are_not_depth_frames(tmp_path):
    for i in range(2):
        np.zeros((48, 64), "<u2").tofile(tmp_path / f"depth-{i}")
    (tmp_path / "Thumbs.db").write_bytes(b"\x00" * 10)
    (tmp_path / "._depth-0").write_bytes(b"\x00" * 10)
    assert [p.name for p in list_depth_frames(tmp_path)] == ["depth-0", "depth-1"]


def test_depth_intrinsics_out_of_range(tmp_path):
    f = tmp_path / "intrinsics.toml"
    f.write_text("size = [640, 480]\nmatrix = [[585.0, 0.0, 1e9], [0.0, 585.0, 239.5], [0.0, 0.0, 1.0]]\n")
    with pytest.raises(InputError, match="principal point") as e:
        read_depth_intrinsics(f)
    assert str(f) in str(e.value)


def test_full_disk_keeps_the_earlier_file(tmp_path, monkeypatch):
    """A full disk during the final writes was a traceback; now an InputError naming the file, the old one kept."""
    import errno

    from toolkit.io import atomic

    f = atomic.atomic_write_text(tmp_path / "metrics.json", "old")

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.os, "fsync", full)
    with pytest.raises(InputError, match="No space left") as e:
        atomic.atomic_write_text(f, "new")
    assert e.value.where == str(f)
    assert f.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["metrics.json"]
