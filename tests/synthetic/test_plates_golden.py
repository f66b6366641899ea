"""Golden test of the ray-cast renderer's background plates and renders (issue 20).

The plates of a camera path's views are drawn once per frame by a
free-viewpoint run (``toolkit.rendering.evaluation.BackgroundPlates``); their
shading was made faster (blocks of rays, per-triangle corner tables, packed
texture gathers, a block sum in ``mean``'s order, the pinhole inverse by rows
and columns) with the same arithmetic per ray.  This test pins the plates
(colour and depth) and a render with a posed body of a small broadcast scene
(textured ground, vertex-coloured stands) to the outputs of the code before
the change (``tests/data/plates_golden.json``), bit for bit: source cameras,
novel cameras, an orbit view, a view between two sources with interpolated
intrinsics, a bird's-eye view.

The scene is generated deterministically; where its surroundings differ from
the digest stored with the outputs (other library versions) the test is
skipped with that reason, and so it is where Open3D's ray caster itself gives
other bits for the same rays (``raycast_probe``: the depths of one camera's
rays against the surroundings, cast directly; Embree's arithmetic follows the
processor's vector instructions: on a machine with AVX-512 the depths differed
from those of the machine the file was made on, with the same
library versions and the code of either commit).  Regenerate the file (only when an intended change
of the outputs has been explained) with
``python tests/synthetic/test_plates_golden.py tests/data/plates_golden.json``.
"""

from __future__ import annotations

import functools
import hashlib
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

GOLDEN = Path(__file__).resolve().parents[1] / "data" / "plates_golden.json"
SPEC = """
seed = 5
frames = 2
fps = 25
[subject]
height_m = 1.75
motion = "walk"
[cameras]
count = 3
layout = "broadcast"
resolution = [96, 54]
calibration_error_px = 4.0
[novel]
count = 2
"""


@functools.lru_cache(maxsize=1)
def _setup():
    from toolkit.cameras import Rig, closest_point_to_rays
    from toolkit.rendering import birds_eye, orbit_path, source_path
    from toolkit.synthetic.environment import make_environment
    from toolkit.synthetic.generator import build_scene
    from toolkit.synthetic.spec import parse_spec

    spec = parse_spec(SPEC, "plates.toml")
    scene = build_scene(spec)
    env = make_environment(spec.layout, scene.rngs["environment"])
    rig = scene.rig
    target = closest_point_to_rays(rig.centers, np.array([c.forward for c in rig]))[0]
    cams = [*rig, *scene.novel,
            orbit_path(target, 5, radius_m=40.0, height_m=12.0, size=rig[0].size, focal_px=float(rig[0].K[0, 0]))[2],
            source_path(Rig(tuple(replace(c, size=rig[0].size) for c in rig)), 7, closed=True)[3],
            birds_eye(rig, target)]
    h = hashlib.sha1()
    for s in env:
        h.update(np.ascontiguousarray(s.vertices, np.float64).tobytes())
        h.update(np.ascontiguousarray(s.triangles, np.int64).tobytes())
        h.update(b"" if s.texture is None else s.texture.tobytes())
    return spec, scene, env, cams, h.hexdigest()


def _sha1(a: np.ndarray) -> str:
    return f"{a.dtype} {a.shape} " + hashlib.sha1(np.ascontiguousarray(a).tobytes()).hexdigest()


def raycast_probe() -> str:
    """Digest of Open3D's hit distances of a fixed grid of rays (the first camera's) against the surroundings."""
    import open3d as o3d

    _, _, env, cams, _ = _setup()
    scene = o3d.t.geometry.RaycastingScene()
    for s in env:
        scene.add_triangles(o3d.core.Tensor(np.asarray(s.vertices, np.float32)),
                            o3d.core.Tensor(np.asarray(s.triangles, np.uint32)))
    cam = cams[0]
    u, v = np.meshgrid(np.arange(0, cam.size[0], 2) + 0.5, np.arange(0, cam.size[1], 2) + 0.5)
    o, d = cam.rays(np.stack([u.ravel(), v.ravel()], 1))
    hit = scene.cast_rays(o3d.core.Tensor(np.hstack([o, d]).astype(np.float32)))
    return _sha1(hit["t_hit"].numpy())


def outputs(renderer_class=None) -> dict:
    """Digests of the plates, depths and body renders of the golden cameras (``renderer_class``: default the
    toolkit's; a digest of the bytes is as strict as the arrays and keeps the file small)."""
    from toolkit.synthetic.generator import BACKGROUND_COLOUR
    from toolkit.synthetic.render import RaycastRenderer

    spec, scene, env, cams, digest = _setup()
    cls = renderer_class or RaycastRenderer
    r = cls(spec.resolution, env, BACKGROUND_COLOUR[spec.layout], spec.supersample)
    out = {"digest": digest}
    for i, cam in enumerate(cams):
        out[f"plate{i}"] = _sha1(r.background_plate(cam))
        out[f"depth{i}"] = _sha1(r._plates[(cam.K.tobytes(), cam.cam_from_world.tobytes())][1])
    mesh = scene.body_mesh(1)
    r.set_bodies([(mesh, mesh.shaded_colors(scene.light_dir))])
    for i, cam in enumerate(cams[:5]):
        out[f"render{i}"] = _sha1(r.render(cam))
    return out


def test_plates_and_renders_equal_the_golden_outputs():
    if not GOLDEN.exists():
        pytest.skip(f"{GOLDEN} missing")
    gold = json.loads(GOLDEN.read_text())
    got = outputs()
    if got["digest"] != gold["digest"]:
        pytest.skip("the generated surroundings differ from the golden scene's (other library versions)")
    if gold.get("raycast_probe") != raycast_probe():
        pytest.skip("Open3D's ray caster gives other bits for the same rays on this machine (another vector "
                    "instruction set, or another Open3D build)")
    assert got == {k: v for k, v in gold.items() if k != "raycast_probe"}


def test_plates_not_kept_equal_kept_ones_and_are_read_only():
    from toolkit.rendering.evaluation import PLATES_KEPT, BackgroundPlates
    from toolkit.synthetic.generator import BACKGROUND_COLOUR
    from toolkit.synthetic.render import RaycastRenderer

    spec, _, env, cams, _ = _setup()
    r = RaycastRenderer(spec.resolution, env, BACKGROUND_COLOUR[spec.layout], spec.supersample)
    once = r.background_plate(cams[5], keep=False)
    assert not r._plates  # nothing kept
    assert once.tobytes() == r.background_plate(cams[5]).tobytes()
    plates = BackgroundPlates.__new__(BackgroundPlates)
    plates._renderer, plates._kept, plates._store = r, {}, None
    first = plates.plate(cams[0])
    with pytest.raises(ValueError):
        first[0, 0] = 0
    for cam in cams:
        plates.plate(cam)
    assert len(plates._kept) == min(PLATES_KEPT, len(cams))


def test_block_sum_downsample_equals_mean():
    from toolkit.synthetic.render import RaycastRenderer

    rng = np.random.default_rng(3)
    for s in (1, 2, 3, 4):
        for shape in ((6 * s, 10 * s, 3), (40 * s, 30 * s, 3), (4 * s, 6 * s), (4 * s, 6 * s, 1)):
            img = (rng.random(shape, np.float32) * 255).astype(np.float32) * rng.random(shape, np.float32)
            h, w = shape[:2]
            ref = img.reshape(h // s, s, w // s, s, *shape[2:]).mean(axis=(1, 3))
            assert RaycastRenderer._downsample(img, s).tobytes() == ref.tobytes(), (s, shape)


if __name__ == "__main__":  # regenerate: python tests/synthetic/test_plates_golden.py tests/data/plates_golden.json
    Path(sys.argv[1]).write_text(json.dumps({**outputs(), "raycast_probe": raycast_probe()}, indent=1) + "\n")
