"""End-to-end: the make_scene recipe writes a dataset and a recording the rerun CLI verifies."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from toolkit.io import Dataset

ROOT = Path(__file__).resolve().parents[2]
RERUN = Path(sys.executable).with_name("rerun")


def test_help():
    r = subprocess.run([sys.executable, str(ROOT / "recipes" / "make_scene.py"), "--help"], capture_output=True,
                       text=True)
    assert r.returncode == 0 and "--out" in r.stdout


def test_make_scene_end_to_end(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text((ROOT / "datasets_synthetic" / "tiny.toml").read_text().replace("frames = 4", "frames = 2"))
    out = tmp_path / "ds"
    r = subprocess.run([sys.executable, str(ROOT / "recipes" / "make_scene.py"), str(spec), "--out", str(out),
                        "--quiet"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "scene.rrd" in r.stdout
    ds = Dataset.open(out)
    assert ds.n_frames == 2 and len(ds.camera_names) == 2
    assert ds.gt_joints3d().shape == (2, 14, 3)
    assert np.isfinite(ds.gt_joints3d()).all()
    assert (out / "groundtruth" / "novel" / "novel00" / "000001.png").is_file()
    if RERUN.exists():
        v = subprocess.run([str(RERUN), "rrd", "verify", str(out / "scene.rrd")], capture_output=True, text=True)
        assert v.returncode == 0, v.stderr
        p = subprocess.run([str(RERUN), "rrd", "print", str(out / "scene.rrd")], capture_output=True, text=True)
        assert "world/cams/cam00" in p.stdout


def test_bad_spec_is_a_clear_error(tmp_path):
    spec = tmp_path / "bad.toml"
    spec.write_text((ROOT / "datasets_synthetic" / "tiny.toml").read_text().replace('"walk"', '"moonwalk"'))
    r = subprocess.run([sys.executable, str(ROOT / "recipes" / "make_scene.py"), str(spec), "--out",
                        str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 2
    assert "subject.motion" in r.stderr and "moonwalk" in r.stderr and "bad.toml" in r.stderr
    assert "Traceback" not in r.stderr
