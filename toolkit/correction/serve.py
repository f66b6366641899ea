"""Serving a correction session's page: until Ctrl-C, or just long enough to take its picture.

``recipes/correct_poses.py`` calls :func:`serve` (the page at
``http://HOST:PORT/``) or :func:`screenshot_page` (serve in a thread, open the
page in headless Chromium, save it, stop).
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

from toolkit.errors import InputError

#: Size of the page's picture, pixels (width, height).
SCREENSHOT_VIEWPORT = (1500, 720)
#: The picture is taken once the page has drawn a joint, and this long after (seconds).
SCREENSHOT_SETTLE_S = 1.0
#: How often the server's start is polled, seconds.
_POLL_S = 0.05


def serve(session, host: str, port: int) -> None:
    """Serve the session's page on ``host:port`` until stopped (Ctrl-C)."""
    import uvicorn

    from toolkit.correction import create_app

    uvicorn.run(create_app(session), host=host, port=port, log_level="warning")


def screenshot_page(session, host: str, port: int, png: str | os.PathLike) -> Path:
    """Serve the page in a thread, save a picture of it (first frame) with headless Chromium, stop.

    Parameters
    ----------
    session : CorrectionSession
    host : str
    port : int
    png : path
        The picture to write.

    Returns
    -------
    Path
        ``png``.

    Raises
    ------
    InputError
        The page could not be served on ``host:port``, or Chromium failed.
    """
    import uvicorn

    from toolkit.correction import create_app
    from toolkit.viz.webshot import screenshot_url

    server = uvicorn.Server(uvicorn.Config(create_app(session), host=host, port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        while not server.started:
            if not thread.is_alive():
                raise InputError(f"{host}:{port}", "an address to serve the page on", "the page could not be served")
            time.sleep(_POLL_S)
        screenshot_url(f"http://{host}:{port}/", png, viewport=SCREENSHOT_VIEWPORT, wait_selector="circle[data-joint]",
                       wait_s=SCREENSHOT_SETTLE_S)
    finally:
        server.should_exit = True
        thread.join(timeout=10)
    return Path(png)
