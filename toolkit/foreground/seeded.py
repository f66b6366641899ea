"""Subject silhouettes seeded by 2D keypoints: footage without a clean plate, a subject that barely moves.

Background subtraction needs the empty scene or a subject that moves; a person on a
treadmill filmed without a clean plate has neither.  What such footage usually has is
a 2D pose per frame (a detector's keypoints, or a 3D pose projected into the camera).
:class:`SeededSegmenter` turns the pose into a trimap and lets OpenCV's GrabCut
(Rother, Kolmogorov and Blake 2004: colour GMMs of subject and background, a graph cut
with contrast-sensitive smoothness) decide the pixels in between:

* **sure subject**: thin bones (the middle of each limb, a shrunk torso, the head's
  centre), drawn only between joints detected with confidence;
* **probable subject**: thick bones (limb half-widths of a typical body scaled by the
  person's size in the image, see :data:`BONE_HALF_WIDTHS`), the torso polygon, head,
  hands and feet;
* **probable background**: a band around that;
* **sure background**: everything farther from the body, and the bodies of other
  people (``others``: a bystander's keypoints) outside the subject's probable region.

The result keeps only the connected components that hold sure-subject pixels, so a
bystander touching the band but not the subject is dropped.  Over time the previous
frame's colour models can start the next frame's (``previous`` with ``carry_models``; off by
default, see :data:`CARRY_MODELS`: a mistake then persists); across views
:func:`refine_masks` carves each camera's mask with the visual hull of the other
cameras' masks around the 3D pose: a pixel whose ray meets no point inside every other
view's mask is background.  ``docs/real_footage.md`` measures it.

Why GrabCut: it is OpenCV's maintained implementation of the seeded colour-model graph
cut, needs no training data and no GPU, and takes exactly this kind of trimap.

Units: pixels for images and 2D joints (centre of the top-left pixel is (0, 0)),
metres for 3D joints.  Joints follow :data:`toolkit.skeleton.JOINTS_14`; map a
detector's keypoints with :func:`toolkit.skeleton.mappings.to_skeleton14`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.foreground.background import check_rgb
from toolkit.observe import as_observer
from toolkit.skeleton import JOINTS_14

__all__ = ["BONE_HALF_WIDTHS", "SeededConfig", "SeededMask", "SeededSegmenter", "RefineConfig", "body_scale",
           "refine_masks", "seed_trimap"]

_J = {n: i for i, n in enumerate(JOINTS_14)}

#: Half-widths of the limbs in units of the torso length (neck to mid-hips, about 0.5 m for an
#: adult): upper arm 5 cm, forearm 4 cm, thigh 7.5 cm, shank 5.5 cm, neck 6 cm (ANSUR II-like
#: girths divided by 2 pi, rounded up for clothes).
BONE_HALF_WIDTHS = {("l_shoulder", "l_elbow"): 0.10, ("l_elbow", "l_wrist"): 0.08,
                    ("r_shoulder", "r_elbow"): 0.10, ("r_elbow", "r_wrist"): 0.08,
                    ("l_hip", "l_knee"): 0.15, ("l_knee", "l_ankle"): 0.11,
                    ("r_hip", "r_knee"): 0.15, ("r_knee", "r_ankle"): 0.11,
                    ("neck", "head"): 0.12}
#: Typical bone lengths in torso lengths, for the body scale when the torso is not seen.
BONE_LENGTHS = {("l_shoulder", "l_elbow"): 0.60, ("l_elbow", "l_wrist"): 0.52,
                ("r_shoulder", "r_elbow"): 0.60, ("r_elbow", "r_wrist"): 0.52,
                ("l_hip", "l_knee"): 0.86, ("l_knee", "l_ankle"): 0.84,
                ("r_hip", "r_knee"): 0.86, ("r_knee", "r_ankle"): 0.84,
                ("l_shoulder", "r_shoulder"): 0.74, ("l_hip", "r_hip"): 0.40}
#: Head radius around the 14-joint ``head`` (the middle of the ears), torso lengths: a head is
#: about 0.12 m from ear level to its top.
HEAD_RADIUS = 0.26
#: The probable head is the typical one times this (hair, a cap, a head tilted toward the camera;
#: at 1.0 the demo's swimming caps fell outside it).
HEAD_PROBABLE_SCALE = 1.35
#: Hands beyond the wrist and feet around the ankle, torso lengths.
HAND_REACH, HAND_RADIUS, FOOT_RADIUS = 0.30, 0.12, 0.30
#: Probable-subject half-widths are the typical ones times this (clothes, keypoint noise, bodies
#: wider than typical).
PROBABLE_SCALE = 1.8
#: Sure-subject half-widths are the typical ones times this, on the middle part of each bone.
SURE_SCALE = 0.4
#: Part of each bone (around its middle) drawn as sure subject: joint ends are where keypoints err.
SURE_BONE_PART = 0.6
#: The torso polygon is shrunk toward its centre by this factor for the sure subject.
SURE_TORSO_SHRINK = 0.5
#: Width of the probable-background band around the probable subject, torso lengths.
BAND = 0.5
#: Keypoints with a confidence below this seed no sure-subject pixels (they still shape the
#: probable region): OpenPose gives 0.1-0.3 to guessed joints.
MIN_SURE_WEIGHT = 0.3
#: GrabCut iterations per frame (OpenCV's default count is 5; 3 gave the same IoU on the test scenes).
ITERATIONS = 4
#: GrabCut works on the crop around the body resized so that its longer side is at most this
#: many pixels (the mask is resized back): a 1920 px tall person costs what a 480 px one does.
WORK_SIDE_PX = 480
#: Fewest seed pixels of each kind to learn a colour model from (GrabCut's GMMs have 5 components).
MIN_SEED_PIXELS = 50
#: After the first cut with the models learned from the seeds, GrabCut learns them again from
#: its cut (OpenCV's iteration) when True; when False every iteration keeps the seeds' models.
RELEARN = True
#: Start each frame's GrabCut from the previous frame's colour models (``previous``) instead of
#: models learned from the frame's own seeds.  Off: it gained 0.007 median IoU on the tuning
#: scenes, but on the Pose2Sim demo a patch of background taken once stays taken (cam_01's mask
#: grew from 163k to 200k pixels over 5 frames with the subject unchanged; docs/real_footage.md).
CARRY_MODELS = False
#: GrabCut's crop is the seeded region grown by this, torso lengths (a rim of sure background).
CROP_PAD = 0.1
#: Components of the mask smaller than this fraction of the subject's area are dropped.
MIN_COMPONENT_FRACTION = 0.02


@dataclass(frozen=True)
class SeededConfig:
    """Options of :class:`SeededSegmenter`; each default is the module constant of that name.

    Parameters
    ----------
    probable_scale, sure_scale, sure_bone_part, sure_torso_shrink, band : float
        Trimap geometry (:data:`PROBABLE_SCALE` ...), in typical half-widths or torso lengths.
    min_sure_weight : float
        :data:`MIN_SURE_WEIGHT`.
    iterations : int
        :data:`ITERATIONS`.
    work_side_px : int
        :data:`WORK_SIDE_PX`.
    min_component_fraction : float
        :data:`MIN_COMPONENT_FRACTION`.
    relearn : bool
        :data:`RELEARN`.
    local_models : bool
        One colour model per body region of :data:`REGIONS` (upper body, legs), each learned on
        the crop around its region, instead of one for the whole body.
    carry_models : bool
        :data:`CARRY_MODELS`.
    """

    probable_scale: float = PROBABLE_SCALE
    sure_scale: float = SURE_SCALE
    sure_bone_part: float = SURE_BONE_PART
    sure_torso_shrink: float = SURE_TORSO_SHRINK
    band: float = BAND
    min_sure_weight: float = MIN_SURE_WEIGHT
    iterations: int = ITERATIONS
    work_side_px: int = WORK_SIDE_PX
    min_component_fraction: float = MIN_COMPONENT_FRACTION
    relearn: bool = RELEARN
    local_models: bool = True
    carry_models: bool = CARRY_MODELS

    def __post_init__(self):
        for name in ("probable_scale", "sure_scale", "band"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"SeededConfig.{name}", "a finite value > 0", repr(v))
        for name in ("sure_bone_part", "sure_torso_shrink", "min_sure_weight", "min_component_fraction"):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0 <= v <= 1):
                raise InputError(f"SeededConfig.{name}", "a value in [0, 1]", repr(v))
        if self.sure_scale >= self.probable_scale:
            raise InputError("SeededConfig.sure_scale", f"a value below probable_scale ({self.probable_scale})",
                             repr(self.sure_scale))
        if int(self.iterations) != self.iterations or self.iterations < 1:
            raise InputError("SeededConfig.iterations", "an integer >= 1", repr(self.iterations))
        if int(self.work_side_px) != self.work_side_px or self.work_side_px < 32:
            raise InputError("SeededConfig.work_side_px", "an integer >= 32", repr(self.work_side_px))


@dataclass(frozen=True, eq=False)
class SeededMask:
    """One camera's segmentation of one frame.

    Attributes
    ----------
    mask : ndarray of shape (H, W), bool
        The subject.
    trimap : ndarray of shape (H, W), uint8
        The seeds given to GrabCut: ``cv2.GC_BGD`` (0), ``GC_FGD`` (1), ``GC_PR_BGD`` (2), ``GC_PR_FGD`` (3).
    scale_px : float
        The body scale used (torso length, pixels); NaN when the pose gave none (then the mask is empty).
    models : tuple of tuple of ndarray
        Per body region (:data:`REGIONS`), GrabCut's background and foreground colour models,
        (1, 65) float64 each (an empty tuple for a region without seeds), for the next frame.
    """

    mask: np.ndarray
    trimap: np.ndarray
    scale_px: float
    models: tuple = field(default=(), repr=False)


def _check_joints(joints2d, weights) -> tuple[np.ndarray, np.ndarray]:
    j = np.asarray(joints2d, float)
    if j.shape != (len(JOINTS_14), 2):
        raise InputError("joints2d", f"an array of shape ({len(JOINTS_14)}, 2) pixels (JOINTS_14 order)",
                         f"shape {j.shape}")
    if weights is None:
        w = np.where(np.all(np.isfinite(j), 1), 1.0, 0.0)
    else:
        w = np.asarray(weights, float)
        if w.shape != (len(JOINTS_14),) or np.any(w[np.isfinite(w)] < 0):
            raise InputError("weights", f"({len(JOINTS_14)},) confidences >= 0 (0 = missing)",
                             f"shape {w.shape}" if w.shape != (len(JOINTS_14),) else f"{w}")
        w = np.where(np.isfinite(w) & np.all(np.isfinite(j), 1), w, 0.0)
    return j, w


def body_scale(joints2d: np.ndarray, weights: np.ndarray | None = None) -> float:
    """The torso length (neck to mid-hips) in pixels, from the joints seen.

    Each visible bone of :data:`BONE_LENGTHS` (and the torso itself) gives an estimate; the
    75th percentile is kept because foreshortening only shortens bones.

    Parameters
    ----------
    joints2d : ndarray of shape (14, 2)
        Pixels, :data:`~toolkit.skeleton.JOINTS_14` order, NaN = missing.
    weights : ndarray of shape (14,), optional
        Confidences (0 = missing).

    Returns
    -------
    float
        Pixels; NaN when fewer than two bones are visible.
    """
    j, w = _check_joints(joints2d, weights)
    ok = w > 0
    est = []
    if ok[_J["neck"]] and ok[_J["l_hip"]] and ok[_J["r_hip"]]:
        est.append(np.linalg.norm(j[_J["neck"]] - (j[_J["l_hip"]] + j[_J["r_hip"]]) / 2))
    for (a, b), length in BONE_LENGTHS.items():
        if ok[_J[a]] and ok[_J[b]]:
            est.append(np.linalg.norm(j[_J[a]] - j[_J[b]]) / length)
    return float(np.percentile(est, 75)) if len(est) >= 2 else float("nan")


def _line(img, p, q, radius, value):
    r = max(int(round(radius)), 0)
    cv2.line(img, tuple(int(round(v)) for v in p), tuple(int(round(v)) for v in q), int(value), 2 * r + 1,
             cv2.LINE_8)


def _draw_body(img: np.ndarray, j: np.ndarray, ok: np.ndarray, s: float, width: float, value: int,
               cfg: SeededConfig, sure: bool) -> None:
    """Draw the body (probable when not ``sure``) into ``img`` with ``value``; coordinates already scaled."""
    for (a, b), hw in BONE_HALF_WIDTHS.items():
        ia, ib = _J[a], _J[b]
        if not (ok[ia] and ok[ib]):
            continue
        p, q = j[ia], j[ib]
        if sure:
            m, d = (p + q) / 2, (q - p) * cfg.sure_bone_part / 2
            p, q = m - d, m + d
        _line(img, p, q, hw * width * s, value)
    torso = [_J[n] for n in ("l_shoulder", "r_shoulder", "r_hip", "l_hip")]
    pts = [j[i] for i in torso + [_J["neck"]] if ok[i]]
    if len(pts) >= 3:
        pts = np.array(pts)
        c = pts.mean(0)
        if sure:
            pts = c + (pts - c) * cfg.sure_torso_shrink
        hull = cv2.convexHull(np.round(pts).astype(np.int32))
        cv2.fillConvexPoly(img, hull, int(value))
        if not sure:
            cv2.polylines(img, [hull], True, int(value), 2 * int(round(0.12 * s)) + 1)
    for hip in ("l_hip", "r_hip"):  # a pelvis seen from the side still joins the hips to the neck
        if ok[_J[hip]] and ok[_J["neck"]] and not sure:
            _line(img, j[_J[hip]], j[_J["neck"]], 0.15 * width * s, value)
    if ok[_J["head"]]:
        r = HEAD_RADIUS * s * (cfg.sure_scale if sure else HEAD_PROBABLE_SCALE * width / PROBABLE_SCALE)
        cv2.circle(img, tuple(int(round(v)) for v in j[_J["head"]]), max(int(round(r)), 0), int(value), -1)
    if sure:
        return
    for side in ("l", "r"):
        e, wr, an = _J[f"{side}_elbow"], _J[f"{side}_wrist"], _J[f"{side}_ankle"]
        if ok[wr]:
            end = j[wr]
            if ok[e]:
                d = j[wr] - j[e]
                end = j[wr] + d / max(np.linalg.norm(d), 1e-9) * HAND_REACH * s
            _line(img, j[wr], end, HAND_RADIUS * width / cfg.probable_scale * s * 1.5, value)
        if ok[an]:
            cv2.circle(img, tuple(int(round(v)) for v in j[an]), int(round(FOOT_RADIUS * s)), int(value), -1)


def seed_trimap(shape: tuple[int, int], joints2d: np.ndarray, weights: np.ndarray | None = None,
                config: SeededConfig | None = None, *, others=(), scale_px: float | None = None) -> np.ndarray:
    """GrabCut's seeds for one image from the subject's 2D pose (module docstring).

    Parameters
    ----------
    shape : tuple of int
        ``(H, W)`` of the image.
    joints2d : ndarray of shape (14, 2)
        The subject's joints, pixels, NaN = missing.
    weights : ndarray of shape (14,), optional
        Confidences in [0, 1] (0 = missing); all 1 for the finite joints when not given.
    config : SeededConfig, optional
    others : sequence of ndarray of shape (14, 2)
        Other people's joints (bystanders): their bodies are sure background outside the
        subject's probable region.
    scale_px : float, optional
        The body scale (torso length, pixels); :func:`body_scale` of the joints when not given.

    Returns
    -------
    ndarray of shape (H, W), uint8
        ``cv2.GC_BGD``, ``GC_FGD``, ``GC_PR_BGD`` or ``GC_PR_FGD`` per pixel; all ``GC_BGD``
        when the pose gives no scale.
    """
    cfg = config or SeededConfig()
    j, w = _check_joints(joints2d, weights)
    h, wd = int(shape[0]), int(shape[1])
    s = body_scale(j, w) if scale_px is None else float(scale_px)
    tri = np.full((h, wd), cv2.GC_BGD, np.uint8)
    if not np.isfinite(s) or s <= 0:
        return tri
    ok = w > 0
    prob = np.zeros((h, wd), np.uint8)
    _draw_body(prob, j, ok, s, cfg.probable_scale, 1, cfg, sure=False)
    band = cv2.distanceTransform((prob == 0).astype(np.uint8), cv2.DIST_L2, 5) <= cfg.band * s
    tri[band] = cv2.GC_PR_BGD
    for other in others:
        oj, ow = _check_joints(other, None)
        so = body_scale(oj, ow)
        if np.isfinite(so):
            o = np.zeros((h, wd), np.uint8)
            _draw_body(o, oj, ow > 0, so, 1.0, 1, cfg, sure=False)
            tri[(o > 0) & (prob == 0)] = cv2.GC_BGD
    tri[prob > 0] = cv2.GC_PR_FGD
    sure = np.zeros((h, wd), np.uint8)
    _draw_body(sure, j, w >= cfg.min_sure_weight, s, cfg.sure_scale, 1, cfg, sure=True)
    tri[sure > 0] = cv2.GC_FGD
    return tri


def _keep_seeded_components(mask: np.ndarray, seeds: np.ndarray, min_fraction: float) -> np.ndarray:
    n, lab, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if n <= 1:
        return mask
    hit = np.zeros(n, bool)
    hit[np.unique(lab[seeds & mask])] = True
    hit[0] = False
    area = stats[:, cv2.CC_STAT_AREA]
    total = area[hit].sum()
    hit &= area >= min_fraction * max(total, 1)
    return hit[lab]


def _pixel_models(bgr: np.ndarray, fg: np.ndarray, bg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """GrabCut's colour models learned from the ``fg`` and ``bg`` pixels only."""
    pix = np.concatenate([bgr[fg], bgr[bg]])[:, None, :]
    lab = np.concatenate([np.full(fg.sum(), cv2.GC_FGD, np.uint8), np.full(bg.sum(), cv2.GC_BGD, np.uint8)])[:, None]
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.setRNGSeed(0)  # GrabCut's k-means draws from OpenCV's global generator: the same input, the same masks
    cv2.grabCut(np.ascontiguousarray(pix), np.ascontiguousarray(lab), None, bgd, fgd, 0, cv2.GC_INIT_WITH_MASK)
    return bgd, fgd


def _grabcut(bgr: np.ndarray, trimap: np.ndarray, models, iterations: int, relearn: bool):
    """Run GrabCut on ``trimap`` (changed in place) and return its colour models.

    The first models come from the sure subject against the background seeds (``models`` None),
    so that background inside the probable region (the floor between the legs) does not enter
    the subject's colours; or they are the previous frame's.  The first cut keeps them; with
    ``relearn`` the remaining iterations learn them again from the cut, as GrabCut does.
    """
    sure_fg = trimap == cv2.GC_FGD
    bg = (trimap == cv2.GC_BGD) | (trimap == cv2.GC_PR_BGD)
    if models is None:
        fg = sure_fg if sure_fg.sum() >= MIN_SEED_PIXELS else sure_fg | (trimap == cv2.GC_PR_FGD)
        if fg.sum() < MIN_SEED_PIXELS or bg.sum() < MIN_SEED_PIXELS:
            return np.zeros((1, 65)), np.zeros((1, 65))
        models = _pixel_models(bgr, fg, bg)
    bgd, fgd = models[0].copy(), models[1].copy()
    cv2.grabCut(bgr, trimap, None, bgd, fgd, 1, cv2.GC_EVAL_FREEZE_MODEL)
    if iterations > 1:
        cv2.grabCut(bgr, trimap, None, bgd, fgd, iterations - 1,
                    cv2.GC_EVAL if relearn else cv2.GC_EVAL_FREEZE_MODEL)
    return bgd, fgd


#: The body's regions with their own colour models: a leg is told from the floor around it, the
#: chest from the wall behind it (one model for the whole body mixes the floor between the legs
#: with a shirt of its colour, the feet with a wall of skin colour).
REGIONS = (("head", "neck", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist"),
           ("l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle"))


def _regions(size: tuple[int, int], j: np.ndarray, ok: np.ndarray) -> list[np.ndarray]:
    """Per region of :data:`REGIONS`, the pixels nearer to its bones than to the others' ((H, W) bool)."""
    w, h = size
    dists = []
    for names in REGIONS:
        idx = [_J[n] for n in names if ok[_J[n]]]
        if not idx:
            continue
        img = np.full((h, w), 255, np.uint8)
        for (a, b), _ in BONE_HALF_WIDTHS.items():
            if _J[a] in idx and _J[b] in idx:
                _line(img, j[_J[a]], j[_J[b]], 0, 0)
        for i in idx:
            _line(img, j[i], j[i], 0, 0)
        if "l_hip" in names and ok[_J["l_hip"]] and ok[_J["r_hip"]]:
            _line(img, j[_J["l_hip"]], j[_J["r_hip"]], 0, 0)
        dists.append(cv2.distanceTransform(img, cv2.DIST_L2, 5))
    if len(dists) <= 1:
        return [np.ones((h, w), bool)]
    nearest = np.argmin(np.stack(dists), 0)
    return [nearest == k for k in range(len(dists))]


def _cut_region(work_img: np.ndarray, work_tri: np.ndarray, region: np.ndarray, models, pad: int,
                cfg: "SeededConfig") -> tuple[np.ndarray, tuple]:
    """GrabCut on the crop around ``region``'s seeded pixels; the subject (float 0/1, work size) and models.

    GrabCut sees the seeded region and a thin rim of sure background: far-away background would
    only dilute its background colour model.
    """
    fg = np.zeros(work_tri.shape, np.float32)
    ys, xs = np.nonzero((work_tri != cv2.GC_BGD) & region)
    if len(ys) == 0:
        return fg, ()
    h, w = work_tri.shape
    a0, a1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, h)
    b0, b1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, w)
    tri = np.ascontiguousarray(work_tri[a0:a1, b0:b1])
    if not (((tri == cv2.GC_FGD) | (tri == cv2.GC_PR_FGD)).any() and ((tri == cv2.GC_BGD) | (tri == cv2.GC_PR_BGD)).any()):
        fg[a0:a1, b0:b1] = (tri == cv2.GC_FGD) | (tri == cv2.GC_PR_FGD)
        return fg, ()
    bgr = np.ascontiguousarray(work_img[a0:a1, b0:b1, ::-1])  # OpenCV's channel order, only here
    bgd, fgd = _grabcut(bgr, tri, models or None, int(cfg.iterations), cfg.relearn)
    fg[a0:a1, b0:b1] = (tri == cv2.GC_FGD) | (tri == cv2.GC_PR_FGD)
    return fg, (bgd, fgd)


def _previous_and_allowed(previous, allowed, shape: tuple[int, int]):
    """Check the previous frame's result and the allowed region of :meth:`SeededSegmenter.segment`.

    Parameters
    ----------
    previous : SeededMask or array_like of shape (H, W) or None
    allowed : array_like of shape (H, W) or None
    shape : tuple of int
        ``(H, W)`` of the image.

    Returns
    -------
    prev_mask : ndarray of shape (H, W), bool, or None
    models : tuple or None
        The previous colour models (None: none).
    allowed : ndarray of shape (H, W), bool, or None

    Raises
    ------
    InputError
        A mask of another shape.
    """
    h, w = shape
    prev_mask, models = None, None
    if isinstance(previous, SeededMask):
        prev_mask, models = previous.mask, previous.models or None
    elif previous is not None:
        prev_mask = np.asarray(previous, bool)
    if prev_mask is not None and prev_mask.shape != (h, w):
        raise InputError("previous", f"a mask of shape {(h, w)}", f"shape {prev_mask.shape}")
    if allowed is not None:
        allowed = np.asarray(allowed, bool)
        if allowed.shape != (h, w):
            raise InputError("allowed", f"a mask of shape {(h, w)}", f"shape {allowed.shape}")
    return prev_mask, models, allowed


def _cut_regions(work_img: np.ndarray, work_tri: np.ndarray, regions: list, prev_models, pad: int,
                 config) -> tuple[np.ndarray, tuple]:
    """GrabCut each region of the work crop with its own colour models.

    Parameters
    ----------
    work_img : ndarray of shape (h, w, 3), uint8
        The crop at work resolution.
    work_tri : ndarray of shape (h, w), uint8
        Its trimap (OpenCV GrabCut labels).
    regions : list of ndarray of shape (h, w), bool
        Disjoint regions covering the crop.
    prev_models : list or None
        Per region, the colour models to start from.
    pad : int
        Margin around each region's box, work pixels.
    config : SeededConfig

    Returns
    -------
    fg : ndarray of shape (h, w), float32
        Foreground probability.
    models : tuple
        Per region, its colour models.
    """
    fg = np.zeros(work_tri.shape, np.float32)
    out = []
    for r, region in enumerate(regions):
        fg_r, m_r = _cut_region(work_img, work_tri, region, None if prev_models is None
                                else prev_models[r], pad, config)
        fg[region] = fg_r[region]
        out.append(m_r)
    return fg, tuple(out)


class SeededSegmenter:
    """Subject masks from an image and the subject's 2D pose (module docstring).

    Parameters
    ----------
    config : SeededConfig, optional
    observer : Observer, optional
        Gets a ``mask`` report (``name="seeded/trimap"``, the trimap scaled to 0-255) and a
        ``mask`` report (``name="seeded/mask"``) per call when ``camera`` is given.

    Examples
    --------
    >>> seg = SeededSegmenter()                                     # doctest: +SKIP
    >>> prev = None
    >>> for t, image in enumerate(frames):                          # doctest: +SKIP
    ...     prev = seg.segment(image, joints2d[t], weights[t], previous=prev)
    ...     masks.append(prev.mask)
    """

    def __init__(self, config: SeededConfig | None = None, observer=None):
        self.config = config or SeededConfig()
        self.observer = as_observer(observer)

    def segment(self, image: np.ndarray, joints2d: np.ndarray, weights: np.ndarray | None = None, *,
                previous: SeededMask | np.ndarray | None = None, others=(), allowed: np.ndarray | None = None,
                camera: str | None = None, frame: int | None = None) -> SeededMask:
        """Segment the subject in one image.

        Parameters
        ----------
        image : ndarray of shape (H, W, 3), uint8
            RGB.
        joints2d : ndarray of shape (14, 2)
            The subject's joints in this image, pixels, NaN = missing (a detector's keypoints mapped
            with :func:`toolkit.skeleton.mappings.to_skeleton14`, or a 3D pose projected).
        weights : ndarray of shape (14,), optional
            Confidences in [0, 1], 0 = missing.
        previous : SeededMask or ndarray of shape (H, W) bool, optional
            The previous frame's result (or mask) of the same camera.  With ``config.carry_models``
            its colour models start GrabCut's; its mask joins the probable subject inside the band
            (which only matters when the sure subject is too small to learn a model from).
        others : sequence of ndarray of shape (14, 2)
            Other people's joints (sure background outside the subject's probable region).
        allowed : ndarray of shape (H, W) bool, optional
            Where the subject may be (e.g. the visual hull of the other views projected,
            :func:`refine_masks`); outside is sure background.
        camera, frame : optional
            Where to report (observer).

        Returns
        -------
        SeededMask
        """
        cfg = self.config
        img = check_rgb(image, "image")
        h, w = img.shape[:2]
        j, wts = _check_joints(joints2d, weights)
        s = body_scale(j, wts)
        prev_mask, models, allowed = _previous_and_allowed(previous, allowed, (h, w))
        mask = np.zeros((h, w), bool)
        tri = np.full((h, w), cv2.GC_BGD, np.uint8)
        out_models: tuple = ()
        seen = wts > 0
        if np.isfinite(s) and seen.any():
            # the crop around the body (probable region and band), worked on at most work_side_px
            m = (cfg.band + cfg.probable_scale * max(BONE_HALF_WIDTHS.values()) + FOOT_RADIUS + HAND_REACH) * s
            lo, hi = j[seen].min(0) - m, j[seen].max(0) + m
            x0, y0 = max(int(np.floor(lo[0])), 0), max(int(np.floor(lo[1])), 0)
            x1, y1 = min(int(np.ceil(hi[0])) + 1, w), min(int(np.ceil(hi[1])) + 1, h)
            if x1 > x0 and y1 > y0:
                f = min(1.0, cfg.work_side_px / max(y1 - y0, x1 - x0))
                size = (max(int(round((x1 - x0) * f)), 1), max(int(round((y1 - y0) * f)), 1))

                def to_work(p):  # full-image pixels -> work pixels (pixel-centre convention)
                    return (np.asarray(p, float) - [x0, y0] + 0.5) * f - 0.5

                work_tri = seed_trimap(size[::-1], to_work(j), wts, cfg, scale_px=s * f,
                                       others=[to_work(o) for o in others])
                crop_img = img[y0:y1, x0:x1]
                work_img = cv2.resize(crop_img, size, interpolation=cv2.INTER_AREA) if f < 1 else crop_img

                def crop_to_work(a):
                    c = a[y0:y1, x0:x1].astype(np.uint8)
                    return (cv2.resize(c, size, interpolation=cv2.INTER_NEAREST) if f < 1 else c) > 0

                if prev_mask is not None:
                    work_tri[(work_tri == cv2.GC_PR_BGD) & crop_to_work(prev_mask)] = cv2.GC_PR_FGD
                if allowed is not None:
                    work_tri[~crop_to_work(allowed) & (work_tri != cv2.GC_FGD)] = cv2.GC_BGD
                tri[y0:y1, x0:x1] = cv2.resize(work_tri, (x1 - x0, y1 - y0), interpolation=cv2.INTER_NEAREST)
                regions = _regions(size, to_work(j), wts > 0) if cfg.local_models else [np.ones(size[::-1], bool)]
                prev_models = (list(models) if cfg.carry_models and models is not None and len(models) == len(regions)
                               else None)
                fg, out_models = _cut_regions(work_img, work_tri, regions, prev_models,
                                              max(int(round(CROP_PAD * s * f)), 4), cfg)
                if f < 1:
                    fg = cv2.resize(fg, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
                crop = fg > 0.5
                crop_tri = tri[y0:y1, x0:x1]
                crop[crop_tri == cv2.GC_BGD] = False
                crop[crop_tri == cv2.GC_FGD] = True
                mask[y0:y1, x0:x1] = crop
                mask = _keep_seeded_components(mask, tri == cv2.GC_FGD, cfg.min_component_fraction)
        if camera is not None:
            self.observer.report("mask", camera=camera, mask=(tri * 85).astype(np.uint8), name="seeded/trimap",
                                 **({} if frame is None else {"frame": frame}))
            self.observer.report("mask", camera=camera, mask=mask, name="seeded/mask",
                                 **({} if frame is None else {"frame": frame}))
        return SeededMask(mask=mask, trimap=tri, scale_px=s, models=out_models)

    def segment_views(self, images: dict[str, np.ndarray], joints2d: dict[str, np.ndarray],
                      weights: dict[str, np.ndarray] | None = None, *, rig: Rig | None = None,
                      joints3d: np.ndarray | None = None, others: dict | None = None,
                      previous: dict[str, SeededMask] | None = None, refine: RefineConfig | None = None,
                      frame: int | None = None) -> tuple[dict[str, np.ndarray], dict[str, SeededMask]]:
        """Segment one frame in every camera, then carve the masks across views.

        Parameters
        ----------
        images : dict of str to ndarray of shape (H, W, 3) uint8
            RGB frame per camera name.
        joints2d : dict of str to ndarray of shape (14, 2)
            The subject's joints per camera, pixels, NaN = missing (a camera without an entry, or
            with no joint, gets an empty mask).
        weights : dict of str to ndarray of shape (14,), optional
            Confidences per camera.
        rig : Rig, optional
            With ``joints3d``: the masks are carved by :func:`refine_masks` (two cameras or more).
        joints3d : ndarray of shape (J, 3), optional
            The subject's 3D joints, metres.
        others : dict of str to sequence of ndarray of shape (14, 2), optional
            Other people's joints per camera.
        previous : dict of str to SeededMask, optional
            The previous frame's results per camera (the second return value of the previous call).
        refine : RefineConfig, optional
        frame : int, optional
            For the observer.

        Returns
        -------
        masks : dict of str to ndarray of shape (H, W) bool
            Carved when ``rig`` and ``joints3d`` are given.
        results : dict of str to SeededMask
            The uncarved results, for ``previous`` of the next frame.
        """
        results = {}
        for c, img in images.items():
            j = joints2d.get(c)
            if j is None:
                j = np.full((len(JOINTS_14), 2), np.nan)
            results[c] = self.segment(img, j, None if weights is None else weights.get(c),
                                      previous=None if previous is None else previous.get(c),
                                      others=() if others is None else others.get(c, ()), camera=c, frame=frame)
        masks = {c: r.mask for c, r in results.items()}
        if rig is not None and joints3d is not None and len(masks) >= 2 \
                and np.sum(np.all(np.isfinite(np.asarray(joints3d, float)), -1)) >= 2:
            masks = refine_masks(masks, rig, joints3d, refine, observer=self.observer, frame=frame)
        return masks, results

    def segment_sequence(self, frames, joints2d: np.ndarray, weights: np.ndarray | None = None, *,
                         camera: str | None = None) -> np.ndarray:
        """Segment a camera's frames in order, each seeded by the previous result.

        Parameters
        ----------
        frames : iterable of ndarray of shape (H, W, 3) uint8
        joints2d : ndarray of shape (T, 14, 2)
            Pixels, NaN = missing.
        weights : ndarray of shape (T, 14), optional
        camera : str, optional

        Returns
        -------
        ndarray of shape (T, H, W), bool
        """
        j = np.asarray(joints2d, float)
        if j.ndim != 3 or j.shape[1:] != (len(JOINTS_14), 2):
            raise InputError("joints2d", f"an array of shape (T, {len(JOINTS_14)}, 2)", f"shape {j.shape}")
        wts = None if weights is None else np.asarray(weights, float)
        if wts is not None and wts.shape != j.shape[:2]:
            raise InputError("weights", f"an array of shape {j.shape[:2]}", f"shape {wts.shape}")
        out, prev = [], None
        for t, img in enumerate(frames):
            if t >= len(j):
                break
            prev = self.segment(img, j[t], None if wts is None else wts[t], previous=prev, camera=camera, frame=t)
            out.append(prev.mask)
        if len(out) != len(j):
            raise InputError("frames", f"{len(j)} frames (as joints2d)", f"{len(out)}")
        return np.stack(out)


# --------------------------------------------------------------------------- across views

#: Voxel edge of the visual hull, metres: finer than a forearm's width.
VOXEL_M = 0.02
#: The hull's box is the 3D joints' box grown by this, metres (head top, hands, feet, flesh).
HULL_MARGIN_M = 0.3
#: Other views' masks are grown by this many pixels before carving (calibration error, mask edges).
MASK_TOLERANCE_PX = 3


#: A voxel seen by at least VOTE_FROM other views stays in the hull when at most MAX_MISSES of
#: their masks miss it: one view's mask that lost a foot (or a head) does not carve it from all
#: the others.  Seen by fewer views, every mask must hold it.
MAX_MISSES = 1
VOTE_FROM = 3


@dataclass(frozen=True)
class RefineConfig:
    """Options of :func:`refine_masks`; defaults :data:`VOXEL_M`, :data:`HULL_MARGIN_M`,
    :data:`MASK_TOLERANCE_PX`, :data:`MAX_MISSES`, :data:`VOTE_FROM`."""

    voxel_m: float = VOXEL_M
    margin_m: float = HULL_MARGIN_M
    mask_tolerance_px: int = MASK_TOLERANCE_PX
    max_misses: int = MAX_MISSES
    vote_from: int = VOTE_FROM

    def __post_init__(self):
        for name in ("voxel_m", "margin_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"RefineConfig.{name}", "a finite value > 0", repr(v))
        for name in ("mask_tolerance_px", "max_misses", "vote_from"):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < 0:
                raise InputError(f"RefineConfig.{name}", "an integer >= 0", repr(v))


def refine_masks(masks: dict[str, np.ndarray], rig: Rig, joints3d: np.ndarray, config: RefineConfig | None = None,
                 *, observer=None, frame: int | None = None) -> dict[str, np.ndarray]:
    """Carve each view's mask with the visual hull of the other views' masks around the 3D pose.

    A voxel of the box around ``joints3d`` is inside the hull seen without camera ``c`` when it
    projects inside the (slightly grown) mask of every other camera that sees it (all but
    ``max_misses`` of them when ``vote_from`` or more see it); camera ``c``'s
    refined mask keeps the pixels of its mask covered by those voxels' projections.  A pixel
    whose ray misses the other views' masks, or leaves the box around the body (a bystander,
    a patch of floor), becomes background.  An empty mask (a camera that lost the pose) carves
    nothing.

    Parameters
    ----------
    masks : dict of str to ndarray of shape (H, W) bool
        One mask per camera name of ``rig`` (at least two).
    rig : Rig
        The cameras (their sizes are the masks' shapes).
    joints3d : ndarray of shape (J, 3)
        The subject's joints, metres, NaN = missing (at least two finite).
    config : RefineConfig, optional
    observer : Observer, optional
        Gets a ``points3d`` report (``name="seeded/hull"``, the voxels inside every mask) and a
        ``mask`` report per camera (``name="seeded/refined"``).
    frame : int, optional

    Returns
    -------
    dict of str to ndarray of shape (H, W) bool
        The refined masks (subsets of the given ones).

    Raises
    ------
    InputError
        Masks of unknown cameras or of the wrong shape, fewer than two cameras, no 3D joints.
    """
    cfg = config or RefineConfig()
    obs = as_observer(observer)
    names = list(masks)
    if len(names) < 2:
        raise InputError("masks", "masks of at least two cameras", f"{len(names)}")
    ms = {}
    for n in names:
        if n not in rig.names:
            raise InputError("masks", f"masks named after cameras {rig.names}", repr(n))
        m = np.asarray(masks[n], bool)
        cam = rig[n]
        if m.shape != (cam.height, cam.width):
            raise InputError(f"masks[{n!r}]", f"shape {(cam.height, cam.width)} (camera {n!r})", f"{m.shape}")
        ms[n] = m
    j = np.asarray(joints3d, float)
    if j.ndim != 2 or j.shape[1] != 3:
        raise InputError("joints3d", "an array of shape (J, 3) metres", f"shape {j.shape}")
    j = j[np.all(np.isfinite(j), 1)]
    if len(j) < 2:
        raise InputError("joints3d", "at least two finite joints", f"{len(j)}")
    lo, hi = j.min(0) - cfg.margin_m, j.max(0) + cfg.margin_m
    axes = [np.arange(lo[k], hi[k] + cfg.voxel_m / 2, cfg.voxel_m) for k in range(3)]
    vox = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    inside, seen, pix = {}, {}, {}
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * cfg.mask_tolerance_px + 1,) * 2)
    for n in names:
        cam = rig[n]
        uv = cam.project(vox)
        front = cam.depth_of(vox) > 0
        ui, vi = np.round(uv[:, 0]).astype(np.int64), np.round(uv[:, 1]).astype(np.int64)
        vis = front & (ui >= 0) & (ui < cam.width) & (vi >= 0) & (vi < cam.height) & np.all(np.isfinite(uv), 1)
        grown = cv2.dilate(ms[n].astype(np.uint8), kernel) > 0
        ins = np.zeros(len(vox), bool)
        ins[vis] = grown[vi[vis], ui[vis]]
        inside[n], seen[n], pix[n] = ins, vis, (ui, vi)
    out = {}
    everywhere = np.ones(len(vox), bool)
    for n in names:
        others = [o for o in names if o != n and ms[o].any()]  # an empty mask (no pose) says nothing
        misses = np.sum([seen[o] & ~inside[o] for o in others], 0) if others else np.zeros(len(vox), int)
        n_seen = np.sum([seen[o] for o in others], 0) if others else np.zeros(len(vox), int)
        keep = seen[n] & (misses <= np.where(n_seen >= cfg.vote_from, cfg.max_misses, 0))
        if ms[n].any():
            everywhere &= inside[n] | ~seen[n]
        cam = rig[n]
        ui, vi = pix[n]
        splat = np.zeros((cam.height, cam.width), np.uint8)
        splat[vi[keep], ui[keep]] = 1
        if keep.any():
            depth = cam.depth_of(vox[keep])
            r = int(np.ceil(0.75 * cam.K[0, 0] * cfg.voxel_m / max(depth.min(), 1e-6)))
            splat = cv2.dilate(splat, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
        out[n] = ms[n] & (splat > 0)
        obs.report("mask", camera=n, mask=out[n], name="seeded/refined", **({} if frame is None else {"frame": frame}))
    obs.report("points3d", points=vox[everywhere], name="seeded/hull", **({} if frame is None else {"frame": frame}))
    return out
