"""Atomic file writes: every output of the toolkit goes through these.

A file is first written under a temporary name in its destination folder and
then renamed over the destination with :func:`os.replace`, which is atomic on
POSIX and Windows when both names are on the same file system.  A reader
therefore sees either the old file or the complete new one, never a partial
write, and an interrupted run leaves at most a hidden ``.<name>.tmp-*`` file.
A full or read-only disk is an :class:`~toolkit.errors.InputError` naming the
file, and leaves the earlier file as it was.

The temporary name keeps the destination's suffix, because some writers
(OpenCV's video writer, ``numpy.savez``) choose a format from it.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import tempfile
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from toolkit.errors import InputError

__all__ = [
    "temp_path",
    "atomic_path",
    "atomic_write_bytes",
    "atomic_write_text",
    "atomic_save_npz",
    "atomic_write_png",
    "encode_png",
]


def _current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: ``errno`` values that mean the destination cannot take the file (full, read-only, quota, permission):
#: reported as an :class:`~toolkit.errors.InputError` naming the file, not a traceback.
_UNWRITABLE = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM})

#: Permissions of files this module creates (``mkstemp`` alone would give 0600).
FILE_MODE = 0o666 & ~_current_umask()


def temp_path(path: str | os.PathLike) -> Path:
    """A fresh, empty temporary file next to ``path`` with the same suffix.

    Its name is ``.<stem>.tmp-<random><suffix>`` and its permissions those of
    an ordinary new file (:data:`FILE_MODE`).
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.tmp-", suffix=path.suffix)
    os.close(fd)
    os.chmod(tmp, FILE_MODE)
    return Path(tmp)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, make_parents: bool = True) -> Iterator[Path]:
    """Yield a temporary path to write; on success rename it to ``path``.

    Parameters
    ----------
    path : str or PathLike
        Final destination.
    make_parents : bool
        Create the destination's missing parent folders.

    Yields
    ------
    Path
        A temporary file in the destination folder, with the destination's
        suffix (it exists and is empty; writers may replace it).

    Notes
    -----
    If the body raises, the temporary file is removed and the destination is
    left untouched; a full or read-only disk (``ENOSPC``, ``EROFS``,
    ``EACCES`` ...) is raised as an InputError naming ``path``.
    """
    path = Path(path)
    try:
        if make_parents:
            path.parent.mkdir(parents=True, exist_ok=True)
        tmp = temp_path(path)
    except OSError as e:
        _raise_unwritable(path, e)
    try:
        yield tmp
        if not tmp.exists():
            raise InputError(
                str(path), "the writer to create its temporary file", f"no file at {tmp}"
            )
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        if isinstance(e, OSError):
            _raise_unwritable(path, e)
        raise


def _raise_unwritable(path: Path, e: OSError) -> None:
    """Re-raise ``e`` as an InputError naming ``path`` when the disk cannot take the file, else as it is."""
    if e.errno not in _UNWRITABLE:
        raise e
    raise InputError(str(path), "room and permission to write the file (an earlier one is kept as it was)",
                     f"{e.strerror or e} (a full or read-only disk, or no permission)") from None


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically and return the path.

    Parameters
    ----------
    path : str or PathLike
    data : bytes

    Returns
    -------
    Path
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8, ``\\n`` line ends) to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_save_npz(path: str | os.PathLike, **arrays) -> Path:
    """Save arrays into an uncompressed ``.npz`` archive atomically.

    Parameters
    ----------
    path : str or PathLike
        Destination; should end in ``.npz``.
    **arrays : array_like
        One entry per key.  Object arrays are refused so that readers never
        need ``allow_pickle``.

    Returns
    -------
    Path

    Raises
    ------
    InputError
        If an array has dtype ``object``.
    """
    converted = {}
    for key, value in arrays.items():
        a = np.asarray(value)
        if a.dtype == object:
            raise InputError(f"{path}: {key}", "a numeric or string array", "an object array")
        converted[key] = a
    buf = io.BytesIO()
    np.savez(buf, **converted)
    return atomic_write_bytes(path, buf.getvalue())


def encode_png(image: np.ndarray, where: str = "image") -> bytes:
    """Encode an image as PNG bytes.

    Parameters
    ----------
    image : ndarray of shape (H, W), (H, W, 3) or (H, W, 4)
        ``uint8`` grey / RGB / RGBA, or ``uint16`` single channel (depth).
    where : str
        Name used in error messages.

    Returns
    -------
    bytes
    """
    a = np.asarray(image)
    if a.dtype not in (np.uint8, np.uint16):
        raise InputError(where, "a uint8 or uint16 image", f"dtype {a.dtype}")
    if a.ndim == 3 and a.shape[2] == 3:
        a = cv2.cvtColor(a, cv2.COLOR_RGB2BGR)
    elif a.ndim == 3 and a.shape[2] == 4:
        a = cv2.cvtColor(a, cv2.COLOR_RGBA2BGRA)
    elif a.ndim != 2:
        raise InputError(
            where, "an image of shape (H, W), (H, W, 3) or (H, W, 4)", f"shape {a.shape}"
        )
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise InputError(where, "a non-empty image", f"shape {a.shape}")
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(a))
    if not ok:  # pragma: no cover - OpenCV encodes every uint8/uint16 array above
        raise InputError(
            where, "an image OpenCV can encode as PNG", f"shape {a.shape}, dtype {a.dtype}"
        )
    return buf.tobytes()


def atomic_write_png(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write an image as a lossless PNG atomically.

    Parameters
    ----------
    path : str or PathLike
    image : ndarray of shape (H, W), (H, W, 3) or (H, W, 4)
        ``uint8`` grey / RGB / RGBA (RGB order, not OpenCV's BGR), or ``uint16``
        single channel.

    Returns
    -------
    Path
    """
    return atomic_write_bytes(path, encode_png(image, where=str(path)))
