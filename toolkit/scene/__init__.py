"""The static scene around the people, from the source cameras alone.

A free-viewpoint frame is the people (articulated billboards) drawn over the
scene they stand in.  This package builds that scene from the source videos:

* :mod:`~toolkit.scene.backgrounds`: each source camera's empty view, estimated
  over time with the people removed (a robust per-pixel median of frames, the
  people left out by their change from it and by their detected keypoints),
  with a per-pixel confidence;
* :mod:`~toolkit.scene.proxy`: the geometry those views are carried on: the
  ground plane, and a vertical cylinder around the capture volume standing for
  the walls, stands or whatever surrounds it, its radius chosen by how well the
  source backgrounds agree on it;
* :mod:`~toolkit.scene.model`: :class:`SceneModel`, the two together, rendered
  into any camera view-dependently (each pixel blends the sources that see its
  proxy point, the ones whose rays are closest to the view's weighted most),
  saved to and loaded from a run folder.

No image of the view being rendered is used: a held-out camera's background
comes from the other cameras only.
"""

from toolkit.scene.backgrounds import SourceBackground, estimate_background, people_exclusion
from toolkit.scene.build import build_scene_model
from toolkit.scene.fit import fit_proxy
from toolkit.scene.model import SceneModel
from toolkit.scene.proxy import SceneProxy

__all__ = ["SourceBackground", "estimate_background", "people_exclusion", "SceneProxy", "fit_proxy",
           "SceneModel", "build_scene_model"]
