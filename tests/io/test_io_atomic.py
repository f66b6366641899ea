"""Atomic writes, PNG encoding and the depth encoding."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.io.atomic import (
    FILE_MODE,
    atomic_path,
    atomic_save_npz,
    atomic_write_bytes,
    atomic_write_png,
    atomic_write_text,
)
from toolkit.io.frames import DEPTH_MAX_M, depth_to_mm, frame_filename, mm_to_depth, read_png

#: Depth is stored in whole millimetres: rounding costs at most half of one.
DEPTH_QUANTUM_M = 0.0005


def test_bytes_text_and_permissions(tmp_path):
    p = atomic_write_bytes(tmp_path / "a" / "b.bin", b"\x00\x01")
    assert p.read_bytes() == b"\x00\x01"
    assert stat.S_IMODE(os.stat(p).st_mode) == FILE_MODE
    atomic_write_text(p, "héllo\n")
    assert p.read_text(encoding="utf-8") == "héllo\n"
    assert [q.name for q in p.parent.iterdir()] == ["b.bin"]


def test_failure_leaves_destination_untouched(tmp_path):
    dest = tmp_path / "x.txt"
    dest.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(dest) as tmp:
            assert (
                tmp.parent == tmp_path and tmp.suffix == ".txt" and tmp.name.startswith(".x.tmp-")
            )
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert dest.read_text() == "old"
    assert [q.name for q in tmp_path.iterdir()] == ["x.txt"]


def test_npz(tmp_path):
    a = np.arange(12.0).reshape(3, 4)
    names = np.array(["head", "neck"])
    p = atomic_save_npz(tmp_path / "d.npz", a=a, names=names)
    with np.load(p, allow_pickle=False) as z:
        np.testing.assert_array_equal(z["a"], a)
        assert z["names"].tolist() == ["head", "neck"]
    with pytest.raises(InputError, match="object"):
        atomic_save_npz(tmp_path / "o.npz", bad=np.array([{"x": 1}], dtype=object))
    assert not (tmp_path / "o.npz").exists()


@pytest.mark.parametrize(
    "shape,dtype",
    [((5, 7, 3), np.uint8), ((5, 7), np.uint8), ((5, 7), np.uint16), ((5, 7, 4), np.uint8)],
)
def test_png_round_trip_is_exact(tmp_path, shape, dtype):
    rng = np.random.default_rng(0)
    img = rng.integers(0, np.iinfo(dtype).max, shape, endpoint=True).astype(dtype)
    p = atomic_write_png(tmp_path / "i.png", img)
    back = read_png(p)
    assert back.dtype == dtype
    np.testing.assert_array_equal(back, img)  # RGB order survives OpenCV's BGR


def test_png_errors(tmp_path):
    with pytest.raises(InputError, match="dtype float64"):
        atomic_write_png(tmp_path / "f.png", np.zeros((4, 4)))
    with pytest.raises(InputError, match="shape"):
        atomic_write_png(tmp_path / "f.png", np.zeros((4, 4, 2), np.uint8))
    with pytest.raises(InputError, match="no such file"):
        read_png(tmp_path / "none.png")
    (tmp_path / "junk.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match="unreadable") as err:
        read_png(tmp_path / "junk.png")
    assert str(tmp_path / "junk.png") in str(err.value)
    atomic_write_png(tmp_path / "g.png", np.zeros((4, 4), np.uint8))
    with pytest.raises(InputError, match="3 channel"):
        read_png(tmp_path / "g.png", channels=3)
    with pytest.raises(InputError, match="uint16"):
        read_png(tmp_path / "g.png", dtype=np.uint16)
    assert sorted(q.name for q in tmp_path.iterdir()) == ["g.png", "junk.png"]


def test_depth_encoding():
    rng = np.random.default_rng(1)
    d = rng.uniform(0.3, 12.0, (6, 8))
    d[0, 0], d[0, 1], d[0, 2], d[0, 3], d[0, 4] = np.nan, np.inf, 0.0, DEPTH_MAX_M + 1.0, 65.535
    mm = depth_to_mm(d)
    assert mm.dtype == np.uint16
    assert mm[0, :4].tolist() == [0, 0, 0, 0] and mm[0, 4] == 65535
    back = mm_to_depth(mm)
    assert back.dtype == np.float32
    assert np.isnan(back[0, :4]).all()
    ok = np.isfinite(back)
    assert np.abs(back[ok] - d[ok]).max() <= DEPTH_QUANTUM_M + 1e-6  # float32 rounding
    with pytest.raises(InputError, match="negative"):
        depth_to_mm(np.array([[1.0, -0.1]]))
    with pytest.raises(InputError, match=r"\(H, W\)"):
        depth_to_mm(np.zeros(3))


def test_frame_filename():
    assert frame_filename(0) == "000000.png"
    assert frame_filename(123456) == "123456.png"
    for bad in (-1, 10**6, 1.5):
        with pytest.raises(InputError, match="frame index"):
            frame_filename(bad)
