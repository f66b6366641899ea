"""Screenshots of web pages and of recordings in rerun's web viewer, in headless Chromium.

Used for the pictures in ``docs/`` (``docs/recordings.md``, ``docs/correction.md``)::

    python -m toolkit.viz.webshot OUT/recording.rrd docs/images/recording_overview.png --wait 300

Chromium is Debian's package (``scripts/setup.sh``), driven by Playwright's Python
package (the test extra) with ``executable_path``; WebGL runs on SwiftShader
(``--use-angle=swiftshader``).  The picture is taken with the DevTools protocol's
``Page.captureScreenshot``: Playwright's own screenshot waits for a compositor
frame that a busy software-rendered WebGL canvas may not deliver in time.
"""

from __future__ import annotations

import argparse
import base64
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from toolkit.errors import InputError

#: Debian's Chromium.
CHROMIUM = "/usr/bin/chromium"
#: Arguments of headless Chromium: WebGL on the CPU, no sandbox (root in containers).
CHROMIUM_ARGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox")
#: Default window size, CSS pixels.
VIEWPORT = (1600, 900)


def chromium_path() -> str:
    """Path of the Chromium binary; raises InputError naming what to install when there is none."""
    found = CHROMIUM if os.path.isfile(CHROMIUM) else shutil.which("chromium")
    if not found:
        raise InputError("chromium", f"Debian's chromium package at {CHROMIUM} (scripts/setup.sh installs it)",
                         "no chromium binary")
    return found


def free_port() -> int:
    """A free TCP port on the loopback interface."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def screenshot_url(url: str, png: str | os.PathLike, *, viewport: tuple[int, int] = VIEWPORT,
                   wait_selector: str | None = None, wait_s: float = 0.0, timeout_s: float = 120.0) -> Path:
    """Open ``url`` in headless Chromium and save what it shows as a PNG.

    Parameters
    ----------
    url : str
    png : path
    viewport : (int, int)
        Window size, CSS pixels.
    wait_selector : str, optional
        Wait for an element matching this CSS selector first.
    wait_s : float
        Then wait this long (seconds), e.g. for a viewer to load its data.
    timeout_s : float
        Longest wait for the page and the selector.

    Returns
    -------
    Path
        ``png``.
    """
    from playwright.sync_api import sync_playwright

    out = Path(png)
    out.parent.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium_path(), args=list(CHROMIUM_ARGS))
        try:
            page = browser.new_page(viewport={"width": int(viewport[0]), "height": int(viewport[1])})
            page.set_default_timeout(timeout_s * 1000)
            page.goto(url)
            if wait_selector:
                page.wait_for_selector(wait_selector)
            if wait_s > 0:
                page.wait_for_timeout(wait_s * 1000)
            cdp = page.context.new_cdp_session(page)
            shot = cdp.send("Page.captureScreenshot", {"format": "png"})
            out.write_bytes(base64.b64decode(shot["data"]))
        finally:
            browser.close()
    return out


def screenshot_recording(rrd: str | os.PathLike, png: str | os.PathLike, *, viewport: tuple[int, int] = VIEWPORT,
                         wait_s: float = 40.0) -> Path:
    """A recording as rerun's web viewer shows it (its blueprint, the last frame), saved as a PNG.

    Serves the file with the rerun CLI (``rerun FILE --serve-web``, loopback only) and opens
    the viewer in headless Chromium.

    Parameters
    ----------
    rrd : path
        Recording (``.rrd``).
    png : path
    viewport : (int, int)
    wait_s : float
        Seconds for the viewer to start and load the recording (software WebGL is slow).
    """
    rrd = Path(rrd)
    if not rrd.is_file():
        raise InputError(str(rrd), "a rerun recording (.rrd)", "no such file")
    cli = Path(sys.executable).with_name("rerun")
    web, grpc = free_port(), free_port()
    # its own process group: the `rerun` entry point starts the viewer binary as a child, ended with it
    proc = subprocess.Popen([str(cli), str(rrd), "--serve-web", "--web-viewer-port", str(web), "--port", str(grpc),
                             "--bind", "127.0.0.1"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 30
        while True:
            try:
                socket.create_connection(("127.0.0.1", web), timeout=1).close()
                break
            except OSError:
                if time.monotonic() > deadline or proc.poll() is not None:
                    raise InputError(str(rrd), "a recording the rerun CLI serves", "the viewer did not start")
                time.sleep(0.2)
        url = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy"
        return screenshot_url(url, png, viewport=viewport, wait_s=wait_s)
    finally:
        for sig in (signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                break
            try:
                proc.wait(timeout=10)
                break
            except subprocess.TimeoutExpired:
                continue


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Screenshot of a recording in rerun's web viewer (headless Chromium)")
    ap.add_argument("rrd", type=Path)
    ap.add_argument("png", type=Path)
    ap.add_argument("--size", default="1600x900", help="window size WxH (default 1600x900)")
    ap.add_argument("--wait", type=float, default=40.0, help="seconds for the viewer to load (default 40)")
    args = ap.parse_args(argv)
    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        ap.error(f"--size: expected WxH, found {args.size!r}")
    try:
        print(screenshot_recording(args.rrd, args.png, viewport=(w, h), wait_s=args.wait))
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
