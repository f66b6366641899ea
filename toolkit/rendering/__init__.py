"""View-dependent rendering of articulated billboards (source 000 §4): camera blending
weights, the per-pixel blend, the CPU compositor and the Open3D renderer, virtual
camera paths, baselines and image metrics."""

from toolkit.rendering.baselines import VisualHull, render_points, sample_billboard, standard_billboards, visual_hull
from toolkit.rendering.blend import RenderResult, composite, composite_subjects, fan_weights
from toolkit.rendering.compositor import CpuCompositor, warp_to_view
from toolkit.rendering.config import BlendConfig
from toolkit.rendering.fans import RENDER_SUPERSAMPLE, render_billboards
from toolkit.rendering.metrics import bbox_scores, mask_bbox, psnr, ssim, subject_scores
from toolkit.rendering.paths import birds_eye, interpolate_cameras, orbit_path, source_path
from toolkit.rendering.weights import (ANGLE_SIGMA, ATTENUATION_SIGMA_M, CameraWeights, attenuation, camera_weights,
                                       foreshortening, grazing_fade, omega, view_angles)

__all__ = ["VisualHull", "render_points", "sample_billboard", "standard_billboards", "visual_hull", "RenderResult",
           "composite", "composite_subjects", "fan_weights", "CpuCompositor", "warp_to_view", "BlendConfig", "RENDER_SUPERSAMPLE",
           "render_billboards", "bbox_scores", "subject_scores", "mask_bbox", "psnr", "ssim", "birds_eye", "interpolate_cameras",
           "orbit_path", "source_path", "ANGLE_SIGMA", "ATTENUATION_SIGMA_M", "CameraWeights", "attenuation",
           "camera_weights", "foreshortening", "grazing_fade", "omega", "view_angles"]


def __getattr__(name):  # Open3D is loaded only when its renderer is asked for
    if name == "Open3DRenderer":
        from toolkit.rendering.open3d_renderer import Open3DRenderer

        return Open3DRenderer
    raise AttributeError(name)
