"""The layer between the stages: where a stage's input comes from.

:mod:`toolkit.pipeline.keypoints` -- stage 1 from a detector's 2D keypoints (instead of the
silhouette database), with silhouettes given, from clean plates, or seeded by the keypoints.
:mod:`toolkit.pipeline.views` -- the views a run is judged in: novel cameras, a held-out source camera.
:mod:`toolkit.pipeline.run` -- what every system's run shares: configs from TOML, run identity derived
from them, per-frame records, :class:`~toolkit.pipeline.run.RunResult`.
:mod:`toolkit.pipeline.free_viewpoint` -- the articulated-billboard system's run (``run(config, dataset=,
out=)``), which ``recipes/free_viewpoint.py`` calls.
:mod:`toolkit.pipeline.pose_from_keypoints` -- a detector's keypoints triangulated (one person or
every person found), which ``recipes/pose_from_keypoints.py`` calls.
:mod:`toolkit.pipeline.depth_tracking` -- one sequence of depth frames tracked (source 001), which
``recipes/depth_tracking.py`` calls.
:mod:`toolkit.pipeline.calibrate` -- intrinsics and extrinsics from scratch, which ``recipes/calibrate.py`` calls.
:mod:`toolkit.pipeline.silhouette_db` -- a silhouette database rendered, which ``recipes/build_silhouette_db.py`` calls.
"""

from toolkit.pipeline.keypoints import (SILHOUETTE_SOURCES, KeypointStage1, KeypointStage1Config,
                                        estimate_from_keypoints, read_dataset_keypoints, read_mask,
                                        triangulate_dataset_keypoints)

__all__ = ["SILHOUETTE_SOURCES", "KeypointStage1", "KeypointStage1Config", "estimate_from_keypoints",
           "read_dataset_keypoints", "read_mask", "triangulate_dataset_keypoints"]
