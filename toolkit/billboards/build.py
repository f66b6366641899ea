"""Building billboard fans from images, part labels and 3D joints (source 000 §1, claims 9 and 11)."""

from __future__ import annotations

from typing import Mapping

import cv2
import numpy as np

from toolkit.billboards.config import BillboardConfig
from toolkit.billboards.geometry import billboard_frame, segment_extent
from toolkit.billboards.model import Billboard, BillboardFan, BillboardModel
from toolkit.billboards.seams import SeamMap, membership_of
from toolkit.billboards.surfaces import lift
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.observe import Observer, as_observer
from toolkit.skeleton import SKELETON_14, Skeleton

#: Largest texture side, texels (a billboard never needs more than the source resolution).
MAX_TEXTURE_SIDE = 1024


def segment_outline(member: np.ndarray) -> np.ndarray:
    """Convex-hull outline (K, 2) of a boolean segment, as pixel-corner coordinates; (0, 2) if empty.

    The hull of every pixel's four corners is the hull of the corners of each
    row's first and last pixel (the others lie between them on the same two
    lines), so only those are handed to ``cv2.convexHull`` (same outline;
    ``tests/billboards/test_outline.py``).
    """
    m = np.asarray(member, bool)
    rows = np.flatnonzero(m.any(axis=1))
    if rows.size == 0:
        return np.zeros((0, 2))
    sub = m[rows]
    first = sub.argmax(axis=1)
    last = m.shape[1] - 1 - sub[:, ::-1].argmax(axis=1)
    pts = np.concatenate([np.stack([x + dx, rows + dy], -1) for x, dx in ((first, -0.5), (last, 0.5))
                          for dy in (-0.5, 0.5)])
    hull = cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2)
    return hull.astype(np.float64)


def check_inputs(images: Mapping, labels: Mapping, rig: Rig) -> None:
    """Validate per-camera images and label images against a rig."""
    for cam in rig:
        w, h = cam.size
        if cam.name not in images:
            raise InputError("images", f"an image for camera {cam.name!r}", f"cameras {sorted(images)}")
        if cam.name not in labels:
            raise InputError("labels", f"a label image for camera {cam.name!r}", f"cameras {sorted(labels)}")
        im = np.asarray(images[cam.name])
        if im.shape != (h, w, 3) or im.dtype != np.uint8:
            raise InputError(f"images[{cam.name!r}]", f"a ({h}, {w}, 3) uint8 RGB image",
                             f"shape {im.shape}, dtype {im.dtype}")
        lb = np.asarray(labels[cam.name])
        if lb.shape != (h, w):
            raise InputError(f"labels[{cam.name!r}]", f"a ({h}, {w}) part-label image", f"shape {lb.shape}")


def memberships(labels: Mapping, seams: Mapping[str, SeamMap] | None, names) -> dict:
    """Per camera the (H, W) uint16 part membership bits (seam pixels count for both parts)."""
    out = {}
    for n in names:
        if seams is not None and n in seams:
            out[n] = np.asarray(seams[n].membership, np.uint16)
        else:
            out[n] = membership_of(np.asarray(labels[n]))
    return out


def build_billboard(image: np.ndarray, member: np.ndarray, camera: Camera, proximal, distal,
                    part: int, config: BillboardConfig = BillboardConfig(),
                    outline: np.ndarray | None = None) -> Billboard | str:
    """One billboard of a bone for one source camera.

    Parameters
    ----------
    image : ndarray of shape (H, W, 3), uint8
    member : ndarray of shape (H, W), bool
        Pixels that belong to the part (seam pixels included).
    camera : Camera
        Source camera, corrected by stage 1's offsets (its projection is where the
        subject appears in ``image``).
    proximal, distal : array_like of shape (3,)
        Bone ends, metres.
    part : int
        1-based part id.
    config : BillboardConfig
    outline : ndarray of shape (K, 2), optional
        Precomputed :func:`segment_outline` of ``member``.

    Returns
    -------
    Billboard or str
        The billboard, or why there is none (``"empty segment"``, ``"edge-on"``, ``"behind camera"``).
    """
    if int(np.count_nonzero(member)) < config.min_pixels:
        return "empty segment"
    frame = billboard_frame(proximal, distal, camera.center, config.edge_on_deg)
    if frame is None:
        return "edge-on"
    if outline is None:
        outline = segment_outline(member)
    depth = float(camera.depth_of(0.5 * (np.asarray(proximal, float) + np.asarray(distal, float))))
    if depth <= 0:
        return "behind camera"
    texel = depth / float(camera.K[0, 0])  # metres per source pixel at the bone
    ext = segment_extent(frame, camera, outline, config.margin_px * texel, config.max_extent_m)
    if ext is None:
        return "behind camera"
    a0, a1, s0, s1 = ext
    w = int(min(max(np.ceil((a1 - a0) / texel), 1), MAX_TEXTURE_SIDE))
    h = int(min(max(np.ceil((s1 - s0) / texel), 1), MAX_TEXTURE_SIDE))
    tu, tv = (a1 - a0) / w, (s1 - s0) / h
    radius = 0.0
    if config.surface != "plane":
        radius = config.radius_m if config.radius_m is not None else 0.5 * (a1 - a0)
        radius = float(max(radius, texel))
    uu, vv = np.meshgrid(a0 + (np.arange(w) + 0.5) * tu, s0 + (np.arange(h) + 0.5) * tv)
    P = lift(frame, uu, vv, config.surface, radius)
    uv = camera.project(P)
    mx = np.nan_to_num(uv[..., 0], nan=-1e6).astype(np.float32)
    my = np.nan_to_num(uv[..., 1], nan=-1e6).astype(np.float32)
    tex = cv2.remap(np.ascontiguousarray(image), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    m8 = member.astype(np.uint8) * 255
    al = cv2.remap(m8, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT).astype(np.float32) / 255.0
    corners = np.stack([frame.to_world(a0, s0), frame.to_world(a1, s0), frame.to_world(a1, s1),
                        frame.to_world(a0, s1)])
    return Billboard(part=part, camera=camera.name, corners=corners, texture=tex, alpha=al,
                     normal=frame.normal, surface=config.surface, radius=radius,
                     axis=np.stack([np.asarray(proximal, float), np.asarray(distal, float)]))


def build_billboards(images: Mapping[str, np.ndarray], labels: Mapping[str, np.ndarray], joints3d: np.ndarray,
                     rig: Rig, seams: Mapping[str, SeamMap] | None = None,
                     config: BillboardConfig = BillboardConfig(), *, frame: int = 0,
                     skeleton: Skeleton = SKELETON_14, observer: Observer | None = None) -> BillboardModel:
    """The articulated billboard model of one frame.

    Parameters
    ----------
    images : dict of str to ndarray of shape (H, W, 3), uint8
        Source images per camera name.
    labels : dict of str to ndarray of shape (H, W), uint8
        Part ids (1-based, 0 background) per camera.
    joints3d : ndarray of shape (14, 3)
        Joints, metres.
    rig : Rig
        Source cameras, corrected by stage 1's offsets
        (:func:`toolkit.multiview.corrected_rig`).
    seams : dict of str to SeamMap, optional
        Seam pixels per camera (:func:`~toolkit.billboards.seams.detect_seams`).
    config : BillboardConfig
    frame : int
    skeleton : Skeleton
    observer : Observer, optional
        Receives ``quads`` (name ``"billboards"``) and a ``text`` per missing billboard.

    Returns
    -------
    BillboardModel
        Parts without any billboard have no fan.
    """
    check_inputs(images, labels, rig)
    J = skeleton.check_joints(joints3d, "joints3d")
    if J.shape != (skeleton.n_joints, 3) or not np.all(np.isfinite(J)):
        raise InputError("joints3d", f"finite joints of shape ({skeleton.n_joints}, 3)",
                         f"shape {J.shape}, {int(np.sum(~np.isfinite(J)))} non-finite values")
    obs = as_observer(observer)
    members = memberships(labels, seams, rig.names)
    ends = skeleton.part_endpoints(J)
    fans = []
    for p in range(skeleton.n_parts):
        pid = p + 1
        bbs = []
        for ci, cam in enumerate(rig):
            member = (members[cam.name] & np.uint16(1 << pid)) != 0
            res = build_billboard(images[cam.name], member, cam, ends[p, 0], ends[p, 1], pid, config)
            if isinstance(res, str):
                obs.report("text", name="billboards/missing", frame=frame,
                           text=f"part {skeleton.parts[p].name}, camera {cam.name}: {res}")
            else:
                bbs.append(res)
        if bbs:
            fans.append(BillboardFan(part=pid, billboards=tuple(bbs), axis=ends[p]))
    model = BillboardModel(fans=tuple(fans), rig=rig, frame=frame, joints=J)
    if model.billboards:
        obs.report("quads", name="billboards", frame=frame,
                   corners=np.stack([b.corners for b in model.billboards]),
                   textures=[b.rgba() for b in model.billboards])
    return model
