"""Calibration boards: geometry, detection in images, and frames read from images or videos.

A board is a checkerboard (``rows x cols`` inner corners) or a ChArUco board
(``rows x cols`` inner corners, i.e. ``(rows + 1) x (cols + 1)`` squares, ArUco
markers in the white squares).  Board coordinates are metres in the board's
plane ``z = 0``, x along the columns, y along the rows, z pointing *into* the
board (OpenCV's convention: a camera that sees the printed side has a negative
z in board coordinates).

Detection uses OpenCV: ``findChessboardCornersSB`` (then ``findChessboardCorners``
with sub-pixel refinement when the first fails), and ``aruco.CharucoDetector``.
When the declared corner count is not found, neighbouring counts are tried so
that the error says which board the images actually show (a wrong declared size
is reported as such, not as "no board detected").
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from toolkit.errors import InputError

__all__ = ["Board", "BoardDetection", "read_board_toml", "detect_board", "board_frames", "IMAGE_SUFFIXES",
           "VIDEO_SUFFIXES", "ARUCO_DICTIONARIES"]

#: Image and video suffixes read from a folder.
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm")
#: ArUco dictionaries accepted for ChArUco boards (name -> OpenCV constant).
ARUCO_DICTIONARIES = {n: getattr(cv2.aruco, n) for n in dir(cv2.aruco) if n.startswith("DICT_")}
#: Sub-pixel corner refinement: half window (pixels) and stop criteria.
SUBPIX_WINDOW = (5, 5)
SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)


@dataclass(frozen=True)
class Board:
    """A planar calibration target.

    Parameters
    ----------
    kind : str
        ``"checkerboard"`` or ``"charuco"``.
    rows, cols : int
        Inner corners along the board's height and width (both >= 2).
    square : float
        Side of a square, metres.
    marker : float or None
        ChArUco only: side of an ArUco marker, metres (smaller than ``square``).
    dictionary : str
        ChArUco only: the ArUco dictionary name (``DICT_4X4_50``, ...).
    """

    kind: str
    rows: int
    cols: int
    square: float
    marker: float | None = None
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self):
        if self.kind not in ("checkerboard", "charuco"):
            raise InputError("board kind", "'checkerboard' or 'charuco'", repr(self.kind))
        if int(self.rows) < 2 or int(self.cols) < 2:
            raise InputError("board corners", "at least 2 x 2 inner corners", f"{self.rows} x {self.cols}")
        if not (np.isfinite(self.square) and self.square > 0):
            raise InputError("board square size", "a positive size", repr(self.square))
        if self.kind == "charuco":
            if self.marker is None or not (0 < self.marker < self.square):
                raise InputError("board marker size", "a ChArUco marker size between 0 and the square size",
                                 f"marker {self.marker!r}, square {self.square!r}")
            if self.dictionary not in ARUCO_DICTIONARIES:
                raise InputError("board dictionary", "an ArUco dictionary name such as DICT_4X4_50",
                                 repr(self.dictionary))

    @property
    def n_corners(self) -> int:
        return int(self.rows) * int(self.cols)

    def object_points(self) -> np.ndarray:
        """Inner corners in board coordinates, (rows * cols, 3) metres, row-major (OpenCV's order)."""
        r, c = np.mgrid[0:self.rows, 0:self.cols]
        return np.stack([c.ravel(), r.ravel(), np.zeros(r.size)], 1).astype(float) * self.square

    def charuco(self):
        """The ``cv2.aruco.CharucoBoard`` (ChArUco boards only)."""
        d = cv2.aruco.getPredefinedDictionary(ARUCO_DICTIONARIES[self.dictionary])
        return cv2.aruco.CharucoBoard((self.cols + 1, self.rows + 1), self.square, self.marker, d)

    def describe(self) -> str:
        s = f"{self.kind} {self.rows}x{self.cols} inner corners, {self.square * 1000:g} mm squares"
        return s + (f", {self.marker * 1000:g} mm markers ({self.dictionary})" if self.kind == "charuco" else "")


def read_board_toml(path: str | os.PathLike) -> Board:
    """Read a board from a TOML file.

    The file holds ``kind``, ``corners = [rows, cols]``, ``square_mm`` and, for
    ChArUco, ``marker_mm`` and optionally ``dictionary``, at the top level or in a
    ``[board]`` table.

    Raises
    ------
    InputError
        Missing file, syntax error or a missing / wrong field (named).
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(str(p), "a board TOML file", "no such file")
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise InputError(str(p), "a valid TOML file", f"a syntax error: {e}") from None
    t = doc.get("board", doc)
    for f in ("kind", "corners", "square_mm"):
        if f not in t:
            raise InputError(f"{p}: {f}", f"a '{f}' field", f"fields {sorted(t)}")
    corners = t["corners"]
    if not (isinstance(corners, list) and len(corners) == 2 and all(isinstance(v, int) for v in corners)):
        raise InputError(f"{p}: corners", "[rows, cols] inner corners (integers)", repr(corners))
    marker = t.get("marker_mm")
    return Board(str(t["kind"]), corners[0], corners[1], float(t["square_mm"]) / 1000.0,
                 None if marker is None else float(marker) / 1000.0, str(t.get("dictionary", "DICT_4X4_50")))


@dataclass(frozen=True, eq=False)
class BoardDetection:
    """The corners of a board found in one image.

    Attributes
    ----------
    source : str
        The image file (or ``video:frame``).
    size : tuple of int
        Image ``(width, height)``.
    ids : ndarray of shape (N,) of int
        Indices of the corners found in :meth:`Board.object_points` (all of them for a checkerboard).
    corners : ndarray of shape (N, 2)
        Pixel positions.
    """

    source: str
    size: tuple[int, int]
    ids: np.ndarray
    corners: np.ndarray


def _gray(image: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image


def _find_checkerboard(gray: np.ndarray, rows: int, cols: int) -> np.ndarray | None:
    # the sector-based detector first: its corners are more accurate than cornerSubPix's on blurred or
    # strongly tilted boards (several pixels on the demo's cam04_03); the classic one finds more boards
    ok, c = cv2.findChessboardCornersSB(gray, (cols, rows), cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
    if not ok:
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
        ok, c = cv2.findChessboardCorners(gray, (cols, rows), flags)
        if ok:
            c = cv2.cornerSubPix(gray, c.astype(np.float32), SUBPIX_WINDOW, (-1, -1), SUBPIX_CRITERIA)
    if not ok:
        return None
    c = c.reshape(rows, cols, 2).astype(float)
    # the printed side faces the camera, so columns then rows turn like the image's x then y axes; OpenCV
    # sometimes orders a grid mirrored (rows reversed), which would give a board pose seen from behind
    u, v = c[0, -1] - c[0, 0], c[-1, 0] - c[0, 0]
    if u[0] * v[1] - u[1] * v[0] < 0:
        c = c[::-1]
    # OpenCV may start at either end (a 180 degree turn).  A board whose corner squares differ in colour
    # ((rows + 1) + (cols + 1) odd, e.g. 5 x 8 squares) says which end is which: the first corner is the
    # one whose outer diagonal square is dark, in every camera.  Otherwise: the end nearest the image's top-left.
    a, b = _outer_square(gray, c[0, 0], c[1, 1]), _outer_square(gray, c[-1, -1], c[-2, -2])
    if (rows + cols) % 2 == 1 and a is not None and b is not None and abs(a - b) > 40:
        flip = a > b
    else:
        flip = c[0, 0].sum() > c[-1, -1].sum()
    if flip:
        c = c[::-1, ::-1]
    return c.reshape(-1, 2)


def _outer_square(gray: np.ndarray, corner: np.ndarray, inner: np.ndarray) -> float | None:
    """Mean grey level at the centre of the square diagonally outside ``corner`` (None off the image)."""
    p = corner + 0.5 * (corner - inner)
    x, y = int(round(p[0])), int(round(p[1]))
    h, w = gray.shape[:2]
    if not (2 <= x < w - 2 and 2 <= y < h - 2):
        return None
    return float(gray[y - 2:y + 3, x - 2:x + 3].mean())


#: ChArUco: a detection whose corners are farther than this from the board-plane homography through them is
#: not the declared board (another grid), pixels (or 2 % of the corners' spread, if larger).
CHARUCO_HOMOGRAPHY_PX = 3.0


def _find_charuco(gray: np.ndarray, board: Board):
    """ChArUco corner ids and pixels, and the markers (corners (M, 4, 2), ids (M,)) found."""
    det = cv2.aruco.CharucoDetector(board.charuco())
    cc, ci, mc, mi = det.detectBoard(gray)
    markers = (np.zeros((0, 4, 2)), np.zeros(0, int)) if mi is None else \
        (np.asarray(mc, float).reshape(-1, 4, 2), mi.ravel().astype(int))
    if ci is None or len(ci) == 0:
        return np.zeros(0, int), np.zeros((0, 2)), markers
    return ci.ravel().astype(int), cc.reshape(-1, 2).astype(float), markers


def charuco_consistency(board: Board, ids: np.ndarray, corners: np.ndarray, markers) -> str | None:
    """Why a ChArUco detection contradicts the declared board (``None`` when it agrees).

    Checks that every marker id belongs to the board, that the corners lie on one plane through a
    homography (a wrong grid puts them in the wrong places), and that the markers measure the declared
    marker size relative to the squares (mapped to the board plane by that homography).
    """
    n_markers = len(board.charuco().getIds())
    mc, mi = markers
    if len(mi) and mi.max() >= n_markers:
        return (f"ArUco marker ids up to {int(mi.max())} while a {board.rows}x{board.cols}-corner ChArUco board has "
                f"{n_markers} markers (ids 0-{n_markers - 1}): check --corners and the dictionary")
    if len(ids) < 6:
        return None
    O = board.object_points()[ids, :2]
    H, _ = cv2.findHomography(O, corners, 0)
    if H is None:
        return None
    proj = cv2.perspectiveTransform(O.reshape(-1, 1, 2), H).reshape(-1, 2)
    err = float(np.sqrt(np.mean(np.sum((proj - corners) ** 2, 1))))
    spread = float(np.linalg.norm(corners.max(0) - corners.min(0)))
    if err > max(CHARUCO_HOMOGRAPHY_PX, 0.02 * spread):
        return (f"ChArUco corners {err:.1f} px off one plane: the markers are not laid out as on a "
                f"{board.rows}x{board.cols}-corner board; check --corners")
    if len(mi):
        back = cv2.perspectiveTransform(mc.reshape(-1, 1, 2), np.linalg.inv(H)).reshape(-1, 4, 2)
        side = float(np.median(np.linalg.norm(back - np.roll(back, 1, axis=1), axis=2)))
        if abs(side / board.marker - 1) > 0.1:
            return (f"the markers measure {side * 1000:.0f} mm on a grid of {board.square * 1000:g} mm squares, "
                    f"not {board.marker * 1000:g} mm as declared: check --marker-mm (and --square-mm)")
    return None


def detect_board(image: np.ndarray, board: Board, source: str = "image",
                 min_corners: int | None = None) -> BoardDetection | None:
    """Find a board's corners in an image.

    Parameters
    ----------
    image : ndarray of shape (H, W) or (H, W, 3)
        8-bit grey or BGR image.
    board : Board
    source : str
        Name of the image for messages.
    min_corners : int, optional
        ChArUco: fewest corners for a detection (default: 6).

    Returns
    -------
    BoardDetection or None
        ``None`` when the board is not found (a checkerboard needs every corner).
    """
    gray = _gray(np.asarray(image))
    h, w = gray.shape[:2]
    if board.kind == "checkerboard":
        c = _find_checkerboard(gray, board.rows, board.cols)
        if c is None:
            return None
        return BoardDetection(source, (w, h), np.arange(board.n_corners), c)
    ids, c, markers = _find_charuco(gray, board)
    if len(ids) < (min_corners or 6) or charuco_consistency(board, ids, c, markers) is not None:
        return None
    return BoardDetection(source, (w, h), ids, c)


def _declared_size_message(images: list[tuple[str, np.ndarray]], board: Board) -> str | None:
    """When no image shows ``board``, which board they show instead (``None`` if none found)."""
    gray = [_gray(im) for _, im in images[:3]]
    if board.kind == "checkerboard":
        cand = {(board.cols, board.rows)}
        for dr in (-2, -1, 0, 1, 2):
            for dc in (-2, -1, 0, 1, 2):
                if (dr or dc) and board.rows + dr >= 2 and board.cols + dc >= 2:
                    cand.add((board.rows + dr, board.cols + dc))
        for rows, cols in sorted(cand, key=lambda rc: abs(rc[0] - board.rows) + abs(rc[1] - board.cols)):
            for g in gray:
                flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
                ok, _ = cv2.findChessboardCorners(g, (cols, rows), flags)
                if ok:
                    return (f"the images show a checkerboard of {rows}x{cols} inner corners (squares minus one), "
                            f"not {board.rows}x{board.cols} as declared: check --corners")
        return None
    # ChArUco: what contradicts the declared board, and which grid the images show
    for g in gray:
        ids, c, markers = _find_charuco(g, board)
        why = charuco_consistency(board, ids, c, markers)
        if why is None and len(markers[1]):
            why = (f"{len(markers[1])} ArUco markers of {board.dictionary} but too few ChArUco corners of a "
                   f"{board.rows}x{board.cols}-corner board")
        if why is None:
            continue
        for dr in (0, -1, 1, -2, 2):
            for dc in (0, -1, 1, -2, 2):
                if (dr or dc) and board.rows + dr >= 2 and board.cols + dc >= 2:
                    other = Board("charuco", board.rows + dr, board.cols + dc, board.square, board.marker,
                                  board.dictionary)
                    i2, c2, m2 = _find_charuco(g, other)
                    if len(i2) >= 6 and charuco_consistency(other, i2, c2, m2) is None:
                        return (f"{why}; the images show a ChArUco board of {other.rows}x{other.cols} inner corners, "
                                f"not {board.rows}x{board.cols} as declared")
        return why
    for name in ("DICT_4X4_50", "DICT_5X5_100", "DICT_6X6_250", "DICT_7X7_250", "DICT_ARUCO_ORIGINAL"):
        if name == board.dictionary:
            continue
        det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(ARUCO_DICTIONARIES[name]))
        for g in gray:
            _, mi, _ = det.detectMarkers(g)
            if mi is not None and len(mi) >= 4:
                return f"no {board.dictionary} markers but {len(mi)} markers of {name}: check --dictionary"
    return None


def _read_image(path: Path) -> np.ndarray:
    im = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if im is None:
        raise InputError(str(path), "an image OpenCV can read", "an unreadable file")
    return im


def board_frames(path: str | os.PathLike, every_s: float = 1.0, max_frames: int = 200):
    """Images of a folder (or a video's frames), as ``(name, image)`` pairs.

    Parameters
    ----------
    path : path-like
        An image file, a video, or a folder of images and / or videos (sorted by name).
    every_s : float
        Videos: seconds between the frames kept.
    max_frames : int
        Stop after this many frames in total.

    Yields
    ------
    name : str
    image : ndarray of shape (H, W, 3) uint8 (BGR)

    Raises
    ------
    InputError
        A missing path, or a folder without images or videos.
    """
    p = Path(path)
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES + VIDEO_SUFFIXES
                       and not f.name.startswith("."))
        if not files:
            raise InputError(str(p), f"images ({', '.join(IMAGE_SUFFIXES)}) or videos ({', '.join(VIDEO_SUFFIXES)})",
                             "none")
    elif p.is_file():
        files = [p]
    else:
        raise InputError(str(p), "an image or video file or a folder of them", "no such path")
    n = 0
    for f in files:
        if f.suffix.lower() in IMAGE_SUFFIXES:
            yield f.name, _read_image(f)
            n += 1
        else:
            cap = cv2.VideoCapture(str(f))
            if not cap.isOpened():
                raise InputError(str(f), "a video OpenCV can read", "an unreadable file")
            fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
            step = max(1, int(round(every_s * fps)))
            i = 0
            while n < max_frames:
                ok, im = cap.read()
                if not ok:
                    break
                if i % step == 0:
                    yield f"{f.name}:{i}", im
                    n += 1
                i += 1
            cap.release()
        if n >= max_frames:
            return


def detect_in_frames(frames, board: Board, where: str) -> tuple[list[BoardDetection], list[tuple[str, str]]]:
    """Detect a board in every frame; the frames without it, with the reason.

    Parameters
    ----------
    frames : iterable of (str, ndarray)
        From :func:`board_frames`.
    board : Board
    where : str
        The folder, for the error message.

    Returns
    -------
    detections : list of BoardDetection
    missed : list of (str, str)
        ``(frame name, reason)`` for frames without a board.

    Raises
    ------
    InputError
        No frame shows the board; the message says which board the images show when
        another corner count (or a ChArUco board not matching the declared one) is found.
    """
    dets, missed, kept = [], [], []
    for name, im in frames:
        d = detect_board(im, board, name)
        if d is None:
            missed.append((name, f"no {board.describe()} found"))
            if len(kept) < 3:
                kept.append((name, im))
        else:
            dets.append(d)
    if not dets:
        hint = _declared_size_message(kept, board) if kept else None
        raise InputError(where, f"images showing a {board.describe()}",
                         hint or f"no board in any of {len(missed)} images")
    return dets, missed


__all__ += ["detect_in_frames", "charuco_consistency"]
