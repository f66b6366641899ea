"""C3D reading and writing with ezc3d: round trip, units, labels, gaps, bad files."""

from __future__ import annotations

import numpy as np
import pytest

from tests.io.conftest import realdata_root
from toolkit.errors import InputError
from toolkit.io.c3d import read_c3d, write_c3d


def _points(rng, t=12, m=4):
    pos = rng.normal(scale=0.5, size=(t, m, 3)) + [0, 0, 1]
    pos[3, 1] = np.nan
    pos[7:9, 2] = np.nan
    return pos


def _ezc3d_file(path, labels, units="mm", n_points=None):
    import ezc3d

    n = len(labels) if n_points is None else n_points
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c.add_parameter("POINT", "UNITS", [units])
    c["data"]["points"] = np.ones((4, n, 5))
    c.write(str(path))
    return path


def test_round_trip_keeps_labels_positions_gaps_and_rate(tmp_path):
    rng = np.random.default_rng(0)
    pos = _points(rng)
    labels = ("LASI", "RASI", "LKNE", "RKNE")
    for units in ("mm", "m"):
        path = write_c3d(tmp_path / f"t_{units}.c3d", labels, pos, 120.0, units=units)
        back = read_c3d(path, require_labels=True)
        assert back.labels == labels and back.units == units and back.fps == 120.0 and back.labelled
        assert np.array_equal(np.isnan(back.positions), np.isnan(pos))
        np.testing.assert_allclose(back.positions, pos, atol=1e-6)  # float32 storage


def test_units_other_than_mm_or_m_are_refused(tmp_path):
    path = _ezc3d_file(tmp_path / "cm.c3d", ["A", "B"], units="cm")
    with pytest.raises(InputError, match=r"POINT:UNITS.*'cm'"):
        read_c3d(path)


def test_duplicated_labels_are_refused(tmp_path):
    path = _ezc3d_file(tmp_path / "dup.c3d", ["A", "B", "A"])
    with pytest.raises(InputError, match="duplicated"):
        read_c3d(path)
    with pytest.raises(InputError, match="distinct"):
        write_c3d(tmp_path / "w.c3d", ["A", "A"], np.zeros((2, 2, 3)), 100.0)


def test_missing_labels_refused_where_required_else_generated(tmp_path):
    path = _ezc3d_file(tmp_path / "nolab.c3d", ["", ""], n_points=2)
    with pytest.raises(InputError, match="POINT:LABELS"):
        read_c3d(path, require_labels=True)
    p = read_c3d(path)
    assert p.labels == ("P000", "P001") and not p.labelled


def test_not_a_c3d_and_missing_file(tmp_path):
    bad = tmp_path / "bad.c3d"
    bad.write_bytes(b"not a c3d file at all")
    with pytest.raises(InputError, match="bad.c3d"):
        read_c3d(bad)
    with pytest.raises(InputError, match="no such file"):
        read_c3d(tmp_path / "absent.c3d")


@pytest.mark.realdata
def test_real_plug_in_gait_file():
    path = realdata_root() / "c3d_plugin_gait" / "Movement_trial.c3d"
    if not path.is_file():
        pytest.skip(f"real data not found at {path}")
    p = read_c3d(path, require_labels=True)
    assert p.units == "mm" and p.fps == 120.0 and p.positions.shape == (323, len(p.labels), 3)
    i = p.labels.index("LKNE")
    d = np.nanmedian(np.linalg.norm(p.positions[:, i] - p.positions[:, p.labels.index("LFEO")], axis=1))
    assert abs(d - 0.079) < 0.002  # (knee width 144 mm + 14 mm) / 2 in metres


def test_subject_measurements_read_from_the_processing_group(tmp_path):
    path = _ezc3d_file(tmp_path / "m.c3d", ["LKNE", "RKNE"])
    import ezc3d

    c = ezc3d.c3d(str(path))
    c.add_parameter("PROCESSING", "LKneeWidth", [144.0])
    c.add_parameter("PROCESSING", "MarkerDiameter", [14.0])
    c.add_parameter("PROCESSING", "LHandWidth", [-17.9])  # not a width a body has: left out
    c.add_parameter("PROCESSING", "Bodymass", [70.0])  # not a width
    c.write(str(path))
    m = read_c3d(path).measurements
    assert m == pytest.approx({"LKneeWidth": 0.144, "MarkerDiameter": 0.014})
    assert read_c3d(_ezc3d_file(tmp_path / "none.c3d", ["A"])).measurements == {}
