"""Importers of tables: any CSV, sensor exports, Tracker's data tables, ImageJ MTrack2 and TrackMate.

Every fixture is written here from the format's documentation (see each importer's module text)
from the tests' own closed-form bouncing ball (:func:`helpers.bouncing_ball`), and read back: times
and heights must be the truth within the table's rounding, and a full analysis of a bouncing track
must give back its e.
"""

import re
import shlex
from pathlib import Path

import numpy as np
import pytest
import yaml

from dropfit import analyse_recording
from dropfit.cli import main
from dropfit.errors import InputError, shown_path
from dropfit.heightlog import trajectory_from_log
from dropfit.importers import FORMATS, ImportOptions, read_track

from helpers import bouncing_ball, write_phyphox_export

#: The truth of most fixtures: a ball (centre 2 cm above the floor at contact) from 1 m, e = 0.5.
DROP_M, E_TRUE, CENTRE_M = 1.0, 0.5, 0.02  # m, 1, m
#: Rounding of the fixtures' numbers: 5 decimals in m (0.5e-5 m), 3 decimals of px.
ROUNDING_M = 6e-6  # m
#: e from 100 Hz noise-free tables of that ball must come within this of the truth (the analysis' own bias).
E_TOL = 0.01  # 1
UNIT_M = {"m": 1.0, "cm": 0.01, "mm": 0.001}  # m per unit, written out independently of dropfit


def truth(sample_rate_hz=100.0, duration_s=1.8):
    time = np.arange(0.0, duration_s, 1.0 / sample_rate_hz)
    return time, bouncing_ball(time, DROP_M, E_TRUE) + CENTRE_M


def rows(separator, *columns, formats):
    return "".join(separator.join(f"{value:{fmt}}" for value, fmt in zip(values, formats)) + "\n"
                   for values in zip(*columns))


def in_metres(track):
    return track.y * UNIT_M[track.unit]


# --- any CSV --------------------------------------------------------------------------------------

def _european(time, height):
    body = rows(";", time, height * 100, formats=(".3f", ".4f")).replace(".", ",")
    return "\ufeffZeit (s);Höhe (cm)\n" + body  # a spreadsheet's "CSV UTF-8" starts with a byte-order mark


GENERIC = {
    "height_m": lambda t, h: "time_s,height_m\n" + rows(",", t, h, formats=(".3f", ".5f")),
    "european_semicolons_decimal_commas_bom": _european,
    "german_slash_units_tabs": lambda t, h: "Zeit/s\tHöhe/mm\n" + rows("\t", t, h * 1000, formats=(".3f", ".2f")),
    "brackets_and_spaces": lambda t, h: "time_s y_cm\n" + rows(" ", t, h * 100, formats=(".3f", ".4f")),
    "units_in_square_brackets": lambda t, h: "time [ms],height [mm]\n" + rows(",", t * 1000, h * 1000,
                                                                             formats=(".0f", ".2f")),
    "uppercase": lambda t, h: "TIME_S,Y_M\n" + rows(",", t, h, formats=(".3f", ".5f")),
    "position_m_quoted": lambda t, h: '"Time (s)","Position (m)"\n' + rows(",", t, h, formats=(".3f", ".5f")),
}


@pytest.mark.parametrize("name", GENERIC)
def test_any_csv_is_read_in_its_units(name, tmp_path):
    """Headers with their units in many spellings, other separators, decimal commas and a BOM: the height in m
    is the truth within the table's rounding."""
    time, height = truth()
    path = tmp_path / f"{name}.csv"
    path.write_text(GENERIC[name](time, height), encoding="utf-8")
    track = read_track(path)
    assert track.source_format == "csv"
    np.testing.assert_allclose(track.time_s, time, atol=1e-6)
    np.testing.assert_allclose(in_metres(track), height, atol=ROUNDING_M)
    assert track.mapping.startswith(f"read {shown_path(path)} as time")


def test_the_guessed_mapping_is_printed_and_a_european_log_gives_the_true_e(tmp_path, capsys):
    """dropfit measure on a semicolon, decimal-comma log prints one line saying what it read as what, and the
    analysis gives back e."""
    time, height = truth()
    path = tmp_path / "messung.csv"
    path.write_text(_european(time, height), encoding="utf-8")
    assert main(["measure", str(path), "--out", str(tmp_path / "trajectory.nc")]) == 0
    assert capsys.readouterr().err == f"read {shown_path(path)} as time 'Zeit (s)' [s], height 'Höhe (cm)' [cm]\n"
    result = analyse_recording(path)
    assert result.fit["restitution"]["e"]["value"] == pytest.approx(E_TRUE, abs=E_TOL)


def test_a_windows_spreadsheet_csv_in_cp1252_is_decoded_and_advice_pastes_into_a_shell(tmp_path, capsys):
    """German Excel saves "CSV" in Windows-1252 ('Höhe' as the byte 0xF6, not UTF-8): it is decoded so, the line
    saying so, and e comes back (it read 'H\ufffdhe (cm)', no height column). The advice naming a column with
    spaces is quoted, so that it pastes into a shell and names the columns."""
    time, height = truth()
    path = tmp_path / "messung.csv"
    path.write_bytes(_european(time, height).removeprefix("\ufeff").encode("cp1252"))
    assert main(["measure", str(path), "--out", str(tmp_path / "trajectory.nc")]) == 0
    assert capsys.readouterr().err == (f"read {shown_path(path)} as time 'Zeit (s)' [s], height 'Höhe (cm)' [cm] "
                                       f"(the text is not UTF-8: decoded as Windows cp1252)\n")
    assert analyse_recording(path).fit["restitution"]["e"]["value"] == pytest.approx(E_TRUE, abs=E_TOL)
    unknown = tmp_path / "gewicht.csv"
    unknown.write_bytes(_european(time, height).removeprefix("\ufeff").replace("Höhe (cm)", "Größe (kg)")
                        .encode("cp1252"))
    with pytest.raises(InputError) as refused:
        read_track(unknown)
    advice = str(refused.value).split("--columns ", 1)[1]
    assert advice == "'time=Zeit (s)[s],y=COL[m]'"
    pasted = shlex.split(advice.replace("COL", "Größe (kg)"))  # as a shell passes it: one argument
    assert read_track(unknown, ImportOptions(columns=pasted[0])).y == pytest.approx(height * 100, abs=6e-5)


def test_columns_option_maps_columns_the_names_do_not_tell(tmp_path, capsys):
    """Columns named a, b, c: refused with the list of columns and what to write; --columns reads them."""
    time, height = truth()
    path = tmp_path / "abc.csv"
    path.write_text("a,b,c\n" + rows(",", time, np.ones_like(time), height * 100, formats=(".3f", ".0f", ".4f")))
    with pytest.raises(InputError, match=r"abc.csv: cannot tell which column is the time among 'a', 'b', 'c'; "
                                         r"name it with --columns"):
        read_track(path)
    track = read_track(path, ImportOptions(columns="time=a[s],y=c[cm]"))
    np.testing.assert_allclose(in_metres(track), height, atol=ROUNDING_M)
    assert main(["measure", str(path), "--out", str(tmp_path / "t.nc"), "--columns", "time=a[s],y=c[cm]"]) == 0
    assert capsys.readouterr().err == f"read {shown_path(path)} as time 'a' [s], height 'c' [cm]\n"


@pytest.mark.parametrize("header, options, message", [
    ("time_s,height", {}, r"the height column 'height' names no unit; give it with --columns, e.g. 'y=height\[cm\]'"),
    ("t (s),height_m,y (cm)", {}, r"2 columns could be the height \('height_m', 'y \(cm\)'\); name one with --columns"),
    ("a,b", {"columns": "time=a[s],y=q[m]"}, r"--columns names 'q' for the height, but the columns are 'a', 'b'"),
    ("a,b", {"columns": "when=a"}, r"--columns 'when=a' is not a mapping such as time=t\[s\],y=height\[cm\]"),
    ("a,b", {"columns": "time=a[h],y=b[m]"}, r"--columns names the unit 'h', not one dropfit reads"),
    ("time_s,height_kg", {}, r"cannot tell which column is the height among 'time_s', 'height_kg'; name it with "
                             r"--columns 'time=time_s\[s\],y=COL\[m\]'"),
    ("time (m),height (m)", {}, r"the time column 'time \(m\)' is in m, not a unit of time"),
    ("a,b", {"columns": "time=a[ms]"}, r"--columns names no height \(y=COL\[m\]\) column; .* --kind audio"),
])
def test_tables_that_cannot_be_read_say_why_in_one_line(header, options, message, tmp_path):
    """Each failure class of the generic reader: one InputError naming the file, what is wrong, what to try."""
    time, height = truth()
    width = len(header.split(","))
    path = tmp_path / "bad.csv"
    path.write_text(header + "\n" + rows(",", time, *[height] * (width - 1), formats=(".3f",) + (".4f",) * (width - 1)))
    with pytest.raises(InputError, match=r"^" + re.escape(shown_path(path)) + ": .*" + message):
        read_track(path, ImportOptions(**options))


def test_time_going_back_is_refused(tmp_path):
    path = tmp_path / "back.csv"
    path.write_text("Zeit (s);Höhe (m)\n0,00;1,0\n0,02;0,99\n0,01;0,98\n")
    with pytest.raises(InputError, match=r"back.csv: time goes back at sample 3 \(0.02 s then 0.01 s\); sort the table"):
        read_track(path)


# --- sensors ----------------------------------------------------------------------------------------

SENSOR_HEIGHT_M = 1.5  # m, a motion detector above the drop, looking down
#: The rest position is found from a plateau of the distance: within the detector's 1 mm quantisation.
REST_TOL_M = 1e-3  # m


def _logger_pro_two_runs(time, distance):
    header = '"Run 1: Time (s)","Run 1: Position (m)","Run 2: Time (s)","Run 2: Position (m)"\n'
    short = len(time) // 2  # run 1 is shorter: its tail is blank
    lines = [f"{t:.3f},{d - 0.1:.4f},{t:.3f},{d:.4f}" if i < short else f",,{t:.3f},{d:.4f}"
             for i, (t, d) in enumerate(zip(time, distance))]
    return header + "\n".join(lines) + "\n"


def _capstone(time, distance):
    return '"Time (s) Run #1","Position (m) Run #1"\n' + rows(",", time, distance, formats=(".3f", ".4f"))


@pytest.mark.parametrize("name, writer, options, expected_format", [
    ("logger_pro", _logger_pro_two_runs, {"track_id": 2}, "vernier"),
    ("capstone", _capstone, {}, "pasco"),
])
def test_motion_detector_distance_becomes_height(name, writer, options, expected_format, tmp_path):
    """A motion detector above the ball logs its distance down: with --sensor-height-m the height is that minus
    the distance; without, the direction comes from the bounces and the zero is where the ball rests."""
    time, height = truth(duration_s=2.5)  # at rest from 1.35 s on
    distance = SENSOR_HEIGHT_M - height
    path = tmp_path / f"{name}.csv"
    path.write_text(writer(time, distance))
    given = read_track(path, ImportOptions(sensor_height_m=SENSOR_HEIGHT_M, **options))
    assert given.source_format == expected_format
    np.testing.assert_allclose(given.y, height, atol=6e-5)
    found = read_track(path, ImportOptions(**options))
    np.testing.assert_allclose(found.y, height - CENTRE_M, atol=REST_TOL_M)
    assert "where the ball comes to rest" in found.notes[-1]


def test_a_motion_detector_held_for_seconds_points_the_right_way(tmp_path):
    """A quiet motion detector at 20 Hz, to the mm, the ball held 5 s under it before the drop (a review's case):
    the rest outnumbered the flights, the axis test took the rest's zero curvature for the flights', turned the
    distances into heights the wrong way and refused ("g upwards … name the column a distance", though it is
    one). Read as distances down from the sensor, e comes back."""
    hold_s = 5.0
    time = np.arange(0.0, hold_s + 2.5, 1 / 20)
    height = np.where(time < hold_s, DROP_M, bouncing_ball(time - hold_s, DROP_M, 0.8)) + CENTRE_M
    distance = SENSOR_HEIGHT_M - height + np.random.default_rng(5).normal(0.0, 3e-4, time.size)
    path = tmp_path / "detector.csv"
    path.write_text("Time (s),Distance (m)\n" + rows(",", time, distance, formats=(".3f", ".3f")))  # to the mm
    assert analyse_recording(path).params["e1"].value == pytest.approx(0.8, abs=E_TOL)


def test_a_sensor_height_below_the_distances_is_refused(tmp_path):
    """A sensor height smaller than the distances it measured would put the ball below the floor (negative
    heights were read without a word): refused in one line, naming the farthest distance."""
    time, height = truth()
    path = tmp_path / "low.csv"
    path.write_text(_capstone(time, SENSOR_HEIGHT_M - height))
    farthest = SENSOR_HEIGHT_M - np.min(height)
    with pytest.raises(InputError, match=rf"low.csv: the distances reach {farthest:.3g} m, more than the sensor "
                                         r"height 0.5 m given: the ball would be below the floor"):
        read_track(path, ImportOptions(sensor_height_m=0.5))


def test_a_clean_height_log_at_30_hz_points_up(tmp_path):
    """A height log at 30 Hz with 0.2 mm of noise (times to the ms, heights to 0.1 mm): its flights curve by 11 mm a step,
    which the axis test took for impacts, every one downwards, so the heights were turned over and refused
    (the audit's file: "the flights fall with -9.805 m/s²"; this one: "no bounce with at least 5 samples").
    Read as heights, e comes back."""
    e, release_s = 0.8, 0.17  # held still before the release, and ending in a flight
    time = np.arange(0.0, 3.0, 1 / 30)  # (written to the ms)
    height = np.where(time < release_s, DROP_M, bouncing_ball(time - release_s, DROP_M, e))
    height += np.random.default_rng(11).normal(0.0, 2e-4, time.size)
    path = tmp_path / "clean.csv"
    path.write_text("Time (s),Position (m)\n" + rows(",", time, height, formats=(".3f", ".4f")))
    result = analyse_recording(path)
    assert result.params["e1"].value == pytest.approx(e, abs=E_TOL)


def test_heights_measured_downwards_are_named_so(tmp_path):
    """Heights measured down from above under a plain name (y (m) holding 1.2 m − h) fall with −g: the refusal
    said "check the units"; it says the heights point down and what reads them, which does."""
    time, height = truth()
    path = tmp_path / "down.csv"
    path.write_text("t (s),y (m)\n" + rows(",", time, 1.2 - height, formats=(".3f", ".5f")))
    with pytest.raises(InputError, match=r"down.csv: the flights fall with -9.\d+ m/s², g upwards: the heights point "
                                         r"down \(a distance from above\); name the column a distance with --columns "
                                         r"distance=COL\[m\]"):
        analyse_recording(path)
    result = analyse_recording(path, columns="time=t (s),distance=y (m)")
    assert result.params["e1"].value == pytest.approx(E_TRUE, abs=E_TOL)


def test_a_line_of_notes_over_the_header_is_not_the_header(tmp_path):
    """A "key,value" line above the header (as wide as the table) was taken for the header ("cannot tell which
    column is the time among 'Experiment', 'Drop 3'"); a header whose names carry units is the header."""
    time, height = truth()
    path = tmp_path / "notes.csv"
    path.write_text("Experiment,Drop 3\n\nTime (s),Height (m)\n" + rows(",", time, height, formats=(".3f", ".5f")))
    track = read_track(path)
    np.testing.assert_allclose(track.y, height, atol=ROUNDING_M)


@pytest.mark.parametrize("header", ["time_s,height_m", "Time (s),Height (m)", "Zeit (s);Höhe (m)", "t\tx\ty"])
def test_a_header_without_samples_says_so(tmp_path, header):
    """A table that is its header alone was refused for its column names ("expected one column y_m …")."""
    path = tmp_path / "empty.csv"
    path.write_text(header + "\n")
    with pytest.raises(InputError, match=r"^\S*empty.csv: the header is there but there are no samples$"):
        read_track(path)


def test_several_runs_need_a_choice(tmp_path):
    time, height = truth()
    path = tmp_path / "runs.csv"
    path.write_text(_logger_pro_two_runs(time, SENSOR_HEIGHT_M - height))
    with pytest.raises(InputError, match=r"runs.csv: holds 2 runs \(Run 1, Run 2\); choose one with --track-id N"):
        read_track(path)
    with pytest.raises(InputError, match=r"runs.csv: no run 3 among Run 1, Run 2"):
        read_track(path, ImportOptions(track_id=3))


def test_phyphox_export_and_motion_detector_format(tmp_path):
    """A phyphox-style export ("Time (s)","Distance (m)", quoted, comma) of a sensor looking down."""
    time, height = truth(duration_s=2.5)
    path = tmp_path / "Raw Data.csv"
    path.write_text('"Time (s)","Distance (m)"\n' + rows(",", time, SENSOR_HEIGHT_M - height,
                                                        formats=(".4E", ".6E")))
    track = read_track(path, ImportOptions(format="phyphox", sensor_height_m=SENSOR_HEIGHT_M))
    np.testing.assert_allclose(track.y, height, atol=ROUNDING_M)


@pytest.mark.parametrize("separator, decimal_point", [(",", "."), ("\t", "."), (";", ",")])
def test_phyphox_zipped_export_reads_its_distance_set(tmp_path, separator, decimal_point):
    """phyphox's default export, a zip of one CSV per data set (written as its source, DataExport.java, writes
    it, in its three CSV variants): the set with a distance is found among the others and read."""
    time, height = truth(duration_s=2.5)
    amplitude_time = np.arange(0.0, 2.5, 0.05)
    sets = {"Raw data": {"Time (s)": amplitude_time, "Amplitude (a.u.)": np.sin(amplitude_time)},
            "Distance": {"Time (s)": time, "Distance (m)": SENSOR_HEIGHT_M - height}}
    path = write_phyphox_export(tmp_path / "Sonar 2024-05-02.zip", sets, separator, decimal_point)
    track = read_track(path, ImportOptions(sensor_height_m=SENSOR_HEIGHT_M))
    np.testing.assert_allclose(track.y, height, atol=1e-9)
    assert analyse_recording(path, sensor_height_m=SENSOR_HEIGHT_M).params["e1"].value == pytest.approx(E_TRUE,
                                                                                                        abs=E_TOL)


def test_phyphox_export_without_one_distance_set_is_refused(tmp_path):
    """A phyphox zip with no set holding a length, or with two, is refused in one line naming the sets."""
    time = np.arange(0.0, 1.0, 0.01)
    none = write_phyphox_export(tmp_path / "light.zip", {"Illuminance": {"Time (s)": time, "Illuminance (lx)": time}})
    with pytest.raises(InputError, match=r"light.zip: this phyphox export holds no set with a position or distance "
                                         r"in m, cm or mm \(sets: Illuminance\)"):
        read_track(none)
    both = {"A": {"Time (s)": time, "Distance (m)": time}, "B": {"Time (s)": time, "Depth (cm)": time}}
    with pytest.raises(InputError, match=r"two.zip: this phyphox export holds several sets with a length \(A, B\)"):
        read_track(write_phyphox_export(tmp_path / "two.zip", both))


# --- Tracker's exported data tables -----------------------------------------------------------------

def test_tracker_data_table_carries_x(tmp_path):
    """Tracker's export: a line naming the track, then t x y (tabs), s and m: x is carried into the trajectory."""
    time, height = truth()
    x = 0.1 + 0.3 * time  # m, a ball drifting sideways at 0.3 m/s
    path = tmp_path / "ball.txt"
    path.write_text("mass A\nt\tx\ty\n" + rows("\t", time, x, height, formats=(".3f", ".5f", ".5f")))
    trajectory = trajectory_from_log(path)
    assert trajectory.attrs["import_format"] == "tracker"
    np.testing.assert_allclose(trajectory["y"].values, height, atol=ROUNDING_M)
    np.testing.assert_allclose(trajectory["x"].values, x, atol=ROUNDING_M)


@pytest.mark.parametrize("name_line, header, first", [
    ("mass A\t\t\n", "t\tx\ty", None),  # the name line padded with tabs (saved from a spreadsheet)
    ("mass A\n", "step\tt\ty", "step"),  # Tracker's step (or frame) column chosen first
    ("mass A\n", "frame\tt\ty", "frame"),
])
def test_tracker_data_tables_as_saved(tmp_path, name_line, header, first):
    """Variants of Tracker's export seen in use: both were refused ("cannot tell which column is the time
    among 'mass A', '', ''", and "the height column 'y' names no unit"); read in m, as Tracker writes."""
    time, height = truth()
    if first:
        columns, formats = (np.arange(time.size), time, height), (".0f", ".3f", ".5f")
    else:
        columns, formats = (time, np.full(time.size, 0.1), height), (".3f", ".3f", ".5f")
    path = tmp_path / "ball.txt"
    path.write_text(name_line + header + "\n" + rows("\t", *columns, formats=formats))
    trajectory = trajectory_from_log(path)
    assert trajectory.attrs["import_format"] == "tracker"
    np.testing.assert_allclose(trajectory["y"].values, height, atol=ROUNDING_M)


def test_tracker_table_of_two_tracks_reads_the_one_chosen_or_the_ball(tmp_path):
    """Tracker exports several tracks side by side: a line naming each over its columns ('mass A<tab><tab><tab>mass
    B<tab><tab>'), then t x y under each. The ball (listed second here) is picked, or the track --track-id names
    (it was 'cannot tell which column is the time among 'mass A', '', ''…', --track-id ignored)."""
    time, height = truth()
    x = 0.1 + 0.3 * time
    short = time.size // 2  # the other mass was marked in the first half only: blank cells after
    cells = [f"{t:.3f}\t0.50000\t0.30000" if i < short else "\t\t" for i, t in enumerate(time)]
    body = "".join(f"{other}\t{t:.3f}\t{x_:.5f}\t{y:.5f}\n" for other, t, x_, y in zip(cells, time, x, height))
    path = tmp_path / "two masses.txt"
    path.write_text("hand\t\t\tball\t\t\nt\tx\ty\tt\tx\ty\n" + body)
    track = read_track(path)
    assert track.source_format == "tracker" and "track 'ball', the most ball-like of 2" in track.mapping
    np.testing.assert_allclose(track.y, height, atol=ROUNDING_M)
    np.testing.assert_allclose(track.x, x, atol=ROUNDING_M)
    assert analyse_recording(path).fit["restitution"]["e"]["value"] == pytest.approx(E_TRUE, abs=E_TOL)
    hand = read_track(path, ImportOptions(track_id=1))
    assert "track 'hand', given" in hand.mapping and hand.time_s.size == short and np.all(hand.y == 0.3)
    with pytest.raises(InputError, match=r"two masses.txt: there is no track 3; the tracks are 1, 2 \(--track-id N\)"):
        read_track(path, ImportOptions(track_id=3))


def test_a_tracker_table_with_a_track_of_no_position_reads_the_ball(tmp_path):
    """A protractor's t θ beside the ball's t x y (a review's file): the whole table was refused ("cannot tell
    which column is the height among 't', 'θ'"); the ball is read, and only --track-id 2 is refused."""
    time, height = truth()
    body = "".join(f"{t:.3f}\t0.01000\t{y:.5f}\t{t:.3f}\t30.000\n" for t, y in zip(time, height))
    path = tmp_path / "angle.txt"
    path.write_text("mass A\t\t\tprotractor A\t\nt\tx\ty\tt\tθ\n" + body, encoding="utf-8")
    np.testing.assert_allclose(read_track(path).y, height, atol=ROUNDING_M)
    with pytest.raises(InputError, match=r"angle.txt: cannot tell which column is the height among 't', 'θ'"):
        read_track(path, ImportOptions(track_id=2))


# --- ImageJ: MTrack2 and TrackMate -----------------------------------------------------------------

FPS = 50.0  # frames/s of the frame-indexed fixtures
PX_PER_M, FLOOR_ROW_PX = 300.0, 400.0  # px/m and image row of height 0 (rows grow down)
LOST_FRAMES = (40, 41)  # the ball is not found in these frames (blank cells)


def ball_in_image(frames):
    time = (frames - frames[0]) / FPS
    height = bouncing_ball(time, DROP_M, E_TRUE) + CENTRE_M
    return time, 100.0 + 20.0 * time, FLOOR_ROW_PX - PX_PER_M * height


def mtrack2_table(separator="\t", header_end=""):
    """Three objects: a still speck (track 1), the ball (track 2, lost in two frames), a short-lived one (3);
    ``header_end`` ends the header line (MTrack2 may end it with a separator)."""
    frames = np.arange(1, 101)
    _, column, row = ball_in_image(frames)
    header = ["Frame"] + [f"{c}{k}" for k in (1, 2, 3) for c in ("X", "Y", "Flag")]
    lines = ["Tracks 1 to 3", separator.join(header) + header_end]
    for i, frame in enumerate(frames):
        cells = [str(frame), "12.0", "30.5", "0"]
        cells += ["", "", ""] if i in LOST_FRAMES else [f"{column[i]:.3f}", f"{row[i]:.3f}", "0"]
        cells += ["200.0", f"{100 + 2 * i:.1f}", "1"] if i < 10 else []
        lines.append(separator.join(cells).rstrip(separator))
    lines += ["", separator.join(["Track ", "Length", "Distance traveled", "Nr of Frames"]), "1\t0\t0\t100",
              "2\t480\t300\t98", "3\t18\t18\t10"]
    return "\n".join(lines) + "\n", frames, column, row


@pytest.mark.parametrize("separator", ["\t", ",", " "])
def test_mtrack2_picks_the_ball_and_times_frames(separator, tmp_path):
    """MTrack2's table in any separator: the ballistic track is picked, lost frames leave gaps of their length."""
    text, frames, column, row = mtrack2_table(separator)
    path = tmp_path / "Results.txt"
    path.write_text(text)
    track = read_track(path, ImportOptions(fps=FPS))
    assert track.source_format == "mtrack2" and "track 2" in track.mapping and track.unit == "px"
    kept = np.setdiff1d(np.arange(frames.size), LOST_FRAMES)
    np.testing.assert_allclose(track.time_s, (frames[kept] - 1) / FPS, atol=1e-12)
    np.testing.assert_allclose(track.y, row[kept], atol=6e-4)
    np.testing.assert_allclose(track.x, column[kept], atol=6e-4)
    still = read_track(path, ImportOptions(fps=FPS, track_id=1))
    assert np.all(still.y == 30.5) and still.time_s.size == frames.size


@pytest.mark.parametrize("spaces", [" ", "   "])
def test_mtrack2_with_spaces_tracks_line_and_star_flags(spaces, tmp_path):
    """MTrack2's table saved with spaces between the fields, its 'Tracks 1 to 2' line, and a Flag written only
    where MTrack2 flags ('*'): runs of spaces hide the blank flags, so rows have 4 to 6 fields under a header of
    7 (it was 'no table of numbers under a header found', or 'not a number ... ('*')'). The positions and the
    times are the fixture's, the flags counted in a note, and e comes back."""
    frames = np.arange(1, 101)
    _, column, row = ball_in_image(frames)
    lines = ["Tracks 1 to 2", spaces.join(["Frame", "X1", "Y1", "Flag1", "X2", "Y2", "Flag2"])]
    flagged = frames % 7 == 0  # the ball's flags
    for i, frame in enumerate(frames):
        cells = [str(frame), "12.0", "30.5", "*" if i % 9 == 0 else " ", f"{column[i]:.3f}", f"{row[i]:.3f}",
                 "*" if flagged[i] else " "]
        lines.append(spaces.join(cells).rstrip())
    path = tmp_path / "Results.txt"
    path.write_text("\n".join(lines) + "\n")
    track = read_track(path, ImportOptions(fps=FPS))
    assert track.source_format == "mtrack2" and "track 2" in track.mapping
    np.testing.assert_allclose(track.time_s, (frames - 1) / FPS, atol=1e-12)
    np.testing.assert_allclose(track.y, row, atol=6e-4)
    np.testing.assert_allclose(track.x, column, atol=6e-4)
    assert f"{np.count_nonzero(flagged)} positions of track 2 flagged '*'" in "; ".join(track.notes)
    assert analyse_recording(path, fps=FPS).fit["restitution"]["e"]["value"] == pytest.approx(E_TRUE, abs=E_TOL)
    path.write_text("\n".join(lines[:5] + ["5 12.0 * 30.5 100.0"]) + "\n")
    with pytest.raises(InputError, match=r"Results.txt: MTrack2 row 4 \('5 12.0 \* 30.5 100.0'\) cannot be split into "
                                         r"X, Y and flag of each object"):
        read_track(path, ImportOptions(fps=FPS))


@pytest.mark.parametrize("numbered", [True, False])
def test_mtrack2_raw_tracks_with_spaces(numbered, tmp_path):
    """The Raw Tracks window saved with spaces ('X1 Y1 Flag1 …', its row numbers with no name over them, or
    none), '*' flags only where flagged: the row (number) is the frame, the positions the fixture's."""
    frames = np.arange(1, 101)
    _, column, row = ball_in_image(frames)
    lines = ["X1 Y1 Flag1 X2 Y2 Flag2"]
    for i, frame in enumerate(frames):
        cells = ([str(frame)] if numbered else []) + ["12.0", "30.5", " ", f"{column[i]:.3f}", f"{row[i]:.3f}",
                                                       "*" if frame % 7 == 0 else " "]
        lines.append(" ".join(cells).rstrip())
    path = tmp_path / "Raw Tracks.txt"
    path.write_text("\n".join(lines) + "\n")
    track = read_track(path, ImportOptions(fps=FPS))
    assert "Raw Tracks" in track.mapping and "track 2" in track.mapping
    np.testing.assert_allclose(track.time_s, (frames - 1) / FPS, atol=1e-12)
    np.testing.assert_allclose(track.y, row, atol=6e-4)


def test_mtrack2_header_ending_in_a_separator(tmp_path):
    """MTrack2 may end its header with a tab the rows do not have: the empty column past the data is no column
    (it was 'no table of numbers under a header found')."""
    text, frames, _, row = mtrack2_table(header_end="\t")
    path = tmp_path / "Results.txt"
    path.write_text(text)
    track = read_track(path, ImportOptions(fps=FPS))
    kept = np.setdiff1d(np.arange(frames.size), LOST_FRAMES)
    assert "track 2" in track.mapping
    np.testing.assert_allclose(track.y, row[kept], atol=6e-4)


@pytest.mark.parametrize("numbered", [True, False])
def test_mtrack2_raw_tracks_window_saved_as_csv(numbered, tmp_path):
    """ImageJ saves MTrack2's Raw Tracks window without a Frame column (' ,X1,Y1,Flag1,…' with its row numbers,
    or 'X1,Y1,Flag1,…'), one row per frame: the row is the frame, --fps gives the times, e comes back (it was
    'cannot tell which column is the time', and --format mtrack2 refused it)."""
    text, frames, column, row = mtrack2_table(",")
    lines = [line.split(",", 1)[1] if "," in line else "" for line in text.splitlines()[1:1 + 1 + frames.size]]
    lines = [(" ," if numbered else "") + lines[0]] + [(f"{i + 1}," if numbered else "") + line
                                                       for i, line in enumerate(lines[1:])]
    path = tmp_path / "Raw Tracks.csv"
    path.write_text("\n".join(lines) + "\n")
    for options in ({}, {"format": "mtrack2"}):
        track = read_track(path, ImportOptions(fps=FPS, **options))
        assert track.source_format == "mtrack2" and "Raw Tracks" in track.mapping and "track 2" in track.mapping
        kept = np.setdiff1d(np.arange(frames.size), LOST_FRAMES)
        np.testing.assert_allclose(track.time_s, (frames[kept] - 1) / FPS, atol=1e-12)
        np.testing.assert_allclose(track.y, row[kept], atol=6e-4)
    assert analyse_recording(path, fps=FPS).fit["restitution"]["e"]["value"] == pytest.approx(E_TRUE, abs=E_TOL)
    with pytest.raises(InputError, match=r"Raw Tracks.csv: the table counts frames but gives no times; give the "
                                         r"frame rate with --fps"):
        read_track(path)


def test_mtrack2_through_gravity_scale_gives_e_and_x(tmp_path):
    """px and frames only: the frame rate gives time, gravity the scale (as px height logs), x comes along."""
    text, frames, column, _ = mtrack2_table()
    path = tmp_path / "Results.txt"
    path.write_text(text)
    result = analyse_recording(path, fps=FPS)
    assert result.fit["restitution"]["e"]["value"] == pytest.approx(E_TRUE, abs=E_TOL)
    trajectory = result.trajectory
    assert trajectory.attrs["scale_m_per_px"] == pytest.approx(-1 / PX_PER_M, rel=2e-3)
    kept = np.setdiff1d(np.arange(frames.size), LOST_FRAMES)
    np.testing.assert_allclose(trajectory["x"].values, column[kept] / PX_PER_M, rtol=3e-3)


def test_mtrack2_needs_the_frame_rate_and_a_track(tmp_path):
    text, *_ = mtrack2_table()
    path = tmp_path / "Results.txt"
    path.write_text(text)
    with pytest.raises(InputError, match=r"Results.txt: the table counts frames but gives no times; give the frame "
                                         r"rate with --fps"):
        read_track(path)
    with pytest.raises(InputError, match=r"Results.txt: there is no track 7; the tracks are 1, 2, 3 \(--track-id N\)"):
        read_track(path, ImportOptions(fps=FPS, track_id=7))
    empty = tmp_path / "empty.txt"
    empty.write_text("Tracks 1 to 1\nFrame\tX1\tY1\tFlag1\n1\t\t\t\n2\t\t\t\n")
    with pytest.raises(InputError, match=r"empty.txt: the MTrack2 table has no track with positions"):
        read_track(empty, ImportOptions(fps=FPS))


def trackmate_table(time_unit="sec", length_unit="pixel"):
    """Spots of two tracks (the ball, id 3; a drifting speck, id 0) and an untracked spot, in no order, with
    TrackMate's three extra header rows (names, short names, units)."""
    frames = np.arange(0, 90)
    time, column, row = ball_in_image(frames)
    scale = {"pixel": 1.0, "mm": 1000.0 / PX_PER_M}[length_unit]
    lines = ["LABEL,ID,TRACK_ID,QUALITY,POSITION_X,POSITION_Y,POSITION_Z,POSITION_T,FRAME,RADIUS",
             "Label,Spot ID,Track ID,Quality,X,Y,Z,T,Frame,Radius",
             "Label,Spot ID,Track ID,Quality,X,Y,Z,T,Frame,R",
             f",,,(quality),({length_unit}),({length_unit}),({length_unit}),({time_unit}),,({length_unit})"]
    spots = [f"ID{i},{i},3,50.0,{column[i] * scale:.4f},{row[i] * scale:.4f},0.0,{time[i]:.4f},{f},6.0"
             for i, f in enumerate(frames)]
    spots += [f"ID{1000 + i},{1000 + i},0,9.0,{300 + 0.1 * i:.4f},{50.0 * scale:.4f},0.0,{time[i]:.4f},{f},3.0"
              for i, f in enumerate(frames[:60])]
    spots.append(f"ID9999,9999,None,5.0,10.0,10.0,0.0,{time[5]:.4f},5,3.0")
    order = np.random.default_rng(3).permutation(len(spots))
    return "\n".join(lines + [spots[i] for i in order]) + "\n", time, column * scale, row * scale


def test_trackmate_spots_sorted_into_the_ball_track(tmp_path):
    text, time, column, row = trackmate_table()
    path = tmp_path / "spots.csv"
    path.write_text(text)
    track = read_track(path)
    assert track.source_format == "trackmate" and "TRACK_ID 3" in track.mapping and track.unit == "px"
    np.testing.assert_allclose(track.time_s, time, atol=1e-4)
    np.testing.assert_allclose(track.y, row, atol=1e-4)
    np.testing.assert_allclose(track.x, column, atol=1e-4)


def test_trackmate_calibrated_in_mm_points_up_and_frames_need_fps(tmp_path):
    """A calibrated TrackMate image gives lengths with y still growing down: turned up; T in frames needs --fps."""
    text, time, _, row = trackmate_table(time_unit="frame", length_unit="mm")
    path = tmp_path / "spots_mm.csv"
    path.write_text(text)
    with pytest.raises(InputError, match="give the frame rate with --fps"):
        read_track(path)
    track = read_track(path, ImportOptions(fps=FPS))
    assert track.unit == "mm"
    np.testing.assert_allclose(track.time_s, time, atol=1e-9)
    np.testing.assert_allclose(track.y, -row, atol=1e-4)


def test_trackmate_without_tracks_or_columns_is_refused(tmp_path):
    path = tmp_path / "spots.csv"
    path.write_text("LABEL,ID,TRACK_ID,POSITION_X,POSITION_Y,FRAME\nID1,1,None,1.0,2.0,0\nID2,2,None,1.5,2.5,1\n")
    with pytest.raises(InputError, match=r"spots.csv: no spot of the TrackMate table belongs to a track"):
        read_track(path, ImportOptions(fps=FPS))
    path.write_text("LABEL,ID,TRACK_ID,POSITION_X,FRAME\nID1,1,0,1.0,0\nID2,2,0,1.5,1\n")
    with pytest.raises(InputError, match=r"spots.csv: .*POSITION_Y missing"):
        read_track(path, ImportOptions(format="trackmate", fps=FPS))


def test_sample_sheet_and_command_line_give_the_import_options(tmp_path, capsys):
    """The samples.tsv columns format, fps, track_id, columns and sensor_height_m reach the importer, as the
    command-line options do: an MTrack2 table measured from the command line with --fps and --track-id."""
    from dropfit.settings import settings_from_config

    row = {"format": "mtrack2", "fps": 50.0, "track_id": 2.0, "columns": "time=a[s],y=b[m]", "sensor_height_m": 1.5}
    _, settings = settings_from_config({}, row)
    assert settings.import_options() == ImportOptions("mtrack2", 50.0, 2, "time=a[s],y=b[m]", 1.5)
    schema = yaml.safe_load((Path(__file__).parents[1] / "workflow/schemas/samples.schema.yaml").read_text())
    assert schema["properties"]["format"]["enum"] == list(FORMATS)
    text, frames, _, row_px = mtrack2_table()
    path = tmp_path / "Results.txt"
    path.write_text(text)
    out = tmp_path / "trajectory.nc"
    assert main(["measure", str(path), "--out", str(out), "--format", "mtrack2", "--fps", "50", "--track-id", "2"]) == 0
    assert capsys.readouterr().err.startswith(f"read {shown_path(path)} as MTrack2 track 2 (given) [px, y down]")
    assert main(["measure", str(path), "--out", str(out), "--track-id", "2.5", "--fps", "50"]) == 1
    assert "--track-id is 2.5; give a whole number" in capsys.readouterr().err


def test_kinovea_style_export_carries_x(tmp_path):
    """A trajectory export as Kinovea can write it with a European locale (no layout documentation was at hand:
    this is the generic reader's path): time in ms, X and Y in cm, semicolons and decimal commas; x comes
    through into the trajectory."""
    time, height = truth()
    x = 0.05 + 0.2 * time  # m
    body = rows(";", time * 1000, x * 100, height * 100, formats=(".0f", ".3f", ".3f")).replace(".", ",")
    path = tmp_path / "trajectory.csv"
    path.write_text("Time (ms);X (cm);Y (cm)\n" + body, encoding="utf-8")
    trajectory = trajectory_from_log(path, import_options=ImportOptions(format="kinovea"))
    assert trajectory.attrs["import_format"] == "kinovea"
    np.testing.assert_allclose(trajectory["y"].values, height, atol=6e-5)
    np.testing.assert_allclose(trajectory["x"].values, x, atol=6e-5)


def _clock(seconds, frames_per_second=None):
    """``h:mm:ss.ss`` of a time in s, or ``h:mm:ss:ff`` counting frames at ``frames_per_second``."""
    whole = int(seconds)
    head = f"{whole // 3600}:{whole // 60 % 60:02d}:{whole % 60:02d}"
    if frames_per_second:
        return f"{head}:{round((seconds - whole) * frames_per_second):02d}"
    return f"{head}.{round((seconds - whole) * 100):02d}"


@pytest.mark.parametrize("fps, written", [(None, "0:00:01.28"), (50.0, "0:00:01:13")])
def test_clock_times_are_read(tmp_path, fps, written):
    """Kinovea writes time as a clock (h:mm:ss.ss) or a timecode counting frames (h:mm:ss:ff, which needs
    --fps); both were refused ("has a value that is not a number"). Read in s, e comes back."""
    time, height = truth(sample_rate_hz=50.0)
    clocks = [_clock(t, fps) for t in time]
    assert written in clocks
    path = tmp_path / "kinovea.csv"
    path.write_text('"Time";"Y (cm)"\n' + "".join(f'"{c}";"{h * 100:.3f}"\n'.replace(".", ",")
                                                   for c, h in zip(clocks, height)))
    if fps:
        with pytest.raises(InputError, match=r"kinovea.csv: the time column 'Time' is a timecode with frames "
                                             r"\(h:mm:ss:ff\); give the frame rate with --fps"):
            read_track(path)
    track = read_track(path, ImportOptions(fps=fps))
    np.testing.assert_allclose(track.time_s, time, atol=0.005)
    assert analyse_recording(path, fps=fps).params["e1"].value == pytest.approx(E_TRUE, abs=E_TOL)


@pytest.mark.parametrize("content, options, message", [
    ("Zeit (s);Höhe (m)\n0,00;1,0\n;0,99\n0,02;0,98\n", {}, r"a time is missing or not finite \(sample 2\); every "
                                                           r"sample needs a time"),
    ("Zeit (s);Höhe (m)\n0,00;\n0,01;\n0,02;\n", {}, r"the height column has no valid value"),
    ("Zeit (s);Höhe (m)\n0,00;1,0\n0,01;inf\n0,02;0,98\n", {}, r"a height is infinite \(sample 2\)"),
    ("Zeit (s);Höhe (m)\n0,00;1,0\n0,01;hoch\n0,02;0,98\n", {}, r"column 'Höhe \(m\)' has a value that is not a number "
                                                             r"in data row 2 \('hoch'\)"),
    ("frame;y (px)\n1;10\n2,5;11\n3;12\n", {"fps": 30.0}, r"a frame number is not a whole number"),
    ("Time (s),Distance (px)\n0,10\n0.1,11\n0.2,12\n", {}, r"a distance from a sensor in px cannot be a height"),
])
def test_values_that_cannot_be_read_say_why(content, options, message, tmp_path):
    """The checks every imported track gets: times, heights, frame numbers, a sensor's unit."""
    path = tmp_path / "values.csv"
    path.write_text(content, encoding="utf-8")
    with pytest.raises(InputError, match=r"^" + re.escape(shown_path(path)) + ": " + message):
        read_track(path, ImportOptions(**options))


@pytest.mark.parametrize("columns, said", [
    ("time=time_s[s],y=y_m[m]junk", "has text after its [unit] or an unclosed bracket"),
    ("time=time_s[s],y=y_m[m", "has text after its [unit] or an unclosed bracket"),
    ("time=time_s[s],y=height[m]", "names 'height' for the height, but the columns are 'time_s', 'y_m'"),
])
def test_a_column_mapping_that_cannot_apply_is_refused_not_ignored(tmp_path, columns, said):
    """Junk after a mapping's unit was taken into the column's name, and on a log in dropfit's own columns the
    mapping was not read at all: the log was analysed as if no --columns had been given."""
    time = np.arange(0.0, 2.0, 0.005)
    path = tmp_path / "log.csv"
    path.write_text("time_s,y_m\n" + "".join(f"{t:.3f},{h:.6f}\n" for t, h in zip(time, bouncing_ball(time, 0.5, 0.7))),
                    encoding="utf-8")
    with pytest.raises(InputError) as refusal:
        read_track(path, ImportOptions(columns=columns))
    assert said in str(refusal.value)
