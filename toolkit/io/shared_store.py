"""A folder the processes of one run share arrays through: each array set computed once in all.

A run's worker processes need some of the same things before their first
frame (the fixed cameras' background plates, the scene model's views of them).
Drawing each in every process costs every process the whole; with a store,
whichever process claims an item first computes it and writes it, the others
skip it (:meth:`SharedStore.compute`) and read it when they need it
(:meth:`SharedStore.get`), waiting while its claimer is still at work.  A claim
is a file created atomically (``O_CREAT | O_EXCL``, also on NFS); one older
than :data:`CLAIM_STALE_S` was left by a killed process and is taken over.

Layout::

    STORE/<key>.npz      the arrays of one item (written atomically)
    STORE/<key>.claim    while a process computes it
"""

from __future__ import annotations

import io
import os
import time
from pathlib import Path
from typing import Callable

import numpy as np

from toolkit.io.atomic import atomic_write_bytes

__all__ = ["SharedStore", "CLAIM_STALE_S"]

#: A claim older than this (seconds) is taken for one a killed process left.
CLAIM_STALE_S = 120.0
#: How often a process waiting for another's item looks again (seconds).
POLL_S = 0.05


def _fresh(path: Path) -> bool:
    try:
        return time.time() - path.stat().st_mtime < CLAIM_STALE_S
    except FileNotFoundError:
        return False


class SharedStore:
    """Arrays shared by the processes of a run through a folder.

    Parameters
    ----------
    folder : path
        Created on first use; a run removes it when it is finished.
    """

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)

    def path(self, key: str) -> Path:
        """Where item ``key`` (a file-name-safe string, e.g. a hex digest) is stored."""
        return self.folder / f"{key}.npz"

    def claim(self, key: str) -> bool:
        """Claim item ``key`` for this process; False when it is stored or another process holds a fresh claim."""
        if self.path(key).exists():
            return False
        self.folder.mkdir(parents=True, exist_ok=True)
        claim = self.path(key).with_suffix(".claim")
        try:
            fd = os.open(claim, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            if _fresh(claim):
                return False
            claim.unlink(missing_ok=True)  # left by a killed process
            return self.claim(key)
        os.close(fd)
        return True

    def release(self, key: str) -> None:
        """Give up the claim on ``key`` (stored or not)."""
        self.path(key).with_suffix(".claim").unlink(missing_ok=True)

    def put(self, key: str, arrays: dict) -> Path:
        """Store ``arrays`` (name -> ndarray) as item ``key``, atomically."""
        buf = io.BytesIO()
        np.savez(buf, **{k: np.asarray(v) for k, v in arrays.items()})
        self.folder.mkdir(parents=True, exist_ok=True)
        return atomic_write_bytes(self.path(key), buf.getvalue())

    def compute(self, key: str, make: Callable[[], dict]) -> bool:
        """Compute and store item ``key`` with ``make()`` unless it is stored or claimed; whether this call did."""
        if not self.claim(key):
            return False
        try:
            self.put(key, make())
        finally:
            self.release(key)
        return True

    def get(self, key: str, wait: bool = True) -> dict | None:
        """Item ``key``'s arrays, or None when nobody stored it (nor, with ``wait``, is computing it now).

        With ``wait``, an item another process has claimed is waited for until it is stored or its
        claim goes stale (:data:`CLAIM_STALE_S`).
        """
        path = self.path(key)
        claim = path.with_suffix(".claim")
        deadline = time.monotonic() + CLAIM_STALE_S
        while True:
            if path.exists():
                with np.load(path, allow_pickle=False) as z:
                    return {k: z[k] for k in z.files}
            if not (wait and claim.exists() and time.monotonic() < deadline and _fresh(claim)):
                return None
            time.sleep(POLL_S)
