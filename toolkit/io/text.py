"""Text files read as users hand them over: with a byte-order mark, too large, nested without end.

Every JSON and TOML reader of the toolkit reads through these, so that a file
a spreadsheet saved with a UTF-8 byte-order mark is read as the same file
without it, a file nested thousands of levels deep (Python's parsers recurse
and raise ``RecursionError``) or larger than any file of its kind is an
:class:`~toolkit.errors.InputError` naming the file, and a folder or missing
file is said to be one.
"""

from __future__ import annotations

import json
import os
import tomllib
from pathlib import Path

from toolkit.errors import InputError

__all__ = ["MAX_TEXT_BYTES", "require_file", "read_text", "parse_json", "parse_toml", "load_json", "load_toml"]

#: Largest text file read, bytes (keypoint files of a whole video stay far below; a larger one is no such file).
MAX_TEXT_BYTES = 512 << 20
#: The UTF-8 byte-order mark some editors write at the start of a file.
BOM = "\ufeff"


def require_file(path: str | os.PathLike, what: str) -> Path:
    """``path`` as a Path when it is an existing regular file, else an InputError saying what it is.

    Parameters
    ----------
    path : str or PathLike
    what : str
        What the file should be, for messages (``"a TOML config file"``).

    Returns
    -------
    Path

    Raises
    ------
    InputError
        No such file, a folder or a special file.
    """
    p = Path(path)
    if not p.exists():
        raise InputError(str(p), what, "no such file")
    if not p.is_file():
        raise InputError(str(p), what, "a folder" if p.is_dir() else "a special file")
    return p


def read_text(path: str | os.PathLike, what: str = "a text file", max_bytes: int = MAX_TEXT_BYTES) -> str:
    """The UTF-8 text of ``path`` (a leading byte-order mark dropped).

    Parameters
    ----------
    path : str or PathLike
    what : str
        What the file should be, for messages (``"a TOML config file"``).
    max_bytes : int
        Larger files are refused before they are read.

    Returns
    -------
    str

    Raises
    ------
    InputError
        No such file, a folder, a file over ``max_bytes``, unreadable or not UTF-8.
    """
    p = require_file(path, what)
    try:
        size = p.stat().st_size
        if size > max_bytes:
            raise InputError(str(p), f"{what} of at most {max_bytes} bytes", f"{size} bytes")
        data = p.read_bytes()
    except OSError as e:
        raise InputError(str(p), what, f"unreadable ({e.strerror or e})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise InputError(str(p), f"{what} in UTF-8", f"undecodable bytes at byte {e.start}") from None
    return text[1:] if text.startswith(BOM) else text


def parse_json(text: str, where: str, what: str = "a JSON file"):
    """Parse JSON text; syntax errors and nesting too deep to parse as InputErrors naming ``where``."""
    if text.startswith(BOM):
        text = text[1:]
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(where, what, f"a JSON syntax error at line {e.lineno}, column {e.colno}: {e.msg}") from None
    except RecursionError:
        raise InputError(where, what, "values nested too deep to read") from None


def parse_toml(text: str, where: str, what: str = "a TOML file") -> dict:
    """Parse TOML text; syntax errors and nesting too deep to parse as InputErrors naming ``where``."""
    if text.startswith(BOM):
        text = text[1:]
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(where, what, f"a TOML syntax error: {e}") from None
    except RecursionError:
        raise InputError(where, what, "values nested too deep to read") from None


def load_json(path: str | os.PathLike, what: str = "a JSON file", max_bytes: int = MAX_TEXT_BYTES):
    """:func:`read_text` then :func:`parse_json`."""
    return parse_json(read_text(path, what, max_bytes), str(path), what)


def load_toml(path: str | os.PathLike, what: str = "a TOML file", max_bytes: int = MAX_TEXT_BYTES) -> dict:
    """:func:`read_text` then :func:`parse_toml`."""
    return parse_toml(read_text(path, what, max_bytes), str(path), what)
