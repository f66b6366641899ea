"""recipes/free_viewpoint.py with three people and no keypoints: the people from the silhouettes.

A ring of four cameras films three walking people over a textured backdrop (its clean plate
written, as the synthetic scenes do).  With ``people = "all"`` (the default) and no keypoints,
the run finds where each person stands in the cameras' foreground, gives each one its share of
the foreground and a silhouette-database estimate of its own, and draws all of them: three people
followed, each within a few centimetres of a true person, every true person drawn in a novel view.
With ``--people main`` the run follows one person, as before.
"""

from __future__ import annotations

import importlib
import json

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.body.model import BodyModel
from toolkit.cameras import Camera, Rig
from toolkit.io import DatasetWriter
from toolkit.io.frames import read_png
from toolkit.motion import generate_motion
from toolkit.silhouettes import BuildConfig, build_database
from toolkit.skeleton import SKELETON_14
from toolkit.synthetic.render import Raycaster

N_FRAMES = 2
SIZE = (320, 240)
#: Stage-1 joint error of each person against the true person it matches (silhouette database of 240
#: walking entries; measured 5-9 cm): with margin.
PERSON_ERROR_M = 0.15
#: Share of each true person's pixels in the novel view that the render covers.
DRAWN = 0.6


def _camera(name, az_deg, radius=5.5):
    a = np.radians(az_deg)
    return Camera.look_at(name, [radius * np.cos(a), radius * np.sin(a), 2.0], [0.0, 0.0, 0.9], size=SIZE,
                          focal_px=260.0)


@pytest.fixture(scope="module")
def three_people(tmp_path_factory):
    root = tmp_path_factory.mktemp("fvv_sil_people") / "three"
    rng = np.random.default_rng(11)
    starts = [(-1.2, -0.6), (0.9, -0.2), (-0.2, 1.1)]
    heading = [0.0, np.pi, -np.pi / 2]
    bodies, paths = [], []
    for k, (start, yaw) in enumerate(zip(starts, heading)):
        props = BodyProportions.sample(1.66 + 0.08 * k, rng)
        bodies.append(BodyModel.sample(props, rng, detail=0.4))
        J = generate_motion("walk", props, N_FRAMES, 25.0, rng)
        J = J - np.r_[J[0, 1, :2], 0.0]
        c, s = np.cos(yaw), np.sin(yaw)
        J = J @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T
        paths.append(J + np.r_[start, 0.0])
    rig = Rig(tuple(_camera(f"cam_{i}", az) for i, az in enumerate((-80.0, 10.0, 100.0, 190.0))))
    novel = Rig((_camera("novel_0", -35.0),))
    caster = Raycaster()
    colours = rng.integers(40, 230, (3, 11, 3)).astype(np.uint8)
    backdrop = {cam.name: rng.integers(90, 140, SIZE[::-1] + (3,)).astype(np.uint8) for cam in (*rig, *novel)}
    instances = {}
    with DatasetWriter(root, 25.0) as w:
        w.write_calibration(rig)
        w.write_gt_calibration(rig)
        w.write_novel_calibration(novel)
        for cam in rig:
            w.write_background(cam.name, backdrop[cam.name])
        for t in range(N_FRAMES):
            meshes = [b.mesh(p[t]) for b, p in zip(bodies, paths)]
            for cam in (*rig, *novel):
                labels, subject, _ = caster.cast(cam, meshes)
                img = backdrop[cam.name].copy()
                for k in range(3):
                    sel = subject == k + 1
                    img[sel] = colours[k][labels[sel]]
                if cam.name.startswith("novel"):
                    w.write_novel_image(cam.name, t, img)
                    w.write_novel_mask(cam.name, t, subject > 0)
                    w.write_novel_parts(cam.name, t, labels)
                    w.write_novel_instances(cam.name, t, subject)
                else:
                    w.write_frame(cam.name, t, img)
                    w.write_mask(cam.name, t, subject > 0)
                    w.write_parts(cam.name, t, labels)
                    w.write_instances(cam.name, t, subject)
                instances[(cam.name, t)] = subject
        w.write_joints3d(paths[0], SKELETON_14.joint_names)
        w.write_people(np.stack(paths), SKELETON_14.joint_names)
    db = build_database(BuildConfig(motions=("walk",), sequences_per_motion=2, frames_per_sequence=40,
                                    frame_stride=4, views_per_pose=12), 5)
    db_path = db.save(tmp_path_factory.mktemp("db") / "walk.npz")
    return root, db_path, paths, instances


@pytest.mark.timeout(900)
def test_three_people_from_silhouettes(three_people, tmp_path, capsys):
    root, db_path, paths, instances = three_people
    out = tmp_path / "run"
    recipe = importlib.import_module("recipes.free_viewpoint")
    rc = recipe.main([str(root), "--out", str(out), "--workers", "1",
                      "--db", str(db_path), "--no-optimize", "--no-baselines",
                      "--no-recording", "--quiet"])
    cap = capsys.readouterr()
    assert rc == 0, cap.out + cap.err
    assert "people from silhouettes: 3 followed" in cap.out + cap.err, cap.out + cap.err
    m = json.loads((out / "metrics.json").read_text())
    assert len(m["people"]["names"]) == 3
    z = np.load(out / "people3d.npz")
    assert z["joints"].shape == (3, N_FRAMES, 14, 3)
    err = np.array([[np.nanmean(np.linalg.norm(z["joints"][i] - p, axis=-1)) for p in paths] for i in range(3)])
    assert sorted(np.argmin(err, axis=1).tolist()) == [0, 1, 2], err
    assert err.min(axis=1).max() < PERSON_ERROR_M, err
    for t in range(N_FRAMES):
        alpha = read_png(out / "novel_alpha" / "novel_0" / f"{t:06d}.png") > 127
        truth = instances[("novel_0", t)]
        for k in (1, 2, 3):
            assert np.mean(alpha[truth == k]) > DRAWN, (t, k, np.mean(alpha[truth == k]))
