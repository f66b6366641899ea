"""The layer between the stages: where a stage's input comes from.

:mod:`toolkit.pipeline.keypoints` -- stage 1 from a detector's 2D keypoints (instead of the
silhouette database), with silhouettes given, from clean plates, or seeded by the keypoints.
:mod:`toolkit.pipeline.holdout` -- leave one camera out and judge the rendering of its view.
"""

from toolkit.pipeline.keypoints import (SILHOUETTE_SOURCES, KeypointStage1, KeypointStage1Config,
                                        estimate_from_keypoints, read_dataset_keypoints, read_mask,
                                        triangulate_dataset_keypoints)

__all__ = ["SILHOUETTE_SOURCES", "KeypointStage1", "KeypointStage1Config", "estimate_from_keypoints",
           "read_dataset_keypoints", "read_mask", "triangulate_dataset_keypoints"]
