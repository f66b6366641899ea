"""The 32 x 40 silhouette descriptor, the bounding-box joint frame, the flow descriptor, silhouette checks."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.silhouettes import (
    DESCRIPTOR_SIZE,
    SILHOUETTE_GRID,
    bounding_box,
    check_silhouette,
    denormalise_joints,
    descriptor_grid,
    flow_descriptor,
    normalise_joints,
    quantise_descriptor,
    silhouette_descriptor,
    silhouette_grid,
)
from toolkit.silhouettes.descriptor import (
    STATE_EMPTY,
    STATE_FULL_FRAME,
    STATE_OK,
    STATE_TOO_SMALL,
    STATE_TRUNCATED,
)

#: Float32 arithmetic of the area-averaging matrices.
FLOAT_TOL = 1e-5


def blob(h=123, w=77, seed=0) -> np.ndarray:
    """An irregular silhouette: a few filled ellipses."""
    rng = np.random.default_rng(seed)
    m = np.zeros((h, w), np.uint8)
    for _ in range(5):
        c = (int(rng.integers(20, w - 20)), int(rng.integers(20, h - 20)))
        ax = (int(rng.integers(5, 15)), int(rng.integers(10, 30)))
        cv2.ellipse(m, c, ax, float(rng.uniform(0, 180)), 0, 360, 1, -1)
    return m.astype(bool)


def test_grid_constants():
    assert SILHOUETTE_GRID == (32, 40)
    assert DESCRIPTOR_SIZE == 1280


def test_descriptor_shape_range_and_full_box():
    m = np.zeros((100, 60), bool)
    m[10:90, 20:40] = True
    v = silhouette_descriptor(m)
    assert v.shape == (1280,) and v.dtype == np.float32
    np.testing.assert_array_equal(v, 1.0)
    g = silhouette_grid(blob())
    assert g.shape == (40, 32)
    assert g.min() >= 0.0 and g.max() <= 1.0


def test_area_averaging_preserves_coverage():
    m = blob()
    box = bounding_box(m)
    c0, r0, c1, r1 = (box + [0.5, 0.5, -0.5, -0.5]).astype(int)
    coverage = m[r0:r1 + 1, c0:c1 + 1].mean()
    assert silhouette_grid(m).mean() == pytest.approx(coverage, abs=FLOAT_TOL)


def test_aspect_is_not_preserved_and_position_is_irrelevant():
    """Integer non-uniform up-scaling and translation leave the descriptor unchanged."""
    m = blob()
    v = silhouette_descriptor(m)
    stretched = np.kron(m, np.ones((2, 3), bool))
    np.testing.assert_allclose(silhouette_descriptor(stretched), v, atol=FLOAT_TOL)
    shifted = np.zeros((300, 200), bool)
    shifted[37:37 + m.shape[0], 51:51 + m.shape[1]] = m
    np.testing.assert_allclose(silhouette_descriptor(shifted), v, atol=FLOAT_TOL)


def test_grid_matches_opencv_area_resize_when_shrinking():
    m = np.kron(blob(), np.ones((3, 3), bool))  # 3x larger than the grid in both directions
    box = bounding_box(m)
    c0, r0, c1, r1 = (box + [0.5, 0.5, -0.5, -0.5]).astype(int)
    ref = cv2.resize(m[r0:r1 + 1, c0:c1 + 1].astype(np.float32), SILHOUETTE_GRID, interpolation=cv2.INTER_AREA)
    np.testing.assert_allclose(silhouette_grid(m), ref, atol=FLOAT_TOL)


def test_descriptor_grid_and_quantise():
    v = silhouette_descriptor(blob())
    np.testing.assert_array_equal(descriptor_grid(v), silhouette_grid(blob()))
    q = quantise_descriptor(v)
    assert q.dtype == np.uint8
    assert np.abs(q / 255.0 - v).max() <= 0.5 / 255 + FLOAT_TOL
    with pytest.raises(InputError, match="descriptor"):
        quantise_descriptor(np.full(1280, 1.5))
    with pytest.raises(InputError, match="descriptor"):
        descriptor_grid(np.zeros(1000))


def test_bounding_box_uses_pixel_edges():
    m = np.zeros((50, 40), bool)
    m[10:21, 5:9] = True
    np.testing.assert_array_equal(bounding_box(m), [4.5, 9.5, 8.5, 20.5])
    assert bounding_box(np.zeros((5, 5), bool)) is None


def test_normalised_joints_round_trip_and_corners():
    box = np.array([4.5, 9.5, 8.5, 20.5])
    corners = np.array([[4.5, 9.5], [8.5, 20.5], [6.5, 15.0]])
    np.testing.assert_allclose(normalise_joints(corners, box), [[0, 0], [1, 1], [0.5, 0.5]])
    rng = np.random.default_rng(1)
    j = rng.uniform(0, 100, (14, 2))
    j[3] = np.nan
    back = denormalise_joints(normalise_joints(j, box), box)
    np.testing.assert_allclose(back, j, atol=1e-9)
    assert np.isnan(back[3]).all()
    with pytest.raises(InputError, match="bbox"):
        normalise_joints(j, [5, 5, 5, 10])


def test_empty_mask_and_bad_shapes_raise():
    with pytest.raises(InputError, match="empty"):
        silhouette_descriptor(np.zeros((10, 10), bool))
    with pytest.raises(InputError, match="mask"):
        silhouette_descriptor(np.zeros((10, 10, 3), bool))
    with pytest.raises(InputError, match="bbox"):
        silhouette_grid(blob(), np.array([-10.5, 0.5, 5.5, 6.5]))


def test_flow_descriptor_of_a_uniform_flow():
    m = blob()
    box = bounding_box(m)
    flow = np.zeros(m.shape + (2,))
    flow[..., 0] = 3.0
    flow[..., 1] = -2.0
    f = flow_descriptor(flow, box)
    assert f.shape == (2560,)
    np.testing.assert_allclose(f[:1280], 3.0 / (box[2] - box[0]), rtol=1e-5)
    np.testing.assert_allclose(f[1280:], -2.0 / (box[3] - box[1]), rtol=1e-5)
    with pytest.raises(InputError, match="flow"):
        flow_descriptor(flow[..., 0], box)


@pytest.mark.parametrize("case, state", [
    ("ok", STATE_OK), ("empty", STATE_EMPTY), ("tiny", STATE_TOO_SMALL), ("full", STATE_FULL_FRAME),
    ("border", STATE_TRUNCATED),
])
def test_check_silhouette_states(case, state):
    m = np.zeros((120, 160), bool)
    if case == "ok":
        m[20:100, 60:90] = True
    elif case == "tiny":
        m[50:55, 50:55] = True
    elif case == "full":
        m[:] = True
    elif case == "border":
        m[40:120, 60:90] = True  # reaches the bottom row: the person is leaving the image
    check = check_silhouette(m)
    assert check.state == state
    assert bool(check) == (state == STATE_OK)
    assert isinstance(check.reason, str) and check.reason
