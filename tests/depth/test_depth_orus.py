"""The orthographic user grid, curvature centres and osculating spheres, the radial profile."""

from __future__ import annotations

import numpy as np
import pytest
from tests.depth.conftest import make_sequence

from toolkit.pointcloud.cloud import ViewFrame, user_cloud
from toolkit.depth.curvature import CONCAVE, CONVEX, PLANAR, curvature_centres
from toolkit.pointcloud.normals import normal_map
from toolkit.depth.orus import ORUS_BIN_SIZE_M, OrusConfig, build_orus
from toolkit.depth.radial import radial_profile
from toolkit.errors import InputError

#: Curvature centres of a cylinder of radius 6 cm lie on its axis within this (bins of 2 cm).
AXIS_TOLERANCE_M = 0.015
#: Their radius is within this fraction of the true radius.
RADIUS_TOLERANCE = 0.3
#: Occupancy of the same person in grids built from 320 x 240 and 640 x 480 depth.
MIN_RESOLUTION_IOU = 0.85


def _surface(fn, xs, ys):
    """Points and outward normals of z = fn(x, y) sampled on a grid (front surface seen from -z)."""
    X, Y = np.meshgrid(xs, ys)
    Z, dzdx, dzdy = fn(X, Y)
    P = np.stack([X, Y, Z], -1).reshape(-1, 3)
    N = np.stack([dzdx, dzdy, -np.ones_like(Z)], -1).reshape(-1, 3)
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    ok = np.all(np.isfinite(P), axis=1)
    return P[ok], N[ok]


def test_grid_of_a_plane():
    P, _ = _surface(lambda X, Y: (2.0 + 0 * X, 0 * X, 0 * X), np.arange(-0.3, 0.3, 0.004), np.arange(-0.5, 0.5, 0.004))
    g = build_orus(P, [0.0, 0.0], OrusConfig())
    assert g.shape == OrusConfig().shape == (52, 52)
    assert g.bin_size == ORUS_BIN_SIZE_M
    occ = g.occupied
    assert occ.sum() == pytest.approx((0.6 / 0.05) * (1.0 / 0.05), abs=25)
    np.testing.assert_allclose(g.mean[occ][:, 2], 2.0)
    np.testing.assert_allclose(g.zmin[occ], 2.0)
    inner = occ & (np.roll(occ, 1, 0) & np.roll(occ, -1, 0) & np.roll(occ, 1, 1) & np.roll(occ, -1, 1))
    np.testing.assert_allclose(g.normal[inner], np.tile([0, 0, -1.0], (inner.sum(), 1)), atol=1e-9)
    # each bin's mean lies inside the bin
    b = g.to_bin(g.mean[occ])
    r, c = np.nonzero(occ)
    assert np.all(np.abs(b[:, 0] - c) <= 0.5 + 1e-9) and np.all(np.abs(b[:, 1] - r) <= 0.5 + 1e-9)
    assert g.n_points == len(P) and g.n_outside == 0


def test_empty_bins_are_filled_from_neighbours():
    P, _ = _surface(lambda X, Y: (2.0 + 0.1 * X, 0 * X, 0 * X), np.arange(-0.3, 0.3, 0.005),
                    np.arange(-0.3, 0.3, 0.005))
    keep = ~((np.abs(P[:, 0] - 0.025) < 0.025) & (np.abs(P[:, 1] - 0.025) < 0.025))   # a one-bin hole
    g = build_orus(P[keep], [0.0, 0.0])
    hole = g.filled & ~g.occupied
    assert hole.sum() >= 1
    i, j = np.argwhere(hole)[0]
    x, y, z = g.mean[i, j]
    assert abs(x - 0.025) < 0.005 and abs(y - 0.025) < 0.005      # the mean of the neighbours' means ...
    assert z == pytest.approx(2.0 + 0.1 * x, abs=1e-6)            # ... lies on the plane (float32 sums)
    assert g.count[i, j] == 0


def test_config_is_checked():
    with pytest.raises(InputError, match="bin_size"):
        OrusConfig(bin_size_m=2.0)
    assert OrusConfig(bin_size_m=0.1).shape == (26, 26)


def test_grid_does_not_depend_on_the_depth_resolution():
    grids = []
    for res in ((320, 240), (640, 480)):
        seq, _, _ = make_sequence("idle", 1, seed=7, resolution=res, environment="none")
        vf = ViewFrame.from_camera(seq.camera)
        cloud = user_cloud(seq.depth[0], seq.subject[0] == 1, vf)
        grids.append((build_orus(cloud.points, cloud.centroid), cloud.n_points))
    (g1, n1), (g2, n2) = grids
    assert g1.shape == g2.shape and n2 > 3 * n1          # 4x the points ...
    iou = (g1.occupied & g2.occupied).sum() / (g1.occupied | g2.occupied).sum()
    assert iou > MIN_RESOLUTION_IOU                       # ... the same grid


def test_cylinder_gives_convex_spheres_on_its_axis():
    r, zc = 0.06, 2.0

    def cyl(X, Y):
        s = np.sqrt(np.maximum(r * r - X * X, 0))
        Z = np.where(np.abs(X) < r, zc - s, np.nan)
        return Z, X / np.where(s > 1e-6, s, np.nan), 0 * X

    P, N = _surface(cyl, np.arange(-0.0595, 0.0595, 0.002), np.arange(-0.4, 0.4, 0.004))
    g = build_orus(P, [0.0, 0.0], OrusConfig(bin_size_m=0.02, normal_source="pixels"), N)
    cr = curvature_centres(g)
    lab = cr.label[g.filled]
    assert (lab == CONVEX).mean() > 0.8
    sp = cr.spheres
    assert len(sp) > 10
    np.testing.assert_allclose(sp.centres[:, 0], 0.0, atol=AXIS_TOLERANCE_M)
    np.testing.assert_allclose(sp.centres[:, 2], zc, atol=AXIS_TOLERANCE_M)
    assert abs(np.median(sp.radii) - r) < RADIUS_TOLERANCE * r


def test_plane_is_planar_and_trough_is_concave():
    P, N = _surface(lambda X, Y: (2.0 + 0.2 * Y, 0 * X, 0.2 + 0 * X), np.arange(-0.3, 0.3, 0.005),
                    np.arange(-0.3, 0.3, 0.005))
    cr = curvature_centres(build_orus(P, [0, 0], OrusConfig(normal_source="pixels"), N))
    assert np.all(cr.label[cr.label > 0] == PLANAR) and len(cr.spheres) == 0
    R = 0.08                                         # the inside of a pipe, seen from its open side

    def trough(X, Y):
        s = np.sqrt(np.maximum(R * R - X * X, 0))
        Z = np.where(np.abs(X) < R, 2.0 + s, np.nan)
        return Z, -X / np.where(s > 1e-6, s, np.nan), 0 * X

    P, N = _surface(trough, np.arange(-0.075, 0.075, 0.002), np.arange(-0.3, 0.3, 0.004))
    cr = curvature_centres(build_orus(P, [0, 0], OrusConfig(bin_size_m=0.02, normal_source="pixels"), N))
    inner = cr.label[cr.label > 0]
    assert (inner == CONCAVE).mean() > 0.7


def test_curvature_of_a_rendered_person(idle_sequence):
    seq = idle_sequence
    vf = ViewFrame.from_camera(seq.camera)
    m = seq.subject[0] == 1
    cloud = user_cloud(seq.depth[0], m, vf, normal_map(seq.depth[0], seq.camera, m))
    g = build_orus(cloud.points, cloud.centroid, OrusConfig(normal_source="pixels"), cloud.normals)
    cr = curvature_centres(g)
    assert len(cr.spheres) > 10
    # sphere centres lie inside the body: behind the visible surface
    b = np.floor((cr.spheres.centres[:, :2] - g.origin) / g.bin_size).astype(int)
    zs = g.zmin[b[:, 1], b[:, 0]]
    ok = np.isfinite(zs)
    assert np.mean(cr.spheres.centres[ok, 2] >= zs[ok] - 0.01) > 0.9


def _t_pose_grid():
    """A T-posed silhouette: head, arms out, legs apart (view frame: x right, y down)."""
    pts = []
    def box(x0, x1, y0, y1):
        X, Y = np.meshgrid(np.arange(x0, x1, 0.01), np.arange(y0, y1, 0.01))
        pts.append(np.stack([X.ravel(), Y.ravel(), np.full(X.size, 2.0)], -1))
    box(-0.08, 0.08, -0.85, -0.65)        # head
    box(-0.2, 0.2, -0.6, 0.0)             # torso
    box(-0.85, 0.85, -0.6, -0.5)          # arms
    box(-0.2, -0.05, 0.0, 0.85)           # legs
    box(0.05, 0.2, 0.0, 0.85)
    return build_orus(np.concatenate(pts), [0.0, -0.1])


def test_radial_profile_peaks_of_a_t_pose():
    g = _t_pose_grid()
    centre = np.array([0.0, -0.25])
    prof = radial_profile(g, centre)
    ang = prof.angles_deg
    tip = np.degrees(np.arctan2(0.85, centre[1] + 0.55))          # angle of the hands from up
    assert prof.head is not None and min(ang[prof.head], 360 - ang[prof.head]) <= 10
    assert len(prof.feet) == 2
    for f in prof.feet:
        assert abs(ang[f] - 180) < 30
    assert abs(ang[prof.feet[0]] - ang[prof.feet[1]]) < 30
    hands = sorted(ang[h] for h in prof.hands)
    assert len(hands) == 2 and abs(hands[0] - tip) < 10 and abs(hands[1] - (360 - tip)) < 10
    # the contour points are on the silhouette's boundary
    assert np.max(prof.distances) < 1.3 and np.min(prof.distances) > 0.1
