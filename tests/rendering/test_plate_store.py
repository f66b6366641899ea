"""Background plates shared by the processes of a run through a store (issue 20: drawn once per run)."""

import os
import time

import numpy as np

from toolkit.io import shared_store
from toolkit.rendering.evaluation import BackgroundPlates


def _fixed_cameras(studio):
    return list(studio.novel_rig)[:1] + [studio.gt_rig[0]]


def test_plates_drawn_once_and_read_by_another_process(studio, tmp_path):
    store = tmp_path / ".plates"
    cams = _fixed_cameras(studio)
    first = BackgroundPlates(studio.root / "scene.toml", store=store)
    assert first.share(cams) == len(cams)
    assert sorted(p.suffix for p in store.iterdir()) == [".npz"] * len(cams)  # no claim left behind
    second = BackgroundPlates(studio.root / "scene.toml", store=store)
    assert second.share(cams) == 0  # nothing left to draw
    drawn = BackgroundPlates(studio.root / "scene.toml")  # no store: drawn here
    for cam in cams:
        got = second.plate(cam)
        assert got.dtype == np.float32 and not got.flags.writeable
        assert got.tobytes() == drawn.plate(cam).tobytes()  # the same values as drawing it


def test_a_claimed_plate_is_left_to_its_claimer_and_a_stale_claim_is_taken(studio, tmp_path, monkeypatch):
    store = tmp_path / ".plates"
    store.mkdir()
    cam = _fixed_cameras(studio)[0]
    plates = BackgroundPlates(studio.root / "scene.toml", store=store)
    claim = plates._path(cam).with_suffix(".claim")
    claim.touch()  # another process draws it now
    assert plates.share([cam]) == 0 and not plates._path(cam).exists()
    old = time.time() - 2 * shared_store.CLAIM_STALE_S
    os.utime(claim, (old, old))  # ... and was killed long ago
    assert plates.share([cam]) == 1 and plates._path(cam).exists() and not claim.exists()


def test_waiting_for_a_plate_another_process_draws(studio, tmp_path, monkeypatch):
    store = tmp_path / ".plates"
    store.mkdir()
    cam = _fixed_cameras(studio)[0]
    plates = BackgroundPlates(studio.root / "scene.toml", store=store)
    claim = plates._path(cam).with_suffix(".claim")
    claim.touch()
    monkeypatch.setattr(shared_store, "CLAIM_STALE_S", 0.3)  # the claimer never finishes: drawn here after that
    t0 = time.monotonic()
    got = plates.plate(cam)
    assert 0.25 <= time.monotonic() - t0
    assert got.tobytes() == BackgroundPlates(studio.root / "scene.toml").plate(cam).tobytes()


def test_the_store_depends_on_the_scene(studio, tmp_path):
    store = tmp_path / ".plates"
    cam = _fixed_cameras(studio)[0]
    a = BackgroundPlates(studio.root / "scene.toml", store=store)
    b = BackgroundPlates(studio.root / "scene.toml", store=store)
    b._scene_digest = "another scene"
    assert a._path(cam) != b._path(cam)
    assert a._path(cam) != a._path(_fixed_cameras(studio)[1])
