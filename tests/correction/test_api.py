"""The JSON API through FastAPI's test client: routes, bodies, error codes, files written."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from toolkit.correction import EDITS_FILE, CorrectionSession, create_app
from toolkit.silhouettes import SilhouetteDatabase, read_edits
from toolkit.skeleton import SKELETON_14


@pytest.fixture
def client(run_copy):
    s = CorrectionSession(run_copy.run, database=run_copy.db, foreground="chroma")
    with TestClient(create_app(s)) as c:
        yield c
    s.close()


def test_frames_and_frame(client):
    assert client.get("/api/frames").json() == {"frames": [0, 1, 2]}
    f = client.get("/api/frames/1").json()
    assert set(f["cameras"]) == {"cam_0", "cam_1", "cam_2"}
    assert set(f["cameras"]["cam_0"]) == set(SKELETON_14.joint_names)
    assert all(len(xy) == 2 for xy in f["cameras"]["cam_0"].values())
    assert set(f["joints3d"]) == set(SKELETON_14.joint_names) and len(f["joints3d"]["head"]) == 3
    assert 0 < f["cost"] < 0.1  # metres
    info = client.get("/api/info").json()
    assert info["cameras"]["cam_0"]["size"] == [480, 270] and len(info["bones"]) == 13


def test_page_and_images_are_served(client):
    r = client.get("/")
    assert r.status_code == 200 and 'id="frame-slider"' in r.text and "http" not in r.text.replace(
        'xmlns="http://www.w3.org', "")  # nothing fetched from the internet
    assert client.get("/static/app.js").status_code == 200
    r = client.get("/api/frames/0/cameras/cam_2/image")
    assert r.status_code == 200 and r.headers["content-type"] == "image/jpeg" and r.content[:2] == b"\xff\xd8"


def test_put_moves_a_joint_and_writes_edits(client, run_copy):
    old = client.get("/api/frames/0").json()
    xy = np.add(old["cameras"]["cam_0"]["l_ankle"], [3.0, 1.5]).tolist()
    r = client.put("/api/frames/0/cameras/cam_0/joints/l_ankle", json={"xy": xy})
    assert r.status_code == 200
    f = r.json()
    np.testing.assert_allclose(f["cameras"]["cam_0"]["l_ankle"], xy)
    assert f["joints3d"]["l_ankle"] != old["joints3d"]["l_ankle"]
    assert client.get("/api/frames/0").json() == f
    (e,) = read_edits(run_copy.run / EDITS_FILE).edits
    np.testing.assert_allclose(dict(e.joints)["l_ankle"], xy, atol=1e-3)
    u = client.post("/api/frames/0/undo").json()
    assert u["cameras"]["cam_0"]["l_ankle"] == old["cameras"]["cam_0"]["l_ankle"]


def test_commit_grows_the_database(client, run_copy):
    n0 = len(SilhouetteDatabase.load(run_copy.db))
    r = client.post("/api/frames/1/commit")
    assert r.status_code == 200 and r.json()["added"] == 3
    assert len(SilhouetteDatabase.load(run_copy.db)) == n0 + 3


@pytest.mark.parametrize("url", ["/api/frames/9", "/api/frames/9/cameras/cam_0/image",
                                 "/api/frames/0/cameras/cam_7/image"])
def test_unknown_things_are_404_with_a_message(client, url):
    r = client.get(url)
    assert r.status_code == 404 and isinstance(r.json()["detail"], str) and r.json()["detail"]


@pytest.mark.parametrize("url,what", [("/api/frames/9/cameras/cam_0/joints/head", "frame 9"),
                                      ("/api/frames/0/cameras/cam_7/joints/head", "camera 'cam_7'"),
                                      ("/api/frames/0/cameras/cam_0/joints/nose", "joint 'nose'")])
def test_put_to_unknown_things_is_404(client, url, what, run_copy):
    r = client.put(url, json={"xy": [10.0, 20.0]})
    assert r.status_code == 404 and what in r.json()["detail"]
    assert client.post(url.split("/cameras")[0] + "/commit").status_code in (200, 404)
    assert not (run_copy.run / EDITS_FILE).exists()


@pytest.mark.parametrize("body", [{}, {"xy": [1.0]}, {"xy": [1.0, 2.0, 3.0]}, {"xy": ["a", 2]},
                                  {"xy": [1.0, 2.0], "extra": 1}, [1, 2], {"xy": None}])
def test_malformed_bodies_are_422(client, body, run_copy):
    r = client.put("/api/frames/0/cameras/cam_0/joints/head", json=body)
    assert r.status_code == 422
    assert not (run_copy.run / EDITS_FILE).exists()


def test_non_finite_positions_are_422(client):
    r = client.put("/api/frames/0/cameras/cam_0/joints/head", content=b'{"xy": [NaN, 1.0]}',
                   headers={"content-type": "application/json"})
    assert r.status_code == 422


def test_commit_without_a_database_file_is_409(run_copy, tmp_path):
    s = CorrectionSession(run_copy.run, database=tmp_path / "none.npz", foreground="chroma")
    with TestClient(create_app(s)) as c:
        r = c.post("/api/frames/0/commit")
    assert r.status_code == 409 and "none.npz" in r.json()["detail"]
    assert not (tmp_path / "none.npz").exists()
    s.close()


def test_writes_only_the_edits_file_and_the_database(client, run_copy):
    before = {p: p.stat().st_mtime_ns for p in run_copy.run.rglob("*")}
    client.put("/api/frames/2/cameras/cam_2/joints/neck", json={"xy": [200.0, 100.0]})
    client.post("/api/frames/2/commit")
    after = {p: p.stat().st_mtime_ns for p in run_copy.run.rglob("*")}
    changed = {p.name for p in after if before.get(p) != after[p]}
    assert changed == {EDITS_FILE}
    parent = {p.name for p in run_copy.db.parent.iterdir()}
    assert parent == {"run", "db.npz"}  # no stray temporary files
