"""Long walks and runs of the soft-body scenes stay where the cameras see them (``[subject] area_m``:
:func:`toolkit.motion.synthesize_motion`'s ``area_m``, :func:`toolkit.synthetic.generator.build_scene`)."""

import numpy as np
import pytest

from benchmarks.bench_softbody import AREA_M, scene_specs
from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion import synthesize_motion
from toolkit.motion.gait import LOOP_TURN_RATE
from toolkit.synthetic.depth_sensor import DepthCameraSpec, depth_camera_for
from toolkit.synthetic.generator import _build_scene, build_scene, frames_out_of_view
from toolkit.synthetic.spec import parse_spec

#: The pelvis sways sideways and turns with the stride on top of the path (metres, radians per second).
SWAY_M = 0.05
STRIDE_TURN_RATE = 1.0


def _pelvis(joints):
    return 0.5 * (joints[:, 8, :2] + joints[:, 11, :2])


@pytest.mark.parametrize("name", ["walk", "run"])
def test_a_long_walk_or_run_loops_inside_its_area(name):
    props = BodyProportions.from_height(1.75)
    m = synthesize_motion(name, props, 300, 25.0, rng=4, area_m=1.0)
    free = synthesize_motion(name, props, 300, 25.0, rng=4)
    pel = _pelvis(m.joints)
    assert m.params["path"] == "loop" and free.params["path"] != "loop"
    assert np.linalg.norm(pel, axis=1).max() < 1.0 + SWAY_M   # the loop is centred on the origin
    assert np.linalg.norm(_pelvis(free.joints) - _pelvis(free.joints).mean(axis=0), axis=1).max() > 1.5
    # it goes round: a turn of the heading per lap, no faster than the loop's turns allow
    assert abs(m.pose.yaw[-1] - m.pose.yaw[0]) > 2 * np.pi
    assert np.abs(np.diff(m.pose.yaw)).max() * 25.0 < LOOP_TURN_RATE + STRIDE_TURN_RATE
    # the bones keep their lengths and the feet stay on the ground
    assert m.joints[:, [10, 13], 2].min() >= props.ankle_height - 1e-6


def test_a_short_walk_within_its_area_is_the_walk_drawn_without_one():
    props = BodyProportions.from_height(1.75)
    a = synthesize_motion("walk", props, 30, 25.0, rng=4, area_m=1.0)
    b = synthesize_motion("walk", props, 30, 25.0, rng=4)
    np.testing.assert_array_equal(a.joints, b.joints)
    with pytest.raises(InputError, match="area_m"):
        synthesize_motion("walk", props, 30, 25.0, rng=4, area_m=-1.0)


@pytest.mark.parametrize("seed", [26000, 27000])
def test_the_benchmarks_long_scenes_stay_in_every_cameras_view(seed):
    for name, kind, text in scene_specs(2, 300, seed, ("walk", "run")):
        spec = parse_spec(text, name)
        assert spec.area_m == AREA_M
        scene, free = build_scene(spec), _build_scene(spec, None)
        for s, out in ((scene, False), (free, True)):   # without the area the same seed leaves the view
            if kind == "depth":
                dspec = DepthCameraSpec.from_table(spec.depth_camera, name)
                left = frames_out_of_view([depth_camera_for(dspec, s.joints)], s.joints, dspec.range_m)
            else:
                left = frames_out_of_view(s.rig, s.joints)
            assert left.any() == out, name


def test_the_benchmarks_short_walks_and_other_motions_are_as_drawn_without_an_area():
    for name, kind, text in scene_specs(4, 30, 26000, ("walk", "run", "jump", "turn")):
        spec = parse_spec(text, name)
        if spec.motion == "run":
            continue   # the drawn 30-frame runs left the cameras' view: they loop now
        np.testing.assert_array_equal(build_scene(spec).joints, _build_scene(spec, None).joints)


def test_a_bad_area_is_refused():
    text = 'seed = 1\nframes = 2\nfps = 25\n[subject]\nheight_m = 1.7\nmotion = "walk"\narea_m = 0.0\n' \
           '[cameras]\ncount = 1\nlayout = "studio"\nresolution = [64, 48]\n'
    with pytest.raises(InputError, match="subject.area_m"):
        parse_spec(text)
