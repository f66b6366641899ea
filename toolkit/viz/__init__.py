"""Rerun recordings: the only subpackage that imports rerun.

:class:`RerunObserver` turns observer reports into rerun entities on an
explicit recording stream (optionally saved to ``.rrd``);
:func:`make_blueprint` builds the default viewer layout.  See
``docs/recordings.md`` for the entity tree.
"""

from toolkit.viz.blueprint import (
    CAMS,
    LOGS,
    METRICS,
    REPORTS,
    WORLD,
    camera_path,
    entity_path,
    image_path,
    make_blueprint,
)
from toolkit.viz.rerun_observer import FRAME_TIMELINE, RerunConfig, RerunObserver

__all__ = ["CAMS", "FRAME_TIMELINE", "LOGS", "METRICS", "REPORTS", "WORLD", "RerunConfig", "RerunObserver",
           "camera_path", "entity_path", "image_path", "make_blueprint"]
