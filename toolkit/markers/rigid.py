"""Rigid subsets: markers that move together, and their rigid motion per frame.

Markers on one bone keep their mutual distances; markers on two bones linked by
a joint do not.  The standard deviation over the trial of each pairwise
distance (NaN-aware: only the frames where both markers are seen count) is
therefore a dissimilarity, and markers are partitioned by agglomerative
clustering of it (scikit-learn's ``AgglomerativeClustering`` on the
precomputed matrix, average linkage, cut at a distance-std threshold in metres,
so the number of subsets follows from the data; scikit-learn is used rather
than a hand-written linkage because it is the well-kept reference for it).

With labels, the segments of a marker set give the subsets directly and
:func:`check_segments` says which markers do not move rigidly with the others
of their segment (soft tissue, a loose marker, a mislabel).

The rigid motion of a subset in each frame (:func:`rigid_motions`) is the
least-squares rotation and translation from its reference shape to the
markers seen in that frame (Kabsch / Umeyama without scale, batched SVD of
numpy; a frame with fewer than three non-collinear markers seen has none).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError


def _check_positions(positions, where="positions") -> np.ndarray:
    p = np.asarray(positions, dtype=float)
    if p.ndim != 3 or p.shape[-1] != 3:
        raise InputError(where, "an array of shape (T, M, 3)", f"shape {p.shape}")
    return p


def distance_std(positions: np.ndarray, *, min_frames: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Standard deviation over time of every pairwise marker distance.

    Parameters
    ----------
    positions : ndarray of shape (T, M, 3)
        Metres, NaN where a marker is missing.
    min_frames : int
        Pairs seen together in fewer frames get an infinite std (unknown).

    Returns
    -------
    std : ndarray of shape (M, M)
        Metres; 0 on the diagonal, inf for pairs seen together too rarely.
    together : ndarray of shape (M, M) int
        Number of frames in which both markers are seen.
    """
    p = _check_positions(positions)
    seen = np.all(np.isfinite(p), axis=-1)  # (T, M)
    together = seen.T.astype(np.int64) @ seen.astype(np.int64)
    m = p.shape[1]
    std = np.full((m, m), np.inf)
    for i in range(m):
        d = np.linalg.norm(p[:, i:i + 1] - p, axis=-1)  # (T, M), NaN where either missing
        with np.errstate(invalid="ignore"), _quiet():
            std[i] = np.nanstd(d, axis=0)
    std[together < min_frames] = np.inf
    std = np.minimum(std, std.T)
    np.fill_diagonal(std, 0.0)
    return std, together


class _quiet:
    """Silence numpy's 'degrees of freedom' / 'mean of empty slice' warnings inside a block."""

    def __enter__(self):
        import warnings
        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)

    def __exit__(self, *exc):
        return self._w.__exit__(*exc)


@dataclass(frozen=True)
class RigidSubsets:
    """A partition of markers into rigidly moving subsets.

    Attributes
    ----------
    subsets : tuple of tuple of int
        Marker indices of each subset (each of at least ``min_size``), largest first.
    leftover : tuple of int
        Markers in no subset (a subset smaller than ``min_size``).
    spread : ndarray of shape (S,)
        Mean pairwise distance std within each subset, metres.
    std : ndarray of shape (M, M)
        The pairwise distance std the partition came from, metres.
    """

    subsets: tuple
    leftover: tuple
    spread: np.ndarray
    std: np.ndarray

    def label_of(self, n_markers: int) -> np.ndarray:
        """Subset index of each marker, -1 for a leftover; shape (M,)."""
        out = np.full(n_markers, -1, dtype=int)
        for k, s in enumerate(self.subsets):
            out[list(s)] = k
        return out


def find_rigid_subsets(positions: np.ndarray, *, threshold_m: float = 0.01, min_size: int = 3,
                       min_frames: int = 10) -> RigidSubsets:
    """Partition markers into rigid subsets without labels.

    Parameters
    ----------
    positions : ndarray of shape (T, M, 3)
        Metres, NaN where missing.
    threshold_m : float
        The average-linkage distance (mean pairwise distance std, metres) at
        which clusters stop merging: the number of subsets follows from it.
    min_size : int
        Smaller clusters are left over (a rigid motion needs three markers).
    min_frames : int
        See :func:`distance_std`.

    Returns
    -------
    RigidSubsets
    """
    from sklearn.cluster import AgglomerativeClustering

    if not threshold_m > 0:
        raise InputError("threshold_m", "a positive distance std in metres", repr(threshold_m))
    std, _ = distance_std(positions, min_frames=min_frames)
    m = std.shape[0]
    if m < 2:
        raise InputError("positions", "at least two markers", f"{m}")
    finite = np.isfinite(std)
    big = 1e3 * max(threshold_m, float(std[finite].max()) if finite.any() else 1.0)
    d = np.where(finite, std, big)
    cl = AgglomerativeClustering(n_clusters=None, metric="precomputed", linkage="average",
                                 distance_threshold=threshold_m).fit(d)
    groups = [tuple(int(i) for i in np.flatnonzero(cl.labels_ == k)) for k in np.unique(cl.labels_)]
    keep = sorted((g for g in groups if len(g) >= min_size), key=lambda g: (-len(g), g[0]))
    leftover = tuple(sorted(i for g in groups if len(g) < min_size for i in g))
    spread = np.array([std[np.ix_(g, g)][np.triu_indices(len(g), 1)].mean() for g in keep])
    return RigidSubsets(subsets=tuple(keep), leftover=leftover, spread=spread, std=std)


def check_segments(positions: np.ndarray, groups: dict, *, tolerance_m: float = 0.015,
                   min_frames: int = 10) -> dict:
    """Which markers of each labelled segment do not move rigidly with the others.

    Parameters
    ----------
    positions : ndarray of shape (T, M, 3)
    groups : dict of str to list of int
        Segment name -> marker indices.
    tolerance_m : float
        A marker whose median distance std to its segment mates exceeds this is flagged.

    Returns
    -------
    dict of str to list of int
        Segment -> flagged marker indices (only segments with any).
    """
    std, _ = distance_std(positions, min_frames=min_frames)
    out = {}
    for name, idx in groups.items():
        idx = list(idx)
        if len(idx) < 3:
            continue
        sub = std[np.ix_(idx, idx)]
        med = np.array([np.median(np.delete(sub[k], k)) for k in range(len(idx))])
        bad = [idx[k] for k in np.flatnonzero(~(med <= tolerance_m))]
        if bad:
            out[name] = bad
    return out


def reference_shape(positions: np.ndarray) -> np.ndarray:
    """A subset's shape in its own frame: markers centred, from the frame(s) where most are seen.

    Built from the mean pairwise distances by classical multidimensional
    scaling would lose the handedness; instead the frame where all (or most)
    markers are seen is taken, and the other frames are aligned to it and
    averaged (one Procrustes pass), which also averages the noise out.

    Parameters
    ----------
    positions : ndarray of shape (T, K, 3)
        The subset's markers, metres, NaN where missing.

    Returns
    -------
    ndarray of shape (K, 3)
        Centred at the mean of the markers; NaN for a marker never seen with enough others.
    """
    p = _check_positions(positions)
    seen = np.all(np.isfinite(p), axis=-1)
    n_seen = seen.sum(axis=1)
    if n_seen.max(initial=0) < 3:
        raise InputError("positions", "a frame with at least three markers of the subset seen",
                         f"at most {n_seen.max(initial=0)}")
    first = int(np.argmax(n_seen))
    ref = p[first] - np.nanmean(p[first], axis=0)
    for _ in range(2):
        rot, trans, _ = rigid_motions(ref, p)
        local = np.einsum("tji,tkj->tki", rot, p - trans[:, None, :])  # R^T (x - t)
        with _quiet():
            new = np.nanmedian(local, axis=0)
        ok = np.isfinite(new).all(axis=1)
        ref = np.where(ok[:, None], new, ref)
        ref = ref - np.nanmean(ref, axis=0)
    return ref


def rigid_motions(reference: np.ndarray, positions: np.ndarray, *, min_markers: int = 3,
                  outlier_m: float = 0.015) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares rigid motion from a reference shape to each frame (Kabsch).

    Parameters
    ----------
    reference : ndarray of shape (K, 3)
        The subset's markers in its own frame, metres (NaN = unknown marker).
    positions : ndarray of shape (T, K, 3)
        The same markers in each frame, world, NaN where missing.
    min_markers : int
        Frames with fewer markers seen (or nearly collinear ones) get NaN.
    outlier_m : float
        After a first fit, a marker farther than this from its fitted place
        (a mislabelled or swapped marker) is left out of that frame and the
        frame is fitted again (when ``min_markers`` remain); 0 = no second pass.

    Returns
    -------
    rotations : ndarray of shape (T, 3, 3)
        ``x_world = R @ x_ref + t``; NaN where the frame has no motion.
    translations : ndarray of shape (T, 3)
    rms : ndarray of shape (T,)
        Root mean square distance of the fitted markers, metres (NaN without a motion).
    """
    ref = np.asarray(reference, dtype=float)
    p = _check_positions(positions)
    w = (np.all(np.isfinite(p), axis=-1) & np.all(np.isfinite(ref), axis=-1)[None]).astype(float)  # (T, K)
    rot, trans, rms, err = _kabsch(ref, p, w, min_markers)
    if outlier_m > 0:
        out = (err > outlier_m) & (w > 0)
        keep = w * ~out
        redo = out.any(axis=1) & (keep.sum(axis=1) >= min_markers)
        if redo.any():
            r2, t2, m2, _ = _kabsch(ref, p[redo], keep[redo], min_markers)
            rot[redo], trans[redo], rms[redo] = r2, t2, m2
    return rot, trans, rms


def _kabsch(ref, p, w, min_markers):
    """Weighted Kabsch of ``ref`` (K, 3) to ``p`` (T, K, 3) with 0/1 weights ``w`` (T, K); + per-marker errors."""
    n = w.sum(axis=1)
    x = np.where(w[..., None] > 0, p, 0.0)
    r = np.where(np.isfinite(ref), ref, 0.0)[None] * w[..., None]
    ns = np.maximum(n, 1)[:, None]
    cx = x.sum(axis=1) / ns
    cr = r.sum(axis=1) / ns
    xc = (x - cx[:, None]) * w[..., None]
    rc = (r - cr[:, None]) * w[..., None]
    h = np.einsum("tki,tkj->tij", rc, xc)  # (T, 3, 3)
    u, s, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.einsum("tji,tkj->tik", vt, u)))  # det(V U^T)
    dm = np.ones((len(d), 3))
    dm[:, 2] = d
    rot = np.einsum("tji,tj,tkj->tik", vt, dm, u)  # V diag(1,1,d) U^T
    trans = cx - np.einsum("tij,tj->ti", rot, cr)
    refall = np.where(np.isfinite(ref), ref, np.nan)
    fitted = np.einsum("tij,kj->tki", rot, refall) + trans[:, None]
    err = np.linalg.norm(fitted - p, axis=-1)  # every marker seen, fitted or not
    rms = np.sqrt(np.nansum((err * w) ** 2, axis=1) / ns[:, 0])
    # degenerate: too few markers or (nearly) collinear ones (second singular value ~ 0)
    bad = (n < min_markers) | (s[:, 1] < 1e-4 * s[:, 0]) | (s[:, 0] <= 0)
    rot[bad] = np.nan
    trans[bad] = np.nan
    rms[bad] = np.nan
    return rot, trans, rms, np.where(np.isfinite(err), err, 0.0)
