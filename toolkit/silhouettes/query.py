"""Querying the silhouette database: the k best entries by E_S (source 000 eq. 1).

    E_S = (1 - λ) · (1/n) Σ_i |v(i) - w(i)|  +  λ · (1/m) Σ_r |p(r) - q(r)|

``v`` is the query descriptor, ``w`` an entry's descriptor (n = 1280 cells,
values in [0, 1]), ``q`` the entry's 14 joints and ``p`` the previous frame's
joints, both normalised to their silhouette's bounding box, ``|p(r) - q(r)|``
the Euclidean distance of joint ``r``.  λ = 0 on the first frame (no previous
pose) and :data:`LAMBDA_TEMPORAL` = 0.5 after; the :data:`K_BEST` = 3 best
entries are kept.

The silhouette term is computed exactly over the whole database with
OpenCV's SIMD absolute difference on the stored uint8 levels, in blocks; the
query descriptor is quantised the same way (``round(255 v)``), so a database
member queried with its own descriptor scores 0.  Previous joints that are
NaN are left out of the joint mean; when all are NaN the query falls back to
λ = 0.

Variants (claims 2-3):

* ``metric="hausdorff"``: the silhouette term becomes the symmetric Hausdorff
  distance between the outer contours of the two 32 x 40 grids (cells at
  least half covered), divided by the grid diagonal so that it lies in [0, 1].
  It re-ranks a shortlist of the :data:`HAUSDORFF_SHORTLIST` best entries by
  the area (L1) version of E_S.
* ``flow_weight = μ > 0`` with a query flow descriptor: the silhouette term
  becomes ``(L1 + μ · mean|f - g|) / (1 + μ)`` for entries that store a flow
  (entries without one keep the plain L1 term).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.spatial.distance import directed_hausdorff

from toolkit.errors import InputError
from toolkit.silhouettes.database import FLOW_SIZE, SilhouetteDatabase
from toolkit.silhouettes.descriptor import (
    DESCRIPTOR_LEVELS,
    DESCRIPTOR_SIZE,
    SILHOUETTE_GRID,
    denormalise_joints,
    descriptor_grid,
    quantise_descriptor,
)
from toolkit.skeleton import SKELETON_14

#: Number of best entries kept per view (source 000 §2.1: k = 3).
K_BEST = 3
#: Weight λ of the temporal term after the first frame (source 000 §2.1: 0.5).
LAMBDA_TEMPORAL = 0.5
#: Entries re-ranked by the Hausdorff variant (best by the L1 error first).
HAUSDORFF_SHORTLIST = 100
#: Rows per block of the vectorised L1 distance (keeps the working set in cache).
DISTANCE_BLOCK_ROWS = 2048
#: A grid cell belongs to the contour shape when at least this fraction is covered.
CONTOUR_THRESHOLD = 0.5
#: Diagonal of the grid in cells: the Hausdorff distance is divided by it.
GRID_DIAGONAL = float(np.hypot(*SILHOUETTE_GRID))
METRICS = ("l1", "hausdorff")


@dataclass(frozen=True)
class QueryConfig:
    """How the database is queried.

    Parameters
    ----------
    k : int
        Number of best entries returned (:data:`K_BEST`).
    lam : float
        λ of eq. (1) when a previous pose is given (:data:`LAMBDA_TEMPORAL`);
        λ = 0 is used without one.
    metric : str
        ``"l1"`` (eq. 1) or ``"hausdorff"`` (contour variant).
    shortlist : int
        Entries re-ranked by the Hausdorff variant.
    flow_weight : float
        μ of the optical-flow term (0: off).
    """

    k: int = K_BEST
    lam: float = LAMBDA_TEMPORAL
    metric: str = "l1"
    shortlist: int = HAUSDORFF_SHORTLIST
    flow_weight: float = 0.0

    def __post_init__(self):
        if isinstance(self.k, bool) or not isinstance(self.k, (int, np.integer)) or self.k < 1:
            raise InputError("QueryConfig.k", "a positive integer", repr(self.k))
        if not 0.0 <= float(self.lam) <= 1.0:
            raise InputError("QueryConfig.lam", "a weight in [0, 1]", repr(self.lam))
        if self.metric not in METRICS:
            raise InputError("QueryConfig.metric", f"one of {METRICS}", repr(self.metric))
        if int(self.shortlist) < 1:
            raise InputError("QueryConfig.shortlist", "a positive integer", repr(self.shortlist))
        if not float(self.flow_weight) >= 0.0:
            raise InputError("QueryConfig.flow_weight", "a non-negative weight", repr(self.flow_weight))


@dataclass(frozen=True)
class Candidates:
    """The best database entries for one silhouette, best first.

    Attributes
    ----------
    indices : ndarray of shape (k,), int
        Database rows.
    errors : ndarray of shape (k,)
        E_S, ascending.
    silhouette_errors : ndarray of shape (k,)
        The matching term (mean |v - w|, or the normalised Hausdorff distance).
    temporal_errors : ndarray of shape (k,)
        Mean joint distance to the previous pose, box units (NaN when λ = 0).
    joints : ndarray of shape (k, 14, 2)
        Candidate joints normalised to the bounding box.
    lam : float
        λ actually used.
    metric : str
    """

    indices: np.ndarray
    errors: np.ndarray
    silhouette_errors: np.ndarray
    temporal_errors: np.ndarray
    joints: np.ndarray
    lam: float
    metric: str = "l1"
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def __len__(self) -> int:
        return len(self.indices)

    def joints_px(self, bbox: np.ndarray) -> np.ndarray:
        """Candidate joints in pixels of the query silhouette's box, (k, 14, 2)."""
        return denormalise_joints(self.joints, bbox)


def _query_levels(descriptor) -> np.ndarray:
    v = np.asarray(descriptor)
    if v.shape != (DESCRIPTOR_SIZE,):
        raise InputError("descriptor", f"an array of shape ({DESCRIPTOR_SIZE},)", f"shape {v.shape}")
    return v if v.dtype == np.uint8 else quantise_descriptor(v)


def silhouette_distances(database: SilhouetteDatabase, descriptor: np.ndarray) -> np.ndarray:
    """Mean absolute difference between a descriptor and every entry.

    Parameters
    ----------
    database : SilhouetteDatabase
    descriptor : ndarray of shape (1280,)
        Values in [0, 1] (quantised to uint8 levels) or uint8 levels.

    Returns
    -------
    ndarray of shape (N,), float64
        ``mean |v - w|`` in [0, 1].
    """
    v = _query_levels(descriptor)
    D = database.descriptors
    n = len(D)
    out = np.empty(n, np.int64)
    rows = min(DISTANCE_BLOCK_ROWS, max(n, 1))
    block_v = np.broadcast_to(v, (rows, DESCRIPTOR_SIZE)).copy()
    for s in range(0, n, rows):
        blk = D[s:s + rows]
        diff = cv2.absdiff(blk, block_v[:len(blk)])
        out[s:s + len(blk)] = cv2.reduce(diff, 1, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
    return out / float(DESCRIPTOR_LEVELS * DESCRIPTOR_SIZE)


def joint_distances(database: SilhouetteDatabase, previous: np.ndarray) -> tuple[np.ndarray, int]:
    """Mean Euclidean distance between previous joints and every entry's joints.

    Parameters
    ----------
    database : SilhouetteDatabase
    previous : ndarray of shape (14, 2)
        Normalised joints; NaN joints are left out.

    Returns
    -------
    distances : ndarray of shape (N,)
        Box units (NaN when no previous joint is finite).
    n_used : int
        Number of finite previous joints.
    """
    p = np.asarray(previous, dtype=np.float64)
    if p.shape != (SKELETON_14.n_joints, 2):
        raise InputError("previous", f"normalised joints of shape ({SKELETON_14.n_joints}, 2)", f"shape {p.shape}")
    ok = np.isfinite(p).all(axis=1)
    if not ok.any():
        return np.full(len(database), np.nan), 0
    cache = database.cache
    if "joints64" not in cache:
        cache["joints64"] = database.joints.astype(np.float64)
    Q, pk = cache["joints64"], p[ok]
    out = np.empty(len(database))
    for s in range(0, len(database), DISTANCE_BLOCK_ROWS):
        d = (Q[s:s + DISTANCE_BLOCK_ROWS] if ok.all() else Q[s:s + DISTANCE_BLOCK_ROWS, ok]) - pk
        out[s:s + len(d)] = np.sqrt(np.einsum("njk,njk->nj", d, d)).mean(axis=1)
    return out, int(ok.sum())


def _flow_term(database: SilhouetteDatabase, flow) -> np.ndarray | None:
    if flow is None or database.flows is None:
        return None
    f = np.asarray(flow, dtype=np.float32)
    if f.shape != (FLOW_SIZE,):
        raise InputError("flow", f"a flow descriptor of shape ({FLOW_SIZE},)", f"shape {f.shape}")
    out = np.full(len(database), np.nan)
    F = database.flows
    has = ~np.isnan(F[:, 0])
    idx = np.flatnonzero(has)
    for s in range(0, len(idx), DISTANCE_BLOCK_ROWS):
        sel = idx[s:s + DISTANCE_BLOCK_ROWS]
        out[sel] = np.abs(F[sel].astype(np.float32) - f).mean(axis=1)
    return out


def grid_contour(grid: np.ndarray, threshold: float = CONTOUR_THRESHOLD) -> np.ndarray:
    """Outer contour points of a 40 x 32 grid, in cell units (cell centres at +0.5).

    Cells covered at least ``threshold`` form the shape; when none is, every
    covered cell does.  Returns an (M, 2) array of (x, y); empty for an empty grid.
    """
    g = np.asarray(grid, dtype=np.float32)
    shape = (g >= threshold * (1.0 if g.max(initial=0) <= 1.0 else DESCRIPTOR_LEVELS))
    if not shape.any():
        shape = g > 0
    if not shape.any():
        return np.zeros((0, 2))
    contours, _ = cv2.findContours(shape.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    pts = np.concatenate([c.reshape(-1, 2) for c in contours]).astype(np.float64)
    return pts + 0.5


def hausdorff_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric Hausdorff distance between two point sets (M, 2) and (K, 2); inf if one is empty."""
    if len(a) == 0 or len(b) == 0:
        return float("inf")
    return max(directed_hausdorff(a, b)[0], directed_hausdorff(b, a)[0])


def _entry_contour(database: SilhouetteDatabase, i: int) -> np.ndarray:
    cache = database.cache.setdefault("contours", {})
    if i not in cache:
        cache[i] = grid_contour(descriptor_grid(database.descriptors[i]).astype(np.float32) / DESCRIPTOR_LEVELS)
    return cache[i]


def query_database(database: SilhouetteDatabase, descriptor: np.ndarray, previous: np.ndarray | None = None,
                   config: QueryConfig = QueryConfig(), *, flow: np.ndarray | None = None) -> Candidates:
    """The k entries with the smallest E_S (eq. 1).

    Parameters
    ----------
    database : SilhouetteDatabase
    descriptor : ndarray of shape (1280,)
        The query silhouette (values in [0, 1] or uint8 levels).
    previous : ndarray of shape (14, 2), optional
        The previous frame's joints normalised to *its* bounding box; ``None``
        on the first frame (λ = 0).  NaN joints are ignored; all NaN gives λ = 0.
    config : QueryConfig
    flow : ndarray of shape (2560,), optional
        Query flow descriptor, used when ``config.flow_weight > 0``.

    Returns
    -------
    Candidates
        ``min(k, N)`` entries, best first.

    Raises
    ------
    InputError
        If the database is empty or an argument has the wrong shape.

    Examples
    --------
    >>> cands = query_database(db, silhouette_descriptor(mask))          # doctest: +SKIP
    >>> cands.joints_px(bounding_box(mask))                              # doctest: +SKIP
    """
    if not isinstance(database, SilhouetteDatabase):
        raise InputError("database", "a SilhouetteDatabase", type(database).__name__)
    n = len(database)
    if n == 0:
        raise InputError("database", "a silhouette database with at least one entry", "an empty database")
    sil = silhouette_distances(database, descriptor)
    if config.flow_weight > 0 and flow is not None:
        fl = _flow_term(database, flow)
        if fl is not None:
            mu = float(config.flow_weight)
            sil = np.where(np.isnan(fl), sil, (sil + mu * np.nan_to_num(fl)) / (1 + mu))
    lam = 0.0
    temporal = np.full(n, np.nan)
    if previous is not None and config.lam > 0:
        temporal, n_used = joint_distances(database, previous)
        if n_used > 0:
            lam = float(config.lam)
    err = sil if lam == 0.0 else (1 - lam) * sil + lam * temporal
    k = min(int(config.k), n)
    if config.metric == "hausdorff":
        m = min(max(int(config.shortlist), k), n)
        short = np.argpartition(err, m - 1)[:m] if m < n else np.arange(n)
        q_contour = grid_contour(descriptor_grid(_query_levels(descriptor)).astype(np.float32)
                                 / DESCRIPTOR_LEVELS)
        haus = np.array([hausdorff_distance(q_contour, _entry_contour(database, int(i))) for i in short])
        sil_s = haus / GRID_DIAGONAL
        err_s = sil_s if lam == 0.0 else (1 - lam) * sil_s + lam * temporal[short]
        order = np.lexsort((short, err_s))[:k]
        idx = short[order]
        return Candidates(idx, err_s[order], sil_s[order], temporal[idx] if lam > 0 else np.full(k, np.nan),
                          database.joints[idx].astype(np.float64), lam, "hausdorff")
    part = np.argpartition(err, k - 1)[:k] if k < n else np.arange(n)
    idx = part[np.lexsort((part, err[part]))]
    return Candidates(idx, err[idx], sil[idx], temporal[idx] if lam > 0 else np.full(k, np.nan),
                      database.joints[idx].astype(np.float64), lam, "l1")
