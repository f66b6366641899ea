"""Point clouds from depth maps, the generic half every point-cloud system starts from.

* :mod:`toolkit.pointcloud.cloud` -- depth to points, the gravity-aligned view
  frame, centroid and principal direction, the user's cloud, Open3D point clouds;
* :mod:`toolkit.pointcloud.mask` -- the user mask (given, or a background model
  and connected components), and the foreground of every person in view;
* :mod:`toolkit.pointcloud.normals` -- normal maps from depth gradients;
* :mod:`toolkit.pointcloud.stereo` -- clouds of trinocular stereo heads (OpenCV SGBM, third-camera check);
* :mod:`toolkit.pointcloud.patches` -- robust local surface patches (a cloud reduced to patch centres).

Depth files and the depth camera's intrinsics are read by :mod:`toolkit.io.depth_readers`.
The depth tracker (:mod:`toolkit.depth`) builds on these; so will the soft-body
and marker systems.
"""

from toolkit.pointcloud.cloud import (UserCloud, ViewFrame, depth_to_points, pixel_rays, principal_direction,
                                      to_open3d_pointcloud, user_cloud)
from toolkit.pointcloud.mask import BackgroundModel, MaskConfig, UserMask, ambiguous_mask, foreground_mask, user_mask
from toolkit.pointcloud.normals import grid_normals, normal_map

__all__ = ["BackgroundModel", "MaskConfig", "UserCloud", "UserMask", "ViewFrame", "ambiguous_mask", "depth_to_points", "foreground_mask", "grid_normals",
           "normal_map", "pixel_rays", "principal_direction", "to_open3d_pointcloud", "user_cloud", "user_mask"]
