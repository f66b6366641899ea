"""A small studio scene with ground truth, generated once per test session."""

import pytest

STUDIO_SPEC = """
name = "render_test"
seed = 5
frames = 2
fps = 25
[subject]
height_m = 1.75
motion = "walk"
[cameras]
count = 3
layout = "studio"
resolution = [320, 180]
calibration_error_px = 0.0
[novel]
count = 1
"""


@pytest.fixture(scope="session")
def studio(tmp_path_factory):
    from toolkit.io import Dataset
    from toolkit.synthetic import generate_scene
    from toolkit.synthetic.spec import parse_spec

    out = tmp_path_factory.mktemp("studio") / "scene"
    generate_scene(parse_spec(STUDIO_SPEC), out, progress=False)
    return Dataset.open(out)


@pytest.fixture(scope="session")
def studio_frame(studio):
    """Images, GT part labels, GT joints and the true rig of frame 1."""
    t = 1
    rig = studio.gt_rig
    images = {c: studio.frame(c, t) for c in rig.names}
    labels = {c: studio.gt_parts(c, t) for c in rig.names}
    return dict(t=t, rig=rig, images=images, labels=labels, joints=studio.gt_joints3d()[t],
                masks={c: labels[c] > 0 for c in rig.names})


@pytest.fixture(scope="session")
def studio_model(studio_frame):
    from toolkit.rendering import render_billboards

    f = studio_frame
    return render_billboards(f["images"], f["labels"], f["joints"], f["rig"], frame=f["t"])
