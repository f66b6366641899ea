"""Tasks in parallel on Dask: frames of a run, sequences, benchmark scenes; one code path with one worker.

:func:`map_tasks` runs a picklable function over a stream of tasks and hands
each result back in the order the tasks were given:

* ``workers=1`` and no scheduler: in this process, one task after the other,
  through the same wrapper the workers use (no Dask at all);
* ``workers=N``: on a :class:`dask.distributed.LocalCluster` of N worker
  processes, one thread each;
* ``scheduler="tcp://HOST:PORT"``: on an existing Dask cluster (``dask
  scheduler`` and ``dask worker`` started by hand, ``docs/parallel.md``).

Why Dask (and not :mod:`multiprocessing`): the same code runs on one machine
and on a cluster, a worker process that dies has its task rescheduled on
another one (the nanny restarts it), and ``as_completed`` gives one progress
bar over all workers.

Each task runs single-threaded (:func:`single_threaded`: BLAS / OpenMP through
threadpoolctl, OpenCV): N workers on N cores, and results that do not depend
on how many threads a library picked.  A task's result comes back to the main
process; where a task writes files (a frame's record and images) it writes
them atomically, so a killed worker leaves no half file and its task is simply
done again.

Things a task reports to an observer are kept by a :class:`ReportBuffer` in
the worker and come back with its result; the main process passes them to its
own observer (one recording, in task order): :func:`replay`.
"""

from __future__ import annotations

import contextlib
import itertools
import re
import warnings
from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolkit.errors import InputError, ToolkitError

#: How often a task is retried when it raised (a worker that died is no failure of its task: Dask
#: reschedules what it held on its own, up to ``distributed.scheduler.allowed-failures`` deaths).
RETRIES = 1
#: Tasks submitted ahead per worker (a bounded queue: a producer such as stage 1 runs ahead, no further).
AHEAD_PER_WORKER = 2
#: Worker-side objects kept per process (:func:`worker_cache`): a few runs' contexts.
CACHE_SIZE = 2
_SCHEDULER = re.compile(r"^(tcp|tls|inproc|ucx|ws|wss)://\S+$")
#: ``workers="auto"``: as many worker processes as this process may use cores (:func:`available_cores`).
AUTO = "auto"

_CACHE: OrderedDict = OrderedDict()


@dataclass(frozen=True)
class ParallelConfig:
    """Where tasks run.

    Parameters
    ----------
    workers : int
        Worker processes of a local cluster; 1: in this process, no Dask.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://HOST:PORT``); ``workers`` is then ignored.
    """

    workers: int = 1
    scheduler: str | None = None

    def __post_init__(self):
        if int(self.workers) != self.workers or int(self.workers) < 1:
            raise InputError("workers (--workers)", "a number of worker processes >= 1", repr(self.workers))
        if self.scheduler is not None and not _SCHEDULER.match(str(self.scheduler)):
            raise InputError("scheduler (--scheduler)", "a Dask scheduler address such as tcp://HOST:8786",
                             repr(self.scheduler))

    @property
    def sequential(self) -> bool:
        """Tasks run in this process, one after the other."""
        return self.scheduler is None and self.workers == 1


def _cgroup_cpus() -> float | None:
    """The CPU limit of this process's cgroup (cgroup v2 ``cpu.max``, v1 ``cpu.cfs_quota_us``), cores; None
    when there is none or it cannot be read."""
    from pathlib import Path

    for quota, period in ((Path("/sys/fs/cgroup/cpu.max"), None),
                          (Path("/sys/fs/cgroup/cpu/cpu.cfs_quota_us"), Path("/sys/fs/cgroup/cpu/cpu.cfs_period_us"))):
        try:
            fields = quota.read_text().split() + ([period.read_text().strip()] if period is not None else [])
            q, p = (float(f) for f in fields[:2])
        except (OSError, ValueError):
            continue
        if q > 0 and p > 0:  # "max" (v2) and -1 (v1) mean no limit
            return q / p
    return None


def available_cores() -> int:
    """Cores this process may run on: its CPU affinity (``os.sched_getaffinity``, else ``os.cpu_count``),
    capped by its cgroup's CPU limit (a container's ``--cpus``, rounded down, at least 1)."""
    import os

    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        n = os.cpu_count() or 1
    limit = _cgroup_cpus()
    if limit is not None:
        n = min(n, int(limit))
    return max(1, n)


def resolve_workers(workers: "int | str", tasks: int | None = None) -> int:
    """The number of worker processes of ``workers``: an integer as it is, :data:`AUTO` every available core
    (:func:`available_cores`) but no more than ``tasks`` (a run of one frame needs no cluster).

    Raises
    ------
    InputError
        Neither ``"auto"`` nor an integer >= 1.
    """
    if isinstance(workers, str) and workers.strip().lower() == AUTO:
        n = available_cores()
        return max(1, min(n, int(tasks))) if tasks is not None else n
    if isinstance(workers, str):
        n = int(workers) if workers.strip().isdigit() else 0
    elif isinstance(workers, (int, np.integer)) and not isinstance(workers, bool):
        n = int(workers)
    else:
        n = 0
    if n < 1:
        raise InputError("workers (--workers)", f"a number of worker processes >= 1, or {AUTO!r}", repr(workers))
    return n


def single_threaded() -> contextlib.AbstractContextManager:
    """Limit this process to one thread for BLAS / OpenMP (threadpoolctl) and OpenCV while in the block."""
    import cv2
    from threadpoolctl import threadpool_limits

    stack = contextlib.ExitStack()
    stack.enter_context(threadpool_limits(limits=1))
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    stack.callback(cv2.setNumThreads, before)
    return stack


def worker_cache(key: str, build: Callable[[], Any]) -> Any:
    """An object built once per process and key (a run's dataset, renderer ...), kept for its next tasks.

    Parameters
    ----------
    key : str
        Unique per run (e.g. a token drawn by the main process).
    build : callable
        Makes the object the first time; an object with ``close()`` is closed when evicted.
    """
    if key in _CACHE:
        _CACHE.move_to_end(key)
        return _CACHE[key]
    value = build()
    _CACHE[key] = value
    while len(_CACHE) > CACHE_SIZE:
        _, old = _CACHE.popitem(last=False)
        close = getattr(old, "close", None)
        if callable(close):
            close()
    return value


def drop_cached(key: str) -> None:
    """Forget (and close) this process's object of ``key``, if any."""
    old = _CACHE.pop(key, None)
    close = getattr(old, "close", None)
    if callable(close):
        close()


def _copied(value):
    """Arrays copied (a report keeps what was reported, even if the caller changes its array later)."""
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, dict):
        return {k: _copied(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_copied(v) for v in value]
    return value


@dataclass
class ReportBuffer:
    """An observer that keeps the reports of a task, to be replayed by the main process (:func:`replay`).

    Attributes
    ----------
    reports : list of (str, dict)
    """

    reports: list = field(default_factory=list)

    def report(self, kind: str, **data: Any) -> None:
        self.reports.append((kind, _copied(data)))


def replay(reports: list, observer) -> None:
    """Pass a task's reports to ``observer``, in the order they were made."""
    if observer is None:
        return
    for kind, data in reports:
        observer.report(kind, **data)


@dataclass(frozen=True)
class _Failed:
    """A toolkit error raised by a task, carried back as data (InputError does not unpickle as itself)."""

    kind: str
    args: tuple


def _call(fn: Callable, args: tuple) -> Any:
    """Run one task single-threaded; toolkit errors come back as :class:`_Failed`."""
    with single_threaded():
        try:
            return fn(*args)
        except InputError as e:
            return _Failed("input", (e.where, e.expected, e.found))
        except ToolkitError as e:
            return _Failed("toolkit", (str(e),))


def _unwrap(value):
    if isinstance(value, _Failed):
        raise InputError(*value.args) if value.kind == "input" else ToolkitError(*value.args)
    return value


#: Dask settings of the local cluster's workers (what each costs was measured on the default scene's frames):
#:
#: * ``MALLOC_TRIM_THRESHOLD_`` unset: Dask's nannies start workers with 65536, which turns off glibc's
#:   adaptive mmap threshold; every large temporary array is then mapped and unmapped afresh (page faults)
#:   and a frame's rendering took 3x the CPU time; the workers keep the allocator's defaults, as the main
#:   process has them.
#: * the workers' statistical profiler off: it samples the task thread's Python stack every 10 ms (taking
#:   the GIL from the task each time) for the dashboard's profile page, which these runs do not show.
#: * workers forked from a fork server that has imported Dask and the run's modules once
#:   (:func:`_forkserver`), instead of each worker starting a fresh interpreter and importing them again
#:   (5-6 s of CPU per worker on two cores busy with the run); a fork server is a single-threaded process,
#:   so forking it is safe, unlike forking this process (stage 1 and Dask's threads run in it).
#: * the housekeeping of the scheduler and the workers less often (the event loop's tick, the system and
#:   memory monitors, the cluster's status line): an idle local cluster of two workers used 13 % of a core
#:   with Dask's defaults (ticks every 20 ms, memory checks every 100 ms), that much taken from the frames.
LOCAL_WORKER_SETTINGS = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                         "distributed.worker.profile.enabled": False,
                         "distributed.worker.multiprocessing-method": "forkserver",
                         "distributed.admin.tick.interval": "1s",
                         "distributed.admin.system-monitor.interval": "2s",
                         "distributed.worker.memory.monitor-interval": "1s",
                         "distributed.deploy.cluster-repr-interval": "5s"}


def _forkserver(preload: tuple) -> None:
    """Have the fork server import Dask and ``preload`` (module names) before it forks the first worker.

    The fork server is one per process, started with the first local cluster; what it imports is fixed
    then (a later cluster of this process gets the same modules; its tasks import the rest themselves).
    """
    import multiprocessing

    from distributed.utils import get_mp_context

    get_mp_context()  # Dask's own preload (distributed and the packages it uses), set once per process
    modules = ["distributed", "numpy", "scipy", "cv2", *preload]
    multiprocessing.get_context("forkserver").set_forkserver_preload(modules)


def _client(config: ParallelConfig, preload: tuple = ()):
    """A Dask client: of the scheduler given, or of a new local cluster (closed with the client).

    ``preload``: modules the local cluster's workers import before their first task (:func:`_forkserver`).
    """
    from dask.distributed import Client, LocalCluster

    if config.scheduler is not None:
        try:
            return Client(config.scheduler, timeout="30s")
        except (OSError, TimeoutError) as e:
            raise InputError("scheduler (--scheduler)", "the address of a running Dask scheduler",
                             f"{config.scheduler!r}: {e}") from None
    import dask

    import multiprocessing

    settings = dict(LOCAL_WORKER_SETTINGS)
    if "forkserver" not in multiprocessing.get_all_start_methods():  # Windows: fresh interpreters
        settings["distributed.worker.multiprocessing-method"] = "spawn"
    with dask.config.set(settings):
        if settings["distributed.worker.multiprocessing-method"] == "forkserver":
            _forkserver(preload)
        cluster = LocalCluster(n_workers=int(config.workers), threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=40)  # a free port: never "8787 in use"
    client = Client(cluster)
    client._toolkit_cluster = cluster  # closed with the client (_close)
    return client


def _close(client) -> None:
    cluster = getattr(client, "_toolkit_cluster", None)
    client.close()
    if cluster is not None:
        cluster.close()


class Cluster:
    """Where tasks run, started before they come: its start overlaps the caller's own work.

    With a sequential :class:`ParallelConfig` nothing is started.  Use it as a
    context manager (closes the client, and the local cluster it started) and
    pass it to :func:`map_tasks` as ``parallel``.

    Parameters
    ----------
    config : ParallelConfig
    preload : tuple of str
        Modules a local cluster's workers import before their first task (once, in the process they are
        forked from: :data:`LOCAL_WORKER_SETTINGS`); ignored with a scheduler given.
    """

    def __init__(self, config: ParallelConfig, preload: tuple = ()):
        from concurrent.futures import ThreadPoolExecutor

        self.config = config
        self._client = None
        self._warm: list = []  # futures of the warm-up tasks (a future let go of is cancelled)
        self._pool = None if config.sequential else ThreadPoolExecutor(1)
        self._starting = None if config.sequential else self._pool.submit(_client, config, tuple(preload))

    @property
    def sequential(self) -> bool:
        return self.config.sequential

    def client(self):
        """The Dask client, once the cluster is up (waits for it)."""
        if self._client is None:
            self._client = self._starting.result()
        return self._client

    @property
    def slots(self) -> int:
        """Tasks the cluster runs at once (its workers' threads)."""
        if self.config.scheduler is None:
            return int(self.config.workers)
        return max(1, sum(self.client().nthreads().values()))

    def warm(self, fn: Callable) -> None:
        """Run ``fn()`` once on every worker as soon as the cluster is up, without waiting for it (imports,
        a run's context in :func:`worker_cache`); does nothing in this process with one worker."""
        if self._pool is not None:
            self._pool.submit(self._warm_all, fn)

    def _warm_all(self, fn: Callable) -> None:
        client = self._starting.result()
        for w in client.scheduler_info()["workers"]:
            self._warm.append(client.submit(_call, fn, (), pure=False, workers=[w], allow_other_workers=False))

    def close(self) -> None:
        if self._pool is None:
            return
        self._pool.shutdown(wait=True)
        self._pool = None
        if self._starting.exception() is None:
            _close(self._starting.result())

    def __enter__(self) -> "Cluster":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def map_tasks(fn: Callable, tasks: Iterable[tuple], *, parallel: "ParallelConfig | Cluster" = ParallelConfig(),
              on_result: Callable[[int, Any], None] | None = None, total: int | None = None,
              progress: bool = False, desc: str | None = None, unit: str = "task") -> list:
    """Run ``fn(*args)`` for every ``args`` of ``tasks``; results handed back in task order.

    Parameters
    ----------
    fn : callable
        Picklable (a module-level function, or an instance of a module-level class).
    tasks : iterable of tuple
        Arguments of each task; may be a generator (e.g. stage 1 over the
        frames): it is read ahead of the running tasks by at most
        ``AHEAD_PER_WORKER`` tasks per worker.
    parallel : ParallelConfig or Cluster
        Where the tasks run; a :class:`Cluster` given is used and left open.
    on_result : callable, optional
        ``on_result(i, result)`` for task ``i`` (0-based, in the order given), in
        that order, as soon as every earlier task's result was handed on.
        None: the results are returned.
    total : int, optional
        Number of tasks, for the progress bar.
    progress : bool
        One progress bar over all workers (driven by the tasks as they finish).
    desc, unit : str
        The bar's label and unit.

    Returns
    -------
    list
        The results in task order (empty when ``on_result`` takes them).

    Raises
    ------
    InputError
        A task's (re-raised in the main process), or a scheduler that cannot be reached.
    KeyboardInterrupt
        Interrupted: the tasks running are cancelled; results handed on stay handed on.
    """
    from tqdm import tqdm

    kept: list = []
    give = on_result if on_result is not None else (lambda i, r: kept.append(r))
    with tqdm(total=total, desc=desc, unit=unit, disable=not progress) as bar:
        if parallel.sequential:
            for i, args in enumerate(tasks):
                result = _unwrap(_call(fn, tuple(args)))
                bar.update(1)
                give(i, result)
            return kept
        own = not isinstance(parallel, Cluster)
        cluster = Cluster(parallel) if own else parallel  # starts while the first task's arguments are made
        try:
            _map_dask(fn, tasks, cluster, give, bar)
        finally:
            if own:
                cluster.close()
    return kept


def _map_dask(fn, tasks, cluster: Cluster, give, bar) -> None:
    """:func:`map_tasks` on a Dask cluster: submit ahead, collect as completed, hand on in order."""
    from dask.distributed import as_completed

    tasks = iter(tasks)
    first = next(tasks, None)  # e.g. stage 1 of the first frame, while the cluster starts
    client = cluster.client()
    if first is not None:
        tasks = itertools.chain([first], tasks)
    futures: dict = {}
    try:
        ahead = AHEAD_PER_WORKER * cluster.slots
        done = as_completed()
        ready: dict = {}
        index_of: dict = {}
        nxt = 0

        def collect(block: bool) -> None:
            nonlocal nxt
            batch = done.next_batch(block=block) if (block or done.has_ready()) else []
            for f in batch:
                i = index_of.pop(f.key)
                ready[i] = _unwrap(f.result())
                futures.pop(i)
                bar.update(1)
            while nxt in ready:
                give(nxt, ready.pop(nxt))
                nxt += 1

        for i, args in enumerate(tasks):
            while len(futures) >= ahead:
                collect(block=True)
            with warnings.catch_warnings():  # a frame's images go to one task, once: no data for Dask to share
                warnings.filterwarnings("ignore", message="Sending large graph")
                f = client.submit(_call, fn, tuple(args), pure=False, retries=RETRIES)
            futures[i], index_of[f.key] = f, i
            done.add(f)
            collect(block=False)
        while futures:
            collect(block=True)
    finally:
        if futures:
            client.cancel(list(futures.values()))


def map_scenes(fn: Callable, scenes: Iterable, *, workers: int = 1, scheduler: str | None = None,
               on_result: Callable[[int, Any], None] | None = None, progress: bool = False,
               desc: str = "scenes") -> list:
    """``fn(scene)`` for every scene of a benchmark, in parallel; results in the scenes' order.

    Parameters
    ----------
    fn : callable
        Picklable, one argument (a scene: a seed, a spec, a folder ...).
    scenes : iterable
    workers : int
        Worker processes (1: in this process).
    scheduler : str, optional
        A Dask scheduler's address.
    on_result : callable, optional
        ``on_result(i, result)`` in the scenes' order as they finish (e.g. a
        line printed per scene); the results are then not returned.
    progress : bool
    desc : str

    Returns
    -------
    list
        The results in the scenes' order (empty with ``on_result``).
    """
    scenes = list(scenes)
    return map_tasks(fn, ((s,) for s in scenes), parallel=ParallelConfig(int(workers), scheduler),
                     on_result=on_result, total=len(scenes), progress=progress, desc=desc, unit="scene")
