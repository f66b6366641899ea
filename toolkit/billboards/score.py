"""The position score of a joint (source 000 §3.1, eqs. 2-6, claims 12-13).

For an evaluated view ``V`` and a pair of source cameras ``(I1, I2)``, each
bone's billboards of ``I1`` and ``I2`` are projectively textured into ``V``.
A pixel is *active* for a camera when its warped part alpha is at least
``ScoreConfig.active_alpha``.  Per pixel (eq. 2)::

    s(p) = 1 - ε(V_I1(p), V_I2(p))   if p is active for both, else 0

with ε the Euclidean RGB distance divided by 255·√3 (so ε ∈ [0, 1]; see
:class:`~toolkit.billboards.config.ScoreConfig`).  The pair score in ``V`` is
the sum of ``s(p)`` divided by the number of pixels active for at least one
camera (eq. 3), so misaligned billboards are penalised.  Pairs are averaged
with weights ω(β) = exp(-β²/2σ²), σ = 0.32 rad, β the angle between the two
cameras' viewing directions (their optical axes, which broadcast cameras aim at
the subject) (eqs. 4-5), and views are
averaged (eq. 6).  The evaluated views are every input camera plus a virtual
camera midway between each camera pair (§3.2).  The score of a joint is the sum
of these bone scores over the bones adjacent to it
(``SKELETON_14.parts_of_joint``), so it lies in ``[0, n_adjacent]``.

Fast path: the part segments of the source images are cut once into small RGBA
patches (colour + membership alpha, seam pixels included); one evaluation warps
each patch straight into each view with the plane-induced homography
``view_from_source`` of its billboard plane (the composition of texturing the
billboard from the source and drawing it into the view), restricted to the
billboard's footprint.  Only the bones adjacent to the moving joint are redone.
Calibration offsets are in the cameras: the rig holds the source cameras
corrected by stage 1's offsets (:func:`toolkit.multiview.corrected_rig`), so a
source pixel is the camera's projection; virtual views lie midway between two
corrected cameras.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import cv2
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from toolkit.billboards.build import check_inputs, memberships, segment_outline
from toolkit.billboards.config import RGB_DIAGONAL, BillboardConfig, ScoreConfig
from toolkit.billboards.geometry import billboard_frame
from toolkit.billboards.seams import SeamMap
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14, Skeleton


@dataclass(frozen=True, eq=False)
class View:
    """An evaluated view: a camera and whether it is virtual."""

    camera: Camera
    virtual: bool


def midway_camera(a: Camera, b: Camera, name: str | None = None) -> Camera:
    """A virtual pinhole camera midway between two cameras, looking at what both look at.

    The target is the point closest to both optical axes (broadcast cameras
    aim at the subject).  The centre lies on the arc between the two
    cameras around the target: the target plus the mean of both cameras'
    distances along the bisector of the two directions to them, so the
    subject keeps about the same image size.  The orientation is the rotation
    halfway between both (spherical interpolation), turned by the smallest
    rotation that points its optical axis at the target; intrinsics are the
    mean of both (no distortion), the size that of ``a``.  (The chord midpoint
    of two cameras 90-100° apart is much closer to the subject and, with the
    interpolated orientation alone, does not see it.)
    """
    from toolkit.cameras import closest_point_to_rays

    rots = Rotation.from_matrix(np.stack([a.R, b.R]))
    R = Slerp([0.0, 1.0], rots)([0.5]).as_matrix()[0]
    x = closest_point_to_rays(np.stack([a.center, b.center]), np.stack([a.forward, b.forward]))[0]
    da, db = a.center - x, b.center - x
    ra, rb = np.linalg.norm(da), np.linalg.norm(db)
    u = da / max(ra, 1e-12) + db / max(rb, 1e-12)
    if not np.all(np.isfinite(x)) or np.linalg.norm(u) < 1e-6:  # parallel axes or opposite cameras
        c = 0.5 * (a.center + b.center)
    else:
        c = x + 0.5 * (ra + rb) * u / np.linalg.norm(u)
        f = R[2]  # optical axis of the interpolated rotation (world)
        want = (x - c) / np.linalg.norm(x - c)
        axis = np.cross(f, want)
        ang = np.arctan2(np.linalg.norm(axis), float(f @ want))
        if np.linalg.norm(axis) > 1e-12:
            turn = Rotation.from_rotvec(axis / np.linalg.norm(axis) * ang).as_matrix()
            R = R @ turn.T  # camera axes (rows of R) rotated by ``turn`` in the world
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ c
    K = 0.5 * (a.K + b.K)
    return Camera(name or f"mid_{a.name}_{b.name}", K, np.zeros(5), a.size, T)


def evaluated_views(rig: Rig, virtual: bool = True) -> list[View]:
    """Every input camera and, if ``virtual``, a camera midway between each pair."""
    views = [View(c, False) for c in rig]
    if virtual:
        for i in range(len(rig)):
            for k in range(i + 1, len(rig)):
                views.append(View(midway_camera(rig[i], rig[k]), True))
    return views


def pair_weight(beta, sigma: float) -> np.ndarray:
    """ω(β) = exp(-β² / 2σ²) (source 000 eq. 5)."""
    b = np.asarray(beta, float)
    return np.exp(-b ** 2 / (2.0 * sigma ** 2))


@dataclass(frozen=True, eq=False)
class _Source:
    patch: np.ndarray      # (h, w, 4) uint8: RGB + 255 where the pixel belongs to the part
    occluder: np.ndarray   # (h, w) uint8: 1 where another part of the subject covers the pixel
    origin: np.ndarray     # (2,) image pixel of patch[0, 0]
    occ_origin: np.ndarray  # (2,) image pixel of occluder[0, 0]
    rays: np.ndarray       # (K, 3) unit world directions of the segment outline
    n_pixels: int
    has_occluder: bool
    hidden: np.ndarray     # (h, w) uint8: ``occluder`` times 2 (bit 1 of the batched scorer's pixel code)


@dataclass(frozen=True)
class PartScore:
    """Score of one bone.

    Attributes
    ----------
    value : float
        In [0, 1]; NaN when no camera pair sees the bone in any view.
    per_view : ndarray of shape (n_views,)
        The pair-weighted score per evaluated view (eqs. 3-5), NaN where undefined.
    n_billboards : ndarray of shape (n_views,), int
        Billboards drawn per view.
    per_pair : ndarray of shape (n_views, n_cams, n_cams) or None
        Eq. 3 per view and camera pair ``(i, k)``, ``i < k`` (unweighted: Σ s(p) / #active
        pixels), 0 for a pair the visibility set counts but whose billboards this pose
        made degenerate, NaN for pairs not evaluated in that view (upper triangle only).
        ``per_view`` is the ω(β)-weighted mean of these.  The joint search uses
        them to check that independent camera pairs agree on a move.
    """

    value: float
    per_view: np.ndarray
    n_billboards: np.ndarray
    per_pair: np.ndarray | None = None


@dataclass(frozen=True)
class MoveEvidence:
    """A joint move split into what each view and each camera pair says (:meth:`PositionScorer.move_evidence`).

    Attributes
    ----------
    view_gain : ndarray of shape (n_views,)
        Rise of the view's score summed over the joint's adjacent bones; NaN for
        views that score none of them.
    pair_gain : ndarray of shape (n_cams, n_cams)
        Rise of the unweighted pair score (eq. 3), averaged over the views that
        evaluate the pair and summed over the adjacent bones; upper triangle
        ``(i, k)``, ``i < k``; NaN for pairs that score none of them.
    """

    view_gain: np.ndarray
    pair_gain: np.ndarray

    @property
    def n_views(self) -> int:
        """Views that score at least one of the joint's bones."""
        return int(np.isfinite(self.view_gain).sum())

    @property
    def n_pairs(self) -> int:
        """Camera pairs that score at least one of the joint's bones."""
        return int(np.isfinite(self.pair_gain).sum())


def _dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products (N,) of (N, 3) arrays, summed left to right (as BLAS ``ddot`` sums three terms)."""
    return (a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]) + a[..., 2] * b[..., 2]


def _norm3(a: np.ndarray) -> np.ndarray:
    """Row-wise Euclidean norms (N,) of (N, 3) arrays: ``np.linalg.norm`` of each row, bit for bit."""
    return np.sqrt(_dot3(a, a))


#: The float32 sum of ``ndarray.sum`` (the same reduction, without the method's Python wrapper).
_add_reduce = np.add.reduce


def _pair_counts() -> np.ndarray:
    """Which pixel codes of a camera pair count for eq. 3 with occlusion, (16, 3) int64.

    A pair's pixel code has bit 0 set where camera 1's warped part is active, bit 1 where
    another part hides the pixel in camera 1, bits 2 and 3 the same for camera 2.  The
    columns: active in both; active in camera 1 and not hidden in camera 2 (or active there
    too); the same for camera 2.  (Part_score's masks: both = a1 & a2 since an active
    pixel is never occluded in its own camera; a1 & ~(occluded 1 | occluded 2) = a1 & ~occluded 2.)
    """
    c = np.arange(16)
    a1, h1, a2, h2 = (c & 1) > 0, (c & 2) > 0, (c & 4) > 0, (c & 8) > 0
    return np.stack([a1 & a2, a1 & (~h2 | a2), a2 & (~h1 | a1)], axis=1).astype(np.int64)


_PAIR_COUNTS = _pair_counts()


class PositionScorer:
    """Evaluate the position score of joints for one frame.

    Parameters
    ----------
    images : dict of str to ndarray of shape (H, W, 3), uint8
        Source images per camera.
    labels : dict of str to ndarray of shape (H, W), uint8
        Part ids per camera (1-based, 0 background).
    rig : Rig
        Source cameras, corrected by stage 1's offsets
        (:func:`toolkit.multiview.corrected_rig`); the virtual views lie midway
        between them.
    seams : dict of str to SeamMap, optional
        Seam pixels: they count for both adjacent parts.
    config : ScoreConfig
    billboard_config : BillboardConfig
        Edge-on threshold and billboard sizing.
    skeleton : Skeleton
    """

    def __init__(self, images: Mapping[str, np.ndarray], labels: Mapping[str, np.ndarray], rig: Rig,
                 seams: Mapping[str, SeamMap] | None = None,
                 config: ScoreConfig = ScoreConfig(), billboard_config: BillboardConfig = BillboardConfig(),
                 skeleton: Skeleton = SKELETON_14):
        check_inputs(images, labels, rig)
        self.rig = rig
        self.config = config
        self.bconfig = billboard_config
        self.skeleton = skeleton
        self.views = evaluated_views(rig, config.virtual_views)
        self._W = skeleton.part_weights  # (P, 2, J)
        self._sin_edge = float(np.sin(np.radians(billboard_config.edge_on_deg)))
        self._sin_graze = float(np.sin(np.radians(config.grazing_deg)))
        self._thr = int(np.ceil(config.active_alpha * 255))
        self._border = int(config.occlusion_border_px)
        members = memberships(labels, seams, rig.names)
        self.sources: list[dict[int, _Source]] = []
        for ci, cam in enumerate(rig):
            per = {}
            img = np.asarray(images[cam.name])
            M = members[cam.name]
            rows, cols = np.flatnonzero(M.any(axis=1)), np.flatnonzero(M.any(axis=0))
            # the parts' pixels are looked for in the box of the labelled pixels only
            r0, c0 = (int(rows[0]), int(cols[0])) if rows.size else (0, 0)
            Mc = M[r0:int(rows[-1]) + 1, c0:int(cols[-1]) + 1] if rows.size else M[:0, :0]
            for p in range(skeleton.n_parts):
                bit = np.uint16(1 << (p + 1))
                m = (Mc & bit) != 0
                n = int(np.count_nonzero(m))
                if n < billboard_config.min_pixels:
                    continue
                ys, xs = np.nonzero(m)
                x0, x1, y0, y1 = xs.min() + c0, xs.max() + 1 + c0, ys.min() + r0, ys.max() + 1 + r0
                mm = m[y0 - r0:y1 - r0, x0 - c0:x1 - c0]
                patch = np.zeros((y1 - y0, x1 - x0, 4), np.uint8)
                patch[..., :3] = img[y0:y1, x0:x1]
                patch[..., 3] = np.where(mm, 255, 0)
                outline = segment_outline(mm) + [x0, y0]
                _, d = cam.rays(outline)
                # occluders may lie outside the part's bounding box: keep a border around it
                bx0, by0 = max(x0 - self._border, 0), max(y0 - self._border, 0)
                bx1, by1 = min(x1 + self._border, cam.width), min(y1 + self._border, cam.height)
                region = M[by0:by1, bx0:bx1]
                occ = ((region != 0) & ((region & bit) == 0)).astype(np.uint8)
                per[p] = _Source(patch, occ, np.array([x0, y0], float), np.array([bx0, by0], float), d, n,
                                 bool(occ.any()), occ * np.uint8(2))
            self.sources.append(per)
        # constant per (view, source camera): relative pose and intrinsics
        self._rel = []
        for v in self.views:
            row = []
            for cam in rig:
                T = v.camera.cam_from_world @ cam.world_from_cam
                row.append((T[:3, :3].copy(), T[:3, 3].copy()))
            self._rel.append(row)
        self._Kinv = [np.linalg.inv(c.K) for c in rig]
        # view_from_source = K_V (R + t n_s^T / d_s) K_s^-1 = M + (K_V t) (n_s^T K_s^-1 / d_s)
        self._M = [[v.camera.K @ R @ self._Kinv[ci] for ci, (R, _) in enumerate(row)]
                   for v, row in zip(self.views, self._rel)]
        self._kt = [[v.camera.K @ t for _, t in row] for v, row in zip(self.views, self._rel)]
        self._centers = rig.centers
        self._view_centers = np.array([v.camera.center for v in self.views])
        self._adjacent = [skeleton.parts_of_joint(j) for j in range(skeleton.n_joints)]
        # ω(β) per camera pair; β between the optical axes (broadcast cameras aim at the subject,
        # so this is the angle between their viewing directions of the subject)
        fw = np.array([c.forward for c in rig])
        self._pair_w = pair_weight(np.arccos(np.clip(fw @ fw.T, -1.0, 1.0)), config.sigma)
        self._Ms = np.array(self._M)  # (n_views, n_cams, 3, 3)
        self._kts = np.array(self._kt)  # (n_views, n_cams, 3)
        self._views_R = np.array([v.camera.R for v in self.views])  # (n_views, 3, 3)
        self._views_t = np.array([v.camera.t for v in self.views])
        self._views_K22 = np.array([v.camera.K[:2, :2] for v in self.views])
        self._views_Kc = np.array([v.camera.K[:2, 2] for v in self.views])
        # squared RGB distance -> min(ε, 1), looked up (the same float32 operations as the per-pixel formula,
        # so the same values)
        self._eps = np.minimum(np.sqrt(np.arange(3 * 255 ** 2 + 1, dtype=np.int32).astype(np.float32))
                               * (config.eps_gain / RGB_DIAGONAL), 1.0)
        #: Part scores computed so far, by (part, ends, visibility): a position is scored once per frame.
        self._memo: dict = {}
        self._vis_memo: dict = {}
        #: Joint-score evaluations so far (one per candidate position of a joint).
        self.n_evaluations = 0

    # ------------------------------------------------------------------ geometry
    def _billboard(self, ci: int, p: int, ends: np.ndarray):
        """Frame and footprint points (K, 3) on the plane of part p for camera ci, or None."""
        src = self.sources[ci].get(p)
        if src is None:
            return None
        fr = billboard_frame(ends[0], ends[1], self._centers[ci], self.bconfig.edge_on_deg)
        if fr is None:
            return None
        c = self._centers[ci]
        den = src.rays @ fr.normal
        num = (fr.origin - c) @ fr.normal
        ok = den < -1e-9  # rays going towards the plane (the camera is on the normal side)
        if not ok.any():
            return None
        t = num / den[ok]
        pts = c + t[:, None] * src.rays[ok] - fr.origin
        a = pts @ fr.e_u
        s = pts @ fr.e_v
        mx = self.bconfig.max_extent_m
        a0, a1 = max(a.min(), -mx), min(a.max(), mx)
        s0, s1 = max(s.min(), -mx), min(s.max(), fr.length + mx)
        if a1 <= a0 or s1 <= s0:
            return None
        # the segment's outline on the plane (clamped like the billboard): a tighter footprint
        # than the billboard's rectangle when the plane is oblique to the view
        outline = np.stack([np.clip(a, a0, a1), np.clip(s, s0, s1)], axis=1)
        return fr, fr.origin + outline @ np.stack([fr.e_u, fr.e_v])

    # ------------------------------------------------------------------- scores
    def visibility(self, joints: np.ndarray, part: int) -> np.ndarray:
        """Which billboards of a bone take part in which evaluated view, (n_views, n_cams) bool.

        A billboard is left out of a view that sees it within ``grazing_deg`` of
        edge-on, or that has part of it behind the camera.  The joint search
        fixes this set from the current pose, so that the scores of all
        candidates average the same views and pairs.
        """
        J = np.asarray(joints, float)
        ends = self._W[part] @ J
        key = (part, ends.tobytes())
        if key not in self._vis_memo:
            self._vis_memo[key] = self._visibility(part, ends)
        return self._vis_memo[key].copy()

    def _visibility(self, part: int, ends: np.ndarray) -> np.ndarray:
        """:meth:`visibility` of the bone with ends (2, 3)."""
        mid = ends.mean(axis=0)
        vis = np.zeros((len(self.views), len(self.rig)), bool)
        for ci in range(len(self.rig)):
            r = self._billboard(ci, part, ends)
            if r is None:
                continue
            fr, quad = r
            for vi, view in enumerate(self.views):
                to_v = self._view_centers[vi] - mid
                to_v /= np.linalg.norm(to_v)
                qz = quad @ view.camera.R[2] + view.camera.t[2]
                vis[vi, ci] = abs(float(fr.normal @ to_v)) >= self._sin_graze and bool(np.all(qz > 1e-6))
        return vis

    def part_score(self, joints: np.ndarray, part: int, visibility: np.ndarray | None = None) -> PartScore:
        """Score of one bone (0-based part index) for a pose (14, 3).

        ``visibility`` (n_views, n_cams) bool fixes which billboards are used in
        which view (default: :meth:`visibility` of this pose).  A billboard in
        that set that this pose turns edge-on (to its source camera or to the
        view) or pushes behind the view contributes nothing: its pairs score 0
        in that view, so degenerate fans are penalised, not skipped.
        """
        J = np.asarray(joints, float)
        ends = self._W[part] @ J
        return self.part_scores(part, ends[None], visibility if visibility is not None
                                else self.visibility(J, part))[0]

    def part_scores(self, part: int, ends: np.ndarray, visibility: np.ndarray) -> list[PartScore]:
        """Scores of one bone at several positions of its ends, all on the same views and billboards.

        The batched form of :meth:`part_score` (same values, bit for bit): the
        geometry of all positions is computed at once, each billboard is warped
        into its (view, position) region of one buffer per camera, and the pixel
        counts and colour distances of every view and position come from a few
        array operations per camera pair over those buffers.  A position scored
        before (same ends, same visibility) is not recomputed.

        Parameters
        ----------
        part : int
            0-based part index.
        ends : ndarray of shape (N, 2, 3)
            Proximal and distal end of the bone per position, metres.
        visibility : ndarray of shape (n_views, n_cams), bool

        Returns
        -------
        list of PartScore
            One per position.
        """
        E = np.asarray(ends, float).reshape(-1, 2, 3)
        vis = np.asarray(visibility, bool)
        vkey = vis.tobytes()
        keys = [(part, e.tobytes(), vkey) for e in E]
        todo = [i for i, k in enumerate(keys) if k not in self._memo]
        if todo:
            # a repeated position inside the batch is computed once
            first = {}
            for i in todo:
                first.setdefault(keys[i], i)
            idx = list(first.values())
            for i, ps in zip(idx, self._score_batch(part, E[idx], vis)):
                self._memo[keys[i]] = ps
        return [self._memo[k] for k in keys]

    # ------------------------------------------------------------ batched scoring
    def _footprints(self, ci: int, part: int, E: np.ndarray) -> dict | None:
        """The billboards of part ``part`` from camera ``ci`` at N bone positions (vectorised :meth:`_billboard`).

        Returns None when the camera has no segment of the part, else a dict of
        ``ok`` (N,) bool (a billboard exists), ``normal`` (N, 3), ``front`` (n_views, N) bool
        (no footprint point behind the view), ``lo``, ``hi`` (n_views, N, 2) the bounding box of
        the footprint's projection into each view, pixels, and ``row`` (N, 3) the plane's
        ``n_s^T K_s^-1 / d_s`` in the camera (NaN where not ``ok``), with which
        ``view_from_source = M + (K_V t) row``.
        The frame arithmetic is :func:`billboard_frame`'s, element by element (its norms and
        dot products of 3-vectors are left-to-right sums, as BLAS ``ddot`` does them).
        """
        src = self.sources[ci].get(part)
        if src is None:
            return None
        c = self._centers[ci]
        x, y = E[:, 0], E[:, 1]
        with np.errstate(all="ignore"):
            b = y - x
            L = _norm3(b)
            ok = np.isfinite(L) & ~(L < 1e-6)
            b = b / L[:, None]
            d = c - x
            dn = _norm3(d)
            ok &= ~(dn < 1e-9)
            d_perp = d - _dot3(d, b)[:, None] * b
            npp = _norm3(d_perp)
            ok &= ~(npp / dn < self._sin_edge)
            n = d_perp / npp[:, None]
            e_u = np.stack([n[:, 1] * b[:, 2] - n[:, 2] * b[:, 1], n[:, 2] * b[:, 0] - n[:, 0] * b[:, 2],
                            n[:, 0] * b[:, 1] - n[:, 1] * b[:, 0]], axis=1)
            # the outline's rays onto the plane (the footprint; it only bounds the warp region)
            r = src.rays
            den = n @ r.T  # (N, K)
            num = _dot3(x - c, n)
            hit = den < -1e-9
            ok &= hit.any(axis=1)
            t = num[:, None] / den
            pts = c + t[..., None] * r - x[:, None]  # (N, K, 3)
            a = np.einsum("nkd,nd->nk", pts, e_u)
            s = np.einsum("nkd,nd->nk", pts, b)
            mx = self.bconfig.max_extent_m
            a0 = np.maximum(np.where(hit, a, np.inf).min(axis=1), -mx)
            a1 = np.minimum(np.where(hit, a, -np.inf).max(axis=1), mx)
            s0 = np.maximum(np.where(hit, s, np.inf).min(axis=1), -mx)
            s1 = np.minimum(np.where(hit, s, -np.inf).max(axis=1), L + mx)
            ok &= ~((a1 <= a0) | (s1 <= s0))
            ac = np.clip(a, a0[:, None], a1[:, None])
            sc = np.clip(s, s0[:, None], s1[:, None])
            quad = x[:, None] + ac[..., None] * e_u[:, None] + sc[..., None] * b[:, None]
            # into every view at once: in front of it, and the bounding box of the projection
            qc = np.einsum("nkd,ved->vnke", quad, self._views_R) + self._views_t[:, None, None, :]
            hit &= ok[:, None]
            front = ~np.any(hit[None] & (qc[..., 2] <= 1e-6), axis=2)  # (n_views, N)
            px = np.einsum("vnkc,vdc->vnkd", qc[..., :2] / qc[..., 2:3], self._views_K22) \
                + self._views_Kc[:, None, None, :]
            m = hit[None, :, :, None]
            lo = np.where(m, px, np.inf).min(axis=2)  # (n_views, N, 2)
            hi = np.where(m, px, -np.inf).max(axis=2)
            # the plane rows feed the warps: n_s = R n, d_s = n_s . (R x + t), row = n_s^T K^-1 / d_s, with
            # the matrix products stacked (numpy calls the same BLAS product per item as one at a time)
            cam = self.rig.cameras[ci]
            R = cam.R
            n_s = (R @ n[:, :, None])[:, :, 0]
            d_s = _dot3(n_s, (R @ x[:, :, None])[:, :, 0] + cam.t)
            row = (n_s[:, None, :] @ self._Kinv[ci])[:, 0] / d_s[:, None]
        return {"ok": ok, "normal": n, "front": front, "lo": lo, "hi": hi, "row": row}

    def _score_batch(self, part: int, E: np.ndarray, vis: np.ndarray) -> list[PartScore]:
        """:meth:`part_scores` without the memo: N positions (N, 2, 3) of one bone."""
        N = len(E)
        nv, nc = len(self.views), len(self.rig)
        per_view = np.full((N, nv), np.nan)
        per_pair = np.full((N, nv, nc, nc), np.nan)
        counts = np.zeros((N, nv), int)
        used = [ci for ci in range(nc) if vis[:, ci].any()]
        if len(used) >= 2:
            mid = (E[:, 0] + E[:, 1]) / 2.0
            bbs = {ci: f for ci in used if (f := self._footprints(ci, part, E)) is not None}
            segs, dens = [], {}
            for vi in range(nv):
                cams = [ci for ci in used if vis[vi, ci]]
                if len(cams) >= 2:
                    dens[vi] = self._view_regions(vi, cams, bbs, mid, per_pair, counts, segs)
            num = np.zeros((N, nv))
            if segs:
                self._score_segments(part, used, bbs, vis, segs, per_pair, num)
            for vi, den in dens.items():
                if den > 0:
                    per_view[:, vi] = num[:, vi] / den
        out = []
        for n in range(N):
            pv = per_view[n]
            ok = np.isfinite(pv)
            out.append(PartScore(float(pv[ok].mean()) if ok.any() else float("nan"), pv, counts[n], per_pair[n]))
        return out

    def _view_regions(self, vi: int, cams: list, bbs: dict, mid: np.ndarray, per_pair, counts, segs: list) -> float:
        """The billboards of ``cams`` drawn into view ``vi`` per position, and the region each position's warps cover.

        Appends ``(vi, positions, x0, y0, width, height, {camera: drawn})`` to ``segs`` for the
        positions with a non-empty region, counts the drawn billboards, sets the view's counted
        pairs to 0 (their value until scored) and returns the sum of their weights ω (eq. 4's
        denominator).
        """
        N = len(mid)
        vc = self.views[vi].camera
        with np.errstate(all="ignore"):
            to_v = self._view_centers[vi] - mid
            to_v = to_v / _norm3(to_v)[:, None]
        alive, lo, hi = {}, np.full((N, 2), np.inf), np.full((N, 2), -np.inf)
        for ci in cams:
            f = bbs.get(ci)
            if f is None:
                continue
            with np.errstate(all="ignore"):
                ok = f["ok"] & ~(np.abs(_dot3(f["normal"], to_v)) < self._sin_graze) & f["front"][vi]
            m = ok[:, None]
            lo = np.minimum(lo, np.where(m, f["lo"][vi], np.inf))
            hi = np.maximum(hi, np.where(m, f["hi"][vi], -np.inf))
            alive[ci] = ok
        w, h = vc.size
        with np.errstate(invalid="ignore"):
            x0 = np.maximum(np.floor(lo[:, 0]), 0)
            y0 = np.maximum(np.floor(lo[:, 1]), 0)
            x1 = np.minimum(np.ceil(hi[:, 0]) + 1, w)
            y1 = np.minimum(np.ceil(hi[:, 1]) + 1, h)
        has = (x1 > x0) & (y1 > y0)
        if alive:
            has &= np.logical_or.reduce(list(alive.values()))
        else:
            has[:] = False
        den = 0.0
        for i in range(len(cams)):
            for k in range(i + 1, len(cams)):
                den += self._pair_w[cams[i], cams[k]]
                per_pair[:, vi, cams[i], cams[k]] = 0.0
        sel = np.flatnonzero(has)
        if sel.size:
            drawn = {ci: a[sel] for ci, a in alive.items()}
            for ci, d in drawn.items():
                counts[sel, vi] += d
            X0, Y0 = x0[sel].astype(int), y0[sel].astype(int)
            segs.append((vi, sel, X0, Y0, x1[sel].astype(int) - X0, y1[sel].astype(int) - Y0, drawn))
        return den

    def _score_segments(self, part: int, used: list, bbs: dict, vis, segs: list, per_pair, num) -> None:
        """Warp every (view, position) region of ``segs`` into one buffer per camera and score the pairs there.

        Adds ``ω(β) * pair value`` to ``num`` (N, n_views) pair by pair in part_score's order
        (pairs ``i < k``), so the sums are the same.
        """
        sv = np.concatenate([np.full(len(s[1]), s[0]) for s in segs])
        sn = np.concatenate([s[1] for s in segs])
        X0, Y0, ww, hh = (np.concatenate([s[i] for s in segs]) for i in (2, 3, 4, 5))
        nseg = len(sv)
        sizes = ww * hh
        offs = np.concatenate([[0], np.cumsum(sizes)])
        total = int(offs[-1])
        drawn = {ci: np.concatenate([s[6].get(ci, np.zeros(len(s[1]), bool)) for s in segs]) for ci in used}
        rgba, code = {}, {}
        for ci in used:
            if ci in bbs and drawn[ci].any():
                rgba[ci], code[ci] = self._warp_segments(part, ci, bbs[ci]["row"], sv, sn, drawn[ci], X0, Y0, ww, hh,
                                                         offs, total)
        seg16 = np.repeat(np.arange(0, 16 * nseg, 16), sizes)
        for i in range(len(used)):
            for k in range(i + 1, len(used)):
                c1, c2 = used[i], used[k]
                if c1 not in code or c2 not in code:
                    continue  # a camera without a billboard here: the pair scores 0 where counted
                pc = code[c1] | (code[c2] << np.uint8(2))
                hist = np.bincount(seg16 + pc, minlength=nseg * 16).reshape(nseg, 16)
                pp = self._pair_values(pc, hist, rgba[c1], rgba[c2], nseg)
                counted = vis[sv, c1] & vis[sv, c2]
                v = np.where(counted & drawn[c1] & drawn[c2], pp, 0.0)
                per_pair[sn[counted], sv[counted], c1, c2] = v[counted]
                num[sn, sv] += self._pair_w[c1, c2] * v

    def _warp_segments(self, part, ci, rows, sv, sn, do, X0, Y0, ww, hh, offs, total):
        """Warp camera ci's patch (and occluders) of the part into each (view ``sv``, position ``sn``) region.

        Returns the RGBA buffer (total, 4) uint8 and the per-pixel code (total,) uint8:
        bit 0 the pixel is active (alpha >= the threshold), bit 1 another part hides it.
        The homographies are part_score's, element by element (the 3x2 products stacked: numpy
        calls the same BLAS product per item), so the warps are the same pixels.
        """
        src = self.sources[ci][part]
        buf = np.zeros((total, 4), np.uint8)
        occ = self.config.occlusion and src.has_occluder
        hid = np.zeros(total, np.uint8) if occ else None
        # H = M + kt row^T, then into the region of the view
        H = self._Ms[sv, ci] + self._kts[sv, ci][:, :, None] * rows[sn][:, None, :]
        H[:, 0] += -X0[:, None] * H[:, 2]
        H[:, 1] += -Y0[:, None] * H[:, 2]
        Hp = H.copy()
        Hp[:, :, 2] += H[:, :, :2] @ src.origin  # from patch pixels
        if occ:
            Ho = H.copy()
            Ho[:, :, 2] = H[:, :, 2] + H[:, :, :2] @ src.occ_origin
        lin, near, const = cv2.INTER_LINEAR, cv2.INTER_NEAREST, cv2.BORDER_CONSTANT
        o, w, h = offs.tolist(), ww.tolist(), hh.tolist()
        for j in np.flatnonzero(do).tolist():
            a, b = o[j], o[j + 1]
            cv2.warpPerspective(src.patch, Hp[j], (w[j], h[j]), dst=buf[a:b].reshape(h[j], w[j], 4), flags=lin,
                                borderMode=const)
            if occ:
                cv2.warpPerspective(src.hidden, Ho[j], (w[j], h[j]), dst=hid[a:b].reshape(h[j], w[j]), flags=near,
                                    borderMode=const)
        code = (buf[:, 3] >= self._thr).view(np.uint8)
        if occ:
            code |= hid
        return buf, code

    def _pair_values(self, pc, hist, rgba1, rgba2, n):
        """Eq. 3 of one camera pair for each of n regions.

        ``pc`` (total,) is the pair's pixel code (:data:`_PAIR_COUNTS`), ``hist`` (n, 16) its
        histogram per region; ``rgba1``, ``rgba2`` (total, 4) the two warps.
        """
        n_both, n_a1, n_a2 = (hist @ _PAIR_COUNTS).T
        n_either = n_a1 + n_a2 - n_both
        idx = np.flatnonzero((pc & 5) == 5)
        out = np.zeros(n)
        if idx.size == 0:
            return out
        d = rgba1.take(idx, axis=0).astype(np.int32)
        d -= rgba2.take(idx, axis=0)
        d = d[:, :3]
        e = self._eps.take(np.einsum("ij,ij->i", d, d))
        ends = np.cumsum(n_both).tolist()
        nb, ne = n_both.tolist(), n_either.tolist()
        for j in range(n):
            if nb[j] > 0 and ne[j] > 0:  # Σ s(p) / #active, with part_score's float32 sum of the same values
                out[j] = float(nb[j] - _add_reduce(e[ends[j] - nb[j]:ends[j]])) / ne[j]
        return out

    def move_evidence(self, joints: np.ndarray, joint: int, position: np.ndarray,
                      visibility: dict | None = None) -> "MoveEvidence":
        """How each evaluated view and each camera pair judges moving ``joint`` to ``position``.

        The joint score is a mean over views of pair-weighted means over camera
        pairs; a rise of it can come from one view or one pair alone (a label
        error in one camera, a billboard seen almost edge-on).  This splits the
        rise into its parts, so that a search can ask whether independent
        evidence agrees.

        Parameters
        ----------
        joints : ndarray of shape (14, 3)
            Current pose, metres.
        joint : int
        position : ndarray of shape (3,)
            Candidate position of ``joint``, metres.
        visibility : dict of int to ndarray (n_views, n_cams) bool, optional
            Per adjacent part, as for :meth:`joint_score` (default: that of ``joints``).

        Returns
        -------
        MoveEvidence
        """
        J0 = np.array(joints, float)
        if J0.shape != (self.skeleton.n_joints, 3):
            raise InputError("joints", f"an array of shape ({self.skeleton.n_joints}, 3)", f"shape {J0.shape}")
        x = np.asarray(position, float)
        if x.shape != (3,) or not np.all(np.isfinite(x)):
            raise InputError("position", "a finite array of shape (3,)", f"{x!r}")
        J1 = J0.copy()
        J1[joint] = x
        parts = self.adjacent_parts(joint)
        vis = visibility if visibility is not None else {p: self.visibility(J0, p) for p in parts}
        nv, nc = len(self.views), len(self.rig)
        view_gain = np.zeros(nv)
        view_seen = np.zeros(nv, bool)
        pair_gain = np.full((nc, nc), np.nan)
        for p in parts:
            a, b = self.part_score(J0, p, vis.get(p)), self.part_score(J1, p, vis.get(p))
            ok = np.isfinite(a.per_view) & np.isfinite(b.per_view)
            view_gain[ok] += b.per_view[ok] - a.per_view[ok]
            view_seen |= ok
            d = b.per_pair - a.per_pair  # (n_views, n_cams, n_cams), NaN where the pair is not evaluated
            seen = np.isfinite(d)
            n = seen.sum(axis=0)
            mean = np.where(n > 0, np.nansum(d, axis=0) / np.maximum(n, 1), np.nan)
            pair_gain = np.where(np.isfinite(mean), np.nan_to_num(pair_gain) + mean, pair_gain)
        self.n_evaluations += 2
        return MoveEvidence(np.where(view_seen, view_gain, np.nan), pair_gain)

    def _check(self, J: np.ndarray, joint: int) -> None:
        """InputError unless ``J`` is a (n_joints, 3) pose and ``joint`` one of its joints."""
        if J.shape != (self.skeleton.n_joints, 3):
            raise InputError("joints", f"an array of shape ({self.skeleton.n_joints}, 3)", f"shape {J.shape}")
        if not 0 <= joint < self.skeleton.n_joints:
            raise InputError("joint", f"a joint index in [0, {self.skeleton.n_joints})", f"{joint}")

    def adjacent_parts(self, joint: int) -> list[int]:
        """0-based indices of the parts whose fans move with ``joint``."""
        return self._adjacent[joint]

    def joint_score(self, joints: np.ndarray, joint: int, visibility: dict | None = None) -> float:
        """Position score of ``joint``: the sum of its adjacent bones' scores (NaN bones count 0).

        ``visibility`` maps part index to a (n_views, n_cams) bool array
        (:meth:`visibility`); default: that of ``joints``.  Returns NaN when no
        adjacent bone can be scored (no camera pair sees any of them).
        """
        J = np.asarray(joints, float)
        self._check(J, joint)
        vis = visibility or {}
        self.n_evaluations += 1
        vals = [self.part_score(J, p, vis.get(p)).value for p in self.adjacent_parts(joint)]
        vals = [v for v in vals if np.isfinite(v)]
        return float(sum(vals)) if vals else float("nan")

    def candidate_scores(self, joints: np.ndarray, joint: int, positions: np.ndarray,
                         visibility: dict | None = None) -> np.ndarray:
        """Scores (N,) of ``joint`` moved to each of ``positions`` (N, 3), the rest of the pose fixed.

        The views and billboards evaluated are those of ``joints`` (or ``visibility``)
        for every candidate, so that candidates are compared on the same terms.
        Each is :meth:`joint_score` of the moved pose (the same value, bit for
        bit), computed for all candidates at once (:meth:`part_scores`).
        """
        J = np.array(joints, float)
        self._check(J, joint)
        pos = np.asarray(positions, float).reshape(-1, 3)
        if visibility is None:
            visibility = {p: self.visibility(J, p) for p in self.adjacent_parts(joint)}
        Jn = np.repeat(J[None], len(pos), axis=0)
        Jn[:, joint] = pos
        values = []
        for p in self.adjacent_parts(joint):
            vp = visibility.get(p)
            scores = self.part_scores(p, self._W[p] @ Jn, vp) if vp is not None else \
                [self.part_score(Jc, p) for Jc in Jn]  # no fixed set: each pose's own
            values.append([ps.value for ps in scores])
        self.n_evaluations += len(pos)
        out = np.empty(len(pos))
        for i in range(len(pos)):
            vals = [v[i] for v in values if np.isfinite(v[i])]
            out[i] = float(sum(vals)) if vals else float("nan")
        return out

    def pose_score(self, joints: np.ndarray) -> float:
        """Mean bone score over the bones that can be scored (NaN if none)."""
        J = np.asarray(joints, float)
        vals = [self.part_score(J, p).value for p in range(self.skeleton.n_parts)]
        vals = [v for v in vals if np.isfinite(v)]
        return float(np.mean(vals)) if vals else float("nan")
