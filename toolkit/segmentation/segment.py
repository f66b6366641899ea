"""Body-part segmentation of one frame in one camera (source 000 §2.3, claim 14).

1. Fit the template to the joints (:func:`toolkit.template.fit_template_pose`)
   and project it thinned and thickened (:meth:`toolkit.template.Template.project`).
2. Silhouette pixels with the same non-zero label in both projections are
   *confident*; the rest of the silhouette is *uncertain*.
3. One Gaussian mixture per part from the confident pixels' colours
   (:func:`toolkit.segmentation.colour.fit_part_models`).
4. Uncertain pixels are labelled by colour alone (``rule="colour"``: the part
   whose model gives the highest likelihood) or by colour then nearest part
   (``rule="colour_then_nearest"``: of the parts whose likelihood is within
   ``colour_margin`` nats of the best, the nearest to the pixel; parts of the
   same colour, such as the two forearms, are told apart by position).  The
   distance is to the part's projected template (``spatial_anchor``; the
   source measured it to the part's confident pixels).  A third rule,
   ``"posterior"``, adds a clipped colour evidence to a Gaussian log-prior of
   the distance (:mod:`toolkit.segmentation.prior`); measured worse, kept for
   the benchmark's sweep.
5. A morphological closing per part, painted back to front in the template's
   depth order (so a closed front part covers the part behind it), removes
   outliers.

Every silhouette pixel gets a label.  Parts with no model are listed in the
result; when no part has a model the uncertain pixels take the nearest
template part, and when even the template is not visible they take the torso.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.observe import as_observer
from toolkit.segmentation.colour import COLOUR_SPACES, PartColourModels, colour_features, fit_part_models
from toolkit.segmentation.plate import refine_silhouette
from toolkit.segmentation.prior import (
    colour_confusion,
    colour_evidence,
    confusion_evidence,
    smooth_evidence,
    spatial_log_prior,
    template_distances,
)
from toolkit.skeleton import SKELETON_14
from toolkit.template import (
    THIN_THICK_FRACTION,
    PoseDatabase,
    Template,
    TemplatePose,
    TemplateProjection,
    disc,
    fit_template_pose,
)

#: Labelling rules for the uncertain pixels.
RULES = ("colour", "colour_then_nearest", "posterior")
#: What distances to a part are measured to (see :class:`SegmentationConfig`).
SPATIAL_ANCHORS = ("template", "confident")
#: Colour evidence of the ``posterior`` rule (:mod:`toolkit.segmentation.prior`).
COLOUR_EVIDENCE = ("ratio", "confusion")
#: Default colour space and mixture size (measured, docs/stage2_segmentation.md).
DEFAULT_COLOUR_SPACE = "rgb"
DEFAULT_COMPONENTS = 3
#: Label given when neither a colour model nor the template says anything (torso).
FALLBACK_PART = 1 + SKELETON_14.part_names.index("torso")


@dataclass(frozen=True)
class SegmentationConfig:
    """Settings of :func:`segment_frame`.

    Attributes
    ----------
    colour_space : str
        One of :data:`toolkit.segmentation.colour.COLOUR_SPACES`.
    n_components : int
        Gaussian-mixture components per part.
    min_pixels : int
        Confident pixels a part needs for a model.
    max_pixels : int
        Confident pixels per part used to fit (random subset).
    reg_covar : float
        Added to the mixtures' covariance diagonals (feature units squared):
        the smallest colour spread a component may have.
    rule : str
        ``"colour"`` or ``"colour_then_nearest"`` (see the module docstring).
    colour_margin : float
        Log-likelihood margin (nats) of the ``colour_then_nearest`` rule.
    thin_thick_fraction : float
        Thinning / thickening radius as a fraction of the subject's image height.
    closing_fraction : float
        Closing radius as a fraction of the subject's image height (0 = no closing).
    spatial_anchor : str
        What an uncertain pixel's distance to a part is measured to:
        ``"template"`` (the part's projected template, default) or
        ``"confident"`` (the part's confident pixels, the source's choice;
        parts without a colour model use the template either way).  Measured
        on a randomised zoo from stage-1 joints: the template gives a median
        part mIoU 0.866 against 0.848 (docs/stage2_segmentation.md): the
        confident pixels are the template thinned *and* cut by the
        silhouette, so near a part's border the thinning, not the part,
        decides which part is nearest.
    plate_min_contrast : float
        With a background plate: smallest distance (feature units; RGB in
        [0, 1]) between the subject's colour and the plate's for a border
        pixel to be judged (:mod:`toolkit.segmentation.plate`).
    plate_ring_px : int
        With a background plate: width of the ring outside the silhouette
        whose subject-like pixels join it, pixels (0: measured best).
    plate_fill_template : bool
        With a background plate: pixels of the thinned template outside the
        silhouette join it unless their colour says plate (where kit and plate
        are alike, the template decides).
    plate_leave_alpha, plate_join_alpha : float
        With a background plate: opacity below which a silhouette pixel
        leaves, and at or above which a candidate pixel joins.
    spatial_sigma_fraction : float
        ``posterior`` rule: standard deviation of the template's placement
        error, as a fraction of the subject's image height
        (:mod:`toolkit.segmentation.prior`).
    colour_cap : float
        ``posterior`` rule: largest colour evidence counted against a part, nats.
    colour_evidence : str
        ``posterior`` rule: ``"ratio"`` (log-likelihood ratio to the best
        part's mixture) or ``"confusion"`` (how often the confident pixels of
        each part have each part's mixture as their best one: parts of one
        colour give each other no evidence).
    smooth_fraction : float
        ``posterior`` rule: the colour evidence is averaged over a Gaussian of
        this standard deviation (fraction of the subject's image height; 0 = per pixel).
    relabel_confident : bool
        ``posterior`` rule: the confident pixels are relabelled too (their
        template label is then a prior, not a fixed label).
    seed : int
        Seeds the pixel subsampling and the mixtures' initialisation.
    """

    colour_space: str = DEFAULT_COLOUR_SPACE
    n_components: int = DEFAULT_COMPONENTS
    min_pixels: int = 30
    max_pixels: int = 1500
    reg_covar: float = 1e-4
    rule: str = "colour_then_nearest"
    colour_margin: float = 100.0
    thin_thick_fraction: float = THIN_THICK_FRACTION
    closing_fraction: float = 0.008
    spatial_anchor: str = "template"
    plate_min_contrast: float = 0.1
    plate_ring_px: int = 0
    plate_fill_template: bool = True
    plate_leave_alpha: float = 0.5
    plate_join_alpha: float = 0.5
    spatial_sigma_fraction: float = 0.03
    colour_cap: float = 3.0
    colour_evidence: str = "ratio"
    smooth_fraction: float = 0.0
    relabel_confident: bool = False
    seed: int = 0

    def __post_init__(self):
        if self.colour_space not in COLOUR_SPACES:
            raise InputError("SegmentationConfig.colour_space", f"one of {list(COLOUR_SPACES)}",
                             repr(self.colour_space))
        if self.rule not in RULES:
            raise InputError("SegmentationConfig.rule", f"one of {list(RULES)}", repr(self.rule))
        if self.n_components < 1:
            raise InputError("SegmentationConfig.n_components", "at least 1", repr(self.n_components))
        if self.spatial_anchor not in SPATIAL_ANCHORS:
            raise InputError("SegmentationConfig.spatial_anchor", f"one of {list(SPATIAL_ANCHORS)}",
                             repr(self.spatial_anchor))
        if self.colour_evidence not in COLOUR_EVIDENCE:
            raise InputError("SegmentationConfig.colour_evidence", f"one of {list(COLOUR_EVIDENCE)}",
                             repr(self.colour_evidence))
        if not (self.spatial_sigma_fraction > 0 and self.colour_cap >= 0 and self.smooth_fraction >= 0):
            raise InputError("SegmentationConfig", "spatial_sigma_fraction > 0, colour_cap >= 0, smooth_fraction >= 0",
                             f"{self.spatial_sigma_fraction}, {self.colour_cap}, {self.smooth_fraction}")
        if self.thin_thick_fraction < 0 or self.closing_fraction < 0 or self.colour_margin < 0:
            raise InputError("SegmentationConfig", "non-negative fractions and margin",
                             f"{self.thin_thick_fraction}, {self.closing_fraction}, {self.colour_margin}")


@dataclass(frozen=True)
class SegmentationResult:
    """Part labels of one frame in one camera.

    Attributes
    ----------
    labels : ndarray of shape (H, W), uint8
        Final part ids (1..10, ids of ``groundtruth/parts``), 0 outside the silhouette.
    confident : ndarray of shape (H, W), bool
        Silhouette pixels with the same label in the thinned and thickened template.
    template_depth : ndarray of shape (H, W), float32
        Camera-frame depth of the posed template, metres (NaN where it is not seen).
    parts_without_model : tuple of int
        Part ids without a colour model (no or too few confident pixels).
    template_labels : ndarray of shape (H, W), uint8
        The projected template (neither thinned nor thickened).
    colour_labels : ndarray of shape (H, W), uint8
        Labels before the closing.
    pose : TemplatePose
        The fitted pose the template was posed with.
    models : PartColourModels
    """

    labels: np.ndarray
    confident: np.ndarray
    template_depth: np.ndarray
    parts_without_model: tuple
    template_labels: np.ndarray = field(repr=False, default=None)
    colour_labels: np.ndarray = field(repr=False, default=None)
    pose: TemplatePose = field(repr=False, default=None)
    models: PartColourModels = field(repr=False, default=None)

    @property
    def confident_labels(self) -> np.ndarray:
        """Labels of the confident pixels only (0 elsewhere), (H, W) uint8."""
        return np.where(self.confident, self.colour_labels, 0).astype(np.uint8)


def _nearest_label(seeds: np.ndarray) -> np.ndarray:
    """Per pixel, the label of the nearest non-zero pixel of ``seeds`` (H, W) uint8."""
    from scipy.ndimage import distance_transform_edt

    if not (seeds > 0).any():
        return np.zeros_like(seeds)
    _, (iy, ix) = distance_transform_edt(seeds == 0, return_indices=True)
    return seeds[iy, ix]


def _box(mask: np.ndarray, pad: int) -> tuple[slice, slice]:
    ys, xs = np.nonzero(mask)
    h, w = mask.shape
    if len(ys) == 0:
        return slice(0, 0), slice(0, 0)
    return (slice(max(0, ys.min() - pad), min(h, ys.max() + pad + 1)),
            slice(max(0, xs.min() - pad), min(w, xs.max() + pad + 1)))


def label_uncertain(ll: np.ndarray, rule: str, margin: float, distances: np.ndarray | None = None) -> np.ndarray:
    """Part index (0-based) per uncertain pixel.

    Parameters
    ----------
    ll : ndarray of shape (N, P)
        Log-likelihood per part (``-inf`` = the part is not a candidate).
    rule : str
        One of :data:`RULES`.
    margin : float
        ``colour_then_nearest``: nats below the best likelihood a part may be and
        still be a candidate.
    distances : ndarray of shape (N, P), optional
        Pixel distance to each part (needed by ``colour_then_nearest``).

    Returns
    -------
    ndarray of shape (N,), int
    """
    if rule == "colour":
        return ll.argmax(1)
    if distances is None or distances.shape != ll.shape:
        raise InputError("label_uncertain: distances", f"an array of shape {ll.shape}",
                         "None" if distances is None else f"shape {distances.shape}")
    if rule == "colour_then_nearest":
        top = ll.max(1, keepdims=True)
        d = np.where(ll >= top - margin, distances, np.inf)
        return d.argmin(1)
    raise InputError("label_uncertain: rule", f"one of {list(RULES)}", repr(rule))


def _label_posterior(feats, sil, confident, uncertain, labels, template_labels, models, height_px, config):
    """Labels of the ``posterior`` rule in the silhouette's box (see :mod:`toolkit.segmentation.prior`)."""
    n_parts = len(SKELETON_14.parts)
    out = labels.copy()
    sel = sil if config.relabel_confident else uncertain
    if not sel.any():
        return out
    anchor = np.where(confident, labels, 0) if config.spatial_anchor == "confident" else template_labels
    prior = spatial_log_prior(template_distances(anchor, n_parts)[sel],
                              max(1.0, config.spatial_sigma_fraction * height_px))
    smooth = config.smooth_fraction * height_px
    at = sil if smooth > 0 else sel
    ll = models.log_likelihood(feats[at])
    if config.colour_evidence == "confusion":
        C = colour_confusion(models.log_likelihood(feats[confident]), labels[confident], n_parts)
        ev = np.maximum(confusion_evidence(ll, C), -config.colour_cap)
    else:
        ev = colour_evidence(ll, config.colour_cap)
    if smooth > 0:
        E = np.zeros(sil.shape + (n_parts,), np.float32)
        E[sil] = ev
        ev = smooth_evidence(E, sil, smooth)[sel]
    score = ev + prior
    out[sel] = np.where(np.isfinite(score.max(1)), score.argmax(1) + 1, FALLBACK_PART).astype(np.uint8)
    return out


def _frame_inputs(image, silhouette, joints3d, camera: Camera, plate):
    """Check the inputs of :func:`segment_frame`.

    Parameters
    ----------
    image, silhouette, joints3d, camera, plate
        As :func:`segment_frame`.

    Returns
    -------
    img : ndarray of shape (H, W, 3), uint8
    sil : ndarray of shape (H, W), bool
    X : ndarray of shape (14, 3) or None
        The joints, None when not given or all missing.
    plate : ndarray of shape (H, W, 3), uint8, or None

    Raises
    ------
    InputError
        Shapes or dtypes wrong.
    """
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError("segment_frame: image", "an (H, W, 3) uint8 RGB image", f"shape {img.shape} {img.dtype}")
    sil = np.asarray(silhouette)
    if sil.shape != img.shape[:2]:
        raise InputError("segment_frame: silhouette", f"shape {img.shape[:2]}", f"shape {sil.shape}")
    sil = sil.astype(bool)
    if plate is not None:
        plate = np.asarray(plate)
        if plate.shape != img.shape or plate.dtype != np.uint8:
            raise InputError("segment_frame: plate", f"a {img.shape} uint8 RGB image",
                             f"shape {plate.shape} {plate.dtype}")
    if (camera.height, camera.width) != img.shape[:2]:
        raise InputError("segment_frame: camera", f"image size {img.shape[1::-1]}", f"size {camera.size}")
    X = None
    if joints3d is not None:
        X = np.asarray(joints3d, float)
        if X.shape != (14, 3):
            raise InputError("segment_frame: joints3d", "an array of shape (14, 3)", f"shape {X.shape}")
        if not np.isfinite(X).any():
            X = None
    return img, sil, X, plate


def _label_uncertain_pixels(feats: np.ndarray, unc_b: np.ndarray, lab_b: np.ndarray, tmpl_b: np.ndarray,
                            models, n_parts: int, config: SegmentationConfig) -> np.ndarray:
    """Label the uncertain pixels by colour with the rules other than ``"posterior"``.

    Parameters
    ----------
    feats : ndarray of shape (h, w, F)
        Colour features of the silhouette's box.
    unc_b : ndarray of shape (h, w), bool
        Uncertain pixels of the box (at least one).
    lab_b : ndarray of shape (h, w), uint8
        Labels of the box (confident pixels labelled); written in place.
    tmpl_b : ndarray of shape (h, w), uint8
        The template's labels of the box.
    models : PartColourModels
    n_parts : int
    config : SegmentationConfig

    Returns
    -------
    ndarray of shape (h, w), uint8
        ``lab_b`` with the uncertain pixels labelled (part ids 1..n_parts).
    """
    if models.models:
        ll = models.log_likelihood(feats[unc_b])  # -inf for parts without a model
        dist = None
        if config.rule == "colour_then_nearest":
            # parts without a model stay candidates where the template puts them: colour score
            # the best modelled part's minus the margin, distance to their template pixels
            ll = np.where(np.isfinite(ll), ll, ll.max(1, keepdims=True) - config.colour_margin)
            dist = np.full(ll.shape, np.inf)
            for p in range(1, n_parts + 1):
                own = p in models.models and config.spatial_anchor == "confident"
                seed = (lab_b == p) if own else (tmpl_b == p)
                if seed.any():
                    dt = cv2.distanceTransform((~seed).astype(np.uint8), cv2.DIST_L2, 3)
                    dist[:, p - 1] = dt[unc_b]
        lab_b[unc_b] = (label_uncertain(ll, config.rule, config.colour_margin, dist) + 1).astype(np.uint8)
    else:
        near = _nearest_label(tmpl_b)
        lab_b[unc_b] = near[unc_b] if near.any() else FALLBACK_PART
    return lab_b


def _close_parts(labels_b: np.ndarray, sb: np.ndarray, part_depth: np.ndarray, r_close: int) -> np.ndarray:
    """Close each part's label mask with a disc, back to front, inside the silhouette.

    Parameters
    ----------
    labels_b : ndarray of shape (h, w), uint8
        Part labels of the silhouette's box.
    sb : ndarray of shape (h, w), bool
        The silhouette in the box.
    part_depth : ndarray of shape (n_parts,)
        Depth of each part, metres (non-finite: unseen).
    r_close : int
        Radius of the disc, pixels (> 0).

    Returns
    -------
    ndarray of shape (h, w), uint8
        The closed labels (nearer parts drawn over farther ones).
    """
    k = disc(r_close)
    depth_rank = np.where(np.isfinite(part_depth), part_depth, np.inf)
    order = np.argsort(-depth_rank, kind="stable")  # far first; unseen parts (inf) first of all
    out_b = labels_b.copy()
    cur_b = labels_b
    for i in order:
        p = i + 1
        m = (cur_b == p).astype(np.uint8)
        if not m.any():
            continue
        closed = cv2.morphologyEx(m, cv2.MORPH_CLOSE, k) > 0
        out_b[closed & sb] = p
    return out_b


def _part_models(feats: np.ndarray, conf_b: np.ndarray, thin_b: np.ndarray, n_parts: int,
                 config: SegmentationConfig):
    """Colour models of the parts from their confident pixels.

    Parameters
    ----------
    feats : ndarray of shape (h, w, F)
        Colour features of the silhouette's box.
    conf_b : ndarray of shape (h, w), bool
        Confident pixels of the box.
    thin_b : ndarray of shape (h, w), uint8
        The thinned template's labels of the box.
    n_parts : int
    config : SegmentationConfig

    Returns
    -------
    PartColourModels
    """
    return fit_part_models(feats[conf_b], thin_b[conf_b], n_parts, n_components=config.n_components,
                           min_pixels=config.min_pixels, max_pixels=config.max_pixels,
                           reg_covar=config.reg_covar, space=config.colour_space, rng=config.seed)


def _plate_refined(sil_b: np.ndarray, feats: np.ndarray, plate_b: np.ndarray, models, thin_b: np.ndarray,
                   config: SegmentationConfig) -> np.ndarray:
    """The silhouette's border checked against the background plate (:mod:`toolkit.segmentation.plate`).

    Parameters
    ----------
    sil_b : ndarray of shape (h, w), bool
        The silhouette in its box.
    feats : ndarray of shape (h, w, F)
        Colour features of the image's box.
    plate_b : ndarray of shape (h, w, 3), uint8
        The plate's box.
    models : PartColourModels
    thin_b : ndarray of shape (h, w), uint8
        The thinned template's labels of the box.
    config : SegmentationConfig

    Returns
    -------
    ndarray of shape (h, w), bool
        The refined silhouette of the box.
    """
    return refine_silhouette(sil_b, feats, colour_features(plate_b, config.colour_space),
                             models, config.plate_min_contrast, config.plate_ring_px,
                             thin_b > 0 if config.plate_fill_template else None,
                             config.plate_leave_alpha, config.plate_join_alpha)


def _report_segmentation(obs, proj: TemplateProjection, confident: np.ndarray, uncertain: np.ndarray,
                         labels: np.ndarray, models, extra: dict) -> None:
    """Report the template's labels, the confident and uncertain masks, the parts and the colour models.

    Parameters
    ----------
    obs : Observer
    proj : TemplateProjection
    confident, uncertain : ndarray of shape (H, W), bool
    labels : ndarray of shape (H, W), uint8
        The final part labels.
    models : PartColourModels
    extra : dict
        Camera name and frame of the reports.
    """
    missing = models.parts_without_model
    names = SKELETON_14.part_names
    obs.report("labels", labels=proj.thin, name="segmentation/template_thin", **extra)
    obs.report("labels", labels=proj.thick, name="segmentation/template_thick", **extra)
    obs.report("mask", mask=confident, name="segmentation/confident", **extra)
    obs.report("mask", mask=uncertain, name="segmentation/uncertain", **extra)
    obs.report("labels", labels=labels, name="segmentation/parts", **extra)
    obs.report("text", name="segmentation/models", text=models.summary(names), **extra)
    obs.report("text", name="segmentation/parts_without_model",
               text=", ".join(names[p - 1] for p in missing) if missing else "(none)", **extra)


def _empty_result(shape: tuple[int, int], n_parts: int) -> SegmentationResult:
    """All background, every part without a model: no joints and an empty silhouette.

    Parameters
    ----------
    shape : tuple of int
        ``(H, W)``.
    n_parts : int

    Returns
    -------
    SegmentationResult
    """
    h, w = shape
    return SegmentationResult(np.zeros((h, w), np.uint8), np.zeros((h, w), bool),
                              np.full((h, w), np.nan, np.float32), tuple(range(1, n_parts + 1)),
                              np.zeros((h, w), np.uint8), np.zeros((h, w), np.uint8), None, None)


def _uncertain_labels(feats: np.ndarray, sil_b: np.ndarray, conf_b: np.ndarray, unc_b: np.ndarray,
                      lab_b: np.ndarray, tmpl_b: np.ndarray, models, hpx: float, n_parts: int,
                      config: SegmentationConfig) -> np.ndarray:
    """The labels of the silhouette's box with its uncertain pixels labelled by ``config.rule``.

    Parameters
    ----------
    feats : ndarray of shape (h, w, F)
        Colour features of the box.
    sil_b, conf_b, unc_b : ndarray of shape (h, w), bool
        Silhouette, confident and uncertain pixels of the box.
    lab_b : ndarray of shape (h, w), uint8
        Labels of the box (confident pixels labelled); may be written in place.
    tmpl_b : ndarray of shape (h, w), uint8
        The template's labels of the box.
    models : PartColourModels
    hpx : float
        The subject's height in the image, pixels.
    n_parts : int
    config : SegmentationConfig

    Returns
    -------
    ndarray of shape (h, w), uint8
    """
    if config.rule == "posterior":
        return _label_posterior(feats, sil_b, conf_b, unc_b, lab_b, tmpl_b, models, hpx, config)
    if unc_b.any():
        return _label_uncertain_pixels(feats, unc_b, lab_b, tmpl_b, models, n_parts, config)
    return lab_b


def segment_frame(image: np.ndarray, silhouette: np.ndarray, joints3d: np.ndarray | None, camera: Camera,
                  template: Template, config: SegmentationConfig = SegmentationConfig(), observer=None, *,
                  joints2d: np.ndarray | None = None, database: PoseDatabase | None = None,
                  frame: int | None = None, plate: np.ndarray | None = None) -> SegmentationResult:
    """Segment the subject's silhouette into body parts.

    Parameters
    ----------
    image : ndarray of shape (H, W, 3), uint8 RGB
    silhouette : ndarray of shape (H, W), bool
        The subject's pixels.
    joints3d : ndarray of shape (14, 3) or None
        World, metres, NaN = missing; the approximate pose of the exact fit.
    camera : Camera
        The view's camera corrected by stage 1's offsets (:func:`toolkit.multiview.corrected_rig`):
        its projection is where the subject appears in ``image``.
    template : Template
    config : SegmentationConfig
    observer : Observer, optional
        Receives ``labels`` (thinned and thickened template, final), ``mask`` (confident,
        uncertain), ``text`` (per-part model summaries, parts without a model).
    joints2d : ndarray of shape (14, 2), optional
        2D pose in this view (pixels, image coordinates, i.e. stage 1's
        offsets included); default: ``joints3d`` projected.  The template is fitted
        exactly onto it.
    database : PoseDatabase, optional
        For joints missing in ``joints3d`` (default: the motion-library database).
    frame : int, optional
        Frame index put on the observer's reports.
    plate : ndarray of shape (H, W, 3), uint8 RGB, optional
        The background alone (clean plate or stage 1's background model).
        When given, the silhouette's border is checked against it and the
        parts' colours (:mod:`toolkit.segmentation.plate`): plate-like pixels
        leave it, subject-like pixels of its outer ring join it; the labels
        then cover the refined silhouette.

    Returns
    -------
    SegmentationResult

    Raises
    ------
    InputError
        Shapes or dtypes wrong.  (No joints and an empty silhouette give an
        all-background result with every part listed as without a model.)
    """
    img, sil, X, plate = _frame_inputs(image, silhouette, joints3d, camera, plate)
    cam = camera
    obs = as_observer(observer)
    extra = {"camera": cam.name} | ({} if frame is None else {"frame": frame})
    n_parts = len(SKELETON_14.parts)

    no_joints = X is None and (joints2d is None or np.isfinite(np.asarray(joints2d, float)).all(-1).sum() < 3)
    if no_joints and not sil.any():  # nothing to fit to and nothing to label
        obs.report("text", name="segmentation/parts_without_model", text="(no joints, empty silhouette)", **extra)
        return _empty_result(sil.shape, n_parts)

    # 1. template
    pose = fit_template_pose(cam, joints2d, X, database, subject_height=template.height, silhouette=sil,
                             observer=observer, frame=frame)
    proj: TemplateProjection = template.project(pose.joints3d, cam, fraction=config.thin_thick_fraction)
    hpx = proj.height_px if proj.height_px > 0 else float(np.ptp(np.nonzero(sil)[0])) if sil.any() else 0.0

    # 2. confident / uncertain
    confident = sil & (proj.thin > 0) & (proj.thin == proj.thick)
    uncertain = sil & ~confident
    labels = np.where(confident, proj.thin, 0).astype(np.uint8)

    # 3. colour models (features only inside the silhouette's box)
    by, bx = _box(sil | (proj.labels > 0), 2)
    feats = colour_features(img[by, bx], config.colour_space)
    conf_b = confident[by, bx]
    models = _part_models(feats, conf_b, proj.thin[by, bx], n_parts, config)

    # 3b. the silhouette's border against the background plate (toolkit.segmentation.plate)
    if plate is not None and sil.any():
        sil = sil.copy()
        sil[by, bx] = _plate_refined(sil[by, bx], feats, plate[by, bx], models, proj.thin[by, bx], config)
        confident &= sil
        uncertain = sil & ~confident
        labels[~sil] = 0
        conf_b = confident[by, bx]

    # 4. uncertain pixels
    unc_b = uncertain[by, bx]
    labels[by, bx] = _uncertain_labels(feats, sil[by, bx], conf_b, unc_b, labels[by, bx], proj.labels[by, bx],
                                       models, hpx, n_parts, config)
    colour_labels = labels.copy()

    # 5. closing, back to front
    r_close = int(round(config.closing_fraction * hpx))
    if r_close > 0 and sil.any():
        labels[by, bx] = _close_parts(labels[by, bx], sil[by, bx], proj.part_depth, r_close)
    labels[~sil] = 0

    missing = models.parts_without_model
    _report_segmentation(obs, proj, confident, uncertain, labels, models, extra)
    return SegmentationResult(labels, confident, proj.depth.astype(np.float32), missing, proj.labels,
                              colour_labels, pose, models)


def part_iou(predicted: np.ndarray, truth: np.ndarray, n_parts: int = len(SKELETON_14.parts)) -> np.ndarray:
    """Intersection over union per part id 1..n_parts, (n_parts,); NaN where the part is in neither."""
    a = np.asarray(predicted)
    b = np.asarray(truth)
    if a.shape != b.shape:
        raise InputError("part_iou: predicted", f"shape {b.shape}", f"shape {a.shape}")
    out = np.full(n_parts, np.nan)
    for p in range(1, n_parts + 1):
        pa, pb = a == p, b == p
        u = np.count_nonzero(pa | pb)
        if u:
            out[p - 1] = np.count_nonzero(pa & pb) / u
    return out
