"""Foreground extraction per camera: raw mask, clean-up, optional motion prior, silhouette."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from toolkit.errors import InputError
from toolkit.foreground.background import BackgroundModel, check_rgb, frame_at, frame_count
from toolkit.foreground.chroma import chroma_key
from toolkit.foreground.config import ForegroundConfig
from toolkit.foreground.morphology import clean_mask, disk
from toolkit.foreground.motion import warp_previous_mask
from toolkit.foreground.silhouette import Silhouette, silhouette_from_mask
from toolkit.observe import Observer, as_observer


class ForegroundExtractor:
    """Silhouettes of one camera's frames.

    Parameters
    ----------
    config : ForegroundConfig, optional

    Examples
    --------
    >>> ex = ForegroundExtractor().fit(frames)            # doctest: +SKIP
    >>> sil = ex.extract(frames[10])                      # doctest: +SKIP
    >>> sil.state, sil.bbox                               # doctest: +SKIP
    """

    def __init__(self, config: ForegroundConfig | None = None):
        self.config = config or ForegroundConfig()
        self.model: BackgroundModel | None = None

    def fit(self, frames: Sequence[np.ndarray] | np.ndarray) -> "ForegroundExtractor":
        """Learn the background (background subtraction only; chroma keying needs nothing)."""
        if self.config.method == "background":
            self.model = BackgroundModel.fit(frames, self.config.background)
        return self

    def raw_mask(self, frame: np.ndarray, prior: np.ndarray | None = None) -> np.ndarray:
        """Foreground before clean-up, (H, W) bool; ``prior`` as in :meth:`extract`."""
        cfg = self.config
        img = check_rgb(frame, "frame")
        if cfg.method == "chroma":
            raw = chroma_key(img, cfg.chroma)
        else:
            if self.model is None:
                raise InputError("ForegroundExtractor", "fit(frames) before extract (background subtraction)",
                                 "no background model")
            use_scale = prior is not None and cfg.background.method == "median"
            raw = self.model.foreground(img, prior if use_scale else None, cfg.motion.prior_threshold_scale)
            if use_scale:
                return raw
        if prior is not None and cfg.motion.prior_reach_px:
            # binary detectors: the prior fills gaps of the detection (pixels that a closing
            # by prior_reach_px adds), never extends it outwards: at the trailing edge the
            # flow of the uncovered background is zero and would drag the old mask along
            r = cfg.motion.prior_reach_px
            pad = cv2.copyMakeBorder(raw.astype(np.uint8), r, r, r, r, cv2.BORDER_CONSTANT, value=0)
            gaps = cv2.morphologyEx(pad, cv2.MORPH_CLOSE, disk(r))[r:-r, r:-r] > 0
            raw = raw | (np.asarray(prior, bool) & gaps)
        return raw

    def extract(self, frame: np.ndarray, previous: tuple[np.ndarray, np.ndarray] | None = None) -> Silhouette:
        """The silhouette of one frame.

        Parameters
        ----------
        frame : ndarray of shape (H, W, 3), uint8 RGB
        previous : (previous_frame, previous_mask), optional
            With ``config.motion.enabled``, the previous mask is warped to this frame by
            dense optical flow and used as a prior.

        Returns
        -------
        Silhouette
            Empty, full-frame and border-touching masks come back with that state.
        """
        cfg = self.config
        img = check_rgb(frame, "frame")
        prior = None
        if cfg.motion.enabled and previous is not None:
            prev_frame, prev_mask = previous
            if np.asarray(prev_mask).any():
                prior = warp_previous_mask(prev_mask, prev_frame, img, cfg.motion.method)
        mask = clean_mask(self.raw_mask(img, prior), cfg.morphology)
        if self.model is not None:
            mask = self.model.trim_border(img, mask)
        return silhouette_from_mask(mask, cfg.silhouette)


def extract_silhouettes(frames: Sequence[np.ndarray] | np.ndarray, config: ForegroundConfig | None = None, *,
                        camera: str | None = None, observer: Observer | None = None,
                        background_frames: Sequence[np.ndarray] | None = None) -> list[Silhouette]:
    """Silhouettes of every frame of one camera.

    Parameters
    ----------
    frames : sequence of ndarray of shape (H, W, 3), uint8 RGB
        An array ``(T, H, W, 3)``, a list or a :class:`~toolkit.io.VideoReader`.
    config : ForegroundConfig, optional
    camera : str, optional
        Camera name for the reports.
    observer : Observer, optional
        Receives per frame a ``mask`` (name ``foreground/mask``), a ``boxes2d``
        (``foreground/bbox``), a ``scalar`` (``foreground/area_fraction/<camera>``) and, for
        states other than ``"ok"``, a ``text`` (``foreground/state``).
    background_frames : sequence, optional
        Frames to learn the background from (default: ``frames``).

    Returns
    -------
    list of Silhouette
        One per frame; a bad frame gives an ``"empty"`` or ``"full"`` silhouette, never
        an exception (wrong image shapes do raise :class:`~toolkit.errors.InputError`).
    """
    obs = as_observer(observer)
    ex = ForegroundExtractor(config).fit(frames if background_frames is None else background_frames)
    out: list[Silhouette] = []
    prev = None
    cam = {} if camera is None else {"camera": camera}
    for t in range(frame_count(frames)):
        img = frame_at(frames, t)
        sil = ex.extract(img, prev)
        out.append(sil)
        prev = (img, sil.mask) if sil.usable else None
        if camera is not None:
            obs.report("mask", mask=sil.mask, name="foreground/mask", frame=t, **cam)
            if sil.bbox is not None:
                x0, y0, x1, y1 = sil.bbox
                obs.report("boxes2d", mins=np.array([[x0 - 0.5, y0 - 0.5]]), sizes=np.array([[x1 - x0, y1 - y0]]),
                           labels=[sil.state], name="foreground/bbox", frame=t, **cam)
        tag = "" if camera is None else f"/{camera}"
        obs.report("scalar", name=f"foreground/area_fraction{tag}", value=sil.area_px / sil.mask.size, frame=t)
        if sil.state != "ok":
            obs.report("text", name="foreground/state", text=f"frame {t}{' ' + camera if camera else ''}: {sil.state}",
                       frame=t)
    return out
