"""Contracts of the controllers' parameter tables (lander_autopilot.controllers.params) for every law
the registry has: a parameter left out is its table's default; the default poles are the poles the
law closes; an unknown name is refused, by the registry and by the law's own constructor; a law made
of parts takes its parts' rows; a name shared by laws has one unit; and ``controller_params`` as the
autopilot node reads them (a ``--params`` file's) are checked by the same tables.

(The docs' generated tables and the per-row bad values: test_param_docs.py.)"""
from __future__ import annotations

import inspect
import re
import typing
from pathlib import Path

import numpy as np
import pytest

from lander_autopilot.controllers import ControllerError, Demand, make_controller
from lander_autopilot.controllers.registry import BUILTINS, available_controllers, parameter_table
from lander_autopilot.design.altitude import altitude_model
from lander_autopilot.design.attitude import attitude_model, quaternion_attitude_model
from lander_autopilot.design.gains import closed_loop_poles
from lander_autopilot.design.translational import horizontal_velocity_model
from lander_autopilot.ros.config import parse_controller_params
from lander_autopilot.ros.slot import build_choice
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation
from lander_tools.fly.checks import read_params_file
from lander_tools.fly.plan import AUTOPILOT_NODE

DOCS = Path(__file__).resolve().parents[2] / "docs"


@pytest.fixture(scope="module")
def vehicle():
    return load_scene("hover-canted").vehicle


#: The scene each law flies in the contract tests (the others hold a hover).
SCENE = {"deorbit": "deorbit", "deorbit-mpc": "deorbit", "landing": "landing", "ground-speed": "ground-speed"}


def test_each_built_in_is_listed_under_its_own_name_and_a_process_imports_only_the_law_it_flies():
    """The registry names each built-in law as the law names itself; building one law imports
    neither the de-orbit laws nor their solvers (a fresh interpreter, as a node starts)."""
    import subprocess
    import sys

    assert {name: BUILTINS[name].name for name in BUILTINS} == {name: name for name in BUILTINS}
    probe = ("import sys; from lander_autopilot.controllers import make_controller; "
             "from lander_sim.scenes.vehicles import lander; "
             "make_controller('combined-quaternion', lander()); "
             "print(sorted(m for m in ('lander_autopilot.controllers.deorbit', 'lander_autopilot.guidance.fuel_optimal', "
             "'numba', 'cvxpy', 'clarabel') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_registry_lists_every_law_with_its_table(capsys):
    from argparse import Namespace

    from lander_tools.commands.controllers import run

    assert run(Namespace(name=None, markdown=False, update_docs=False)) == 0  # `lander controllers`
    listed = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert listed == available_controllers() and set(BUILTINS) <= set(listed)
    for name in BUILTINS:
        table = parameter_table(name)
        assert table is not None and table.rows, name
        assert run(Namespace(name=name, markdown=False, update_docs=False)) == 0  # `lander controllers NAME`
        rows = capsys.readouterr().out.splitlines()
        assert rows[0].split() == ["name", "default", "unit", "range", "meaning"]
        assert [r.split()[0] for r in rows[1:]] == table.names, name


@pytest.mark.parametrize("name", sorted(BUILTINS))
def test_leaving_a_parameter_out_is_giving_its_tables_default(name):
    # The law built with nothing given flies its scene for 3 s; the law built with every default of
    # its table given answers the same states the same, bit for bit: what the table says a default
    # is, the law uses.
    table = parameter_table(name)
    assert table is not None
    scene = load_scene(SCENE.get(name, "hover-canted"))
    implicit = make_controller(name, scene.vehicle)
    explicit = make_controller(name, scene.vehicle, **table.defaults())
    wanted = scene.autopilot.demand_altitude if scene.autopilot is not None else None
    demand = Demand(altitude=500.0 if wanted is None else wanted, velocity=(1.0, -0.5))
    sim = Simulation(scene)
    while sim.t < 3.0:
        a, b = implicit.update(sim.t, sim.state(), demand), explicit.update(sim.t, sim.state(), demand)
        assert np.array_equal(a.throttles, b.throttles), (name, sim.t)
        assert (a.saturated, a.mode, a.requests) == (b.saturated, b.mode, b.requests), (name, sim.t)
        sim.set_throttles(a.throttles)
        sim.step()


def _poles(name: str, key: str = "poles") -> np.ndarray:
    table = parameter_table(name)
    assert table is not None
    return np.sort_complex(np.asarray(table[key].default, dtype=complex))


def test_the_default_poles_are_the_poles_each_law_closes(vehicle):
    fuel = vehicle.fuel_capacity  # design_fuel's default: a full tank
    alt = altitude_model(vehicle, fuel, 0.0)
    # placed poles are met to rounding; six repeated attitude poles (pairs per axis) spread as eps^(1/2)
    law = make_controller("altitude", vehicle)
    np.testing.assert_allclose(closed_loop_poles(alt.A, alt.B, law.K), _poles("altitude"), atol=1e-9)
    assert parameter_table("altitude-p")["p_only"].default is True
    assert make_controller("altitude-p", vehicle).K[0, 1] == 0.0  # eq 21: no climb-rate feedback
    law = make_controller("altitude-integral", vehicle)
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    B = np.array([[0.0], [0.0], [law.T_v / law.design_mass]])
    np.testing.assert_allclose(closed_loop_poles(A, B, law.K), _poles("altitude-integral"), atol=1e-9)
    euler = attitude_model(vehicle, fuel, np.asarray(parameter_table("attitude-euler")["design_attitude"].default))
    law = make_controller("attitude-euler", vehicle)
    np.testing.assert_allclose(closed_loop_poles(euler.A, euler.B, law.K), _poles("attitude-euler"), atol=1e-5)
    quat = quaternion_attitude_model(vehicle, fuel)
    law = make_controller("attitude-quaternion", vehicle)
    np.testing.assert_allclose(closed_loop_poles(quat.A, quat.B, law.K), _poles("attitude-quaternion"), atol=1e-5)
    A, B = horizontal_velocity_model()
    law = make_controller("ground-speed", vehicle)
    K = np.array([[law.k_i, law.k_p]])
    np.testing.assert_allclose(closed_loop_poles(A, B, K), _poles("ground-speed", "velocity_poles"), atol=1e-9)


@pytest.mark.parametrize("name", sorted(BUILTINS))
def test_an_unknown_name_is_refused_by_the_registry_and_by_the_laws_constructor(vehicle, name):
    table = parameter_table(name)
    assert table is not None
    accepted = f"accepted: {', '.join(sorted(table.names))}"
    with pytest.raises(ControllerError) as err:
        make_controller(name, vehicle, colour="red")
    assert f"controller {name!r}: unknown parameter(s) colour; {accepted}" == str(err.value)
    with pytest.raises(ControllerError) as err:
        BUILTINS[name](vehicle, colour="red")  # the class itself, not through the registry
    assert "unknown parameter(s) colour" in str(err.value) and accepted in str(err.value)


def test_a_law_made_of_parts_takes_its_parts_rows():
    def table(name):
        t = parameter_table(name)
        assert t is not None
        return t

    for summed, altitude, attitude in (("combined", "altitude", "attitude-euler"),
                                       ("combined-quaternion", "altitude", "attitude-quaternion"),
                                       ("integral", "altitude-integral", "attitude-euler")):
        for key, part, part_key in (("altitude_poles", altitude, "poles"), ("K_altitude", altitude, "K"),
                                    ("attitude_poles", attitude, "poles"), ("K_attitude", attitude, "K")):
            row, of = table(summed)[key], table(part)[part_key]
            assert (row.default, row.unit, row.range, row.check) == (of.default, of.unit, of.range, of.check), key
        assert table(summed)["design_fuel"] is table(altitude)["design_fuel"] is table(attitude)["design_fuel"]
    for law in ("combined", "integral", "lqr"):
        assert table(law)["design_attitude"] is table("attitude-euler")["design_attitude"]
    # ground-speed's parts are the summed law's (its attitude poles faster), landing's ground-speed's
    assert table("ground-speed")["altitude_poles"] == table("combined-quaternion")["altitude_poles"]
    assert table("ground-speed")["attitude_poles"].check is table("combined-quaternion")["attitude_poles"].check
    for key in ("max_tilt", "velocity_poles", "attitude_poles", "design_fuel"):
        assert table("landing")[key] is table("ground-speed")[key], key


def test_a_name_shared_by_laws_has_one_unit():
    # `K` is each law's own gain: its unit is that law's state's (1/m, s/m for the altitude law's
    # [h - h_e, h'], 1/rad, s/rad for the attitude laws'), and so is a summed law's `K_altitude`
    # (`integral`'s is altitude-integral's, on [int (h - h_e) dt, h - h_e, h']); every other shared
    # name has one unit
    units: dict[str, set[str]] = {}
    for name in BUILTINS:
        table = parameter_table(name)
        assert table is not None
        for row in table.rows:
            units.setdefault(row.name, set()).add(row.unit)
    assert {k: u for k, u in units.items() if len(u) > 1 and k not in ("K", "K_altitude")} == {}


def test_controller_params_as_the_node_reads_them_are_checked_by_the_table():
    # The node builds its law from the parameter's YAML text (build_choice): a --params file's
    # override flies, a value out of range is refused naming the parameter, the value and the range.
    default = build_choice("hover-canted", "lqr", parse_controller_params("")).controller
    slow = build_choice("hover-canted", "lqr", parse_controller_params("{R_altitude: 400.0}")).controller
    assert abs(slow.altitude_design.K[0, 0]) < abs(default.altitude_design.K[0, 0])  # a dearer throttle: a softer gain
    with pytest.raises(ControllerError, match=r"^R_altitude: expected a positive number, got -1$"):
        build_choice("hover-canted", "lqr", parse_controller_params("{R_altitude: -1}"))
    with pytest.raises(ControllerError, match=r"Q_altitude: expected 2 numbers >= 0, got \[1.0, -1.0\]"):
        build_choice("hover-canted", "lqr", parse_controller_params("{Q_altitude: [1.0, -1.0]}"))


def test_the_docs_params_file_example_flies_its_law_with_its_parameters(tmp_path):
    # docs/control.md's example --params file: the launcher accepts it, and the law it names is
    # built with the parameters it gives (a softer altitude gain than the default's)
    text = (DOCS / "control.md").read_text()
    example = re.search(r"```yaml\n# lqr-slow.yaml:  lander fly (\S+) --controller (\S+) --params lqr-slow.yaml\n(.*?)```",
                        text, re.S)
    assert example is not None, "the --params example in docs/control.md"
    scene, law, body = example.groups()
    (tmp_path / "lqr-slow.yaml").write_text(body)
    params = parse_controller_params(read_params_file(tmp_path / "lqr-slow.yaml")[AUTOPILOT_NODE]["controller_params"])
    assert params and set(params) <= set(parameter_table(law).names)
    given = build_choice(scene, law, params).controller
    default = build_choice(scene, law, {}).controller
    assert abs(given.altitude_design.K[0, 0]) < abs(default.altitude_design.K[0, 0])


@pytest.mark.parametrize("name", sorted(BUILTINS))
def test_a_laws_typed_keywords_are_its_tables_names(name):
    # a law typed `**params: Unpack[SomeParams]` (for the checker) lists exactly its table's rows
    (keywords,) = [p for p in inspect.signature(BUILTINS[name], eval_str=True).parameters.values()
                   if p.kind is p.VAR_KEYWORD]
    if typing.get_origin(keywords.annotation) is not typing.Unpack:
        assert keywords.annotation is object, name  # `**params: object`: the table alone says what they are
        return
    (typed,) = typing.get_args(keywords.annotation)
    assert sorted(typed.__annotations__) == sorted(parameter_table(name).names)
