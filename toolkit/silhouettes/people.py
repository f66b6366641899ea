"""Several people from silhouettes alone: where each stands, and each one's silhouette per camera.

Stage 1 from silhouettes follows one person.  With several people in the
volume and no keypoints, the cameras' foreground masks are shared by everyone;
this module separates them:

1. **Where the people stand** (:func:`locate_people`): the ground plane
   (z = 0, metres) is cut into cells; a person standing on a cell fills the
   image box of an upright body there (the projection of a
   ``2 r x 2 r x height`` box) in the cameras that see it.  People are chosen
   greedily, best first.  The pixels of a chosen person's box are
   *explained*; for every other cell a camera is *clear* when less than
   ``occluded_share`` of its box is explained (else it says nothing: the
   person would be behind or in front of one already chosen), and *agrees*
   when the unexplained part of its box is at least ``min_fill`` foreground.
   A cell needs two agreeing cameras (one in a one-camera rig); its score is
   the agreeing cameras' fill minus the shortfall of the clear ones that do
   not agree, so a camera that misses a person (a kit the colour of the
   pitch) lowers the score but does not veto it.  A person hidden behind
   people already chosen in every camera but one (two cameras and a crowd)
   is taken on that one camera when it *stands* there: the box's bottom band
   (the feet) is foreground and the band just below it is not, which fixes
   the depth along that camera's ray; the hidden cameras must show
   foreground over the box.  Last, a person must show foreground of its own
   (no other chosen box over it) in two cameras (the one for such a hidden
   person), else it is dropped: a ghost (the crossing of two people's rays,
   which plain visual-hull occupancy finds) is explained by the real people
   in the cameras that made it and empty in the others.
   Each position is then refined (:func:`refine_positions`): the vertical
   planes through every camera and the median column of the person's own
   silhouette meet on the ground.
2. **Who is who over time** (:func:`track_positions`): positions linked frame
   to frame by a minimum-cost assignment within a step; tracks followed in
   enough frames are the participants, their positions interpolated over the
   frames they were missed.
3. **Each one's silhouette** (:func:`split_masks`): a foreground pixel inside
   a person's wide box (arms out) belongs to that person; where boxes overlap,
   to the nearer person whose core box holds it, else to the person whose
   image axis is nearest.  A camera in which a person's core box is mostly
   behind nearer people is left out of that person's stage 1 (``None``): a
   half-hidden silhouette matches the wrong pose.

4. **Which way each one faces** (:func:`faces_backwards`): silhouettes do not
   tell a pose from its mirror image (every view's left and right swapped:
   the same rays, the same cost), and stage 1 breaks that tie by the limbs'
   bends or the previous frame.  A person walking or running faces the way
   they go: where the track moves faster than
   :data:`MIRROR_MIN_SPEED_M_S` and the hips face backwards, the mirror
   image is taken.

All positions are metres on the ground plane ``z = 0`` (the synthetic scenes'
and the calibrated rigs' convention: z up).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from toolkit.cameras import Rig
from toolkit.errors import InputError

__all__ = ["PeopleSilhouettesConfig", "GroundGrid", "ground_grid", "locate_people", "refine_positions",
           "track_positions", "split_masks", "ground_velocities", "faces_backwards"]


#: Speed (m/s) from which a person is taken to face the way it goes (a walk is 1.2-1.5 m/s).
MIRROR_MIN_SPEED_M_S = 0.8
#: ... and faces backwards when the cosine between its hips' facing and the way it goes is below this.
MIRROR_MAX_COSINE = -0.3

#: Ground contact of a box in a camera (people hidden in all cameras but one): the feet band is
#: this share of the box's height; it must be at least CONTACT_MIN_FEET foreground, and the band of
#: the same height just below the box at most CONTACT_MAX_BELOW.
CONTACT_BAND, CONTACT_MIN_FEET, CONTACT_MAX_BELOW = 0.08, 0.1, 0.1

#: A person seen usable by one camera only stands where the ray of its silhouette's median column at
#: this percentile of its rows (the feet) meets the ground.
FEET_PERCENTILE = 99.0

#: Rounds of :func:`refine_positions` at most, and the move (metres) under which it stops.
REFINE_ROUNDS, REFINE_STOP_M = 4, 0.02


@dataclass(frozen=True)
class PeopleSilhouettesConfig:
    """Options of the people's separation.

    Parameters
    ----------
    cell_m : float
        Ground cell size, metres.
    radius_m : float
        Half width of a body's core box, metres (torso and legs).
    height_m : float
        Height of a body's box, metres.
    wide_radius_m : float
        Half width of the region a person's silhouette may take (arms out), metres.
    min_fill : float
        Share of the visible part of a camera's core box that must be foreground for the camera to
        agree that a person stands there.
    disagree_weight : float
        A clear camera that does not agree lowers a cell's score by this times its shortfall.
    occluded_share : float
        A camera whose core box is at least this share covered by the boxes of people already chosen
        is occluded for that cell.
    min_visible : float
        A camera showing less than this share of a person's core box (nearer people in front) is
        left out of that person's stage 1.
    min_separation_m : float
        Two people stand at least this far apart, metres.
    min_own : float
        A person must show at least this share of its core box as foreground no other person's box
        covers, in two cameras (one in a one-camera rig), or it is dropped as a ghost.
    max_people : int
        At most this many people per frame.
    max_step_m : float
        Tracking: the largest move of a person between two consecutive frames, metres.
    min_share : float
        Tracking: a track found in fewer than this share of the frames is not a participant.
    max_cells : int
        The ground grid is coarsened until it has at most this many cells.
    """

    cell_m: float = 0.1
    radius_m: float = 0.18
    height_m: float = 1.75
    wide_radius_m: float = 0.7
    min_fill: float = 0.35
    disagree_weight: float = 1.0
    occluded_share: float = 0.5
    min_visible: float = 0.6
    min_separation_m: float = 0.5
    min_own: float = 0.3
    max_people: int = 16
    max_step_m: float = 0.8
    min_share: float = 0.25
    max_cells: int = 250_000

    def __post_init__(self):
        for name in ("cell_m", "radius_m", "height_m", "wide_radius_m", "max_step_m"):
            if not getattr(self, name) > 0:
                raise InputError(f"PeopleSilhouettesConfig.{name}", "a positive length in metres",
                                 f"{getattr(self, name)}")
        for name in ("min_fill", "occluded_share", "min_visible", "min_share"):
            if not 0 <= getattr(self, name) <= 1:
                raise InputError(f"PeopleSilhouettesConfig.{name}", "a share in [0, 1]", f"{getattr(self, name)}")


@dataclass(frozen=True)
class GroundGrid:
    """Ground cells and their core boxes in every camera.

    Attributes
    ----------
    xy : ndarray of shape (N, 2)
        Cell centres, metres on z = 0.
    boxes : ndarray of shape (V, N, 4), int
        Per camera, the core box ``x0, y0, x1, y1`` (pixels, end exclusive) clipped to the image.
    seen : ndarray of shape (V, N), bool
        The camera sees the cell: at least half the box inside the image, in front of the camera.
    """

    xy: np.ndarray
    boxes: np.ndarray
    seen: np.ndarray


def _box_corners(xy: np.ndarray, r: float, h: float) -> np.ndarray:
    """(N, 2) ground points to the 8 corners (N, 8, 3) of upright boxes of half width r, height h."""
    d = np.array([[sx * r, sy * r, z] for sx in (-1, 1) for sy in (-1, 1) for z in (0.0, h)])
    return np.concatenate([xy, np.zeros((len(xy), 1))], 1)[:, None, :] + d[None]


def _boxes(rig: Rig, xy: np.ndarray, r: float, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image boxes (V, N, 4) clipped, the unclipped area share inside (V, N) and in-front flags (V, N)."""
    corners = _box_corners(xy, r, h)
    boxes = np.zeros((len(rig), len(xy), 4), int)
    inside = np.zeros((len(rig), len(xy)))
    front = np.zeros((len(rig), len(xy)), bool)
    for v, cam in enumerate(rig):
        front[v] = (cam.depth_of(corners) > 0.1).all(-1)
        uv = cam.project(corners)
        ok = front[v] & np.isfinite(uv).all((-1, -2))
        uv = np.where(ok[:, None, None], uv, 0.0)
        lo, hi = uv.min(axis=1), uv.max(axis=1)
        w, hgt = cam.size
        x0, y0 = np.floor(lo[:, 0] + 0.5), np.floor(lo[:, 1] + 0.5)
        x1, y1 = np.floor(hi[:, 0] + 0.5) + 1, np.floor(hi[:, 1] + 0.5) + 1
        area = np.maximum(x1 - x0, 1) * np.maximum(y1 - y0, 1)
        cx0, cy0 = np.clip(x0, 0, w), np.clip(y0, 0, hgt)
        cx1, cy1 = np.clip(x1, 0, w), np.clip(y1, 0, hgt)
        inside[v] = np.where(ok, (cx1 - cx0) * (cy1 - cy0) / area, 0.0)
        boxes[v] = np.stack([cx0, cy0, cx1, cy1], 1).astype(int)
        front[v] &= ok
    return boxes, inside, front


def _ground_extent(rig: Rig, limit_m: float = 150.0) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (lo, hi) of the ground points the cameras' image corners and centres look at."""
    hits = []
    for cam in rig:
        w, h = cam.size
        px = np.array([[x, y] for x in np.linspace(0, w - 1, 5) for y in np.linspace(0, h - 1, 5)], float)
        p = _ground_points(cam, px)
        hits.append(p[np.isfinite(p).all(1)])
        hits.append(cam.center[None, :2])
    pts = np.clip(np.concatenate(hits), -limit_m, limit_m)
    return pts.min(0), pts.max(0)


def ground_grid(rig: Rig, config: PeopleSilhouettesConfig = PeopleSilhouettesConfig()) -> GroundGrid:
    """The ground cells seen by at least one camera (two where the rig has two or more), with their boxes.

    Parameters
    ----------
    rig : Rig
    config : PeopleSilhouettesConfig

    Returns
    -------
    GroundGrid
    """
    need = min(2, len(rig))

    def centre_seen(xy):
        p = np.concatenate([xy, np.full((len(xy), 1), config.height_m / 2)], 1)
        return sum((cam.depth_of(p) > 0.1) & cam.in_image(cam.project(p)) for cam in rig)

    lo, hi = _ground_extent(rig)
    step = max(0.5, float(np.max(hi - lo)) / 200)  # a coarse pass finds where the cameras overlap
    xs, ys = np.arange(lo[0], hi[0] + step, step), np.arange(lo[1], hi[1] + step, step)
    xy = np.stack(np.meshgrid(xs, ys, indexing="ij"), -1).reshape(-1, 2)
    both = xy[centre_seen(xy) >= need]
    if len(both):
        lo, hi = both.min(0) - step, both.max(0) + step
    cell = config.cell_m
    while np.prod(np.floor((hi - lo) / cell) + 1) > 2 * config.max_cells:
        cell *= 1.25
    while True:
        xs, ys = np.arange(lo[0], hi[0] + cell, cell), np.arange(lo[1], hi[1] + cell, cell)
        xy = np.stack(np.meshgrid(xs, ys, indexing="ij"), -1).reshape(-1, 2)
        xy = xy[centre_seen(xy) >= need]
        if len(xy) <= config.max_cells:
            break
        cell *= 1.25
    boxes, inside, front = _boxes(rig, xy, config.radius_m, config.height_m)
    seen = front & (inside >= 0.5)
    keep = seen.sum(0) >= need
    xy, boxes, seen = xy[keep], boxes[:, keep], seen[:, keep]
    return GroundGrid(xy=xy, boxes=boxes, seen=seen)


def _box_sums(integral: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Sums of a (H+1, W+1) integral image over boxes (N, 4)."""
    x0, y0, x1, y1 = boxes.T
    return integral[y1, x1] - integral[y0, x1] - integral[y1, x0] + integral[y0, x0]


def _area(boxes: np.ndarray) -> np.ndarray:
    return np.maximum((boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1]), 1)


def _contact(integral: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Per box (N, 4) of one camera: does a person standing there touch the ground in the image?

    The bottom band of the box (:data:`CONTACT_BAND` of its height) holds the feet: at least
    :data:`CONTACT_MIN_FEET` foreground; the band of the same height just below it is the ground in
    front of the feet: at most :data:`CONTACT_MAX_BELOW` (a box at the image's bottom edge passes).
    A box further along the ray than the person is smaller and ends above the feet (legs below it);
    a nearer one ends below them (no feet in its band).  The box's bottom edge is its near face's, a
    little below the feet of a person seen from above (a striding person's feet also fill little of
    a narrow box), hence the low :data:`CONTACT_MIN_FEET`.
    """
    x0, y0, x1, y1 = boxes.T
    height = integral.shape[0] - 1
    band = np.maximum(2, np.round((y1 - y0) * CONTACT_BAND)).astype(int)
    feet = np.stack([x0, np.maximum(y1 - band, y0), x1, y1], 1)
    below = np.stack([x0, y1, x1, np.minimum(y1 + band, height)], 1)
    f = _box_sums(integral, feet) / _area(feet)
    u = _box_sums(integral, below) / _area(below)
    return (f >= CONTACT_MIN_FEET) & (u <= CONTACT_MAX_BELOW)


def locate_people(masks, grid: GroundGrid, config: PeopleSilhouettesConfig = PeopleSilhouettesConfig()
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Where people stand in one frame (see the module docstring).

    Parameters
    ----------
    masks : sequence of (ndarray of shape (H, W), bool, or None)
        Foreground per camera of the grid's rig (None: no frame, the camera says nothing).
    grid : GroundGrid
    config : PeopleSilhouettesConfig

    Returns
    -------
    positions : ndarray of shape (P, 2)
        Metres on the ground, best first.
    scores : ndarray of shape (P,)
        Each one's score (share of its box that is its own foreground).
    """
    V, N = grid.seen.shape
    if len(masks) != V:
        raise InputError("masks", f"one mask (or None) per camera ({V})", f"{len(masks)}")
    fg = [None if m is None else np.asarray(m, bool) for m in masks]
    avail = np.array([m is not None for m in fg])
    seen = grid.seen & avail[:, None]
    areas = np.stack([_area(grid.boxes[v]) for v in range(V)])
    need = min(2, int(avail.sum()))
    possible = seen.sum(0) >= max(need, 1)
    integrals = [None if m is None else cv2.integral(m.astype(np.uint8)) for m in fg]
    total = np.zeros((V, N))
    contact = np.zeros((V, N), bool)
    for v in range(V):
        if fg[v] is not None:
            total[v] = _box_sums(integrals[v], grid.boxes[v])
            contact[v] = _contact(integrals[v], grid.boxes[v])
    hidden = np.zeros((V, N))  # box area covered by the boxes of people already chosen
    taken = np.zeros((V, N))   # the foreground in it
    chosen, scores, hidden_in = [], [], []
    while len(chosen) < config.max_people and possible.any():
        visible = np.maximum(areas - hidden, 1.0)
        clear = seen & (hidden / areas < config.occluded_share)
        free = np.where(clear, (total - taken) / visible, 0.0)
        good = clear & (free >= config.min_fill)
        bad = clear & ~good
        n_good = good.sum(0)
        score = (free * good).sum(0) - config.disagree_weight * ((config.min_fill - free) * bad).sum(0)
        lone = _hidden_but_one(good, bad, seen & ~clear, total / areas, contact, need, config)
        ok = (n_good >= max(need, 1)) | lone
        score = np.where(possible & ok & (score >= config.min_fill), score, -np.inf)
        best = int(np.argmax(score))
        if not np.isfinite(score[best]):
            break
        chosen.append(best)
        scores.append(float(score[best]))
        # a person taken on one camera is hidden in the others: it explains nothing there
        hidden_in.append(set(np.flatnonzero(seen[:, best] & ~clear[:, best])) if n_good[best] < need else set())
        possible &= np.linalg.norm(grid.xy - grid.xy[best], axis=1) >= config.min_separation_m
        for v in range(V):  # every other cell loses what the chosen person's box covers
            if fg[v] is None or not grid.seen[v, best]:
                continue
            b = grid.boxes[v]
            inter = np.stack([np.maximum(b[:, 0], b[best, 0]), np.maximum(b[:, 1], b[best, 1]),
                              np.minimum(b[:, 2], b[best, 2]), np.minimum(b[:, 3], b[best, 3])], 1)
            inter[:, 2:] = np.maximum(inter[:, 2:], inter[:, :2])
            hidden[v] += (inter[:, 2] - inter[:, 0]) * (inter[:, 3] - inter[:, 1])
            taken[v] += _box_sums(integrals[v], inter)
        hidden = np.minimum(hidden, areas)
        taken = np.minimum(taken, total)
    keep = _explaining(fg, grid, chosen, hidden_in, need, config)
    return grid.xy[np.array(chosen, int)[keep]].reshape(-1, 2), np.array(scores, float)[keep]


def _hidden_but_one(good: np.ndarray, bad: np.ndarray, occluded: np.ndarray, fill: np.ndarray,
                    contact: np.ndarray, need: int, config: PeopleSilhouettesConfig) -> np.ndarray:
    """Cells (N,) a person may stand on with one agreeing camera: in a rig that asks for two, exactly
    one camera agrees and shows the person standing there (``contact``), no clear camera disagrees,
    and every other camera that sees the cell is occluded by people already chosen with foreground
    over the box.  Inputs are (V, N): agreeing, clear but not agreeing, occluded, box fill, ground
    contact."""
    if need < 2:
        return np.zeros(good.shape[1], bool)
    consistent = occluded & (fill >= config.min_fill)
    return ((good.sum(0) == 1) & (good & contact).any(0) & ~bad.any(0) & consistent.any(0)
            & ~(occluded & ~consistent).any(0))


def _explaining(fg: list, grid: GroundGrid, cells: list, hidden_in: list, need: int,
                config: PeopleSilhouettesConfig) -> list:
    """Indices of the chosen cells that explain foreground of their own: weakest first, a person is
    dropped unless at least ``need`` cameras (one for a person taken on one camera) show
    ``config.min_own`` of its box as foreground that no other (remaining) person's box covers.  A
    ghost between real people has none of its own.  ``hidden_in[i]``: the cameras in which person
    ``i`` was taken on one camera as hidden; its box covers nothing there."""
    alive = list(range(len(cells)))
    for i in reversed(range(len(cells))):
        others = [(cells[j], hidden_in[j]) for j in alive if j != i]
        own_views = 0
        for v, m in enumerate(fg):
            if m is None or not grid.seen[v, cells[i]]:
                continue
            x0, y0, x1, y1 = grid.boxes[v, cells[i]]
            if x1 <= x0 or y1 <= y0:
                continue
            free = m[y0:y1, x0:x1].copy()
            for c, hid in others:
                if grid.seen[v, c] and v not in hid:
                    a0, b0, a1, b1 = grid.boxes[v, c]
                    free[max(b0 - y0, 0):max(b1 - y0, 0), max(a0 - x0, 0):max(a1 - x0, 0)] = False
            own_views += free.mean() >= config.min_own
        if own_views < (1 if hidden_in[i] else need):
            alive.remove(i)
    return alive


def track_positions(detections: list, config: PeopleSilhouettesConfig = PeopleSilhouettesConfig()
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Link per-frame positions into people and fill the frames they were missed.

    Parameters
    ----------
    detections : list of ndarray of shape (P_t, 2)
        Positions per frame (metres).
    config : PeopleSilhouettesConfig

    Returns
    -------
    positions : ndarray of shape (P, T, 2)
        Every participant (found in at least ``config.min_share`` of the frames), the one found
        most often first; frames before its first and after its last detection hold those, the
        frames between interpolated.
    found : ndarray of shape (P, T), bool
        The frames each participant was found in.
    """
    T = len(detections)
    tracks: list[dict] = []  # frame -> position
    active: list[int] = []
    for t, det in enumerate(detections):
        det = np.asarray(det, float).reshape(-1, 2)
        last = [tracks[k][max(tracks[k])] for k in active]
        gap = [t - max(tracks[k]) for k in active]
        matched = set()
        if active and len(det):
            cost = np.linalg.norm(np.array(last)[:, None] - det[None], axis=-1)
            reach = config.max_step_m * np.array(gap, float)[:, None]
            big = 1e6
            rows, cols = linear_sum_assignment(np.where(cost <= reach, cost, big))
            for r, c in zip(rows, cols):
                if cost[r, c] <= reach[r, 0]:
                    tracks[active[r]][t] = det[c]
                    matched.add(int(c))
        for c in range(len(det)):
            if c not in matched:
                tracks.append({t: det[c]})
                active.append(len(tracks) - 1)
        active = [k for k in active if t - max(tracks[k]) <= 5]  # a track missed 5 frames ends
    found = np.zeros((len(tracks), T), bool)
    for k, tr in enumerate(tracks):
        found[k, list(tr)] = True
    keep = [k for k in np.argsort(-found.sum(1), kind="stable") if found[k].sum() >= config.min_share * T]
    out = np.zeros((len(keep), T, 2))
    for i, k in enumerate(keep):
        ts = np.array(sorted(tracks[k]))
        xy = np.array([tracks[k][t] for t in ts])
        for d in range(2):
            out[i, :, d] = np.interp(np.arange(T), ts, xy[:, d])
    return out, found[keep].reshape(len(keep), T)


def split_masks(masks, rig: Rig, positions: np.ndarray,
                config: PeopleSilhouettesConfig = PeopleSilhouettesConfig()) -> list:
    """Each person's silhouette per camera, exclusive (see the module docstring).

    Parameters
    ----------
    masks : sequence of (ndarray of shape (H, W), bool, or None)
        Foreground per camera of ``rig``.
    rig : Rig
    positions : ndarray of shape (P, 2)
        The people's ground positions this frame, metres.
    config : PeopleSilhouettesConfig

    Returns
    -------
    masks : list of list of (ndarray of shape (H, W), bool, or None)
        Per person, per camera: its exclusive silhouette (None where the camera has no frame or the
        person is behind it).
    usable : list of list of bool
        Per person, per camera: the camera shows at least ``config.min_visible`` of the person's
        core box (its silhouette can go to stage 1).
    """
    P = len(positions)
    out = [[None] * len(rig) for _ in range(P)]
    usable = [[False] * len(rig) for _ in range(P)]
    if not P:
        return out, usable
    xy = np.asarray(positions, float).reshape(P, 2)
    core, _, front = _boxes(rig, xy, config.radius_m, config.height_m)
    wide, _, _ = _boxes(rig, xy, config.wide_radius_m, config.height_m)
    mid = np.concatenate([xy, np.full((P, 1), config.height_m / 2)], 1)
    for v, cam in enumerate(rig):
        m = masks[v]
        if m is None:
            continue
        m = np.asarray(m, bool)
        h, w = m.shape
        depth = np.linalg.norm(mid - cam.center, axis=1)
        order = np.argsort(depth)  # near to far
        owner = np.full((h, w), -1, np.int32)
        covered = np.zeros((h, w), bool)
        visible = np.zeros(P)
        for k in order:  # core boxes: the nearer person first
            x0, y0, x1, y1 = core[v, k]
            if not front[v, k] or x1 <= x0 or y1 <= y0:
                continue
            box_cov = covered[y0:y1, x0:x1]
            visible[k] = 1.0 - box_cov.mean()
            sub = owner[y0:y1, x0:x1]
            take = (sub < 0) & m[y0:y1, x0:x1]
            sub[take] = k
            covered[y0:y1, x0:x1] = True
        # the rest of the foreground inside wide boxes: the person whose image axis is nearest
        axis_top = cam.project(mid + [0, 0, config.height_m / 2])
        axis_bot = cam.project(mid - [0, 0, config.height_m / 2])
        ys, xs = np.nonzero(m & (owner < 0))
        if len(xs):
            best = np.full(len(xs), np.inf)
            who = np.full(len(xs), -1)
            p = np.stack([xs, ys], 1).astype(float)
            for k in range(P):
                x0, y0, x1, y1 = wide[v, k]
                if not front[v, k]:
                    continue
                inside = (xs >= x0) & (xs < x1) & (ys >= y0) & (ys < y1)
                a, b = axis_bot[k], axis_top[k]
                ab = b - a
                s = np.clip(((p - a) @ ab) / max(ab @ ab, 1e-9), 0, 1)
                d = np.linalg.norm(p - (a + s[:, None] * ab), axis=1)
                closer = inside & (d < best)
                best[closer], who[closer] = d[closer], k
            owner[ys, xs] = who
        for k in range(P):
            if not front[v, k]:
                continue
            mk = owner == k
            # keep the parts connected to the person's core box
            n, lab = cv2.connectedComponents(mk.astype(np.uint8), connectivity=8)
            if n > 2:
                x0, y0, x1, y1 = core[v, k]
                ids = np.unique(lab[y0:y1, x0:x1])
                mk = np.isin(lab, ids[ids > 0])
            out[k][v] = mk
            usable[k][v] = bool(visible[k] >= config.min_visible)
    return out, usable


def refine_positions(masks, rig: Rig, positions: np.ndarray,
                     config: PeopleSilhouettesConfig = PeopleSilhouettesConfig()) -> np.ndarray:
    """Each person's ground position from the middle of its own silhouette in every camera.

    A camera where the person is usable (:func:`split_masks`) gives the vertical plane through its
    centre and the median column of the person's silhouette; the planes meet the ground in lines, and
    the point nearest to all of them (least squares) is the person's position.  The grid's cells
    are coarse and a box is not a body: this is what puts the silhouettes' own middle under the
    person.  The silhouettes are split again at the new positions and the step repeated (at most
    :data:`REFINE_ROUNDS` times, until no one moves :data:`REFINE_STOP_M`).  A person seen usable by
    fewer than two cameras whose planes cross, or that would move further than
    ``config.wide_radius_m`` from the position given, keeps its position.

    Parameters
    ----------
    masks : sequence of (ndarray of shape (H, W), bool, or None)
    rig : Rig
    positions : ndarray of shape (P, 2)
        Metres on the ground.
    config : PeopleSilhouettesConfig

    Returns
    -------
    ndarray of shape (P, 2)
    """
    start = np.asarray(positions, float).reshape(-1, 2)
    out = start.copy()
    for _ in range(REFINE_ROUNDS):
        new = _refine_once(masks, rig, out, start, config)
        moved = np.linalg.norm(new - out, axis=1).max(initial=0.0)
        out = new
        if moved < REFINE_STOP_M:
            break
    return out


def _refine_once(masks, rig: Rig, positions: np.ndarray, start: np.ndarray, config) -> np.ndarray:
    """One round of :func:`refine_positions` (the silhouettes split at ``positions``)."""
    own, usable = split_masks(masks, rig, positions, config)
    out = positions.copy()
    for k in range(len(positions)):
        rows, rhs, feet = [], [], None
        for v, cam in enumerate(rig):
            m = own[k][v]
            if m is None or not usable[k][v]:
                continue
            ys, xs = np.nonzero(m)
            if len(xs) < 20:
                continue
            u, vmid = float(np.median(xs)), float(np.median(ys))
            feet = (cam, u, float(np.percentile(ys, FEET_PERCENTILE)))  # the last usable camera's feet
            _, d = cam.rays(np.array([[u, vmid], [u, vmid + 10.0]]))
            n = np.cross(d[0], d[1])
            if np.linalg.norm(n[:2]) < 1e-9:
                continue
            n = n / np.linalg.norm(n[:2])
            rows.append(n[:2])
            rhs.append(n @ cam.center)
        if len(rows) == 1 and feet is not None:  # one camera: the ground under its feet
            cam, u, v = feet
            p = _ground_points(cam, np.array([[u, v]]))[0]
            if np.isfinite(p).all() and np.linalg.norm(p - start[k]) <= config.wide_radius_m:
                out[k] = p
            continue
        if len(rows) < 2:
            continue
        A, b = np.array(rows), np.array(rhs)
        if np.linalg.cond(A) > 1e3:  # parallel planes: no crossing
            continue
        p = np.linalg.lstsq(A, b, rcond=None)[0]
        if np.linalg.norm(p - start[k]) <= config.wide_radius_m:
            out[k] = p
    return out


def _ground_points(cam, px: np.ndarray) -> np.ndarray:
    """Where the rays of pixels (N, 2) meet the ground z = 0: (N, 2) metres, NaN for a ray that does not
    go down to it."""
    o, d = cam.rays(np.asarray(px, float))
    down = d[:, 2] < -1e-6
    s = np.where(down, -o[:, 2] / np.where(down, d[:, 2], -1.0), np.nan)
    return (o + s[:, None] * d)[:, :2]


def ground_velocities(positions: np.ndarray, fps: float) -> np.ndarray:
    """Velocities (P, T, 2) m/s of tracked positions (P, T, 2) metres (central differences; 0 for one frame)."""
    positions = np.asarray(positions, float)
    if positions.shape[1] < 2:
        return np.zeros_like(positions)
    return np.gradient(positions, axis=1) * float(fps)


def faces_backwards(joints3d: np.ndarray, velocity, left_hip: int, right_hip: int) -> bool:
    """Whether a person moving at ``velocity`` (2,) m/s on the ground has its hips facing the other way.

    Parameters
    ----------
    joints3d : ndarray of shape (J, 3)
        Metres, z up.
    velocity : array-like of shape (2,)
    left_hip, right_hip : int
        Indices of the hips in ``joints3d``.

    Returns
    -------
    bool
        False when the person moves slower than :data:`MIRROR_MIN_SPEED_M_S` or its hips are unknown.
    """
    v = np.asarray(velocity, float)
    speed = float(np.linalg.norm(v))
    J = np.asarray(joints3d, float)
    across = J[left_hip, :2] - J[right_hip, :2]
    if speed < MIRROR_MIN_SPEED_M_S or not np.isfinite(across).all() or np.linalg.norm(across) < 1e-6:
        return False
    facing = np.array([across[1], -across[0]]) / np.linalg.norm(across)  # (L - R) x up, on the ground
    return bool(facing @ v / speed < MIRROR_MAX_COSINE)
