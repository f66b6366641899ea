"""Constants of source 000 (§3, §4) and the configurations of the billboard stage."""

from __future__ import annotations

from dataclasses import dataclass

from toolkit.errors import InputError

#: σ of the camera-pair weight ω(β) = exp(-β² / 2σ²), radians (source 000 §3.1, eq. 5).
PAIR_ANGLE_SIGMA = 0.32
#: φ: depth difference under which two differently labelled 4-neighbours form a seam, metres (§3.3).
SEAM_DEPTH_M = 0.03
#: Largest RGB distance between two 8-bit colours (the diagonal of the RGB cube); ε divides by it.
RGB_DIAGONAL = 255.0 * 3.0 ** 0.5


@dataclass(frozen=True)
class BillboardConfig:
    """How fans are built.

    Attributes
    ----------
    margin_px : float
        Extra border around a part's segment when sizing a billboard, source pixels.
    min_pixels : int
        A part with fewer segment pixels in a camera gets no billboard from it.
    edge_on_deg : float
        A billboard is degenerate (skipped) when the angle between the bone and
        the ray to its source camera is below this, degrees (bone pointing at the camera).
    max_extent_m : float
        Largest half-width of a billboard across the bone and overhang past its
        ends, metres (guards against grazing rays of stray segment pixels).
    surface : str
        Projection surface: ``"plane"``, ``"cylinder"`` or ``"ellipsoid"``.
    radius_m : float or None
        Radius of cylinder / ellipsoid surfaces; None = half the billboard width.
    """

    margin_px: float = 2.0
    min_pixels: int = 4
    edge_on_deg: float = 8.0
    max_extent_m: float = 0.5
    surface: str = "plane"
    radius_m: float | None = None

    def __post_init__(self):
        if self.surface not in ("plane", "cylinder", "ellipsoid"):
            raise InputError("BillboardConfig.surface", "'plane', 'cylinder' or 'ellipsoid'", repr(self.surface))
        if not 0.0 < self.edge_on_deg < 90.0:
            raise InputError("BillboardConfig.edge_on_deg", "an angle in (0, 90) degrees", f"{self.edge_on_deg}")


@dataclass(frozen=True)
class ScoreConfig:
    """The position score of source 000 §3.1.

    ε(c1, c2) = |c1 - c2|₂ / (255 √3): the Euclidean RGB distance of two 8-bit
    colours normalised to [0, 1] by the diagonal of the RGB cube
    (:data:`RGB_DIAGONAL`), optionally scaled by ``eps_gain`` and clipped to 1.

    Attributes
    ----------
    sigma : float
        σ of the pair weight, radians (:data:`PAIR_ANGLE_SIGMA`).
    eps_gain : float
        Multiplier on ε before clipping to [0, 1]; 1 = the plain normalised RGB distance.
    active_alpha : float
        A warped billboard pixel is active when its alpha is at least this.
    grazing_deg : float
        A billboard seen within this angle of edge-on from an evaluated view is
        left out of that view, degrees.
    virtual_views : bool
        Evaluate the virtual cameras midway between each camera pair as well
        as the input cameras (source 000 §3.2).
    occlusion : bool
        Resolve occlusion with the segmentation (source 000 §3.1: "La
        segmentación ... se utiliza para resolver la oclusión"): a pixel active
        for one camera whose ray in the other camera lands on another part of
        the subject (that part hides this one there) is left out of the
        normalisation n(p) instead of counting as misaligned.
    occlusion_border_px : int
        Border around a part's bounding box searched for occluding parts, pixels.
    """

    sigma: float = PAIR_ANGLE_SIGMA
    eps_gain: float = 1.0
    active_alpha: float = 0.5
    grazing_deg: float = 15.0
    virtual_views: bool = True
    occlusion: bool = True
    occlusion_border_px: int = 24

    def __post_init__(self):
        if self.sigma <= 0:
            raise InputError("ScoreConfig.sigma", "a positive angle in radians", f"{self.sigma}")
        if not 0.0 < self.active_alpha <= 1.0:
            raise InputError("ScoreConfig.active_alpha", "a value in (0, 1]", f"{self.active_alpha}")
