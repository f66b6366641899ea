"""How reports are drawn and stored in recordings: colours and :class:`RerunConfig`.

No rerun import here; :mod:`toolkit.viz.rerun_observer` applies them.
"""

from __future__ import annotations

from dataclasses import dataclass

from toolkit.errors import InputError

#: Keypoint colours (RGB) by body side, so left/right swaps are visible at a glance.
LEFT_COLOR = (60, 180, 75)
RIGHT_COLOR = (230, 25, 75)
CENTRE_COLOR = (255, 225, 25)
#: Bone colours of successive registered skeletons.
SKELETON_COLORS = ((0, 130, 200), (245, 130, 48), (145, 30, 180), (70, 240, 240))
#: Part-label colours; label id ``1 + i`` gets ``PART_COLORS[i % len]``
#: (for SKELETON_14: head, torso, l_upper_arm, l_forearm, r_upper_arm,
#: r_forearm, l_thigh, l_shank, r_thigh, r_shank).
PART_COLORS = ((255, 225, 25), (0, 130, 200), (60, 180, 75), (170, 255, 195), (230, 25, 75),
               (250, 190, 212), (128, 128, 0), (210, 245, 60), (128, 0, 0), (255, 215, 180))
#: Foreground colour of binary masks.
MASK_COLOR = (255, 0, 255)
#: Colour of untextured quads without ``colors``.
QUAD_COLOR = (180, 180, 180)
#: Report kinds logged static unless the report says ``static=False``.
STATIC_KINDS = frozenset({"rig", "skeleton"})
#: Longest field text of a generic (unknown-kind) report line.
GENERIC_TEXT_CHARS = 200


@dataclass(frozen=True)
class RerunConfig:
    """How reports are drawn and stored.

    Parameters
    ----------
    compress_images : bool
        JPEG-encode 8-bit RGB / grey images of at least ``compress_min_pixels``.
    jpeg_quality : int
        JPEG quality, 1..100.
    compress_min_pixels : int
        Images smaller than this (``H * W``) are stored raw.
    depth_png : bool
        Store depth maps of at least ``compress_min_pixels`` as 16-bit PNG
        (lossless at ``1 / depth_png_units_per_metre``; beyond 65535 units
        becomes "no depth").
    depth_png_units_per_metre : float
        Depth units per metre of the PNG (1000 = millimetres).
    joint_radius_m : float
        Radius of 3D joints, metres.
    keypoint_radius_px : float
        Radius of 2D keypoints and points, pixels.
    point_radius_m : float
        Default radius of 3D points, metres.
    ray_radius_m : float
        Radius of rays and 3D lines, metres.
    overlay_opacity : float
        Opacity of masks and part-label images over the camera image.
    image_plane_distance_m : float or None
        Depth at which the viewer draws camera frusta and images (None: rerun's choice).
    auto_blueprint : bool
        Send the default blueprint on the first ``rig`` report if none was sent; it is
        sent again when it can show more (a camera's first overlay of a stage, the
        subject's first 3D joints that frame the 3D view).
    joint_labels : bool
        Draw joint names next to 2D and 3D joints.  Off by default: on a subject
        100-200 px tall the 14 names cover it; the name shows when hovering a joint.
    crop_overlays : bool
        Store masks, part labels and other named images of a camera cropped to what
        they show (the bounding box of the non-zero pixels, or for colour images the
        subject's box, from the latest 3D joints, widened by ``crop_margin``), placed
        at their offset in the camera image by a 2D translation.  The camera's own
        image is never cropped.
    crop_margin : float
        Margin of a colour image's subject crop, as a fraction of the subject box's
        height on each side.
    compact_on_close : bool
        When the observer saved to a file, compact it on :meth:`close` with the rerun
        CLI (``rerun rrd optimize``: the rows of each entity merged into few chunks;
        a third smaller for a pipeline run) and replace it atomically.  The file is
        complete and valid before, so a failed compaction only warns.
    """

    compress_images: bool = True
    jpeg_quality: int = 90
    compress_min_pixels: int = 64 * 64
    depth_png: bool = True
    depth_png_units_per_metre: float = 1000.0
    joint_radius_m: float = 0.02
    keypoint_radius_px: float = 3.0
    point_radius_m: float = 0.005
    ray_radius_m: float = 0.002
    overlay_opacity: float = 0.5
    image_plane_distance_m: float | None = 0.5
    auto_blueprint: bool = True
    joint_labels: bool = False
    crop_overlays: bool = True
    crop_margin: float = 0.35
    compact_on_close: bool = True

    def __post_init__(self):
        if not 1 <= int(self.jpeg_quality) <= 100:
            raise InputError("RerunConfig.jpeg_quality", "an int in 1..100", f"{self.jpeg_quality}")
        if self.depth_png_units_per_metre <= 0:
            raise InputError("RerunConfig.depth_png_units_per_metre", "> 0",
                             f"{self.depth_png_units_per_metre}")
        if not 0.0 <= self.crop_margin:
            raise InputError("RerunConfig.crop_margin", ">= 0", f"{self.crop_margin}")
        if not 0.0 <= self.overlay_opacity <= 1.0:
            raise InputError("RerunConfig.overlay_opacity", "a value in [0, 1]", f"{self.overlay_opacity}")
