"""Views a run renders and judges: the dataset's novel cameras and a held-out source camera.

Leaving a real camera out (``free_viewpoint.py --hold-out CAM``) is the honest test
of a novel-view method on real footage: the pipeline runs without that camera's
images and keypoints, renders its view from the others, and compares with what it
filmed.  Without ground truth, *the person's region* of the held-out frame is its
subject mask, from the first of: masks given for that camera (``--masks`` or the
dataset's ``masks/``), the dataset's ground-truth mask (synthetic), or a
segmentation of that frame seeded by that camera's own keypoints (used for the
evaluation only: the pipeline never sees them).  The whole frame is rendered
from the other cameras: the people over the run's scene model
(:mod:`toolkit.scene`, built from the other cameras' videos), so no pixel of the
held-out camera is used but for judging; ``nearest_source`` (the closest source
camera's frame carried through the scene proxy) is the baseline of the whole
frame.  With ``background="plates"`` (an evaluation aid for the person alone) the
view is rendered over the camera's clean plate when the dataset has one, else
over its own frame with the region (dilated by :data:`BLANK_MARGIN_PX`) filled
in from its surroundings (:func:`blanked_background`), so that a part a method
fails to draw shows the background, never the real person.  Scores: PSNR over the region
dilated by 2 px (``psnr_subject``), PSNR / SSIM in the region's box (``psnr``,
``ssim``), the share of the region drawn with opacity > 0.5 (``coverage``),
and PSNR over the whole frame (``psnr_frame``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError

__all__ = ["EvaluationView", "HeldOutRegions", "split_rig", "blanked_background", "render_evaluation", "shifted",
           "BLANK_MARGIN_PX", "HELDOUT_REGION_DOC"]

#: The person's region is filled in the held-out frame's background this far beyond its mask, pixels.
BLANK_MARGIN_PX = 6


@dataclass(frozen=True, eq=False)
class EvaluationView:
    """One view to render and (when a reference exists) judge.

    Attributes
    ----------
    camera : Camera
    kind : {"novel", "heldout"}
        Where the articulated rendering is written: ``novel/`` or ``heldout/``.
    background : ndarray of shape (H, W, 3) float32
        What the subject is drawn over, 0..255.
    reference : ndarray of shape (H, W, 3) uint8, optional
        What the camera saw.
    region : ndarray of shape (H, W) bool, optional
        The subject's pixels in ``reference``.
    carried : ndarray of shape (H, W, 3) uint8, optional
        The ``nearest_source`` baseline's whole frame: the source camera closest to this view, its
        frame carried through the scene proxy (:meth:`toolkit.scene.SceneModel.carry`).
    people : list of ndarray of shape (H, W) bool, optional
        Each person's pixels in ``reference`` (several people): scored one by one
        (``psnr_people``).
    """

    camera: Camera
    kind: str
    background: np.ndarray
    reference: np.ndarray | None = None
    region: np.ndarray | None = None
    carried: np.ndarray | None = None
    people: list | None = None


def split_rig(rig: Rig, camera: str) -> tuple[Rig, Camera]:
    """The rig without ``camera``, and that camera.

    Raises
    ------
    InputError
        ``camera`` is not in the rig, or fewer than two cameras would remain.
    """
    if camera not in rig.names:
        raise InputError("--hold-out", f"one of the dataset's cameras {rig.names}", repr(camera))
    rest = Rig(tuple(c for c in rig if c.name != camera))
    if len(rest) < 2:
        raise InputError("--hold-out", "a camera of a rig of at least 3 (two must remain to triangulate)",
                         f"{camera!r} of {len(rig)} cameras")
    return rest, rig[camera]


def blanked_background(frame: np.ndarray, region: np.ndarray, margin_px: int = BLANK_MARGIN_PX) -> np.ndarray:
    """The held-out frame with the person's region (dilated by ``margin_px``) filled in from its surroundings.

    An estimate of the empty scene without a clean plate: OpenCV's inpainting (Telea's fast
    marching method) continues the wall, floor and treadmill into the region.  Where a method
    rightly draws nothing (a gap between an arm and the torso that a loose region holds) the
    estimate is close to what the camera saw; where it fails to draw the person, it shows the
    background, never the real person.

    Returns
    -------
    ndarray of shape (H, W, 3) float32, 0..255
    """
    k = 2 * int(margin_px) + 1
    grown = cv2.dilate(np.asarray(region, np.uint8), np.ones((k, k), np.uint8))
    img = np.ascontiguousarray(np.asarray(frame, np.uint8))
    # inpaint on a reduced image (the fill is smooth anyway), then keep the frame outside the region
    s = min(1.0, 480.0 / max(img.shape[:2]))
    small = cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_AREA) if s < 1 else img
    hole = cv2.resize(grown, (small.shape[1], small.shape[0]), interpolation=cv2.INTER_NEAREST) if s < 1 else grown
    hole = cv2.dilate(hole, np.ones((3, 3), np.uint8))
    filled = cv2.inpaint(small, hole, 5, cv2.INPAINT_TELEA)
    if s < 1:
        filled = cv2.resize(filled, (img.shape[1], img.shape[0]), interpolation=cv2.INTER_LINEAR)
    bg = img.astype(np.float32)
    bg[grown > 0] = filled[grown > 0]
    return bg


#: The last background written per camera and its PNG: (the array, the bytes).
_PLATE_PNGS: dict = {}


def _plate_png(camera: str, background: np.ndarray) -> bytes:
    """PNG of a view's background (rounded to uint8), encoded once while the camera's plate is the same
    read-only array (a novel camera's, drawn once per run); other backgrounds every time."""
    from toolkit.io import encode_png

    last = _PLATE_PNGS.get(camera)
    if last is not None and last[0] is background:
        return last[1]
    data = encode_png(np.clip(np.asarray(background, np.float32) + 0.5, 0, 255).astype(np.uint8))
    if isinstance(background, np.ndarray) and not background.flags.writeable:
        _PLATE_PNGS[camera] = (background, data)
    return data


def render_evaluation(result, view: EvaluationView, out: Path, frame: int, compositor=None,
                      observer=None) -> dict:
    """Render ``result`` with every method into ``view``, write the images, and score them.

    Writes ``novel/<camera>/NNNNNN.png`` (or ``heldout/``), its opacity under
    ``novel_alpha/`` (or ``heldout_alpha/``), ``baselines/<method>/<camera>/NNNNNN.png``
    and ``baselines/plate/<camera>/NNNNNN.png`` (the background alone).

    Returns
    -------
    dict of str -> dict
        Per method its scores (``psnr``, ``ssim``, ``psnr_subject``, ``coverage``, and ``psnr_frame``:
        PSNR over the whole frame); empty without a reference and region.  With ``view.carried``
        the ``nearest_source`` baseline too (written under ``baselines/nearest_source/``).
    """
    from toolkit.io import atomic_write_bytes, atomic_write_png
    from toolkit.io.frames import frame_filename
    from toolkit.rendering import bbox_scores, subject_scores
    from toolkit.rendering.freeviewpoint import render_views

    out = Path(out)
    name = frame_filename(frame)
    cam = view.camera.name
    atomic_write_bytes(out / "baselines" / "plate" / cam / name, _plate_png(cam, view.background))
    from toolkit.rendering import psnr
    from toolkit.rendering.freeviewpoint import RenderedView

    views = render_views(result, view.camera, view.background, compositor, observer=observer)
    if view.carried is not None:
        views["nearest_source"] = RenderedView(view.carried, np.ones(view.carried.shape[:2], np.float32))
    scores: dict = {}
    for m, v in views.items():
        folder = out / view.kind if m == "articulated" else out / "baselines" / m
        atomic_write_png(folder / cam / name, v.image)
        if m == "articulated":
            atomic_write_png(out / f"{view.kind}_alpha" / cam / name,
                             np.clip(np.rint(v.alpha * 255.0), 0, 255).astype(np.uint8))
        if view.reference is not None and view.region is not None:
            scores[m] = {**bbox_scores(v.image, view.reference, view.region),
                         **subject_scores(v.image, view.reference, view.region, v.alpha),
                         "psnr_frame": psnr(v.image, view.reference)}
            if view.people:
                scores[m]["psnr_people"] = [subject_scores(v.image, view.reference, r, v.alpha)["psnr_subject"]
                                            if r.any() else float("nan") for r in view.people]
        if observer is not None:
            observer.report("image", camera=cam, image=v.image, name=f"render/{m}", frame=frame)
    return scores


#: How the held-out camera's person region is defined (written into metrics.json).
HELDOUT_REGION_DOC = (
    "the held-out camera's subject mask, from the first of: masks given for that camera (--masks or the dataset's "
    "masks/), the dataset's ground-truth mask, a segmentation of that frame seeded by that camera's own keypoints "
    "(evaluation only: the pipeline never sees them); the held-out camera is first corrected by its 2D offset "
    "(the median of its own keypoints minus the run's 3D joints projected: a calibration error is not a rendering "
    "error); the whole frame rendered from the other cameras (the people over the scene model of the other "
    "cameras' videos; with background 'plates': over the camera's clean plate when the dataset has "
    "one, else over its own frame with the region (dilated by %d px) filled in from its surroundings); "
    "psnr_subject: PSNR over the region dilated by 2 px; psnr, ssim: in the region's box; coverage: share of the "
    "region drawn with opacity > 0.5; psnr_frame: PSNR over the whole frame; nearest_source: the closest other "
    "camera's frame carried through the scene proxy" % BLANK_MARGIN_PX)


class HeldOutRegions:
    """The reference, person's region and background of a held-out camera, frame by frame.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    camera : Camera
        The held-out camera (its calibration as used by the run).
    masks_dir : path-like, optional
        Masks given, ``<dir>/<camera>/NNNNNN.png``.
    keypoints : path-like, optional
        The dataset's keypoints folder: the held-out camera's own keypoints seed its region
        when there is neither a mask nor ground truth.
    out : path-like, optional
        Where the regions used are written (``heldout_region/<camera>/NNNNNN.png``) for checking.
    fmt : str, optional
        The keypoints' format (default: found from the files).
    correct : bool
        Correct the held-out camera by its 2D offset from its own keypoints (:meth:`view`).

    Attributes
    ----------
    how : dict of int -> str
        Per frame, where its region came from (``"masks"``, ``"ground truth"``,
        ``"seeded by its keypoints"`` or ``"none"``).
    """

    def __init__(self, dataset, camera: Camera, masks_dir=None, keypoints=None, out=None, correct: bool = True,
                 fmt: str | None = None):
        self.dataset = dataset
        self.fmt = fmt
        self.correct = bool(correct)
        self.offsets: dict = {}
        self.camera = camera
        self.masks_dir = None if masks_dir is None else Path(masks_dir)
        self.keypoints = None if keypoints is None else Path(keypoints)
        self.out = None if out is None else Path(out)
        self.how: dict = {}
        self._kp = None
        self._segmenter = None

    def _own_keypoints(self, frame: int, near: np.ndarray | None = None):
        """The held-out camera's own 14 joints (pixels) and confidences in ``frame``, or None.

        Of the people it detected, the one nearest to ``near`` (14 joints projected into it,
        pixels: the run's person) when given, else the most confident.
        """
        if self.keypoints is None:
            return None
        if self._kp is None:
            from toolkit.multiview.tracking import frame_detections
            from toolkit.pipeline.keypoints import read_dataset_keypoints
            from toolkit.skeleton.mappings import to_skeleton14

            _, _, data = read_dataset_keypoints(self.keypoints, self.dataset.camera_names, Rig((self.camera,)),
                                                fmt=self.fmt, person="most_confident")
            dets = frame_detections(data.cameras, data.frames, data.keypoints.shape[2])
            people = [to_skeleton14(d[0][None, None], data.format.fmt, confidence=True)[0, 0]
                      if len(d[0]) else np.zeros((0, 14, 3)) for d in dets]
            self._kp = (np.asarray(data.frames, int), people)
        frames, people = self._kp
        hit = np.flatnonzero(frames == int(frame))
        if not hit.size or not len(people[hit[0]]):
            return None
        cand = people[hit[0]]  # (P, 14, 3)
        if near is not None and len(cand) > 1 and np.isfinite(near).all(-1).sum() >= 4:
            d = [np.nanmedian(np.where(c[:, 2:3] > 0, np.linalg.norm(c[:, :2] - near, axis=-1)[:, None], np.nan))
                 if (c[:, 2] > 0).any() else np.inf for c in cand]
            k = int(np.nanargmin(d))
        else:
            k = int(np.argmax([np.nansum(c[:, 2]) for c in cand]))
        return cand[k][:, :2], np.nan_to_num(cand[k][:, 2])

    def region(self, frame: int, image: np.ndarray) -> tuple[np.ndarray | None, str]:
        """The person's pixels in the held-out ``image`` of ``frame`` and where they come from."""
        from toolkit.pipeline.keypoints import read_mask

        name = self.camera.name
        if self.masks_dir is not None:
            m = read_mask(self.masks_dir, name, frame, self.camera.size)
            if m is not None:
                return m, "masks"
        if self.dataset.has_groundtruth:
            return self.dataset.gt_mask(name, frame), "ground truth"
        own = self._own_keypoints(frame)
        if own is not None and np.count_nonzero(own[1] > 0) >= 6:
            from toolkit.foreground.seeded import SeededSegmenter

            if self._segmenter is None:
                self._segmenter = SeededSegmenter()
            res = self._segmenter.segment(image, own[0], own[1])
            # GrabCut may take patches of the probable-background band: keep the body's envelope only
            envelope = np.isin(res.trimap, (cv2.GC_FGD, cv2.GC_PR_FGD))
            return res.mask & envelope, "seeded by its keypoints"
        return None, "none"

    def offset(self, frame: int, joints3d: np.ndarray | None) -> np.ndarray:
        """The held-out camera's 2D offset in ``frame``: where its own keypoints are minus where the
        run's 3D joints project (median over the joints detected with confidence >= 0.3), pixels;
        zero without keypoints or joints."""
        J = None if joints3d is None else np.asarray(joints3d, float)
        own = self._own_keypoints(frame, self.camera.project(J)) if J is not None else None
        if own is None:
            return np.zeros(2)
        d = own[0] - self.camera.project(J)
        ok = (own[1] >= 0.3) & np.isfinite(d).all(-1)
        return np.median(d[ok], axis=0) if ok.sum() >= 4 else np.zeros(2)

    def people_regions(self, frame: int, image: np.ndarray, people: list) -> list | None:
        """Each person's pixels in the held-out ``image``: the ground truth's instances (synthetic),
        else a segmentation seeded by the held-out camera's own detection of that person (the one
        nearest to the person's 3D joints projected), a pixel two regions claim given to the nearer
        person (:func:`toolkit.pipeline.people.exclusive_masks`); None with fewer than two people."""
        if people is None or len(people) < 2:
            return None
        name = self.camera.name
        if self.dataset.has_groundtruth and getattr(self.dataset, "people_count", 1) > 1:
            inst = self.dataset.gt_instances(name, frame)
            return [inst == k + 1 for k in range(self.dataset.people_count)]
        from toolkit.foreground.seeded import SeededSegmenter

        if self._segmenter is None:
            self._segmenter = SeededSegmenter()
        out = []
        for J in people:
            own = self._own_keypoints(frame, self.camera.project(np.asarray(J, float)))
            if own is None or np.count_nonzero(own[1] > 0) < 6:
                out.append(np.zeros(image.shape[:2], bool))
                continue
            res = self._segmenter.segment(image, own[0], own[1])
            out.append(res.mask & np.isin(res.trimap, (cv2.GC_FGD, cv2.GC_PR_FGD)))
        # where two people's regions overlap, the pixel is the nearer person's (as for the sources' silhouettes)
        from toolkit.pipeline.people import exclusive_masks

        excl = exclusive_masks([[m] for m in out], [np.asarray(J, float) for J in people], Rig((self.camera,)))
        return [e[0] if e[0] is not None else np.zeros(image.shape[:2], bool) for e in excl]

    def view(self, frame: int, joints3d: np.ndarray | None = None, scene=None, images: dict | None = None,
             people: list | None = None) -> EvaluationView:
        """The :class:`EvaluationView` of ``frame`` (writes its region under ``heldout_region/``).

        With ``joints3d`` (the run's joints of this frame) and the camera's own keypoints, the
        camera is corrected by its 2D offset (:meth:`offset`: its principal point shifted, two
        numbers per frame, as stage 1 does for the source cameras), so that a calibration error
        of the held-out camera is not scored as a rendering error; ``offsets`` keeps them.

        With ``scene`` (a :class:`toolkit.scene.SceneModel` of the other cameras) the whole frame
        is rendered from the other cameras: the background is the scene model's view (shifted by
        the same offset), and ``images`` (the source cameras' frames) give the ``nearest_source``
        baseline; no pixel of the held-out camera is used but for judging.  Without it the
        background is the camera's clean plate, else its own frame with the region filled in.
        With ``people`` (several people's 3D joints) each person's region is judged too
        (:meth:`people_regions`).
        """
        name = self.camera.name
        ref = self.dataset.frame(name, frame)
        o = self.offset(frame, joints3d) if self.correct else np.zeros(2)
        self.offsets[int(frame)] = o
        cam = self.camera
        if np.any(o != 0):
            K = cam.K.copy()
            K[0, 2] += o[0]
            K[1, 2] += o[1]
            cam = cam.replace(K=K)
        region, how = self.region(frame, ref)
        self.how[int(frame)] = how
        regions = self.people_regions(frame, ref, people) if region is not None else None
        if regions is not None and how == "seeded by its keypoints":
            region = np.logical_or.reduce(regions)  # every person's, not only the most confident one's
        if region is not None and self.out is not None:
            from toolkit.io import atomic_write_png
            from toolkit.io.frames import frame_filename

            atomic_write_png(self.out / "heldout_region" / name / frame_filename(frame),
                             region.astype(np.uint8) * 255)
        carried = None
        if scene is not None:
            bg = shifted(scene.render(self.camera)[0], o)
            if images is not None:
                near = scene.nearest_source(self.camera)
                carried = shifted(scene.carry(self.camera, near, images[near]), o)
        else:
            plate = self.dataset.background(name)
            if plate is not None:
                bg = np.asarray(plate, np.float32)
            elif region is not None:
                bg = blanked_background(ref, region)
            else:
                bg = np.asarray(ref, np.float32)
        return EvaluationView(cam, "heldout", bg, ref if region is not None else None, region, carried, regions)


def shifted(image: np.ndarray, offset) -> np.ndarray:
    """``image`` (H, W, C) moved by ``offset`` (dx, dy) pixels (a principal-point shift), edges replicated."""
    o = np.asarray(offset, float)
    if not np.any(o != 0):
        return image
    h, w = image.shape[:2]
    M = np.array([[1.0, 0.0, o[0]], [0.0, 1.0, o[1]]])
    return cv2.warpAffine(np.asarray(image), M, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
