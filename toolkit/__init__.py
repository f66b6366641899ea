"""Markerless articulated pose estimation and free-viewpoint video toolkit.

Subpackages follow the pipeline (see ``docs/architecture.md``):

``cameras``        pinhole camera model, rigs, projection, rays, triangulation
``skeleton``       skeletons as data (14-joint billboard skeleton, 13/17 depth skeletons)
``anthropometry``  bone-length limits and the constraint checker
``motion``         procedural motion library, BVH import/export
``synthetic``      synthetic multi-camera scenes with exact ground truth
``observe``        the observer protocol algorithms report to
``io``             every file read and write (calibration, datasets, video)
``viz``            the only place that imports rerun
"""

__version__ = "0.1.0"
