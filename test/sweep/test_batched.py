"""The batched core keeps the sweep's contract: each flight's metrics equal the per-flight path's.

Tolerance: the two paths differ only in the order of a few floating-point sums (the attitude
gain times the error; dot products), so states agree to ~1e-14 relative. Metrics are compared
to 1e-9 relative, with an absolute floor for the altitude-error metrics of 1e-9 of the altitude
(~500 m): an altitude error is ``|r_W| - R - h_d``, a difference of numbers of size 3.4e6 m whose
last bit is 4.7e-10 m, so near zero its relative error is not small although the flight is the same.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_sim.physics.wind import sample_gusts
from lander_tools.sweep import batched, flight, summary
from lander_tools.sweep.runner import run_dask, run_local
from lander_tools.sweep.spec import NONDETERMINISTIC_METRICS, parse_spec

from .conftest import SMALL, same_rows

ALTITUDE_METRICS = {"hover_error", "final_altitude_error"}
ALTITUDE_SCALE = 500.0  # [m]

CANTED = {**SMALL, "name": "canted", "scene": "hover-canted", "flights": 16, "seed": 77,
          "end": {"duration": 12.0, "demand_step_time": 4.0, "hover_window": 3.0}}
#: Every flight is told to go down to the ground: touchdowns (and failures, gusts) on both paths.
LANDING = {**CANTED, "name": "down", "flights": 6, "end": {"duration": 40.0, "demand_step_time": 1.0, "hover_window": 3.0,
                                                           "allow_touchdown": True},
           "dispersions": {**SMALL["dispersions"], "demand_altitude_step": {"uniform": {"min": -700.0, "max": -600.0}}}}


def _close(a: dict, b: dict) -> list[str]:
    """Fields where rows ``a`` and ``b`` differ beyond the tolerance (see the module docstring)."""
    bad = []
    for k, va in a.items():
        if k in NONDETERMINISTIC_METRICS:  # measured (compute time): not a property of the flight
            continue
        vb = b[k]
        if isinstance(va, float) and isinstance(vb, float):
            if math.isnan(va) and math.isnan(vb):
                continue
            floor = 1e-9 * ALTITUDE_SCALE if k in ALTITUDE_METRICS else 0.0
            if not abs(va - vb) <= 1e-9 * abs(vb) + floor:
                bad.append(f"{k}: {va!r} vs {vb!r}")
        elif va != vb:
            bad.append(f"{k}: {va!r} vs {vb!r}")
    return bad


@pytest.fixture(scope="module")
def canted():
    return parse_spec(CANTED, "canted")


def _compare_paths(spec) -> list[dict]:
    rows = batched.fly_chunk(spec, range(spec.flights))
    ref = [flight.fly_task(spec, ci, i) for i in range(spec.flights) for ci in range(len(spec.controllers))]
    assert [(r["index"], r["controller_index"]) for r in rows] == [(r["index"], r["controller_index"]) for r in ref]
    for a, b in zip(rows, ref):
        assert b["outcome"] != "error", b["error"]
        assert not _close(a, b), (a["index"], _close(a, b))
    return rows


def test_batched_rows_equal_per_flight_rows_with_every_dispersion_on(canted):
    rows = _compare_paths(canted)
    assert any(r["failed_thruster"] >= 0 for r in rows)  # failures were flown
    assert any(r["wind_gust"] > 0 for r in rows)


def test_touchdowns_end_each_flight_as_the_simulation_classifies_them():
    spec = parse_spec(LANDING, "down")
    rows = _compare_paths(spec)
    assert all(r["outcome"] in ("landed", "crashed") for r in rows)
    assert all(math.isfinite(r["touchdown_speed"]) for r in rows)


def test_a_flight_flown_alone_on_the_batched_core_is_bit_identical(canted):
    rows = batched.fly_chunk(canted, range(canted.flights))
    alone = batched.fly_chunk(canted, [5]) + batched.fly_chunk(canted, [11, 2])
    by_index = {r["index"]: r for r in rows}
    assert same_rows(alone, [by_index[5], by_index[2], by_index[11]])


def test_the_compiled_loop_on_threads_gives_the_same_rows(canted):
    assert same_rows(batched.fly_chunk(canted, range(6), parallel=True), batched.fly_chunk(canted, range(6)))


def test_gust_normals_are_the_numbers_the_simulation_draws(canted):
    fl = batched.setup_flight(canted, 3, 4)
    g = fl.sim.gusts
    assert g is not None
    n = 50
    packed = batched.pack_flights([fl], n)
    seq = np.empty((n + 1, 3))
    seq[0] = packed["gust_g0"][0]
    for k in range(n):  # the kernel's recurrence
        seq[k + 1] = seq[k] * packed["gust_ab"][0, 1] + packed["gust_w"][0, k] * packed["gust_ab"][0, 2]
    assert np.array_equal(seq, sample_gusts(g.config, fl.sim.dt, n + 1))


def test_sweep_says_which_path_it_took(canted, small_spec):
    got = run_local(canted, workers=1, progress=False)
    assert got.path == "batched"
    assert run_local(small_spec, workers=1, progress=False, indices=[0]).path_note.startswith(
        "per-flight (scene 'hover' has the stabiliser on")
    gs = parse_spec({**CANTED, "controllers": ["ground-speed"]}, "gs")
    assert "controller 'ground-speed' has no compiled form" in batched.unsupported_reason(gs)
    with pytest.raises(ValueError, match="batched core cannot fly this sweep"):
        run_local(small_spec, workers=1, progress=False, path="batched")


def test_same_seed_same_summary_on_two_local_processes_and_on_dask(canted):
    serial = run_local(canted, workers=1, progress=False)
    two = run_local(canted, workers=2, progress=False)
    dask = run_dask(canted, workers=2, progress=False)
    assert two.path == dask.path == "batched"
    assert same_rows(serial.rows, two.rows) and same_rows(serial.rows, dask.rows)
    text = summary.format_summary(summary.summarise(serial.rows, canted.metrics), [])
    assert text == summary.format_summary(summary.summarise(dask.rows, canted.metrics), [])
    per_flight = run_local(canted, workers=1, progress=False, path="per-flight")
    assert text == summary.format_summary(summary.summarise(per_flight.rows, canted.metrics), [])


def _bits(a) -> bytes:
    return np.ascontiguousarray(a).tobytes()


@pytest.mark.parametrize("spec_data", [CANTED, LANDING], ids=["canted", "landing"])
def test_fast_set_up_packs_the_numbers_the_flights_simulation_holds(spec_data):
    """The fast set-up (no scene, no Simulation per flight) gives, bit for bit, the packed model
    parameters, thrust, initial state, mean wind, gust process and normals, failure steps and
    demands that building each flight's scene and Simulation gives."""
    spec = parse_spec(spec_data, spec_data["name"])
    tpl = batched.template_of(spec)
    assert tpl.why_not is None
    idx = range(spec.flights)
    fast = [batched.setup_flight_fast(spec, i, tpl) for i in idx]
    ref = [batched.setup_flight(spec, i, 4) for i in idx]
    assert all(f.sim is None for f in fast)
    n = 120
    a, b = batched.pack_flights(fast, n, tpl), batched.pack_flights(ref, n)
    assert a.keys() == b.keys()
    for k in a:
        assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, k
        assert _bits(a[k]) == _bits(b[k]), k  # bitwise: -0.0 and NaN payloads included
    assert tpl.stop == ref[0].sim.ground.contact_radius and tpl.dt == ref[0].sim.dt
    if spec_data is CANTED:
        assert (a["fail_step"] >= 0).any() and (a["gust_ab"][:, 0] == 1.0).any()
    # A flight's Simulation, built when needed (touchdown hand-back), is the reference one.
    sim = fast[0].simulation()
    assert _bits(sim.y) == _bits(ref[0].sim.y) and sim.scheduled_failures == ref[0].sim.scheduled_failures


@pytest.mark.parametrize("spec_data", [CANTED, LANDING], ids=["canted", "landing"])
def test_fast_and_reference_set_up_give_bit_identical_rows(spec_data):
    spec = parse_spec(spec_data, spec_data["name"])
    fast = batched.fly_chunk(spec, range(spec.flights))
    ref = batched.fly_chunk(spec, range(spec.flights), fast_setup=False)
    assert same_rows(fast, ref)


def test_compact_rows_read_and_write_as_the_dicts(canted, tmp_path):
    from lander_tools.sweep import output

    rows = batched.fly_chunk(canted, range(canted.flights))
    rows[2] = {**rows[2], "outcome": "error", "error": 'line 1\nline "2"'}
    rows.insert(4, {"index": 3, "controller_index": 9, "controller": "x", "outcome": "error", "success": False, "error": "e"})
    table = output.RowTable(rows)
    assert len(table) == len(rows) and same_rows(table, rows) and same_rows([table[-1]], [rows[-1]])
    assert all(type(v) is type(w) for r, q in zip(table, rows) for v, w in zip(r.values(), q.values()))
    output.write_json(list(rows), tmp_path / "a.json")
    output.write_rows_json(table, tmp_path / "b.json")
    assert (tmp_path / "a.json").read_text() == (tmp_path / "b.json").read_text()
    output.write_csv(rows, tmp_path / "a.csv")
    output.write_csv(table, tmp_path / "b.csv")
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    shuffled = output.RowTable()
    for part in (rows[8:], rows[:8]):
        shuffled.extend(output.RowTable(part))
    assert same_rows(shuffled.sorted(), sorted(rows, key=lambda r: (r["index"], r["controller_index"])))


def test_a_fast_set_up_that_disagrees_falls_back_to_the_reference_set_up(canted, monkeypatch):
    """The per-chunk guard: if the fast set-up stopped reproducing the Simulation (e.g. a new
    dispersion it does not know), the chunk is set up by building each flight's Simulation."""
    ref = batched.fly_chunk(canted, range(4), fast_setup=False)
    tpl = batched.template_of(canted)
    assert batched.fast_setup_agrees(canted, batched.setup_flight_fast(canted, 0, tpl))
    good = batched.SetupTemplate.values

    def off(self, spec, case):
        v = good(self, spec, case)
        v["kparams"] = v["kparams"].copy()
        v["kparams"][7] *= 1.0 + 1e-12  # the dry mass, one part in 1e12 off
        return v

    monkeypatch.setattr(batched.SetupTemplate, "values", off)
    assert not batched.fast_setup_agrees(canted, batched.setup_flight_fast(canted, 0, tpl))
    assert same_rows(batched.fly_chunk(canted, range(4)), ref)
