"""Spatial prior and colour evidence of the ``posterior`` rule, and the spatial anchor setting."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.segmentation import (
    SegmentationConfig,
    colour_confusion,
    colour_evidence,
    confusion_evidence,
    segment_frame,
    smooth_evidence,
    spatial_log_prior,
    template_distances,
)
from toolkit.template import Template

#: distanceTransform with a 5x5 mask is exact to 2 % on straight distances.
DISTANCE_RTOL = 0.02


def test_template_distances_are_pixel_distances():
    L = np.zeros((20, 30), np.uint8)
    L[5:10, 2:6] = 1
    D = template_distances(L, 3)
    assert D.shape == (20, 30, 3)
    assert (D[5:10, 2:6, 0] == 0).all()
    np.testing.assert_allclose(D[7, 16, 0], 11.0, rtol=DISTANCE_RTOL)  # 11 columns right of the block
    assert np.isinf(D[..., 1]).all() and np.isinf(D[..., 2]).all()  # parts not shown


def test_colour_evidence_is_clipped_ratio():
    ll = np.array([[-1.0, -3.0, -np.inf], [-50.0, -2.0, -4.0]])
    e = colour_evidence(ll, 5.0)
    np.testing.assert_allclose(e, [[0.0, -2.0, -5.0], [-5.0, 0.0, -2.0]])


def test_confusion_gives_no_evidence_between_parts_of_one_colour():
    # parts 1 and 2 share a colour (their pixels' best model is either), part 3 is apart
    ll_conf = np.array([[0, -1, -50]] * 50 + [[-1, 0, -50]] * 50 + [[0, -1, -50]] * 50 + [[-1, 0, -50]] * 50
                       + [[-50, -50, 0]] * 100, float)
    labels = np.array([1] * 100 + [2] * 100 + [3] * 100)
    C = colour_confusion(ll_conf, labels, 3)
    np.testing.assert_allclose(C.sum(1), 1.0)
    e = confusion_evidence(np.array([[0.0, -1.0, -50.0]]), C)[0]  # a pixel coloured like parts 1 and 2
    assert abs(e[0] - e[1]) < 0.05 and e[2] < -3.0


def test_smoothing_and_prior():
    E = np.zeros((9, 9, 2), np.float32)
    E[4, 4, 1] = -9.0
    m = np.ones((9, 9), bool)
    S = smooth_evidence(E, m, 1.0)
    assert -9.0 < S[4, 4, 1] < 0 and S[0, 0, 1] > -1e-3
    np.testing.assert_allclose(spatial_log_prior(np.array([0.0, 2.0]), 2.0), [0.0, -0.5])
    with pytest.raises(InputError, match="sigma_px"):
        spatial_log_prior(np.zeros(2), 0.0)


def test_config_rejects_unknown_anchor_and_evidence():
    with pytest.raises(InputError, match="spatial_anchor"):
        SegmentationConfig(spatial_anchor="skeleton")
    with pytest.raises(InputError, match="colour_evidence"):
        SegmentationConfig(colour_evidence="svm")


@pytest.mark.parametrize("config", [SegmentationConfig(spatial_anchor="confident"),
                                    SegmentationConfig(rule="posterior"),
                                    SegmentationConfig(rule="posterior", colour_evidence="confusion",
                                                       smooth_fraction=0.01, relabel_confident=True)])
def test_every_variant_labels_the_silhouette(frame, config):
    sil = frame.parts > 0
    r = segment_frame(frame.image, sil, frame.joints3d, frame.camera, Template(1.75), config)
    assert (r.labels[sil] > 0).all() and (r.labels[~sil] == 0).all()
