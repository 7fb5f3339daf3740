"""Fly a sweep's flights in parallel: local processes by default, or a Dask distributed cluster.

No job system of our own: :class:`concurrent.futures.ProcessPoolExecutor` over local cores, or
``dask.distributed`` (a ``LocalCluster`` by default, or a running scheduler's address). Both call
the same picklable task function, one flight per task, and return rows sorted by
``(flight index, controller)`` so the output does not depend on completion order.

Progress (tqdm): flights done, failures so far, time left; silent when stderr is not a TTY.
"""
from __future__ import annotations

import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from functools import partial
from typing import Any, Callable, Iterator, Sequence

from lander_tools.sweep.spec import SweepSpec

#: ``task(spec, controller_index, flight_index) -> row``; must be importable (picklable by reference).
Task = Callable[[SweepSpec, int, int], dict[str, Any]]


@dataclass(frozen=True)
class SweepResult:
    """Rows (one per flight and controller), wall time [s] and how they were run."""

    rows: list[dict[str, Any]]
    wall_time: float
    engine: str
    workers: int

    @property
    def flights_per_second(self) -> float:
        return len(self.rows) / self.wall_time if self.wall_time > 0 else float("nan")


def _default_task() -> Task:
    from lander_tools.sweep.flight import fly_task

    return fly_task


def tasks_of(spec: SweepSpec, indices: Sequence[int] | None = None) -> list[tuple[int, int]]:
    """``(controller index, flight index)`` pairs: every controller flies every case."""
    idx = range(spec.flights) if indices is None else indices
    return [(c, i) for i in idx for c in range(len(spec.controllers))]


def _progress(total: int, enabled: bool | None) -> Any:
    from tqdm import tqdm

    show = sys.stderr.isatty() if enabled is None else enabled
    return tqdm(total=total, unit="flight", disable=not show, smoothing=0.1, dynamic_ncols=True)


def _collect(done: Iterator[dict[str, Any]], total: int, progress: bool | None) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    failures = 0
    with _progress(total, progress) as bar:
        for row in done:
            rows.append(row)
            failures += not row["success"]
            bar.set_postfix(failures=failures, refresh=False)
            bar.update(1)
    rows.sort(key=lambda r: (r["index"], r["controller_index"]))
    return rows


def run_local(
    spec: SweepSpec,
    *,
    workers: int | None = None,
    indices: Sequence[int] | None = None,
    progress: bool | None = None,
    task: Task | None = None,
) -> SweepResult:
    """Fly on local processes; ``workers=None`` uses every core, ``workers=1`` flies in this process."""
    fn = task or _default_task()
    work = tasks_of(spec, indices)
    n = workers or os.cpu_count() or 1
    t0 = time.perf_counter()
    if n == 1:
        rows = _collect((fn(spec, c, i) for c, i in work), len(work), progress)
    else:
        with ProcessPoolExecutor(max_workers=n) as pool:
            futures = [pool.submit(fn, spec, c, i) for c, i in work]
            rows = _collect((f.result() for f in as_completed(futures)), len(work), progress)
    return SweepResult(rows, time.perf_counter() - t0, "local", n)


def run_dask(
    spec: SweepSpec,
    *,
    address: str | None = None,
    workers: int | None = None,
    indices: Sequence[int] | None = None,
    progress: bool | None = None,
    task: Task | None = None,
) -> SweepResult:
    """Fly on Dask distributed: a ``LocalCluster`` of ``workers`` (default 2) single-threaded
    processes, or the cluster whose scheduler listens at ``address`` (e.g. ``tcp://host:8786``).

    Workers of a real cluster need this project importable (same version) to unpickle the task.
    """
    from dask.distributed import Client, LocalCluster
    from dask.distributed import as_completed as dask_completed

    fn = task or _default_task()
    work = tasks_of(spec, indices)
    cluster = None
    t0 = time.perf_counter()
    if address is None:
        n = workers or 2
        # One thread per worker: the flights are pure-Python CPU work, threads would share the GIL.
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    else:
        client = Client(address)
        n = len(client.scheduler_info().get("workers", {}))
    try:
        futures = client.map(partial(fn, spec), [c for c, _ in work], [i for _, i in work], pure=False)
        rows = _collect((f.result() for f in dask_completed(futures)), len(work), progress)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return SweepResult(rows, time.perf_counter() - t0, "dask" if address is None else f"dask@{address}", n)
