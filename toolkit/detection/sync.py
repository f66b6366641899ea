"""Each camera's frame offset from the people it sees.

Cameras started at different times film the same motion shifted by whole frames.  Offsets mean:
``offsets[c] = k`` when camera ``c`` started ``k`` frames late, i.e. its frame ``f`` shows the
instant of frame ``f + k`` of a camera with offset 0.  The smallest offset is 0.

With a calibration, :func:`find_offsets_geometric` solves all offsets at once from where the rays
of every pair of cameras meet (:func:`pair_cost_curves`: per pair and lag, how far the rays of the
same keypoints pass from each other beyond a constant per keypoint); the offsets minimise the
summed cost of all pairs, and a camera is called late only when its pairs agree on it clearly.

Without one, :func:`motion_signal` measures how fast the people move in each camera's image at
every frame: the keypoints of each person are matched to the nearest person of the next frame,
their speeds (pixels per frame, divided by the person's height in the image, so near and far
cameras weigh alike) are summed over keypoints and people.  Speeds of one motion seen from
different directions differ in size but rise and fall together; :func:`find_offsets` correlates
every camera's signal with a reference camera's over lags of up to ``max_offset`` frames (the
standardised signals' product on the frames both cover, after a light smoothing; summed over the
overlap and divided by the shorter signal's length, so lags that leave little overlap score low)
and takes the best lag.  A camera whose best correlation is weak (below ``min_peak``) keeps
offset 0 and is reported as not synchronised.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from toolkit.errors import InputError

__all__ = ["SyncResult", "motion_signal", "find_offsets", "pair_cost_curves", "find_offsets_geometric", "MAX_OFFSET",
           "MIN_PEAK", "MIN_CONFIDENCE"]

#: Largest offset searched, frames.
MAX_OFFSET = 60
#: Correlation a lag must reach to be trusted.
MIN_PEAK = 0.3
#: Keypoints below this confidence do not count in the motion.
MIN_CONFIDENCE = 0.3
#: Smoothing of the signals (frames, Gaussian sigma) before correlating.
SMOOTH_SIGMA = 1.0
#: Fewest frames two signals must share at a lag for it to be tried.
MIN_OVERLAP = 20


@dataclass
class SyncResult:
    """Offsets and the evidence for them.

    Attributes
    ----------
    offsets : dict of str to int
        Frames each camera started late (0 for the earliest).
    reference : str
        ``"motion"``: the camera every other was correlated with; ``"rays"``: the camera held at 0
        during the joint search (the offsets do not depend on it).
    peaks : dict of str to float
        ``"motion"``: the correlation at the chosen lag (1.0 for the reference); ``"rays"``: the
        camera's summed pair cost at the offset found (lower is better).
    second : dict of str to float
        ``"motion"``: the best correlation at least 3 frames away from the chosen lag; ``"rays"``:
        the least cost at least 2 frames away from the offset found.
    trusted : dict of str to bool
        ``"motion"``: the peak passed ``min_peak`` (an untrusted camera keeps offset 0); ``"rays"``:
        the confidence passed ``min_gain``.
    curves : dict of str to list of float
        Per lag ``-max_offset .. max_offset``: ``"motion"`` the correlation with the reference (NaN
        where the overlap is too short); ``"rays"`` the camera's cost with its offset moved by the lag
        from the one found.
    max_offset : int
    method : str
        ``"motion"`` (:func:`find_offsets`) or ``"rays"`` (:func:`find_offsets_geometric`).
    confidence : dict of str to float
        ``"rays"``: ``(second - peaks) / (cameras - 1)``: how much more each of the camera's pairs
        costs (in units of the pair's median cost) at the best offset two frames or more away.
    pair_curves : dict of str to list of float
        ``"rays"``: per pair ``"a|b"``, the cost (metres) of frame ``t`` of ``a`` against frame
        ``t + lag`` of ``b`` per lag (least at ``offsets[a] - offsets[b]``).
    """

    offsets: dict[str, int]
    reference: str
    peaks: dict[str, float]
    second: dict[str, float]
    trusted: dict[str, bool]
    curves: dict[str, list[float]] = field(repr=False)
    max_offset: int = MAX_OFFSET
    method: str = "motion"
    confidence: dict[str, float] = field(default_factory=dict)
    pair_curves: dict[str, list[float]] = field(default_factory=dict, repr=False)

    def to_json(self) -> dict:
        """The ``sync.json`` document: offsets, then the evidence."""
        def num(v):
            return None if v is None or not np.isfinite(v) else round(float(v), 5)

        doc = {"offsets": {k: int(v) for k, v in self.offsets.items()},
               "meaning": "offsets[camera] = k: the camera started k frames late; its frame f shows the instant "
                          "of frame f + k of a camera with offset 0",
               "method": self.method, "reference": self.reference,
               "peaks": {k: num(v) for k, v in self.peaks.items()},
               "second_peaks": {k: num(v) for k, v in self.second.items()},
               "trusted": self.trusted, "max_offset": self.max_offset,
               "lags": list(range(-self.max_offset, self.max_offset + 1)),
               "curves": {k: [num(v) for v in c] for k, c in self.curves.items()}}
        if self.method == "rays":
            doc["evidence"] = ("curves[camera][i]: the camera's pair costs (each pair's cost over its median over "
                               "lags, summed) with its offset moved by lags[i] from the one found, the others kept; "
                               "pair_curves['a|b'][i]: metres, frame t of a against frame t + lags[i] of b, least at "
                               "offsets[a] - offsets[b]; confidence = (second_peaks - peaks) / (cameras - 1)")
            doc["confidence"] = {k: num(v) for k, v in self.confidence.items()}
            doc["pair_curves"] = {k: [num(v) for v in c] for k, c in self.pair_curves.items()}
        return doc


def _height(kp: np.ndarray) -> float:
    ok = kp[:, 2] >= MIN_CONFIDENCE
    if ok.sum() < 3:
        return np.nan
    ys = kp[ok, 1]
    return float(max(ys.max() - ys.min(), 1.0))


def motion_signal(people_per_frame: list[list[np.ndarray]], min_confidence: float = MIN_CONFIDENCE) -> np.ndarray:
    """How fast the people move in one camera, per frame.

    Parameters
    ----------
    people_per_frame : list of list of ndarray of shape (K, 3)
        Per frame the people detected, ``(x, y, confidence)`` in pixels.
    min_confidence : float

    Returns
    -------
    ndarray of shape (T,)
        Speed at frame t (from t to t + 1), in person heights per frame summed over keypoints and
        people; NaN where nobody is seen in both frames.  The last value is NaN.
    """
    T = len(people_per_frame)
    out = np.full(T, np.nan)
    for t in range(T - 1):
        now, nxt = people_per_frame[t], people_per_frame[t + 1]
        if not now or not nxt:
            continue
        centres = [np.nanmean(np.where((p[:, 2:3] >= min_confidence), p[:, :2], np.nan), axis=0) for p in nxt]
        total, used = 0.0, False
        for p in now:
            h = _height(p)
            if not np.isfinite(h):
                continue
            c = np.nanmean(np.where(p[:, 2:3] >= min_confidence, p[:, :2], np.nan), axis=0)
            d = [np.linalg.norm(c - q) if np.all(np.isfinite(q)) else np.inf for q in centres]
            j = int(np.argmin(d))
            if not np.isfinite(d[j]) or d[j] > 0.5 * h:
                continue
            q = nxt[j]
            ok = (p[:, 2] >= min_confidence) & (q[:, 2] >= min_confidence)
            if ok.sum() < 3:
                continue
            total += float(np.linalg.norm(q[ok, :2] - p[ok, :2], axis=1).sum()) / h
            used = True
        if used:
            out[t] = total
    return out


def _smooth(x: np.ndarray, sigma: float) -> np.ndarray:
    from scipy.ndimage import gaussian_filter1d

    ok = np.isfinite(x)
    if sigma <= 0 or not ok.any():
        return x
    filled = np.where(ok, x, 0.0)
    num = gaussian_filter1d(filled, sigma, mode="nearest")
    den = gaussian_filter1d(ok.astype(float), sigma, mode="nearest")
    with np.errstate(invalid="ignore", divide="ignore"):
        out = num / den
    out[~ok] = np.nan
    return out


def _zscore(x: np.ndarray) -> np.ndarray:
    ok = np.isfinite(x)
    if ok.sum() < 2 or np.std(x[ok]) == 0:
        return np.zeros_like(x)
    z = (x - x[ok].mean()) / x[ok].std()
    z[~ok] = 0.0
    return z


def _correlation(ref: np.ndarray, sig: np.ndarray, lag: int) -> float:
    """Cross-correlation of the standardised ref[t + lag] and sig[t], summed over the frames both have
    and divided by the shorter signal's length: lags that leave little overlap score low (a Pearson
    correlation over a few frames would score high by chance)."""
    n = len(sig)
    t = np.arange(n)
    u = t + lag
    keep = (u >= 0) & (u < len(ref))
    if keep.sum() < MIN_OVERLAP:
        return np.nan
    return float((ref[u[keep]] * sig[t[keep]]).sum() / min(len(ref), len(sig)))


def find_offsets(signals: dict[str, np.ndarray], max_offset: int = MAX_OFFSET, min_peak: float = MIN_PEAK,
                 reference: str | None = None, smooth_sigma: float = SMOOTH_SIGMA) -> SyncResult:
    """Frame offsets of cameras from their motion signals.

    Parameters
    ----------
    signals : dict of str to ndarray of shape (T_c,)
        Per camera its :func:`motion_signal`.
    max_offset : int
        Largest offset searched either way, frames.
    min_peak : float
        Correlation a camera's best lag must reach to be trusted.
    reference : str, optional
        The camera the others are correlated with (default: the one with the most frames of motion).
    smooth_sigma : float
        Gaussian smoothing of the signals before correlating, frames.

    Returns
    -------
    SyncResult

    Raises
    ------
    InputError
        Fewer than two cameras, or a reference that is not among them.
    """
    if len(signals) < 2:
        raise InputError("sync: cameras", "at least two cameras to synchronise", f"{list(signals)}")
    if not (isinstance(max_offset, int) and max_offset >= 0):
        raise InputError("sync: max_offset", "a whole number of frames >= 0", repr(max_offset))
    names = list(signals)
    if reference is None:
        reference = max(names, key=lambda n: int(np.isfinite(signals[n]).sum()))
    if reference not in signals:
        raise InputError("sync: reference", f"one of {names}", repr(reference))
    smoothed = {n: _zscore(_smooth(np.asarray(s, float), smooth_sigma)) for n, s in signals.items()}
    lags = np.arange(-max_offset, max_offset + 1)
    lag_of, peaks, second, trusted, curves = {}, {}, {}, {}, {}
    for n in names:
        if n == reference:
            lag_of[n], peaks[n], second[n], trusted[n] = 0, 1.0, float("nan"), True
            curves[n] = [np.nan] * len(lags)
            continue
        curve = np.array([_correlation(smoothed[reference], smoothed[n], int(k)) for k in lags])
        curves[n] = curve.tolist()
        if not np.isfinite(curve).any():
            lag_of[n], peaks[n], second[n], trusted[n] = 0, float("nan"), float("nan"), False
            continue
        i = int(np.nanargmax(curve))
        away = np.abs(lags - lags[i]) >= 3
        peaks[n] = float(curve[i])
        second[n] = float(np.nanmax(curve[away])) if np.isfinite(curve[away]).any() else float("nan")
        trusted[n] = bool(curve[i] >= min_peak)
        lag_of[n] = int(lags[i]) if trusted[n] else 0
    # lag k: camera frame t shows reference frame t + k, i.e. the camera started k frames late
    low = min(lag_of.values())
    offsets = {n: int(lag_of[n] - low) for n in names}
    return SyncResult(offsets=offsets, reference=reference, peaks=peaks, second=second, trusted=trusted,
                      curves=curves, max_offset=max_offset)


# ------------------------------------------------------------------------------------ ray geometry

#: Residuals beyond this (metres) count as this much: a mis-detected keypoint weighs no more than a bad lag.
RESIDUAL_CLIP_M = 0.15
#: Rays of two cameras closer to parallel than this (sine of their angle) give no residual.
MIN_RAY_SINE = 0.1
#: Keypoints two views must share in a frame for the frame to count.
MIN_SHARED_KEYPOINTS = 6
#: Two views' people are paired when their rays pass within this (median over keypoints, metres).
MATCH_GATE_M = 0.3
#: Cost of moving one camera off the start most cameras share, per camera pair it belongs to, in units of
#: a pair's median cost over lags: a camera is declared late only when its pairs say so by more than this.
SHIFT_PENALTY = 0.03
#: A camera's offset is trusted when the best offset two frames or more away costs each of its pairs this
#: much more, in units of a pair's median cost.
MIN_GAIN = 0.01
#: Median-polish sweeps taking each frame's level out of a pair's frame-pair costs.
POLISH_SWEEPS = 3
#: The joint search tries every combination of offsets up to this many; beyond, coordinate descent.
EXHAUSTIVE_LIMIT = 2_000_000


def _nanmedian(x: np.ndarray, axis: int) -> np.ndarray:
    """``np.nanmedian`` without the warning for all-NaN slices (they give NaN)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(x, axis=axis, keepdims=True)


def _camera_rays(people_per_frame: list, camera, min_confidence: float) -> np.ndarray:
    """Unit ray directions ``(T, P, K, 3)`` of every person's keypoints (NaN where missing or unsure)."""
    n_people = max([len(f) for f in people_per_frame] + [1])
    n_kp = next((np.asarray(p).shape[0] for f in people_per_frame for p in f), 1)
    kp = np.full((len(people_per_frame), n_people, n_kp, 3), np.nan)
    for t, frame in enumerate(people_per_frame):
        for i, p in enumerate(frame):
            p = np.asarray(p, float)
            if p.ndim != 2 or p.shape != (n_kp, 3):
                raise InputError(f"sync: camera {camera.name!r}, frame {t}, person {i}",
                                 f"keypoints of shape ({n_kp}, 3) as in the other frames", f"{p.shape}")
            kp[t, i] = p
    kp[kp[..., 2] < min_confidence] = np.nan
    _, d = camera.rays(kp[..., :2])
    return d


def _signed_residuals(oa: np.ndarray, da: np.ndarray, ob: np.ndarray, db: np.ndarray,
                      lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances (metres) between camera a's rays at frame t and camera b's at frame t + lag.

    Per frame the people of the two views are paired one to one, the pair whose rays meet best
    first (least median distance over the keypoints both see, at least
    :data:`MIN_SHARED_KEYPOINTS`), as long as that median is under :data:`MATCH_GATE_M`.  Every
    pair counts, not only the best: a person standing still meets the other view's rays at every
    lag, and only the people who move tell the lag.  The sign is that of ``(ob - oa) . (da x db)``:
    for one pair of cameras looking at people it keeps its meaning from frame to frame, so a constant
    disagreement of two views about a keypoint is a constant residual.

    Parameters
    ----------
    oa, ob : ndarray of shape (3,)
        The cameras' centres, metres.
    da, db : ndarray of shape (T_a, P_a, K, 3) and (T_b, P_b, K, 3)
        Unit ray directions per frame, person and keypoint (NaN where missing).
    lag : int

    Returns
    -------
    residuals : ndarray of shape (T_a, min(P_a, P_b), K)
        Per frame of a, the paired people's residuals; NaN where there is no pair, the keypoint is
        missing, or the two rays are near parallel.
    unpaired : ndarray of shape (T_a,)
        People who could have been paired (both views see that many) but whose rays do not meet.
    """
    n_a, n_b = len(da), len(db)
    n_pairs = min(da.shape[1], db.shape[1])
    out = np.full((n_a, n_pairs, da.shape[2]), np.nan)
    unpaired = np.zeros(n_a, int)
    t0, t1 = max(0, -lag), min(n_a, n_b - lag)
    if t1 <= t0:
        return out, unpaired
    a = da[t0:t1, :, None]                        # (T, Pa, 1, K, 3)
    b = db[t0 + lag:t1 + lag, None]               # (T, 1, Pb, K, 3)
    n = np.cross(a, b)
    sine = np.linalg.norm(n, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = (n @ (ob - oa)) / sine
    s[~(sine >= MIN_RAY_SINE)] = np.nan            # near-parallel rays, or NaN
    med = _nanmedian(np.abs(s), -1)[..., 0]
    med[np.isfinite(s).sum(-1) < MIN_SHARED_KEYPOINTS] = np.inf
    seen_a = (np.isfinite(a[..., 0]).sum(-1) >= MIN_SHARED_KEYPOINTS).sum((1, 2))
    seen_b = (np.isfinite(b[..., 0]).sum(-1) >= MIN_SHARED_KEYPOINTS).sum((1, 2))
    res, left = out[t0:t1], np.minimum(seen_a, seen_b)
    single = (med.shape[1] == 1) and (med.shape[2] == 1)
    if single:
        ok = med[:, 0, 0] <= MATCH_GATE_M
        res[ok, 0] = s[ok, 0, 0]
        left = left - ok
    else:
        for t in range(len(med)):
            m = med[t].copy()
            for k in range(n_pairs):
                i, j = np.unravel_index(np.argmin(m), m.shape)
                if not m[i, j] <= MATCH_GATE_M:
                    break
                res[t, k] = s[t, i, j]
                m[i, :], m[:, j] = np.inf, np.inf
                left[t] -= 1
    unpaired[t0:t1] = left
    return out, unpaired


def _frame_costs(residuals: np.ndarray, unpaired: np.ndarray) -> np.ndarray:
    """How badly two views' rays disagree per frame, beyond a constant per keypoint (metres).

    Each keypoint's residuals minus their median over the frames and people (what stays is the
    part that changes with the motion: a joint the detector places differently in the two views is
    taken out), clipped at :data:`RESIDUAL_CLIP_M`, averaged over each pair's keypoints; the frame's
    cost is the mean over its pairs, a person left unpaired counting as :data:`RESIDUAL_CLIP_M`.

    Parameters
    ----------
    residuals : ndarray of shape (T, P, K)
    unpaired : ndarray of shape (T,)
        :func:`_signed_residuals` at one lag.

    Returns
    -------
    ndarray of shape (T,)
        NaN where the frame has neither a pair nor an unpaired person.
    """
    n_t, n_p, n_k = residuals.shape
    flat = residuals.reshape(n_t * n_p, n_k)
    keep = np.isfinite(flat).sum(0) >= 3
    per_pair = np.full(n_t * n_p, np.nan)
    rows = np.isfinite(flat[:, keep]).any(1)
    if rows.any():
        r = flat[rows][:, keep]
        centred = np.minimum(np.abs(r - _nanmedian(r, 0)), RESIDUAL_CLIP_M)
        per_pair[rows] = np.nanmean(centred, axis=1)
    per_pair = per_pair.reshape(n_t, n_p)
    count = np.isfinite(per_pair).sum(1) + unpaired
    total = np.nansum(per_pair, axis=1) + unpaired * RESIDUAL_CLIP_M
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _lag_curve(costs: np.ndarray, max_offset: int, min_overlap: int, sweeps: int = POLISH_SWEEPS) -> np.ndarray:
    """A pair's cost per lag from its frame-pair costs, each frame's general level taken out.

    ``costs[t, u]`` is the cost of frame ``t`` of one camera against frame ``u`` of the other (at
    lag ``u - t``).  Frames differ in how well the two views agree at every lag (a person hidden,
    two people mixed into one detection, nobody moving); averaging them straight would let the
    lags that happen to cover the good frames win.  A median polish (``sweeps`` times: subtract each
    row's median, then each column's) takes each frame's level out, then the mean along each
    diagonal ``u - t = k`` is the lag's cost (plus the median of all costs, to keep metres).

    Returns
    -------
    ndarray of shape (2 * max_offset + 1,)
        NaN where fewer than ``min_overlap`` frame pairs.
    """
    level = float(np.nanmedian(costs)) if np.isfinite(costs).any() else np.nan
    p = costs.copy()
    for _ in range(sweeps):
        p = p - np.nan_to_num(_nanmedian(p, 1))
        p = p - np.nan_to_num(_nanmedian(p, 0))
    lags = range(-max_offset, max_offset + 1)
    sums = np.array([np.nansum(np.diagonal(p, offset=k)) for k in lags])
    counts = np.array([np.isfinite(np.diagonal(p, offset=k)).sum() for k in lags])
    curve = np.full(len(sums), np.nan)
    ok = counts >= min_overlap
    if ok.any():
        curve[ok] = level + sums[ok] / counts.max()
    return curve


def pair_cost_curves(people: dict[str, list[list[np.ndarray]]], cameras: dict, max_offset: int = MAX_OFFSET,
                     min_confidence: float = MIN_CONFIDENCE,
                     min_overlap: int = MIN_OVERLAP) -> dict[tuple[str, str], np.ndarray]:
    """Per pair of cameras and lag, how badly their keypoints' rays disagree.

    Per lag, :func:`_signed_residuals` then :func:`_frame_costs` give each frame's cost; the
    frame-pair costs of all lags become one curve per pair by :func:`_lag_curve`.

    Parameters
    ----------
    people : dict of str to list of list of ndarray of shape (K, 3)
        Per camera, per frame the people detected (pixels, confidence).
    cameras : dict of str to Camera
        The calibrated camera of each name in ``people``.
    max_offset : int
        Lags ``-max_offset .. max_offset`` frames.
    min_confidence : float
        Keypoints below it are not used.
    min_overlap : int
        Fewest frames with a pairing of people for a lag's cost.

    Returns
    -------
    dict of (str, str) to ndarray of shape (2 * max_offset + 1,)
        For the pair ``(a, b)`` (in the order of ``people``), at lag ``k`` the cost (metres) of frame
        ``t`` of ``a`` against frame ``t + k`` of ``b``: least at ``k = offsets[a] - offsets[b]``.
        NaN where the overlap is too short.
    """
    names = list(people)
    centres = {n: np.asarray(cameras[n].center, float) for n in names}
    dirs = {n: _camera_rays(people[n], cameras[n], min_confidence) for n in names}
    curves = {}
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            n_a, n_b = len(dirs[a]), len(dirs[b])
            costs = np.full((n_a, n_b), np.nan)
            t = np.arange(n_a)
            for k in range(-max_offset, max_offset + 1):
                inside = (t + k >= 0) & (t + k < n_b)
                if inside.sum() < min_overlap:
                    continue
                e = _frame_costs(*_signed_residuals(centres[a], dirs[a], centres[b], dirs[b], k))
                costs[t[inside], t[inside] + k] = e[inside]
            curves[(a, b)] = _lag_curve(costs, max_offset, min_overlap)
    return curves


def _normalised(curve: np.ndarray) -> np.ndarray:
    """A pair's cost curve over its median over lags; lags without a cost at the curve's worst."""
    ok = np.isfinite(curve)
    if not ok.any():
        return np.ones_like(curve)
    c = curve / np.median(curve[ok]) if np.median(curve[ok]) > 0 else np.where(ok, curve, 0.0)
    return np.where(ok, c, np.max(c[ok]))


def _total_cost(offsets: np.ndarray, pairs: list, costs: np.ndarray, max_offset: int,
                penalty: float) -> np.ndarray:
    """Summed pair costs of offset combinations ``(N, C)`` (inf where two offsets differ by more than
    ``max_offset``), plus ``penalty`` per camera outside the largest group sharing one offset."""
    total = np.zeros(len(offsets))
    for p, (i, j) in enumerate(pairs):
        k = offsets[:, i] - offsets[:, j]
        inside = np.abs(k) <= max_offset
        total += np.where(inside, costs[p, np.clip(k + max_offset, 0, 2 * max_offset)], np.inf)
    same = (offsets[:, :, None] == offsets[:, None, :]).sum(-1).max(-1)
    return total + penalty * (offsets.shape[1] - same)


def _joint_offsets(n_cams: int, pairs: list, costs: np.ndarray, max_offset: int, penalty: float) -> np.ndarray:
    """The offsets (camera 0 at 0) of least :func:`_total_cost`: every combination when few enough, else
    coordinate descent from several starts (all at 0; each camera's best lag against every other)."""
    lags = np.arange(-max_offset, max_offset + 1)
    n_free = n_cams - 1
    if len(lags) ** n_free <= EXHAUSTIVE_LIMIT:
        best, best_cost = np.zeros(n_cams, int), np.inf
        rest = np.stack(np.meshgrid(*[lags] * (n_free - 1), indexing="ij"), -1).reshape(-1, n_free - 1) \
            if n_free > 1 else np.zeros((1, 0), int)
        for k in lags:   # one value of camera 1 at a time keeps the arrays small
            o = np.column_stack([np.zeros(len(rest), int), np.full(len(rest), k), rest])
            total = _total_cost(o, pairs, costs, max_offset, penalty)
            i = int(np.argmin(total))
            if total[i] < best_cost:
                best, best_cost = o[i].copy(), total[i]
        return best
    starts = [np.zeros(n_cams, int)]
    for anchor in range(n_cams):
        s = np.zeros(n_cams, int)
        for p, (i, j) in enumerate(pairs):   # lag k = offsets[i] - offsets[j]
            if anchor in (i, j):
                k = int(lags[np.argmin(costs[p])])
                s[j if i == anchor else i] = -k if i == anchor else k
        starts.append(s - s[0])
    best, best_cost = starts[0], np.inf
    for o in starts:
        o = np.clip(o, -max_offset, max_offset)
        cost = float(_total_cost(o[None], pairs, costs, max_offset, penalty)[0])
        for _ in range(50):
            moved = False
            for c in range(1, n_cams):
                trial = np.repeat(o[None], len(lags), 0)
                trial[:, c] = lags
                total = _total_cost(trial, pairs, costs, max_offset, penalty)
                i = int(np.argmin(total))
                if total[i] < cost:
                    o, cost, moved = trial[i], float(total[i]), True
            if not moved:
                break
        if cost < best_cost:
            best, best_cost = o, cost
    return best


def find_offsets_geometric(people: dict[str, list[list[np.ndarray]]], cameras: dict, max_offset: int = MAX_OFFSET,
                           reference: str | None = None, min_confidence: float = MIN_CONFIDENCE,
                           shift_penalty: float = SHIFT_PENALTY, min_gain: float = MIN_GAIN) -> SyncResult:
    """Frame offsets of calibrated cameras, solved jointly from where every pair's keypoint rays meet.

    Keypoints of one instant seen by two calibrated cameras lie on rays that (nearly) meet; a lag
    moves the moving limbs off them.  For every pair of cameras and lag, :func:`pair_cost_curves`
    measures the rays' signed distances per keypoint, takes out each keypoint's constant part (two
    views that place a joint differently disagree by the same amount at every frame, which would
    otherwise pull the least cost to a wrong lag when the motion is slow) and averages the rest.
    Each pair's curve is divided by its median over lags, so every pair counts alike.  The offsets
    minimise the sum over all pairs of the cost at the lag they imply (pair ``a, b``: lag
    ``offsets[a] - offsets[b]``), plus ``shift_penalty`` per pair of each camera that is not in the
    largest group of cameras sharing one start: a camera is called late only when its pairs agree
    on it clearly, so a rig in sync comes out all 0.  No camera is a reference: a late one is found
    by its pairs with all the others.

    A camera's ``confidence`` is how much more its pairs cost, each on average and in units of its
    median cost, at the best offset two frames or more from the one found: above ``min_gain`` it is
    ``trusted`` (the offset is right to a frame).  An untrusted camera keeps the offset found;
    ``curves`` show why.

    Parameters
    ----------
    people : dict of str to list of list of ndarray of shape (K, 3)
        Per camera, per frame the people detected (pixels, confidence).
    cameras : dict of str to Camera
        The calibrated camera of each name in ``people``.
    max_offset : int
        Largest offset between two cameras, frames.
    reference : str, optional
        The camera held at 0 during the search (any; default the one with the most frames with
        people).  The offsets do not depend on it.
    min_confidence : float
        Keypoints below it are not used.
    shift_penalty : float
        See above, in units of a pair's median cost.
    min_gain : float
        Confidence a camera needs to be trusted.

    Returns
    -------
    SyncResult
        ``method`` ``"rays"``; ``peaks[c]`` the camera's summed normalised pair cost at the offset
        found, ``second[c]`` the least two frames or more away, ``curves[c]`` that cost with the
        camera moved by each of ``-max_offset .. max_offset`` frames (the others kept; NaN beyond
        ``max_offset`` from another camera), ``pair_curves`` each pair's cost (metres) per lag.

    Raises
    ------
    InputError
        Fewer than two cameras, a camera without calibration, a reference not among them, a bad
        ``max_offset``, or keypoint arrays of different shapes in one camera.
    """
    names = list(people)
    if len(names) < 2:
        raise InputError("sync: cameras", "at least two cameras to synchronise", f"{names}")
    if not (isinstance(max_offset, int) and max_offset >= 0):
        raise InputError("sync: max_offset", "a whole number of frames >= 0", repr(max_offset))
    missing = [n for n in names if n not in cameras]
    if missing:
        raise InputError("sync: calibration", f"a camera for each keypoint folder {names}", f"none for {missing}")
    if reference is None:
        reference = max(names, key=lambda n: sum(bool(f) for f in people[n]))
    if reference not in people:
        raise InputError("sync: reference", f"one of {names}", repr(reference))
    order = [reference] + [n for n in names if n != reference]
    raw = pair_cost_curves({n: people[n] for n in order}, cameras, max_offset, min_confidence)
    pairs = [(order.index(a), order.index(b)) for a, b in raw]
    costs = np.array([_normalised(c) for c in raw.values()])
    penalty = shift_penalty * (len(names) - 1)
    rel = _joint_offsets(len(order), pairs, costs, max_offset, penalty)
    lags = np.arange(-max_offset, max_offset + 1)
    peaks, second, confidence, trusted, curves = {}, {}, {}, {}, {}
    for c, n in enumerate(order):
        trial = np.repeat(rel[None], len(lags), 0)
        trial[:, c] = rel[c] + lags
        own = [p for p, (i, j) in enumerate(pairs) if c in (i, j)]
        curve = _total_cost(trial, [pairs[p] for p in own], costs[own], max_offset, 0.0)
        curve[~np.isfinite(curve)] = np.nan
        away = np.abs(lags) >= 2
        peaks[n] = float(curve[max_offset])
        second[n] = float(np.nanmin(curve[away])) if np.isfinite(curve[away]).any() else float("nan")
        confidence[n] = (second[n] - peaks[n]) / len(own) if np.isfinite(second[n]) else float("nan")
        trusted[n] = bool(np.isfinite(confidence[n]) and confidence[n] > min_gain)
        curves[n] = curve.tolist()
    offsets = {n: int(rel[order.index(n)] - rel.min()) for n in names}
    return SyncResult(offsets=offsets, reference=reference, peaks={n: peaks[n] for n in names},
                      second={n: second[n] for n in names}, trusted={n: trusted[n] for n in names},
                      curves={n: curves[n] for n in names}, max_offset=max_offset, method="rays",
                      confidence={n: confidence[n] for n in names},
                      pair_curves={f"{a}|{b}": c.tolist() for (a, b), c in raw.items()})
