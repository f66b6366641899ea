"""The silhouette's border checked against the background plate (toolkit.segmentation.plate)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from tests.segmentation.conftest import make_frame
from toolkit.errors import InputError
from toolkit.segmentation import SegmentationConfig, part_iou, segment_frame
from toolkit.synthetic.environment import GRASS_RGB
from toolkit.template import Template

#: A silhouette dilated by 2 px (24 % of the true area wrong on the fixture frame, seed 4) is brought
#: back to 0.9 % wrong with the exact plate; over seeds 4-7: 0.9-3.9 %, mean part IoU +0.14 to +0.21.
REFINED_ERROR_BOUND = 0.03
MIOU_GAIN_BOUND = 0.10
#: On a kit like the backdrop the border cannot be judged: the silhouette must not be eaten.
LOW_CONTRAST_KEPT = 0.95


@pytest.fixture(scope="module")
def template():
    return Template(1.75)


def test_plate_brings_a_dilated_silhouette_back(frame, template):
    truth = frame.parts > 0
    sil = cv2.dilate(truth.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))) > 0
    r0 = segment_frame(frame.image, sil, frame.joints3d, frame.camera, template)
    r1 = segment_frame(frame.image, sil, frame.joints3d, frame.camera, template, plate=frame.plate)
    refined = r1.labels > 0
    assert (refined ^ truth).sum() / truth.sum() <= REFINED_ERROR_BOUND
    gain = np.nanmean(part_iou(r1.labels, frame.parts)) - np.nanmean(part_iou(r0.labels, frame.parts))
    assert gain >= MIOU_GAIN_BOUND


def test_plate_keeps_a_low_contrast_kit(template):
    f = make_frame(1, size=(320, 240), distance=5.0, motion="walk", t=12, kit=GRASS_RGB)
    truth = f.parts > 0
    r = segment_frame(f.image, truth, f.joints3d, f.camera, template, plate=f.plate)
    assert ((r.labels > 0) & truth).sum() >= LOW_CONTRAST_KEPT * truth.sum()


def test_plate_must_match_the_image(frame, template):
    with pytest.raises(InputError, match="plate"):
        segment_frame(frame.image, frame.parts > 0, frame.joints3d, frame.camera, template,
                      SegmentationConfig(), plate=frame.plate[:10])


#: A band across the torso (shirt like the grass) cut out of the silhouette: stage 1's loss on such kits.
#: Measured (seed 1): the template fills 0.934 of it back (seeds 0-5: 0.88-0.95; without the template
#: fill 0), no false pixels.
BAND_RECOVERED = 0.80
BAND_FALSE = 0.02


def test_plate_template_fills_a_low_contrast_hole(template):
    f = make_frame(1, size=(320, 240), distance=5.0, motion="walk", t=12, kit=GRASS_RGB)
    truth = f.parts > 0
    ys = np.nonzero(f.parts == 2)[0]
    band = (f.parts == 2) & (np.arange(truth.shape[0])[:, None] >= np.percentile(ys, 30)) \
        & (np.arange(truth.shape[0])[:, None] <= np.percentile(ys, 60))
    r = segment_frame(f.image, truth & ~band, f.joints3d, f.camera, template, plate=f.plate)
    refined = r.labels > 0
    assert (refined & band).sum() >= BAND_RECOVERED * band.sum()
    assert (refined & ~truth).sum() <= BAND_FALSE * truth.sum()
