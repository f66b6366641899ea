"""Which dataset and options a resumable output folder was made from (``OUT/run.json``).

A recipe that resumes (skips frames whose results exist) must not mix the
results of two different inputs: after the dataset was regenerated, or with
other options, the old frames are stale.  :func:`start_run` compares the
identity of this run (a fingerprint of the dataset's files and the options
that change the results) with the one stored in the folder and refuses to
resume a different run, or, when asked, moves the stale folder aside (never
deleting finished work) and starts afresh.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
import uuid
from pathlib import Path
from typing import Iterator

from toolkit.errors import InputError
from toolkit.io.atomic import atomic_write_text, temp_path
from toolkit.io.layout import is_stray
from toolkit.io.text import load_json

#: The identity file of a run folder.
RUN_FILE = "run.json"
#: Key of ``run.json`` holding the run's rerun recording id (drawn when the run starts; not part of the
#: identity): every part of a resumed run's recording carries it, so the viewer merges them.
RECORDING_ID_KEY = "recording_id"
#: File name of a run's recording; a resumed run writes ``recording.resume-<k>.rrd`` beside it.
RECORDING_FILE = "recording.rrd"
#: Bytes hashed at each end of a large file (whole files below twice this).
_HASH_EDGE = 4 << 20


def file_fingerprint(path: str | os.PathLike) -> str:
    """SHA-256 of a file's size and content (first and last 4 MiB of large files), hex."""
    p = Path(path)
    size = p.stat().st_size
    h = hashlib.sha256(str(size).encode())
    with open(p, "rb") as f:
        if size <= 2 * _HASH_EDGE:
            h.update(f.read())
        else:
            h.update(f.read(_HASH_EDGE))
            f.seek(size - _HASH_EDGE)
            h.update(f.read(_HASH_EDGE))
    return h.hexdigest()


#: Files of an input folder a run does not read: its recordings (``scene.rrd``).
_UNREAD_SUFFIXES = (".rrd",)


def _input_files(root: Path, exclude: tuple) -> list:
    """Every file under ``root`` a run may read, sorted: hidden, stray and excluded ones left out."""
    if root.is_file():
        return [root]
    skip = [Path(e).resolve() for e in exclude]
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        d = Path(dirpath)
        dirnames[:] = sorted(n for n in dirnames if not n.startswith(".") and (d / n).resolve() not in skip)
        out += [d / n for n in sorted(filenames) if not n.startswith(".") and not is_stray(n)
                and not n.endswith(_UNREAD_SUFFIXES)]
    return out


def dataset_fingerprint(root: str | os.PathLike, *, exclude: tuple = ()) -> str:
    """Fingerprint of an input folder (or file): every file a run may read (names, sizes, content), hex.

    Every file under ``root`` counts (calibration, videos, ``background/``,
    ``field_model.json``, ``scene.toml``, ``groundtruth/``, ``keypoints/``,
    masks, depth frames ...), so a dataset changed in any file a run reads is
    another dataset; left out are hidden files (an interrupted write's
    temporaries), files the operating system leaves (``Thumbs.db``), rerun
    recordings and the folders of ``exclude`` (a run's own output inside its
    dataset).

    Parameters
    ----------
    root : path
        Dataset folder (``docs/dataset_layout.md``), or one input file.
    exclude : tuple of path
        Folders under ``root`` left out.
    """
    root = Path(root)
    h = hashlib.sha256()
    for f in _input_files(root, tuple(exclude)):
        h.update((f.relative_to(root).as_posix() if f != root else f.name).encode())
        h.update(file_fingerprint(f).encode())
    return h.hexdigest()


def _flatten(d: dict, prefix: str = "") -> dict:
    """Nested dicts as one dict with dotted keys (``config.frame.optimize``), to name what differs."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict) and v:
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _refuse_files_on_path(out: Path, what: str) -> None:
    """An InputError when ``out`` or a folder above it is a file."""
    for p in (out, *out.parents):
        if p.exists() and not p.is_dir():
            raise InputError(f"{what} {out}", "an output folder", f"{p} is a file" if p != out else "a file")


def check_out_folder(out: str | os.PathLike, what: str = "--out") -> Path:
    """``out`` as a folder this process can write, created if missing, or an InputError.

    Parameters
    ----------
    out : path
        An output folder.
    what : str
        The argument that named it, for messages.

    Returns
    -------
    Path

    Raises
    ------
    InputError
        ``out`` (or a folder above it) is a file, or it cannot be created or written.
    """
    out = Path(out)
    _refuse_files_on_path(out, what)
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = temp_path(out / "write-probe")
        probe.unlink()
    except OSError as e:
        raise InputError(f"{what} {out}", "a folder this user can write",
                         f"{e.strerror or e} (read-only disk or folder, or no permission)") from None
    return out


@contextlib.contextmanager
def staged_folder(out: str | os.PathLike, *, overwrite: bool = False, what: str = "--out",
                  log=print) -> Iterator[Path]:
    """Yield a fresh folder to write a whole output into; on success it replaces ``out`` in one step.

    The folder is a hidden sibling of ``out`` (``.<name>.partial-*``, on the
    same file system), renamed to ``out`` only when the body finished, so a
    failed or interrupted write leaves ``out`` as it was and never a mix of
    an old and a new output.

    Parameters
    ----------
    out : path
        The output folder.
    overwrite : bool
        Replace an ``out`` that holds files (else refused).
    what : str
        The argument that named ``out``, for messages.
    log : callable or None

    Yields
    ------
    Path
        The staging folder (empty).

    Raises
    ------
    InputError
        ``out`` holds files and not ``overwrite``, or is a file, or cannot be written.
    """
    out = Path(out)
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise InputError(f"{what} {out}", "a new or empty folder", "a folder with files (pass --overwrite to "
                         "replace it once the new one is complete)")
    check_out_folder(out.parent, f"the folder of {what}")
    if out.exists() and not out.is_dir():
        raise InputError(f"{what} {out}", "an output folder", "a file")
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        yield stage
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    old = None
    if out.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
        os.replace(out, old / out.name)
    os.replace(stage, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
        if log is not None:
            log(f"{out}: replaced (--overwrite)")


def start_run(out: str | os.PathLike, identity: dict, *, replace_stale: bool = False, log=print) -> bool:
    """Check (or record) which inputs a resumable output folder belongs to.

    Parameters
    ----------
    out : path
        The recipe's output folder.
    identity : dict
        JSON-serialisable description of the run: the dataset fingerprint and the
        options that change the results.
    replace_stale : bool
        When ``out`` holds results of another run, rename it to
        ``<out>.stale-<k>`` and start afresh instead of raising.
    log : callable or None

    Returns
    -------
    bool
        True when ``out`` holds earlier results of this same run (resume).

    Raises
    ------
    InputError
        ``out`` holds results of another dataset or other options (and not
        ``replace_stale``), or its ``run.json`` is unreadable.
    """
    out = Path(out)
    _refuse_files_on_path(out, "--out")
    log = log or (lambda *_: None)
    ident = json.loads(json.dumps(identity, sort_keys=True))
    if RECORDING_ID_KEY in ident:
        raise InputError("identity", f"a description without the reserved key {RECORDING_ID_KEY!r}",
                         f"keys {sorted(ident)}")
    path = out / RUN_FILE
    stale = ""
    if path.is_file():
        old = load_json(path, "the JSON identity of an earlier run")
        if not isinstance(old, dict):
            raise InputError(str(path), "the JSON identity of an earlier run", type(old).__name__)
        rec_id = old.pop(RECORDING_ID_KEY, None)
        if old == ident:
            if rec_id is None:  # written before runs had a recording id
                atomic_write_text(path, json.dumps({**ident, RECORDING_ID_KEY: uuid.uuid4().hex}, indent=2,
                                                   sort_keys=True) + "\n")
            return True
        a, b = _flatten(old), _flatten(ident)
        diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        stale = f"results of another run (differs in: {', '.join(diff)})"
    elif out.is_dir() and any(out.iterdir()):
        stale = f"results without a {RUN_FILE} (made before runs were identified, or by another recipe)"
    if stale:
        if not replace_stale:
            raise InputError(str(out), "an empty folder or the results of this same run to resume",
                             f"{stale}; use another --out, remove it, or pass --replace-stale to move it aside")
        k = 1
        while out.with_name(f"{out.name}.stale-{k}").exists():
            k += 1
        aside = out.with_name(f"{out.name}.stale-{k}")
        out.rename(aside)
        log(f"{out}: {stale}; moved to {aside}")
    check_out_folder(out)
    atomic_write_text(path, json.dumps({**ident, RECORDING_ID_KEY: uuid.uuid4().hex}, indent=2, sort_keys=True)
                      + "\n")
    return False




def run_recording(out: str | os.PathLike, resumed: bool) -> tuple[Path, str]:
    """Where this run of a resumable recipe writes its recording, and the recording id to use.

    A first run writes ``OUT/recording.rrd``.  A resumed run must not overwrite
    it (it holds the finished frames' intermediates): it writes the next free
    ``OUT/recording.resume-<k>.rrd``.  Every part gets the run's recording id,
    drawn once by :func:`start_run` and kept in ``run.json``, so that the
    viewer opens ``rerun OUT/recording*.rrd`` as one recording (also after the
    folder was moved; a run started afresh draws a new one).

    Parameters
    ----------
    out : path
        The run's output folder (after :func:`start_run`).
    resumed : bool
        True when :func:`start_run` found earlier results of this run.

    Returns
    -------
    path : Path
    recording_id : str

    Raises
    ------
    InputError
        ``OUT/run.json`` is missing or holds no recording id (call :func:`start_run` first).
    """
    out = Path(out)
    ident = out / RUN_FILE
    try:
        rec_id = json.loads(ident.read_text(encoding="utf-8"))[RECORDING_ID_KEY]
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError):
        raise InputError(str(ident), f"a run identity with a {RECORDING_ID_KEY!r} (written by start_run)",
                         "none") from None
    path = out / RECORDING_FILE
    if resumed and path.exists():
        k = 1
        while (out / f"recording.resume-{k}.rrd").exists():
            k += 1
        path = out / f"recording.resume-{k}.rrd"
    return path, rec_id
