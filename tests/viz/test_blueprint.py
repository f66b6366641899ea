"""The default blueprint and entity path helpers, read back from saved recordings."""

from __future__ import annotations

import numpy as np
import pytest
import rerun as rr

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.viz import RerunObserver, camera_path, entity_path, image_path, make_blueprint


def views(path) -> dict[str, set[str]]:
    """View kind (``3D``, ``2D``, ``TimeSeries``, ``TextLog``) -> space origins in the blueprint."""
    reader = rr.chunk.RrdReader(path)
    (bp,) = reader.blueprints()
    rows: dict[str, dict] = {}
    for chunk in reader.stream(store=bp):
        rb = chunk.to_record_batch()
        for name in ("ViewBlueprint:class_identifier", "ViewBlueprint:space_origin"):
            if name in rb.schema.names:
                rows.setdefault(chunk.entity_path, {})[name] = rb.column(name).to_pylist()[-1][0]
    out: dict[str, set[str]] = {}
    for r in rows.values():
        origin = r["ViewBlueprint:space_origin"].strip("/")
        out.setdefault(r["ViewBlueprint:class_identifier"], set()).add(origin)
    return out


def data_entities(path) -> set[str]:
    return {c.entity_path.strip("/") for c in rr.chunk.RrdReader(path).stream()}


def test_default_layout_has_3d_2d_metrics_and_log_views(tmp_path):
    path = tmp_path / "bp.rrd"
    with RerunObserver(path=path) as obs:
        obs.send_blueprint(make_blueprint(["cam0", "cam1"], extra_2d=["views/atlas"]))
    got = views(path)
    assert got == {"3D": {"world"}, "2D": {"world/cams/cam0/image", "world/cams/cam1/image", "views/atlas"},
                   "TimeSeries": {"metrics"}, "TextLog": {"logs"}}


def test_camera_names_send_the_blueprint_at_creation(tmp_path):
    path = tmp_path / "bp.rrd"
    RerunObserver(path=path, camera_names=["a", "b", "c"]).close()
    assert views(path)["2D"] == {"world/cams/a/image", "world/cams/b/image", "world/cams/c/image"}


def test_optional_views_can_be_left_out(tmp_path):
    path = tmp_path / "bp.rrd"
    with RerunObserver(path=path) as obs:
        obs.send_blueprint(make_blueprint([], include_metrics=False, include_logs=False))
    assert views(path) == {"3D": {"world"}}


def test_rig_report_sends_a_blueprint_whose_2d_views_hold_the_pinholes(tmp_path):
    """Camera names with spaces are escaped the same way in the data and the layout."""
    rig = Rig((Camera.look_at("side cam", [3.0, 0, 1], [0, 0, 1], size=(40, 30), fov_x_deg=50),
               Camera.look_at("top.cam", [0, 0.1, 5], [0, 0, 0], size=(40, 30), fov_x_deg=50)))
    path = tmp_path / "rig.rrd"
    with RerunObserver(path=path) as obs:
        obs.report("rig", rig=rig)
        obs.report("image", camera="side cam", image=np.zeros((30, 40, 3), np.uint8))
    origins_2d = views(path)["2D"]
    assert len(origins_2d) == 2
    assert origins_2d <= data_entities(path)


def test_rig_under_another_root(tmp_path):
    rig = Rig((Camera.look_at("k0", [2.0, 0, 1], [0, 0, 1], size=(40, 30), fov_x_deg=50),))
    path = tmp_path / "kinect.rrd"
    with RerunObserver(path=path) as obs:
        obs.report("rig", rig=rig, path="world/depth_cams")
        obs.report("depth", camera="k0", depth=np.full((30, 40), 2.0))
    assert views(path)["2D"] == {"world/depth_cams/k0/image"}
    assert {"world/depth_cams/k0", "world/depth_cams/k0/image", "world/depth_cams/k0/image/depth"} <= \
        data_entities(path)


def test_entity_paths():
    assert entity_path("world", "fit/residual") == "world/fit/residual"
    assert entity_path("/world/", "//a") == "world/a"
    assert entity_path("world", "my joints") == "world/my\\ joints"
    assert camera_path("cam 0") == "world/cams/cam\\ 0"
    assert camera_path("a/b") == "world/cams/a\\/b"  # one camera, not a nested entity
    assert image_path("cam0", "world/depth_cams") == "world/depth_cams/cam0/image"


@pytest.mark.parametrize("parts", [(), ("",), ("/", "//")])
def test_empty_entity_path_raises(parts):
    with pytest.raises(InputError, match="entity path"):
        entity_path(*parts)


@pytest.mark.parametrize("names", [["cam0", "cam0"], ["cam0", ""]])
def test_bad_camera_names_raise(names):
    with pytest.raises(InputError, match="camera_names"):
        make_blueprint(names)


def test_softbody_layout(tmp_path):
    from toolkit.viz.blueprint import softbody_blueprint, subject_eye

    path = tmp_path / "sb.rrd"
    with RerunObserver(path=path) as obs:
        obs.send_blueprint(softbody_blueprint(["torso", "l_thigh"], eye=subject_eye([0, 0, 1], [[0, -3, 1]])))
    got = views(path)
    assert got["3D"] == {"world"} and got["TextLog"] == {"logs"}
    assert got["TimeSeries"] == {"metrics/softbody/median_residual_mm", "metrics/softbody/track",
                                 "metrics/softbody/track/other_points", "metrics/softbody/posture"}
    assert got["BarChart"] == {"metrics/softbody/global/cost", "metrics/softbody/global/lengths/torso",
                               "metrics/softbody/global/lengths/l_thigh"}
