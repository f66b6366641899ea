"""Joint correction in the browser (source 000 claim 7): a run's poses, the user's drags, the database.

``session``   :class:`CorrectionSession`: a run folder's 2D and 3D poses, moves with re-triangulation,
              undo, ``RUN/edits.toml`` (the format of :mod:`toolkit.silhouettes.edits`), commits
              to the silhouette database
``app``       :func:`create_app`: the FastAPI application (JSON API and the static page in ``static/``)
``serve``     :func:`~toolkit.correction.serve.serve` the page until Ctrl-C, or
              :func:`~toolkit.correction.serve.screenshot_page` take its picture in headless Chromium

Start it with ``recipes/correct_poses.py RUN --port PORT``; see ``docs/correction.md``.
"""

from toolkit.correction.session import EDITS_FILE, CorrectionSession, NotFound


def create_app(session):
    """The FastAPI application of a session (see :func:`toolkit.correction.app.create_app`)."""
    from toolkit.correction.app import create_app as _create

    return _create(session)


__all__ = ["EDITS_FILE", "CorrectionSession", "NotFound", "create_app"]
