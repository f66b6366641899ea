"""The scene model: backgrounds without the people, the proxy, and view-dependent rendering from other cameras."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.scene import SceneModel, SceneProxy, SourceBackground, estimate_background, fit_proxy, people_exclusion
from toolkit.scene.fit import RADIUS_CANDIDATES
from toolkit.scene.model import CARRIES_KEPT
from toolkit.scene.proxy import SURFACE_GROUND, SURFACE_NONE, SURFACE_WALL

SIZE = (160, 120)


def _texture(points: np.ndarray, surface: np.ndarray) -> np.ndarray:
    """A smooth colour per world point: stripes on the ground, angular bands on the wall, (N, 3) 0..255."""
    x, y, z = points.T
    ground = np.stack([128 + 90 * np.sin(x * 2.1), 128 + 90 * np.sin(y * 1.7), 128 + 60 * np.cos((x + y) * 1.3)], 1)
    th = np.arctan2(y, x)
    wall = np.stack([128 + 100 * np.sin(th * 9), 128 + 100 * np.cos(th * 7 + z), 90 + 40 * np.sin(z * 2.0)], 1)
    out = np.where((surface == SURFACE_WALL)[:, None], wall, ground)
    out[surface == SURFACE_NONE] = 0
    return out.astype(np.float32)


def _ring(n: int, radius: float = 5.0, start: float = 0.0, height: float = 1.6, pitch_to: float = 0.6) -> Rig:
    cams = []
    for i in range(n):
        a = np.radians(start + i * 360.0 / n)
        eye = [radius * np.cos(a), radius * np.sin(a), height]
        cams.append(Camera.look_at(f"cam{i}", eye, [0.0, 0.0, pitch_to], size=SIZE, focal_px=110.0))
    return Rig(tuple(cams))


def _truth_view(cam: Camera, proxy: SceneProxy) -> np.ndarray:
    w, h = cam.size
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    o, d = cam.rays(np.stack([u, v], -1).reshape(-1, 2))
    pts, surf = proxy.intersect(o, d)
    return _texture(pts, surf).reshape(h, w, 3)


def _backgrounds(rig: Rig, proxy: SceneProxy) -> dict:
    return {cam.name: SourceBackground(_truth_view(cam, proxy), np.ones(cam.size[::-1], np.float32), 1) for cam in rig}


def test_background_leaves_out_a_passer_by_and_the_excluded_people():
    rng = np.random.default_rng(0)
    h, w = 60, 80
    empty = rng.integers(40, 200, (h, w, 3)).astype(np.uint8)
    frames, exclude = [], []
    for t in range(12):
        f = empty.copy()
        x = 5 + 6 * t
        f[20:40, x:x + 8] = (250, 20, 20)          # walks across: never more than a few frames on a pixel
        f[5:15, 60:70] = (20, 250, 20)            # stands still all along, but a detector finds it
        m = np.zeros((h, w), bool)
        m[3:17, 58:72] = True
        frames.append(f)
        exclude.append(m)
    bg = estimate_background(frames, exclude)
    err = np.abs(bg.image - empty).max(-1)
    seen = bg.confidence > 0
    assert np.median(err[seen]) < 1.0 and np.percentile(err[20:40], 95) < 2.0
    assert (bg.confidence[5:15, 60:70] == 0).all()     # never seen empty: no confidence
    assert (bg.confidence[45:, :] == 1).all()
    with pytest.raises(InputError, match="exclude"):
        estimate_background(frames, exclude[:3])


def test_people_exclusion_covers_the_body_beyond_its_keypoints():
    kp = np.array([[50, 20, 0.9], [50, 40, 0.9], [40, 60, 0.9], [60, 60, 0.9], [45, 90, 0.9], [55, 90, 0.9],
                   [10, 10, 0.0]], float)
    m = people_exclusion([kp], (100, 120))
    assert m[20:90, 45:55].all() and m[12, 50] and not m[10, 10] and not m[110, 5]


def test_proxy_rays_meet_the_ground_and_the_wall():
    p = SceneProxy((0.0, 0.0), 10.0)
    o = np.array([[0, 0, 5.0]] * 5)
    d = np.array([[0, 0, -1.0], [1, 0, 0.0], [0, 1, 1.0], [1, 0, -1.0], [1, 0, -0.1]])
    pts, surf = p.intersect(o, d)
    assert list(surf) == [SURFACE_GROUND, SURFACE_WALL, SURFACE_WALL, SURFACE_GROUND, SURFACE_WALL]
    np.testing.assert_allclose(pts[0], [0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(pts[1], [10, 0, 5], atol=1e-9)
    np.testing.assert_allclose(pts[2], [0, 10, 15], atol=1e-9)
    np.testing.assert_allclose(pts[4], [10, 0, 4], atol=1e-9)  # the ground would be met 50 m out: the wall first
    outside = p.intersect(np.array([[20.0, 0, 5]]), np.array([[1.0, 0, 0]]))
    assert outside[1][0] == SURFACE_NONE and np.isnan(outside[0]).all()
    with pytest.raises(InputError, match="radius"):
        SceneProxy((0.0, 0.0), -1.0)


def test_a_view_no_source_stood_at_is_drawn_from_the_others():
    proxy = SceneProxy((0.0, 0.0), 12.0)
    rig = _ring(4)
    model = SceneModel(rig, _backgrounds(rig, proxy), proxy)
    target = _ring(4, start=30.0, height=2.2)[0]
    img, cover, surf = model.render(target, with_surface=True)
    truth = _truth_view(target, proxy)
    seen = cover > 0
    assert seen.mean() > 0.9 and (surf == SURFACE_WALL).any() and (surf == SURFACE_GROUND).any()
    assert np.median(np.abs(img - truth).max(-1)[seen]) < 4.0
    # a source's own view comes back as it is (its own rays weigh most)
    own = model.render(rig[1])[0]
    assert np.median(np.abs(own - _truth_view(rig[1], proxy)).max(-1)) < 1.0
    # one source carried alone: black where it does not see
    carried = model.carry(target, model.nearest_source(target), truth.astype(np.uint8))
    assert carried.shape == truth.shape and (carried.sum(-1) == 0).any()


def test_the_wall_radius_is_found_from_the_sources_agreement():
    rig = _ring(4, pitch_to=1.4)   # looking across the room: the walls fill the upper half of every view
    far = 5.0
    true_radius = far * RADIUS_CANDIDATES[4]
    proxy, evidence = fit_proxy(rig, _backgrounds(rig, SceneProxy((0.0, 0.0), true_radius)))
    assert evidence["chosen_by"] == "agreement"
    assert proxy.radius_m == pytest.approx(true_radius, rel=1e-6), evidence
    assert np.allclose(proxy.centre, (0.0, 0.0), atol=1e-6)


def test_the_model_is_saved_and_loaded_for_the_same_cameras(tmp_path):
    proxy = SceneProxy((0.5, -0.5), 9.0)
    rig = _ring(3)
    model = SceneModel(rig, _backgrounds(rig, proxy), proxy, {"chosen_by": "test"})
    model.save(tmp_path / "scene")
    back = SceneModel.load(tmp_path / "scene", rig)
    assert back.proxy == proxy and back.evidence["chosen_by"] == "test"
    for cam in rig:
        assert np.abs(back.backgrounds[cam.name].image - model.backgrounds[cam.name].image).max() <= 0.5
    with pytest.raises(InputError, match="sources"):
        SceneModel.load(tmp_path / "scene", Rig(rig.cameras[:2]))


def test_a_dataset_whose_keypoints_hold_nobody_still_gets_its_backgrounds(tmp_path):
    """Keypoint files with no person (a detector that found no one): the scene is learnt all the same."""
    from toolkit.io import DatasetWriter, Dataset
    from toolkit.io.openpose import write_openpose_json
    from toolkit.scene import build_scene_model

    rig = _ring(3)
    proxy = SceneProxy((0.0, 0.0), 12.0)
    views = {cam.name: np.clip(_truth_view(cam, proxy), 0, 255).astype(np.uint8) for cam in rig}
    with DatasetWriter(tmp_path / "ds", 25.0) as w:
        w.write_calibration(rig)
        for t in range(4):
            for cam in rig:
                w.write_frame(cam.name, t, views[cam.name])
    for cam in rig:
        for t in range(4):
            write_openpose_json(tmp_path / "ds" / "keypoints" / cam.name / f"{cam.name}_{t:012d}_keypoints.json", [])
    with Dataset.open(tmp_path / "ds") as ds:
        model = build_scene_model(ds, ds.rig, 4)
    assert model.evidence["people_from"] == {c: "keypoints" for c in rig.names}
    err = np.abs(model.backgrounds["cam0"].image - views["cam0"]).max(-1)
    assert np.median(err) < 10.0  # the videos' compression of a fine texture only (max channel)


def test_carrying_into_a_fixed_camera_reuses_its_maps_and_gives_the_same_image():
    proxy = SceneProxy((0.0, 0.0), 12.0)
    rig = _ring(4)
    model = SceneModel(rig, _backgrounds(rig, proxy), proxy)
    target = _ring(4, start=30.0, height=2.2)[0]
    src = model.nearest_source(target)
    rng = np.random.default_rng(2)
    frames = [rng.integers(0, 256, target.size[::-1] + (3,), dtype=np.uint8) for _ in range(2)]
    first = [model.carry(target, src, f) for f in frames]
    assert len(model._carried) == 1  # the maps of (camera, source) made once
    fresh = SceneModel(rig, _backgrounds(rig, proxy), proxy)
    for f, img in zip(frames, first):
        assert np.array_equal(img, fresh.carry(target, src, f))  # the same bits as maps made anew
        fresh._carried.clear()
    for k in range(6):  # other cameras push the oldest maps out: memory stays bounded
        model.carry(_ring(6, start=10.0 * k)[0], src, frames[0])
    assert len(model._carried) <= CARRIES_KEPT


def _reference_render(model: SceneModel, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """The scene model's view drawn as its definition reads: each source's seen pixels gathered and weighted
    one by one (float64), the rays from ``Camera.rays`` (no tables); holes left unfilled."""
    import cv2

    w, h = camera.size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    o, view = camera.rays(np.stack([u, v], -1).reshape(-1, 2))
    pts, surf = model.proxy.intersect(o, view)
    acc, wsum, cover = np.zeros((len(pts), 3)), np.zeros(len(pts)), np.zeros(len(pts), np.float32)
    for cam in model.rig:
        b = model.backgrounds[cam.name]
        pc = cam.to_cam(pts)
        with np.errstate(invalid="ignore", divide="ignore"):
            n = pc[:, :2] / pc[:, 2:3]
        lo, hi = model._frusta[cam.name]
        sees = (pc[:, 2] > 1e-6) & np.all((n >= lo) & (n <= hi), axis=1) & (surf != SURFACE_NONE)
        uv = np.full((len(pts), 2), -1e4, np.float32)
        uv[sees] = cam.project(pts[sees])
        sees &= np.isfinite(uv).all(1) & cam.in_image(uv)
        mx, my = (np.ascontiguousarray(uv[:, k].reshape(h, w)) for k in (0, 1))
        col, conf = (cv2.remap(np.asarray(im, np.float32), mx, my, cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE).reshape(len(pts), -1) for im in (b.image, b.confidence))
        src = pts[sees] - cam.center
        src /= np.linalg.norm(src, axis=1, keepdims=True)
        ang = np.degrees(np.arccos(np.clip((src * view[sees]).sum(1), -1.0, 1.0)))
        wt = conf[sees, 0] / (1.0 + ang / 4.0) ** 2
        acc[sees] += wt[:, None] * col[sees]
        wsum[sees] += wt
        cover[sees] = np.maximum(cover[sees], conf[sees, 0])
    img = np.zeros((len(pts), 3), np.float32)
    ok = wsum > 0
    img[ok] = acc[ok] / wsum[ok, None]
    return img.reshape(h, w, 3), cover.reshape(h, w)


def test_a_view_is_the_same_bits_as_its_definition_and_fixed_cameras_are_prepared_ahead():
    """The per-intrinsics ray tables, the column-wise arithmetic and the in-place weighting give exactly the
    pixels of the gathered, per-source definition (the outputs of a run stay byte for byte the same)."""
    proxy = SceneProxy((0.0, 0.0), 12.0)
    rig = _ring(4)
    model = SceneModel(rig, _backgrounds(rig, proxy), proxy, fill_holes=False)
    path = [_ring(8, start=5.0 * k, height=2.0 + 0.1 * k)[k] for k in range(3)]  # one intrinsics, three poses
    for cam in path:
        img, cover = model.render(cam)
        ref_img, ref_cover = _reference_render(model, cam)
        assert np.array_equal(img, ref_img) and np.array_equal(cover, ref_cover)
    assert len(model._rays) == 1  # the path's views shared one ray table
    fixed = _ring(4, start=30.0, height=2.2)[0]
    model.prepare([fixed])
    kept = model.render(fixed)
    assert kept is model.render(fixed) and len(model._carried) == 1  # drawn once, its carry maps made ahead
    assert np.array_equal(kept[0], _reference_render(model, fixed)[0])


def test_views_of_fixed_cameras_are_drawn_once_for_every_process(tmp_path, monkeypatch):
    """share_views: the first process draws each view into the run's store, another reads the same values
    without drawing, and a model of other backgrounds does not take them."""
    from toolkit.io import shared_store

    proxy = SceneProxy(ground_z=0.0, centre=(0.0, 0.0), radius_m=9.0)
    rig = _ring(3)
    views = list(_ring(2, radius=4.0, start=30.0))
    store = tmp_path / ".views"
    first = SceneModel(rig, _backgrounds(rig, proxy), proxy)
    assert first.share_views(views, store) == 2
    assert sorted(p.suffix for p in store.iterdir()) == [".npz", ".npz"]  # no claim left
    second = SceneModel(rig, _backgrounds(rig, proxy), proxy)
    assert second.share_views(views, store) == 0  # nothing left to draw
    alone = SceneModel(rig, _backgrounds(rig, proxy), proxy)
    drew = []
    monkeypatch.setattr(second, "_geometry", lambda cam: drew.append(cam) or alone._geometry(cam))
    for cam in views:
        img, cov = second.render(cam)
        want = alone.render(cam)
        assert img.tobytes() == want[0].tobytes() and cov.tobytes() == want[1].tobytes()
        assert not img.flags.writeable
    assert not drew  # read from the store, not drawn
    other = _backgrounds(rig, proxy)
    other["cam0"] = SourceBackground(other["cam0"].image * 0.5, other["cam0"].confidence, 1)
    assert SceneModel(rig, other, proxy).share_views(views, store) == 2  # another model: its own views
    # a view another process is drawing is waited for, then drawn here when its claim goes stale
    third = SceneModel(rig, _backgrounds(rig, proxy), proxy)
    cam = list(_ring(1, radius=3.0, start=75.0))[0]
    third.share_views([], store)
    key = third._shared.setdefault(__import__("toolkit.scene.model", fromlist=["_key"])._key(cam),
                                   "claimed-by-another")
    (store / f"{key}.claim").touch()
    monkeypatch.setattr(shared_store, "CLAIM_STALE_S", 0.3)
    import time

    t0 = time.monotonic()
    img, _ = third.render(cam)
    assert time.monotonic() - t0 >= 0.25
    assert img.tobytes() == alone.render(cam)[0].tobytes()
