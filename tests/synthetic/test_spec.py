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
