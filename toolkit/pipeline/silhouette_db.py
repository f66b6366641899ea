"""Rendering a silhouette database as a run (``recipes/build_silhouette_db.py``).

:func:`run` renders the database of a :class:`~toolkit.silhouettes.BuildConfig`
(procedural motions, several seeded people each, and any BVH files, seen from
virtual cameras all around) with :func:`~toolkit.silhouettes.build_database`
and saves it.  Not a frame-by-frame run: it renders every sequence and writes
one file; the result does not depend on the number of workers.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from toolkit.errors import InputError
from toolkit.silhouettes.building import DEFAULT_BUILD, DEFAULT_SEED, BuildConfig


@dataclass(frozen=True)
class SilhouetteDatabaseRunConfig:
    """Options of a database build (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    build : BuildConfig
        What goes into the database (a ``[build]`` table in TOML: ``motions``,
        ``sequences_per_motion``, ``frames_per_sequence``, ``frame_stride``,
        ``views_per_pose``, ``mirror``, ``with_flow``, ...).
    bvh : tuple of Path
        BVH files to add (CMU or :func:`toolkit.motion.write_bvh` layout).
    seed : int
        Random seed (one seed per sequence is drawn from it).
    workers : int, optional
        Parallel processes (default: every core).
    progress : bool
        Show a progress bar.
    """

    build: BuildConfig = field(default_factory=lambda: DEFAULT_BUILD)
    bvh: tuple[Path, ...] = ()
    seed: int = DEFAULT_SEED
    workers: int | None = None
    progress: bool = True

    def __post_init__(self):
        if self.workers is not None and (isinstance(self.workers, bool) or int(self.workers) < 1):
            raise InputError("SilhouetteDatabaseRunConfig.workers (--workers)", "a positive integer",
                             repr(self.workers))

    @property
    def n_workers(self) -> int:
        """The processes used: ``workers``, else every core this process may use
        (:func:`toolkit.pipeline.parallel.available_cores`: CPU affinity and cgroup limits)."""
        from toolkit.pipeline.parallel import available_cores

        return int(self.workers) if self.workers is not None else available_cores()


@dataclass(frozen=True)
class BuiltDatabase:
    """What :func:`run` wrote.

    Attributes
    ----------
    path : Path
        The database file.
    entries : int
    seconds : float
        Rendering time (the file's writing excluded).
    size_bytes : int
    """

    path: Path
    entries: int
    seconds: float
    size_bytes: int


def run(config: SilhouetteDatabaseRunConfig, *, out, observer=None, log=print) -> BuiltDatabase:
    """Render the database of ``config`` and save it to ``out`` (``.npz``).

    Parameters
    ----------
    config : SilhouetteDatabaseRunConfig
    out : path
        Database file to write.
    observer : Observer, optional
        Receives the build's scalar reports and its summary.
    log : callable or None
        Receives what is rendered (entries, sequences, workers).

    Returns
    -------
    BuiltDatabase

    Raises
    ------
    InputError
        Neither a motion nor a BVH file, or bad build options.
    """
    from tqdm import tqdm

    from toolkit.silhouettes import build_database

    log = log or (lambda *_: None)
    build = config.build
    total = len(build.motions) * build.sequences_per_motion + len(config.bvh)
    if total == 0:
        raise InputError("--motions / --bvh", "at least one motion or BVH file", "none")
    log(f"rendering about {build.n_entries} entries from {total} sequences"
        f"{' + BVH' if config.bvh else ''} with {config.n_workers} worker(s) ...")
    bar = tqdm(total=total, desc="sequences", unit="seq", disable=not config.progress)
    t0 = time.perf_counter()
    try:
        db = build_database(build, config.seed, bvh_files=config.bvh, workers=config.n_workers, observer=observer,
                            progress=lambda done, _total: bar.update(done - bar.n))
    finally:
        bar.close()
    dt = time.perf_counter() - t0
    path = db.save(out)
    return BuiltDatabase(Path(path), len(db), dt, Path(path).stat().st_size)


def summary_lines(result: BuiltDatabase) -> list:
    """What a database build says when it ends (the recipe prints these)."""
    return [f"wrote {result.path}: {result.entries} entries in {result.seconds:.1f} s "
            f"({result.entries / result.seconds:.0f} entries/s), {result.size_bytes / 1e6:.1f} MB",
            f"use it with: python recipes/pose_from_silhouettes.py DATASET --out OUT --db {result.path}"]
