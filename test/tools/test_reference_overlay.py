"""`lander analyse --reference`: a de-orbit flight's powered descent against the fuel-optimal
reference from its handover state (lander_tools/reference_overlay.py), on a real bag.

The bag. A whole de-orbit recorded through the ROS nodes takes many minutes, and no flight can start
at the handover through them: the node builds the scene's `deorbit` controller in its slew and no
parameter starts it in a later phase (`DeorbitController.start_in` is Python only). So the bag is
written from a core-only flight of the common handover case of test/control/test_deorbit_mpc.py
(852 m, -36.8 m/s straight down, chute open, 67.39 kg; the scheduled law `deorbit` from
`start_in(PARACHUTE)`) with the nodes' own message code, in lockstep order: the simulator's
`SimAdapter.readout` and `fill_state`, the autopilot's `state_view` (the law flies on the message,
as in the node), its `fill_status` / `fill_demand_status` / `fill_throttle` / `fill_event` and the
node's MODE_CHANGED detail, written with the rosbags Writer and the project's type store, as the
recorder writes what it receives (bag time: a wall clock, mapped through /clock). The CDR bytes are
the type store's: byte for byte what the recorder got from the node for the same MODE_CHANGED event
of a recorded de-orbit flight (checked by hand), whereas `rclpy.serialization.serialize_message`
pads a FlightEvent with empty `values` by 4 bytes more (92 against 88), which rosbags refuses.
Its metadata names the scene `deorbit` (the vehicle; the initial state is the handover case's).
It is read back by the product's reader (`read_bag`, `Flight`).
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import warnings
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from handover_case import handover_sim

from lander_sim.physics.constants import MARS_RADIUS
from lander_tools import cli, reference_overlay
from lander_tools.analysis import Flight
from lander_tools.bagio import read_bag
from lander_tools.plotstyle import unlabelled_axes

DEMAND = 500.0
#: The tests that need the reference: two solves of ~10 s CPU each, shared by them (module fixtures):
#: the file took 28 s wall at a quiet moment and 55 s with the 2 cores shared, so slow, as the other
#: tests of the optimum are (test_deorbit_mpc.py, test_fuel_optimal.py).
SOLVES = pytest.mark.slow
EV_MODE_CHANGED = 11


@dataclasses.dataclass
class Recorded:
    """What the core-only flight itself knew (not read from the bag)."""

    path: Path
    handover: tuple[float, np.ndarray, np.ndarray, float] | None = None  # t, r_W, v_W, fuel
    hover: tuple[float, float] | None = None  # t, fuel


def _write_flight_bag(path: Path, until: float, after_hover: float = 3.0) -> Recorded:
    """Fly the handover case with `deorbit` to ``until`` s (or ``after_hover`` s into the hover),
    writing what the nodes would publish (module docstring)."""
    from builtin_interfaces.msg import Time
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosgraph_msgs.msg import Clock

    from lander_autopilot.controllers import Demand
    from lander_autopilot.controllers.deorbit import Phase
    from lander_autopilot.controllers.registry import make_controller
    from lander_autopilot.ros import convert as ap
    from lander_interfaces.msg import AutopilotStatus, FlightEvent, LanderState, ThrottleCommand
    from lander_sim.ros import convert as sim_convert
    from lander_sim.ros.sim_adapter import SimAdapter
    from lander_tools.bagio import lander_typestore

    sc, sim = handover_sim()
    adapter = SimAdapter(sim)
    ctrl = make_controller("deorbit", sc.vehicle)
    ctrl.start_in(Phase.PARACHUTE, chute_open=True)
    demand = Demand(altitude=DEMAND)
    rec = Recorded(path)
    types = lander_typestore()
    topics = {"/clock": "rosgraph_msgs/msg/Clock", "/lander/state": "lander_interfaces/msg/LanderState",
              "/lander/throttle": "lander_interfaces/msg/ThrottleCommand",
              "/autopilot/status": "lander_interfaces/msg/AutopilotStatus",
              "/lander/events": "lander_interfaces/msg/FlightEvent"}
    wall = 1_700_000_000 * 10**9  # the recorder's receive time (wall clock, ns)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        for k, v in {"scene": "deorbit", "controller": "deorbit", "speed": "0.0", "lockstep": "True"}.items():
            w.set_custom_data(k, v)
        conns = {t: w.add_connection(t, ty, typestore=types) for t, ty in topics.items()}

        def write(topic: str, msg) -> None:
            nonlocal wall
            wall += 1000
            w.write(conns[topic], wall, types.serialize_cdr(_as_rosbags(msg, topics[topic], types), topics[topic]))

        mode, sequence = ctrl.phase.value, 0
        while sim.t <= until + 1e-9:
            # the simulator publishes the instant
            sequence += 1
            snap = adapter.readout()
            clock, state = Clock(), LanderState()
            sim_convert.fill_stamp(clock.clock, snap.t)
            sim_convert.fill_state(state, sequence, snap)
            write("/clock", clock)
            write("/lander/state", state)
            # the autopilot answers it: throttles, mode change event, status
            view = ap.state_view(state, sc.vehicle.n_thrusters)
            out = ctrl.update(view.t, view, demand)
            if out.mode != mode:
                ev = FlightEvent()
                ap.fill_event(ev, stamp=state.header.stamp, kind=FlightEvent.MODE_CHANGED,
                              detail=f"controller 'deorbit' mode {mode!r} -> {out.mode!r}")
                write("/lander/events", ev)
                mode = out.mode
            cmd, status = ThrottleCommand(), AutopilotStatus()
            ap.fill_throttle(cmd, state, out.throttles)
            ap.fill_status(status, stamp=Time(sec=state.header.stamp.sec, nanosec=state.header.stamp.nanosec),
                           controller="deorbit", saturated=out.saturated, steps=sequence, rejected=0,
                           last_error="", throttles=out.throttles, state_ok=True)
            ap.fill_demand_status(status, demand, out.mode)
            write("/lander/throttle", cmd)
            write("/autopilot/status", status)
            if ctrl.phase is Phase.POWERED and rec.handover is None:
                rec.handover = (snap.t, snap.r_W.copy(), snap.v_W.copy(), float(snap.fuel))
            if ctrl.phase is Phase.HOVER and rec.hover is None:
                rec.hover = (snap.t, float(snap.fuel))
            if rec.hover is not None and snap.t >= rec.hover[0] + after_hover - 1e-9:
                break
            sim.set_throttles(out.throttles)  # lockstep: the step flies the answer
            sim.step()
            assert not [e for e in sim.drain_events() if e.kind.name in ("CRASHED", "LANDED", "HARD_LANDING")]
    return rec


def _as_rosbags(msg, msgtype: str, types):
    """An rclpy message as the type store's message of ``msgtype``, field by field."""
    from rosbags.interfaces import Nodetype

    values = {}
    for name, (kind, detail) in types.fielddefs[msgtype][1]:
        v = getattr(msg, name)
        if kind == Nodetype.NAME:
            values[name] = _as_rosbags(v, detail, types)
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            values[name] = np.asarray(list(v), dtype=detail[0][1][0])  # primitive elements (float64 here)
        else:
            values[name] = v
    return types.types[msgtype](**values)


def _analyse(*args: str) -> tuple[int, str, str]:
    """``lander analyse ARGS`` in this process (as the console script runs it): exit code, stdout, stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = cli.main(["analyse", *args])
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def flown(tmp_path_factory) -> Recorded:
    rec = _write_flight_bag(tmp_path_factory.mktemp("bag") / "deorbit-handover", until=60.0)
    assert rec.handover is not None and rec.hover is not None
    return rec


@pytest.fixture(scope="module")
def analysed(flown, tmp_path_factory):
    """``lander analyse BAG --reference --json --out DIR``; the overlay its real ``solve_reference``
    returned is kept by a spy (one solve serves every test)."""
    real, built = reference_overlay.solve_reference, []

    def spy(*args, **kwargs):
        built.append(real(*args, **kwargs))
        return built[-1]

    png = tmp_path_factory.mktemp("png")
    with mock.patch.object(reference_overlay, "solve_reference", spy):
        rc, out, err = _analyse(str(flown.path), "--reference", "--json", "--out", str(png))
    assert rc == 0, err
    assert len(built) == 1
    return json.loads(out), err, png, built[0]


@pytest.fixture(scope="module")
def optimum(flown):
    """``fuel_optimal.solve`` from the handover state the flight itself recorded (as bench/deorbit_fuel.py)."""
    from lander_autopilot.controllers.deorbit_mpc import handover_problem
    from lander_autopilot.guidance.fuel_optimal import solve
    from lander_sim.scenes import load_scene

    _, r_W, v_W, fuel = flown.handover
    problem, _ = handover_problem(load_scene("deorbit").vehicle, r_W, v_W, fuel, DEMAND)
    return solve(problem, steps=60)


@SOLVES
def test_the_handover_is_the_state_sample_of_the_powered_descent_event(flown, analysed):
    doc, _, _, overlay = analysed
    t, r_W, v_W, fuel = flown.handover
    h = overlay.handover
    # the event and its state share the stamp (lockstep): the very state the law decided on
    assert h.event_time == pytest.approx(t, abs=1e-9) and h.t == pytest.approx(t, abs=1e-9)
    assert np.array_equal(h.r_W, r_W) and np.array_equal(h.v_W, v_W) and h.fuel == fuel
    assert h.chute_open and overlay.demand_altitude == DEMAND
    assert overlay.scene == "deorbit" and overlay.controller == "deorbit"
    ref = doc["reference"][0]
    assert ref["handover_time"] == h.t and ref["handover_altitude"] == pytest.approx(np.linalg.norm(r_W) - MARS_RADIUS, abs=1e-9)
    assert ref["handover_climb_rate"] == pytest.approx(v_W[0], abs=1e-12)  # straight down along +x
    assert ref["handover_ground_speed"] == pytest.approx(0.0, abs=1e-9)


@SOLVES
def test_the_reference_is_fuel_optimal_solve_from_the_same_state(analysed, optimum):
    doc, _, _, overlay = analysed
    sol = overlay.solution
    assert sol.fuel == optimum.fuel and sol.final_time == optimum.final_time  # the same numbers
    assert np.array_equal(sol.thrust_L, optimum.thrust_L) and np.array_equal(sol.position_L, optimum.position_L)
    assert doc["reference"][0]["fuel_optimum"] == optimum.fuel
    assert doc["reference"][0]["optimum_final_time"] == optimum.final_time


@SOLVES
def test_flown_fuel_is_the_fuel_between_the_two_events_samples(flown, analysed):
    doc, _, _, overlay = analysed
    flight = Flight.from_bag(read_bag(flown.path))
    changes = [(t, d) for t, kind, d, _ in flight.events if kind == EV_MODE_CHANGED]
    assert [d.split("-> ")[-1] for _, d in changes] == ["'powered-descent'", "'hover'"]
    (t_p, _), (t_h, _) = changes
    fuel_at = {t: float(flight.fuel[np.searchsorted(flight.t, t - 1e-9)]) for t in (t_p, t_h)}
    assert overlay.fuel_flown == fuel_at[t_p] - fuel_at[t_h]
    assert overlay.fuel_flown == pytest.approx(flown.handover[3] - flown.hover[1], abs=1e-12)  # the flight's own count
    assert overlay.hover_time == pytest.approx(flown.hover[0], abs=1e-9)
    ref = doc["reference"][0]
    assert ref["fuel_flown"] == overlay.fuel_flown and ref["ratio"] == overlay.fuel_flown / overlay.fuel_optimum
    # the optimum is a lower bound up to its own tolerances (fuel_optimal.py; reference_overlay.py)
    assert ref["ratio"] >= 1.0 - reference_overlay.OPTIMUM_TOLERANCE
    assert ref["ratio"] < 2.0  # a sane law (docs/deorbit.md: the scheduled law ~1.06 x from this case)


@SOLVES
def test_the_png_is_written_with_every_axis_labelled(flown, analysed):
    _, err, png, overlay = analysed
    path = png / "flight-reference.png"
    assert f"wrote {path}" in err
    assert path.stat().st_size > 30_000  # five panels of lines, not an empty canvas
    import matplotlib.image

    img = matplotlib.image.imread(path)
    assert img.shape[0] > 1000 and float(np.std(img[..., :3])) > 0.05
    flight = Flight.from_bag(read_bag(flown.path))
    fig = reference_overlay.figure(flight, overlay)
    assert unlabelled_axes(fig) == []
    labels = [ax.get_ylabel() for ax in fig.get_axes()]
    assert labels == ["altitude [m]", "vertical speed [m/s]", "ground speed [m/s]", "thrust magnitude [N]", "fuel [kg]"]
    # the reference is drawn offset to the handover: it starts at the handover's altitude and time
    line = fig.get_axes()[0].get_lines()[1]
    assert line.get_xdata()[0] == overlay.handover.t
    assert line.get_ydata()[0] == pytest.approx(overlay.handover.altitude, abs=1e-6)
    # and without a hover in the bag the figure still draws, the text says why there is no ratio
    cut = dataclasses.replace(overlay, hover_index=None, hover_time=None, fuel_flown=None)
    assert unlabelled_axes(reference_overlay.figure(flight, cut)) == []
    assert "no MODE_CHANGED into 'hover'" in "\n".join(cut.lines()) and cut.ratio is None


@SOLVES
def test_the_text_report(analysed):
    _, _, _, overlay = analysed
    text = "\n".join(overlay.lines())
    h = overlay.handover
    assert f"altitude {h.altitude:.1f} m, vertical speed {h.climb_rate:.2f} m/s" in text
    assert f"fuel {overlay.fuel_flown:.3f} kg" in text and f"fuel {overlay.fuel_optimum:.3f} kg" in text
    assert f"flown / optimum: {overlay.ratio:.4f}" in text


def test_a_flight_without_a_powered_descent_is_one_line_and_not_an_error(tmp_path):
    rec = _write_flight_bag(tmp_path / "chute-only", until=3.0)  # under the chute: before the handover
    assert rec.handover is None
    rc, out, err = _analyse(str(rec.path), "--reference", "--json")
    assert rc == 0, err
    assert json.loads(out)["reference"] == [None]
    lines = [ln for ln in err.splitlines() if "reference" in ln]
    assert len(lines) == 1 and "no MODE_CHANGED into 'powered-descent'" in lines[0]
    assert lines[0].startswith(f"lander analyse: {rec.path}: no fuel-optimal reference: ")
    rc, out, err = _analyse(str(rec.path), "--reference")  # the table still comes
    assert rc == 0 and out.startswith("metric") and "fuel-optimal reference," not in out


def test_a_bag_without_a_scene_is_one_clear_error(flown, tmp_path):
    import shutil

    import yaml

    bag = tmp_path / "no-scene"
    shutil.copytree(flown.path, bag)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"]["custom_data"].pop("scene")
    (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))
    rc, _, err = _analyse(str(bag), "--reference")
    assert rc == 2 and "Traceback" not in err
    assert [ln for ln in err.splitlines() if "metadata names no scene" in ln]


def test_corrupt_and_truncated_bags_are_one_line(flown, tmp_path):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "bad.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\xff" * 100)
    (bad / "metadata.yaml").write_text("rosbag2_bagfile_information: {version: 9}\n")
    rc, _, err = _analyse(str(bad), "--reference")
    assert rc == 2 and "Traceback" not in err and err.startswith("lander analyse: ") and len(err.splitlines()) == 1
    data = next(flown.path.glob("*.mcap")).read_bytes()
    for fraction in (0.3, 0.9):  # a recorder killed mid-flight: no index, no metadata.yaml
        cut = tmp_path / f"cut-{fraction}"
        cut.mkdir()
        (cut / "cut.mcap").write_bytes(data[: int(len(data) * fraction)])
        rc, _, err = _analyse(str(cut), "--reference")
        assert rc == 2 and "Traceback" not in err, err
        assert all(ln.startswith("lander analyse: ") for ln in err.splitlines())
        # 0.3: nothing readable is left; 0.9: the states are, the scene (in metadata.yaml) is not
        assert ("not a readable MCAP bag" if fraction < 0.5 else "give the flight's scene with --scene") in err
    # with the scene given, the cut bag's handover is the whole bag's (the reference's input; no solve here)
    whole = reference_overlay.prepare(Flight.from_bag(read_bag(flown.path)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        flight = Flight.from_bag(read_bag(tmp_path / "cut-0.9"))
    assert any("truncated or damaged" in str(w.message) for w in caught)
    setup = reference_overlay.prepare(flight, scene="deorbit")
    a, b = setup.handover, whole.handover
    assert (a.t, a.fuel, a.chute_open) == (b.t, b.fuel, b.chute_open) and setup.fuel_flown == whole.fuel_flown
    assert np.array_equal(a.r_W, b.r_W) and np.array_equal(a.v_W, b.v_W)
    assert np.array_equal(setup.problem.velocity_L, whole.problem.velocity_L) and setup.problem.mass == whole.problem.mass
