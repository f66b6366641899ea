#!/usr/bin/env python3
"""How well the soft body's metaballs match the rendered bodies' surface; the trunk layout's calibration.

Usage::

    python -m benchmarks.calibrate_softbody_layout                   # the layout's surface bias, held-out bodies
    python -m benchmarks.calibrate_softbody_layout --seeds 2000 2200 2400 --fit   # the session-11 calibration
    python -m benchmarks.calibrate_softbody_layout --noiseless --seeds 9900 9300  # the global fit's bias

Each case is a :class:`toolkit.body.BodyModel` mesh of a random person of the
soft-body benchmark (``benchmarks.bench_softbody.scene_specs``: 4 scenes per
seed, wave / kick / crouch / turn, frames 0 and 6) and the soft body of the
same proportions and girth posed on the mesh's own joints with the true
lengths (:func:`toolkit.softbody.init.fit_pose_to_joints`): no fit to points,
so what remains is the model's shape.  Printed: the median signed distance
(mm; + outside the model, i.e. the model too thin) and the mean absolute
distance of the mesh's vertices, per body part and in 10 cm bands of height
above the mid-hip point (torso vertices).

``--fit`` refits the five trunk and pelvis metaballs' radii (x, y
multipliers), axial extents (multiplier) and places (metres along z for the
pelvis blocks, a fraction of the trunk for the trunk balls) to the torso's
and upper thighs' vertices (``scipy.optimize.least_squares``, soft-L1 at
1 cm) and prints the 20 values, as a change to the current layout
(``toolkit/softbody/model.py``: ``_primitives``).  A biased
layout biases the global fit's lengths: on noiseless points of the true
mesh the old layout's global fit raised the pelvis 30-96 mm
(``docs/benchmarks.md``, "Session 11: the trunk's metaballs").

``--noiseless`` measures that bias directly: for each scene of the seeds
(``scene_specs(3, 12, seed)``, depth and trinocular people), 1500 points
spread over the true mesh in frames 0, 3, 6 and 9, tracked from the true
lengths and frame 0's true pose (no silhouettes), then the global fit with
the lengths free; printed: the mean joint error (mm) after tracking and
after the global fit, the global fit's mid-hip height error (mm) and its
mean length error (mm).
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

N_FITTED = 5  # the pelvis blocks and the trunk balls: the first five primitives


def cases(seeds, frames=(0, 6), every: int = 2) -> list:
    """``(model, params, vertices (N, 3), part (N,), height above the mid-hip (N,))`` per body and frame."""
    from benchmarks.bench_softbody import scene_specs
    from toolkit.softbody import SoftBodyModel
    from toolkit.softbody.init import fit_pose_to_joints
    from toolkit.synthetic.generator import build_scene
    from toolkit.synthetic.spec import parse_spec

    out = []
    for seed in seeds:
        for name, _, text in scene_specs(4, max(frames) + 1, seed):
            sc = build_scene(parse_spec(text, name))
            for t in frames:
                m = sc.body_mesh(t)
                part = np.zeros(len(m.vertices), int)
                part[m.triangles.ravel()] = np.repeat(m.triangle_parts, 3)
                j = sc.joints[t]
                model = SoftBodyModel(sc.proportions, girth=sc.body.shape.girth)
                p = model.default_params(root_translation=j[1] - [0, 0, 0.5]).replace(
                    lengths=model.lengths_from_proportions(sc.proportions))
                p = fit_pose_to_joints(model, p, j)
                z = m.vertices[:, 2] - 0.5 * (j[8, 2] + j[11, 2])
                out.append((sc, p, m.vertices[::every], part[::every], z[::every]))
    return out


def _layout(change):
    """``toolkit.softbody.model._primitives`` with the first five primitives changed by ``change`` (20,)."""
    import toolkit.softbody.model as M

    base = M._primitives

    def prims(p, girth=1.0):
        out = base(p, girth)
        hh = p.height / 1.75
        for i in range(N_FITTED):
            q = out[i]
            rx, ry, rz, dz = change[4 * i:4 * i + 4]
            r = (q.radii[0] * rx, q.radii[1] * ry, q.radii[2] * rz)
            out[i] = (M._Primitive(q.frame, q.s + dz, q.offset, r, q.group, q.axial) if q.axial else
                      M._Primitive(q.frame, q.s, (q.offset[0], q.offset[1], q.offset[2] + dz * hh), r, q.group,
                                   q.axial))
        return out
    return prims


def signed_distances(cs, change=None) -> list:
    """Per case, the mesh vertices' signed distance (N,) metres to the soft body (``change``: see :func:`_layout`)."""
    import toolkit.softbody.model as M
    from toolkit.softbody import SoftBodyModel
    from toolkit.softbody.distance import distance

    base = M._primitives
    if change is not None:
        M._primitives = _layout(change)
    try:
        return [distance(SoftBodyModel(sc.proportions, girth=sc.body.shape.girth), p, v) for sc, p, v, _, _ in cs]
    finally:
        M._primitives = base


def summary(cs, ds) -> dict:
    """``{row: (median mm, mean |d| mm, n)}`` per part and per torso height band."""
    from toolkit.skeleton import SKELETON_14

    names = ("background",) + tuple(SKELETON_14.part_names)
    torso = names.index("torso")
    rows = {}
    for (_, _, _, part, z), d in zip(cs, ds):
        for k in np.unique(part):
            if k:
                rows.setdefault(names[k], []).append(d[part == k])
        for lo in np.arange(-0.2, 0.8, 0.1):
            sel = (part == torso) & (z >= lo) & (z < lo + 0.1)
            rows.setdefault(f"torso z {lo:+.1f}..{lo + 0.1:+.1f} m", []).append(d[sel])
    out = {}
    for k, v in rows.items():
        v = np.concatenate(v)
        if len(v):
            out[k] = (1000 * float(np.median(v)), 1000 * float(np.mean(np.abs(v))), len(v))
    return out


def noiseless(seeds, frames=(0, 3, 6, 9), n_points: int = 1500) -> list:
    """Per scene: ``(name, tracking mm, global fit mm, mid-hip height error mm, mean length error mm)``."""
    import open3d as o3d

    from benchmarks.bench_softbody import scene_specs
    from toolkit.softbody import GlobalFitConfig, SoftBodyModel, TrackConfig, global_fit, track_sequence
    from toolkit.softbody.init import fit_pose_to_joints
    from toolkit.synthetic.generator import build_scene
    from toolkit.synthetic.spec import parse_spec

    out = []
    for seed in seeds:
        for name, _, text in scene_specs(3, 12, seed):
            sc = build_scene(parse_spec(text, name))
            model = SoftBodyModel(sc.proportions, girth=sc.body.shape.girth)
            lt = model.lengths_from_proportions(sc.proportions)
            p = model.default_params(root_translation=sc.joints[0, 1] - [0, 0, 0.5]).replace(lengths=lt)
            p = fit_pose_to_joints(model, p, sc.joints[0])
            clouds = []
            for t in frames:
                m = sc.body_mesh(t)
                tm = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(m.vertices),
                                               o3d.utility.Vector3iVector(m.triangles))
                o3d.utility.random.seed(t)
                clouds.append(np.asarray(tm.sample_points_uniformly(n_points).points))
            tr = track_sequence(model, p, clouds, config=TrackConfig(silhouette_weight=0))
            fit = global_fit(model, tr, clouds, config=GlobalFitConfig(silhouette_weight=0, max_nfev=25))
            truth = sc.joints[list(frames)]
            err = lambda j: 1000 * float(np.linalg.norm(j - truth, axis=-1).mean())  # noqa: E731
            hip = 1000 * float(np.mean((fit.joints[:, [8, 11]] - truth[:, [8, 11]])[..., 2]))
            out.append((name, err(tr.joints), err(fit.joints), hip, 1000 * float(np.mean(np.abs(fit.lengths - lt)))))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--seeds", type=int, nargs="+", default=[3000, 3200],
                    help="benchmark seeds whose bodies are measured (4 people each; the calibration used "
                         "2000 2200 2400)")
    ap.add_argument("--fit", action="store_true", help="refit the five trunk and pelvis metaballs")
    ap.add_argument("--noiseless", action="store_true",
                    help="the global fit on noiseless points of the true bodies of these seeds' scenes")
    args = ap.parse_args(argv)
    if args.noiseless:
        print(f"{'scene':<30}{'tracking mm':>13}{'global fit mm':>15}{'mid-hip dz mm':>15}{'lengths mm':>12}")
        for name, trk, glb, hip, lerr in noiseless(args.seeds):
            print(f"{name:<30}{trk:>13.1f}{glb:>15.1f}{hip:>+15.0f}{lerr:>12.1f}", flush=True)
        return 0
    cs = cases(args.seeds)
    print(f"{len(cs)} meshes (seeds {args.seeds})")
    for k, (med, mad, n) in summary(cs, signed_distances(cs)).items():
        print(f"  {k:24s} median {med:+6.1f} mm   mean |d| {mad:5.1f} mm   ({n} vertices)")
    if not args.fit:
        return 0
    from scipy.optimize import least_squares
    from toolkit.skeleton import SKELETON_14

    names = ("background",) + tuple(SKELETON_14.part_names)
    use = [(part == names.index("torso")) | (np.isin(part, [names.index("l_thigh"), names.index("r_thigh")])
                                            & (z > -0.15)) for _, _, _, part, z in cs]

    def residuals(x):
        return np.concatenate([d[u][::3] for d, u in zip(signed_distances(cs, x), use)])

    x0 = np.tile([1.0, 1.0, 1.0, 0.0], N_FITTED)
    lo, hi = np.tile([0.6, 0.6, 0.5, -0.08], N_FITTED), np.tile([1.5, 1.5, 2.0, 0.08], N_FITTED)
    sol = least_squares(residuals, x0, loss="soft_l1", f_scale=0.01, diff_step=1e-3, max_nfev=25, bounds=(lo, hi))
    print("change (rx, ry, rz multipliers and dz per primitive):", json.dumps(np.round(sol.x, 3).tolist()))
    for k, (med, mad, n) in summary(cs, signed_distances(cs, sol.x)).items():
        print(f"  {k:24s} median {med:+6.1f} mm   mean |d| {mad:5.1f} mm   ({n} vertices)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
