"""Run the tasks of a study on Dask (``dask.distributed``): a :class:`~distributed.LocalCluster` on this
machine by default, or an existing cluster's scheduler (``tcp://HOST:PORT`` or its scheduler file).

Only the command-line entry points that distribute work import this module (it imports Dask, which costs
~0.5 s), so ``gaitlog --help`` and the other commands never load it.

The client (this process) submits the tasks without a stored result, and writes each result into the
:class:`~gaitlog.host.studies.task_store.TaskStore` as it arrives: the workers need no shared file system, and a run
cut at any point keeps every finished task (the next run computes only the others).

Tasks with a ``group`` attribute (e.g. :attr:`gaitlog.host.studies.sweep_grid.SweepTask.group`: the tasks of one simulated
walk) share an expensive set-up that a worker keeps in memory; the groups are dealt round-robin to the workers
as a preference (``allow_other_workers``: an idle worker still takes work), so each set-up is done about once
instead of once per worker. Placement changes the time only, never a result. The workers must be
able to import ``host`` (the same version): on a remote cluster, install gaitlog on every worker.

The local cluster's workers do not get Dask's default ``MALLOC_TRIM_THRESHOLD_=65536``: fixing glibc's trim
threshold turns off its dynamic mmap threshold, and the simulation's large numpy temporaries then cost page
faults on every allocation -- measured: rendering one walk took 1.3 s of CPU in such a worker, 0.6 s
without it (0.8 s in a worker without it). The thread limits (``OMP_NUM_THREADS=1``...) are kept.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

import dask
from distributed import Client, LocalCluster, as_completed

from gaitlog.host.errors import HostError
from gaitlog.host.studies.task_store import TaskStore

__all__ = ["run_on_dask"]


def run_on_dask(job: Callable[[Any], Any], tasks: Sequence[Any], store: TaskStore, *, scheduler: str | None = None,
                workers: int = 2, processes: bool = True, progress: Callable[[], object] | None = None,
                on_start: Callable[[str], object] | None = None) -> int:
    """Run the pending ``tasks`` (``job(task)`` each) on Dask, storing each result as it arrives; returns how many
    were computed.

    Parameters
    ----------
    scheduler
        Address of an existing scheduler (``tcp://HOST:PORT``), or the path of the scheduler file it writes
        (``dask scheduler --scheduler-file FILE``: waited for up to 30 s); None starts a :class:`LocalCluster` of
        ``workers`` single-threaded worker processes (threads with ``processes=False``) for this run.
    progress
        Called once per finished task.
    on_start
        Called with a description of where the tasks run (once connected).
    """
    todo = store.pending(tasks)
    if not todo:
        return 0
    if scheduler is None:
        if workers < 1:
            raise HostError(f"--workers must be >= 1, got {workers}")
        environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ", {}).items()
                   if k != "MALLOC_TRIM_THRESHOLD_"}
        with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                                   dashboard_address=None, silence_logs=logging.ERROR)
        client = Client(cluster)
    else:
        cluster = None
        try:
            client = (Client(scheduler, timeout="10s") if "://" in scheduler
                      else Client(scheduler_file=scheduler, timeout="30s"))
        except (OSError, TimeoutError) as err:
            raise HostError(f"--scheduler {scheduler}: cannot connect: {err}") from None
    try:
        if on_start is not None:
            n = len(client.scheduler_info().get("workers", {}))
            on_start(f"{'LocalCluster' if cluster is not None else scheduler}, {n} worker(s)")
        placed = _placement(todo, list(client.scheduler_info().get("workers", {})))
        futures = {client.submit(job, task, key=f"task-{task.key}", pure=False,
                                 **({"workers": placed[i], "allow_other_workers": True} if i in placed else {})): task
                   for i, task in enumerate(todo)}
        for future in as_completed(futures):
            store.write(futures[future], future.result())
            if progress is not None:
                progress()
            future.release()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return len(todo)


def _placement(tasks: Sequence[Any], workers: list[str]) -> dict[int, list[str]]:
    """Preferred worker of each task index: the groups (module notes) dealt round-robin, in order."""
    if len(workers) < 2:
        return {}
    groups: dict[Any, str] = {}
    out = {}
    for i, task in enumerate(tasks):
        g = getattr(task, "group", None)
        if g is None:
            continue
        if g not in groups:
            groups[g] = workers[len(groups) % len(workers)]
        out[i] = [groups[g]]
    return out
