"""recipes/correct_poses.py: refusals and the page's screenshot (serving is tested through the app and the
browser tests)."""

from __future__ import annotations

import shutil
import socket
from pathlib import Path

import cv2
import pytest

from recipes import correct_poses
from toolkit.correction import EDITS_FILE


def test_a_folder_that_is_not_a_run_is_refused(tmp_path, capsys):
    rc = correct_poses.main([str(tmp_path / "nothing"), "--port", "8123"])
    assert rc == 2 and "nothing" in capsys.readouterr().err


def test_bad_port_is_an_argument_error(tmp_path):
    with pytest.raises(SystemExit):
        correct_poses.main([str(tmp_path), "--port", "70000"])


def test_screenshot_of_the_page(tiny_run, tmp_path):
    """In its own module: Playwright's sync API cannot start inside another module's running browser."""
    pytest.importorskip("playwright.sync_api", reason="Playwright's Python package is not installed")
    if not Path("/usr/bin/chromium").is_file():
        pytest.skip("Chromium is not installed at /usr/bin/chromium (scripts/setup.sh installs it)")
    run = tmp_path / "run"
    shutil.copytree(tiny_run.run, run)
    png = tmp_path / "page.png"
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    rc = correct_poses.main([str(run), "--db", str(tiny_run.db), "--foreground", "chroma",
                                            "--port", str(port), "--screenshot", str(png)])
    assert rc == 0
    img = cv2.imread(str(png))
    assert img is not None and img.shape[:2] == (720, 1500) and img.std() > 10  # a picture, not a blank
    assert not (run / EDITS_FILE).exists()  # looking writes nothing
