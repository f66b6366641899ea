from types import SimpleNamespace

import numpy as np

from toolkit.observe import RecordingObserver
from toolkit.pipeline.frame import FrameProcessor
from toolkit.rendering.freeviewpoint import METHODS, STATUS_NO_POSE, STATUS_NO_VIEWS, render_methods


def _estimate(ok, joints):
    return SimpleNamespace(ok=ok, joints3d=joints, offsets=np.full((3, 2), np.nan),
                           poses2d=np.full((3, 14, 2), np.nan))


def test_frame_without_pose_is_empty_and_marked(studio_frame):
    f = studio_frame
    obs = RecordingObserver()
    proc = FrameProcessor(f["rig"], observer=obs)
    res = proc.process(1, f["images"], [None, None, None], _estimate(False, np.full((14, 3), np.nan)))
    assert res.status == STATUS_NO_POSE and not res.ok and res.model is None
    assert any("no 3D pose" in d["text"] for d in obs.of_kind("text"))
    cam = f["rig"][0]
    bg = np.full(cam.size[::-1] + (3,), 77, np.uint8)
    views = render_methods(res, cam, bg)
    assert set(views) == set(METHODS) and all(np.all(v == 77) for v in views.values())


def test_frame_without_any_silhouette(studio_frame):
    f = studio_frame
    obs = RecordingObserver()
    proc = FrameProcessor(f["rig"], observer=obs)
    res = proc.process(1, f["images"], [None, np.zeros(f["rig"][1].size[::-1], bool), None],
                       _estimate(True, f["joints"]))
    assert res.status == STATUS_NO_VIEWS
    assert sum("left out" in d["text"] for d in obs.of_kind("text")) == 3


def test_template_pose_option_is_checked():
    import pytest

    from toolkit.errors import InputError
    from toolkit.rendering.freeviewpoint import TEMPLATE_POSES, FreeViewpointConfig

    assert FreeViewpointConfig().template_pose == "multiview" and "per_view" in TEMPLATE_POSES
    with pytest.raises(InputError, match="template_pose"):
        FreeViewpointConfig(template_pose="nearest")
