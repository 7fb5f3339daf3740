"""The `lander` command line: every subcommand explains itself, mistakes give one line, no traceback.

Behaviour tests, no tolerances: exit codes and line counts are exact by design (argparse uses
exit 2 for usage errors; the CLI maps user errors, i.e. ValueError, to the same).
"""

import shutil
import subprocess
import sys
import types

import pytest

from lander_tools import cli

SUBCOMMANDS = ["fly", "scenes", "design", "analyse", "bench", "sweep"]


def run_main(capsys, *argv):
    """Run cli.main in-process; returns (exit code, stdout, stderr)."""
    try:
        code = cli.main(list(argv))
    except SystemExit as exc:  # argparse exits for --help and usage errors
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_top_level_help_lists_every_subcommand(capsys):
    code, out, _ = run_main(capsys, "--help")
    assert code == 0
    for name in SUBCOMMANDS:
        assert f"\n    {name} " in out, f"{name} missing from lander --help"


@pytest.mark.parametrize("name", SUBCOMMANDS)
def test_subcommand_help_exits_zero(capsys, name):
    code, out, err = run_main(capsys, name, "--help")
    assert code == 0, err
    assert out.startswith(f"usage: lander {name}")


@pytest.mark.parametrize("argv", [["no-such-command"], ["fly", "hover", "--no-such-option"],
                                  ["fly"], ["--no-such-option"], []])
def test_usage_errors_are_one_line_nonzero(capsys, argv):
    code, out, err = run_main(capsys, *argv)
    assert code == 2
    if argv:  # bare `lander` prints the help instead of a one-line error
        assert len(err.strip().splitlines()) == 1 and err.startswith("lander"), err
        assert "Traceback" not in err


def test_value_error_from_a_command_is_one_line(capsys, monkeypatch):
    """User errors (SceneError, InputError: ValueError subclasses) print `lander CMD: msg`, exit 2."""

    class SceneError(ValueError):
        pass

    def run(args):
        raise SceneError("unknown scene 'nowhere'\n(choices: hover, descent-10km)")

    fake = types.ModuleType("lander_tools.commands.fake")
    fake.add_arguments = lambda parser: parser.add_argument("scene")
    fake.run = run
    monkeypatch.setitem(sys.modules, "lander_tools.commands.fake", fake)
    monkeypatch.setitem(cli.SUMMARIES, "fake", "a test command")
    code, _, err = run_main(capsys, "fake", "nowhere")
    assert code == 2
    assert err == "lander fake: unknown scene 'nowhere'; (choices: hover, descent-10km)\n"


def test_scenes_lists_the_catalogue(capsys):
    from lander_sim import scenes

    code, out, _ = run_main(capsys, "scenes")
    assert code == 0
    listed = [line.split()[0] for line in out.splitlines()]
    assert listed == [s.name for s in scenes.list_scenes()]


def test_installed_console_script_runs_without_traceback():
    """The `lander` executable installed by ./dev (pip -e .) reaches cli.main."""
    exe = shutil.which("lander")
    assert exe, "`lander` not on PATH: run the tests through ./dev test"
    ok = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0 and "usage: lander" in ok.stdout
    bad = subprocess.run([exe, "no-such-command"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1
