"""Configuration of the constrained 3D joint optimisation (source 000 §3.2, claim 10)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError

#: Finest step of the adaptive grid, metres ("ajustada en forma empírica a 1,2 cm", source 000 §3.2).
GRID_MIN_STEP_M = 0.012
#: Sweeps over all joints after which the source's optimisation has usually converged (§3.2: "4 iteraciones").
SOURCE_SWEEPS = 4
#: Least rise of a joint's score for the joint to move: the score's noise margin.  Resampling
#: and compression move it by ~0.005, but label errors, calibration error and the flat score
#: along the bones make spurious maxima up to a few hundredths higher than the true pose;
#: measured over the stage-3 benchmark (min_gain 0.01 / 0.03 / 0.06), 0.03 halves the
#: damage done to good starts and keeps the gains (docs/stage3_billboards.md).
MIN_GAIN = 0.03


#: A view confirms a move when the joint's score in that view rises by more than this: the
#: resampling noise of one view's score (``docs/stage3_billboards.md``).
VIEW_NOISE = 0.005
#: Camera pairs that must each raise a joint's score for a move to be kept (two independent
#: pieces of evidence; with one pair, two cameras, every view compares the same two images).
MIN_AGREEING_PAIRS = 2

#: Weight of the pull towards the start (score units at one ``prior_sigma_m``), :class:`OptimizeConfig`.
PRIOR_WEIGHT = 0.05


@dataclass(frozen=True)
class OptimizeConfig:
    """Adaptive grid search per joint, joints swept in turn.

    Attributes
    ----------
    initial_step_m : float
        First grid step, metres; halved each level down to ``min_step_m``
        (default 4.8 cm = 4 x 1.2 cm: levels 4.8, 2.4, 1.2 cm).
    min_step_m : float
        Finest step (:data:`GRID_MIN_STEP_M`).
    grid_radius : int
        The grid around a centre has ``(2 r + 1)^3`` nodes.
    keep_best : int
        Number of best candidates the grid is refined around at each level.
    max_sweeps : int
        Most sweeps over all joints (:data:`SOURCE_SWEEPS`).
    min_improvement : float
        Stop when a sweep raises the summed joint score by less than this.
    min_gain : float
        A joint moves only when its score (the sum over its adjacent bones)
        rises by more than this (:data:`MIN_GAIN`).
    tie_tol : float
        Candidates scoring within this of the best count as equally good; the
        one nearest the current position wins (the score is flat along a bone).
    min_views : int
        A joint is searched only when its bones are scored in at least this
        many evaluated views (a view scores a bone when two of its billboards
        are seen there, not edge-on).  With two cameras far apart each
        camera sees the other's billboards edge-on and only the virtual view
        midway between them scores: one synthetic viewpoint whose maxima lie
        5-14 cm from the truth (``docs/stage3_billboards.md``), so such joints
        keep their start.  1 searches them anyway.
    decisive : bool
        Keep a move only when the evidence for it is decisive (beyond the
        ``min_gain`` margin): every evaluated view that scores the joint's bones
        confirms it (rises by more than ``view_noise``) and at least ``min_pairs`` camera
        pairs each raise the joint's score (:meth:`PositionScorer.move_evidence`).
        A move that fails ends with status ``"not_decisive"`` and the joint
        keeps its position.  This holds for a start that breaks an anthropometric
        rule too: it is not a candidate, but it keeps its real score, so a move
        away from it needs the margin and the evidence (the rules say the joint
        is wrong, not where it belongs).  False: the source's rule (the best
        candidate wins; a start that breaks a rule scores 0, so any valid
        candidate replaces it).
    view_noise : float
        :data:`VIEW_NOISE`.
    min_pairs : int
        :data:`MIN_AGREEING_PAIRS`; 1 lets a single camera pair (two cameras) move joints.
    prior_weight, prior_sigma_m : float
        A quadratic pull towards where each joint started the optimisation:
        candidates compete on ``score - prior_weight * (d / prior_sigma_m)^2``,
        d the distance to the start (0: off, the source's pure score).  A
        Gaussian prior of 5 cm around stage 1's estimate in score units: a
        candidate 5 cm away must score 0.05 more.  On the 3-camera benchmark
        scene it turned the search's effect from +6 % to -4 % (from stage 1)
        and from -9 % to -22 % (from 5 cm noise): without it, joints whose
        score is flat (hips, a shoulder whose upper arm one camera cannot see)
        drift by 3-5 cm.
    """

    initial_step_m: float = 0.048
    min_step_m: float = GRID_MIN_STEP_M
    grid_radius: int = 1
    keep_best: int = 2
    max_sweeps: int = SOURCE_SWEEPS
    min_improvement: float = 1e-3
    min_gain: float = MIN_GAIN
    tie_tol: float = 0.005
    min_views: int = 2
    decisive: bool = True
    view_noise: float = VIEW_NOISE
    min_pairs: int = MIN_AGREEING_PAIRS
    prior_weight: float = PRIOR_WEIGHT
    prior_sigma_m: float = 0.05

    def __post_init__(self):
        if not 0 < self.min_step_m <= self.initial_step_m:
            raise InputError("OptimizeConfig.initial_step_m/min_step_m", "0 < min_step_m <= initial_step_m",
                             f"{self.initial_step_m}, {self.min_step_m}")
        if not (np.isfinite(self.prior_weight) and self.prior_weight >= 0 and self.prior_sigma_m > 0):
            raise InputError("OptimizeConfig.prior_weight/prior_sigma_m", "weight >= 0 and sigma > 0",
                             f"{self.prior_weight}, {self.prior_sigma_m}")
        if self.min_pairs < 1 or not (np.isfinite(self.view_noise) and self.view_noise >= 0):
            raise InputError("OptimizeConfig.min_pairs/view_noise", "min_pairs >= 1 and view_noise >= 0",
                             f"{self.min_pairs}, {self.view_noise}")
        if self.min_views < 1:
            raise InputError("OptimizeConfig.min_views", "an integer >= 1", repr(self.min_views))
        if self.grid_radius < 1 or self.keep_best < 1 or self.max_sweeps < 1:
            raise InputError("OptimizeConfig", "grid_radius, keep_best and max_sweeps >= 1",
                             f"{self.grid_radius}, {self.keep_best}, {self.max_sweeps}")
