"""Each camera's frame offset from the motion of the people it sees.

Cameras started at different times film the same motion shifted by whole frames.  Per camera,
:func:`motion_signal` measures how fast the people move in its image at every frame: the
keypoints of each person are matched to the nearest person of the next frame, their speeds (pixels
per frame, divided by the person's height in the image, so near and far cameras weigh alike) are
summed over keypoints and people.  Speeds of one motion seen from different directions differ in
size but rise and fall together; :func:`find_offsets` correlates every camera's signal with a
reference camera's over lags of up to ``max_offset`` frames (the standardised signals' product on the frames both
cover, after a light smoothing; summed over the overlap and divided by the shorter signal's length, so
lags that leave little overlap score low) and takes the best lag.

Offsets mean: ``offsets[c] = k`` when camera ``c`` started ``k`` frames late, i.e. its frame ``f``
shows the instant of frame ``f + k`` of a camera with offset 0.  The smallest offset is 0.  A
camera whose best correlation is weak (below ``min_peak``) or not clearly better than the
next best lag away from it keeps offset 0 and is reported as not synchronised.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolkit.errors import InputError

__all__ = ["SyncResult", "motion_signal", "find_offsets", "MAX_OFFSET", "MIN_PEAK", "MIN_CONFIDENCE"]

#: Largest offset searched, frames.
MAX_OFFSET = 60
#: Correlation a lag must reach to be trusted.
MIN_PEAK = 0.3
#: Keypoints below this confidence do not count in the motion.
MIN_CONFIDENCE = 0.3
#: Smoothing of the signals (frames, Gaussian sigma) before correlating.
SMOOTH_SIGMA = 1.0
#: A geometric lag is trusted when its ray cost is below this share of the least cost 3+ frames away.
TRUST_RATIO = 0.8
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
        The camera every other was correlated with.
    peaks : dict of str to float
        The correlation at the chosen lag (1.0 for the reference).
    second : dict of str to float
        The best correlation at least 3 frames away from the chosen lag (how clear the peak is).
    trusted : dict of str to bool
        Whether the peak passed ``min_peak`` (an untrusted camera keeps offset 0).
    curves : dict of str to list of float
        Correlation per lag, lags ``-max_offset .. max_offset`` (NaN where the overlap is too short).
    max_offset : int
    """

    offsets: dict[str, int]
    reference: str
    peaks: dict[str, float]
    second: dict[str, float]
    trusted: dict[str, bool]
    curves: dict[str, list[float]] = field(repr=False)
    max_offset: int = MAX_OFFSET

    def to_json(self) -> dict:
        """The ``sync.json`` document: offsets, then the evidence."""
        return {"offsets": {k: int(v) for k, v in self.offsets.items()},
                "meaning": "offsets[camera] = k: the camera started k frames late; its frame f shows the instant "
                           "of frame f + k of a camera with offset 0",
                "reference": self.reference, "peaks": self.peaks, "second_peaks": self.second,
                "trusted": self.trusted, "max_offset": self.max_offset,
                "lags": list(range(-self.max_offset, self.max_offset + 1)),
                "curves": {k: [None if not np.isfinite(v) else round(float(v), 4) for v in c]
                           for k, c in self.curves.items()}}


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


def _ray_distance(o1, d1, o2, d2) -> np.ndarray:
    """Distance between the lines (o1, d1) and (o2, d2), row by row (unit directions)."""
    n = np.cross(d1, d2)
    norm = np.linalg.norm(n, axis=-1)
    w = o2 - o1
    par = norm < 1e-9
    out = np.abs((w * n).sum(-1)) / np.where(par, 1.0, norm)
    # parallel rays: the distance of o2 from the first line
    out[par] = np.linalg.norm(np.cross(w[par], d1[par]), axis=-1)
    return out


def _pair_cost(rays_a: list, rays_b: list) -> float:
    """The smallest, over pairs of people, median ray distance of their keypoints seen by both (metres)."""
    best = np.inf
    for (oa, da, ca) in rays_a:
        for (ob, db, cb) in rays_b:
            ok = ca & cb
            if ok.sum() < 6:
                continue
            best = min(best, float(np.median(_ray_distance(oa[ok], da[ok], ob[ok], db[ok]))))
    return best


def find_offsets_geometric(people: dict[str, list[list[np.ndarray]]], cameras: dict, max_offset: int = MAX_OFFSET,
                           reference: str | None = None, min_confidence: float = MIN_CONFIDENCE) -> SyncResult:
    """Frame offsets of calibrated cameras: the lag at which their keypoints' rays meet the reference's best.

    For a calibrated rig this is far sharper than the motion signals of :func:`find_offsets`: keypoints
    of the same instant seen from two cameras lie on rays that (nearly) meet, and a lag of a few frames
    moves the limbs off them.  Per camera and lag, the median over frames of the median distance
    between the camera's and the reference's rays of the same keypoints (the best pairing of people in
    the frame) is the cost; the lag of least cost wins.  The evidence (``peaks``, ``curves``) holds
    ``1 - cost / cost at the worst lag`` so that higher is better as for :func:`find_offsets`.

    Parameters
    ----------
    people : dict of str to list of list of ndarray of shape (K, 3)
        Per camera, per frame the people detected (pixels, confidence).
    cameras : dict of str to Camera
        The calibrated camera of each name in ``people``.
    max_offset : int
    reference : str, optional
        Default: the camera with the most frames with people.
    min_confidence : float

    Returns
    -------
    SyncResult
    """
    names = list(people)
    if len(names) < 2:
        raise InputError("sync: cameras", "at least two cameras to synchronise", f"{names}")
    missing = [n for n in names if n not in cameras]
    if missing:
        raise InputError("sync: calibration", f"a camera for each keypoint folder {names}", f"none for {missing}")
    if reference is None:
        reference = max(names, key=lambda n: sum(bool(f) for f in people[n]))
    rays = {}
    for n in names:
        cam, per_frame = cameras[n], []
        for frame in people[n]:
            rs = []
            for p in frame:
                o, d = cam.rays(np.asarray(p, float)[:, :2])
                rs.append((o, d, (np.asarray(p)[:, 2] >= min_confidence) & np.isfinite(d).all(-1)))
            per_frame.append(rs)
        rays[n] = per_frame
    lags = np.arange(-max_offset, max_offset + 1)
    lag_of, peaks, second, trusted, curves = {}, {}, {}, {}, {}
    ref = rays[reference]
    for n in names:
        if n == reference:
            lag_of[n], peaks[n], second[n], trusted[n], curves[n] = 0, 1.0, float("nan"), True, [np.nan] * len(lags)
            continue
        cost = np.full(len(lags), np.nan)
        for i, k in enumerate(lags):
            d = [_pair_cost(rays[n][t], ref[t + k]) for t in range(len(rays[n])) if 0 <= t + k < len(ref)]
            d = [x for x in d if np.isfinite(x)]
            if len(d) >= MIN_OVERLAP:
                cost[i] = np.median(d)
        if not np.isfinite(cost).any():
            lag_of[n], peaks[n], second[n], trusted[n], curves[n] = 0, float("nan"), float("nan"), False, cost.tolist()
            continue
        score = 1.0 - cost / np.nanmax(cost)
        i = int(np.nanargmin(cost))
        away = np.abs(lags - lags[i]) >= 3
        peaks[n] = float(score[i])
        second[n] = float(np.nanmax(score[away])) if np.isfinite(score[away]).any() else float("nan")
        # trusted: the best lag's rays meet clearly better than at lags three frames or more away
        trusted[n] = bool(np.isfinite(second[n]) and cost[i] < TRUST_RATIO * np.nanmin(cost[away]))
        lag_of[n] = int(lags[i]) if trusted[n] else 0
        curves[n] = score.tolist()
    low = min(lag_of.values())
    offsets = {n: int(lag_of[n] - low) for n in names}
    return SyncResult(offsets=offsets, reference=reference, peaks=peaks, second=second, trusted=trusted,
                      curves=curves, max_offset=max_offset)
