"""Articulated billboards with finer textures, for rendering.

Stage 3 samples billboard textures at about one texel per source pixel; drawing
such a texture back into its own source view resamples the image twice and
blurs it (measured: 31-35 dB PSNR inside the subject on 320x180 studio
scenes).  :func:`render_billboards` builds the same fans from images and part
labels enlarged ``supersample`` times (bilinear colour, nearest labels) with
the rig scaled to match, so the textures carry 1/supersample source pixels per
texel and a virtual camera on a source camera reproduces it (about 40 dB at 4x,
43 dB at 6x on 320x180 studio scenes); only the subject's bounding box is enlarged.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from toolkit.billboards import BillboardConfig, SeamMap, build_billboards
from toolkit.billboards.model import Billboard, BillboardFan, BillboardModel
from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.observe import Observer
from toolkit.skeleton import SKELETON_14

#: Texture supersampling of the rendered fans (texels per source pixel along each axis).
RENDER_SUPERSAMPLE = 6
#: Margin around the subject's labels kept when enlarging a view, source pixels.
CROP_MARGIN_PX = 8
#: A limb's billboard whose segment covers less than this share of the area its mirror limb's covers in the
#: same camera is taken as occluded there and replaced by the mirror limb's, moved onto its bone
#: (:func:`borrow_occluded`).
BORROW_MIN_SHARE = 0.4


def render_billboards(images: dict, labels: dict, joints3d: np.ndarray, rig: Rig,
                      seams: dict | None = None, config: BillboardConfig = BillboardConfig(), *,
                      supersample: int = RENDER_SUPERSAMPLE, borrow: bool = True,
                      frame: int = 0, observer: Observer | None = None) -> BillboardModel:
    """:func:`toolkit.billboards.build_billboards` with ``supersample`` x finer textures.

    Parameters
    ----------
    images : dict of str -> ndarray (H, W, 3) uint8
    labels : dict of str -> ndarray (H, W) uint8
        Part ids (seams already resolved into the labels).
    joints3d : ndarray of shape (14, 3)
    rig : Rig
        Source cameras at the source resolution, corrected by stage 1's offsets
        (:func:`toolkit.multiview.corrected_rig`).
    seams : dict of str -> SeamMap, optional
        Seam pixels of stage 3 (enlarged with the labels).
    supersample : int
        Enlargement factor (1 = stage 3's textures).
    borrow : bool
        Give limbs hidden from a camera the billboard of their mirror limb (:func:`borrow_occluded`).

    Returns
    -------
    BillboardModel
        With the original ``rig`` (the geometry does not depend on the scale).
    """
    if int(supersample) < 1:
        raise InputError("render_billboards: supersample", "an integer >= 1", repr(supersample))
    s = int(supersample)
    if s == 1:
        m = build_billboards(images, labels, joints3d, rig, seams, config=config, frame=frame,
                             observer=observer)
        return borrow_occluded(m) if borrow else m
    # enlarge only the subject's bounding box (plus a margin) of each view
    crops, big_img, big_lab, big_seams = [], {}, {}, {}
    for cam in rig:
        lab = np.asarray(labels[cam.name])
        ys, xs = np.nonzero(lab)
        W, H = cam.size
        if len(xs) == 0:
            x0, y0, x1, y1 = 0, 0, 2, 2
        else:
            x0, y0 = max(xs.min() - CROP_MARGIN_PX, 0), max(ys.min() - CROP_MARGIN_PX, 0)
            x1, y1 = min(xs.max() + CROP_MARGIN_PX + 1, W), min(ys.max() + CROP_MARGIN_PX + 1, H)
        K = cam.K.copy()
        K[0, 2] -= x0
        K[1, 2] -= y0
        crops.append(cam.replace(K=K, size=(x1 - x0, y1 - y0)).scaled(s))
        big_img[cam.name] = cv2.resize(np.ascontiguousarray(images[cam.name][y0:y1, x0:x1]), None, fx=s, fy=s,
                                       interpolation=cv2.INTER_LINEAR)
        big_lab[cam.name] = cv2.resize(np.ascontiguousarray(lab[y0:y1, x0:x1]), None, fx=s, fy=s,
                                       interpolation=cv2.INTER_NEAREST)
        if seams is not None and seams.get(cam.name) is not None:
            sm = seams[cam.name]
            big_seams[cam.name] = SeamMap(
                np.kron(np.asarray(sm.mask[y0:y1, x0:x1]), np.ones((s, s), bool)),
                np.kron(np.asarray(sm.membership[y0:y1, x0:x1]), np.ones((s, s), np.uint16)))
    big_rig = Rig(tuple(crops))
    cfg = replace(config, margin_px=config.margin_px * s, min_pixels=config.min_pixels * s * s)
    m = build_billboards(big_img, big_lab, joints3d, big_rig, big_seams or None, config=cfg, frame=frame)
    if observer is not None and m.billboards:  # recorded at about the source resolution
        observer.report("quads", name="billboards", frame=frame, corners=np.stack([b.corners for b in m.billboards]),
                        textures=[cv2.resize(b.rgba(), (max(b.size[0] // s, 1), max(b.size[1] // s, 1)),
                                             interpolation=cv2.INTER_AREA) for b in m.billboards])
    m = BillboardModel(m.fans, rig, m.frame, m.joints)
    return borrow_occluded(m) if borrow else m


@dataclass(frozen=True, eq=False)
class BorrowedBillboard(Billboard):
    """A billboard of a limb's mirror limb moved onto the limb (:func:`borrow_occluded`).

    Its source camera did not see the limb (or a sliver of it: ``original``,
    the limb's own billboard from that camera, or None), so the blend fades it
    out near that camera and draws ``original`` over it
    (:func:`toolkit.rendering.blend.composite`): a source view is still
    reproduced exactly.
    """

    original: Billboard | None = None
    borrowed = True


def _area_m2(b: Billboard) -> float:
    """Area of a billboard's segment (alpha >= 0.5), square metres."""
    w, h = b.size
    du = float(np.linalg.norm(b.corners[1] - b.corners[0])) / w
    dv = float(np.linalg.norm(b.corners[3] - b.corners[0])) / h
    return float(np.count_nonzero(b.alpha >= 0.5)) * du * dv


def moved_billboard(b: Billboard, part: int, axis: np.ndarray, eye: np.ndarray,
                    original: Billboard | None = None) -> BorrowedBillboard | None:
    """Billboard ``b`` moved onto another bone ``axis`` (2, 3), facing ``eye`` (its source camera's centre).

    The texture keeps its place relative to the bone: across the bone at the
    same distance, along it in proportion to the bone lengths; the new plane
    holds the new bone and faces ``eye`` as the source's planes do
    (:mod:`toolkit.billboards.geometry`); ``original`` is kept with it (:class:`BorrowedBillboard`).
    None when a bone is degenerate or points at ``eye``.
    """
    if b.axis is None:
        return None
    a0, a1 = (np.asarray(x, float) for x in b.axis)
    f0, f1 = (np.asarray(x, float) for x in axis)
    lg, lf = float(np.linalg.norm(a1 - a0)), float(np.linalg.norm(f1 - f0))
    if lg < 1e-6 or lf < 1e-6:
        return None
    ev_g = (a1 - a0) / lg
    n_g = b.normal - (b.normal @ ev_g) * ev_g
    if np.linalg.norm(n_g) < 1e-9:
        return None
    n_g /= np.linalg.norm(n_g)
    eu_g = np.cross(n_g, ev_g)
    ev_f = (f1 - f0) / lf
    n_f = np.asarray(eye, float) - f0
    n_f = n_f - (n_f @ ev_f) * ev_f
    if np.linalg.norm(n_f) < 1e-6:
        return None
    n_f /= np.linalg.norm(n_f)
    eu_f = np.cross(n_f, ev_f)
    q = b.corners - a0
    corners = f0 + np.outer(q @ eu_g, eu_f) + np.outer((q @ ev_g) * (lf / lg), ev_f)
    return BorrowedBillboard(part, b.camera, corners, b.texture, b.alpha, n_f, axis=np.stack([f0, f1]),
                             original=original)


def borrow_occluded(model: BillboardModel, min_share: float = BORROW_MIN_SHARE) -> BillboardModel:
    """Limbs hidden from a camera take their mirror limb's billboard from that camera.

    A source camera often sees one arm (or leg) and not the other, hidden
    behind the body: its billboard of the hidden limb is missing or a sliver,
    and a novel view that sees that limb (the far side, a high view) draws
    nothing there.  Left and right limbs look alike (same sleeve, same
    trouser), so the visible limb's billboard of that camera, moved onto the
    hidden limb's bone (:func:`moved_billboard`), stands in for it.  A limb's
    billboard is replaced where its segment covers less than ``min_share`` of
    the area its mirror limb's covers in the same camera (bone lengths and
    image scale included: areas in square metres on the billboards).  Per
    camera, not per limb: borrowing only for limbs no camera saw well (a
    limb seen by one camera keeps its own billboards everywhere) kept the
    between-view PSNR of a two-camera pair but lost the gain end to end
    (7 zoo scenes, 42 views: +0.00 dB and worst coverage 0.665, against
    +0.06 dB and 0.796 per camera; docs/stage4_rendering.md).

    Parameters
    ----------
    model : BillboardModel
    min_share : float
        Area ratio below which a limb counts as hidden from a camera (0 = never borrow).

    Returns
    -------
    BillboardModel
        The same model when nothing is borrowed; fans of limbs no camera saw are added.
    """
    J = np.asarray(model.joints, float)
    if min_share <= 0 or J.shape != (SKELETON_14.n_joints, 3) or not np.all(np.isfinite(J)):
        return model
    names = [p.name for p in SKELETON_14.parts]
    ends = SKELETON_14.part_endpoints(J)
    fans = {f.part: f for f in model.fans}
    centers = dict(zip(model.rig.names, model.rig.centers))
    changed = False
    out = dict(fans)
    for i, name in enumerate(names):
        if name[:2] not in ("l_", "r_"):
            continue
        mirror = {"l_": "r_", "r_": "l_"}[name[:2]] + name[2:]
        pid, qid = i + 1, names.index(mirror) + 1
        if qid not in fans:
            continue
        own = {b.camera: b for b in fans[pid].billboards} if pid in fans else {}
        boards = []
        for g in fans[qid].billboards:
            f = own.pop(g.camera, None)
            if f is None or _area_m2(f) < min_share * _area_m2(g):
                moved = moved_billboard(g, pid, ends[i], centers[g.camera], original=f)
                if moved is not None:
                    boards.append(moved)
                    changed = True
                    continue
            if f is not None:
                boards.append(f)
        boards += list(own.values())
        if boards:
            order = {n: k for k, n in enumerate(model.rig.names)}
            out[pid] = BillboardFan(pid, tuple(sorted(boards, key=lambda b: order[b.camera])), ends[i])
    if not changed:
        return model
    new_fans = tuple(out[k] for k in sorted(out))
    return BillboardModel(new_fans, model.rig, model.frame, model.joints)
