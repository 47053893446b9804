"""The one orchestrator (dropfit.pipeline) and its settings: the command line's stages, ``dropfit run``, the
workflow's options and a notebook's ``dropfit.analyse_recording`` give the same numbers from the same
defaults; the result object; the options' checks and the site's g."""

import inspect
import json
import math

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import dropfit
from dropfit import pipeline
from dropfit.analysis import analyse_bounces
from dropfit.cli import main
from dropfit.contact import LinearContact
from dropfit.errors import InputError
from dropfit.heightlog import make_trajectory
from dropfit.balls import ball_kind
from dropfit.physics import (NORMAL_GRAVITY_SE_M_S2, STANDARD_GRAVITY_M_S2, UNKNOWN_SITE_GRAVITY_SE_M_S2, drag_parameter,
                             normal_gravity)
from dropfit.result import REPORT_SECTIONS
from dropfit.settings import (OPTIONS, Ball, OptionError, Settings, settings_from_config, split_options,
                              stage_arguments, workflow_values)
from dropfit.video.quality import SPEED_DEPENDENT_CENTRE_ERROR_PX, TRACKED_CENTRE_CORRELATION

from helpers import (DROP_BALL, DROP_FLOOR_M, RECORDING_FILES, assert_nothing_written, assert_one_line_error,
                     fit_numbers, option_arguments, write_bad_log, write_drop_log)

#: The workflow's config as config/config.yaml gives it, with a site (where the normal gravity is the
#: synthetic logs' standard gravity to 1e-7) and a wider ITF tolerance.
CONFIG = {"gravity_m_s2": None, "latitude_deg": 45.5, "altitude_m": 0.0, "analysis": {"drag": "auto"},
          "itf": {"drop_height_m": 2.54, "rebound_min_m": 1.35, "rebound_max_m": 1.47, "drop_height_tolerance_m": 0.03}}
#: A sample-sheet row of the drop log (empty cells as pandas reads them).
ROW = pd.Series({"sample_id": "drop", "kind": "height_log", "ball_type": DROP_BALL["ball_type"],
                 "ball_radius_m": DROP_BALL["ball_radius_m"], "ball_mass_kg": DROP_BALL["ball_mass_kg"],
                 "scale_m_per_px": np.nan, "floor_m": DROP_FLOOR_M, "ruler_tick_m": np.nan, "batch": "b"})


@pytest.fixture(scope="module")
def drop_log(tmp_path_factory):
    return write_drop_log(tmp_path_factory.mktemp("log") / "drop.csv")


@pytest.fixture(scope="module")
def drop_run(drop_log, tmp_path_factory):
    """The drop log through the workflow's stage commands (options as the workflow builds them) and
    through ``dropfit run``: (stage directory, run directory, run's stdout)."""
    root = tmp_path_factory.mktemp("runs")
    stages_dir, run_dir = root / "stages", root / "run"
    d = stages_dir
    commands = [
        ["measure", drop_log, "--out", d / "trajectory.nc", "--sample-id", "drop", *stage_arguments("measure", CONFIG, ROW)],
        ["analyse", d / "trajectory.nc", "--impacts", d / "impacts.csv", "--flights", d / "flights.csv",
         "--summary", d / "analysis.json", *stage_arguments("analyse", CONFIG, ROW)],
        ["fit", "--analysis", d / "analysis.json", "--impacts", d / "impacts.csv", "--out", d / "fit.json",
         *stage_arguments("fit", CONFIG, ROW)],
        ["report", "--trajectory", d / "trajectory.nc", "--flights", d / "flights.csv", "--impacts", d / "impacts.csv",
         "--analysis", d / "analysis.json", "--fit", d / "fit.json", "--html", d / "report.html",
         "--figure", d / "report.png"],
    ]
    for command in commands:
        assert main([str(argument) for argument in command]) == 0
    return stages_dir, run_dir, [str(a) for a in ["run", drop_log, "--out", run_dir, "--sample-id", "drop",
                                                  *stage_arguments("run", CONFIG, ROW)]]


def test_run_writes_what_the_workflow_stages_write(drop_log, drop_run, capsys):
    """``dropfit run`` and the workflow's four stage commands, the same options from the same config and
    sample row: the same files, impacts and flights byte for byte, the fit result number for number."""
    stages_dir, run_dir, run_args = drop_run
    capsys.readouterr()
    assert main(run_args) == 0
    out = capsys.readouterr().out
    assert len(out.splitlines()) == 1 and out.startswith("drop: e = ")
    assert sorted(path.name for path in run_dir.iterdir()) == sorted(RECORDING_FILES)  # no temporary left
    for name in ("impacts.csv", "flights.csv", "analysis.json", "fit.json"):
        assert (run_dir / name).read_bytes() == (stages_dir / name).read_bytes(), name
    run_fit = json.loads((run_dir / "fit.json").read_text(encoding="utf-8"))
    assert run_fit["status"] == "ok"
    assert run_fit["contact_height_m"]["value"] == DROP_FLOOR_M + DROP_BALL["ball_radius_m"]  # the row's floor
    assert run_fit["config"]["gravity_source"] == "normal gravity"  # the config's site reached the analysis
    assert run_fit["config"]["itf_drop_height_tolerance_m"] == 0.03
    with xr.open_dataset(run_dir / "trajectory.nc") as run_trajectory, \
            xr.open_dataset(stages_dir / "trajectory.nc") as stage_trajectory:
        assert run_trajectory.identical(stage_trajectory)
    assert (run_dir / "report.png").read_bytes().startswith(b"\x89PNG")
    assert "Restitution models" in (run_dir / "report.html").read_text(encoding="utf-8")

    # a notebook: the same recording, the same options, in memory
    ball, settings = settings_from_config(CONFIG, ROW)
    result = dropfit.analyse_recording(drop_log, sample_id="drop", settings=settings, ball_radius_m=ball.radius_m,
                                       ball_mass_kg=ball.mass_kg, ball_type=ball.type)
    assert fit_numbers(result.to_dict()) == fit_numbers(run_fit)
    assert result.to_dict() == run_fit
    written = pd.read_csv(run_dir / "impacts.csv")
    notes = written.pop("note")  # an empty note is read back as NaN
    assert [note if isinstance(note, str) else "" for note in notes] == list(result.impacts["note"])
    pd.testing.assert_frame_equal(result.impacts.drop(columns="note"), written, check_dtype=False, check_exact=True)


def test_defaults_are_the_same_everywhere(drop_log, tmp_path):
    """No option given anywhere: the stages, ``run`` and ``analyse_recording`` agree, and g is that of an
    unknown site (standard gravity with its standard error, which the analysis records)."""
    assert main(["run", str(drop_log), "--out", str(tmp_path / "run"), *option_arguments(DROP_BALL)]) == 0
    run_fit = json.loads((tmp_path / "run" / "fit.json").read_text(encoding="utf-8"))
    result = dropfit.analyse_recording(drop_log, **DROP_BALL)
    assert result.to_dict() == run_fit
    assert run_fit["config"]["gravity_m_s2"] == STANDARD_GRAVITY_M_S2
    assert run_fit["config"]["gravity_se_m_s2"] == pytest.approx(UNKNOWN_SITE_GRAVITY_SE_M_S2)
    assert run_fit["config"]["gravity_source"] == "unknown site"
    assert run_fit["drag"]["model"] in ("nominal", "quadratic")  # the ball's radius and mass give a drag prior
    assert stage_arguments("measure", {}, None) == []  # the workflow passes nothing it was not given


def test_analyse_recording_adds_the_nominal_drag_that_bare_analyse_bounces_leaves_out():
    """The issue: a steel ball's weak drag. ``analyse_bounces`` with its own defaults knows no ball and
    holds k at 0; the orchestrator holds it at the smooth sphere's k (with its error), as the workflow."""
    truth = dropfit.simulate_drop(0.5, 0.0125, {"kind": "constant", "e0": 0.92}, mass_kg=0.0642, drag_coefficient=0.5)
    log = dropfit.sample_height_log(truth, np.random.default_rng(3), 100.0, duration_s=2.5)
    bare = analyse_bounces(log["time_s"], log["y_m"])
    trajectory = make_trajectory(log["time_s"].to_numpy(), log["y_m"].to_numpy(), "steel", "test")
    result = dropfit.analyse_recording(trajectory, ball_radius_m=0.0125, ball_mass_kg=0.0642, ball_type="steel")
    assert bare.summary["drag_model"] == "none"
    assert result.fit["drag"]["model"] == "nominal"
    k = result.params["drag_k"]
    assert k.value == pytest.approx(drag_parameter(ball_kind("steel").drag_coefficient, 0.0125, 0.0642), rel=0.3) and k.stderr > 0
    assert result.params["e1"].stderr > bare.impacts["e_se"].iloc[0]  # the drag's error is carried


@pytest.fixture(scope="module")
def contact_result():
    """A 2 kHz log of a tennis ball on the seed's spring–damper floor (known): contact times, k and c."""
    truth = dropfit.simulate_drop(1.0, 0.0335, mass_kg=0.057, contact_model=LinearContact(3e4, 8.2))
    log = dropfit.sample_height_log(truth, np.random.default_rng(21), 2000.0, noise_m=1e-4, duration_s=1.6)
    trajectory = make_trajectory(log["time_s"].to_numpy(), log["y_m"].to_numpy(), "contact.csv", "test")
    return dropfit.analyse_recording(trajectory, floor_m=0.0, ball_radius_m=0.0335, ball_mass_kg=0.057,
                                     ball_type="tennis", latitude_deg=45.5)


def test_result_params_report_and_html(contact_result):
    result = contact_result
    impacts = result.impacts
    n = len(impacts)
    for number, row in zip(impacts["impact"], impacts.itertuples()):
        e = result.params[f"e{number}"]
        assert (e.value, e.stderr, e.ci95, e.unit) == (row.e, row.e_se, (row.e_ci95_low, row.e_ci95_high), "1")
        assert result.params[f"v_in{number}"].unit == "m/s"
        assert result.params[f"rebound_height{number}"].value == row.h_after_m
    resolved = impacts["contact_resolvable"].to_numpy()
    assert resolved.any()
    for number, ok, ms in zip(impacts["impact"], resolved, impacts["t_contact_ms"]):
        assert (f"contact_time{number}" in result.params) == bool(ok)
        if ok:
            assert result.params[f"contact_time{number}"].value == pytest.approx(1e-3 * ms, rel=1e-15)
            assert result.params[f"contact_time{number}"].unit == "s"
    restitution = result.fit["restitution"]
    assert result.params["e"].value == restitution["e"]["value"]
    model = restitution["model"]
    if model != "per_impact":
        assert {f"{model}_{name}" for name in restitution["parameters"]} <= set(result.params)
    for name in ("drop_height", "contact_height", "drag_k", "gravity", "contact_stiffness", "contact_damping",
                 "itf_rebound"):
        assert name in result.params, name
    assert result.params["contact_stiffness"].value == result.fit["contact_model"]["stiffness_n_m"]["value"]
    assert result.params["gravity"].value == normal_gravity(45.5)
    assert result.params["gravity"].stderr == NORMAL_GRAVITY_SE_M_S2
    assert all(isinstance(name, str) and name.isidentifier() for name in result.params)
    assert len(result.params) >= 4 * n + 6
    assert result.best_values["e1"] == result.params["e1"].value
    assert "e1" in repr(result.params["e1"])

    text = result.report()
    positions = [text.index(f"\n{title}\n{'-' * len(title)}\n") for title in REPORT_SECTIONS]
    assert positions == sorted(positions)
    assert restitution["model"] in text and "N/m" in text
    html = result._repr_html_()
    assert html.startswith("<div>") and "<table>" in html and "e1" in html
    assert result.summary().startswith("contact.csv: e = ")


def test_report_sections_are_fixed_when_parts_are_missing():
    """A tennis ball without mass or floor: no contact model, contact times not resolvable, an ITF verdict;
    still every section, in the same order."""
    truth = dropfit.simulate_drop(1.2, 0.0335, {"kind": "constant", "e0": 0.75}, mass_kg=0.057)
    log = dropfit.sample_height_log(truth, np.random.default_rng(8), 100.0, duration_s=2.5)
    log.loc[[40, 41, 42], "y_m"] = np.nan
    trajectory = make_trajectory(log["time_s"].to_numpy(), log["y_m"].to_numpy(), "tennis.csv", "test")
    result = dropfit.analyse_recording(trajectory, ball_radius_m=0.0335, ball_type="Tennis", gravity_m_s2=9.81)
    assert result.ball.type == "tennis"
    text = result.report()
    assert [line for line in text.splitlines() if line in REPORT_SECTIONS] == list(REPORT_SECTIONS)
    assert "itf_rebound" in result.params and "contact_stiffness" not in result.params
    assert any(note.startswith("no contact times") for note in result.notes)
    assert any("3 samples are dropouts" in note for note in result.notes)
    assert result.fit["config"]["gravity_se_m_s2"] == 0.0 and result.params["gravity"].value == 9.81
    assert json.dumps(result.to_dict(), allow_nan=False)


def test_analysis_options_are_made_in_one_place():
    attrs = {"ball_radius_m": 0.02, "ball_mass_kg": 0.05, "ball_type": "steel", "floor_m": 0.3, "floor_se_m": 1e-4,
             "video": "clip.avi", "scale_rel_se": 0.001, "source": "clip.avi", "scale_source": "gravity"}
    options = pipeline.analysis_options(attrs, Settings(drag="off", latitude_deg=45.0), sample_interval_s=0.004)
    assert options["contact_height_m"] == pytest.approx(0.32)
    assert options["contact_height_se_m"] == 1e-4
    assert options["contact_guard_s"] == pytest.approx(0.002)
    assert options["noise_correlation"] == TRACKED_CENTRE_CORRELATION
    steel = ball_kind("steel")
    assert options["nominal_drag_k_per_m"] == drag_parameter(steel.drag_coefficient, 0.02, 0.05) > 0
    assert options["nominal_drag_relative_se"] == pytest.approx(steel.drag_coefficient_se / steel.drag_coefficient)
    assert options["contact_time_exponent"] == (steel.contact_time_exponent, steel.contact_time_exponent_se)
    assert options["max_contact_time_s"] == steel.max_contact_time_s and options["ball_radius_m"] == 0.02
    assert options["drag"] == "off" and options["scale_rel_se"] == 0.001
    assert options["gravity_m_s2"] == normal_gravity(45.0)
    assert options["gravity_se_m_s2"] == NORMAL_GRAVITY_SE_M_S2
    assert options["contact_time_prior_s"] == (0.2e-3, 0.2e-3)
    assert options["gravity_scaled"] is True
    plain = pipeline.analysis_options({"source": "log.csv"}, Settings())
    assert plain["contact_height_m"] is None and plain["contact_guard_s"] == 0.0
    assert plain["nominal_drag_k_per_m"] == 0.0 and plain["noise_correlation"] == 0.0
    assert plain["gravity_scaled"] is False
    # a table tracked on a video by another tool: its frames were exposed around their times too, but its centres'
    # errors are not dropfit's tracker's; a Photron clip is tracked by dropfit
    tracked_elsewhere = pipeline.analysis_options({"source": "toss.trk", "import_format": "tracker",
                                                   "import_frame_rate_hz": 30.0, "scale_m_per_px": 0.002},
                                                  Settings(), sample_interval_s=1 / 30)
    assert tracked_elsewhere["contact_guard_s"] == pytest.approx(1 / 60)
    assert tracked_elsewhere["noise_correlation"] == 0.0 and tracked_elsewhere["speed_dependent_error_m"] == 0.0
    photron = pipeline.analysis_options({"source": "ball.cihx", "import_format": "mraw", "import_frame_rate_hz": 5000.0,
                                         "scale_m_per_px": 1e-4, "speed_error_px": 0.3}, Settings(),
                                        sample_interval_s=2e-4)
    assert photron["contact_guard_s"] == pytest.approx(1e-4)
    assert photron["noise_correlation"] == TRACKED_CENTRE_CORRELATION
    assert photron["speed_dependent_error_m"] == pytest.approx(1e-4 * 0.3)  # the tracker's, at the scale
    # a video trajectory written before the error was recorded per clip: the largest, a predicted codec's
    older = pipeline.analysis_options({"source": "clip.mp4", "video": "clip.mp4", "scale_m_per_px": 1e-3}, Settings(),
                                      sample_interval_s=1 / 30)
    assert older["speed_dependent_error_m"] == pytest.approx(1e-3 * SPEED_DEPENDENT_CENTRE_ERROR_PX)
    # every option is a parameter of analyse_bounces
    assert set(options) <= set(inspect.signature(analyse_bounces).parameters)


def test_site_gravity():
    assert Settings().site_gravity().source == "unknown site"
    assert Settings().site_gravity().se_m_s2 == UNKNOWN_SITE_GRAVITY_SE_M_S2
    site = Settings(latitude_deg=60.0, altitude_m=1000.0).site_gravity()
    assert (site.value_m_s2, site.se_m_s2) == (normal_gravity(60.0, 1000.0), NORMAL_GRAVITY_SE_M_S2)
    given = Settings(gravity_m_s2=9.8, latitude_deg=60.0).site_gravity()  # a given g wins
    assert (given.value_m_s2, given.se_m_s2, given.source) == (9.8, 0.0, "given")


@pytest.mark.parametrize("options, words", [
    ({"ball_radius_m": 33.5}, "ball_radius_m is 33.5 m, implausible: likely given in cm (0.335 m) or mm (0.0335 m); give the ball's radius in m"),
    ({"ball_mass_kg": 0}, "ball_mass_kg is 0"),
    ({"ball_type": "golf"}, "ball_type is 'golf', not a kind dropfit knows"),
    ({"gravity_m_s2": math.nan}, "gravity_m_s2 is nan"),
    ({"latitude_deg": 91}, "latitude_deg is 91"),
    ({"altitude_m": 100.0}, "altitude_m is given without latitude_deg"),
    ({"scale_m_per_px": 0.0}, "scale_m_per_px is 0"),
    ({"drag": "maybe"}, "drag is 'maybe'; give one of auto, off, on"),
    ({"itf_rebound_min_m": 1.5}, "the ITF rebound window is empty (itf_rebound_min_m 1.5 is not below itf_rebound_max_m"),
    ({"floor_m": "0.1"}, "floor_m is '0.1', not a number"),
])
def test_options_are_checked_once_with_one_line(options, words):
    with pytest.raises(OptionError) as caught:
        split_options(options)
    assert words in str(caught.value)
    assert "\n" not in str(caught.value)
    flags = caught.value.named(lambda name: OPTIONS[name].flag)
    assert "--" in flags and "_" not in flags.split(";")[0].replace("ITF rebound", "")


def test_tracker_hints_are_read_from_text_as_the_command_line_and_sample_sheet_give_them():
    ball, settings = split_options({"ball_colour": "#FF8000", "roi_px": "(10, 20, 300, 400)",
                                    "ball_at_px": "3 100.5 20", "ball_radius_px": 12})
    assert ball.colour == (0.0, 128.0, 255.0)  # BGR
    assert settings.roi_px == (10, 20, 300, 400)
    assert (settings.ball_at_px, settings.ball_radius_px) == ((3, 100.5, 20.0), 12.0)
    assert split_options({"ball_colour": "Tennis"})[0].colour == split_options({"ball_colour": "40,225,205"})[0].colour
    # what the workflow passes on (str of the held tuple) reads back the same
    assert split_options({"roi_px": str(settings.roi_px)})[1].roi_px == settings.roi_px
    for name, value in (("roi_px", "5,5,2,9"), ("ball_at_px", "1,2"), ("ball_colour", "mauve")):
        with pytest.raises(OptionError, match=name):
            split_options({name: value})


def test_tracker_hints_reach_the_video_tracker(tmp_path, monkeypatch):
    """The hints given as options reach the tracker under its names (the colour in BGR)."""
    passed = {}

    def fake_track(path, capture_fps=None, **keywords):
        passed.update(keywords)
        raise InputError(f"{path}: stopped after tracking")

    monkeypatch.setattr("dropfit.video.track.track_video_and_background", fake_track)
    ball, settings = split_options({"ball_colour": "red", "roi_px": "0,0,100,200", "ball_at_px": "5,50,60",
                                    "ball_radius_px": 8.0})
    with pytest.raises(InputError, match="stopped after tracking"):
        pipeline.measure_recording(tmp_path / "clip.avi", ball, settings)
    assert passed["expected_radius_px"] == 8.0
    hints = passed["hints"]
    assert (hints.roi_px, hints.ball_at_px, hints.ball_colour_bgr) == ((0, 0, 100, 200), (5, 50.0, 60.0),
                                                                       (40.0, 40.0, 200.0))


def test_unknown_settings_are_refused():
    with pytest.raises(TypeError, match="unknown setting gravity"):
        Settings().replace(gravity=9.81)
    with pytest.raises(TypeError, match="unknown option"):
        split_options({"radius_m": 0.1})


def test_workflow_values_map_config_and_row():
    values = workflow_values(CONFIG, ROW)
    assert values["latitude_deg"] == 45.5 and values["floor_m"] == DROP_FLOOR_M and "scale_m_per_px" not in values
    assert values["itf_drop_height_tolerance_m"] == 0.03 and values["drag"] == "auto"
    # a row's site replaces the config's whole site
    row = ROW.copy()
    row["gravity_m_s2"] = 9.79
    site = workflow_values(CONFIG, row)
    assert site["gravity_m_s2"] == 9.79 and "latitude_deg" not in site and "altitude_m" not in site
    assert sorted(stage_arguments("analyse", CONFIG, row)) == sorted(["--gravity-m-s2=9.79", "--drag=auto"])
    assert any(argument.startswith("--ball-radius-m=") for argument in stage_arguments("measure", CONFIG, row))
    assert stage_arguments("fit", CONFIG, row)[0] == "--ball-type=rubber"
    assert not any(argument.startswith("--ball-type") for argument in stage_arguments("qc", CONFIG, None))
    ball, settings = settings_from_config(CONFIG, row)
    assert ball == Ball(0.025, 0.05, "rubber") and settings.gravity_m_s2 == 9.79 and settings.latitude_deg is None


def test_a_trajectory_takes_no_measuring_options(drop_log):
    trajectory = dropfit.measure_recording(drop_log, Ball(radius_m=0.025))
    with pytest.raises(InputError, match="scale_m_per_px applies to measuring a recording"):
        dropfit.analyse_recording(trajectory, scale_m_per_px=0.001)
    with_floor = dropfit.analyse_recording(trajectory, floor_m=DROP_FLOOR_M, ball_mass_kg=0.05)
    assert with_floor.params["contact_height"].value == DROP_FLOOR_M + 0.025
    assert with_floor.fit["ball"]["mass_kg"] == 0.05
    assert "floor_m" not in trajectory.attrs  # the caller's trajectory is left as it was
    with pytest.raises(TypeError, match="a recording is a path or a trajectory"):
        dropfit.analyse_recording([0.0, 1.0])


def test_run_bad_input_one_line_and_nothing_written(tmp_path, capsys):
    log = write_bad_log(tmp_path, "not_a_number")
    out = tmp_path / "out"
    assert main(["run", str(log), "--out", str(out), "--ball-radius-m", "0.03"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert_one_line_error(captured.err, log.name)
    assert not out.exists() or list(out.iterdir()) == []
    assert main(["run", str(log), "--out", str(out), "--latitude-deg", "120"]) == 1
    assert "--latitude-deg is 120" in capsys.readouterr().err
    assert_nothing_written(out, *RECORDING_FILES)
    # a batch goes on: failure records in every file the workflow would write
    assert main(["run", str(log), "--out", str(out), "--record-failure"]) == 0
    message = capsys.readouterr().err.strip().removeprefix("dropfit: error: ")
    assert json.loads((out / "fit.json").read_text(encoding="utf-8")) == {"status": "failed", "error": message}
    assert sorted(path.name for path in out.iterdir()) == sorted(RECORDING_FILES)


def test_an_unknown_ball_type_of_an_old_trajectory_names_the_file():
    trajectory = make_trajectory(np.arange(10.0), np.ones(10), "old.csv", "test", {"ball_type": "golf"})
    with pytest.raises(InputError, match=r"^old\.csv: ball type 'golf' is not one dropfit knows"):
        pipeline.analysis_options(trajectory.attrs)


def test_capture_interval_counts_captures_where_the_ball_moves():
    """A 30 Hz capture in a 60 fps file: the repeats are found (and dropped) only while the ball moves, so the
    held ball's frames keep the file's 1/60 s step and outnumber the moving ones; the captures are 1/30 s apart,
    and the flights' limits count them. Without the ball's heights, the samples' median step."""
    held = np.arange(0.0, 2.0, 1 / 60)  # a hand holds the ball still for 2 s: 120 frames
    falling = 2.0 + np.arange(1, 30) / 30  # then 29 captures of a falling ball, each repeat dropped
    time = np.concatenate([held, falling])
    seen = np.concatenate([np.full(held.size, 1.0) + np.random.default_rng(0).normal(0.0, 2e-4, held.size),
                           1.0 - 0.5 * 9.81 * (falling - 2.0) ** 2])
    assert np.median(np.diff(time)) == pytest.approx(1 / 60)
    assert pipeline.capture_interval(time, seen) == pytest.approx(1 / 30)
    assert pipeline.capture_interval(time) == pytest.approx(1 / 60)
    seen[held.size:] = np.nan  # the ball never seen moving: the file's step is all there is
    assert pipeline.capture_interval(time, seen) == pytest.approx(1 / 60)
