"""Multi-view selection of 2D pose candidates (source 000, §2.1 and claims 5-6).

Each view brings ``k`` candidate 2D poses (the ``k = 3`` best database
silhouettes in the source, or one detector pose).  For every combination of
one candidate per view, rays are cast from each camera centre through the
candidate's joints; every joint gets the 3D point closest to its rays; the
combination's cost is the mean distance of the rays to their points (the
source sums them, see :func:`~toolkit.multiview.offsets.mean_ray_distance`).
Per-view 2D offsets are optimised jointly by Levenberg-Marquardt to absorb
calibration error (:func:`~toolkit.multiview.offsets.fit_offsets`).  The
combination of smallest cost gives each view its pose, the 3D joints and the
offsets.

Left/right swaps: flipped copies of every candidate join the search
(``MultiViewConfig.flips``), so a view whose candidate has left and right
exchanged is matched to the others the right way round.  Geometry alone cannot
tell a combination from its mirror (every view flipped the other way: the
same rays with left and right relabelled, exactly the same cost); such ties
go to the combination closest to the previous frame's 3D pose when one is
given, then to the one whose knees bend forward and elbows backward
(:func:`~toolkit.multiview.anatomy.chirality_score`, when the limbs are bent
enough to tell), then to the one with fewer flipped views, then to
better-ranked candidates.

Speed: all combinations are first scored without offsets in one vectorised
pass; then, best first, at most ``refine_top`` of them are refined by
Levenberg-Marquardt, stopping at the first whose unrefined cost exceeds
``refine_ratio`` times the best refined cost so far (the offsets lower a wrong
combination's cost by a few per cent, the right one's by up to a half).  A
mirror combination is never optimised twice: its fit is the other's with the
joints relabelled.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from toolkit.cameras import Rig, closest_point_to_rays
from toolkit.errors import InputError
from toolkit.multiview.anatomy import chirality_score
from toolkit.multiview.config import MultiViewConfig
from toolkit.multiview.offsets import OffsetFit, fit_offsets, mean_ray_distance, triangulate_views
from toolkit.observe import Observer, as_observer
from toolkit.skeleton import SKELETON_14, Skeleton

#: Report-name prefix of everything this module reports.
REPORT_PREFIX = "multiview"
#: Rays are drawn from the camera centre to this factor times the distance to their joint.
RAY_DRAW_FACTOR = 1.15
#: Smallest radius of the reported closest points, metres.
CLOSEST_POINT_RADIUS_M = 0.005
#: Combinations listed in the text report, best first.
REPORTED_COMBINATIONS = 12


@dataclass(frozen=True, eq=False)
class MultiViewSelection:
    """Result of :func:`select_multiview`.

    Attributes
    ----------
    choice : ndarray of shape (n_views,) of int
        Chosen candidate per view, index into the ``k`` candidates given; -1 for a
        view that took no part (no candidate, or dropped by the robust mode).
    flip : ndarray of shape (n_views,) of object
        Flip applied to the chosen candidate: ``""`` (none), ``"all"``, ``"arms"``, ``"legs"``.
    poses2d_raw : ndarray of shape (n_views, n_joints, 2)
        The chosen candidates (flip applied), pixels; NaN for unused views.
    poses2d : ndarray of shape (n_views, n_joints, 2)
        Offset-corrected: ``poses2d_raw + offsets[:, None]``.
    joints3d : ndarray of shape (n_joints, 3)
        Metres, world frame; NaN where fewer than two rays.
    offsets : ndarray of shape (n_views, 2)
        Pixels, added to the 2D joints.
    ray_distances : ndarray of shape (n_views, n_joints)
        Metres, NaN for missing rays.
    reprojection_errors : ndarray of shape (n_views, n_joints)
        Pixels between projected 3D joints and ``poses2d``.
    cost : float
        Mean ray distance of the chosen combination, metres (``inf`` without a result).
    combinations : ndarray of shape (n_combinations, n_views) of int
        Every combination evaluated, as indices into the extended candidate list
        (``flip_index * k + candidate``, flip 0 = as given, then ``config.flips`` in order;
        -1 = view absent).
    combination_costs : ndarray of shape (n_combinations,)
        Mean ray distance of each combination, metres: after Levenberg-Marquardt for the
        refined ones, without offsets for the others.
    refined : ndarray of shape (n_combinations,) of bool
    best : int
        Row of ``combinations`` chosen (-1 without a result).
    views_used : ndarray of shape (n_views,) of bool
    violations : tuple of str
        Broken anthropometric constraints of ``joints3d`` (reported, not enforced).
    success : bool
    message : str
    """

    choice: np.ndarray
    flip: np.ndarray
    poses2d_raw: np.ndarray
    poses2d: np.ndarray
    joints3d: np.ndarray
    offsets: np.ndarray
    ray_distances: np.ndarray
    reprojection_errors: np.ndarray
    cost: float
    combinations: np.ndarray
    combination_costs: np.ndarray
    refined: np.ndarray
    best: int
    views_used: np.ndarray
    violations: tuple
    success: bool
    message: str

    def __bool__(self) -> bool:
        return self.success

    @property
    def flipped(self) -> np.ndarray:
        """(n_views,) bool: the chosen candidate was flipped."""
        return np.array([f != "" for f in self.flip], bool)


# ---------------------------------------------------------------- candidates
def flip_permutation(skeleton: Skeleton, mode: str) -> np.ndarray:
    """Joint permutation swapping left and right for a group of joints.

    Parameters
    ----------
    skeleton : Skeleton
    mode : str
        ``"all"``, ``"arms"`` (shoulders, elbows, wrists) or ``"legs"`` (hips, knees, ankles).

    Returns
    -------
    ndarray of shape (n_joints,) of int
        ``pose[perm]`` is the flipped pose.
    """
    full = skeleton.flip_permutation
    if mode == "all":
        return full
    groups = {"arms": ("shoulder", "elbow", "wrist", "hand"), "legs": ("hip", "knee", "ankle", "foot")}
    if mode not in groups:
        raise InputError("flip mode", "'all', 'arms' or 'legs'", repr(mode))
    perm = np.arange(skeleton.n_joints)
    for i, name in enumerate(skeleton.joint_names):
        if name[2:] in groups[mode] and name[:2] in ("l_", "r_"):
            perm[i] = full[i]
    return perm


def extend_candidates(candidates: np.ndarray, weights: np.ndarray | None, flips: tuple[str, ...],
                      skeleton: Skeleton = SKELETON_14):
    """Candidates followed by their flipped copies.

    Parameters
    ----------
    candidates : ndarray of shape (n_views, k, n_joints, 2)
    weights : ndarray of shape (n_views, k, n_joints) or None
    flips : tuple of str

    Returns
    -------
    extended : ndarray of shape (n_views, k * (1 + len(flips)), n_joints, 2)
    extended_weights : ndarray of shape (n_views, k * (1 + len(flips)), n_joints)
    """
    c = np.asarray(candidates, float)
    w = np.ones(c.shape[:3]) if weights is None else np.asarray(weights, float)
    perms = [np.arange(skeleton.n_joints)] + [flip_permutation(skeleton, f) for f in flips]
    return (np.concatenate([c[:, :, p] for p in perms], axis=1),
            np.concatenate([w[:, :, p] for p in perms], axis=1))


def _check(candidates, rig, weights, skeleton):
    c = np.asarray(candidates, float)
    n_views = len(rig)
    if c.ndim != 4 or c.shape[0] != n_views or c.shape[2] != skeleton.n_joints or c.shape[3] != 2:
        raise InputError("candidates", f"an array of shape ({n_views}, k, {skeleton.n_joints}, 2) "
                         "(views, candidates, joints, pixels)", f"shape {c.shape}")
    if c.shape[1] < 1:
        raise InputError("candidates", "at least one candidate per view", "k = 0")
    if np.any(np.isinf(c)):
        raise InputError("candidates", "finite pixels or NaN", "infinite values")
    if weights is not None:
        w = np.asarray(weights, float)
        if w.shape != c.shape[:3]:
            raise InputError("weights", f"an array of shape {c.shape[:3]}", f"shape {w.shape}")
        if np.any(w < 0):
            raise InputError("weights", "non-negative weights", "negative values")
    if n_views < 2:
        raise InputError("rig", "at least two cameras", f"{n_views}")
    return c


# ------------------------------------------------------------------ scoring
def score_combinations(rig: Rig, extended: np.ndarray, weights: np.ndarray, combinations: np.ndarray,
                       offsets: np.ndarray | None = None) -> np.ndarray:
    """Mean ray distance of every combination with fixed offsets, vectorised.

    Parameters
    ----------
    rig : Rig
    extended : ndarray of shape (n_views, K, n_joints, 2)
        Candidates, pixels.
    weights : ndarray of shape (n_views, K, n_joints)
    combinations : ndarray of shape (C, n_views) of int
        Candidate index per view, -1 = view absent.
    offsets : ndarray of shape (n_views, 2), optional

    Returns
    -------
    ndarray of shape (C,)
        Metres; ``inf`` where no joint has two rays.
    """
    n_views = len(rig)
    off = np.zeros((n_views, 2)) if offsets is None else offsets
    uv = extended + off[:, None, None, :]
    O, D = [], []
    for v, cam in enumerate(rig):
        o, d = cam.rays(uv[v])  # (K, J, 3)
        idx = combinations[:, v]
        dv = np.where((idx >= 0)[:, None, None], d[np.maximum(idx, 0)], np.nan)
        O.append(np.broadcast_to(cam.center, dv.shape))
        D.append(dv)
    W = np.stack([np.where((combinations[:, v] >= 0)[:, None], weights[v][np.maximum(combinations[:, v], 0)], 0.0)
                  for v in range(n_views)])
    X, dist = closest_point_to_rays(np.stack(O), np.stack(D), W)
    dist = np.where(np.isfinite(X).all(-1)[None], dist, np.nan)
    return mean_ray_distance(dist, W, axis=(0, 2))


def _enumerate(ext: np.ndarray, ext_w: np.ndarray, max_combinations: int) -> np.ndarray:
    """All combinations of present candidates, (C, n_views); absent views get -1."""
    present = (np.isfinite(ext).all(-1) & (ext_w > 0)).any(-1)  # (V, K)
    lists = [np.flatnonzero(p).tolist() or [-1] for p in present]
    n = int(np.prod([len(x) for x in lists], dtype=float))
    if n > max_combinations:
        raise InputError("candidates", f"at most {max_combinations} combinations (MultiViewConfig.max_combinations)",
                         f"{n} = " + " x ".join(str(len(x)) for x in lists))
    return np.array(list(itertools.product(*lists)), dtype=int).reshape(-1, len(lists))


def _prefer_plausible(order, costs, fits, cfg: MultiViewConfig) -> list:
    """The combinations to choose from: ``order``, or only its plausible ones when the cheapest is not plausible.

    A combination is plausible when its 3D skeleton is within
    ``cfg.plausible_excess`` of the anthropometric rules
    (:meth:`~toolkit.anthropometry.AnthropometricConstraints.excess`); when the
    cheapest is not, the plausible ones whose cost is at most
    ``cfg.plausible_cost_ratio`` times the best cost are kept (in cost order),
    if there are any.  Two views far apart can
    make a wrong candidate's rays meet as well as the right one's, with a
    forearm a metre long: the ray cost alone cannot see that.
    """
    if cfg.constraints is None or cfg.plausible_cost_ratio <= 1 or not order:
        return order

    def plausible(i):
        J = fits[i].joints3d
        return bool(np.isfinite(J).all()) and cfg.constraints.excess(J) <= cfg.plausible_excess

    if plausible(order[0]):
        return order
    limit = costs[order[0]] * cfg.plausible_cost_ratio
    front = [i for i in order[1:] if costs[i] <= limit and plausible(i)]
    return front or order


def _tie_break(order, costs, combos, k, previous_joints3d, fits, cfg: MultiViewConfig, skeleton: Skeleton):
    """Among the combinations tied with the best, the preferred one (see the module docstring)."""
    best = order[0]
    tied = [i for i in order if costs[i] <= costs[best] * (1 + cfg.tie_relative) + 1e-12]
    if len(tied) == 1:
        return best

    def key(i):
        c = combos[i]
        flips = int(np.sum((c >= k)))
        rank = int(np.sum(np.where(c >= 0, c % k, 0)))
        prev = 0.0
        if previous_joints3d is not None:
            d = np.linalg.norm(fits[i].joints3d - previous_joints3d, axis=-1)
            prev = float(np.nanmean(d)) if np.isfinite(d).any() else np.inf
        anatomy = 0
        if cfg.anatomy_tie_break:
            s = chirality_score(fits[i].joints3d, skeleton, cfg.up)
            anatomy = 0 if s > cfg.chirality_min_m else (2 if s < -cfg.chirality_min_m else 1)
        return (prev, anatomy, flips, rank, costs[i])

    return min(tied, key=key)


def _mirror_slots(flips: tuple[str, ...], skeleton: Skeleton) -> list[tuple[np.ndarray, np.ndarray]]:
    """Flips ``g`` under which the set of candidate slots is closed.

    Returns, per such ``g``, the slot table (slot ``s`` -> slot of ``s`` followed by ``g``;
    slot 0 = as given, then ``flips`` in order) and ``g``'s joint permutation.
    """
    perms = [np.arange(skeleton.n_joints)] + [flip_permutation(skeleton, f) for f in flips]

    def slot(perm):
        for s, p in enumerate(perms):
            if np.array_equal(p, perm):
                return s
        return None

    out = []
    for g in range(1, len(perms)):
        table = [slot(perms[s][perms[g]]) for s in range(len(perms))]
        if all(t is not None for t in table):
            out.append((np.array(table), perms[g]))
    return out


def _permuted(fit: OffsetFit, perm: np.ndarray) -> OffsetFit:
    """The fit of the mirror combination: joints relabelled by ``perm``."""
    return OffsetFit(offsets=fit.offsets, joints3d=fit.joints3d[perm], ray_distances=fit.ray_distances[:, perm],
                     reprojection_errors=fit.reprojection_errors[:, perm], cost=fit.cost, active=fit.active,
                     success=fit.success, message=fit.message, nfev=0)


# ----------------------------------------------------------------- reporting
def _report(obs: Observer, rig: Rig, candidates, sel: MultiViewSelection, ray_origins, ray_ends,
            frame, skeleton: Skeleton, prefix: str = REPORT_PREFIX):
    P = prefix
    extra = {} if frame is None else {"frame": frame}
    for v, cam in enumerate(rig):
        for i in range(candidates.shape[1]):
            if np.isfinite(candidates[v, i]).any():
                obs.report("joints2d", camera=cam.name, joints=candidates[v, i], name=f"{P}/candidate_{i}",
                           skeleton=skeleton, **extra)
        if sel.views_used[v]:
            obs.report("joints2d", camera=cam.name, joints=sel.poses2d[v], name=f"{P}/chosen",
                       skeleton=skeleton, **extra)
            raw, cor = sel.poses2d_raw[v], sel.poses2d[v]
            ok = np.isfinite(raw).all(-1)
            obs.report("lines2d", camera=cam.name, strips=[np.stack([raw[j], cor[j]]) for j in np.flatnonzero(ok)],
                       name=f"{P}/offset", **extra)
            obs.report("scalar", name=f"{P}/offset_px/{cam.name}/x", value=float(sel.offsets[v, 0]), **extra)
            obs.report("scalar", name=f"{P}/offset_px/{cam.name}/y", value=float(sel.offsets[v, 1]), **extra)
    X = sel.joints3d
    if ray_origins is not None:
        obs.report("rays", origins=ray_origins, ends=ray_ends, name=f"{P}/rays", **extra)
    rd = np.where(np.isfinite(sel.ray_distances), sel.ray_distances, -np.inf).max(axis=0)
    radii = np.where(np.isfinite(rd), rd, 0.0) + CLOSEST_POINT_RADIUS_M  # a sphere as large as the worst ray miss
    obs.report("points3d", points=X, radii=radii, name=f"{P}/closest_points", **extra)
    obs.report("joints3d", joints=X, name=f"{P}/joints3d", skeleton=skeleton, **extra)
    obs.report("scalar", name=f"{P}/cost_mm", value=1000 * sel.cost if np.isfinite(sel.cost) else np.nan, **extra)
    per_joint = mean_ray_distance(sel.ray_distances, axis=0)
    for j, name in enumerate(skeleton.joint_names):
        if np.isfinite(per_joint[j]):
            obs.report("scalar", name=f"{P}/ray_distance_mm/{name}", value=1000 * float(per_joint[j]), **extra)
    order = np.argsort(sel.combination_costs)[:REPORTED_COMBINATIONS]
    lines = [f"{len(sel.combination_costs)} combinations, {int(sel.refined.sum())} refined by LM; best first:"]
    for i in order:
        c = sel.combinations[i]
        mark = "*" if i == sel.best else " "
        lines.append(f"{mark} {c.tolist()} cost {1000 * sel.combination_costs[i]:.1f} mm"
                     + (" (LM)" if sel.refined[i] else ""))
    obs.report("text", name=f"{P}/combinations", text="\n".join(lines), **extra)
    obs.report("text", name=f"{P}/anthropometry",
               text="\n".join(sel.violations) if sel.violations else "all anthropometric constraints hold",
               **extra)


# ----------------------------------------------------------------- selection
def _empty(n_views, n_joints, combos, costs, refined, message) -> MultiViewSelection:
    nan2 = np.full((n_views, n_joints, 2), np.nan)
    return MultiViewSelection(
        choice=np.full(n_views, -1), flip=np.array([""] * n_views, dtype=object), poses2d_raw=nan2,
        poses2d=nan2.copy(), joints3d=np.full((n_joints, 3), np.nan), offsets=np.zeros((n_views, 2)),
        ray_distances=np.full((n_views, n_joints), np.nan), reprojection_errors=np.full((n_views, n_joints), np.nan),
        cost=float("inf"), combinations=combos, combination_costs=costs, refined=refined, best=-1,
        views_used=np.zeros(n_views, bool), violations=(), success=False, message=message)


def _robust_masks(fit: OffsetFit, w: np.ndarray, cfg: MultiViewConfig):
    """Weights with the outlying view or rays of ``fit`` removed, or None when nothing to drop."""
    e = np.where(w > 0, fit.reprojection_errors, np.nan)
    used = np.isfinite(e).any(axis=1)
    new_w = w.copy()
    if used.sum() >= 3:
        med = np.array([np.nanmedian(e[v]) if used[v] else np.nan for v in range(len(e))])
        worst = int(np.nanargmax(med))
        others = np.nanmedian(np.delete(med, worst))
        if med[worst] > cfg.robust_view_px and med[worst] > cfg.robust_view_ratio * others:
            new_w[worst] = 0.0
            return new_w
    rays_per_joint = np.isfinite(e).sum(axis=0)
    bad = np.nan_to_num(e) > cfg.robust_ray_px
    # drop only the worst ray of a joint, and only when two others remain
    worst_ray = np.nanargmax(np.where(np.isfinite(e), e, -1), axis=0)
    drop = np.zeros_like(bad)
    drop[worst_ray, np.arange(e.shape[1])] = True
    drop &= bad & (rays_per_joint >= 3)[None]
    if drop.any():
        new_w[drop] = 0.0
        return new_w
    return None


def _check_start(initial_offsets, previous_joints3d, n_views: int, n_joints: int):
    """Check the starting offsets and the previous frame's joints.

    Parameters
    ----------
    initial_offsets : array_like of shape (n_views, 2) or None
        Pixels.
    previous_joints3d : array_like of shape (n_joints, 3) or None
        Metres.
    n_views, n_joints : int

    Returns
    -------
    init : ndarray of shape (n_views, 2)
        The offsets (zeros when not given).
    previous_joints3d : ndarray of shape (n_joints, 3) or None

    Raises
    ------
    InputError
        A wrong shape or non-finite offsets.
    """
    if initial_offsets is not None:
        init = np.asarray(initial_offsets, float)
        if init.shape != (n_views, 2) or not np.all(np.isfinite(init)):
            raise InputError("initial_offsets", f"a finite array of shape ({n_views}, 2)", f"shape {init.shape}")
    else:
        init = np.zeros((n_views, 2))
    if previous_joints3d is not None:
        previous_joints3d = np.asarray(previous_joints3d, float)
        if previous_joints3d.shape != (n_joints, 3):
            raise InputError("previous_joints3d", f"an array of shape ({n_joints}, 3)",
                             f"shape {previous_joints3d.shape}")
    return init, previous_joints3d


def _combo_arrays(ext: np.ndarray, ext_w: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 2D poses and weights of one combination.

    Parameters
    ----------
    ext : ndarray of shape (n_views, K, n_joints, 2)
        Extended candidates (flips included), pixels.
    ext_w : ndarray of shape (n_views, K, n_joints)
        Their weights.
    c : ndarray of int, shape (n_views,)
        The candidate of each view (-1: the view takes no part).

    Returns
    -------
    pts : ndarray of shape (n_views, n_joints, 2)
        NaN for views taking no part.
    w : ndarray of shape (n_views, n_joints)
        0 for views taking no part.
    """
    n_views, n_joints = ext.shape[0], ext.shape[2]
    pts = np.stack([ext[v, c[v]] if c[v] >= 0 else np.full((n_joints, 2), np.nan) for v in range(n_views)])
    w = np.stack([ext_w[v, c[v]] if c[v] >= 0 else np.zeros(n_joints) for v in range(n_views)])
    return pts, w


def _refine_leading(order: list, combos: np.ndarray, costs: np.ndarray, ext: np.ndarray, ext_w: np.ndarray, k: int,
                    rig: Rig, cfg: MultiViewConfig, init: np.ndarray, skeleton: Skeleton) -> dict:
    """Fit the offsets of the best-screening combinations (up to ``cfg.refine_top`` classes), their mirrors for free.

    Parameters
    ----------
    order : list of int
        Combinations with a finite screening cost, cheapest first.
    combos : ndarray of int, shape (n_combinations, n_views)
    costs : ndarray of shape (n_combinations,)
        Screening costs.
    ext : ndarray of shape (n_views, K, n_joints, 2)
    ext_w : ndarray of shape (n_views, K, n_joints)
    k : int
        Candidates per view before the flips (combination entry ``x`` is flip ``x // k`` of candidate ``x % k``).
    rig : Rig
    cfg : MultiViewConfig
    init : ndarray of shape (n_views, 2)
        Starting offsets, pixels.
    skeleton : Skeleton

    Returns
    -------
    dict of int to OffsetFit
        The fit of every refined combination (mirrors included).
    """
    fits: dict[int, OffsetFit] = {}
    row_of = {tuple(c): i for i, c in enumerate(combos.tolist())}
    mirrors = _mirror_slots(cfg.flips, skeleton)

    n_classes, best_refined, best_screened = 0, np.inf, np.inf
    for i in order:
        if i in fits:
            continue
        # costs only grow along ``order``; a combination that screens as well as the best
        # refined one (e.g. its mirror among the candidates) is always refined, for the tie-break
        limit = max(cfg.refine_ratio * best_refined, best_screened * (1 + cfg.tie_relative))
        if n_classes == cfg.refine_top or costs[i] > limit:
            break
        n_classes += 1
        pts, w = _combo_arrays(ext, ext_w, combos[i])
        f = fit_offsets(pts, rig, cfg, weights=w, initial_offsets=init)
        fits[i] = f
        if f.cost < best_refined:
            best_refined, best_screened = f.cost, costs[i]
        # mirror combinations (every view flipped by the same flip g) give the same fit with
        # the joints relabelled: no need to optimise them again
        for table, perm in mirrors:
            c = combos[i]
            m = tuple(int(table[x // k] * k + x % k) if x >= 0 else -1 for x in c)
            j = row_of.get(m)
            if j is not None and j not in fits:
                fits[j] = _permuted(f, perm)
    return fits


def _robust_refit(fit: OffsetFit, pts: np.ndarray, w: np.ndarray, rig: Rig, cfg: MultiViewConfig,
                  init: np.ndarray) -> tuple[OffsetFit, np.ndarray, str]:
    """Robust mode: drop the outlying joints or views (:func:`_robust_masks`) and fit again, until none is left.

    Parameters
    ----------
    fit : OffsetFit
        The chosen combination's fit.
    pts : ndarray of shape (n_views, n_joints, 2)
        Its 2D poses, pixels.
    w : ndarray of shape (n_views, n_joints)
        Its weights.
    rig : Rig
    cfg : MultiViewConfig
    init : ndarray of shape (n_views, 2)

    Returns
    -------
    fit : OffsetFit
    w : ndarray of shape (n_views, n_joints)
        The weights left.
    message : str
        The views dropped, for the selection's message ("" when none).
    """
    n_views, n_joints = w.shape
    w0 = w
    message = ""
    for _ in range(n_views * n_joints):
        new_w = _robust_masks(fit, w, cfg)
        if new_w is None:
            break
        w = new_w
        fit = fit_offsets(pts, rig, cfg, weights=w, initial_offsets=init)
    dropped = ~(w > 0).any(axis=1) & (w0 > 0).any(axis=1)
    if dropped.any():
        message += f"; robust mode dropped view(s) {[rig[int(v)].name for v in np.flatnonzero(dropped)]}"
    return fit, w, message


def select_multiview(candidates: np.ndarray, rig: Rig, config: MultiViewConfig | None = None, *,
                     weights: np.ndarray | None = None, initial_offsets: np.ndarray | None = None,
                     previous_joints3d: np.ndarray | None = None, observer: Observer | None = None,
                     frame: int | None = None, skeleton: Skeleton = SKELETON_14,
                     report_prefix: str = REPORT_PREFIX) -> MultiViewSelection:
    """Choose one 2D pose per view and triangulate it with per-view offsets.

    Parameters
    ----------
    candidates : ndarray of shape (n_views, k, n_joints, 2)
        Candidate 2D poses per view, pixels; NaN for a missing joint, an all-NaN
        candidate is absent, a view without candidates takes no part.
    rig : Rig
        ``n_views >= 2`` cameras in the order of ``candidates``.
    config : MultiViewConfig, optional
    weights : ndarray of shape (n_views, k, n_joints), optional
        Non-negative joint confidences; 0 drops a joint.
    initial_offsets : ndarray of shape (n_views, 2), optional
        Starting offsets, pixels (the previous frame's, for video).
    previous_joints3d : ndarray of shape (n_joints, 3), optional
        The previous frame's 3D joints; break ties between mirror combinations.
    observer : Observer, optional
        Receives the candidates, chosen poses, offsets, rays, closest points, ray
        distances, combination costs and anthropometric report (names ``multiview/...``).
    frame : int, optional
        Passed on with every report.
    skeleton : Skeleton
        Joint names and left/right pairs (default the 14-joint skeleton).
    report_prefix : str
        First part of the report names (default ``"multiview"``); a second
        triangulation of the same frame (pooled or corrected poses) uses its own
        prefix so that it does not overwrite the selection's reports.

    Returns
    -------
    MultiViewSelection
        ``success=False`` (and NaN joints) when fewer than two views share joints;
        never an exception for missing data.

    Raises
    ------
    InputError
        Arrays of the wrong shape, infinite pixels, negative weights, fewer than two
        cameras, more combinations than ``config.max_combinations``.
    """
    cfg = config or MultiViewConfig()
    obs = as_observer(observer)
    cand = _check(candidates, rig, weights, skeleton)
    n_views, k, n_joints = cand.shape[:3]
    init, previous_joints3d = _check_start(initial_offsets, previous_joints3d, n_views, n_joints)
    ext, ext_w = extend_candidates(cand, weights, cfg.flips, skeleton)
    ext_w = np.where(np.isfinite(ext).all(-1), ext_w, 0.0)
    ext = np.where((ext_w > 0)[..., None], ext, np.nan)
    flip_names = ("",) + cfg.flips
    combos = _enumerate(ext, ext_w, cfg.max_combinations)
    costs = score_combinations(rig, ext, ext_w, combos, init)
    refined = np.zeros(len(combos), bool)
    order = np.argsort(costs, kind="stable")
    order = [i for i in order if np.isfinite(costs[i])]
    if not order:
        sel = _empty(n_views, n_joints, combos, costs, refined, "no joint is seen by two views")
        _report(obs, rig, cand, sel, None, None, frame, skeleton, report_prefix)
        return sel

    fits = _refine_leading(order, combos, costs, ext, ext_w, k, rig, cfg, init, skeleton)

    for i, f in fits.items():
        costs[i] = f.cost
        refined[i] = True
    order = sorted(fits, key=lambda i: costs[i])
    order = _prefer_plausible(order, costs, fits, cfg)
    best = _tie_break(order, costs, combos, k, previous_joints3d, fits, cfg, skeleton)
    fit = fits[best]
    pts, w = _combo_arrays(ext, ext_w, combos[best])
    message = fit.message
    if cfg.robust:
        fit, w, dropped_msg = _robust_refit(fit, pts, w, rig, cfg, init)
        message += dropped_msg
    used = (w > 0).any(axis=1) & np.isfinite(fit.ray_distances).any(axis=1)
    c = combos[best]
    raw = np.where(used[:, None, None], pts, np.nan)
    violations = ()
    if cfg.constraints is not None:  # reported, not enforced: 2D candidates can be noisy
        violations = tuple(str(v) for v in cfg.constraints.violations(fit.joints3d))
    sel = MultiViewSelection(
        choice=np.where(used, np.where(c >= 0, c % k, -1), -1),
        flip=np.array([flip_names[c[v] // k] if used[v] and c[v] >= 0 else "" for v in range(n_views)], dtype=object),
        poses2d_raw=raw, poses2d=raw + fit.offsets[:, None, :], joints3d=fit.joints3d,
        offsets=np.where(used[:, None], fit.offsets, 0.0),
        ray_distances=np.where(w > 0, fit.ray_distances, np.nan),
        reprojection_errors=np.where(w > 0, fit.reprojection_errors, np.nan),
        cost=float(fit.cost), combinations=combos, combination_costs=costs, refined=refined, best=int(best),
        views_used=used, violations=violations, success=bool(fit.success), message=message)
    _report(obs, rig, cand, sel, *_ray_segments(rig, sel, w), frame, skeleton, report_prefix)
    return sel


def _ray_segments(rig: Rig, sel: MultiViewSelection, w: np.ndarray):
    """Start and end points (N, 3) of the used rays, drawn a little past their joint's point."""
    if not sel.views_used.any():
        return None, None
    uvs = np.where((w > 0)[..., None], sel.poses2d, np.nan)
    o, d, _, _ = triangulate_views(rig, uvs)
    X = np.broadcast_to(sel.joints3d[None], o.shape)
    along = np.sum((X - o) * d, axis=-1, keepdims=True)
    ends = (o + RAY_DRAW_FACTOR * along * d).reshape(-1, 3)
    o = o.reshape(-1, 3)
    ok = np.isfinite(ends).all(-1) & np.isfinite(o).all(-1)
    return o[ok], ends[ok]
