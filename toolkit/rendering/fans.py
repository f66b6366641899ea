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

from dataclasses import replace

import cv2
import numpy as np

from toolkit.billboards import BillboardConfig, SeamMap, build_billboards
from toolkit.billboards.model import BillboardModel
from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.observe import Observer

#: Texture supersampling of the rendered fans (texels per source pixel along each axis).
RENDER_SUPERSAMPLE = 6
#: Margin around the subject's labels kept when enlarging a view, source pixels.
CROP_MARGIN_PX = 8


def render_billboards(images: dict, labels: dict, joints3d: np.ndarray, rig: Rig, offsets=None,
                      seams: dict | None = None, config: BillboardConfig = BillboardConfig(), *,
                      supersample: int = RENDER_SUPERSAMPLE,
                      frame: int = 0, observer: Observer | None = None) -> BillboardModel:
    """:func:`toolkit.billboards.build_billboards` with ``supersample`` x finer textures.

    Parameters
    ----------
    images : dict of str -> ndarray (H, W, 3) uint8
    labels : dict of str -> ndarray (H, W) uint8
        Part ids (seams already resolved into the labels).
    joints3d : ndarray of shape (14, 3)
    rig : Rig
    offsets : ndarray of shape (n_cams, 2), optional
        Calibration offsets at the source resolution, pixels.
    seams : dict of str -> SeamMap, optional
        Seam pixels of stage 3 (enlarged with the labels).
    supersample : int
        Enlargement factor (1 = stage 3's textures).

    Returns
    -------
    BillboardModel
        With the original ``rig`` and ``offsets`` (the geometry does not depend on the scale).
    """
    if int(supersample) < 1:
        raise InputError("render_billboards: supersample", "an integer >= 1", repr(supersample))
    s = int(supersample)
    off = np.zeros((len(rig), 2)) if offsets is None else np.asarray(offsets, float)
    if s == 1:
        return build_billboards(images, labels, joints3d, rig, off, seams, config=config, frame=frame,
                                observer=observer)
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
    m = build_billboards(big_img, big_lab, joints3d, big_rig, off * s, big_seams or None, config=cfg, frame=frame)
    if observer is not None and m.billboards:  # recorded at about the source resolution
        observer.report("quads", name="billboards", frame=frame, corners=np.stack([b.corners for b in m.billboards]),
                        textures=[cv2.resize(b.rgba(), (max(b.size[0] // s, 1), max(b.size[1] // s, 1)),
                                             interpolation=cv2.INTER_AREA) for b in m.billboards])
    return BillboardModel(m.fans, rig, off, m.frame, m.joints)
