"""Novel views from any direction: a subject is never missing, parts keep their width.

A body ray-cast with flat part colours is seen by two far cameras 100 degrees
apart (a broadcast pair); the articulated billboards, built from the true
joints and part labels, are rendered into novel cameras between the sources,
behind both of them (the reverse angle) and high above, and compared with the
ray-cast ground truth.
"""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.billboards.model import Billboard
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.motion import generate_motion
from toolkit.rendering import CpuCompositor, render_billboards, subject_scores
from toolkit.rendering.blend import facing_pose
from toolkit.rendering.config import BlendConfig
from toolkit.body.model import BodyModel
from toolkit.synthetic.render import Raycaster

#: Flat colour per part id (0 = background, black).
COLOURS = np.array([[0, 0, 0], [225, 185, 150], [190, 40, 40], [215, 125, 95], [215, 125, 95], [170, 50, 50],
                    [205, 105, 85], [40, 40, 130], [70, 45, 25], [45, 45, 150], [80, 55, 35]], np.uint8)
#: Share of the true mask every novel view must cover with opacity > 0.5 (issue 13).
MIN_COVERAGE = 0.9
#: Coverage bounds of the harder views, measured 0.95 (140 degrees round: one source seen from behind, the
#: other edge-on; 0.91 before the edge-on billboards came before the back faces and the back faces under
#: every part) and 0.95 (55 degrees above: planes through the bones cannot show the top of the body,
#: shoulders and the torso's depth; 0.73 before the far-side copy, 0.86 before the borrowed hidden limbs,
#: 0.88 before the back faces under the parts; see docs/stage4_rendering.md).
REVERSE_SIDE_COVERAGE = MIN_COVERAGE
HIGH_VIEW_COVERAGE = MIN_COVERAGE
#: Subject-region PSNR of the reverse-angle view (measured 19.9 dB: flat colours, the back drawn with the
#: front's texture); a view that misses the subject scores ~9 dB.
REVERSE_PSNR_DB = 16.0
#: Without the fallback (back faces off, billboards not turned) the reverse view is empty: coverage ~0.
EMPTY_COVERAGE = 0.05
#: Rotation residual, radians / metres.
POSE_TOL = 1e-9


def _camera(name, centre, az_deg, elev_deg=15.0, dist=30.0):
    a, e = np.radians(az_deg), np.radians(elev_deg)
    eye = centre + dist * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    return Camera.look_at(name, eye, centre, size=(320, 240), focal_px=2400.0)


@pytest.fixture(scope="module")
def pair_scene():
    """Source images, labels, joints, rig, novel cameras and their ray-cast truth (image, mask)."""
    rng = np.random.default_rng(3)
    props = BodyProportions.sample(1.75, rng)
    body = BodyModel.sample(props, rng, detail=0.4)
    joints = generate_motion("walk", props, 1, 25.0, rng)[0]
    centre = np.r_[joints[1, :2], 0.9]
    rig = Rig((_camera("cam_0", centre, -50.0), _camera("cam_1", centre, 50.0)))
    novel = {"between": _camera("between", centre, 0.0), "reverse": _camera("reverse", centre, 180.0),
             "reverse_side": _camera("reverse_side", centre, 140.0), "high": _camera("high", centre, 90.0, 55.0)}
    caster = Raycaster()
    mesh = body.mesh(joints)
    images, labels = {}, {}
    for cam in rig:
        lab, _, _ = caster.cast(cam, [mesh])
        images[cam.name], labels[cam.name] = COLOURS[lab], lab
    truth = {}
    for k, cam in novel.items():
        lab, subject, _ = caster.cast(cam, [mesh])
        truth[k] = (COLOURS[lab], subject > 0)
    return images, labels, joints, rig, novel, truth


@pytest.fixture(scope="module")
def pair(pair_scene):
    images, labels, joints, rig, novel, truth = pair_scene
    model = render_billboards(images, labels, joints, rig)
    return model, novel, truth


def _score(model, cam, truth, config=BlendConfig()):
    r = CpuCompositor(config).render(model, cam)
    return subject_scores(r.over(np.zeros(r.rgb.shape, np.float32)), truth[0], truth[1], r.alpha)


def test_two_cameras_reverse_angle_renders_the_subject(pair):
    model, novel, truth = pair
    bounds = {"between": MIN_COVERAGE, "reverse": MIN_COVERAGE, "reverse_side": REVERSE_SIDE_COVERAGE,
              "high": HIGH_VIEW_COVERAGE}
    for k in novel:
        s = _score(model, novel[k], truth[k])
        assert s["coverage"] >= bounds[k], (k, s)
    assert _score(model, novel["reverse"], truth["reverse"])["psnr_subject"] > REVERSE_PSNR_DB
    # the same view with the source's blend alone (grazing / back-facing billboards faded out): empty
    old = BlendConfig(back_faces=False, normalise_fade=False, face_view=False)
    assert _score(model, novel["reverse"], truth["reverse"], old)["coverage"] < EMPTY_COVERAGE


def test_facing_pose_turns_about_the_bone_towards_the_view(pair):
    model, novel, _ = pair
    rig = model.rig
    for b in model.billboards:
        x0, x1 = b.axis
        bone = (x1 - x0) / np.linalg.norm(x1 - x0)
        at_source = facing_pose(b, rig[b.camera].center)
        assert np.allclose(at_source, np.eye(4), atol=1e-7)  # a source view is drawn unchanged
        for cam in novel.values():
            T = facing_pose(b, cam.center)
            R = T[:3, :3]
            assert np.allclose(R @ R.T, np.eye(3), atol=POSE_TOL) and np.linalg.det(R) > 0
            assert np.allclose(T[:3, :3] @ x0 + T[:3, 3], x0, atol=POSE_TOL)  # the bone stays put
            assert np.allclose(R @ bone, bone, atol=POSE_TOL)
            n = R @ b.normal
            to_eye = cam.center - x0
            across = to_eye - (to_eye @ bone) * bone
            # it now faces the view (front or back), turned by at most 90 degrees
            assert abs(abs(n @ across) / np.linalg.norm(across) - 1.0) < 1e-9
            assert n @ b.normal >= -POSE_TOL


def test_turn_free_angle_and_part_ratios(pair):
    from toolkit.errors import InputError

    model, novel, _ = pair
    for b in model.billboards:
        for cam in novel.values():
            assert np.allclose(facing_pose(b, cam.center, free_deg=90.0), np.eye(4), atol=1e-9)  # never turned
            T, T30 = facing_pose(b, cam.center), facing_pose(b, cam.center, free_deg=30.0)
            full = np.degrees(np.arccos(np.clip((np.trace(T[:3, :3]) - 1) / 2, -1, 1)))
            part = np.degrees(np.arccos(np.clip((np.trace(T30[:3, :3]) - 1) / 2, -1, 1)))
            assert abs(part - max(full - 30.0, 0.0)) < 1e-6
    cfg = BlendConfig(part_depth_ratios=(("torso", 0.8),), turn_free_deg=10.0)
    assert abs(cfg.free_angles_deg()[2] - np.degrees(np.arccos(0.8))) < 1e-9  # torso: part id 2
    assert BlendConfig().free_angles_deg() == {}
    with pytest.raises(InputError, match="part_depth_ratios"):
        BlendConfig(part_depth_ratios=(("tail", 0.5),))
    with pytest.raises(InputError, match="part_depth_ratios"):
        BlendConfig(part_depth_ratios=(("torso", 1.5),))


def _fan_geometry(model):
    """Per fan and rig camera: billboard normals, centres (F, C, 3) and presence (F, C), as fan_weights sees them."""
    names = model.rig.names
    n_f, n_c = len(model.fans), len(names)
    normals = np.tile([0.0, 0.0, 1.0], (n_f, n_c, 1))
    points = np.zeros((n_f, n_c, 3))
    present = np.zeros((n_f, n_c), bool)
    for i, f in enumerate(model.fans):
        for b in f.billboards:
            j = names.index(b.camera)
            normals[i, j], points[i, j], present[i, j] = b.normal, b.center, True
    return normals, points, present


def test_edge_on_front_billboards_come_before_back_faces(pair):
    """A view 82 degrees round from one source and behind the other: the parts' visible side, seen edge-on,
    is drawn by the source that saw it (not the back faces of the other source's billboards)."""
    from toolkit.rendering import fan_weights, foreshortening, grazing_fade

    model, _, _ = pair
    centre = np.r_[model.joints[1, :2], 0.9]
    cam = _camera("edge_on", centre, 132.0)
    normals, points, present = _fan_geometry(model)
    ratio = np.where(present, foreshortening(normals, points, cam.center, model.rig.centers), -np.inf)
    front = np.where(present, grazing_fade(normals, points, cam.center, model.rig.centers), 0.0)
    edge_on = ~np.any(front > 0, axis=1) & np.any(ratio > 0, axis=1)
    assert edge_on.sum() >= 3  # the case this test is about: parts seen from the front, past the fade
    w = fan_weights(model, cam)
    rows = np.flatnonzero(edge_on)
    best = np.argmax(ratio, axis=1)
    assert np.all(w.nearest[rows] == best[rows])
    assert np.all(w.fade[rows, best[rows]] == 1.0) and np.all(w.omega[rows, best[rows]] == 1.0)
    assert w.back is None or not np.any(w.back[rows, best[rows]])
    # the rule off: the same parts are drawn by back faces
    off = fan_weights(model, cam, BlendConfig(grazing_front=False))
    assert off.back is not None and np.all(off.back[rows, off.nearest[rows]])


def test_back_faces_under_the_parts_seen_from_the_front(pair):
    """A view 50 degrees from one source and 150 from the other: the far source's back faces are drawn under
    every part (never its nearest, colour weight at most ``back_underlay``), not at a source camera, not for
    borrowed billboards, and not with ``back_underlay = 0``."""
    import dataclasses

    from toolkit.rendering import fan_weights
    from toolkit.rendering.fans import BorrowedBillboard

    model, _, _ = pair
    centre = np.r_[model.joints[1, :2], 0.9]
    cam = _camera("side", centre, 100.0)
    far = model.rig.names.index("cam_0")
    config = BlendConfig()
    w = fan_weights(model, cam, config)
    assert np.all(w.nearest != far) and w.back is not None
    under = w.back[:, far]
    assert under.sum() >= len(model.fans) // 2
    assert np.all(w.fade[under, far] > 0)
    assert np.all(w.omega[under, far] <= config.back_underlay + 1e-12)
    assert np.all(w.weight[under, far] > 0)
    off = fan_weights(model, cam, BlendConfig(back_underlay=0.0))
    assert off.back is None and np.all(off.fade[:, far] == 0)
    # at the near source itself the back faces weigh nothing: that view is reproduced exactly
    at_source = fan_weights(model, model.rig["cam_1"], config)
    assert np.all(at_source.weight[:, far] == 0)
    # a stand-in (borrowed) billboard's outline is another source's: not drawn under the part
    fans = tuple(dataclasses.replace(f, billboards=tuple(
        BorrowedBillboard(**{k.name: getattr(b, k.name) for k in dataclasses.fields(Billboard)})
        if b.camera == "cam_0" else b for b in f.billboards)) for f in model.fans)
    borrowed = fan_weights(dataclasses.replace(model, fans=fans), cam, config)
    assert borrowed.back is None or not np.any(borrowed.back[:, far])
    with pytest.raises(InputError, match="back_underlay"):
        BlendConfig(back_underlay=1.5)
