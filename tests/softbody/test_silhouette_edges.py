"""Silhouette outlines moved onto the image's edge (toolkit.softbody.silhouette.edge_offset).

Masks found by background subtraction are fatter than the subject: on the trinocular
benchmark the clean-plate masks' outline lay 1.5 px outside the image's edge and the
outline rays stretched the fitted body (head high, ankles low).  With the image given,
the view measures the offset and moves its outline onto the edge.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from tests.softbody.test_silhouette import posed, ring
from toolkit.errors import InputError
from toolkit.softbody import SoftBodyModel
from toolkit.softbody.silhouette import SilhouetteConfig, SilhouetteView, model_mask


def picture(mask: np.ndarray, contrast: float = 150.0) -> np.ndarray:
    """An RGB image of a bright subject (``mask``) on a darker, textured background, blurred like a video."""
    rng = np.random.default_rng(3)
    img = 40.0 + rng.normal(0, 3, mask.shape + (3,)) + contrast * mask[..., None]
    return np.clip(cv2.GaussianBlur(img, (5, 5), 1.0), 0, 255).astype(np.uint8)


def grow(mask: np.ndarray, px: int) -> np.ndarray:
    return cv2.dilate(mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * px + 1,) * 2)) > 0


@pytest.fixture(scope="module")
def scene():
    model = SoftBodyModel()
    p = posed(model)
    cam = ring(p.vector[3:6], 1, size=(320, 240))[0]
    return model, p, cam, model_mask(model, p, cam)


def ray_miss_px(model, p, view) -> float:
    """Median of the outline rays' miss of the model (pixels at the subject; + outside the model)."""
    from toolkit.softbody.silhouette import ray_minimum

    s, r = ray_minimum(model, p, view.origins, view.directions)
    return float(np.median(r / s * view.focal))


@pytest.mark.parametrize("fat", [0, 2])
def test_the_outline_goes_onto_the_images_edge(scene, fat):
    model, p, cam, mask = scene
    img = picture(mask)
    m = grow(mask, fat) if fat else mask
    plain = SilhouetteView(cam, m)
    moved = SilhouetteView(cam, m, image=img)
    assert moved.edge_offset_px == pytest.approx(-fat, abs=0.6)
    assert ray_miss_px(model, p, plain) == pytest.approx(fat, abs=0.6)  # the fat mask's rays miss the body
    assert abs(ray_miss_px(model, p, moved)) < 0.6                       # moved onto the edge: they graze it


def test_no_clear_edge_leaves_the_outline(scene):
    model, p, cam, mask = scene
    flat = picture(mask, contrast=0.0)  # the subject does not stand out: no edge to go by
    v = SilhouetteView(cam, grow(mask, 2), image=flat)
    assert v.edge_offset_px == 0.0
    off = SilhouetteView(cam, grow(mask, 2), SilhouetteConfig(edge_search_px=0.0), image=picture(mask))
    assert off.edge_offset_px == 0.0


def test_an_image_of_another_size_is_refused(scene):
    _, _, cam, mask = scene
    with pytest.raises(InputError, match="silhouette image"):
        SilhouetteView(cam, mask, image=np.zeros((10, 10, 3), np.uint8))


def test_an_offset_measured_once_moves_the_outline_alike(scene):
    """Sources measure the offset when they find the mask (mask_edge_offset) and keep only the number."""
    from toolkit.softbody.silhouette import mask_edge_offset, silhouette_views

    _, _, cam, mask = scene
    fat, img = grow(mask, 2), picture(mask)
    off = mask_edge_offset(img, fat)
    measured = SilhouetteView(cam, fat, image=img)
    given, = silhouette_views([cam], [fat], edge_offsets=[off])
    assert off == measured.edge_offset_px == given.edge_offset_px
    np.testing.assert_array_equal(given.outline, measured.outline)
    assert mask_edge_offset(img, np.zeros_like(fat)) == 0.0
    with pytest.raises(InputError, match="edge offset"):
        SilhouetteView(cam, fat, edge_offset_px=float("nan"))
