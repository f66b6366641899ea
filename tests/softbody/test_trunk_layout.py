"""The soft body's metaballs against the rendered bodies' surface (issue 18).

The model posed on a :class:`toolkit.body.BodyModel` mesh's own joints with the
true lengths and girth: the mesh's vertices should lie on the model's surface.
The layout before 80bd066 left the waist 20 mm and the top of the chest
17 mm too thin (median signed distance in those height bands), which the global
fit paid for by raising the pelvis 30-96 mm on noiseless points of the true body.
About 40 % of the mesh's vertices are buried inside another of its volumes (no
camera sees them); they make the neck and the upper arms look too fat (head
mean |d| 21 mm, upper arms 16 mm over all vertices; 5 and 2 mm on the outer
surface).  The layout of 80bd066, fitted to every vertex, left the band
0-0.1 m above the mid-hip 20 mm too thin on the outer surface; the current
layout (0508e32) is calibrated on the outer surface (``calibrate_softbody_layout --fit
--groups trunk head arms``).
Bodies of seed 3000: not those the layout was calibrated on (2000, 2200, 2400).
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.calibrate_softbody_layout import cases, signed_distances, summary


@pytest.fixture(scope="module")
def measured():
    cs = cases([3000], frames=(0,), every=3)
    return cs, signed_distances(cs)


@pytest.fixture(scope="module")
def bias(measured):
    return summary(*measured)


@pytest.fixture(scope="module")
def outer(measured):
    return summary(*measured, outer=True)


def test_trunk_and_thighs_lie_on_the_true_surface(bias, outer):
    assert abs(bias["torso"][0]) < 4 and bias["torso"][1] < 12  # median, mean |d| mm (before 80bd066: 14.6)
    # the thighs' buried vertices (their hip caps inside the trunk) read as "too fat" once the trunk's outer
    # surface is filled (all vertices: 20.6 mm): the outer surface only
    for side in ("l", "r"):
        assert abs(outer[f"{side}_thigh"][0]) < 4 and outer[f"{side}_thigh"][1] < 5


def test_no_thin_waist_or_chest(bias):
    # old layout: +19.5 mm (waist, 0.1-0.2 m above the mid-hip) and +17.4 mm (upper chest, 0.6-0.7 m)
    for band in ("torso z +0.1..+0.2 m", "torso z +0.2..+0.3 m", "torso z +0.5..+0.6 m", "torso z +0.6..+0.7 m"):
        assert abs(bias[band][0]) < 8, (band, bias[band])


def test_buried_vertices_read_as_a_fat_neck_and_arms(measured, bias, outer):
    # whatever the layout: the all-vertex head and upper-arm figures are the buried vertices'
    cs, _ = measured
    assert 0.25 < 1 - sum(c[5].sum() for c in cs) / sum(len(c[5]) for c in cs) < 0.55
    assert bias["head"][1] > 2 * outer["head"][1] and bias["l_upper_arm"][1] > 4 * outer["l_upper_arm"][1]
    assert outer["head"][1] < 6 and outer["l_upper_arm"][1] < 3 and outer["r_upper_arm"][1] < 3


def test_no_thin_band_just_above_the_hips(outer):
    # 80bd066: +20.1 mm median, 21.2 mean |d|; 0508e32: -0.5, 1.4
    band = outer["torso z +0.0..+0.1 m"]
    assert abs(band[0]) < 8 and band[1] < 8, band


def test_trunk_lies_on_the_outer_surface(outer):
    assert abs(outer["torso"][0]) < 3 and outer["torso"][1] < 4  # 80bd066: +1.8, 7.4 mm; 0508e32: -0.2, 2.5


def test_head_and_neck_lie_on_the_outer_surface(outer):
    # 80bd066: median -2.1 mm (the neck ball too fat); 0508e32: -0.4
    assert abs(outer["head"][0]) < 1.5 and outer["head"][1] < 5.5, outer["head"]


def test_arms_lie_on_the_outer_surface(outer):
    # 80bd066: upper arms median +0.8, mean |d| 2.1 mm, forearms 2.0-2.1; 0508e32: 0.0, 1.2, 1.4
    for side in ("l", "r"):
        for part in ("upper_arm", "forearm"):
            med, mad, _ = outer[f"{side}_{part}"]
            assert abs(med) < 0.5 and mad < 1.7, (side, part, med, mad)


def test_layout_change_touches_only_its_group(measured):
    # calibrate_softbody_layout --fit: a change of one key moves only its primitives, the identity none
    from benchmarks.calibrate_softbody_layout import group_keys

    cs, ds = measured
    keys = group_keys(["arms"])
    x = np.tile([1.0, 1.0, 1.0, 0.0], len(keys))
    assert all(np.allclose(a, b) for a, b in zip(signed_distances(cs[:1], x, keys), ds[:1]))
    i = keys.index("upper_arm:1")
    x[4 * i:4 * i + 2] = 1.3  # the middle upper-arm balls 30 % thicker
    moved = np.abs(signed_distances(cs[:1], x, keys)[0] - ds[0])
    part = cs[0][3]  # 1 head, 2 torso, 3 l_upper_arm, 5 r_upper_arm
    assert np.percentile(moved[(part == 3) | (part == 5)], 95) > 5e-3 and np.median(moved[part <= 2]) < 1e-6
    assert set(keys) == {"upper_arm:0", "upper_arm:1", "upper_arm:2", "forearm:0", "forearm:1", "forearm:2",
                         "forearm:3"}
