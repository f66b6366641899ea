"""Silhouette observations of the soft body (toolkit/softbody/silhouette.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.softbody.conftest import model_walk
from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.skeleton import SKELETON_14
from toolkit.softbody import (GlobalFitConfig, SoftBodyModel, SoftBodyParams, SoftBodyTrack, TrackConfig, global_fit,
                              track_sequence)
from toolkit.softbody.distance import primitive_distances
from toolkit.softbody.model import FRAMES, LENGTH_NAMES
from toolkit.softbody.silhouette import (SilhouetteBlock, SilhouetteConfig, SilhouetteView, model_mask, ray_minimum,
                                         report_silhouettes, silhouette_views)

SIZE = (160, 120)


def ring(centre, n=3, dist=2.6, size=SIZE):
    """``n`` cameras around ``centre`` (3,) at ``dist`` metres, 0.3 m above it."""
    c = np.asarray(centre, float)
    return [Camera.look_at(f"c{i}", c + dist * np.array([np.cos(a), np.sin(a), 0.0]) + [0, 0, 0.3], c, size=size,
                           fov_x_deg=55) for i, a in enumerate(np.radians([-90, 30, 150][:n]))]


def posed(model):
    v = model.default_params((0.0, 0.0, 1.0)).vector.copy()
    v[6 + 9] = 0.6  # a shoulder raised
    v[6 + 12] = 0.9  # an elbow bent
    return SoftBodyParams(v)


def test_outline_rays_graze_the_models_own_silhouette():
    model = SoftBodyModel()
    p = posed(model)
    cams = ring(p.vector[3:6], 2)
    views = silhouette_views(cams, [model_mask(model, p, c) for c in cams])
    assert [v.state for v in views] == ["ok", "ok"]
    blk = SilhouetteBlock(model, p, views)
    r, J = blk.residuals(p, model.state(p), np.arange(47))
    px_m = 2.6 / cams[0].K[0, 0]  # a pixel at the subject, metres
    assert blk.n_rays > 100
    assert abs(np.median(r[:blk.n_rays])) < 0.1 * px_m       # no bias: the outline lies on the boundary
    assert np.percentile(np.abs(r[:blk.n_rays]), 90) < px_m   # within a pixel's quantisation
    assert np.all(r[blk.n_rays:] == 0)                        # no model point outside its own mask


def test_jacobian_matches_finite_differences():
    """Pose, lengths and widths: the outline rays (envelope theorem) and the mask block (chain rule)."""
    model = SoftBodyModel()
    p = posed(model)
    cams = ring(p.vector[3:6], 2)
    views = silhouette_views(cams, [model_mask(model, p, c) for c in cams], SilhouetteConfig(ray_tol=1e-6))
    rng = np.random.default_rng(4)
    x = p.vector.copy()
    x[6:27] += rng.normal(0, 0.05, 21)
    x[27:40] *= 1.04
    x[40:] *= 1.08  # fatter: model points outside the mask
    q = SoftBodyParams(x)
    blk = SilhouetteBlock(model, q, views)
    cols = np.arange(47)
    r0, J0 = blk.residuals(q, model.state(q), cols)
    assert np.sum(r0[blk.n_rays:] != 0) > 20 and np.sum(r0[:blk.n_rays] < 0) > 20 and np.sum(r0[:blk.n_rays] > 0) > 5
    eps = 1e-6
    Jn = np.zeros_like(J0)
    for k in cols:
        a, b = x.copy(), x.copy()
        a[k] += eps
        b[k] -= eps
        pa, pb = SoftBodyParams(a), SoftBodyParams(b)
        Jn[:, k] = (blk.residuals(pa, model.state(pa), cols, False)[0]
                    - blk.residuals(pb, model.state(pb), cols, False)[0]) / (2 * eps)
    assert np.linalg.norm(Jn - J0) < 1e-3 * np.linalg.norm(Jn)
    for block in (slice(0, 27), slice(27, 40), slice(40, 47)):  # pose, lengths, widths each
        assert np.abs(J0[:, block]).max() > 1e-3
        assert np.linalg.norm(Jn[:, block] - J0[:, block]) < 2e-3 * np.linalg.norm(Jn[:, block])


def test_ray_minimum_is_the_least_distance_along_the_ray():
    model = SoftBodyModel()
    p = posed(model)
    cam = ring(p.vector[3:6], 1)[0]
    rng = np.random.default_rng(1)
    o, d = cam.rays(rng.uniform([50, 20], [110, 100], (30, 2)))
    s, dmin = ray_minimum(model, p, o, d)
    from toolkit.softbody import distance
    grid = np.linspace(1.5, 4.0, 2000)
    dense = distance(model, p, (o[:, None] + grid[None, :, None] * d[:, None]).reshape(-1, 3)).reshape(30, -1)
    assert np.all(dmin <= dense.min(axis=1) + 1e-5)
    assert np.allclose(dmin, distance(model, p, o + s[:, None] * d))


@pytest.fixture(scope="module")
def walk_without_a_forearm():
    """5 frames of a walk, the left forearm's points removed, and three cameras' silhouettes of the true body."""
    model, truth, joints, clouds, lengths, _ = model_walk(5, 500, 3)
    cams = ring(truth[0].vector[3:6])
    sil = [silhouette_views(cams, [model_mask(model, p, c) for c in cams]) for p in truth]
    fa = FRAMES.index("l_forearm")
    cut = []
    for p, x in zip(truth, clouds):
        e = primitive_distances(model.state(p), x)
        cut.append(x[model.prim_frame[np.argmin(e, axis=1)] != fa])
    return model, truth, joints, cut, lengths, sil


def test_silhouettes_hold_an_arm_without_points(walk_without_a_forearm):
    """The global fit started with both forearms 4 cm short and no points on the left one: the left
    wrist stays where the short forearm puts it without silhouettes, and goes to the outline with them."""
    model, truth, joints, clouds, lengths, sil = walk_without_a_forearm
    li = [LENGTH_NAMES.index("l_forearm"), LENGTH_NAMES.index("r_forearm")]
    v = np.stack([p.vector for p in truth])
    v[:, 27 + np.array(li)] -= 0.04
    tr = SoftBodyTrack(v, np.stack([model.joints(SoftBodyParams(x)) for x in v]), ("ok",) * len(v),
                       np.full(len(v), 500), np.ones(len(v)), np.zeros(len(v)))
    wr = SKELETON_14.joint_names.index("l_wrist")
    err, length = {}, {}
    for w in (0.0, 1.0):
        # the start's split and no proportion prior: those alone now fix a forearm short against its upper arm
        cfg = GlobalFitConfig(silhouette_weight=w, max_nfev=25, split_reference="start", proportion_weight=0.0)
        fit = global_fit(model, tr, clouds, config=cfg, silhouettes=sil)
        err[w] = 1000 * np.linalg.norm(fit.joints[:, wr] - joints[:, wr], axis=1).mean()
        length[w] = 1000 * np.abs(fit.lengths[li[0]] - lengths[li[0]])
    assert err[0.0] > 10.0          # without: the short forearm's wrist (11.5 mm with the outer-surface layout)
    assert err[1.0] < min(8.0, 0.5 * err[0.0])  # with: the silhouettes place it (3.4 mm)
    # the length itself moves towards the truth only a little: the split prior holds the start's ratio
    assert length[1.0] < length[0.0]


def test_tracking_with_silhouettes_keeps_the_pose(walk_without_a_forearm):
    model, truth, joints, clouds, lengths, sil = walk_without_a_forearm
    obs = RecordingObserver()
    tr = track_sequence(model, truth[0], clouds[:3], config=TrackConfig(silhouette_weight=1.0), silhouettes=sil[:3],
                        observer=obs)
    assert tr.states == ("ok",) * 3
    assert 1000 * np.linalg.norm(tr.joints - joints[:3], axis=-1).max() < 10.0
    report_silhouettes(obs, model, truth[2], sil[2], frame=2)
    reps = [d for k, d in obs.reports if k == "silhouette"]
    assert len(reps) == 3 and {d["camera"] for d in reps} == {"c0", "c1", "c2"}
    assert all(len(d["points"]) == len(d["residuals"]) > 20 for d in reps)


def test_bad_masks_are_refused_or_stated():
    model = SoftBodyModel()
    p = posed(model)
    cam = ring(p.vector[3:6], 1)[0]
    with pytest.raises(InputError, match="c0"):
        SilhouetteView(cam, np.ones((SIZE[0], SIZE[1]), bool))   # transposed: the wrong size
    with pytest.raises(InputError):
        SilhouetteView("c0", np.ones((SIZE[1], SIZE[0]), bool))
    with pytest.raises(InputError):
        silhouette_views([cam], [])
    empty = SilhouetteView(cam, np.zeros((SIZE[1], SIZE[0]), bool))
    full = SilhouetteView(cam, np.ones((SIZE[1], SIZE[0]), np.uint8))
    assert (empty.state, full.state) == ("empty", "no_outline")
    blk = SilhouetteBlock(model, p, [empty, full])
    r, J = blk.residuals(p, model.state(p), np.arange(27))
    assert len(blk) == 0 and r.shape == (0,) and J.shape == (0, 27)
    # an empty silhouette in a sequence: tracked on the points alone
    model, truth, joints, clouds, _, _ = model_walk(2, 300, 5)
    with pytest.raises(InputError, match="silhouettes"):
        track_sequence(model, truth[0], clouds, config=TrackConfig(silhouette_weight=1.0), silhouettes=[[empty]])
    tr = track_sequence(model, truth[0], clouds, config=TrackConfig(silhouette_weight=1.0),
                        silhouettes=[[empty], None])
    assert tr.states == ("ok", "ok")
    with pytest.raises(InputError):
        TrackConfig(silhouette_weight=-1.0)
    with pytest.raises(InputError, match="silhouettes"):
        global_fit(model, replace(tr), clouds, config=GlobalFitConfig(silhouette_weight=1.0), silhouettes=[None])
