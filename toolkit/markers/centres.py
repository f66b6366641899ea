"""Centres and axes of rotation between two rigid marker subsets.

Two methods of Ehrig, Taylor, Duda and Heller, both linear least squares on the
rigid motions of the two subsets (``x_world = R_t x_local + t_t`` per frame,
from :func:`toolkit.markers.rigid.rigid_motions`):

* **SCoRE**, the symmetrical centre of rotation estimation (Ehrig et al. 2006,
  "A survey of formal methods for determining the centre of rotation of ball
  joints", J Biomech 39:2798-2809): the point fixed in both segments' frames,
  ``c_p`` in the parent's and ``c_c`` in the child's, minimising
  ``sum_t |R_p,t c_p + t_p,t - R_c,t c_c - t_c,t|^2``.  Neither segment needs
  to stand still and the soft-tissue errors of both enter symmetrically.
* **SARA**, the symmetrical axis of rotation approach (Ehrig et al. 2007, "A
  survey of formal methods for determining functional joint axes", J Biomech
  40:2150-2157): for a hinge (knee, elbow) the same system has a one-dimensional
  null space whose right singular vector gives the axis in both frames; the
  points of the axis are the least-squares solution plus any multiple of it.
  Where on the axis the joint centre lies is not observable from the motion; it
  is taken from an anatomical estimate (the scaled generic skeleton's joint,
  projected onto the axis).

:func:`sphere_centre` and :func:`circle_axis` serve a child with no rigid
motion of its own (fewer than three markers, or markers nearly on one line):
its markers' spheres (a ball joint) or circles (a hinge) in the parent's frame.

The linear algebra is numpy's (``lstsq``, ``svd``); relative orientations and
their spread (the range of motion) use ``scipy.spatial.transform.Rotation``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError

#: How a joint centre was obtained.
METHODS = ("score", "sara", "sphere", "circle", "generic", "none")


@dataclass(frozen=True)
class CentreFit:
    """A centre (and for SARA an axis) of rotation between a parent and a child subset.

    Attributes
    ----------
    method : str
        ``"score"``, ``"sara"``, ``"sphere"`` or ``"circle"``.
    local_parent, local_child : ndarray of shape (3,)
        The centre in the parent's and the child's reference frames, metres.
    axis_parent, axis_child : ndarray of shape (3,) or None
        SARA: unit axis direction in each frame; None for SCoRE.
    centre : ndarray of shape (T, 3)
        The centre in the world per frame (mean of the two segments' estimates
        where both are seen), NaN where neither segment is.
    axis : ndarray of shape (T, 3) or None
        SARA: the axis direction in the world per frame (from the parent).
    residual_m : float
        RMS over frames of the distance between the parent's and the child's
        estimate of the centre, metres.
    rom_deg : ndarray of shape (3,)
        Range of motion of the child relative to the parent along the three
        principal axes of the relative rotations (2.5-97.5 percentile extent), degrees.
    n_frames : int
        Frames with both motions known (the equations used).
    conditioning : float
        Smallest over second smallest singular value of the system (near 0: a
        hinge, whose centre along the axis is not determined by the motion).
    axis_spread_m : float
        Circle fits: RMS distance of each child marker's own circle centre
        from the common one, metres (how well the motion fixes where the axis
        lies); NaN for the other methods.
    """

    method: str
    local_parent: np.ndarray
    local_child: np.ndarray
    axis_parent: np.ndarray | None
    axis_child: np.ndarray | None
    centre: np.ndarray
    axis: np.ndarray | None
    residual_m: float
    rom_deg: np.ndarray
    n_frames: int
    conditioning: float
    axis_spread_m: float = float("nan")


def _check_motion(rot, trans, where):
    rot = np.asarray(rot, dtype=float)
    trans = np.asarray(trans, dtype=float)
    if rot.ndim != 3 or rot.shape[1:] != (3, 3) or trans.shape != (rot.shape[0], 3):
        raise InputError(where, "rotations (T, 3, 3) and translations (T, 3)", f"{rot.shape}, {trans.shape}")
    return rot, trans


def range_of_motion(rot_parent: np.ndarray, rot_child: np.ndarray, *, smooth: int = 9) -> np.ndarray:
    """Range of motion of a child segment relative to its parent, degrees.

    Parameters
    ----------
    rot_parent, rot_child : ndarray of shape (T, 3, 3)
        World rotations of the two segments, NaN where unknown.
    smooth : int
        The relative rotations are averaged over this many consecutive frames
        first, so that the jitter of rotations fitted to few, noisy markers is
        not taken for motion.

    Returns
    -------
    ndarray of shape (3,)
        Extent (2.5th to 97.5th percentile) of the relative rotations about
        their mean, along their principal axes, largest first; zeros with fewer
        than two frames.
    """
    from scipy.ndimage import uniform_filter1d

    from scipy.spatial.transform import Rotation

    ok = np.all(np.isfinite(rot_parent), axis=(1, 2)) & np.all(np.isfinite(rot_child), axis=(1, 2))
    if ok.sum() < 2:
        return np.zeros(3)
    rel = Rotation.from_matrix(np.einsum("tji,tjk->tik", rot_parent[ok], rot_child[ok]))
    dev = (rel.mean().inv() * rel).as_rotvec()
    if smooth > 1 and len(dev) > smooth:
        dev = uniform_filter1d(dev, size=smooth, axis=0, mode="nearest")
    dev = dev - dev.mean(axis=0)
    _, _, vt = np.linalg.svd(dev, full_matrices=False)
    proj = dev @ vt.T
    ext = np.percentile(proj, 97.5, axis=0) - np.percentile(proj, 2.5, axis=0)
    out = np.zeros(3)
    out[:len(ext)] = np.degrees(ext)
    return np.sort(out)[::-1]


def _system(rp, tp, rc, tc):
    ok = (np.all(np.isfinite(rp), axis=(1, 2)) & np.all(np.isfinite(rc), axis=(1, 2))
          & np.all(np.isfinite(tp), axis=1) & np.all(np.isfinite(tc), axis=1))
    if ok.sum() < 3:
        raise InputError("rigid motions", "at least three frames with both segments seen", f"{int(ok.sum())}")
    a = np.concatenate([rp[ok], -rc[ok]], axis=2).reshape(-1, 6)  # (3n, 6)
    b = (tc[ok] - tp[ok]).reshape(-1)
    return a, b, int(ok.sum())


def _world(rp, tp, rc, tc, cp, cc):
    gp = np.einsum("tij,j->ti", rp, cp) + tp
    gc = np.einsum("tij,j->ti", rc, cc) + tc
    both = np.isfinite(gp).all(axis=1) & np.isfinite(gc).all(axis=1)
    centre = np.where(both[:, None], 0.5 * (gp + gc), np.where(np.isfinite(gp), gp, gc))
    d = np.linalg.norm(gp - gc, axis=1)[both]
    residual = float(np.sqrt(np.mean(d ** 2))) if d.size else float("nan")
    return centre, residual


def _local_anchor(rot, trans, anchor):
    """Median over frames of a world point in a segment's frame (NaN-aware), or None."""
    if anchor is None:
        return None
    anc = np.broadcast_to(np.asarray(anchor, dtype=float), trans.shape)
    local = np.einsum("tji,tj->ti", rot, anc - trans)
    ok = np.isfinite(local).all(axis=1)
    return np.median(local[ok], axis=0) if ok.any() else None


def _solve(a, b, prior, cols, weight):
    """Least squares ``a x = b``, pulled towards ``prior`` on ``cols``.

    Tikhonov regularisation of weight ``weight`` x the largest singular value of ``a``.
    """
    s = np.linalg.svd(a, compute_uv=False)
    if prior is None or weight <= 0:
        x, *_ = np.linalg.lstsq(a, b, rcond=None)
        return x, s
    lam = weight * s[0]
    reg = np.zeros((len(cols), a.shape[1]))
    reg[np.arange(len(cols)), cols] = lam
    x, *_ = np.linalg.lstsq(np.vstack([a, reg]), np.concatenate([b, lam * prior]), rcond=None)
    return x, s


def score(rot_parent, trans_parent, rot_child, trans_child, *, anchor: np.ndarray | None = None,
          prior_weight: float = 0.0) -> CentreFit:
    """SCoRE centre of rotation (Ehrig et al. 2006, J Biomech 39:2798).

    Parameters
    ----------
    rot_parent, rot_child : ndarray of shape (T, 3, 3)
        World rotations of the segments' reference frames, NaN where unknown.
    trans_parent, trans_child : ndarray of shape (T, 3)
        World translations, metres.

    anchor : ndarray of shape (T, 3) or (3,), optional
        An anatomical estimate of the centre (world, NaN allowed).  The
        solution is pulled towards it (Tikhonov regularisation of weight
        ``prior_weight`` x the system's largest singular value), which only
        matters along directions the motion does not determine (a joint that
        moved about one axis: the centre along that axis).
    prior_weight : float
        0 (default): no pull; the caller treats a ball joint that moved about
        one axis as a hinge (:func:`sara`) instead.

    Returns
    -------
    CentreFit
        ``method="score"``.

    Raises
    ------
    InputError
        Fewer than three frames with both segments seen.
    """
    rp, tp = _check_motion(rot_parent, trans_parent, "rot_parent/trans_parent")
    rc, tc = _check_motion(rot_child, trans_child, "rot_child/trans_child")
    a, b, n = _system(rp, tp, rc, tc)
    ap, ac = _local_anchor(rp, tp, anchor), _local_anchor(rc, tc, anchor)
    prior = None if ap is None or ac is None else np.concatenate([ap, ac])
    x, s = _solve(a, b, prior, np.arange(6), prior_weight)
    centre, residual = _world(rp, tp, rc, tc, x[:3], x[3:])
    return CentreFit("score", x[:3], x[3:], None, None, centre, None, residual,
                     range_of_motion(rp, rc), n, float(s[-1] / max(s[-2], 1e-30)))


def sara(rot_parent, trans_parent, rot_child, trans_child, *, anchor: np.ndarray | None = None) -> CentreFit:
    """SARA hinge axis (Ehrig et al. 2007, J Biomech 40:2150), with the centre placed on it.

    Parameters
    ----------
    rot_parent, trans_parent, rot_child, trans_child
        As for :func:`score`.
    anchor : ndarray of shape (T, 3) or (3,), optional
        An anatomical estimate of the joint centre in the world (per frame, NaN
        allowed): the centre is the point of the axis nearest to it (median
        over frames, in the parent's frame).  Without it, the minimum-norm
        least-squares point (nearest the two subsets' reference origins).

    Returns
    -------
    CentreFit
        ``method="sara"`` with the axis in both frames and in the world.
    """
    rp, tp = _check_motion(rot_parent, trans_parent, "rot_parent/trans_parent")
    rc, tc = _check_motion(rot_child, trans_child, "rot_child/trans_child")
    a, b, n = _system(rp, tp, rc, tc)
    u, s, vt = np.linalg.svd(a, full_matrices=False)
    v = vt[-1]
    # least-squares solution without the axis direction (pseudo-inverse of the first five)
    x0 = vt[:-1].T @ ((u[:, :-1].T @ b) / s[:-1])
    ap, ac = v[:3], v[3:]
    if np.dot(ap, ap) < 1e-12:
        raise InputError("rigid motions", "a hinge whose axis is seen in the parent's frame", "a degenerate system")
    lam = 0.0
    if anchor is not None:
        anc = np.broadcast_to(np.asarray(anchor, dtype=float), tp.shape)
        local = np.einsum("tji,tj->ti", rp, anc - tp)  # R^T (x - t)
        lam_t = (local - x0[:3]) @ ap / np.dot(ap, ap)
        if np.isfinite(lam_t).any():
            lam = float(np.nanmedian(lam_t))
    x = x0 + lam * v
    centre, residual = _world(rp, tp, rc, tc, x[:3], x[3:])
    axp = ap / np.linalg.norm(ap)
    axc = ac / np.linalg.norm(ac) if np.linalg.norm(ac) > 0 else ac
    axis = np.einsum("tij,j->ti", rp, axp)
    return CentreFit("sara", x[:3], x[3:], axp, axc, centre, axis, residual,
                     range_of_motion(rp, rc), n, float(s[-1] / max(s[-2], 1e-30)))


def sphere_centre(rot_parent, trans_parent, points: np.ndarray, *, anchor: np.ndarray | None = None,
                  prior_weight: float = 0.05) -> CentreFit:
    """Centre of the spheres that child markers describe in the parent's frame.

    Used when the child segment has fewer than three markers (no rigid motion
    of its own, e.g. Plug-in Gait's thigh: ``THI`` and ``KNE``): each child
    marker keeps its distance to the joint centre, so in the parent's frame it
    moves on a sphere about it.  The common centre and one radius per marker
    are the linear least-squares solution of ``|x|^2 = 2 x.c + (r_k^2 - |c|^2)``
    (the algebraic sphere fit of Gamage and Lasenby 2002, "New least squares
    solutions for estimating the average centre of rotation and the axis of
    rotation", J Biomech 35:87-93, with a common centre for all markers).

    Parameters
    ----------
    rot_parent : ndarray of shape (T, 3, 3)
    trans_parent : ndarray of shape (T, 3)
    points : ndarray of shape (T, K, 3)
        The child's markers in the world, metres, NaN where missing.
    anchor, prior_weight
        As for :func:`score` (the centre is pulled towards the anchor along
        directions the motion leaves undetermined).

    Returns
    -------
    CentreFit
        ``method="sphere"``: ``local_parent`` the centre in the parent's frame,
        ``local_child`` the radii (K,) padded/truncated to 3 values, ``residual_m``
        the RMS of ``|x - c| - r_k``; the range of motion is that of the
        markers' directions seen from the centre.
    """
    rp, tp = _check_motion(rot_parent, trans_parent, "rot_parent/trans_parent")
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 3 or pts.shape[0] != rp.shape[0] or pts.shape[2] != 3:
        raise InputError("points", f"an array of shape ({rp.shape[0]}, K, 3)", f"{pts.shape}")
    local = np.einsum("tji,tkj->tki", rp, pts - tp[:, None])  # (T, K, 3) in the parent's frame
    k = pts.shape[1]
    # in coordinates centred on the markers' mean m (better conditioned): |y|^2 = 2 y.c' + d_k,
    # y = x - m, c' = c - m, d_k = r_k^2 - |c'|^2
    flat = local.reshape(-1, 3)
    flat = flat[np.isfinite(flat).all(axis=1)]
    if not len(flat):
        raise InputError("points", "child markers seen in frames with the parent's motion", "none")
    mean = flat.mean(axis=0)
    ys = [local[:, j][np.isfinite(local[:, j]).all(axis=1)] - mean for j in range(k)]
    a = np.concatenate([np.concatenate([2 * y, np.eye(k)[[j] * len(y)]], axis=1) for j, y in enumerate(ys)])
    b = np.concatenate([(y ** 2).sum(axis=1) for y in ys])
    if len(b) < 3 + k + 3:
        raise InputError("points", "enough frames with the child's markers and the parent's motion", f"{len(b)}")
    pl = _local_anchor(rp, tp, anchor)
    sol, s = _solve(a, b, None if pl is None else pl - mean, np.arange(3), prior_weight)
    c = sol[:3] + mean
    radii = np.sqrt(np.maximum(sol[3:] + sol[:3] @ sol[:3], 0.0))
    dist = np.linalg.norm(local - c, axis=-1) - radii  # (T, K)
    residual = float(np.sqrt(np.nanmean(dist ** 2)))
    centre = np.einsum("tij,j->ti", rp, c) + tp
    # range of motion: spread of the directions of the markers seen from the centre
    dirs = local - c
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    rom = np.zeros(3)
    for j in range(k):
        d = dirs[:, j][np.isfinite(dirs[:, j]).all(axis=1)]
        if len(d) > 1 and radii[j] > 0.05:  # a marker near the centre gives no direction
            mean = d.mean(axis=0)
            mean /= np.linalg.norm(mean)
            ang = np.degrees(np.arccos(np.clip(d @ mean, -1, 1)))
            rom[0] = max(rom[0], 2 * np.percentile(ang, 97.5))
    radii3 = np.full(3, np.nan)
    radii3[:min(3, k)] = radii[:3]
    return CentreFit("sphere", c, radii3, None, None, centre, None, residual, rom, len(b),
                     float(s[-1] / max(s[-2], 1e-30)))



def _circles(local: np.ndarray) -> dict:
    """Common plane normal and centre of the circles of child markers (T, K, 3) in the parent's frame."""
    seen = np.isfinite(local).all(axis=-1)  # (T, K)
    keep = [k for k in range(local.shape[1]) if seen[:, k].sum() >= 3]
    if not keep:
        raise InputError("points", "a child marker seen in at least 3 frames with the parent's motion", "none")
    ys = [local[seen[:, k], k] for k in keep]
    centred = np.concatenate([y - y.mean(axis=0) for y in ys])
    _, s, vt = np.linalg.svd(centred, full_matrices=False)
    n, u, v = vt[2], vt[0], vt[1]
    mean = np.concatenate(ys).mean(axis=0)
    # the circles' common centre in the plane (u, v about ``mean``), one constant per marker
    q = [np.stack([(y - mean) @ u, (y - mean) @ v], axis=1) for y in ys]
    k = len(ys)
    a = np.concatenate([np.concatenate([2 * qj, np.eye(k)[[j] * len(qj)]], axis=1) for j, qj in enumerate(q)])
    b = np.concatenate([(qj ** 2).sum(axis=1) for qj in q])
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    radii = np.sqrt(np.maximum(sol[2:] + sol[:2] @ sol[:2], 0.0))
    # the algebraic fit is biased towards small circles on short arcs: refined by the geometric one
    # (distances to the circles, scipy's least_squares from the algebraic solution)
    from scipy.optimize import least_squares

    def dist(x):
        return np.concatenate([np.linalg.norm(qj - x[:2], axis=1) - x[2 + j] for j, qj in enumerate(q)])

    x = least_squares(dist, np.concatenate([sol[:2], radii])).x
    sol, radii = x[:2], np.abs(x[2:])
    # each marker's own circle centre: their spread says how well the motion fixes the axis' position
    own = []
    for j, qj in enumerate(q):
        if len(q) > 1:
            xj = least_squares(lambda z: np.linalg.norm(qj - z[:2], axis=1) - z[2], np.r_[sol, radii[j]]).x
            own.append(np.linalg.norm(xj[:2] - sol))
    spread = float(np.sqrt(np.mean(np.square(own)))) if own else 0.0
    c0 = mean + sol[0] * u + sol[1] * v  # a point of the axis
    levels = np.array([float(np.mean((y - c0) @ n)) for y in ys])  # each circle's plane along the axis
    return {"keep": keep, "n": n, "u": u, "v": v, "c0": c0, "mean": mean, "radii": radii, "levels": levels,
            "s": s, "n_eq": len(centred), "spread": spread}


def _on_circles(local: np.ndarray, fit: dict) -> np.ndarray:
    """The nearest point of each marker's circle to its position (T, K, 3), NaN where unseen or not fitted."""
    out = np.full_like(local, np.nan)
    n, c0 = fit["n"], fit["c0"]
    for j, k in enumerate(fit["keep"]):
        d = local[:, k] - c0
        perp = d - (d @ n)[:, None] * n
        rho = np.linalg.norm(perp, axis=1, keepdims=True)
        out[:, k] = c0 + fit["levels"][j] * n + fit["radii"][j] * perp / np.maximum(rho, 1e-9)
    return out


def _circle_distances(local: np.ndarray, fit: dict) -> np.ndarray:
    """Distance of each sample (T, K, 3) from its marker's circle (T, K); NaN where unseen or not fitted."""
    out = np.full(local.shape[:2], np.nan)
    n, c0 = fit["n"], fit["c0"]
    for j, k in enumerate(fit["keep"]):
        d = local[:, k] - c0
        h = d @ n
        rho = np.linalg.norm(d - h[:, None] * n, axis=1)
        out[:, k] = np.hypot(h - fit["levels"][j], rho - fit["radii"][j])
    return out


def _kabsch_per_frame(ref: np.ndarray, pts: np.ndarray):
    """Rigid motions (T, 3, 3), (T, 3) taking per-frame references ``ref`` (T, K, 3) onto ``pts``; NaN-aware."""
    w = (np.isfinite(ref).all(axis=-1) & np.isfinite(pts).all(axis=-1)).astype(float)[..., None]
    nw = np.maximum(w.sum(axis=1), 1.0)
    r = np.where(w > 0, ref, 0.0)
    x = np.where(w > 0, pts, 0.0)
    cr, cx = r.sum(axis=1) / nw, x.sum(axis=1) / nw
    h = np.einsum("tki,tkj->tij", (r - cr[:, None]) * w, (x - cx[:, None]) * w)
    u, sv, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.einsum("tji,tkj->tik", vt, u)))
    dm = np.ones((len(d), 3))
    dm[:, 2] = d
    rot = np.einsum("tji,tj,tkj->tik", vt, dm, u)
    trans = cx - np.einsum("tij,tj->ti", rot, cr)
    bad = (w[..., 0].sum(axis=1) < 3) | ~(sv[:, 1] > 1e-4 * sv[:, 0])
    rot[bad], trans[bad] = np.nan, np.nan
    return rot, trans


def _fit_circles(rp: np.ndarray, tp: np.ndarray, pts: np.ndarray, local: np.ndarray, fit: dict,
                 pref: np.ndarray | None, ppts: np.ndarray | None, iterations: int, outlier_m: float):
    """Refine the circles (and, with the parent's markers, the parent's poses), then again without outliers.

    Refined with every sample, then (``outlier_m > 0``) again without the child samples far off their circles
    (a mislabel, a swap).  Each refinement round fits the parent's pose per frame to its reference markers and
    the child markers' nearest points on their circles (Kabsch), then the circles again.

    Parameters
    ----------
    rp : ndarray of shape (T, 3, 3)
    tp : ndarray of shape (T, 3)
        The parent's motion, NaN where unknown.
    pts : ndarray of shape (T, K, 3)
        The child's markers, world, metres.
    local : ndarray of shape (T, K, 3)
        The child's markers in the parent's frame.
    fit : dict
        The first fit of :func:`_circles`.
    pref : ndarray of shape (P, 3) or None
        The parent's markers in its frame (None: no refinement of the parent).
    ppts : ndarray of shape (T, P, 3) or None
        The parent's markers in the world.
    iterations : int
        Refinement rounds per stage (0 without the parent's markers).
    outlier_m : float
        Distance from the circle beyond which a sample is left out, metres (0: keep all).

    Returns
    -------
    rp, tp : ndarray
        The parent's motion (refined).
    local : ndarray of shape (T, K, 3)
        The child's markers in the (refined) parent's frame.
    fit : dict
        The circles.
    use : ndarray of shape (T, K), bool
        The samples used.
    """
    known = np.isfinite(tp).all(axis=1)  # frames the parent's own fit kept
    use = np.isfinite(local).all(axis=-1)
    # refined with every sample, then (outlier_m > 0) again without the samples far off their circles
    for stage in range(2 if outlier_m > 0 else 1):
        if stage:  # a child sample far off its circle (a mislabel, a swap) is left out
            use = np.isfinite(local).all(axis=-1) & ~(_circle_distances(local, fit) > outlier_m)
            fit = _circles(np.where(use[..., None], local, np.nan))
        for _ in range(iterations):
            targets = np.where(use[..., None], _on_circles(local, fit), np.nan)
            ref = np.concatenate([np.broadcast_to(pref, (len(rp), *pref.shape)), targets], axis=1)
            r2, t2 = _kabsch_per_frame(ref, np.concatenate([ppts, pts], axis=1))
            ok = np.isfinite(t2).all(axis=1) & known
            rp, tp = np.where(ok[:, None, None], r2, rp), np.where(ok[:, None], t2, tp)
            local = np.einsum("tji,tkj->tki", rp, pts - tp[:, None])
            fit = _circles(np.where(use[..., None], local, np.nan))
    return rp, tp, local, fit, use


def _circle_distances_and_rom(local: np.ndarray, fit: dict) -> tuple[list, float]:
    """Distances of the child markers from their circles, and the largest angular extent about the axis.

    Parameters
    ----------
    local : ndarray of shape (T, K, 3)
        The child's markers in the parent's frame (NaN: not used), metres.
    fit : dict
        From :func:`_circles`.

    Returns
    -------
    dist : list of ndarray
        Per kept marker, its distance from its circle in each frame it is seen, metres.
    rom : float
        Largest 2.5-97.5 percentile angular extent of a marker about the axis, degrees (markers within 5 cm of
        the axis give none).
    """
    n, u, v, c0, radii = fit["n"], fit["u"], fit["v"], fit["c0"], fit["radii"]
    dist, rom = [], 0.0
    for j, k in enumerate(fit["keep"]):
        y = local[:, k][np.isfinite(local[:, k]).all(axis=1)]
        d = y - c0
        h = d @ n
        perp = d - h[:, None] * n
        rho = np.linalg.norm(perp, axis=1)
        dist.append(np.sqrt((h - fit["levels"][j]) ** 2 + (rho - radii[j]) ** 2))
        if radii[j] > 0.05:  # a marker near the axis gives no angle
            ang = np.arctan2(perp @ v, perp @ u)
            ang = np.angle(np.exp(1j * (ang - np.angle(np.exp(1j * ang).mean()))))  # about the mean direction
            rom = max(rom, float(np.degrees(np.percentile(ang, 97.5) - np.percentile(ang, 2.5))))
    return dist, rom


def _circle_inputs(rot_parent, trans_parent, points, parent_reference, parent_points, iterations: int):
    """Check the inputs of :func:`circle_axis`.

    Parameters
    ----------
    rot_parent, trans_parent, points, parent_reference, parent_points, iterations
        As :func:`circle_axis`.

    Returns
    -------
    rp : ndarray of shape (T, 3, 3)
    tp : ndarray of shape (T, 3)
    pts : ndarray of shape (T, K, 3)
    pref : ndarray of shape (P, 3) or None
        None when the parent's poses are not refined.
    ppts : ndarray of shape (T, P, 3) or None

    Raises
    ------
    InputError
        Wrong shapes.
    """
    rp, tp = _check_motion(rot_parent, trans_parent, "rot_parent/trans_parent")
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 3 or pts.shape[0] != rp.shape[0] or pts.shape[2] != 3 or pts.shape[1] < 1:
        raise InputError("points", f"an array of shape ({rp.shape[0]}, K, 3), K >= 1", f"{pts.shape}")
    pref = ppts = None
    if parent_reference is not None and parent_points is not None and iterations > 0:
        pref = np.asarray(parent_reference, dtype=float)
        ppts = np.asarray(parent_points, dtype=float)
        if pref.ndim != 2 or pref.shape[1] != 3 or ppts.shape != (rp.shape[0], pref.shape[0], 3):
            raise InputError("parent_reference/parent_points", f"(P, 3) and ({rp.shape[0]}, P, 3)",
                             f"{pref.shape}, {ppts.shape}")
    return rp, tp, pts, pref, ppts


def _axis_point(fit: dict, rp: np.ndarray, tp: np.ndarray, anchor) -> np.ndarray:
    """The joint centre on the axis: nearest the anchor, else at the markers' mean level (parent's frame).

    Parameters
    ----------
    fit : dict
        From :func:`_circles`.
    rp : ndarray of shape (T, 3, 3)
    tp : ndarray of shape (T, 3)
    anchor : ndarray of shape (T, 3) or (3,) or None
        World, metres.

    Returns
    -------
    ndarray of shape (3,)
        Metres, parent's frame.
    """
    n, c0 = fit["n"], fit["c0"]
    lam = float((fit["mean"] - c0) @ n)
    anc_local = _local_anchor(rp, tp, anchor)
    if anc_local is not None:
        lam = float((anc_local - c0) @ n)
    c = c0 + lam * n
    return c


def _parent_distances(rp: np.ndarray, tp: np.ndarray, pref: np.ndarray, ppts: np.ndarray) -> np.ndarray:
    """Distances of the parent's markers from their places under its fitted poses.

    Parameters
    ----------
    rp : ndarray of shape (T, 3, 3)
    tp : ndarray of shape (T, 3)
    pref : ndarray of shape (P, 3)
        The parent's markers in its frame.
    ppts : ndarray of shape (T, P, 3)
        The parent's markers in the world, metres.

    Returns
    -------
    ndarray of shape (M,)
        The finite distances, metres.
    """
    fitted = np.einsum("tij,kj->tki", rp, pref) + tp[:, None]
    e = np.linalg.norm(fitted - ppts, axis=-1)
    return e[np.isfinite(e)]


def circle_axis(rot_parent, trans_parent, points: np.ndarray, *, anchor: np.ndarray | None = None,
                parent_reference: np.ndarray | None = None, parent_points: np.ndarray | None = None,
                iterations: int = 5, outlier_m: float = 0.015) -> CentreFit:
    """Hinge axis from the circles that child markers describe in the parent's frame.

    For a child segment whose own markers give no reliable rigid motion (one
    or two markers, or markers nearly on one line: Plug-in Gait's shank
    ``TIB``/``ANK`` with the borrowed ``KNE``, whose rotation about that line
    the skin noise decides), each child marker still turns about the hinge:
    in the parent's frame it moves on a circle in a plane normal to the axis,
    centred on it (the axis method of Gamage and Lasenby 2002, "New least
    squares solutions for estimating the average centre of rotation and the
    axis of rotation", J Biomech 35:87-93).  Linear least squares twice:

    1. the axis direction ``n``: the common normal of the markers' planes,
       the smallest right singular vector of the markers' positions centred
       per marker and stacked (``n . y_kt = d_k``);
    2. the axis position: the common centre ``c`` (in the plane) of the
       markers' circles, ``|y|^2 = 2 y.c + (r_k^2 - |c|^2)`` in plane
       coordinates, as in :func:`sphere_centre`.

    With the parent's markers given, the parent's pose in each frame is then
    fitted to its own markers and the child markers' circles together (the
    hinge as a joint constraint of a global optimisation, Lu and O'Connor
    1999, "Bone position estimation from skin marker co-ordinates using
    global optimisation with joint constraints", J Biomech 32:129-134):
    alternately, each child marker's nearest point on its circle joins the
    parent's reference markers in a per-frame Kabsch fit, and the circles are
    fitted again; each step lowers the same sum of squared marker distances.
    A parent whose markers leave its rotation about one line loosely held
    (Plug-in Gait's thigh: ``THI`` a few centimetres off the hip-``KNE``
    line) thus takes it from the child's circles.

    Where on the axis the joint lies is not observable from the motion (as
    for :func:`sara`): the point of the axis nearest the anchor.

    Parameters
    ----------
    rot_parent : ndarray of shape (T, 3, 3)
    trans_parent : ndarray of shape (T, 3)
        The parent's rigid motion (``x_world = R x_local + t``), NaN where unknown.
    points : ndarray of shape (T, K, 3)
        The child's markers in the world, metres, NaN where missing.
    anchor : ndarray of shape (T, 3) or (3,), optional
        An anatomical estimate of the joint centre (world, NaN allowed); the
        centre is the point of the axis nearest to it (median over frames, in
        the parent's frame).  Without it, the axis point at the markers' mean level.
    parent_reference : ndarray of shape (P, 3), optional
        The parent's markers in its own frame (``rot_parent`` maps them to the world).
    parent_points : ndarray of shape (T, P, 3), optional
        The parent's markers in the world; with ``parent_reference``, the
        parent's poses are refined as above.
    iterations : int
        Refinement rounds.
    outlier_m : float
        A child marker farther than this from its fitted circle in a frame (a
        mislabel, a swap) after the first fit (and refinement) is left out
        of that frame and the fit done again; 0 = keep every sample.

    Returns
    -------
    CentreFit
        ``method="circle"``: ``local_parent`` the centre and ``axis_parent``
        the axis in the parent's frame, ``axis`` in the world per frame,
        ``local_child`` the circles' radii (K,) padded/truncated to 3 values
        (no child frame); ``axis_spread_m`` how far the markers' own circle
        centres lie from the common one; ``residual_m`` the RMS distance of the child
        markers from their circles and (refined) of the parent's markers from
        their fitted places; ``rom_deg[0]`` the largest angular extent
        (2.5-97.5 percentile) of a marker about the axis; ``conditioning`` the
        smallest over the second smallest singular value of the child
        markers' centred positions (near 0: they stay in planes, a clean hinge).

    Raises
    ------
    InputError
        Wrong shapes; fewer than three frames of a marker seen with the parent's motion.
    """
    rp, tp, pts, pref, ppts = _circle_inputs(rot_parent, trans_parent, points, parent_reference, parent_points,
                                             iterations)
    refine = pref is not None
    local = np.einsum("tji,tkj->tki", rp, pts - tp[:, None])  # (T, K, 3), parent's frame
    fit = _circles(local)
    rp, tp, local, fit, use = _fit_circles(rp, tp, pts, local, fit, pref, ppts, iterations if refine else 0,
                                           outlier_m)
    local = np.where(use[..., None], local, np.nan)
    n, radii = fit["n"], fit["radii"]
    dist, rom = _circle_distances_and_rom(local, fit)
    if refine:
        dist.append(_parent_distances(rp, tp, pref, ppts))
    residual = float(np.sqrt(np.mean(np.concatenate(dist) ** 2)))
    c = _axis_point(fit, rp, tp, anchor)
    centre = np.einsum("tij,j->ti", rp, c) + tp
    axis = np.einsum("tij,j->ti", rp, n)
    k = len(radii)
    radii3 = np.full(3, np.nan)
    radii3[:min(3, k)] = radii[:3]
    s = fit["s"]
    return CentreFit("circle", c, radii3, n, None, centre, axis, residual, np.array([rom, 0.0, 0.0]),
                     fit["n_eq"], float(s[2] / max(s[1], 1e-30)), fit["spread"])
