"""Scene spec parsing: every impossible value is rejected naming its field."""

import pytest

from toolkit.errors import InputError
from toolkit.synthetic import load_spec, parse_spec
from tests.synthetic.conftest import TINY_SPEC


def test_parses_default_specs():
    from pathlib import Path
    for p in sorted((Path(__file__).resolve().parents[2] / "datasets_synthetic").glob("*.toml")):
        spec = load_spec(p)
        assert spec.frames > 0 and spec.camera_count > 0


@pytest.mark.parametrize("old, new, field", [
    ('frames = 3', 'frames = 0', "frames"),
    ('fps = 25', 'fps = -1', "fps"),
    ('height_m = 1.75', 'height_m = 3.5', "subject.height_m"),
    ('motion = "walk"', 'motion = "moonwalk"', "subject.motion"),
    ('motion = "walk"', 'motion = "missing.bvh"', "subject.motion"),
    ('count = 2\nlayout', 'count = 0\nlayout', "cameras.count"),
    ('layout = "broadcast"', 'layout = "drone"', "cameras.layout"),
    ('resolution = [320, 180]', 'resolution = [321, 180]', "cameras.resolution"),
    ('resolution = [320, 180]', 'resolution = [320]', "cameras.resolution"),
    ('calibration_error_px = 4.0', 'calibration_error_px = -2.0', "cameras.calibration_error_px"),
    ('calibration_error_px = 4.0', 'calibration_error_px = "big"', "calibration_error_px"),
    ('[novel]\ncount = 1', '[novel]\ncount = -1', "novel.count"),
    ('seed = 11', 'seed = 11\ncolour = 3', "unknown keys"),
    ('seed = 11', '', "seed"),
    ('seed = 11', 'seed = [', "valid TOML"),
    ('motion = "walk"', 'motion = "walk"\noutfit = "camouflage"', "subject.outfit"),
    ('motion = "walk"', 'motion = "walk"\nshirt_rgb = [0.2, 1.5, 0.1]', "subject.shirt_rgb"),
    ('motion = "walk"', 'motion = "walk"\ntrousers_rgb = [0.2, 0.1]', "subject.trousers_rgb"),
    ('motion = "walk"', 'motion = "walk"\npattern = "dots"', "subject.pattern"),
    ('calibration_error_px = 4.0', 'calibration_error_px = 4.0\nspacing_deg = [90, 30]', "cameras.spacing_deg"),
    ('calibration_error_px = 4.0', 'calibration_error_px = 4.0\nspacing_deg = 200', "cameras.spacing_deg"),
    ('calibration_error_px = 4.0', 'calibration_error_px = 4.0\nsubject_px = "tall"', "cameras.subject_px"),
    ('layout = "broadcast"\nresolution = [320, 180]\ncalibration_error_px = 4.0',
     'layout = "studio"\nresolution = [320, 180]\ncalibration_error_px = 4.0\nsubject_px = 100', "cameras.subject_px"),
    ('[novel]\ncount = 1', '[novel]\ncount = 1\nplacement = "behind"', "novel.placement"),
])
def test_bad_values_name_the_field(old, new, field):
    text = TINY_SPEC.replace(old, new, 1)
    assert text != TINY_SPEC
    with pytest.raises(InputError) as e:
        parse_spec(text, "scene.toml")
    assert field in str(e.value) and "scene.toml" in str(e.value)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_spec(tmp_path / "nope.toml")


def test_bvh_motion_scene(tmp_path):
    """A spec can name a motion-capture file; the scene then follows it."""
    import os
    from pathlib import Path

    import numpy as np

    from toolkit.synthetic import build_scene
    root = Path(os.environ.get("TOOLKIT_REALDATA", Path(__file__).resolve().parents[3] / "shared" / "realdata"))
    bvh = root / "cmu_mocap" / "01_01.bvh"
    if not bvh.is_file():
        pytest.skip(f"real data not found at {bvh}")
    spec_path = tmp_path / "bvh.toml"
    spec_path.write_text(TINY_SPEC.replace('"walk"', f'"{bvh}"'))
    scene = build_scene(load_spec(spec_path))
    assert scene.joints.shape == (3, 14, 3) and np.isfinite(scene.joints).all()
    assert scene.joints[..., 2].min() > -0.02


ZOO_SPEC = TINY_SPEC.replace('motion = "walk"', 'motion = "turn"\noutfit = "like_background"\npattern = "checks"').replace(
    'calibration_error_px = 4.0', 'calibration_error_px = 0.0\nspacing_deg = 100\nsubject_px = 120').replace(
    '[novel]\ncount = 1', '[novel]\ncount = 4\nplacement = "around"').replace(
    'resolution = [320, 180]', 'resolution = [960, 540]')
#: Subject-size tolerance: ``subject_px`` is the stature; joints span ~90 % of it (head top and soles lie outside).
SUBJECT_PX_SPAN = (0.8, 1.0)
#: Outfit "like_background": the shirt's base colour lies this close (max per channel) to the grass.
KIT_NEAR_TOL = 0.3


def test_zoo_fields_shape_the_scene():
    import numpy as np

    from toolkit.synthetic.environment import GRASS_RGB
    from toolkit.synthetic.generator import _spacings_deg, build_scene

    spec = parse_spec(ZOO_SPEC, "zoo.toml")
    assert spec.spacing_deg == (100.0, 100.0) and spec.subject_px == (120.0, 120.0)
    scene = build_scene(spec)
    assert abs(_spacings_deg(scene.rig, scene.joints)[0] - 100.0) < 1.0
    for cam in scene.rig:
        uv = cam.project(scene.joints)
        span = np.nanmedian(np.nanmax(uv[..., 1], 1) - np.nanmin(uv[..., 1], 1))
        assert SUBJECT_PX_SPAN[0] * 120 < span < SUBJECT_PX_SPAN[1] * 120
    shirt = scene.body.shape.colours[2]
    assert np.abs(shirt - np.array(GRASS_RGB)).max() < KIT_NEAR_TOL
    assert scene.body.shape.pattern_kind == "checks"
    # novel cameras all around: the first one is on the far side of the subject from both sources
    c = scene.joints[:, 1].mean(0)
    back = scene.novel[0].center[:2] - c[:2]
    for cam in scene.rig:
        src = cam.center[:2] - c[:2]
        assert np.dot(back, src) / np.linalg.norm(back) / np.linalg.norm(src) < -0.3
    elev = [np.degrees(np.arctan2(cam.center[2] - 0.9, np.linalg.norm(cam.center[:2] - c[:2]))) for cam in scene.novel]
    assert max(elev) > 35.0  # a high view
    for cam in scene.novel:  # every novel camera sees the subject
        uv = cam.project(scene.joints[0])
        assert ((uv >= 0) & (uv < np.array(cam.size))).all()


def test_zoo_fields_leave_other_draws_unchanged():
    """Widening the scene space must not change the scenes the project already has."""
    import numpy as np

    from toolkit.synthetic.generator import build_scene

    a = build_scene(parse_spec(TINY_SPEC, "a.toml"))
    b = build_scene(parse_spec(TINY_SPEC.replace('motion = "walk"', 'motion = "walk"\nshirt_rgb = [0.1, 0.2, 0.3]'),
                               "b.toml"))
    np.testing.assert_array_equal(a.joints, b.joints)
    for ca, cb in zip(a.rig, b.rig):
        np.testing.assert_array_equal(ca.K, cb.K)
    np.testing.assert_array_equal(a.body.shape.colours[3], b.body.shape.colours[3])
    np.testing.assert_allclose(b.body.shape.colours[2], [0.1, 0.2, 0.3])
