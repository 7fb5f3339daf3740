"""docs/deorbit.md's example of changing a de-orbit parameter and flying it, checked for real.

The doc's block between ``<!-- example: deorbit-params -->`` and ``<!-- /example -->`` holds a
``--params`` file (YAML) and the command that flies it. The file must parse with the nodes' own
reader and the launcher's checks, every parameter it sets must be accepted by the ``deorbit``
law's table and reach the law built from it (a misspelt name is refused, naming it and the
accepted ones), and the command must fly: through the real simulator and autopilot nodes the
de-orbit burn begins at the ``slew_time`` the file sets, not at the default.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from lander_autopilot.controllers import ControllerError, make_controller
from lander_autopilot.controllers.registry import parameter_table
from lander_autopilot.ros.config import parse_controller_params
from lander_ros.params import read_params_file
from lander_sim.scenes import load_scene
from lander_tools.fly.checks import read_params_file as launcher_params
from lander_tools.fly.plan import AUTOPILOT_NODE

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "deorbit.md"
#: [s] flown past the burn's start: the event needs a control period or two after it
AFTER_BURN = 5.0
#: [s] the scene's control period (its dt): the burn starts on the control grid
PERIOD = 0.1


def example() -> tuple[str, list[str]]:
    """The example's params file text and its ``./dev fly`` command's arguments (after ``fly``)."""
    text = DOC.read_text()
    block = re.search(r"<!-- example: deorbit-params -->\n(.*?)<!-- /example -->", text, re.DOTALL)
    assert block, "docs/deorbit.md has no '<!-- example: deorbit-params -->' ... '<!-- /example -->' block"
    assert text[:block.end()].count("\n") < 100, "the example must be within the doc's first 100 lines"
    yaml_text = re.search(r"```yaml\n(.*?)```", block.group(1), re.DOTALL)
    command = re.search(r"^\./dev fly (.*)$", block.group(1), re.MULTILINE)
    assert yaml_text and command, "the example needs a ```yaml block and a './dev fly ...' line"
    return yaml_text.group(1), shlex.split(command.group(1).split("#")[0])


@pytest.fixture(scope="module")
def params_file(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    """The example's file, written under the name its command gives it, and the command's arguments."""
    text, args = example()
    where = tmp_path_factory.mktemp("example")
    name = args[args.index("--params") + 1]
    (where / name).write_text(text)
    return where / name, args


def controller_params(path: Path) -> dict[str, object]:
    sections = read_params_file(path)  # the nodes' reader
    assert launcher_params(path)[AUTOPILOT_NODE] == next(iter(sections.values()))  # the launcher's checks pass
    return parse_controller_params(launcher_params(path)[AUTOPILOT_NODE]["controller_params"])


def test_the_examples_parameters_are_the_de_orbit_laws_and_reach_it(params_file) -> None:
    path, args = params_file
    assert args[0] == "deorbit"  # the scene whose law is 'deorbit'
    params = controller_params(path)
    table = parameter_table("deorbit")
    assert table is not None and params and set(params) <= set(table.names)
    resolved = table.resolve(params, "deorbit")
    for name, value in params.items():
        assert resolved[name] == value != table[name].default, name  # each one changes the law
    law = make_controller("deorbit", load_scene("deorbit").vehicle, **params)
    built = {"slew_time": law.slew_time, "stop_above": law.descent.stop_above,
             "brake_fraction": law.descent.law.brake_fraction}
    assert {k: built[k] for k in params if k in built} == {k: v for k, v in params.items() if k in built}
    assert "slew_time" in params  # the flight below sees it


def test_a_misspelt_name_is_refused_naming_it_and_the_accepted_ones(params_file) -> None:
    params = controller_params(params_file[0])
    name = next(iter(params))
    wrong = {**{k: v for k, v in params.items() if k != name}, name[:-1]: params[name]}
    with pytest.raises(ControllerError) as err:
        make_controller("deorbit", load_scene("deorbit").vehicle, **wrong)
    message = str(err.value)
    assert f"controller 'deorbit': unknown parameter(s) {name[:-1]}; accepted:" in message
    assert name in message.split("accepted:")[1].replace(",", " ").split()


def test_the_example_flies_and_the_burn_starts_at_the_slew_time_it_sets(params_file) -> None:
    path, args = params_file
    slew = float(controller_params(path)["slew_time"])  # type: ignore[arg-type]
    default = parameter_table("deorbit")["slew_time"].default  # type: ignore[index]
    assert abs(slew - default) > 1.0
    cmd = [sys.executable, "-m", "lander_tools.cli", "fly", *args, "--duration", str(slew + AFTER_BURN), "--no-progress"]
    r = subprocess.run(cmd, cwd=path.parent, env=dict(os.environ, PYTHONPATH=str(REPO)), capture_output=True,
                       text=True, timeout=240, check=False)
    assert r.returncode == 0, r.stdout + r.stderr
    burn = re.search(r"event at t = ([0-9.]+) s: controller 'deorbit' mode 'deorbit-slew' -> 'deorbit-burn'", r.stdout)
    assert burn, r.stdout
    # a circular orbit: the burn is planned to start as soon as the slew allows
    assert slew <= float(burn.group(1)) < slew + PERIOD + 1e-9, r.stdout
