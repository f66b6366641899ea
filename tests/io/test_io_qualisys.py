"""Qualisys ``.qca.txt`` calibrations: the conversion, the match with Pose2Sim's, clear errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.io.conftest import random_rig
from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.io import read_calibration
from toolkit.io.qualisys import is_qca, read_calibration_qca

SUB = 64.0


def qca_text(rig: Rig, *, view_rotation: str = "0", drop: str | None = None) -> str:
    """A ``.qca.txt`` of ``rig`` written as QTM does (sub-pixel intrinsics, centre in mm, QTM's axes)."""
    rows = []
    for cam in rig.cameras:
        w, h = cam.size
        R_qtm = np.diag([1.0, -1.0, -1.0]) @ cam.R
        c = cam.center * 1000.0
        K, d = cam.K, np.zeros(5)
        d[:len(cam.dist)] = cam.dist[:5]
        r = " ".join(f'r{i + 1}{j + 1}="{R_qtm[i, j]:.17g}"' for i in range(3) for j in range(3))
        transform = f'<transform {r} x="{c[0]:.17g}" y="{c[1]:.17g}" z="{c[2]:.17g}"/>'
        intrinsic = (f'<intrinsic centerPointU="{K[0, 2] * SUB:.17g}" centerPointV="{K[1, 2] * SUB:.17g}" '
                     f'focalLengthU="{K[0, 0] * SUB:.17g}" focalLengthV="{K[1, 1] * SUB:.17g}" '
                     f'radialDistortion1="{d[0] * SUB:.17g}" radialDistortion2="{d[1] * SUB:.17g}" '
                     f'radialDistortion3="{d[4] * SUB:.17g}" tangentalDistortion1="{d[2] * SUB:.17g}" '
                     f'tangentalDistortion2="{d[3] * SUB:.17g}" sensorMinU="0" sensorMaxU="{w * SUB:.17g}" '
                     f'sensorMinV="0" sensorMaxV="{h * SUB:.17g}" skew="0"/>')
        fov = f'<fov_video left="0" top="0" right="{w - 1}" bottom="{h - 1}"/>'
        parts = {"transform": transform, "intrinsic": intrinsic, "fov_video": fov}
        if drop:
            parts.pop(drop)
        rows.append(f'<camera active="1" serial="{cam.name}" viewrotation="{view_rotation}">'
                    + "".join(parts.values()) + "</camera>")
    return "<?xml version='1.0'?>\n<calibration><cameras>" + "\n".join(rows) + "</cameras></calibration>\n"


def test_round_trip_projects_identically(tmp_path):
    rig = random_rig(np.random.default_rng(3), n_cams=4, size=(1088, 1920), dist_lengths=(5,))
    path = tmp_path / "Calib.qca.txt"
    path.write_text(qca_text(rig))
    assert is_qca(path)
    got = read_calibration(path)
    assert [c.name for c in got.cameras] == [c.name for c in rig.cameras]
    pts = np.random.default_rng(0).uniform([-1, -1, 0], [1, 1, 2], (50, 3))
    for a, b in zip(got.cameras, rig.cameras):
        assert a.size == b.size
        np.testing.assert_allclose(a.project(pts), b.project(pts), atol=1e-6)
        np.testing.assert_allclose(a.center, b.center, atol=1e-9)


def test_matches_pose2sims_conversion_of_the_demo(pose2sim_demo):
    """The demo's ``Calib_qualisys.toml`` was made by Pose2Sim from the ``Calib.qca.txt`` beside it."""
    calib = pose2sim_demo / "S00_Calibration"
    ours = read_calibration(calib / "Calib.qca.txt")
    theirs = read_calibration(calib / "Calib_qualisys.toml")
    pts = np.random.default_rng(0).uniform([-1, -1, 0], [1, 1, 2], (200, 3))
    for a, b in zip(ours.cameras, theirs.cameras):
        assert a.name == b.name and a.size == b.size
        err = np.linalg.norm(a.project(pts) - b.project(pts), axis=1)
        assert np.nanmax(err) < 1e-3, (a.name, np.nanmax(err))


def test_multiperson_calibration_reads(pose2sim_demo):
    qca = pose2sim_demo.parent / "pose2sim_multiperson" / "calibration" / "Calib.qca.txt"
    if not qca.is_file():
        pytest.skip(f"{qca} not found")
    rig = read_calibration(qca)
    assert [c.name for c in rig.cameras] == ["cam01", "cam02", "cam03", "cam04"]
    # cameras 1.7-2.1 m above the origin, looking at it
    for cam in rig.cameras:
        assert 1.6 < cam.center[2] < 2.2
        assert cam.in_image(cam.project(np.zeros((1, 3))))[0]


@pytest.mark.parametrize("text, where", [
    ("<calibration><cameras><camera", "line 1"),
    ("<calibration><results/></calibration>", "<cameras>"),
    ("<calibration><cameras></cameras></calibration>", "<cameras>"),
])
def test_malformed_files_are_named(tmp_path, text, where):
    path = tmp_path / "bad.qca.txt"
    path.write_text(text)
    with pytest.raises(InputError) as e:
        read_calibration(path)
    assert str(path) in str(e.value) and where in str(e.value)


@pytest.mark.parametrize("drop", ["transform", "intrinsic", "fov_video"])
def test_missing_element_is_named(tmp_path, drop):
    rig = random_rig(np.random.default_rng(1), n_cams=2)
    path = tmp_path / "Calib.qca.txt"
    path.write_text(qca_text(rig, drop=drop))
    with pytest.raises(InputError, match=drop):
        read_calibration_qca(path)


def test_bad_attribute_and_rotated_view(tmp_path):
    rig = random_rig(np.random.default_rng(1), n_cams=2)
    path = tmp_path / "Calib.qca.txt"
    path.write_text(qca_text(rig).replace('focalLengthU="', 'focalLengthU="x', 1))
    with pytest.raises(InputError, match="focalLengthU"):
        read_calibration_qca(path)
    path.write_text(qca_text(rig, view_rotation="90"))
    with pytest.raises(InputError, match="viewrotation"):
        read_calibration_qca(path)
    with pytest.raises(InputError, match="no such file"):
        read_calibration_qca(tmp_path / "none.qca.txt")


def test_unknown_suffix_lists_qca(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text("x")
    with pytest.raises(InputError, match=r"\.qca\.txt"):
        read_calibration(path)
