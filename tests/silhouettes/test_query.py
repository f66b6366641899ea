"""E_S queries (source 000 eq. 1): exactness, the temporal term, NaN handling, Hausdorff and flow variants."""

from __future__ import annotations

import time

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.silhouettes import (
    K_BEST,
    LAMBDA_TEMPORAL,
    QueryConfig,
    SilhouetteDatabase,
    descriptor_grid,
    hausdorff_distance,
    query_database,
)
from toolkit.silhouettes.database import FLOW_SIZE
from toolkit.silhouettes.query import GRID_DIAGONAL, grid_contour

#: Floating-point agreement between the vectorised and the naive E_S.
ES_TOL = 1e-12


def naive_es(db: SilhouetteDatabase, v_levels: np.ndarray, previous, lam: float) -> np.ndarray:
    """E_S of eq. (1), entry by entry."""
    out = []
    for i in range(len(db)):
        s = np.mean(np.abs(db.descriptors[i].astype(float) - v_levels.astype(float))) / 255.0
        if previous is None or lam == 0:
            out.append(s)
            continue
        ok = np.isfinite(previous).all(1)
        p = np.mean(np.linalg.norm(db.joints[i].astype(float)[ok] - previous[ok], axis=1))
        out.append((1 - lam) * s + lam * p)
    return np.array(out)


def test_source_constants():
    assert K_BEST == 3
    assert LAMBDA_TEMPORAL == 0.5


def test_query_with_a_member_returns_it(walk_db):
    rng = np.random.default_rng(0)
    for i in rng.choice(len(walk_db), 10, replace=False):
        c = query_database(walk_db, walk_db.descriptors[i])
        assert len(c) == K_BEST
        assert c.errors[0] == 0.0
        assert c.indices[0] == i or np.array_equal(walk_db.descriptors[c.indices[0]], walk_db.descriptors[i])
        assert np.all(np.diff(c.errors) >= 0)
        np.testing.assert_array_equal(c.joints[0], walk_db.joints[c.indices[0]])
        assert c.lam == 0.0 and np.isnan(c.temporal_errors).all()


def test_vectorised_es_matches_the_formula(walk_db):
    rng = np.random.default_rng(1)
    db = walk_db.subset(rng.choice(len(walk_db), 200, replace=False))
    v = rng.random(1280)
    levels = np.rint(v * 255).astype(np.uint8)
    prev = rng.random((14, 2))
    for previous, lam in ((None, 0.0), (prev, LAMBDA_TEMPORAL)):
        c = query_database(db, v, previous, QueryConfig(k=len(db)))
        ref = naive_es(db, levels, previous, lam)
        np.testing.assert_allclose(c.errors, ref[c.indices], atol=ES_TOL)
        np.testing.assert_allclose(np.sort(ref), c.errors, atol=ES_TOL)


def two_entry_db():
    """Entry 0 matches the query silhouette exactly, entry 1 nearly; their joints are far apart."""
    v = np.zeros(1280)
    v[:640] = 1.0
    w = v.copy()
    w[640:704] = 1.0  # 64 of 1280 cells differ: silhouette error 0.05
    q0 = np.full((14, 2), 0.25)  # exact in float32
    q1 = np.full((14, 2), 0.75)
    return SilhouetteDatabase(np.stack([v, w]), np.stack([q0, q1])), v, q0, q1


def test_temporal_term_changes_the_ranking():
    db, v, q0, q1 = two_entry_db()
    first = query_database(db, v, None, QueryConfig(k=2))
    np.testing.assert_array_equal(first.indices, [0, 1])
    np.testing.assert_allclose(first.errors, [0.0, 0.05], atol=ES_TOL)
    later = query_database(db, v, q1, QueryConfig(k=2))
    np.testing.assert_array_equal(later.indices, [1, 0])
    d = np.hypot(0.5, 0.5)
    np.testing.assert_allclose(later.errors, [0.5 * 0.05, 0.5 * d], atol=ES_TOL)
    np.testing.assert_allclose(later.temporal_errors, [0.0, d], atol=ES_TOL)
    assert later.lam == LAMBDA_TEMPORAL


def test_nan_previous_joints_fall_back():
    db, v, q0, q1 = two_entry_db()
    all_nan = query_database(db, v, np.full((14, 2), np.nan), QueryConfig(k=2))
    assert all_nan.lam == 0.0
    np.testing.assert_array_equal(all_nan.indices, [0, 1])
    partial = q1.copy()
    partial[:10] = np.nan
    part = query_database(db, v, partial, QueryConfig(k=2))
    np.testing.assert_array_equal(part.indices, [1, 0])
    np.testing.assert_allclose(part.temporal_errors, [0.0, np.hypot(0.5, 0.5)], atol=ES_TOL)


def test_empty_database_and_bad_arguments():
    with pytest.raises(InputError, match="empty database"):
        query_database(SilhouetteDatabase.empty(), np.zeros(1280))
    db, v, _, _ = two_entry_db()
    with pytest.raises(InputError, match="descriptor"):
        query_database(db, np.zeros(100))
    with pytest.raises(InputError, match="previous"):
        query_database(db, v, np.zeros((13, 2)))
    with pytest.raises(InputError, match="metric"):
        QueryConfig(metric="l2")
    with pytest.raises(InputError, match="k"):
        QueryConfig(k=0)
    assert len(query_database(db, v, None, QueryConfig(k=10))) == 2


def test_hausdorff_distance_of_known_point_sets():
    a = np.array([[0.0, 0.0], [1.0, 0.0]])
    b = np.array([[0.0, 0.0], [1.0, 0.0], [4.0, 4.0]])
    assert hausdorff_distance(a, b) == pytest.approx(5.0)
    assert hausdorff_distance(a, a) == 0.0
    assert hausdorff_distance(a, np.zeros((0, 2))) == np.inf


def test_hausdorff_variant_reranks_the_shortlist(walk_db):
    cfg = QueryConfig(metric="hausdorff", k=5, shortlist=40)
    i = 17
    c = query_database(walk_db, walk_db.descriptors[i], None, cfg)
    assert c.metric == "hausdorff" and c.errors[0] == 0.0
    assert np.array_equal(walk_db.descriptors[c.indices[0]], walk_db.descriptors[i])
    # each error is the contour distance / grid diagonal, recomputed here
    q = grid_contour(descriptor_grid(walk_db.descriptors[i] / 255.0))
    for idx, e in zip(c.indices, c.errors):
        ref = hausdorff_distance(q, grid_contour(descriptor_grid(walk_db.descriptors[idx] / 255.0)))
        assert e == pytest.approx(ref / GRID_DIAGONAL)
    assert np.all(np.diff(c.errors) >= 0)


def test_flow_term_separates_identical_silhouettes():
    v = np.zeros(1280)
    v[:700] = 1.0
    flows = np.zeros((3, FLOW_SIZE))
    flows[0] = 0.1   # moving right
    flows[1] = -0.1  # moving left
    flows[2] = np.nan
    db = SilhouetteDatabase(np.stack([v, v, v]), np.zeros((3, 14, 2)), flows=flows)
    c = query_database(db, v, None, QueryConfig(k=3, flow_weight=1.0), flow=np.full(FLOW_SIZE, -0.1))
    assert c.indices[0] in (1, 2) and c.errors[0] == 0.0
    assert c.indices[-1] == 0
    assert c.errors[-1] == pytest.approx(0.2 / 2, rel=1e-3)  # (L1 0 + mu * 0.2) / (1 + mu)


def test_query_time_on_50000_entries():
    """The brute-force E_S over 50 000 entries stays interactive (docs quote the measured time)."""
    rng = np.random.default_rng(3)
    db = SilhouetteDatabase((rng.random((50_000, 1280)) > 0.5).astype(np.uint8) * 255,
                            rng.random((50_000, 14, 2)).astype(np.float32))
    v = db.descriptors[123]
    query_database(db, v)  # warm up
    t = time.perf_counter()
    c = query_database(db, v, rng.random((14, 2)))
    elapsed = time.perf_counter() - t
    assert c.indices.shape == (3,)
    assert elapsed < 0.5  # measured ~0.03 s on 2 cores; a generous bound for slow CI machines
