"""Building a dataset: plan, shard, resume, run in parallel, write the manifest.

- Plan: the family lists every task (split, id, class, seed) deterministically.
- Shard ``i/n``: task ``k`` belongs to shard ``k mod n``; shards are independent processes
  (job-array pieces) writing into the same folder.
- Resume: a task is done when its record or skip marker exists; both are written atomically.
- Workers: a spawn process pool, one thread per worker for numpy/BLAS/torch.
- Manifest: written when no task is missing, by whichever run notices first (or ``--finalize``).
- One writer per shard: a lock file in the folder (:mod:`radar2shape.locking`) refuses a second
  build of the same shard; the shards of a job array lock separately and run side by side.
- SIGTERM: the record being built is dropped (its temporary file removed), finished ones stay, and
  :class:`radar2shape.preemption.Preempted` says how many are done; pool workers stop too.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import torch
from tqdm import tqdm

from data_modules.config import BuildConfig, config_from_dict
from data_modules.manifest import missing_tasks, write_manifest
from data_modules.record_builder import RecordBuilder
from data_modules.records import record_path, skip_path, write_json, write_record
from radar2shape import preemption
from radar2shape.errors import UserInputError
from radar2shape.geometry.families import ShapeTask

CONFIG_FILE = "build_config.json"
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")


@dataclass
class BuildSummary:
    """What one ``build_dataset`` call did."""

    planned: int  # tasks in this shard
    built: int  # records written by this call
    skipped: int  # skip markers written by this call
    already_done: int  # tasks found finished at the start (resume)
    manifest: dict | None  # the manifest, when this call could write it


def lock_name(shard: tuple[int, int]) -> str:
    """The lock file of a shard's writer (one for an unsharded build)."""
    index, count = shard
    return ".build-data.lock" if count == 1 else f".build-data.shard-{index}-of-{count}.lock"


def _check_config(root: Path, config: BuildConfig) -> None:
    """Refuse to mix records of different configs in one folder."""
    path = root / CONFIG_FILE
    current = config.to_dict()
    if path.exists():
        previous = json.loads(path.read_text())
        previous.setdefault("simulator", {})  # builds from before the simulator section used PO
        if previous != current:
            changed = sorted(k for k in set(previous) | set(current) if previous.get(k) != current.get(k))
            raise UserInputError(f"{root} holds a build with a different config (changed: {', '.join(changed)}); "
                                 "use another --out, or delete the folder to rebuild")
    else:
        write_json(path, current)


def build_task(builder: RecordBuilder, root: str | Path, task: ShapeTask) -> str:
    """Write ``task``'s record, or a skip marker with the reason; returns "built" or "skipped"."""
    try:
        record = builder.build(task)
    except Exception as err:  # any failure of one input skips it; the build goes on
        write_json(skip_path(root, task.split, task.record_id),
                   {"split": task.split, "id": task.record_id, "source": task.source or f"seed {task.seed}",
                    "reason": f"{type(err).__name__}: {err}"})
        return "skipped"
    write_record(record_path(root, task.split, task.record_id), record)
    return "built"


_WORKER_BUILDER: RecordBuilder | None = None  # one per pool worker, made by the initializer


def _init_worker(config_dict: dict) -> None:
    """Pool initializer: one torch thread (the workers are the parallelism), SIGTERM stops the
    record being built (its temporary file removed), then the builder."""
    global _WORKER_BUILDER
    preemption.install()
    torch.set_num_threads(1)
    _WORKER_BUILDER = RecordBuilder(config_from_dict(config_dict))


def _worker_task(root: str, task: ShapeTask) -> str:
    preemption.raise_if_received()  # queued before the signal: not started
    return build_task(_WORKER_BUILDER, root, task)


@contextmanager
def _threads_limited():
    """Spawned workers start with one BLAS/OpenMP thread each.

    Spawned children copy the environment when they start, before they import numpy, which is
    the only moment these variables take effect; the parent's environment is restored after.
    """
    saved = {name: os.environ.get(name) for name in _THREAD_VARIABLES}
    os.environ.update({name: "1" for name in _THREAD_VARIABLES})
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _statuses(config: BuildConfig, root: Path, todo: list[ShapeTask], workers: int) -> Iterator[str]:
    """Build ``todo`` in-process (``workers <= 1``) or in a spawn pool, yielding each status as it ends."""
    if not todo:
        return
    if workers <= 1:
        builder = RecordBuilder(config)
        yield from (build_task(builder, root, task) for task in todo)
        return
    with _threads_limited():
        pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_worker, initargs=(config.to_dict(),))
    try:
        yield from (future.result() for future in as_completed([pool.submit(_worker_task, str(root), t) for t in todo]))
    except BaseException:  # SIGTERM (here or in a worker), an error, or the caller stopping early
        _stop_workers(pool)
        raise
    pool.shutdown()


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel the queued tasks and SIGTERM the workers, which drop the record they are building;
    then wait for them (a bare ``shutdown`` would first build everything queued)."""
    import signal

    workers = list(multiprocessing.active_children())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in workers:
        if process.is_alive():
            os.kill(process.pid, signal.SIGTERM)
    for process in workers:
        process.join()


def build_dataset(config: BuildConfig, root: str | Path, workers: int = 1, shard: tuple[int, int] = (0, 1),
                  progress: bool = True) -> BuildSummary:
    """Build (or resume) shard ``shard`` of ``config`` into ``root``; write the manifest when complete."""
    index, count = shard
    if not 0 <= index < count:
        raise UserInputError(f"--shard: expected i/n with 0 <= i < n, got {index}/{count}")
    family = config.make_family()
    tasks = family.plan(config.num, config.splits, config.seed)  # before anything is written
    root = Path(root)
    from radar2shape.locking import folder_lock

    with folder_lock(root, lock_name(shard), f"another build-data of shard {index}/{count}", "--out"):
        _check_config(root, config)
        mine = tasks[index::count]
        todo = missing_tasks(root, mine)
        counts = {"built": 0, "skipped": 0}
        try:
            with tqdm(total=len(mine), initial=len(mine) - len(todo), unit="shape", disable=not progress,
                      desc=f"build-data {family.name} shard {index}/{count}", file=sys.stderr) as bar:
                for status in _statuses(config, root, todo, workers):
                    counts[status] += 1
                    bar.update()
        except preemption.Preempted as stop:
            done = len(mine) - len(missing_tasks(root, mine))
            stop.detail = f"{done} of {len(mine)} records of shard {index}/{count} done"
            raise
        manifest = None if missing_tasks(root, tasks) else write_manifest(root, config, family, tasks)
    return BuildSummary(len(mine), counts["built"], counts["skipped"], len(mine) - len(todo), manifest)


def finalize(config: BuildConfig, root: str | Path) -> dict:
    """Write the manifest of a finished build (all shards done); errors if records are missing."""
    root = Path(root)
    family = config.make_family()
    _check_config(root, config)
    return write_manifest(root, config, family, family.plan(config.num, config.splits, config.seed))
