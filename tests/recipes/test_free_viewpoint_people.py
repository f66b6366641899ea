"""recipes/free_viewpoint.py with two people crossing in front of each other (keypoints of both).

A ring of four studio cameras films two flat-coloured people, one in warm colours
and one in cold colours, walking past each other; every camera's keypoint files
hold both people (in a random order).  With ``people = "all"`` (the default)
each person goes through stages 1-4 on its own and the views draw them in depth
order: a held-out camera's render must show each person in their own colours
where the truth shows them, also where one hides the other in some source view.
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.body.model import BodyModel
from toolkit.cameras import Camera, Rig
from toolkit.io import DatasetWriter
from toolkit.io.frames import read_png
from toolkit.io.openpose import write_openpose_json
from toolkit.motion import generate_motion
from toolkit.skeleton import SKELETON_14
from toolkit.skeleton.mappings import from_skeleton14
from toolkit.synthetic.render import Raycaster

N_FRAMES = 3
HELD = "cam_1"
SIZE = (320, 240)
#: Part colours (index = part id + 1) of the warm person and of the cold one.
WARM = np.array([[0, 0, 0], [230, 190, 150], [200, 60, 40], [225, 140, 90], [225, 140, 90], [190, 70, 50],
                 [215, 120, 80], [150, 60, 30], [120, 70, 30], [170, 80, 40], [130, 80, 40]], np.uint8)
COLD = np.array([[0, 0, 0], [150, 200, 230], [40, 150, 70], [90, 180, 200], [90, 180, 200], [50, 160, 90],
                 [80, 170, 190], [40, 60, 160], [30, 70, 120], [50, 80, 180], [40, 90, 130]], np.uint8)
#: Share of a person's truly visible pixels (of the held-out view) drawn closer to their own palette than
#: to the other person's, where something is drawn.  Measured 0.83-1.0 (the lowest: the 450 visible pixels of the
#: person behind, frame 2); with the silhouettes not made exclusive the person behind in frame 1 was 0.41
#: (textured with the one in front).
OWN_COLOURS = 0.8


def _camera(name, az_deg):
    a = np.radians(az_deg)
    eye = [4.5 * np.cos(a), 4.5 * np.sin(a), 1.7]
    return Camera.look_at(name, eye, [0.0, 0.0, 0.95], size=SIZE, focal_px=300.0)


def _palette_side(img: np.ndarray) -> np.ndarray:
    """Per pixel: 0 closer to the warm palette, 1 closer to the cold one."""
    px = img.reshape(-1, 1, 3).astype(float)
    dw = np.min(np.linalg.norm(px - WARM[1:][None].astype(float), axis=-1), axis=1)
    dc = np.min(np.linalg.norm(px - COLD[1:][None].astype(float), axis=-1), axis=1)
    return (dc < dw).reshape(img.shape[:2])


@pytest.fixture(scope="module")
def crossing(tmp_path_factory):
    root = tmp_path_factory.mktemp("fvv_people") / "crossing"
    rng = np.random.default_rng(8)
    bodies, paths = [], []
    for k, (start, end) in enumerate((((-0.5, -0.35), (0.5, -0.35)), ((0.55, 0.35), (-0.45, 0.35)))):
        props = BodyProportions.sample(1.70 + 0.08 * k, rng)
        bodies.append(BodyModel.sample(props, rng, detail=0.4))
        J = generate_motion("idle", props, N_FRAMES, 25.0, rng)
        J = J - np.r_[J[0, 1, :2], 0.0]
        s = np.linspace(0.0, 1.0, N_FRAMES)[:, None]
        shift = (1 - s) * np.asarray(start) + s * np.asarray(end)
        paths.append(J + np.concatenate([shift, np.zeros((N_FRAMES, 1))], 1)[:, None, :])
    # cam_0 and cam_3 look across the line the people walk on: one hides the other there
    rig = Rig(tuple(_camera(f"cam_{i}", az) for i, az in enumerate((-90.0, -30.0, 40.0, 95.0))))
    caster = Raycaster()
    backdrop = {cam.name: rng.integers(90, 140, SIZE[::-1] + (3,)).astype(np.uint8) for cam in rig}
    instances = {}
    with DatasetWriter(root, 5.0) as w:  # 5 fps: the people walk 2.5 m/s
        w.write_calibration(rig)
        w.write_gt_calibration(rig)
        for t in range(N_FRAMES):
            meshes = [b.mesh(p[t]) for b, p in zip(bodies, paths)]
            for cam in rig:
                labels, subject, _ = caster.cast(cam, meshes)
                img = backdrop[cam.name].copy()
                for k, pal in enumerate((WARM, COLD)):
                    sel = subject == k + 1
                    img[sel] = pal[labels[sel]]
                w.write_frame(cam.name, t, img)
                w.write_mask(cam.name, t, subject > 0)
                w.write_parts(cam.name, t, labels)
                instances[(cam.name, t)] = subject
        w.write_joints3d(paths[0], SKELETON_14.joint_names)
        w.write_joints2d({cam.name: cam.project(paths[0]) for cam in rig})
    for cam in rig:
        kps = [from_skeleton14(cam.project(p) + rng.normal(0, 0.7, (N_FRAMES, 14, 2)), "body_25", 0.9)
               for p in paths]
        for t in range(N_FRAMES):
            people = [kps[k][t] for k in rng.permutation(2)]
            write_openpose_json(root / "keypoints" / cam.name / f"{cam.name}_{t:012d}_keypoints.json", people)
    return root, paths, instances


@pytest.mark.timeout(900)
def test_two_people_crossing_keep_their_own_textures(crossing, tmp_path, capsys):
    root, paths, instances = crossing
    # one source view sees one person hide the other (the case the exclusive silhouettes are for)
    hidden = [any(np.sum(instances[(c, t)] == k) < 0.8 * np.sum(instances[(HELD, t)] == k) for c in ("cam_0", "cam_3")
                  for k in (1, 2)) for t in range(N_FRAMES)]
    assert any(hidden)
    out = tmp_path / "run"
    recipe = importlib.import_module("recipes.free_viewpoint")
    rc = recipe.main([str(root), "--out", str(out), "--workers", "1",
                      "--hold-out", HELD, "--keypoint-format", "body_25",
                      "--no-optimize", "--no-recording", "--quiet"])
    cap = capsys.readouterr()
    assert rc == 0, cap.out + cap.err
    m = json.loads((out / "metrics.json").read_text())
    assert len(m.get("people", {}).get("names", [])) == 2, cap.out
    assert m["people"]["frames_drawn"] == {"person_0": N_FRAMES, "person_1": N_FRAMES}
    z = np.load(out / "people3d.npz")
    assert z["joints"].shape == (2, N_FRAMES, 14, 3)
    # each estimated person is one of the true people, within a few centimetres
    err = [[np.nanmean(np.linalg.norm(z["joints"][i] - p, axis=-1)) for p in paths] for i in range(2)]
    assert sorted(int(np.argmin(e)) for e in err) == [0, 1] and max(min(e) for e in err) < 0.06, err
    for t in range(N_FRAMES):
        img = read_png(out / "heldout" / HELD / f"{t:06d}.png")
        alpha = read_png(out / "heldout_alpha" / HELD / f"{t:06d}.png") > 127
        side = _palette_side(img)
        truth = instances[(HELD, t)]
        for k in (1, 2):
            sel = (truth == k) & alpha
            assert sel.sum() > 200, (t, k)
            own = np.mean(side[sel] == (k == 2))
            assert own > OWN_COLOURS, (t, k, own)
        # both people are drawn: the union of their regions is mostly covered
        assert np.mean(alpha[truth > 0]) > 0.8
    # the part labels of a source view hold both people
    parts = read_png(out / "parts" / "cam_2" / "000001.png")
    assert (parts > 0).sum() > 0.7 * (instances[("cam_2", 1)] > 0).sum()
