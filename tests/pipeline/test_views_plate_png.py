"""A novel camera's plate is encoded once per run and written as the same bytes every frame (issue 20)."""

from __future__ import annotations

import numpy as np

import toolkit.io as tio
from toolkit.pipeline import views


def test_plate_png_encoded_once_while_the_plate_is_the_same(monkeypatch):
    calls = []
    encode = tio.encode_png
    monkeypatch.setattr(tio, "encode_png", lambda img, *a, **k: calls.append(1) or encode(img, *a, **k))
    monkeypatch.setattr(views, "_PLATE_PNGS", {})
    plate = np.random.default_rng(1).uniform(0, 255, (6, 8, 3)).astype(np.float32)
    plate.flags.writeable = False
    want = encode(np.clip(plate + 0.5, 0, 255).astype(np.uint8))
    assert views._plate_png("novel00", plate) == want and views._plate_png("novel00", plate) == want
    assert len(calls) == 1
    other = plate.copy()  # writeable (e.g. a held-out view's background made per frame): every time
    assert views._plate_png("novel00", other) == want and views._plate_png("novel00", other) == want
    assert len(calls) == 3
