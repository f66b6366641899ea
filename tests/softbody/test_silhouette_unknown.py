"""Pixels a depth camera cannot tell from the background (toolkit.pointcloud.ambiguous_mask) are unknown
to the silhouettes: feet on the floor are left out of the foreground mask (within its margin of the
floor behind them), and the mask block then pushed the model's feet up (depth benchmark, seed 12000:
ankles 14-34 mm high, shanks 14-24 mm short after the global fit)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.softbody.test_silhouette import posed, ring
from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.pointcloud import BackgroundModel, MaskConfig, ambiguous_mask, foreground_mask
from toolkit.softbody import SoftBodyModel
from toolkit.softbody.silhouette import SilhouetteBlock, SilhouetteView, model_mask


def _camera(size=(160, 120)):
    w, h = size
    return Camera("d", [[150.0, 0, (w - 1) / 2], [0, 150.0, (h - 1) / 2], [0, 0, 1]], np.zeros(5), size, np.eye(4))


def test_ambiguous_pixels_lie_between_the_noise_and_the_foreground_margin():
    cam = _camera()
    bg = np.full((120, 160), 3.0, np.float32)
    d = bg.copy()
    d[10:30, 10:30] = 2.5     # 0.5 m in front: foreground
    d[50:70, 10:30] = 2.9     # 0.1 m in front: within the foreground margin (0.08 + 0.02 * 3 = 0.14 m)
    d[90:110, 10:30] = 2.99   # 1 cm: the sensor's noise (margin 0.02 + 0.01 * 3 = 0.05 m)
    d[90:110, 100:120] = np.nan
    b = BackgroundModel(bg)
    fg, amb = foreground_mask(d, cam, background=b), ambiguous_mask(d, cam, background=b)
    assert fg[20, 20] and not amb[20, 20]
    assert amb[60, 20] and not fg[60, 20]
    assert not amb[100, 20] and not amb[100, 110] and not amb[5, 100]
    assert amb.sum() == 400
    assert not ambiguous_mask(d, cam).any()  # no background model: nothing to be ambiguous about
    wide = MaskConfig(ambiguous_margin_m=0.2)  # the band closes when its margin reaches the foreground's
    assert not ambiguous_mask(d, cam, background=b, config=wide).any()
    with pytest.raises(InputError, match="background"):
        ambiguous_mask(d, cam, background=BackgroundModel(bg[:10]))


@pytest.fixture(scope="module")
def feet_cut():
    """The model's own mask without its lowest rows (the feet on the floor), those rows unknown."""
    model = SoftBodyModel()
    p = posed(model)
    cam = ring(p.vector[3:6], 1, size=(320, 240))[0]
    full = model_mask(model, p, cam)
    rows = np.nonzero(full.any(axis=1))[0]
    cut = full.copy()
    cut[rows[-1] - 8:] = False
    unknown = full & ~cut
    return model, p, cam, cut, unknown


def test_unknown_pixels_cost_nothing(feet_cut):
    model, p, cam, cut, unknown = feet_cut
    cols = np.arange(47)
    for u, expect_cost in ((None, True), (unknown, False)):
        v = SilhouetteView(cam, cut, unknown=u)
        blk = SilhouetteBlock(model, p, [v])
        r, _ = blk.residuals(p, model.state(p), cols)
        mask_r, ray_r = r[blk.n_rays:], r[:blk.n_rays]
        assert (np.abs(mask_r).max() > 1e-3) == expect_cost  # the feet's surface points project outside the mask
        # the cut's straight edge is not the body's: its rays cut through the feet (1-3 cm) unless left out
        assert (np.sum(ray_r < -0.01) > 2) == expect_cost


def test_unknown_of_another_size_is_refused(feet_cut):
    _, _, cam, cut, _ = feet_cut
    with pytest.raises(InputError, match="unknown pixels"):
        SilhouetteView(cam, cut, unknown=np.zeros((5, 5), bool))
