#!/usr/bin/env python3
"""How well the soft body's metaballs match the rendered bodies' surface; the layout's calibration.

Usage::

    python -m benchmarks.calibrate_softbody_layout                   # the layout's surface bias, held-out bodies
    python -m benchmarks.calibrate_softbody_layout --seeds 2000 2200 2400 --fit   # refit the trunk's metaballs
    python -m benchmarks.calibrate_softbody_layout --seeds 2000 2200 2400 --fit --groups trunk arms --max-nfev 15
    python -m benchmarks.calibrate_softbody_layout --noiseless --seeds 9900 9300  # the global fit's bias

Each case is a :class:`toolkit.body.BodyModel` mesh of a random person of the
soft-body benchmark (``benchmarks.bench_softbody.scene_specs``: 4 scenes per
seed, wave / kick / crouch / turn, frames 0 and 6) and the soft body of the
same proportions and girth posed on the mesh's own joints with the true
lengths (:func:`toolkit.softbody.init.fit_pose_to_joints`): no fit to points,
so what remains is the model's shape.  Printed: the median signed distance
(mm; + outside the model, i.e. the model too thin) and the mean absolute
distance of the mesh's vertices, per body part and in 10 cm bands of height
above the mid-hip point (torso vertices), over all vertices and over the
*outer surface* only.  The mesh is a union of closed capsules and
ellipsoids that overlap: about 40 % of its vertices lie inside another of
its volumes (the neck's lower half inside the chest, the shoulder and hip
caps inside the trunk, the elbow and knee caps inside the next segment), no
camera can see them, and they read as "model too fat" (head: mean |d| 4 mm
on the outer surface, 21 mm over all vertices; upper arms 2 mm and 16 mm).

``--fit`` refits the metaballs of the chosen ``--groups`` (``trunk``: the
pelvis blocks and trunk balls; ``head``: neck and head; ``arms``: the upper
arm, forearm and hand balls; ``legs``: the thigh, shank and foot balls; left
and right share their values): per primitive its radii (x, y multipliers),
axial extent (multiplier) and place (metres times stature / 1.75 along the
frame's z for fixed primitives, a fraction of the segment for those stretched
along it), fitted (``scipy.optimize.least_squares``, soft-L1 at 1 cm, at most
``--max-nfev`` evaluations) to the signed distance of the outer-surface
vertices of the groups' parts (``trunk``: the torso and the thighs' top
15 cm; ``--all-vertices`` to include the buried ones, as the fit of 80bd066 did).  It
prints the values, as a change to the current layout
(``toolkit/softbody/model.py``: ``_primitives``), and the table after the
change.  A biased layout biases the global fit's lengths: on noiseless
points of the true mesh the global fit with the layout before 80bd066 raised the pelvis
30-96 mm (``docs/benchmarks.md``, soft-body section (the earlier runs: its git history)).  The
outer-surface fit and the all-vertex fit disagree: the buried vertices pull
the model in where the torso meets the thighs (fitted to every vertex, the
band 0-0.1 m above the mid-hip stays 19 mm too thin even with a fourth
trunk ball there), and a layout fitted to the outer surface makes the
global fit on clouds that include the buried surfaces (``--noiseless``
without ``--outer``) raise the pelvis 30-80 mm.

``--noiseless`` measures that bias directly: for each scene of the seeds
(``scene_specs(3, 12, seed)``, depth and trinocular people), 1500 points
spread over the true mesh in frames 0, 3, 6 and 9 (``--outer``: over its
outer surface only, the triangles with a vertex outside the other volumes),
tracked from the true lengths and frame 0's true pose (no silhouettes), then
the global fit with the lengths free; printed: the mean joint error (mm)
after tracking and after the global fit, the global fit's mid-hip height
error (mm) and its mean length error (mm).  Without ``--outer`` a third of
the points lie on buried surfaces no camera sees, and they dominate what is
left: with the layout of 80bd066 (seed 9900's six scenes) the global fit's
joints are 6.1-7.8 mm off and its lengths 3.9-6.8 mm, with ``--outer``
2.4-3.7 mm and 1.5-2.8 mm.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

#: The trunk group is also fitted to the thighs' vertices less than this far below the mid-hip (metres).
THIGH_TOP = 0.15
#: Fitted groups: the frames (side prefix dropped) whose primitives they change, and the mesh parts they are fitted to.
GROUPS = {
    "trunk": (("pelvis", "trunk"), ("torso",)),
    "head": (("head",), ("head",)),
    "arms": (("upper_arm", "forearm"), ("l_upper_arm", "r_upper_arm", "l_forearm", "r_forearm")),
    "legs": (("thigh", "shank"), ("l_thigh", "r_thigh", "l_shank", "r_shank")),
}


def buried(mesh) -> np.ndarray:
    """Vertices inside another closed component of the mesh, (V,) bool.

    The components are the mesh's connected pieces (each capsule and
    ellipsoid of :class:`toolkit.body.BodyModel` is one); a vertex more than
    0.1 mm inside another (``open3d`` signed distance) is hidden from every
    camera.
    """
    import open3d as o3d
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    V, T = np.asarray(mesh.vertices, float), np.asarray(mesh.triangles)
    n = len(V)
    a, b = np.concatenate([T[:, 0], T[:, 1]]), np.concatenate([T[:, 1], T[:, 2]])
    nc, label = connected_components(coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)), directed=False)
    out = np.zeros(n, bool)
    for c in range(nc):
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(V.astype(np.float32)),
                            o3d.core.Tensor(T[label[T[:, 0]] == c].astype(np.uint32)))
        other = np.flatnonzero(label != c)
        sd = scene.compute_signed_distance(o3d.core.Tensor(V[other].astype(np.float32))).numpy()
        out[other[sd < -1e-4]] = True
    return out


def cases(seeds, frames=(0, 6), every: int = 2) -> list:
    """Per body and frame: ``(scene, params, vertices (N, 3), part (N,), height above the mid-hip (N,), outer (N,))``.

    ``outer`` is ``True`` for the vertices on the mesh's outer surface (not :func:`buried`).
    """
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
                out.append((sc, p, m.vertices[::every], part[::every], z[::every], ~buried(m)[::every]))
    return out


def primitive_keys() -> list:
    """Name of each primitive of ``_primitives``: ``"frame:k"``, the side prefix dropped (left and right share it)."""
    import toolkit.softbody.model as M
    from toolkit.anthropometry.proportions import BodyProportions

    keys, seen = [], {}
    for q in M._primitives(BodyProportions.from_height(1.75)):
        f = M.FRAMES[q.frame]
        k = seen.get(f, 0)
        seen[f] = k + 1
        keys.append(f"{f.removeprefix('l_').removeprefix('r_')}:{k}")
    return keys


def group_keys(groups) -> list:
    """The primitive keys (:func:`primitive_keys`, in order, each once) of the named :data:`GROUPS`."""
    frames = {f for g in groups for f in GROUPS[g][0]}
    return list(dict.fromkeys(k for k in primitive_keys() if k.split(":")[0] in frames))


def _layout(change, keys):
    """``toolkit.softbody.model._primitives`` with the primitives ``keys`` changed by ``change`` (4 len(keys),).

    Per key: x and y radius multipliers, axial extent multiplier, shift (fraction
    of the segment for axial primitives, metres times stature / 1.75 along the
    frame's z otherwise).
    """
    import toolkit.softbody.model as M

    base = M._primitives
    all_keys = primitive_keys()
    where = {k: i for i, k in enumerate(keys)}

    def prims(p, girth=1.0):
        out = base(p, girth)
        hh = p.height / 1.75
        for n, q in enumerate(out):
            if all_keys[n] not in where:
                continue
            i = where[all_keys[n]]
            rx, ry, rz, dz = change[4 * i:4 * i + 4]
            r = (q.radii[0] * rx, q.radii[1] * ry, q.radii[2] * rz)
            out[n] = (M._Primitive(q.frame, q.s + dz, q.offset, r, q.group, q.axial) if q.axial else
                      M._Primitive(q.frame, q.s, (q.offset[0], q.offset[1], q.offset[2] + dz * hh), r, q.group,
                                   q.axial))
        return out
    return prims


def signed_distances(cs, change=None, keys=None) -> list:
    """Per case, the vertices' signed distance (N,) metres to the soft body (``change``, ``keys``: :func:`_layout`)."""
    import toolkit.softbody.model as M
    from toolkit.softbody import SoftBodyModel
    from toolkit.softbody.distance import distance

    base = M._primitives
    if change is not None:
        M._primitives = _layout(change, keys)
    try:
        return [distance(SoftBodyModel(c[0].proportions, girth=c[0].body.shape.girth), c[1], c[2]) for c in cs]
    finally:
        M._primitives = base


def summary(cs, ds, outer: bool = False) -> dict:
    """``{row: (median mm, mean |d| mm, n)}`` per part and per torso height band (``outer``: outer-surface vertices)."""
    from toolkit.skeleton import SKELETON_14

    names = ("background",) + tuple(SKELETON_14.part_names)
    torso = names.index("torso")
    rows = {}
    for (_, _, _, part, z, out), d in zip(cs, ds):
        use = out if outer else np.ones(len(d), bool)
        for k in np.unique(part):
            if k:
                rows.setdefault(names[k], []).append(d[use & (part == k)])
        for lo in np.arange(-0.2, 0.8, 0.1):
            sel = use & (part == torso) & (z >= lo) & (z < lo + 0.1)
            rows.setdefault(f"torso z {lo:+.1f}..{lo + 0.1:+.1f} m", []).append(d[sel])
    res = {}
    for k, v in rows.items():
        v = np.concatenate(v)
        if len(v):
            res[k] = (1000 * float(np.median(v)), 1000 * float(np.mean(np.abs(v))), len(v))
    return res


def fit(cs, groups, *, outer: bool = True, max_nfev: int = 25, stride: int = 3):
    """Refit the primitives of ``groups`` (:data:`GROUPS`) to the cases' vertices of the groups' parts.

    Parameters
    ----------
    cs : list
        :func:`cases`.
    groups : sequence of str
    outer : bool
        Fit to the outer-surface vertices only.
    max_nfev : int
        Evaluations of ``scipy.optimize.least_squares``.
    stride : int
        Every ``stride``-th selected vertex is used.

    Returns
    -------
    keys : list of str
    change : ndarray of shape (4 len(keys),)
        As :func:`_layout`.
    """
    from scipy.optimize import least_squares
    from toolkit.skeleton import SKELETON_14

    names = ("background",) + tuple(SKELETON_14.part_names)
    parts = [names.index(n) for g in groups for n in GROUPS[g][1]]
    thighs = [names.index(n) for n in ("l_thigh", "r_thigh")]
    sub = []
    for sc, p, v, part, z, out in cs:
        use = np.isin(part, parts)
        if "trunk" in groups:
            use |= np.isin(part, thighs) & (z > -THIGH_TOP)
        if outer:
            use &= out
        idx = np.flatnonzero(use)[::stride]
        sub.append((sc, p, v[idx], part[idx], z[idx], out[idx]))
    keys = group_keys(groups)

    def residuals(x):
        return np.concatenate(signed_distances(sub, x, keys))

    x0 = np.tile([1.0, 1.0, 1.0, 0.0], len(keys))
    lo, hi = np.tile([0.6, 0.6, 0.5, -0.08], len(keys)), np.tile([1.5, 1.5, 2.0, 0.08], len(keys))
    sol = least_squares(residuals, x0, loss="soft_l1", f_scale=0.01, diff_step=1e-3, max_nfev=max_nfev,
                        bounds=(lo, hi))
    return keys, sol.x


def _print(cs, ds) -> None:
    a, o = summary(cs, ds), summary(cs, ds, outer=True)
    print(f"  {'':24s} {'all vertices':>31s}   {'outer surface':>31s}")
    for k, (med, mad, n) in a.items():
        om, oa, on = o.get(k, (np.nan, np.nan, 0))
        print(f"  {k:24s} median {med:+6.1f} mean |d| {mad:5.1f} ({n:5d})   "
              f"median {om:+6.1f} mean |d| {oa:5.1f} ({on:5d})")


def noiseless(seeds, frames=(0, 3, 6, 9), n_points: int = 1500, outer: bool = False) -> list:
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
                tri = m.triangles
                if outer:
                    tri = tri[(~buried(m))[tri].any(1)]
                tm = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(m.vertices),
                                               o3d.utility.Vector3iVector(tri))
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
    ap.add_argument("--fit", action="store_true", help="refit the metaballs of --groups")
    ap.add_argument("--groups", nargs="+", choices=sorted(GROUPS), default=["trunk"],
                    help="the primitives --fit changes (default: trunk)")
    ap.add_argument("--max-nfev", type=int, default=25, help="least_squares evaluations of --fit (default 25)")
    ap.add_argument("--all-vertices", action="store_true",
                    help="--fit to every vertex of the parts, the buried ones too (default: outer surface)")
    ap.add_argument("--noiseless", action="store_true",
                    help="the global fit on noiseless points of the true bodies of these seeds' scenes")
    ap.add_argument("--outer", action="store_true", help="--noiseless: points on the outer surface only")
    args = ap.parse_args(argv)
    if args.noiseless:
        print(f"{'scene':<30}{'tracking mm':>13}{'global fit mm':>15}{'mid-hip dz mm':>15}{'lengths mm':>12}")
        for name, trk, glb, hip, lerr in noiseless(args.seeds, outer=args.outer):
            print(f"{name:<30}{trk:>13.1f}{glb:>15.1f}{hip:>+15.0f}{lerr:>12.1f}", flush=True)
        return 0
    cs = cases(args.seeds)
    print(f"{len(cs)} meshes (seeds {args.seeds})")
    _print(cs, signed_distances(cs))
    if not args.fit:
        return 0
    keys, x = fit(cs, args.groups, outer=not args.all_vertices, max_nfev=args.max_nfev)
    print("change (rx, ry, rz multipliers and dz) per primitive:")
    for i, k in enumerate(keys):
        print(f"  {k:14s}", json.dumps(np.round(x[4 * i:4 * i + 4], 3).tolist()))
    _print(cs, signed_distances(cs, x, keys))
    return 0


if __name__ == "__main__":
    sys.exit(main())
