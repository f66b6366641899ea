"""Video files: streaming MP4 writing and frame-exact reading, RGB in and out.

Frames are ``(H, W, 3) uint8`` arrays in RGB order everywhere in the toolkit;
OpenCV's BGR order stays inside this module.

Writing uses OpenCV's FFmpeg backend with the MPEG-4 Part 2 codec (fourcc
``mp4v``), the one codec that opencv-python-headless can always encode into an
``.mp4`` (its H.264 encoders need hardware or a licence-restricted build).  It
is lossy: on smooth synthetic images the mean absolute error is about 3 grey
levels, on pixel noise it is far larger.  Keep exact images as PNG.

Writing is atomic: frames stream into a hidden temporary ``.mp4`` next to the
destination, which is renamed to the destination when the writer is closed
without error.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator

import cv2
import numpy as np

from toolkit.errors import InputError
from toolkit.io.atomic import temp_path

__all__ = [
    "DEFAULT_FOURCC",
    "VIDEO_SUFFIXES",
    "VideoWriter",
    "write_video",
    "VideoReader",
    "VideoInfo",
    "probe_video",
    "count_frames",
]

#: Suffixes of the video files the toolkit looks for in folders (trials, rigs).
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm")
#: Codec used for ``.mp4`` files (MPEG-4 Part 2, encodable by opencv-python-headless).
DEFAULT_FOURCC = "mp4v"


class VideoWriter:
    """Stream RGB frames into a video file, atomically.

    Parameters
    ----------
    path : str or PathLike
        Destination (``.mp4``); its folder is created if missing.
    fps : float
        Frames per second, > 0.
    fourcc : str
        Four-character codec code (default :data:`DEFAULT_FOURCC`).

    Notes
    -----
    The frame size is fixed by the first frame.  Nothing appears at ``path``
    until :meth:`close`; :meth:`abort` (or an exception inside a ``with``
    block) discards the temporary file.  A video needs at least one frame.

    Examples
    --------
    >>> with VideoWriter("out.mp4", fps=25) as w:          # doctest: +SKIP
    ...     for rgb in frames:
    ...         w.write(rgb)
    """

    def __init__(self, path: str | os.PathLike, fps: float, *, fourcc: str = DEFAULT_FOURCC):
        self.path = Path(path)
        if not (
            isinstance(fps, (int, float, np.integer, np.floating)) and np.isfinite(fps) and fps > 0
        ):
            raise InputError(f"{self.path}: fps", "a positive finite frame rate", f"{fps!r}")
        if not isinstance(fourcc, str) or len(fourcc) != 4:
            raise InputError(f"{self.path}: fourcc", "a four-character codec code", f"{fourcc!r}")
        self.fps = float(fps)
        self.fourcc = fourcc
        self.size: tuple[int, int] | None = None
        self.n_frames = 0
        self._writer = None
        self._tmp: Path | None = None
        self._closed = False

    def _open(self, width: int, height: int) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = temp_path(self.path)
        w = cv2.VideoWriter(
            str(self._tmp), cv2.VideoWriter_fourcc(*self.fourcc), self.fps, (width, height)
        )
        if not w.isOpened():
            self._tmp.unlink(missing_ok=True)
            self._tmp = None
            raise InputError(
                str(self.path),
                f"a video OpenCV can encode with fourcc {self.fourcc!r}",
                f"the writer failed to open for size {width}x{height}",
            )
        self._writer = w
        self.size = (width, height)

    def write(self, rgb: np.ndarray) -> None:
        """Append one frame.

        Parameters
        ----------
        rgb : ndarray of shape (H, W, 3), uint8
            RGB frame; every frame must have the size of the first.
        """
        if self._closed:
            raise InputError(str(self.path), "an open writer", "a closed writer")
        a = np.asarray(rgb)
        where = f"{self.path}: frame {self.n_frames}"
        if (
            a.dtype != np.uint8
            or a.ndim != 3
            or a.shape[2] != 3
            or a.shape[0] == 0
            or a.shape[1] == 0
        ):
            raise InputError(
                where,
                "an RGB image of shape (H, W, 3) and dtype uint8",
                f"shape {a.shape}, dtype {a.dtype}",
            )
        h, w = a.shape[:2]
        if w % 2 or h % 2:
            raise InputError(
                where,
                "an even width and height (MPEG-4 stores colour at half resolution)",
                f"{w}x{h}",
            )
        if self._writer is None:
            self._open(w, h)
        elif (w, h) != self.size:
            raise InputError(
                where, f"size {self.size[0]}x{self.size[1]} (the first frame's)", f"{w}x{h}"
            )
        self._writer.write(cv2.cvtColor(a, cv2.COLOR_RGB2BGR))
        self.n_frames += 1

    def close(self) -> Path:
        """Finish the file and move it to :attr:`path`.

        Returns
        -------
        Path

        Raises
        ------
        InputError
            If no frame was written.
        """
        if self._closed:
            return self.path
        if self._writer is None:
            self._closed = True
            raise InputError(str(self.path), "at least one frame", "no frames")
        self._writer.release()
        self._closed = True
        os.replace(self._tmp, self.path)
        self._tmp = None
        return self.path

    def abort(self) -> None:
        """Discard everything written so far; :attr:`path` is left untouched."""
        if self._writer is not None and not self._closed:
            self._writer.release()
        if self._tmp is not None:
            self._tmp.unlink(missing_ok=True)
        self._closed = True

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> "VideoWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def write_video(
    path: str | os.PathLike,
    frames: Iterable[np.ndarray],
    fps: float,
    *,
    fourcc: str = DEFAULT_FOURCC,
) -> int:
    """Write RGB frames to a video file atomically.

    Parameters
    ----------
    path : str or PathLike
        Destination, usually ``.mp4``.
    frames : iterable of ndarray of shape (H, W, 3), uint8
        RGB frames, all of one size; consumed lazily.
    fps : float
        Frames per second.
    fourcc : str
        Codec (default :data:`DEFAULT_FOURCC`).

    Returns
    -------
    int
        The number of frames written.

    Raises
    ------
    InputError
        Empty ``frames``, a frame of the wrong dtype, shape or size, or a codec
        OpenCV cannot open.
    """
    with VideoWriter(path, fps, fourcc=fourcc) as w:
        for frame in frames:
            w.write(frame)
    return w.n_frames


def _open_capture(path: Path) -> cv2.VideoCapture:
    if not path.exists():
        raise InputError(str(path), "an existing video file", "no such file")
    if not path.is_file():
        raise InputError(str(path), "a video file", "a folder or special file")
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    if not cap.isOpened():
        cap.release()
        raise InputError(
            str(path), "a video file OpenCV/FFmpeg can decode", "a file it cannot open"
        )
    return cap


def _count_by_decoding(cap: cv2.VideoCapture) -> int:
    n = 0
    while cap.grab():
        n += 1
    return n


@dataclass(frozen=True)
class VideoInfo:
    """What a video container says about its stream.

    Attributes
    ----------
    path : Path
    n_frames : int
        Frame count (from the container, or by decoding; see :func:`probe_video`).
    fps : float
        Frames per second.
    size : tuple of int
        ``(width, height)`` in pixels.
    """

    path: Path
    n_frames: int
    fps: float
    size: tuple[int, int]


def probe_video(path: str | os.PathLike, *, exact: bool = False) -> VideoInfo:
    """Frame count, frame rate and size of a video without decoding it.

    Parameters
    ----------
    path : str or PathLike
    exact : bool
        Count frames by grabbing every one instead of trusting the container's
        count (slower; for files from unknown sources).  Frames are also
        counted this way when the container gives no count.

    Returns
    -------
    VideoInfo

    Raises
    ------
    InputError
        Missing or unreadable file, or a video with no frame.
    """
    path = Path(path)
    cap = _open_capture(path)
    try:
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        n = int(round(cap.get(cv2.CAP_PROP_FRAME_COUNT)))
        if exact or n <= 0:
            n = _count_by_decoding(cap)
    finally:
        cap.release()
    if n <= 0:
        raise InputError(str(path), "a video with at least one frame", "no decodable frame")
    return VideoInfo(path, n, fps, size)


def count_frames(path: str | os.PathLike, *, exact: bool = False) -> int:
    """Number of frames in a video (see :func:`probe_video` for ``exact``).

    Raises
    ------
    InputError
        Missing or unreadable file, or a video with no frame.
    """
    return probe_video(path, exact=exact).n_frames


class VideoReader:
    """Read a video's frames as RGB arrays, sequentially or by index.

    Parameters
    ----------
    path : str or PathLike
    exact_count : bool
        Count frames by decoding (see :func:`count_frames`) rather than from
        the container.

    Attributes
    ----------
    path : Path
    fps : float
        Frames per second from the container.
    size : tuple of int
        ``(width, height)`` in pixels.

    Notes
    -----
    :meth:`read` is exact for any index: reading forward grabs the frames in
    between, reading backward reopens the file and grabs up to the index (cost
    proportional to the index).  The last frame read is cached, so reading the
    same index twice decodes once.  Iteration starts from frame 0 each time.

    Examples
    --------
    >>> with VideoReader("cam01.mp4") as video:              # doctest: +SKIP
    ...     for rgb in video:
    ...         ...
    """

    def __init__(self, path: str | os.PathLike, *, exact_count: bool = False):
        self.path = Path(path)
        info = probe_video(self.path, exact=exact_count)
        self.fps = info.fps
        self.size = info.size
        self._n = info.n_frames
        self._cap = _open_capture(self.path)
        self._next = 0  # index of the frame the capture returns next
        self._cached: tuple[int, np.ndarray] | None = None

    def __len__(self) -> int:
        return self._n

    def _reopen(self) -> None:
        self._cap.release()
        self._cap = _open_capture(self.path)
        self._next = 0

    def _decode_next(self) -> np.ndarray:
        ok, bgr = self._cap.read()
        if not ok or bgr is None:
            raise InputError(
                f"{self.path}: frame {self._next}",
                f"a decodable frame (the file declares {self._n})",
                "the end of the stream",
            )
        self._next += 1
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)

    def read(self, index: int) -> np.ndarray:
        """Frame ``index`` as an RGB ``(H, W, 3) uint8`` array.

        Raises
        ------
        IndexError
            If ``index`` is outside ``[0, len(self))`` (negative indices count from the end).
        """
        if self._cap is None:
            raise InputError(str(self.path), "an open reader", "a closed reader")
        i = int(index)
        if i < 0:
            i += self._n
        if not 0 <= i < self._n:
            raise IndexError(f"{self.path}: frame {index} out of range [0, {self._n})")
        if self._cached is not None and self._cached[0] == i:
            return self._cached[1].copy()
        if i < self._next:
            self._reopen()
        while self._next < i:
            if not self._cap.grab():
                raise InputError(
                    f"{self.path}: frame {self._next}",
                    f"a decodable frame (the file declares {self._n})",
                    "the end of the stream",
                )
            self._next += 1
        frame = self._decode_next()
        self._cached = (i, frame)
        return frame.copy()

    def __iter__(self) -> Iterator[np.ndarray]:
        for i in range(self._n):
            yield self.read(i)

    def close(self) -> None:
        """Release the decoder (idempotent)."""
        if self._cap is not None:
            self._cap.release()
            self._cap = None
        self._cached = None

    def __enter__(self) -> "VideoReader":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    def __del__(self):
        with contextlib.suppress(Exception):
            self.close()
