"""Sweeps are reproducible: the same per-flight metrics serially, on 2 local processes, on a
local Dask cluster with 2 workers, and for a flight re-flown alone."""
from __future__ import annotations

import pytest

from lander_tools.sweep import flight
from lander_tools.sweep.runner import run_dask, run_local, tasks_of

from .conftest import same_rows


@pytest.fixture(scope="module")
def parallel(small_spec):
    return run_local(small_spec, workers=2, progress=False)


def test_every_flight_is_flown_once_in_index_order(parallel, small_spec):
    assert [(r["controller_index"], r["index"]) for r in parallel.rows] == tasks_of(small_spec)
    assert all(r["outcome"] != "error" for r in parallel.rows), [r["error"] for r in parallel.rows]


def test_parallel_equals_serial(parallel, small_spec):
    serial = run_local(small_spec, workers=1, progress=False)
    assert same_rows(serial.rows, parallel.rows)


def test_three_flights_replayed_alone_are_bit_identical(parallel, small_spec):
    # Empty the per-process caches first: "alone" means from scratch, as `--replay` would.
    flight.clear_caches()
    flight._CONTROLLERS.clear()
    picks = [1, 3, 5]
    alone = [flight.fly_case(small_spec, 0, i).row for i in reversed(picks)][::-1]
    assert same_rows(alone, [parallel.rows[i] for i in picks])


def test_local_dask_cluster_with_two_workers_gives_identical_rows(parallel, small_spec):
    result = run_dask(small_spec, workers=2, progress=False)
    assert result.workers == 2
    assert same_rows(result.rows, parallel.rows)
