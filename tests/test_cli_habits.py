"""The command line's habits: a version, help on every argument, unit slips and ball kinds refused in one
line, values that start with ``-`` read as values, and usage errors recorded under ``--record-failure``."""

import argparse
import importlib.metadata
import json

import pytest

from dropfit.cli import build_parser, main
from dropfit.settings import OPTIONS, stage_arguments

from helpers import assert_one_line_error, dropfit, write_drop_log


def test_version_is_the_package_version(tmp_path):
    """``dropfit --version`` prints one line with the version of the installed distribution's metadata."""
    version = importlib.metadata.version("dropfit")
    result = dropfit("--version", cwd=tmp_path)
    assert result.returncode == 0
    assert result.stdout.splitlines() == [f"dropfit {version}"]


def _commands(parser):
    """(name, parser) of the main parser and of every subcommand."""
    yield "dropfit", parser
    for action in parser._actions:  # argparse has no public walk of its subcommands
        if isinstance(action, argparse._SubParsersAction):
            yield from action.choices.items()


def test_every_argument_has_help():
    """Every option and positional argument of every subcommand says what it is."""
    missing = [f"{name} {action.dest}" for name, command in _commands(build_parser())
               for action in command._actions if not (action.help or "").strip()]
    assert missing == []


@pytest.mark.parametrize(("flag", "value", "option", "unit"),
                         [("--ball-radius-m", "3.35", "--ball-radius-m", "cm"), ("--ball-mass-kg", "57", "--ball-mass-kg", "g")])
def test_unit_slips_are_refused_naming_the_likely_unit(tmp_path, flag, value, option, unit):
    """A tennis ball's 3.35 cm radius or 57 g mass given in m or kg is refused in one line naming the option,
    the value and the unit it was likely written in; nothing is written."""
    log = write_drop_log(tmp_path / "drop.csv")
    result = dropfit("run", log, "--out", tmp_path / "out", flag, value, cwd=tmp_path)
    assert result.returncode == 1
    assert_one_line_error(result.stderr, "drop.csv")
    assert option in result.stderr and value in result.stderr and f"in {unit} (" in result.stderr
    assert not (tmp_path / "out" / "fit.json").exists()


def test_ball_type_any_case_or_refused(tmp_path):
    """``Tennis`` is the tennis ball (it gets the ITF verdict); ``Tenis`` is refused with the known kinds."""
    log = write_drop_log(tmp_path / "drop.csv")
    assert main(["run", str(log), "--out", str(tmp_path / "out"), "--ball-type", "Tennis"]) == 0
    fit = json.loads((tmp_path / "out" / "fit.json").read_text())
    assert fit["ball"]["type"] == "tennis" and fit["itf"]["verdict"] != "not applicable"
    result = dropfit("run", log, "--out", tmp_path / "bad", "--ball-type", "Tenis", cwd=tmp_path)
    assert result.returncode == 1
    assert_one_line_error(result.stderr, "drop.csv")
    assert "tennis" in result.stderr and "Tenis" in result.stderr


def test_values_and_paths_starting_with_a_dash(tmp_path):
    """A tiny negative floor (``-5e-05``, which argparse alone takes for an option) reaches the option as a
    number, both as ``--floor-m -5e-05`` and as the workflow's ``--floor-m=-5e-05``, and a recording named
    ``-drop.csv`` is read after ``--``."""
    write_drop_log(tmp_path / "-drop.csv")
    workflow = stage_arguments("measure", {}, {"floor_m": -5e-05})
    assert workflow == ["--floor-m=-5e-05"]
    for n, floor in enumerate((["--floor-m", "-5e-05"], workflow)):
        out = tmp_path / f"t{n}.nc"
        assert main(["measure", "--out", str(out), *floor, "--", str(tmp_path / "-drop.csv")]) == 0
        result = dropfit("measure", "--out", out, *floor, "--", "-drop.csv", cwd=tmp_path)
        assert result.returncode == 0, result.stderr


def test_usage_error_is_recorded_under_record_failure(tmp_path):
    """A bad option value under ``--record-failure`` writes every output's failure record naming the option
    (status 0, the batch goes on); without it, argparse's usage error (status 2) and nothing written."""
    args = ["analyse", "t.nc", "--impacts", "i.csv", "--flights", "f.csv", "--summary", "a.json",
            "--gravity-m-s2", "abc"]
    refused = dropfit(*args, cwd=tmp_path)
    assert refused.returncode == 2 and "--gravity-m-s2" in refused.stderr
    assert not any(tmp_path.iterdir())
    recorded = dropfit(*args, "--record-failure", cwd=tmp_path)
    assert recorded.returncode == 0
    assert_one_line_error(recorded.stderr, "t.nc")
    summary = json.loads((tmp_path / "a.json").read_text())
    assert summary["status"] == "failed" and "--gravity-m-s2" in summary["error"] and "abc" in summary["error"]
    assert (tmp_path / "i.csv").exists() and (tmp_path / "f.csv").exists()


def test_every_option_flag_is_bound_by_the_workflow():
    """The workflow's arguments bind each value to its flag, whatever the option."""
    row = {name: -5e-05 for name, option in OPTIONS.items() if option.column and not option.text}
    arguments = stage_arguments("measure", {}, row)
    assert arguments and all(argument.startswith("--") and "=" in argument for argument in arguments)
