"""Configuration of the multi-view selection (source 000, §2.1 and claims 5-6).

Every default is defined once, here.  The constants of the source are named
after it; the others are engineering choices, each with its reason.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from toolkit.anthropometry import AnthropometricConstraints
from toolkit.errors import InputError

#: Source 000 §2.1: "the 2D offset needed to minimise the error measure can be up to 8 pixels".
SOURCE_MAX_OFFSET_PX = 8.0
#: Source 000 §2.1: the k = 3 best database silhouettes per view are combined.
SOURCE_K = 3

#: Hard bound on each offset component, pixels: twice the largest offset the source needed,
#: so the source's 8 px sit well inside the bound (the bound is smooth, ``B tanh(p / B)``,
#: and bends the offsets noticeably only beyond ~B/2).
MAX_OFFSET_PX = 2 * SOURCE_MAX_OFFSET_PX
#: Prior standard deviation of each offset component, pixels (a zero-mean Gaussian prior):
#: the source's 8 px taken as one sigma.  It removes the gauge freedom (a 3D translation of
#: the body shifts every view's joints almost uniformly, so the offsets are determined only
#: up to that shift) by picking the smallest offsets that explain the data.
OFFSET_PRIOR_PX = SOURCE_MAX_OFFSET_PX
#: Prior standard deviation of the offset of a camera refined on the field lines, pixels.
#: The refinement leaves 0.6 px mean and 1.25 px worst calibration error at the joints
#: (docs/calibration_refinement.md); with the 8 px prior the offsets absorbed the silhouette
#: database's 2D joint errors instead (1-3 px on cameras with no error left), which shifted
#: stage 1's body and, applied by stage 3, every billboard (docs/stage1_multiview.md).
REFINED_OFFSET_PRIOR_PX = 1.5
#: Prior standard deviation of the offsets' gauge component, pixels: the part of the offsets
#: that a 3D translation of the body would also explain (:func:`~toolkit.multiview.offsets.gauge_basis`).
#: For far (broadcast) cameras that direction is exactly flat and the offset prior alone picks
#: the smallest offsets; for near (studio, 3.5-5 m) cameras perspective makes it only nearly
#: flat, and the 2-5 px errors of the database's 2D joints pulled all views' offsets 10-16 px
#: the same way (the body moved 5-8 cm; zoo seed 13 studio scene with its true calibration:
#: 12 mm MPJPE without offsets, 53-75 mm with them).  A tight prior on that component leaves
#: the body where the rays put it (docs/stage1_multiview.md, "The offset gauge").
GAUGE_PRIOR_PX = 1.0
#: Standard deviation of a 2D joint, pixels, used to weigh the offset prior against the data.
KEYPOINT_SIGMA_PX = 2.0
#: Combinations refined by Levenberg-Marquardt, best first by their cost without offset
#: correction.  A wrong candidate (another pose, a left/right swap) costs tens of centimetres
#: of ray distance; an 8 px calibration error at broadcast distances costs a few centimetres,
#: so the right combination is always among the first few; 16 leaves a wide margin.
REFINE_TOP = 16
#: A plausible combination (3D skeleton within :data:`PLAUSIBLE_EXCESS` of the anthropometric
#: rules) is preferred to an implausible cheaper one when it costs at most this many times as much.
PLAUSIBLE_COST_RATIO = 3.0
#: Summed relative excess over the anthropometric rules still counted as plausible
#: (:meth:`toolkit.anthropometry.AnthropometricConstraints.excess`; noisy 2D candidates
#: break a limit by a few per cent).
PLAUSIBLE_EXCESS = 0.25
#: Refinement stops at the first combination (best first) whose cost without offsets exceeds
#: this multiple of the best refined cost.  On the Pose2Sim demo the offsets lower the right
#: combination's mean ray distance from 30 to 15 mm and wrong ones (a view flipped) by 4-5 %,
#: from 90 mm up; 3 keeps every combination that offsets could make the best.
REFINE_RATIO = 3.0
#: Largest number of combinations evaluated (k'^n_views); beyond it the call is refused.
MAX_COMBINATIONS = 200_000
#: Two combination costs closer than this (relative) are a tie, broken by the previous
#: frame's pose, then by fewer flipped views, then by the candidates' ranks.  Mirror
#: combinations (every view flipped the other way) have exactly the same cost.
TIE_RELATIVE = 1e-3
#: Mirror ties are broken by anatomy only when the limb bends say so by at least this much
#: (metres, summed over four limbs; a knee flexed by 15 degrees sits ~3 cm off its limb line).
CHIRALITY_MIN_M = 0.02
#: Robust mode: a view whose median reprojection error exceeds this (pixels) and
#: ``ROBUST_VIEW_RATIO`` times the median of the other views is dropped (needs >= 3 views).
ROBUST_VIEW_PX = 15.0
#: Robust mode: ratio of a view's median error to the others' before it is dropped.
ROBUST_VIEW_RATIO = 3.0
#: Robust mode: a single ray whose reprojection error exceeds this (pixels) is dropped
#: when its joint keeps at least two other rays.
ROBUST_RAY_PX = 25.0

#: Names of the left/right flips that can be added as extra candidates.
FLIP_MODES = ("all", "arms", "legs")
#: Residuals the Levenberg-Marquardt step can minimise.
RESIDUALS = ("reprojection", "ray")


@dataclass(frozen=True)
class MultiViewConfig:
    """Options of :func:`toolkit.multiview.select_multiview`.

    Parameters
    ----------
    flips : tuple of str
        Left/right flipped copies of every candidate added as extra candidates:
        ``"all"`` swaps every left joint with its right twin, ``"arms"`` only
        shoulders, elbows and wrists, ``"legs"`` only hips, knees and ankles.
        Empty: no flips.  The source relies on the combination search to resolve
        left/right ambiguity, so ``("all",)`` is the default.
    optimise_offsets : bool
        Optimise one 2D offset per view by Levenberg-Marquardt (source claim 6).
    residual : str
        ``"reprojection"`` (pixels, default) or ``"ray"`` (ray-to-point distances in
        metres, the source's measure).  See ``docs/stage1_multiview.md`` for the
        comparison; the selection cost is the mean ray distance either way.
    max_offset_px : float
        Smooth bound on each offset component, pixels.
    offset_prior_px : float
        Standard deviation of the zero-mean offset prior, pixels (``inf``: no prior).
    camera_offset_prior_px : tuple of (str, float)
        Per-camera overrides of ``offset_prior_px`` by camera name, e.g. the
        cameras refined on the field lines (:data:`REFINED_OFFSET_PRIOR_PX`,
        :meth:`with_offset_priors`).
    gauge_prior_px : float
        Standard deviation of the prior on the offsets' gauge component (the image shifts of
        a 3D translation of the body), pixels (``inf``: none, only ``offset_prior_px``).
    keypoint_sigma_px : float
        Standard deviation of a 2D joint, pixels.
    reference_view : int or None
        When set, that view's offset is held at zero (an alternative gauge).
    refine_top : int
        Most combinations refined by Levenberg-Marquardt, best first.
    refine_ratio : float
        Stop refining at the first combination whose cost without offsets exceeds this
        multiple of the best refined cost.
    max_combinations : int
        Refuse inputs with more combinations than this.
    tie_relative : float
        Relative cost difference below which two combinations tie.
    anatomy_tie_break : bool
        Break mirror ties by the limb bends (knees forward, elbows backward) before the
        number of flipped views.
    chirality_min_m : float
        Smallest limb-bend score (metres) trusted for that.
    up : tuple of float
        World up direction (the toolkit's world is z up).
    robust : bool
        Drop a view whose rays disagree with the others, and single outlying rays.
    robust_view_px, robust_view_ratio, robust_ray_px : float
        Thresholds of the robust mode.
    min_view_joints : int
        A view takes part only with at least this many joints shared with another view.
    constraints : AnthropometricConstraints or None
        Checked on the 3D result and reported (never a hard rejection); ``None``
        skips the check and the plausibility preference.
    plausible_cost_ratio : float
        When the cheapest refined combination's skeleton is implausible, a
        plausible one costing at most this many times as much is chosen instead
        (1 or less: pure ray cost, as in the source).
    plausible_excess : float
        Largest summed relative excess over the anthropometric rules counted as
        plausible (:meth:`~toolkit.anthropometry.AnthropometricConstraints.excess`).
    """

    flips: tuple[str, ...] = ("all",)
    optimise_offsets: bool = True
    residual: str = "reprojection"
    max_offset_px: float = MAX_OFFSET_PX
    offset_prior_px: float = OFFSET_PRIOR_PX
    camera_offset_prior_px: tuple[tuple[str, float], ...] = ()
    gauge_prior_px: float = GAUGE_PRIOR_PX
    keypoint_sigma_px: float = KEYPOINT_SIGMA_PX
    reference_view: int | None = None
    refine_top: int = REFINE_TOP
    refine_ratio: float = REFINE_RATIO
    max_combinations: int = MAX_COMBINATIONS
    tie_relative: float = TIE_RELATIVE
    anatomy_tie_break: bool = True
    chirality_min_m: float = CHIRALITY_MIN_M
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    robust: bool = False
    robust_view_px: float = ROBUST_VIEW_PX
    robust_view_ratio: float = ROBUST_VIEW_RATIO
    robust_ray_px: float = ROBUST_RAY_PX
    min_view_joints: int = 3
    constraints: AnthropometricConstraints | None = AnthropometricConstraints()
    plausible_cost_ratio: float = PLAUSIBLE_COST_RATIO
    plausible_excess: float = PLAUSIBLE_EXCESS

    def __post_init__(self):
        flips = tuple(self.flips)
        for f in flips:
            if f not in FLIP_MODES:
                raise InputError("MultiViewConfig.flips", f"names among {list(FLIP_MODES)}", repr(f))
        if len(set(flips)) != len(flips):
            raise InputError("MultiViewConfig.flips", "distinct flip names", repr(flips))
        object.__setattr__(self, "flips", flips)
        up = np.asarray(self.up, float)
        if up.shape != (3,) or not np.isfinite(up).all() or np.linalg.norm(up) == 0:
            raise InputError("MultiViewConfig.up", "a non-zero 3-vector", repr(self.up))
        object.__setattr__(self, "up", tuple(float(x) for x in up))
        if self.residual not in RESIDUALS:
            raise InputError("MultiViewConfig.residual", f"one of {list(RESIDUALS)}", repr(self.residual))
        if not (np.isfinite(self.plausible_cost_ratio) and np.isfinite(self.plausible_excess)
                and self.plausible_excess >= 0):
            raise InputError("MultiViewConfig.plausible_cost_ratio/plausible_excess", "finite values, excess >= 0",
                             f"{self.plausible_cost_ratio}, {self.plausible_excess}")
        if not self.refine_ratio >= 1:
            raise InputError("MultiViewConfig.refine_ratio", "a value >= 1 (inf: no early stop)",
                             repr(self.refine_ratio))
        for name in ("max_offset_px", "keypoint_sigma_px", "chirality_min_m", "robust_view_px", "robust_view_ratio",
                     "robust_ray_px"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"MultiViewConfig.{name}", "a finite value > 0", repr(v))
        if not self.offset_prior_px > 0:
            raise InputError("MultiViewConfig.offset_prior_px", "a value > 0 (inf: no prior)",
                             repr(self.offset_prior_px))
        if not self.gauge_prior_px > 0:
            raise InputError("MultiViewConfig.gauge_prior_px", "a value > 0 (inf: no gauge prior)",
                             repr(self.gauge_prior_px))
        try:
            pri = tuple((str(n), float(v)) for n, v in self.camera_offset_prior_px)
        except (TypeError, ValueError):
            raise InputError("MultiViewConfig.camera_offset_prior_px", "pairs (camera name, pixels)",
                             repr(self.camera_offset_prior_px)) from None
        for n, v in pri:
            if not v > 0:
                raise InputError(f"MultiViewConfig.camera_offset_prior_px[{n!r}]", "a value > 0 (inf: no prior)",
                                 repr(v))
        object.__setattr__(self, "camera_offset_prior_px", pri)
        if not (np.isfinite(self.tie_relative) and self.tie_relative >= 0):
            raise InputError("MultiViewConfig.tie_relative", "a finite value >= 0", repr(self.tie_relative))
        for name in ("refine_top", "max_combinations", "min_view_joints"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise InputError(f"MultiViewConfig.{name}", "an integer >= 1", repr(v))
        if self.reference_view is not None and (int(self.reference_view) != self.reference_view
                                                or self.reference_view < 0):
            raise InputError("MultiViewConfig.reference_view", "None or a view index >= 0",
                             repr(self.reference_view))

    def offset_prior_of(self, camera: str) -> float:
        """Offset prior standard deviation of one camera, pixels."""
        return dict(self.camera_offset_prior_px).get(camera, self.offset_prior_px)

    def with_offset_priors(self, cameras, prior_px: float = REFINED_OFFSET_PRIOR_PX) -> "MultiViewConfig":
        """This configuration with the offset prior of ``cameras`` (names) set to ``prior_px``."""
        pri = dict(self.camera_offset_prior_px)
        pri.update({str(c): float(prior_px) for c in cameras})
        return replace(self, camera_offset_prior_px=tuple(sorted(pri.items())))
