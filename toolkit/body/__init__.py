"""The body every system shares: its geometry on the 14-joint skeleton and the 13 control points.

* :mod:`toolkit.body.model` -- the clothed articulated body of smooth volumes
  (:class:`BodyShape`, :class:`BodyModel`, :class:`BodyMesh`): the synthetic
  generator renders it, the template of stage 2 projects it, the silhouette
  database is rendered from it.
* :mod:`toolkit.body.control_points` -- the 13 control points of the depth
  tracker's model (indices from :data:`toolkit.skeleton.JOINTS_13`), their
  placement on a body, the fitting primitives' radii and the body's dimensions.

The inverse-crime risk: the estimators' templates (stage 2's template, the
silhouette database, the depth model's primitives) are built from this same
body that renders the synthetic scenes, so on synthetic data the model fits
the images better than it would fit a real person.  What the benchmarks do
about it is in ``docs/architecture.md`` ("The body and the inverse crime").
"""

from toolkit.body.control_points import BodyDimensions, control_points, mirror13, rest_pose13
from toolkit.body.model import BodyMesh, BodyModel, BodyShape, dress

__all__ = ["BodyDimensions", "BodyMesh", "BodyModel", "BodyShape", "control_points", "dress", "mirror13",
           "rest_pose13"]
