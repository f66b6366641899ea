"""Configuration of the view-dependent billboard renderer (source 000 §4)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14
from toolkit.rendering.weights import ANGLE_SIGMA, ATTENUATION_SIGMA_M, FADE_RATIO_HIGH, FADE_RATIO_LOW

#: Angle off its normal up to which a billboard is drawn where its source put it, degrees.
TURN_FREE_DEG = 0.0
#: Depth / width of the torso's cross-section, about 0.8 (chest depth over chest breadth).  Not used by
#: default: ``part_depth_ratios=(("torso", TORSO_DEPTH_RATIO),)`` gains 0.7 dB on the seeds 7/8 benchmark
#: and 0.1-0.4 dB on four new scenes but loses 0.3 and 1.2 dB on two others (docs/stage4_rendering.md).
TORSO_DEPTH_RATIO = 0.8
#: Depth / breadth of the torso's cross-section as its billboards see it (side segment, chest to back,
#: over front segment, shoulder to shoulder): 0.55-0.64 measured on the synthetic bodies, about 0.6 for
#: adults (chest depth ~0.24 m, shoulder breadth ~0.40 m).
TORSO_SECTION_RATIO = 0.6
#: Joint pairs (left, right) whose differences give a part's left-right direction, by part name: the parts
#: that can have an oriented cross-section (``BlendConfig.section_ratios``).
LATERAL_JOINTS = {"torso": (("l_shoulder", "r_shoulder"), ("l_hip", "r_hip"))}
#: Parts drawn with an oriented elliptic cross-section by default (:func:`toolkit.rendering.blend.section_widths`).
SECTION_RATIOS = (("torso", TORSO_SECTION_RATIO),)
#: Default: every part is turned as a round one.
PART_DEPTH_RATIOS = ()
#: Where the back copy of a turned billboard sits, in part depths behind the bone (0.5: the part's back
#: surface when the bone runs through its middle).
THICKNESS = 0.5
#: Standard deviation of the adaptive smoothing Gaussian, pixels.
SMOOTHING_SIGMA_PX = 0.8
#: Half-width of the band around detected discontinuities that gets smoothed, pixels (0: the
#: discontinuity pixels themselves, on both sides of each border; wider bands blurred whole limbs of
#: 100-200 px tall subjects and lost 0.5 dB on the broadcast benchmark).
SMOOTHING_BAND_PX = 0
#: Colour jump (grey levels, largest channel) that makes a fan-to-fan or camera-switch border a discontinuity.
SMOOTHING_MIN_JUMP = 24.0
#: Colour weight of the back faces drawn under a part (``BlendConfig.back_underlay``), relative to the part's
#: nearest billboard, for the back face with the best mirrored angle.
BACK_UNDERLAY_WEIGHT = 0.3


@dataclass(frozen=True)
class BlendConfig:
    """Blending and compositing parameters.

    Parameters
    ----------
    angle_sigma : float
        Width of omega(beta), radians (eq. 5: 0.32).
    attenuation_sigma_m : float
        Width of the attenuation f, metres (eq. 7: 1 m).
    fade_low, fade_high : float
        Foreshortening ratios between which grazing billboards fade in
        (:func:`toolkit.rendering.weights.grazing_fade`).
    back_faces : bool
        Where a view sees every billboard of a part from behind, draw their back
        faces (the fallback that keeps the subject in reverse-angle views) instead
        of nothing.
    grazing_front : bool
        Where no billboard of a part passes the fade but the view sees some of
        them from the front (edge-on, past the fade), draw those, the least
        foreshortened one opaque, before any back face: they show the side of
        the part the view sees, a back face shows the other side mirrored.
    back_underlay : float
        With ``back_faces``, draw the back faces the view sees under every
        part, the billboards not drawn from the front: their colour weight
        is this times their omega of the mirrored angle (relative to the best
        back face), the part's nearest billboard's 1, so they fill the
        part's outline where the billboards seen from the front do not reach
        (0: off; :func:`toolkit.rendering.blend.fan_weights`).
    normalise_fade : bool
        Take each fan's nearest camera as the one with the largest
        ``omega * fade`` and divide the fan's fades by its fade, so the
        billboard whose alpha eq. 10 uses is opaque and a part seen only at
        grazing angles is not drawn half transparent.
    face_view : bool
        Turn each planar billboard about its bone to face the view
        (:func:`toolkit.rendering.blend.facing_pose`), so parts keep their width
        between and behind the sources; at a source camera nothing turns.
    turn_free_deg : float
        Billboards seen at most this far off their normal are not turned;
        farther ones are turned only down to it, degrees
        (:func:`toolkit.rendering.blend.facing_pose`).
    part_depth_ratios : tuple of (str, float)
        Parts that are not round about their bone: (part name of
        ``SKELETON_14.parts``, depth / width of its cross-section).  Such a part
        truly looks narrower from the side, so its billboards are turned only
        beyond ``arccos(ratio)``: foreshortened at most to the ratio.
    view_width : bool
        With ``face_view``, stretch each turned billboard across its bone to
        the part's width from the view, predicted by an elliptic
        cross-section fitted to the widths its sources saw
        (:func:`toolkit.rendering.blend.view_widths`), the more the farther
        the view from the billboard's source (not at all on it).
    section_ratios : tuple of (str, float)
        With ``face_view``, parts whose cross-section is an ellipse oriented
        by the skeleton (part name with an entry in
        :data:`LATERAL_JOINTS`, prior depth / breadth
        ratio): each turned billboard is stretched across its bone to the
        part's width from the view (:func:`toolkit.rendering.blend.section_widths`)
        where no source saw it that wide, the more the farther the view from
        its source; overrides ``view_width`` for those parts.
    thickness : float
        With ``face_view``, each billboard is also drawn this many part
        depths (:func:`toolkit.rendering.blend.part_depth`) behind itself,
        under itself: seen from the side nothing changes, seen from above (or
        below) the part's far half shows, as on a body (0 = off).
    binary_alpha : bool
        Threshold each warped billboard alpha at 0.5 (the source's binary
        segmentation masks): the parts of a source view then tile it exactly,
        and the jagged borders are left to the adaptive smoothing.
    smoothing : bool
        Apply the adaptive Gaussian smoothing at the discontinuities found while rendering.
    smoothing_sigma_px : float
        Gaussian standard deviation, pixels.
    smoothing_band_px : int
        Half-width of the smoothed band around each discontinuity, pixels.
    smoothing_min_jump : float
        Colour jump (0..255) above which a border between fans, or between
        cameras, counts as a discontinuity.
    """

    angle_sigma: float = ANGLE_SIGMA
    attenuation_sigma_m: float = ATTENUATION_SIGMA_M
    fade_low: float = FADE_RATIO_LOW
    fade_high: float = FADE_RATIO_HIGH
    back_faces: bool = True
    grazing_front: bool = True
    back_underlay: float = BACK_UNDERLAY_WEIGHT
    normalise_fade: bool = True
    face_view: bool = True
    turn_free_deg: float = TURN_FREE_DEG
    part_depth_ratios: tuple = PART_DEPTH_RATIOS
    view_width: bool = False
    section_ratios: tuple = SECTION_RATIOS
    thickness: float = THICKNESS
    binary_alpha: bool = True
    smoothing: bool = True
    smoothing_sigma_px: float = SMOOTHING_SIGMA_PX
    smoothing_band_px: int = SMOOTHING_BAND_PX
    smoothing_min_jump: float = SMOOTHING_MIN_JUMP

    def __post_init__(self):
        for name in ("angle_sigma", "attenuation_sigma_m", "smoothing_sigma_px"):
            v = getattr(self, name)
            if not v > 0:
                raise InputError(f"BlendConfig.{name}", "a positive number", repr(v))
        if not 0 <= self.fade_low < self.fade_high:
            raise InputError("BlendConfig.fade_low/fade_high", "0 <= fade_low < fade_high",
                             f"{self.fade_low}, {self.fade_high}")
        names = [p.name for p in SKELETON_14.parts]
        for entry in self.part_depth_ratios:
            if len(entry) != 2 or entry[0] not in names or not 0.0 < float(entry[1]) <= 1.0:
                raise InputError("BlendConfig.part_depth_ratios", f"(part name in {names}, ratio in (0, 1]) pairs",
                                 repr(entry))
        for entry in self.section_ratios:
            if len(entry) != 2 or entry[0] not in LATERAL_JOINTS or not 0.0 < float(entry[1]) <= 1.0:
                raise InputError("BlendConfig.section_ratios",
                                 f"(part name in {tuple(LATERAL_JOINTS)}, ratio in (0, 1]) pairs", repr(entry))
        if not 0.0 <= self.thickness <= 2.0:
            raise InputError("BlendConfig.thickness", "a number of part depths in [0, 2]", repr(self.thickness))
        if not 0.0 <= self.back_underlay <= 1.0:
            raise InputError("BlendConfig.back_underlay", "a colour weight in [0, 1]", repr(self.back_underlay))
        if self.smoothing_band_px < 0:
            raise InputError("BlendConfig.smoothing_band_px", "a non-negative integer", repr(self.smoothing_band_px))

    def section_ratio_ids(self) -> dict:
        """Per 1-based part id, the depth / breadth ratio of its oriented cross-section (``section_ratios``)."""
        ids = {p.name: i + 1 for i, p in enumerate(SKELETON_14.parts)}
        return {ids[n]: float(r) for n, r in self.section_ratios}

    def free_angles_deg(self) -> dict:
        """Per 1-based part id, the angle up to which its billboards are not turned, degrees."""
        ids = {p.name: i + 1 for i, p in enumerate(SKELETON_14.parts)}
        return {ids[n]: max(self.turn_free_deg, float(np.degrees(np.arccos(r)))) for n, r in self.part_depth_ratios}
