"""The cheap test in front of the people search (``toolkit.pipeline.people._several_blobs``)."""

import numpy as np

from toolkit.pipeline.people import _several_blobs


def _mask(*columns, size=(120, 160)):
    m = np.zeros(size, bool)
    for x0, x1 in columns:
        m[20:100, x0:x1] = True
    return m


def test_two_people_apart_in_one_camera_and_overlapping_in_the_other_are_several():
    apart, overlapping = _mask((20, 40), (90, 110)), _mask((60, 95))
    assert _several_blobs([apart, overlapping])
    assert _several_blobs([None, apart])


def test_one_person_and_specks_are_one():
    person = _mask((60, 80))
    specks = person.copy()
    specks[5:8, 5:8] = True                   # under min_px
    small = _mask((60, 80))
    small[100:110, 130:135] = True            # 50 px, far under 30 % of the person
    assert not _several_blobs([person, specks, small, None])
