"""The correction page's web application (FastAPI): the JSON API and the static page.

Routes (``docs/correction.md``):

=====================================================  ===========================================
``GET  /``                                             the page (``static/index.html``)
``GET  /api/info``                                     run, cameras and image sizes, joints, bones
``GET  /api/frames``                                   ``{"frames": [t, ...]}``
``GET  /api/frames/{t}``                               ``{"cameras": {camera: {joint: [x, y]}},
                                                       "joints3d": {joint: [x, y, z]}, "cost": c, ...}``
``GET  /api/frames/{t}/cameras/{camera}/image``        the camera's image (JPEG)
``PUT  /api/frames/{t}/cameras/{camera}/joints/{joint}``  body ``{"xy": [x, y]}``: move a joint;
                                                       returns the frame as ``GET`` does
``POST /api/frames/{t}/undo``                          take back the frame's last move
``POST /api/frames/{t}/commit``                        add the frame's poses to the database
=====================================================  ===========================================

Unknown frames, cameras and joints answer 404 with a message (``{"detail":
...}``), malformed bodies 422; a commit without a database file answers 409.
FastAPI was chosen for its request validation (pydantic), its test client
and its small footprint; the page is plain HTML, CSS and JavaScript served
from the package (nothing is fetched from the internet).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import cv2
import numpy as np
from fastapi import Body, FastAPI, HTTPException, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, ConfigDict, Field, FiniteFloat

from toolkit.correction.session import CorrectionSession, NotFound
from toolkit.errors import InputError

#: Folder of the page's files (installed with the package).
STATIC_DIR = Path(__file__).resolve().parent / "static"
#: JPEG quality of the camera images sent to the page.
IMAGE_JPEG_QUALITY = 90


class JointMove(BaseModel):
    """Body of a joint move: the new position in image pixels."""

    model_config = ConfigDict(extra="forbid")
    xy: Annotated[list[FiniteFloat], Field(min_length=2, max_length=2)]


def create_app(session: CorrectionSession) -> FastAPI:
    """The web application serving one correction session.

    Parameters
    ----------
    session : CorrectionSession

    Returns
    -------
    fastapi.FastAPI
        Run it with uvicorn (``recipes/correct_poses.py``) or test it with
        ``fastapi.testclient.TestClient``.
    """
    app = FastAPI(title="billboard-toolkit pose correction", docs_url=None, redoc_url=None, openapi_url=None)
    app.state.session = session
    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")

    @app.exception_handler(RequestValidationError)
    async def malformed(request: Request, exc: RequestValidationError):
        # where and what only: the rejected input itself may not be valid JSON (NaN)
        return JSONResponse(status_code=422, content={"detail": [
            {"loc": [str(x) for x in e.get("loc", ())], "msg": str(e.get("msg", "")), "type": str(e.get("type", ""))}
            for e in exc.errors()]})

    def call(fn, *args):
        try:
            return fn(*args)
        except NotFound as e:
            raise HTTPException(status_code=404, detail=str(e)) from None
        except InputError as e:
            raise HTTPException(status_code=409, detail=str(e)) from None

    @app.get("/", include_in_schema=False)
    def index():
        return FileResponse(STATIC_DIR / "index.html", media_type="text/html")

    @app.get("/favicon.ico", include_in_schema=False)
    def favicon():
        return Response(status_code=204)

    @app.get("/api/info")
    def info():
        return session.info()

    @app.get("/api/frames")
    def frames():
        return {"frames": session.frames}

    @app.get("/api/frames/{t}")
    def frame(t: int):
        return call(session.frame_json, t)

    @app.get("/api/frames/{t}/cameras/{camera}/image")
    def image(t: int, camera: str):
        img = call(session.image, camera, t)
        ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(img[..., ::-1]),
                               [cv2.IMWRITE_JPEG_QUALITY, IMAGE_JPEG_QUALITY])
        if not ok:  # pragma: no cover - OpenCV encodes any uint8 image
            raise HTTPException(status_code=500, detail=f"could not encode the image of {camera}, frame {t}")
        return Response(content=buf.tobytes(), media_type="image/jpeg",
                        headers={"Cache-Control": "max-age=3600"})

    @app.put("/api/frames/{t}/cameras/{camera}/joints/{joint}")
    def move(t: int, camera: str, joint: str, body: Annotated[JointMove, Body()]):
        return call(session.move_joint, t, camera, joint, body.xy)

    @app.post("/api/frames/{t}/undo")
    def undo(t: int):
        return call(session.undo, t)

    @app.post("/api/frames/{t}/commit")
    def commit(t: int):
        return call(session.commit, t)

    return app
