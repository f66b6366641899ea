"""Robust local surface patches (issue 18): centres on the surface, injected outliers dropped."""

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.pointcloud.patches import PatchConfig, surface_patches


def _sphere(rng, n, r=0.3, noise=0.003):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * (r + rng.normal(0, noise, (n, 1))) + [0.0, 0.0, 1.0]


def test_patches_keep_the_surface_and_drop_outliers():
    rng = np.random.default_rng(0)
    surface = _sphere(rng, 20000)
    outliers = rng.uniform([-1, -1, 0], [1, 1, 2], (4000, 3))  # 17 % of the cloud, scattered
    clump = rng.normal([0.0, 0.0, 1.5], 0.02, (12, 3))  # a small blob off the surface (a spurious match)
    p = surface_patches(np.concatenate([surface, outliers, clump]), PatchConfig(patch_m=0.05))
    off = np.abs(np.linalg.norm(p.centres - [0, 0, 1], axis=1) - 0.3)
    assert len(p) > 150
    assert off.max() < 0.02  # no patch from the outliers or the blob
    assert np.median(off) < 0.003  # centres on the surface (the mean of a cell lies slightly inside a sphere)
    assert p.n_isolated + p.n_rejected >= 0.9 * len(outliers)
    radial = (p.centres - [0, 0, 1]) / np.linalg.norm(p.centres - [0, 0, 1], axis=1, keepdims=True)
    assert np.median(np.abs((p.normals * radial).sum(1))) > 0.98  # planes tangent to the sphere
    assert p.n_input == len(surface) + len(outliers) + len(clump)


def test_without_outlier_removal_the_flatness_test_rejects_a_volume_of_points():
    rng = np.random.default_rng(1)
    surface = _sphere(rng, 20000)
    thick = rng.normal([0.6, 0.0, 1.0], 0.05, (3000, 3))  # a volume of points, not a surface
    p = surface_patches(np.concatenate([surface, thick]), PatchConfig(patch_m=0.05, min_points=6, sor_neighbours=0, max_residual_m=0.008))
    far = np.linalg.norm(p.centres - [0.6, 0.0, 1.0], axis=1) < 0.12
    assert far.sum() <= 2
    assert len(p) > 150


@pytest.mark.parametrize("pts", [np.zeros((0, 3)), np.zeros((2, 3)), np.full((5, 3), np.nan)])
def test_empty_and_tiny_clouds_give_no_patch(pts):
    p = surface_patches(pts)
    assert len(p) == 0 and p.centres.shape == (0, 3)


def test_bad_input_is_named():
    with pytest.raises(InputError, match="points"):
        surface_patches(np.zeros((4, 2)))
    with pytest.raises(InputError, match="patch_m"):
        PatchConfig(patch_m=0.0)


def test_the_patch_scale_follows_a_noisy_cloud():
    """A far person's depth points (noise growing with the square of the distance): at the fixed 2.5 cm
    scale almost nothing is a patch; the scale doubles until the patches hold the cloud, and their centres
    still lie on the surface.  A clean cloud keeps the fixed scale (the same patches)."""
    from toolkit.pointcloud.patches import PatchConfig, surface_patches

    rng = np.random.default_rng(7)
    # the front half of a 0.15 m cylinder, 1 m tall, 1.5 cm spacing, 20 mm of noise along the view (y)
    a, z = np.meshgrid(np.arange(0.1, np.pi - 0.1, 0.015 / 0.15), np.arange(0.0, 1.0, 0.015))
    clean = np.c_[0.15 * np.cos(a.ravel()), -0.15 * np.sin(a.ravel()), z.ravel()]
    noisy = clean.copy()
    noisy[:, 1] += rng.normal(0, 0.02, len(clean))
    fixed = surface_patches(noisy, PatchConfig(max_doublings=0))
    assert fixed.support.sum() < 0.1 * len(noisy)  # measured 3 %
    adapted = surface_patches(noisy)
    assert adapted.support.sum() >= 0.3 * len(noisy) and len(adapted.centres) >= 50  # 41 %, 111
    r = np.hypot(adapted.centres[:, 0], adapted.centres[:, 1])
    assert np.median(np.abs(r - 0.15)) < 0.012  # 5.8 mm
    same = surface_patches(clean), surface_patches(clean, PatchConfig(max_doublings=0))
    np.testing.assert_array_equal(same[0].centres, same[1].centres)


def test_bad_scale_options_are_named():
    from toolkit.errors import InputError
    from toolkit.pointcloud.patches import PatchConfig

    with pytest.raises(InputError, match="min_coverage"):
        PatchConfig(min_coverage=1.5)
    with pytest.raises(InputError, match="max_doublings"):
        PatchConfig(max_doublings=-1)
