"""The soft body's trunk metaballs against the rendered bodies' surface (issue 18).

The model posed on a :class:`toolkit.body.BodyModel` mesh's own joints with the
true lengths and girth: the mesh's vertices should lie on the model's surface.
The layout before session 11 left the waist 20 mm and the top of the chest
17 mm too thin (median signed distance in those height bands), which the global
fit paid for by raising the pelvis 30-96 mm on noiseless points of the true body.
Bodies of seed 3000: not those the layout was calibrated on (2000, 2200, 2400).
"""

from __future__ import annotations

import pytest

from benchmarks.calibrate_softbody_layout import cases, signed_distances, summary


@pytest.fixture(scope="module")
def bias():
    cs = cases([3000], frames=(0,), every=3)
    return summary(cs, signed_distances(cs))


def test_trunk_and_thighs_lie_on_the_true_surface(bias):
    assert abs(bias["torso"][0]) < 4 and bias["torso"][1] < 12  # median, mean |d| mm (old layout: 13.9)
    for side in ("l", "r"):
        assert abs(bias[f"{side}_thigh"][0]) < 4 and bias[f"{side}_thigh"][1] < 13  # old: 16.9


def test_no_thin_waist_or_chest(bias):
    # old layout: +19.5 mm (waist, 0.1-0.2 m above the mid-hip) and +17.4 mm (upper chest, 0.6-0.7 m)
    for band in ("torso z +0.1..+0.2 m", "torso z +0.2..+0.3 m", "torso z +0.5..+0.6 m", "torso z +0.6..+0.7 m"):
        assert abs(bias[band][0]) < 8, (band, bias[band])
