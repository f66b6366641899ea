"""Cameras: the pinhole model, rigs, projection, rays and triangulation."""

from toolkit.cameras.camera import Camera, Rig, camera_with_offset, distort_to_pixels, plane_homography
from toolkit.cameras.triangulation import (
    closest_point_to_rays,
    reprojection_errors,
    triangulate_linear,
    triangulate_rays,
)

__all__ = ["Camera", "Rig", "camera_with_offset", "distort_to_pixels", "plane_homography", "closest_point_to_rays", "reprojection_errors",
           "triangulate_linear", "triangulate_rays"]
