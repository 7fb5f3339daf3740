"""The batched core on the estimate: the sensors and the navigation filter inside the compiled loop
give the per-flight path's flights (``flight.fly_case`` with ``onboard.Onboard``, the reference).

Tolerance, as ``test_batched.py``'s (1e-9 relative; altitude-error metrics to 1e-9 of a 500 m
altitude): the sensors take the very same normals (each sensor's own generator, drawn in the order
the Python sensor draws them), and the two paths differ only in the summation order of the small
products (``R v``, ``C f``, ``r . r``; numpy's BLAS against the kernels' loops), ~1e-16 relative
each. The filter feeds them back through the law, so they grow over a flight: measured at most
1.2e-10 relative (a touchdown tilt; fuel 1.2e-13) over 150-s and 400-s flights of both comparison
specs' cases, and the altitude errors differ at the last bit of ``|r_W|`` (4.7e-10 m at Mars' radius).
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from lander_autopilot.estimation.compiled import (
    nav_propagate,
    nav_update_altimeter,
    nav_update_doppler,
    nav_update_ground_fix,
    nav_update_star_tracker,
    pack_filter,
)
from lander_autopilot.estimation.flights import initial_covariance, initial_error_rng, start_filter
from lander_sim.scenes import load_scene
from lander_sim.sensors import compiled as sc
from lander_sim.sensors.base import Truth
from lander_sim.sensors.suite import SensorSuite
from lander_tools.sweep import batched, flight
from lander_tools.sweep import batched_kernel as bk
from lander_tools.sweep.runner import run_local
from lander_tools.sweep.spec import load_spec, parse_spec

from .conftest import same_rows
from .test_batched import _close

pytestmark = pytest.mark.skipif(not bk.HAVE_NUMBA, reason="the batched core needs numba")

ROOT = Path(__file__).resolve().parents[2]
#: A compiled law on each side: the landing law has none, so the landing specs' own laws fly per flight.
LAWS = [{"name": "combined-quaternion", "label": "truth"},
        {"name": "combined-quaternion", "label": "estimate", "navigation": "estimate"}]


def landing_spec(name: str, flights: int, duration: float):
    """The comparison spec ``sweeps/NAME.yaml`` (its scene with sensors, seed and dispersions) with a
    compiled law on the truth and on the estimate, ``flights`` flights of ``duration`` [s]."""
    data = yaml.safe_load((ROOT / "sweeps" / f"{name}.yaml").read_text())
    data.update(controllers=LAWS, flights=flights, end={**data["end"], "duration": duration})
    data.pop("acceptance", None)
    return parse_spec(data, f"{name}.yaml")


def _compare(spec, indices) -> list[dict]:
    rows = batched.fly_chunk(spec, indices)
    ref = [flight.fly_task(spec, ci, i) for i in indices for ci in range(len(spec.controllers))]
    assert [(r["index"], r["controller_index"]) for r in rows] == [(r["index"], r["controller_index"]) for r in ref]
    for a, b in zip(rows, ref):
        assert b["outcome"] != "error", b["error"]
        assert not _close(a, b), (a["index"], a["controller"], _close(a, b))
    return rows


@pytest.mark.parametrize(("name", "duration"), [("compare-nav-landing-hover", 40.0), ("compare-nav-landing-scenario1", 60.0)])
def test_each_landing_specs_cases_on_the_estimate_equal_the_per_flight_flights(name, duration):
    spec = landing_spec(name, 3, duration)
    assert batched.unsupported_reason(spec) is None
    rows = _compare(spec, range(3))
    truth, est = rows[0::2], rows[1::2]
    # on the estimate the flights are other flights than on the truth (the filter's errors steer them)
    assert all(a["fuel_used"] != b["fuel_used"] for a, b in zip(truth, est))


def test_every_sensor_and_the_sensor_dispersions_down_to_a_touchdown(tmp_path):
    """Ground fix on too, the sensor noise and bias dispersions, gusts and failures; demand to the
    ground: touchdowns handed back to the Simulation after flights on the estimate."""
    data = yaml.safe_load(Path(load_scene("landing-hover-sensors").source).read_text())
    data["name"] = "all-sensors"
    data["sensors"]["ground_fix"] = {"rate": 1.0, "position_noise": 20.0, "velocity_noise": 0.2}
    scene = tmp_path / "all-sensors.yaml"
    scene.write_text(yaml.safe_dump(data))
    spec = parse_spec({
        "name": "all", "scene": str(scene), "controllers": LAWS, "flights": 4, "seed": 31, "control_rate": 10.0,
        "end": {"duration": 60.0, "allow_touchdown": True},
        "dispersions": {"initial_altitude": {"uniform": {"min": -420.0, "max": -380.0}},
                        "initial_tilt": {"normal": {"mean": 0.0, "std": 0.05}},
                        "wind_gust": {"uniform": {"min": 0.0, "max": 1.0}},
                        "thruster_failure": {"probability": 0.5, "time": {"uniform": {"min": 1.0, "max": 20.0}}},
                        "sensor_noise_error": {"uniform": {"min": -0.3, "max": 0.3}},
                        "sensor_bias_error": {"uniform": {"min": -0.3, "max": 0.3}}},
    }, "all.yaml")
    rows = _compare(spec, range(4))
    assert all(r["outcome"] in ("landed", "crashed") for r in rows[1::2])


def test_flights_on_the_estimate_alone_in_chunks_on_threads_and_set_up_either_way_are_bit_identical():
    spec = landing_spec("compare-nav-landing-hover", 5, 20.0)
    rows = batched.fly_chunk(spec, range(5))
    by = {(r["index"], r["controller_index"]): r for r in rows}
    alone = batched.fly_chunk(spec, [3]) + batched.fly_chunk(spec, [4, 1])
    assert same_rows(alone, [by[(i, c)] for i in (3, 1, 4) for c in (0, 1)])
    assert same_rows(batched.fly_chunk(spec, range(5), parallel=True), rows)
    assert same_rows(batched.fly_chunk(spec, range(5), fast_setup=False), rows)  # each flight's scene and Simulation built
    # chunks of NAV_CHUNK flights inside one call: the same rows
    small = dataclasses.replace(spec, flights=batched.NAV_CHUNK + 2)
    idx = [0, 1, batched.NAV_CHUNK, batched.NAV_CHUNK + 1]
    whole = [r for r in batched.fly_chunk(small, range(small.flights)) if r["index"] in idx]
    assert same_rows(whole, batched.fly_chunk(small, idx))


def test_the_sweep_on_the_estimate_takes_the_batched_path_and_says_so():
    spec = landing_spec("compare-nav-landing-hover", 2, 10.0)
    got = run_local(spec, workers=1, progress=False)
    assert got.path == "batched"
    assert got.path_note == "batched (sensors and navigation filter compiled in the loop)"
    # the landing law itself has no compiled form: its comparison flies per flight and says why
    reason = batched.unsupported_reason(load_spec(ROOT / "sweeps" / "compare-nav-landing-hover.yaml"))
    assert reason == "controller 'truth' has no compiled form"
    plain = dataclasses.replace(spec, scene="landing-hover")
    assert batched.unsupported_reason(plain) == "controller 'estimate' flies on the estimate: scene 'landing-hover' has no sensors.imu"


def test_the_speed_line_of_lander_sweep_names_the_path(tmp_path, capsys):
    """The shipped comparison on the estimate that flies batched; ``--path`` picks the other path;
    ``--path batched`` on a sweep it cannot fly is one line naming why."""
    from lander_tools.cli import main

    spec = str(ROOT / "sweeps" / "compare-nav-hover.yaml")
    args = ["sweep", spec, "--flights", "2", "--workers", "1", "--no-plots"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert "flights/s (core-only, no ROS; batched (sensors and navigation filter compiled in the loop) path)" in \
        capsys.readouterr().out
    assert main([*args, "--out", str(tmp_path / "b"), "--path", "per-flight"]) == 0
    assert "flights/s (core-only, no ROS; per-flight (asked for) path)" in capsys.readouterr().out
    landing = str(ROOT / "sweeps" / "compare-nav-landing-hover.yaml")
    assert main(["sweep", landing, "--path", "batched", "--flights", "1", "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert err == ("lander sweep: --path batched: the batched core cannot fly this sweep: "
                   "controller 'truth' has no compiled form\n")


# --- the parts: the compiled sensors and filter against the Python ones -----------------------------


def _truths(n: int, dt: float, radius: float) -> list[Truth]:
    """A tumbling descent from 4.1 km: the altimeter out of range at first, the star tracker losing
    lock while the body turns fast (over 2 deg/s between 1 s and 2 s)."""
    out = []
    for i in range(n + 1):
        t = i * dt
        w = np.array([0.001, 0.05 if 1.0 <= t < 2.0 else 0.002, 0.003])
        a = 0.2 * t
        q = np.array([math.cos(a / 2), math.sin(a / 2) * 0.6, math.sin(a / 2) * 0.8, 0.0])
        h = 4100.0 - 30.0 * t
        out.append(Truth(t=t, r_W=np.array([10.0 * t, -(radius + h), 3.0]), v_W=np.array([10.0, 30.0, 0.1 * t]), q=q,
                         omega_B=w, f_B=np.array([0.1, -0.2, 3.7]) + 0.01 * t, planet_radius=radius))
    return out


def test_the_compiled_sensors_give_the_python_sensors_measurements_and_dropouts():
    """Same normals in the same order, same schedule, same dropouts: every measurement to 1e-12
    relative (the vector products' summation order), every sample's time and sensor alike."""
    scene = load_scene("landing-hover-sensors")
    data = dict(scene.sensors.sections)
    data["ground_fix"] = {"rate": 1.0, "position_noise": 20.0, "velocity_noise": 0.2}
    data["star_tracker"] = {**data["star_tracker"], "bias": 1e-4}
    data["doppler"] = {**data["doppler"], "bias": 0.01}
    data["altimeter"] = {**data["altimeter"], "bias": 0.3}
    sensors = dataclasses.replace(scene.sensors, seed=12345, sections=data)
    g = scene.models.get("gravity")
    dt, n = 0.1, 40
    truths = _truths(n, dt, g.radius)
    ref = SensorSuite(sensors)
    sp, bias, w, off = sc.pack_suite(SensorSuite(sensors), n, dt, g.radius, g.gm)
    cur, nxt, last = off[:5].copy(), np.zeros(5), np.full(5, -1.0)
    z, sig, got = np.zeros((5, 7)), np.zeros((5, 6)), np.zeros(5, dtype=np.int64)
    keys = list(sc.SENSORS)
    seen = {"measured": 0, "dropout": 0}
    for tr in truths:
        y = np.concatenate((tr.r_W, tr.v_W, tr.q, tr.omega_B, [0.0]))
        assert sc.sample_step(tr.t, y, tr.omega_B, tr.f_B, sp, bias, w, off, cur, nxt, last, z, sig, got)
        expect = ref.sample_due(tr)
        assert [keys[k] for k in range(5) if got[k]] == [key for key, _ in expect]
        for key, m in expect:
            k = keys.index(key)
            assert (got[k] == 2) == (m is None), (tr.t, key)
            if m is None:
                seen["dropout"] += 1
                continue
            seen["measured"] += 1
            np.testing.assert_allclose(z[k, :m.z.size], m.z, rtol=1e-12, atol=0.0)
            np.testing.assert_allclose(sig[k, :m.sigma.size], m.sigma, rtol=1e-12, atol=0.0)
    assert seen["dropout"] > 0 and seen["measured"] > 0


def test_the_filter_kernels_are_the_compiled_filter_to_rounding():
    """Propagation and each sensor's update on the packed state equal ``CompiledNavFilter``'s to
    1e-9 relative after 60 steps (its own agreement with the Python filter is 1.5e-12)."""
    from lander_autopilot.estimation.compiled import compiled_copy

    scene = load_scene("landing-hover-sensors")
    g = scene.models.get("gravity")
    truths = _truths(60, 0.1, g.radius)
    t0 = truths[0]
    P0 = initial_covariance(scene.sensors)
    filt = compiled_copy(start_filter(scene.sensors, t0.r_W, t0.v_W, t0.q, 0.0, P0, initial_error_rng(3), g.gm, g.radius))
    x, P, qc = pack_filter(filt)
    rng = np.random.default_rng(0)
    beam = np.array([0.0, 0.0, -1.0])
    for tr in truths[1:]:
        om, fm = tr.omega_B + 1e-4 * rng.standard_normal(3), tr.f_B + 1e-3 * rng.standard_normal(3)
        filt.propagate(om, fm, 0.1)
        assert nav_propagate(x, P, om, fm, 0.1, g.gm, qc)
        qm = tr.q / np.linalg.norm(tr.q)
        filt.update_star_tracker(qm, np.full(3, 1e-4))
        assert nav_update_star_tracker(x, P, qm, np.full(3, 1e-4))
        rho = 4100.0 - 30.0 * tr.t
        assert (filt.update_altimeter(rho, 5.0, beam) is None) != nav_update_altimeter(x, P, rho, 5.0, beam, g.radius)
        filt.update_doppler(np.array([1.0, 2.0, 30.0]), np.full(3, 0.3))
        assert nav_update_doppler(x, P, np.array([1.0, 2.0, 30.0]), np.full(3, 0.3))
        zf = np.concatenate((tr.r_W, tr.v_W))
        filt.update_ground_fix(zf, np.array([20.0] * 3 + [0.2] * 3))
        assert nav_update_ground_fix(x, P, zf, np.array([20.0] * 3 + [0.2] * 3))
    xr, Pr, _ = pack_filter(filt)
    np.testing.assert_allclose(x[0:6], xr[0:6], rtol=1e-9)
    np.testing.assert_allclose(x[6:], xr[6:], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(P, Pr, rtol=1e-9, atol=1e-9 * np.max(np.abs(Pr)))
    # a refused input leaves the state alone, as the Python filter's EstimationError does
    before = x.copy()
    assert not nav_update_doppler(x, P, np.array([1.0, math.nan, 3.0]), np.full(3, 0.3))
    assert not nav_update_star_tracker(x, P, np.array([2.0, 0.0, 0.0, 0.0]), np.full(3, 1e-4))
    assert np.array_equal(x, before)
