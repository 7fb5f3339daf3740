"""Fly a sweep's flights in parallel: local processes by default, or a Dask distributed cluster.

No job system of our own: :class:`concurrent.futures.ProcessPoolExecutor` over local cores, or
``dask.distributed`` (a ``LocalCluster`` by default, or a running scheduler's address). Both return
rows sorted by ``(flight index, controller)`` so the output does not depend on completion order.

Two paths (:attr:`SweepResult.path`): when every controller of the spec has a compiled form and
the scene fits the compiled loop (:func:`lander_tools.sweep.batched.unsupported_reason`), flights
are flown in chunks on the **batched** core (locally in this process, its compiled loop on every
core; on Dask one chunk per task); otherwise **per-flight**, one picklable task function call per
flight. ``path="per-flight"`` forces the second; a custom ``task`` implies it.

Progress (tqdm): flights done, failures so far, time left; silent when stderr is not a TTY.
"""
from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from functools import partial
from typing import Any

from lander_tools.sweep.spec import SweepSpec

#: ``task(spec, controller_index, flight_index) -> row``; must be importable (picklable by reference).
Task = Callable[[SweepSpec, int, int], dict[str, Any]]


@dataclass(frozen=True)
class SweepResult:
    """Rows (one per flight and controller), wall time [s] and how they were run."""

    #: A list of dicts (per-flight path) or a compact :class:`~lander_tools.sweep.output.RowTable`
    #: of read-only row mappings (batched path); either reads as a sequence of rows.
    rows: Sequence[Any]
    wall_time: float
    engine: str
    workers: int
    #: ``batched`` (compiled core, chunks of flights) or ``per-flight``; and why not batched, or on the
    #: batched path what it flies besides the laws (the sensors and the filter of laws on the estimate).
    path: str = "per-flight"
    path_reason: str = ""

    @property
    def path_note(self) -> str:
        """One line saying which path flew the sweep (and why, for the per-flight path)."""
        return self.path if not self.path_reason else f"{self.path} ({self.path_reason})"

    @property
    def flights_per_second(self) -> float:
        return len(self.rows) / self.wall_time if self.wall_time > 0 else float("nan")


def _default_task() -> Task:
    from lander_tools.sweep.flight import fly_task

    return fly_task


def choose_path(spec: SweepSpec, path: str, task: Task | None) -> tuple[str, str]:
    """``(path, reason)``: ``batched`` if allowed and possible (the reason then says what it flies
    besides the laws, :func:`~lander_tools.sweep.batched.path_detail`), else ``per-flight`` and why."""
    if path not in ("auto", "batched", "per-flight"):
        raise ValueError(f"path must be 'auto', 'batched' or 'per-flight', got {path!r}")
    if path == "per-flight":
        return "per-flight", "asked for"
    if task is not None:
        return "per-flight", "custom task"
    from lander_tools.sweep.batched import path_detail, unsupported_reason

    why = unsupported_reason(spec)
    if why is not None and path == "batched":
        raise ValueError(f"the batched core cannot fly this sweep: {why}")
    return ("per-flight", why) if why is not None else ("batched", path_detail(spec))


def _chunk_task(spec: SweepSpec, indices: list[int]) -> Any:
    """The unit of work on the batched path: one chunk of flights, every controller, one thread;
    its rows as a compact :class:`~lander_tools.sweep.output.RowTable` (small to send back and keep)."""
    from lander_tools.sweep.batched import fly_chunk
    from lander_tools.sweep.output import RowTable

    return RowTable(fly_chunk(spec, indices, parallel=False))


def tasks_of(spec: SweepSpec, indices: Sequence[int] | None = None) -> list[tuple[int, int]]:
    """``(controller index, flight index)`` pairs: every controller flies every case."""
    idx = range(spec.flights) if indices is None else indices
    return [(c, i) for i in idx for c in range(len(spec.controllers))]


def _progress(total: int, enabled: bool | None) -> Any:
    from tqdm import tqdm

    show = sys.stderr.isatty() if enabled is None else enabled
    return tqdm(total=total, unit="flight", disable=not show, smoothing=0.1, dynamic_ncols=True)


def _chunk_progress(bar: Any) -> Callable[[list[dict[str, Any]]], None]:
    """Advance ``bar`` by a chunk of rows, counting failures as :func:`_collect` does."""
    failures = 0

    def advance(rows: list[dict[str, Any]]) -> None:
        nonlocal failures
        failures += sum(not r["success"] for r in rows)
        bar.set_postfix(failures=failures, refresh=False)
        bar.update(len(rows))

    return advance


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
    path: str = "auto",
    chunk: int | None = None,
) -> SweepResult:
    """Fly on local processes; ``workers=None`` uses every core, ``workers=1`` flies in this process.

    On the batched path each process flies chunks of ``chunk`` flights (default: about four chunks
    per worker, at most :data:`~lander_tools.sweep.batched.DEFAULT_CHUNK`)."""
    chosen, why = choose_path(spec, path, task)
    fn = task or _default_task()
    work = tasks_of(spec, indices)
    n = workers or os.cpu_count() or 1
    t0 = time.perf_counter()
    if chosen == "batched":
        return _run_local_batched(spec, n, indices, progress, chunk, why)
    if n == 1:
        rows = _collect((fn(spec, c, i) for c, i in work), len(work), progress)
    else:
        with ProcessPoolExecutor(max_workers=n) as pool:
            futures = [pool.submit(fn, spec, c, i) for c, i in work]
            rows = _collect((f.result() for f in as_completed(futures)), len(work), progress)
    return SweepResult(rows, time.perf_counter() - t0, "local", n, chosen, why)


def _run_local_batched(spec: SweepSpec, n: int, indices: Sequence[int] | None, progress: bool | None,
                       chunk: int | None, detail: str = "") -> SweepResult:
    """The batched path on ``n`` local processes: each flies whole chunks, set-up and compiled loop
    (one thread each); ``n = 1`` flies them in this process. Set-up (drawing the case, building its
    scene and Simulation) is Python, so processes rather than threads share it out. The wall time
    starts after the start-up (compiled loop loaded, controllers designed), as the per-flight path's
    would if its workers were warm; the pool's start is inside it."""
    from lander_tools.sweep.batched import DEFAULT_CHUNK, chunks, fly_chunk

    idx = list(range(spec.flights)) if indices is None else list(indices)
    size = chunk or min(DEFAULT_CHUNK, max(1, -(-len(idx) // (4 * n))))
    parts = list(chunks(idx, size))
    total = len(idx) * len(spec.controllers)
    # Start-up, not flying: load the compiled loop (numba cache) and design the controllers here,
    # once; forked workers inherit both. The wall time counts from after it.
    fly_chunk(spec, idx[:1], parallel=False)
    t0 = time.perf_counter()
    # Rows are kept as compact columns (RowTable, ~8 bytes a value): a 100,000-flight sweep's
    # rows take tens of MB, not a dict of Python objects per row.
    from lander_tools.sweep.output import RowTable

    table = RowTable()
    with _progress(total, progress) as bar:
        advance = _chunk_progress(bar)
        if n == 1:
            for part in parts:
                got = _chunk_task(spec, part)
                table.extend(got)
                advance(got)
        else:
            with ProcessPoolExecutor(max_workers=n) as pool:
                for fut in as_completed([pool.submit(_chunk_task, spec, part) for part in parts]):
                    got = fut.result()
                    table.extend(got)
                    advance(got)
    rows = table.sorted()
    return SweepResult(rows, time.perf_counter() - t0, "local", n, "batched", detail)


def run_dask(
    spec: SweepSpec,
    *,
    address: str | None = None,
    workers: int | None = None,
    indices: Sequence[int] | None = None,
    progress: bool | None = None,
    task: Task | None = None,
    path: str = "auto",
    chunk: int | None = None,
) -> SweepResult:
    """Fly on Dask distributed: a ``LocalCluster`` of ``workers`` (default 2) single-threaded
    processes, or the cluster whose scheduler listens at ``address`` (e.g. ``tcp://host:8786``).

    On the batched path each task is a chunk of flights (default: about four chunks per worker,
    at most :data:`~lander_tools.sweep.batched.DEFAULT_CHUNK` flights each) flown by the compiled
    loop on the worker's one thread. Workers of a real cluster need this project importable (same
    version) to unpickle the task.
    """
    from dask.distributed import Client, LocalCluster
    from dask.distributed import as_completed as dask_completed

    chosen, why = choose_path(spec, path, task)
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
        if chosen == "batched":
            from lander_tools.sweep.batched import DEFAULT_CHUNK, chunks

            idx = list(range(spec.flights)) if indices is None else list(indices)
            size = chunk or min(DEFAULT_CHUNK, max(1, -(-len(idx) // (4 * max(1, n)))))
            from lander_tools.sweep.output import RowTable

            futures = client.map(partial(_chunk_task, spec), list(chunks(idx, size)), pure=False)
            table = RowTable()
            with _progress(len(work), progress) as bar:
                advance = _chunk_progress(bar)
                for f in dask_completed(futures):
                    got = f.result()
                    table.extend(got)
                    advance(got)
            rows: Any = table.sorted()
        else:
            futures = client.map(partial(fn, spec), [c for c, _ in work], [i for _, i in work], pure=False)
            done = (f.result() for f in dask_completed(futures))
            rows = _collect(done, len(work), progress)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    engine = "dask" if address is None else f"dask@{address}"
    return SweepResult(rows, time.perf_counter() - t0, engine, n, chosen, why)
