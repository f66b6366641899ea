"""Configuration and per-frame result of stage 1 (:mod:`toolkit.silhouettes.pipeline`): frame states,
:class:`Stage1Config`, :class:`FrameEstimate`."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from toolkit.errors import InputError
from toolkit.multiview import MultiViewConfig, MultiViewSelection
from toolkit.silhouettes.descriptor import MAX_FILL_FRACTION, MIN_SILHOUETTE_PIXELS
from toolkit.silhouettes.query import QueryConfig

#: Frame states (one per frame) and their codes.
FRAME_OK = 0
FRAME_TOO_FEW_VIEWS = 1
FRAME_SELECTION_FAILED = 2
FRAME_NOT_PROCESSED = 3
FRAME_STATES = {
    FRAME_OK: "ok",
    FRAME_TOO_FEW_VIEWS: "fewer than two usable silhouettes",
    FRAME_SELECTION_FAILED: "multi-view selection failed (no joint seen by two views)",
    FRAME_NOT_PROCESSED: "not processed (the run stopped early)",
}
#: Database entries pooled per view after the selection (:class:`Stage1Config`).
POOL_K = 6
#: Largest mean joint distance of a pooled entry to the chosen pose, x box height.
POOL_RADIUS = 0.06



@dataclass(frozen=True)
class Stage1Config:
    """Options of the silhouette-based 2D/3D pose stage.

    Parameters
    ----------
    query : QueryConfig
        k, λ and the matching variant.
    multiview : MultiViewConfig
        Combination search and offsets (owned by :mod:`toolkit.multiview`).
    min_pixels : int
        Fewest pixels of a usable silhouette.
    max_fill : float
        Largest usable fraction of the image.
    border_px : int
        A silhouette within this many pixels of the border counts as cut off.
    add_edits_to_database : bool
        Add corrected poses to the database (unless an edit says otherwise).
    pool_k : int
        Candidate pooling (k-nearest-neighbour regression): after the
        multi-view selection, each view's chosen pose is replaced by the
        weighted mean (weights 1 / (E_S + 0.001)) of those of its ``pool_k``
        best database entries that agree with it (directly or with left and
        right swapped) to within ``pool_radius`` of the box height, and the
        views are triangulated again with their offsets.  The database is a
        sample of poses, so the mean of close neighbours is nearer the true
        pose than any one of them (2D error -8 % with 3 entries, -19 % with
        6 on the stage-1 benchmark).  ``pool_k <= 1`` turns it off; the
        selection itself always uses the ``query.k`` best.
    pool_radius : float
        Largest mean joint distance to the chosen pose, as a fraction of the
        silhouette's box height, of a pooled entry.
    """

    query: QueryConfig = QueryConfig()
    multiview: MultiViewConfig = field(default_factory=MultiViewConfig)
    min_pixels: int = MIN_SILHOUETTE_PIXELS
    max_fill: float = MAX_FILL_FRACTION
    border_px: int = 0
    add_edits_to_database: bool = True
    pool_k: int = POOL_K
    pool_radius: float = POOL_RADIUS

    def __post_init__(self):
        if not (isinstance(self.pool_k, (int, np.integer)) and self.pool_k >= 0):
            raise InputError("Stage1Config.pool_k", "an integer >= 0", repr(self.pool_k))
        if not (np.isfinite(self.pool_radius) and self.pool_radius > 0):
            raise InputError("Stage1Config.pool_radius", "a positive fraction of the box height",
                             repr(self.pool_radius))

    def with_refined_cameras(self, cameras) -> "Stage1Config":
        """This configuration with the tight offset prior for ``cameras`` (names) refined on field lines.

        A refined camera is good to about a pixel, so its stage-1 offset gets the
        prior :data:`~toolkit.multiview.REFINED_OFFSET_PRIOR_PX` instead of the
        source's 8 px (:meth:`~toolkit.multiview.MultiViewConfig.with_offset_priors`).
        """
        cams = list(cameras)
        if not cams:
            return self
        return replace(self, multiview=self.multiview.with_offset_priors(cams))


@dataclass(frozen=True, eq=False)
class FrameEstimate:
    """Stage-1 result of one frame.

    Attributes
    ----------
    frame : int
    state : int
        ``FRAME_*`` code (:data:`FRAME_STATES`).
    view_states : ndarray of shape (n_views,), uint8
        Silhouette ``STATE_*`` codes (:data:`toolkit.silhouettes.descriptor.SILHOUETTE_STATES`).
    bboxes : ndarray of shape (n_views, 4)
        Silhouette boxes, pixel edges; NaN where none.
    candidates : tuple of (Candidates or None)
        Database candidates per view (None for unusable views).
    candidates_px : ndarray of shape (n_views, k, 14, 2)
        Candidate joints in pixels; NaN for unusable views.
    poses2d : ndarray of shape (n_views, 14, 2)
        Chosen 2D pose per view in image pixels (flip applied, pooled with
        the agreeing database entries when ``Stage1Config.pool_k > 1``, before
        the offset; after the user's edits); NaN for views without one.
    offsets : ndarray of shape (n_views, 2)
        Per-view 2D offsets (pixels) that make the rays meet: the pose aligned
        with the calibration is ``poses2d + offsets``; NaN for unused views.
    joints3d : ndarray of shape (14, 3)
        Metres, world; NaN without an estimate.
    cost : float
        Mean ray distance of the chosen combination, metres (NaN without one).
    edited : ndarray of shape (n_views,), bool
        Views whose joints were corrected by the user.
    added : tuple of int
        Database rows added from the corrections.
    selection : MultiViewSelection or None
    timings : dict of str to float
        Seconds spent per stage: ``"query"`` (checks, descriptors and database
        queries), ``"multiview"`` (selection and offsets), ``"edits"``;
        :func:`estimate_dataset` adds ``"foreground"``.
    """

    frame: int
    state: int
    view_states: np.ndarray
    bboxes: np.ndarray
    candidates: tuple
    candidates_px: np.ndarray
    poses2d: np.ndarray
    offsets: np.ndarray
    joints3d: np.ndarray
    cost: float
    edited: np.ndarray
    added: tuple = ()
    selection: MultiViewSelection | None = None
    timings: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.state == FRAME_OK

    def __bool__(self) -> bool:
        return self.ok
