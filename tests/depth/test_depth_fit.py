"""Local fitting (both solvers), the initial pose and the global moves' records."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from toolkit.pointcloud.cloud import ViewFrame, user_cloud
from toolkit.depth.curvature import curvature_centres
from toolkit.depth.energy import EnergyTerms, fit_data
from toolkit.depth.fit import FitConfig, GlobalSearch, LocalFit, Move, fit_local
from toolkit.depth.init import head_candidates, initial_poses, key_points, top_contour_peaks
from toolkit.body.control_points import HEAD, LENGTH_PAIRS, BodyDimensions
from toolkit.pointcloud.normals import normal_map
from toolkit.depth.orus import OrusConfig, build_orus
from toolkit.depth.radial import radial_profile

#: A local fit from the truth perturbed by 3 cm lands this close to the truth (noisy 320 x 240 depth).
LOCAL_FIT_MPJPE_M = 0.045
#: The two solvers take the same steps: their results agree to this.
SOLVER_AGREEMENT_M = 0.02
#: The initial pose of a standing person, before any tracking.
INIT_MPJPE_M = 0.08


def _frame_data(seq, t=0):
    vf = ViewFrame.from_camera(seq.camera)
    m = seq.subject[t] == 1
    d = seq.depth[t]
    cloud = user_cloud(d, m, vf, normal_map(d, seq.camera, m))
    g = build_orus(cloud.points, cloud.centroid, OrusConfig(normal_source="pixels"), cloud.normals)
    return vf, cloud, g, fit_data(g, curvature_centres(g), vf)


def test_local_fit_with_both_solvers(idle_sequence):
    seq = idle_sequence
    vf, _, _, data = _frame_data(seq, 5)
    truth = vf.from_world(seq.joints13[5])
    X0 = truth + np.random.default_rng(0).normal(0, 0.03, truth.shape)
    L = np.array([np.linalg.norm(truth[a] - truth[b]) for a, b in LENGTH_PAIRS])
    dims = BodyDimensions.from_stature(1.75).with_lengths(L)
    out = {}
    for solver in ("lm", "scipy"):
        cfg = replace(FitConfig(), solver=solver, outer_iterations=3, lm_max_evaluations=10, lm_refine_evaluations=10)
        f = fit_local(X0, data, dims, X0, np.full(13, 0.1), cfg, ground_y=vf.ground_y)
        err = np.linalg.norm(f.X - truth, axis=1)
        assert err.mean() < LOCAL_FIT_MPJPE_M, solver
        assert err.mean() < np.linalg.norm(X0 - truth, axis=1).mean()     # the fit improves on its start
        assert f.energy.explained > 0.95 and len(f.history) >= 1
        out[solver] = f.X
    assert np.abs(out["lm"] - out["scipy"]).max() < SOLVER_AGREEMENT_M


def test_initial_pose_of_a_standing_person(idle_sequence):
    seq = idle_sequence
    vf, cloud, g, _ = _frame_data(seq, 0)
    prof = radial_profile(g, cloud.centroid)
    kp = key_points(g, prof)
    heads = head_candidates(kp, cloud.centroid, cloud.principal_axis, prof, grid=g)
    truth = vf.from_world(seq.joints13[0])
    assert heads and np.linalg.norm(heads[0].position[:2] - truth[HEAD, :2]) < 0.12
    poses = initial_poses(g, kp, heads, cloud.centroid, cloud.principal_axis, vf.ground_y, False)
    best = min(np.linalg.norm(p.X - truth, axis=1).mean() for p in poses)
    assert best < INIT_MPJPE_M
    assert abs(poses[0].dims.stature - 1.75) < 0.12          # measured from the head top to the ground
    assert len(top_contour_peaks(g, min_body_m=0.8)) == 1     # one person


def test_global_moves_are_ranked_by_their_record():
    best = LocalFit(np.zeros((13, 3)), EnergyTerms({}, 100.0, 1.0, None))
    losing = Move("losing", lambda X, ctx: [X + 1.0])
    winning = Move("winning", lambda X, ctx: [X + 2.0])
    search = GlobalSearch([losing, winning], FitConfig(max_moves=2))
    assert [m.name for m in search.ranked()] == ["losing", "winning"]       # ties keep the given order

    def fit(X0):
        e = 120.0 if X0[0, 0] == 1.0 else 60.0
        return LocalFit(X0, EnergyTerms({"surface": e}, e, 1.0, None))

    for _ in range(3):
        out, won = search.run(best, None, fit)
        assert won == "winning" and out.energy.total == 60.0
    assert search.records["winning"].wins == 3 and search.records["losing"].wins == 0
    assert [m.name for m in search.ranked()] == ["winning", "losing"]
    assert search.records["winning"].weight > search.records["losing"].weight
    # moves without a proposal are not counted as tried
    quiet = GlobalSearch([Move("nothing", lambda X, ctx: [])])
    assert quiet.run(best, None, fit) == (best, None) and quiet.records["nothing"].tries == 0
