"""The correction page in a real headless Chromium (Debian's package), driven by Playwright.

One server (uvicorn in a thread) and one browser for the module; each test opens a page.
Skipped, saying why, only where Chromium or Playwright is not installed (``scripts/setup.sh``
installs both).
"""

from __future__ import annotations

import shutil
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from toolkit.correction import EDITS_FILE, CorrectionSession, create_app
from toolkit.silhouettes import SilhouetteDatabase, read_edits
from toolkit.skeleton import SKELETON_14

#: Debian's Chromium (``apt-get install chromium``, scripts/setup.sh).
CHROMIUM = Path("/usr/bin/chromium")
#: WebGL and canvas in headless Chromium without a GPU.
CHROMIUM_ARGS = ["--use-angle=swiftshader", "--no-sandbox"]
#: Screen pixels of the drag.
DRAG_PX = (24.0, -16.0)
#: Where the dropped joint lands, image pixels, against where the drag put it (sub-pixel mouse rounding).
DROP_TOLERANCE_PX = 1.0
#: Page actions wait at most this long, ms.
TIMEOUT_MS = 20000

sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright's Python package is not installed "
                               "(pip install -e '.[test]')")
if not CHROMIUM.is_file():
    pytest.skip(f"Chromium is not installed at {CHROMIUM} (scripts/setup.sh installs Debian's chromium package)",
                allow_module_level=True)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def served(tiny_run, tmp_path_factory):
    """A copy of the run served on a free loopback port."""
    import uvicorn

    base = tmp_path_factory.mktemp("served")
    run, db = base / "run", base / "db.npz"
    shutil.copytree(tiny_run.run, run)
    shutil.copyfile(tiny_run.db, db)
    session = CorrectionSession(run, database=db, foreground="chroma")
    port = _free_port()
    server = uvicorn.Server(uvicorn.Config(create_app(session), host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not server.started:
        if time.monotonic() > deadline or not thread.is_alive():
            pytest.fail("the correction server did not start")
        time.sleep(0.05)
    yield session, f"http://127.0.0.1:{port}/", db
    server.should_exit = True
    thread.join(timeout=10)
    session.close()


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield b
        b.close()


def _open(browser, url):
    """A page with the app loaded; collects console errors, page errors and failed requests."""
    page = browser.new_page(viewport={"width": 1400, "height": 900})
    page.set_default_timeout(TIMEOUT_MS)
    problems, images = [], {}
    page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
    page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
    page.on("requestfailed", lambda r: problems.append(f"request failed: {r.url}"))
    page.on("response", lambda r: images.__setitem__(r.url, r.status) if r.url.endswith("/image") else None)
    page.goto(url)
    page.wait_for_selector("circle[data-joint]")
    page.wait_for_load_state("networkidle")
    return page, problems, images


def test_page_loads_with_every_image_and_one_joint_per_camera(browser, served):
    session, url, _ = served
    page, problems, images = _open(browser, url)
    cams = session.camera_names
    assert problems == []
    assert sorted(images) == sorted(f"{url}api/frames/0/cameras/{c}/image" for c in cams)
    assert set(images.values()) == {200}
    # every image decoded by the browser (an SVG <image> has no naturalWidth: load it as an <img>)
    sizes = page.evaluate("""async (urls) => Promise.all(urls.map((u) => new Promise((ok) => {
        const i = new Image(); i.onload = () => ok([i.naturalWidth, i.naturalHeight]); i.onerror = () => ok(null);
        i.src = u; })))""", sorted(images))
    assert sizes == [[480, 270]] * len(cams)
    pairs = page.eval_on_selector_all("circle[data-joint]", "cs => cs.map(c => [c.dataset.camera, c.dataset.joint])")
    assert sorted(map(tuple, pairs)) == sorted((c, j) for c in cams for j in SKELETON_14.joint_names)
    assert page.locator("#view3d circle").count() == SKELETON_14.n_joints
    assert "mm" in page.locator("#cost").inner_text()
    page.close()


def test_mouse_drag_moves_the_joint_retriangulates_and_writes_edits(browser, served):
    session, url, _ = served
    page, problems, _ = _open(browser, url)
    cam, joint = "cam_1", "r_wrist"
    before = session.frame_json(0)
    circle = page.locator(f'circle[data-camera="{cam}"][data-joint="{joint}"]')
    box = circle.bounding_box()
    scale = page.evaluate("(c) => c.ownerSVGElement.getScreenCTM().a", circle.element_handle())
    x0, y0 = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    # where the page puts the joint under the starting mouse position (image pixels)
    start = page.evaluate("""([c, x, y]) => { const s = c.ownerSVGElement, p = s.createSVGPoint(); p.x = x; p.y = y;
        const q = p.matrixTransform(s.getScreenCTM().inverse()); return [q.x, q.y]; }""",
                          [circle.element_handle(), x0, y0])
    with page.expect_response(lambda r: r.request.method == "PUT" and r.url.endswith(f"/joints/{joint}")) as resp:
        page.mouse.move(x0, y0)
        page.mouse.down()
        page.mouse.move(x0 + DRAG_PX[0] / 2, y0 + DRAG_PX[1] / 2, steps=4)
        page.mouse.move(x0 + DRAG_PX[0], y0 + DRAG_PX[1], steps=4)
        page.mouse.up()
    assert resp.value.status == 200
    after = session.frame_json(0)
    expected = np.add(start, np.divide(DRAG_PX, scale))
    np.testing.assert_allclose(after["cameras"][cam][joint], expected, atol=DROP_TOLERANCE_PX)
    moved = np.subtract(after["cameras"][cam][joint], before["cameras"][cam][joint])
    assert np.linalg.norm(moved) > 0.5 * np.linalg.norm(DRAG_PX) / scale
    assert np.linalg.norm(np.subtract(after["joints3d"][joint], before["joints3d"][joint])) > 1e-3
    (e,) = read_edits(session.run / EDITS_FILE).edits
    assert (e.frame, e.camera, e.joint_names) == (0, cam, (joint,))
    np.testing.assert_allclose(dict(e.joints)[joint], after["cameras"][cam][joint], atol=1e-3)
    # the page shows the new position, and the drag is undone with the button
    cx = float(circle.get_attribute("cx"))
    assert cx == pytest.approx(after["cameras"][cam][joint][0], abs=1e-3)
    with page.expect_response(lambda r: r.url.endswith("/undo")):
        page.click("#undo")
    np.testing.assert_allclose(session.frame_json(0)["cameras"][cam][joint], before["cameras"][cam][joint])
    assert problems == []
    page.close()


def test_commit_button_grows_the_database_by_the_frames_poses(browser, served):
    session, url, db = served
    page, problems, _ = _open(browser, url)
    n0 = len(SilhouetteDatabase.load(db))
    page.locator("#frame-slider").fill("2")
    page.wait_for_selector("text=frame 2: drag")
    with page.expect_response(lambda r: r.url.endswith("/api/frames/2/commit")) as resp:
        page.click("#commit")
    assert resp.value.status == 200
    page.wait_for_selector("#status:has-text('added')")
    db_now = SilhouetteDatabase.load(db)
    assert len(db_now) == n0 + len(session.camera_names)
    assert list(db_now.frame[n0:]) == [2] * len(session.camera_names)
    assert problems == []
    page.close()

