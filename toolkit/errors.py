"""Toolkit error types.

Every error raised on bad user input names the file, field or argument, what
was expected and what was found.
"""

from __future__ import annotations


class ToolkitError(Exception):
    """Base class of the toolkit's own errors."""


class InputError(ToolkitError, ValueError):
    """Bad input data: a file, field or argument with an unexpected value.

    Parameters
    ----------
    where : str
        The file, field or argument at fault (e.g. ``"calibration.toml: [cam01].matrix"``).
    expected : str
        What was expected.
    found : str
        What was found instead.
    """

    def __init__(self, where: str, expected: str, found: str):
        self.where = where
        self.expected = expected
        self.found = found
        super().__init__(f"{where}: expected {expected}, found {found}")

    def __reduce__(self):
        # rebuilt from its three parts when it crosses a process boundary (workers, child processes)
        return (type(self), (self.where, self.expected, self.found))


def check_shape(name: str, array, shape: tuple) -> None:
    """Raise :class:`InputError` unless ``array`` has ``shape``.

    Parameters
    ----------
    name : str
        Argument name used in the message.
    array : array_like
        The value to check.
    shape : tuple of (int or None)
        Expected shape; ``None`` matches any size on that axis.
    """
    import numpy as np

    arr = np.asarray(array)
    ok = arr.ndim == len(shape) and all(s is None or s == a for s, a in zip(shape, arr.shape))
    if not ok:
        exp = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise InputError(name, f"an array of shape {exp}", f"shape {arr.shape}")
