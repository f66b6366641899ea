"""The run layer every system's recipe shares: configs, run identity, frame records, results.

A recipe is ``argparse -> config -> run(config, dataset=..., out=...) ->
summary``.  What sits between (resume bookkeeping, the run's identity, the
per-frame records, the recording's file, metrics written at the end) lives
here, once:

* :func:`config_identity` -- the JSON identity of a run, derived from its
  config dataclasses (nested ones included) minus the fields that do not
  change results, so no hand-kept dict can forget an option;
* :func:`config_from_toml` / :func:`load_config` -- any config dataclass from a
  TOML file (nested tables for nested configs), unknown keys rejected with the
  file and key named;
* :class:`FrameRecords` -- ``OUT/frames/NNNNNN.json``: a frame with a record is
  finished and skipped when the run resumes, records are written atomically;
* :func:`open_run` -- :func:`toolkit.io.runs.start_run` plus the records and
  the recording path of this part of the run;
* :func:`run_frames` -- the frame loop of a run: every frame a task (in this
  process, or on Dask workers: :mod:`toolkit.pipeline.parallel`), its reports
  passed to the run's observer in frame order, Ctrl-C stopping it cleanly;
* :class:`RunResult` -- what a run returns: counts, whether it stopped early,
  its metrics and recording.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import signal
import threading
import time
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path

from toolkit.errors import InputError
from toolkit.io.atomic import atomic_write_text
from toolkit.io.frames import frame_filename
from toolkit.io.runs import dataset_fingerprint, run_recording, start_run
from toolkit.io.text import load_toml
from toolkit.pipeline.parallel import ParallelConfig, ReportBuffer, map_tasks, replay

#: Sub-folder of a run's output holding one JSON record per finished frame.
FRAMES_DIR = "frames"
#: How :attr:`RunResult.stopped` says a run was interrupted (Ctrl-C).
STOPPED_INTERRUPTED = "interrupted"


def _jsonable(value):
    """``value`` as JSON-safe data: dataclasses as dicts, paths as resolved strings, tuples as lists."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, os.PathLike):
        return str(Path(value).resolve())
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return value.tolist()
    return value


def config_identity(config, *, exclude: tuple = ()) -> dict:
    """The run identity of a config dataclass: every field, nested configs included, as JSON data.

    Parameters
    ----------
    config : dataclass instance
    exclude : tuple of str
        Top-level fields that do not change the results (progress bars,
        how many frames, recording options); left out.

    Returns
    -------
    dict

    Raises
    ------
    InputError
        ``config`` is not a dataclass instance, or ``exclude`` names no field of it.
    """
    if not dataclasses.is_dataclass(config) or isinstance(config, type):
        raise InputError("config_identity: config", "a dataclass instance", type(config).__name__)
    names = {f.name for f in dataclasses.fields(config)}
    unknown = sorted(set(exclude) - names)
    if unknown:
        raise InputError("config_identity: exclude", f"fields of {type(config).__name__}", f"{unknown}")
    return {k: v for k, v in _jsonable(config).items() if k not in exclude}


def _dataclass_in(tp):
    """The dataclass type a field annotation allows (``X``, ``X | None``), or None."""
    if dataclasses.is_dataclass(tp):
        return tp
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        for a in typing.get_args(tp):
            if dataclasses.is_dataclass(a):
                return a
    return None


def _tuple_item(tp):
    """The item type of ``tuple[X, ...]`` (or of ``tuple[X, ...] | None``), else None."""
    for t in (tp, *(typing.get_args(tp) if typing.get_origin(tp) in (typing.Union, types.UnionType) else ())):
        if typing.get_origin(t) is tuple:
            args = typing.get_args(t)
            if len(args) == 2 and args[1] is Ellipsis:
                return args[0]
    return None


def _is_tuple(tp) -> bool:
    """Whether annotation ``tp`` is a tuple type or allows one (``tuple[int, int] | None``)."""
    members = typing.get_args(tp) if typing.get_origin(tp) in (typing.Union, types.UnionType) else (tp,)
    return any(typing.get_origin(t) is tuple or t is tuple for t in members)


def _tuples(value):
    """Lists (nested ones included) as tuples: TOML arrays for tuple-valued options."""
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


def _allows(tp, kind) -> bool:
    """Whether annotation ``tp`` admits ``kind`` (e.g. ``Path | None`` admits Path)."""
    if tp is kind:
        return True
    return typing.get_origin(tp) in (typing.Union, types.UnionType) and kind in typing.get_args(tp)


def _key(where: str, key: str) -> str:
    """``FILE: table.key``: where a key of a (nested) table is, for errors."""
    return f"{where}.{key}" if ": " in where else f"{where}: {key}"


def config_from_dict(cls, data: dict, *, where: str = "config"):
    """A config dataclass from plain data (a parsed TOML table); unknown keys rejected.

    Nested dataclass fields take nested tables (a tuple of dataclasses an
    array of tables); fields annotated ``Path`` take strings; lists (nested
    ones included) become tuples where the field is a tuple.  Values
    are checked by the dataclass itself (its ``__post_init__``).

    Parameters
    ----------
    cls : dataclass type
    data : dict
    where : str
        Where the data came from (a file), named in errors with the key at
        fault (``FILE: table.key``).

    Returns
    -------
    cls instance

    Raises
    ------
    InputError
        A key is no field of ``cls`` (the known ones are listed), or a nested
        config is given something else than a table.
    """
    if not isinstance(data, dict):
        raise InputError(where, f"a table of {cls.__name__} options", type(data).__name__)
    flds = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - set(flds))
    if unknown:
        raise InputError(_key(where, unknown[0]) if len(unknown) == 1 else where,
                         f"options of {cls.__name__}: {sorted(flds)}", f"unknown key(s) {unknown}")
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for k, v in data.items():
        tp = hints.get(k)
        sub = _dataclass_in(tp)
        if sub is not None and isinstance(v, dict):
            kwargs[k] = config_from_dict(sub, v, where=_key(where, k))
        elif sub is not None and v is not None:
            raise InputError(_key(where, k), f"a table of {sub.__name__} options", repr(v))
        elif isinstance(v, str) and _allows(tp, Path):
            kwargs[k] = Path(v)
        elif isinstance(v, list) and dataclasses.is_dataclass(item := _tuple_item(tp)):
            # an array of tables for a tuple of configs (e.g. joint limits)
            kwargs[k] = tuple(config_from_dict(item, x, where=_key(where, f"{k}[{i}]")) for i, x in enumerate(v))
        elif isinstance(v, list) and (isinstance(flds[k].default, tuple) or _is_tuple(tp)):
            kwargs[k] = _tuples(v)
        else:
            kwargs[k] = v
    try:
        return cls(**kwargs)
    except TypeError as e:
        raise InputError(where, f"valid {cls.__name__} options", str(e)) from None


def load_config(cls, path: str | os.PathLike | None, **overrides):
    """A config from an optional TOML file, then command-line overrides on top.

    Parameters
    ----------
    cls : dataclass type
    path : path or None
        TOML file whose top-level keys are ``cls``'s fields (nested configs as
        tables).  None: the defaults.
    **overrides
        Field values that replace the file's (e.g. the recipe's flags); a
        value of ``None`` leaves the field alone.

    Returns
    -------
    cls instance

    Raises
    ------
    InputError
        The file is missing or not TOML, or holds unknown keys.
    """
    data = {}
    if path is not None:
        data = load_toml(path, "a TOML config file")
    config = config_from_dict(cls, data, where=str(path) if path is not None else cls.__name__)
    given = {k: v for k, v in overrides.items() if v is not None}
    return dataclasses.replace(config, **given) if given else config


@dataclass(frozen=True)
class FrameRecords:
    """The per-frame records of a resumable run, ``OUT/frames/NNNNNN.json``.

    Parameters
    ----------
    out : Path
        The run's output folder.
    n_frames : int
        Frames the run covers (0 .. n_frames - 1).
    """

    out: Path
    n_frames: int

    def path(self, t: int) -> Path:
        """File of frame ``t``'s record."""
        return Path(self.out) / FRAMES_DIR / frame_filename(t, ".json")

    def done(self) -> set:
        """Frames with a record (finished)."""
        return {t for t in range(self.n_frames) if self.path(t).exists()}

    def todo(self) -> list:
        """Frames without a record, in order."""
        done = self.done()
        return [t for t in range(self.n_frames) if t not in done]

    def write(self, t: int, record: dict) -> None:
        """Write frame ``t``'s record atomically (the frame is then finished)."""
        atomic_write_text(self.path(t), json.dumps(record, allow_nan=True))

    def read_all(self) -> list:
        """Every finished frame's record, in frame order.

        Raises
        ------
        InputError
            A record is not JSON (e.g. written by a foreign tool).
        """
        return list(self.each())

    def each(self):
        """Yields every finished frame's record, in frame order, one read at a time (a long run's end goes
        through them without holding them all).

        Raises
        ------
        InputError
            A record is not JSON (e.g. written by a foreign tool).
        """
        for t in sorted(self.done()):
            p = self.path(t)
            try:
                record = json.loads(p.read_text(encoding="utf-8"))
            except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
                raise InputError(str(p), "a frame record (JSON) written by this run", f"unreadable: {e}") from None
            yield record


def check_frames_held(out: str | os.PathLike, n_frames: int, held: int, *, what: str = "finished frames") -> None:
    """Refuse a run of fewer frames than its folder already holds results of (the same run, resumed).

    The frame count (``--max-frames``) is not part of a run's identity, so a
    second run with a smaller one resumes the folder; it would then write the
    run's summaries (poses, metrics) for its first ``n_frames`` only, over
    those of every frame the folder holds.

    Parameters
    ----------
    out : path
        The run's output folder.
    n_frames : int
        Frames this run covers.
    held : int
        Frames the folder holds results of (the highest finished frame + 1).
    what : str
        What the folder holds, for the message.

    Raises
    ------
    InputError
        ``held > n_frames``.
    """
    if held > n_frames:
        raise InputError(str(out), f"a run of at least the {held} frames the folder holds {what} of (its summaries "
                         "cover them all)", f"a run of {n_frames} frames (a smaller frame limit): give a limit "
                         f"of {held} frames or more, or none, or another --out")


def _records_held(out: Path) -> int:
    """The highest frame index with a record in ``out/frames/``, plus one (0: none)."""
    folder = Path(out) / FRAMES_DIR
    if not folder.is_dir():
        return 0
    idx = [int(p.stem) for p in folder.glob("*.json") if p.stem.isdigit()]
    return max(idx) + 1 if idx else 0


@dataclass(frozen=True)
class RunFolder:
    """A run's output folder once opened: whether it resumed, its records, its recording part.

    Attributes
    ----------
    out : Path
    resumed : bool
        The folder held earlier results of this same run.
    records : FrameRecords
    recording : Path or None
        Where this part of the run writes its recording (None: no recording,
        or nothing left to do).
    recording_id : str or None
    """

    out: Path
    resumed: bool
    records: FrameRecords
    recording: Path | None
    recording_id: str | None


def open_run(out: str | os.PathLike, recipe: str, dataset_root, config, n_frames: int, *,
             exclude: tuple = (), extra: dict | None = None, replace_stale: bool = False,
             recording: bool = True, log=print) -> RunFolder:
    """Start or resume a run in ``out``: identity checked, records listed, recording part chosen.

    Parameters
    ----------
    out : path
    recipe : str
        The system's name, part of the identity.
    dataset_root : path
        The dataset folder; its fingerprint is part of the identity.
    config : dataclass instance
        The run's config; its fields (less ``exclude``) are the rest of the identity.
    n_frames : int
    exclude : tuple of str
        Config fields that do not change the results.
    extra : dict, optional
        More identity (e.g. the name of a default database file whose name
        holds its build key).
    replace_stale : bool
        Move a folder of another run aside instead of refusing it.
    recording : bool
        Whether this part writes a recording (none when every frame is done).
    log : callable or None

    Returns
    -------
    RunFolder

    Raises
    ------
    InputError
        ``out`` holds another run's results (and not ``replace_stale``), or
        finished frames of this run beyond ``n_frames`` (:func:`check_frames_held`).
    """
    identity = {"recipe": recipe, "dataset": dataset_fingerprint(dataset_root, exclude=(out,)),
                "config": config_identity(config, exclude=exclude), **(extra or {})}
    resumed = start_run(out, identity, replace_stale=replace_stale, log=log)
    if resumed:
        check_frames_held(out, n_frames, _records_held(Path(out)))
    records = FrameRecords(Path(out), n_frames)
    rec = rec_id = None
    if resumed:  # a killed run's recording parts: one file again before this part is named
        merge_killed_parts(out)
    if recording and records.todo():
        rec, rec_id = run_recording(out, resumed)
    return RunFolder(Path(out), resumed, records, rec, rec_id)


def merge_killed_parts(out: str | os.PathLike) -> None:
    """Merge the recording parts a run killed outright left in ``out`` (``recording*.parts/``) into files.

    Each folder becomes the ``.rrd`` of its name, or the next free
    ``recording.resume-<k>.rrd`` when that exists
    (:func:`toolkit.viz.rerun_observer.finish_parts`), so that a new part
    of the recording never takes them in or is mixed with them.
    """
    from toolkit.viz.rerun_observer import finish_parts

    for parts in sorted(Path(out).glob("recording*.parts")):
        finish_parts(parts)


def frame_ranges(frames) -> str:
    """Frame numbers as ranges, for a summary: [0, 1, 2, 5] -> '0-2, 5' ('' for none)."""
    runs: list = []
    for f in sorted(frames):
        if runs and f == runs[-1][1] + 1:
            runs[-1][1] = f
        else:
            runs.append([f, f])
    return ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in runs)


@dataclass(frozen=True)
class RunResult:
    """What a run returns.

    Attributes
    ----------
    out : Path
        The output folder.
    frames : int
        Frames the run covers.
    finished : int
        Frames with a record after this run (earlier parts included).
    processed : int
        Frames processed by this run.
    earlier : int
        Frames that were already finished when this run started (resumed).
    stopped : str
        ``""`` when the run went through, else why it stopped early
        (:data:`STOPPED_INTERRUPTED`).
    seconds : float
        Wall time of this run.
    metrics : dict
        The run's metrics (also in ``out/metrics.json`` where the system writes one).
    recording : Path or None
        This part's recording (None: none written).
    extra : dict
        System-specific results (e.g. the held-out camera's name).
    """

    out: Path
    frames: int
    finished: int
    processed: int
    earlier: int
    stopped: str
    seconds: float
    metrics: dict
    recording: Path | None = None
    extra: dict = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        """Every frame is finished."""
        return self.finished == self.frames


@contextlib.contextmanager
def terminate_as_interrupt():
    """While the body runs, SIGTERM (``kill``, a job scheduler's stop) stops it as Ctrl-C does.

    Python ends on SIGTERM without running ``finally`` blocks, so a run
    stopped so lost what it held (its last results, the end of its
    recording).  Inside this context SIGTERM raises :class:`KeyboardInterrupt`
    in the main thread instead, and the run's Ctrl-C path keeps what is
    finished.  Outside the main thread (where signals cannot be caught) it
    does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, _frame):
        raise KeyboardInterrupt(f"signal {signal.Signals(signum).name}")

    old = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


@contextlib.contextmanager
def deferred_interrupts():
    """While the body runs, Ctrl-C and SIGTERM are held, then delivered once it ends.

    For a set of result files written together (a run computed as a whole
    writes them at its end): a stop never leaves some of them new and the
    others old or missing.  Outside the main thread it does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = []

    def hold(signum, _frame):
        held.append(signum)

    old = {s: signal.signal(s, hold) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
        if held:
            signal.raise_signal(held[0])


def close_run_recording(observer, out: str | os.PathLike, *, keep: bool) -> Path | None:
    """Close a run's own recording: kept (its file replaces the folder's) or dropped; the file it leaves.

    Parameters
    ----------
    observer : RerunObserver
        Written in parts (``parts=True``), so that a dropped recording leaves
        the folder's earlier file as it was.
    out : path
        The run folder.
    keep : bool
        Whether the run's results replaced the earlier ones (or there were
        none): its recording then shows them; else it is dropped and the
        earlier recording stays beside the earlier results.

    Returns
    -------
    Path or None
        The finished recording file of this run (None: dropped, or not
        finalised: nothing to offer as openable).

    Notes
    -----
    A run computed as a whole writes one recording, ``OUT/recording.rrd``;
    ``recording.resume-<k>.rrd`` files in its folder are the parts of a
    killed earlier run merged by :func:`open_run`, superseded: they are
    removed (opened with ``rerun OUT/recording*.rrd`` they would mix with
    the recording of the results).
    """
    observer.close(keep=keep)
    for stale in Path(out).glob("recording.resume-*.rrd"):
        stale.unlink(missing_ok=True)
    return getattr(observer, "saved", None)


@dataclass
class WholeRun:
    """A run computed as a whole (tracking that carries its state, a global fit), inside :func:`whole_run`.

    Attributes
    ----------
    observer : Observer or None
        The run's observer (its ``checkpoint()`` ends a part of the recording).
    stopped : str
        ``""``, or :data:`STOPPED_INTERRUPTED` once Ctrl-C or SIGTERM stopped the body.
    written : bool
        The run's results are written (:meth:`writing` ended).
    recording : Path or None
        The finished recording of this run once :func:`whole_run` ended (None:
        none, or dropped because the earlier complete results were kept).
    """

    observer: typing.Any = None
    stopped: str = ""
    written: bool = False
    recording: Path | None = None

    def checkpoint(self) -> None:
        """End a part of the recording: a run killed outright after this leaves it complete."""
        checkpoint = getattr(self.observer, "checkpoint", None)
        if callable(checkpoint):
            checkpoint()

    @contextlib.contextmanager
    def writing(self):
        """The body writes the run's results here: Ctrl-C and SIGTERM held until every file is written
        (:func:`deferred_interrupts`); the run then counts as written."""
        with deferred_interrupts():
            yield
            self.written = True


@contextlib.contextmanager
def whole_run(out: str | os.PathLike, observer=None, *, own: bool, earlier: bool):
    """The body of a run computed as a whole: its stops, and what becomes of its recording.

    A run whose frames depend on each other (the soft-body tracking and its
    global fit, the marker labelling and joint centres) writes its results at
    the end, all together (:meth:`WholeRun.writing`), and a rerun computes
    them again from the start.  Inside this context

    * SIGTERM stops the body as Ctrl-C does (:func:`terminate_as_interrupt`),
      and either ends it quietly: ``state.stopped`` says so (no traceback);
    * the results of an earlier complete run stay until this run has written
      its own (they are written only at the end);
    * the run's own recording (``own``; a :class:`~toolkit.viz.RerunObserver`
      written in parts, ``state.checkpoint()`` between steps, so that a run
      killed outright leaves the finished parts complete) is closed at the
      end: kept when the run wrote its results or the folder held none
      (``earlier`` False), else dropped, so the earlier recording stays with
      the results it shows (:func:`close_run_recording`).

    Parameters
    ----------
    out : path
        The run folder.
    observer : Observer, optional
    own : bool
        ``observer`` is the run's own recording (closed here).
    earlier : bool
        The folder holds the complete results of an earlier run of the same identity.

    Yields
    ------
    WholeRun
    """
    state = WholeRun(observer)
    try:
        with terminate_as_interrupt():
            yield state
    except KeyboardInterrupt:
        state.stopped = STOPPED_INTERRUPTED
    finally:
        if own and observer is not None:
            state.recording = close_run_recording(observer, out, keep=state.written or not earlier)


@dataclass(frozen=True)
class _FrameCall:
    """One frame's task as the workers run it: ``task(*args, observer=...)``, its reports kept."""

    task: typing.Any
    observe: bool

    def __call__(self, *args) -> list:
        buffer = ReportBuffer() if self.observe else None
        self.task(*args, observer=buffer)
        return buffer.reports if buffer is not None else []


def run_frames(task, frames, *, total: int, parallel: ParallelConfig = ParallelConfig(), observer=None,
               progress: bool = True, desc: str = "frames",
               on_frame: typing.Callable[[int], None] | None = None) -> tuple[int, str, float]:
    """The frame loop of a run: each frame a task, here or on Dask workers, reports in frame order.

    The task writes the frame's results itself (atomically, its record last:
    :class:`FrameRecords`), so a frame is either finished or done again when
    the run resumes, wherever it ran.  What it reports is kept
    (:class:`~toolkit.pipeline.parallel.ReportBuffer`) and passed to
    ``observer`` in frame order by this process, which alone writes the
    recording; after each frame the observer's ``checkpoint()`` (where it has
    one) closes a part of the recording, so a run killed outright leaves a
    recording that opens.  SIGTERM stops the loop as Ctrl-C does
    (:func:`terminate_as_interrupt`).  With one worker the same task runs in this process
    (:func:`~toolkit.pipeline.parallel.map_tasks`).

    Parameters
    ----------
    task : callable
        Picklable; ``task(*args, observer=obs)`` processes one frame.
    frames : iterable of tuple
        Each frame's ``args`` in frame order (a generator: e.g. what needs the
        previous frame, such as stage 1, runs here, ahead of the workers).
    total : int
        Number of frames (progress).
    parallel : ParallelConfig
    observer : Observer, optional
    progress : bool
    desc : str
    on_frame : callable, optional
        ``on_frame(i)`` in this process once frame ``i`` (0-based, in the order
        of ``frames``) is finished and its reports passed on (e.g. its log line).

    Returns
    -------
    processed : int
        Frames finished by this run.
    stopped : str
        ``""``, or :data:`STOPPED_INTERRUPTED` after Ctrl-C.
    seconds : float
        Wall time.
    """
    processed, stopped = 0, ""
    checkpoint = getattr(observer, "checkpoint", None)

    def finished(_i: int, reports: list) -> None:
        nonlocal processed
        replay(reports, observer)
        if callable(checkpoint):
            checkpoint()
        processed += 1
        if on_frame is not None:
            on_frame(_i)

    t0 = time.perf_counter()
    try:
        with terminate_as_interrupt():
            map_tasks(_FrameCall(task, observer is not None), frames, parallel=parallel, on_result=finished,
                      total=total, progress=progress, desc=desc, unit="frame")
    except KeyboardInterrupt:
        stopped = STOPPED_INTERRUPTED
    return processed, stopped, time.perf_counter() - t0


#: Files of a run folder that differ from run to run by nature: its identity's recording id, the recording.
_UNCOMPARED = ("run.json", "recording*.rrd", "recording*.parts/*", "*.stale-*")
#: Keys holding wall times, left out when two runs' records and metrics are compared.
_TIMING_KEYS = frozenset({"timings", "seconds_per_frame", "seconds"})


def _untimed(value):
    if isinstance(value, dict):
        return {k: _untimed(v) for k, v in value.items() if k not in _TIMING_KEYS}
    if isinstance(value, list):
        return [_untimed(v) for v in value]
    return value


def _json_diff(a, b, atol: float, where: str = ""):
    """Where two JSON values first differ (numbers to ``atol``, absolute or relative; NaN equals NaN), or None."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{where}/{k}"
            w = _json_diff(a[k], b[k], atol, f"{where}/{k}")
            if w is not None:
                return w
        return None
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{where} (length)"
        for i, (x, y) in enumerate(zip(a, b)):
            w = _json_diff(x, y, atol, f"{where}[{i}]")
            if w is not None:
                return w
        return None
    numbers = (int, float)
    if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool) and not isinstance(b, bool):
        fa, fb = float(a), float(b)
        same = (fa != fa and fb != fb) or fa == fb or abs(fa - fb) <= atol * max(1.0, abs(fa), abs(fb))
        return None if same else where
    return None if a == b else where


def compare_runs(a: str | os.PathLike, b: str | os.PathLike, *, atol_m: float = 1e-9) -> list:
    """Where two run folders of the same system and inputs differ (e.g. one worker against several).

    Images and every other file byte for byte; JSON records and metrics less
    their wall times, numbers to ``atol_m`` (absolute, or relative above 1);
    ``.npz`` arrays (less wall times) to ``atol_m`` (poses, metres) where float, exactly
    otherwise.  ``run.json`` (its recording id), the recordings and hidden
    files (the temporary file of a write a killed worker left) are not compared.

    Parameters
    ----------
    a, b : path
        Output folders.
    atol_m : float

    Returns
    -------
    list of str
        One line per difference (empty: the same outputs).
    """
    import fnmatch

    import numpy as np

    a, b = Path(a), Path(b)

    def files(root: Path) -> set:  # hidden files left out: an atomic write's temporary, left by a killed worker
        return {p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file()
                and not any(part.startswith(".") for part in p.relative_to(root).parts)
                and not any(fnmatch.fnmatch(p.relative_to(root).as_posix(), g) for g in _UNCOMPARED)}

    fa, fb = files(a), files(b)
    diffs = [f"only in {a}: {f}" for f in sorted(fa - fb)] + [f"only in {b}: {f}" for f in sorted(fb - fa)]
    for f in sorted(fa & fb):
        pa, pb = a / f, b / f
        if f.endswith(".json"):
            ja, jb = (_untimed(json.loads(p.read_text(encoding="utf-8"))) for p in (pa, pb))
            where = _json_diff(ja, jb, atol_m)
            if where is not None:
                diffs.append(f"{f}: differs at {where or 'the top'}")
        elif f.endswith(".npz"):
            za, zb = np.load(pa), np.load(pb)
            for k in sorted((set(za.files) | set(zb.files)) - _TIMING_KEYS):
                if k not in za.files or k not in zb.files:
                    diffs.append(f"{f}: {k} in one only")
                elif za[k].dtype.kind == "f":
                    if za[k].shape != zb[k].shape or not np.allclose(za[k], zb[k], rtol=0, atol=atol_m,
                                                                    equal_nan=True):
                        diffs.append(f"{f}: {k} differs by more than {atol_m}")
                elif not np.array_equal(za[k], zb[k]):
                    diffs.append(f"{f}: {k} differs")
        elif pa.read_bytes() != pb.read_bytes():
            diffs.append(f"{f}: bytes differ")
    return diffs
