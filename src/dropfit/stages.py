"""The workflow's stages: each reads files, calls the orchestrator (:mod:`dropfit.pipeline`) and
writes its outputs whole.

Every stage function takes paths, the ball (:class:`dropfit.settings.Ball`) and the settings
(:class:`dropfit.settings.Settings`), and raises :class:`dropfit.errors.InputError` for a problem with
the recording; :func:`dropfit.cli.main` turns that into one line (or into failure records, with
``--record-failure``). :func:`run` does measure, analyse, fit and report in one go and writes the
same files.
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import sys
import tempfile
import time
from pathlib import Path

import yaml

from .errors import InputError, OutputError, one_line, shown, shown_path
from .files import (RUN_TEMPORARY_PREFIX, SAMPLE_ID_ADVICE, atomic_output, environment_message, read_bytes, read_table,
                    sample_id_problem, write_json, write_table, write_text, writing)
from .fitrecord import analysis_summary, fit_summary
from .heightlog import read_trajectory
from .inputs import read_analysis, read_fit, read_flights, read_impacts, read_report_analysis
from .pipeline import analyse_trajectory, measure_recording, process_recording, track_recording
from .settings import Settings
from .synth import scenario_recordings, synthesize
from .videolog import is_video


def synth(scenarios_path, name, log_path, truth_path, seed=None):
    """Generate the height log and ground truth of scenario ``name`` from a scenarios YAML file."""
    try:
        scenarios = yaml.safe_load(Path(scenarios_path).read_text(encoding="utf-8"))["scenarios"]
        scenario, scenario_seed = scenario_recordings(scenarios)[name]
    except InputError as error:
        raise InputError(f"{scenarios_path}: {error}") from None
    except (OSError, KeyError, TypeError, yaml.YAMLError) as error:
        raise InputError(f"{scenarios_path}: no scenario {name!r} ({type(error).__name__}: {error})") from None
    log, truth = synthesize(scenario, scenario_seed if seed is None else seed)
    truth["scenario_name"] = name
    unit = log.columns[1]
    header = (f"# dropfit height log (synthetic scenario {name}, seed {truth['seed']})\n"
              f"# {unit}: height of the ball centre above the sensor zero; empty = dropout\n")
    with atomic_output(log_path) as tmp:
        tmp.write_text(header + log.to_csv(index=False, float_format="%.6f", na_rep=""), encoding="utf-8")
    write_json(truth_path, truth)


def synth_video(name, out_dir, seed=0):
    """Render the default synthetic video ``name`` with its per-frame and drop ground truth."""
    from .video_synth import default_clips, make_default_videos

    if name not in default_clips():
        raise InputError(f"no synthetic clip {name!r}; known: {', '.join(default_clips())}")
    make_default_videos(out_dir, seed=seed, names=[name])


def measure(log_path, out_path, ball=None, settings=None, sample_id=None, track_path=None):
    """Height log or video → trajectory NetCDF (:func:`dropfit.pipeline.measure_recording`).

    With ``track_path`` (a video only) the tracked table (every frame's ball in px and quality flag) is
    written there first, so that a clip refused after tracking still shows what was tracked.
    """
    tracked = None
    if track_path is not None:
        tracked = track_recording(log_path, settings, ball)
        write_table(track_path, tracked.table)
    trajectory = measure_recording(log_path, ball, settings, sample_id=sample_id, tracked=tracked)
    write_trajectory(out_path, trajectory)
    say_how_read(trajectory)


def say_how_read(trajectory):
    """Print how an imported table was read (its columns, units and repairs) to standard error, one line, so
    that the user sees what was guessed; nothing for videos, nor for dropfit's own height log unless
    something was repaired (a row exported twice, a video frame shown twice)."""
    attrs = trajectory.attrs
    if attrs.get("import_format", "dropfit") != "dropfit" or attrs.get("import_notes"):
        notes = f"; {attrs['import_notes']}" if attrs.get("import_notes") else ""
        print(one_line(attrs["import_mapping"] + notes), file=sys.stderr)


def overlay(video, sheet_path, clip_path=None, results_dir=None, ball=None, settings=None, sample_id=None,
            tiles=None):
    """What was tracked, drawn on the video: a contact sheet (PNG) and, with ``clip_path``, an annotated
    H.264 clip (:mod:`dropfit.video.overlay`).

    With ``results_dir`` the tracked table, trajectory and analysis are read from the files the workflow
    writes there (``track.csv``, ``trajectory.nc``, ``flights.csv``, ``impacts.csv``, ``analysis.json``);
    otherwise the video is tracked and analysed here with ``ball`` and ``settings``. A clip refused after
    tracking gets its sheet with the reason as a caption.
    """
    from .video.overlay import SHEET_TILES, contact_sheet, write_annotated_clip

    if tiles is not None and tiles < 1:
        raise InputError(f"{shown_path(video)}: --tiles must be at least 1, got {tiles}")
    if results_dir is not None:
        scene = scene_from_results(results_dir)
    else:
        tracked = track_recording(video, settings, ball)
        scene = refusal_aware_scene(
            tracked.table, lambda: measure_recording(video, ball, settings, sample_id=sample_id, tracked=tracked),
            lambda trajectory: _analysis_parts(analyse_trajectory(trajectory, settings), trajectory.attrs))
    image, _ = contact_sheet(video, scene, tiles or SHEET_TILES, title=shown_path(video))
    write_png(sheet_path, image)
    if clip_path is not None:
        with atomic_output(clip_path) as tmp:
            write_annotated_clip(video, tmp, scene)


def refusal_aware_scene(table, trajectory_of, analysis_of):
    """The overlay's scene (:func:`dropfit.video.overlay.overlay_scene`) of a tracked ``table``: the
    trajectory from ``trajectory_of()`` and (flights, impacts, analysis summary) from
    ``analysis_of(trajectory)``; an :class:`InputError` of either (a refusal) becomes the caption."""
    from .video.overlay import overlay_scene

    trajectory = None
    try:
        trajectory = trajectory_of()
        return overlay_scene(table, trajectory, *analysis_of(trajectory))
    except InputError as error:
        return overlay_scene(table, trajectory, reason=one_line(str(error)))


def _analysis_parts(analysis, trajectory_attrs):
    """(flights, impacts, summary as analysis.json holds it) of an analysis."""
    return analysis.flights, analysis.impacts, analysis_summary(analysis, trajectory_attrs)


def scene_from_results(directory):
    """The overlay's scene (:class:`dropfit.video.overlay.OverlayScene`) from a recording's results directory
    (``track.csv``, ``trajectory.nc``, ``flights.csv``, ``impacts.csv``, ``analysis.json``); a failure record
    there is the clip's refusal and becomes the caption."""
    directory = Path(directory)
    table = read_table(directory / "track.csv", "tracked table (track.csv) written by dropfit measure --track")
    return refusal_aware_scene(
        table, lambda: read_trajectory(directory / "trajectory.nc"),
        lambda _: (read_flights(directory / "flights.csv"), read_impacts(directory / "impacts.csv"),
                   read_report_analysis(directory / "analysis.json")))


def write_png(path, image):
    """Write a blue-green-red image (numpy array) as PNG to ``path`` atomically."""
    from .video.opencv import cv2

    ok, png = cv2.imencode(".png", image)
    if not ok:
        raise ValueError(f"an image of shape {image.shape} could not be encoded as PNG")
    with atomic_output(path) as tmp:
        tmp.write_bytes(png.tobytes())


def analyse(trajectory_path, impacts_path, flights_path, summary_path, settings=None):
    """Trajectory → impacts table, flights table and analysis summary with the covariances
    (:func:`dropfit.pipeline.analyse_trajectory`)."""
    trajectory = read_trajectory(trajectory_path)
    analysis = analyse_trajectory(trajectory, settings, source=str(trajectory_path))
    write_analysis(analysis, trajectory.attrs, impacts_path, flights_path, summary_path)


def fit(analysis_path, impacts_path, out_path, settings=None, ball_type=None):
    """Impacts → fit result JSON: e with uncertainty, theory checks, ITF verdict, provenance
    (:func:`dropfit.fitrecord.fit_summary`); ``ball_type`` overrides the trajectory's."""
    # JSON has no NaN: the analysis wrote missing numbers (no rest seen, BIC of a model not tried) as null
    summary = read_analysis(analysis_path)
    impacts = read_impacts(impacts_path, summary, analysis_path)
    write_json(out_path, fit_summary(summary, impacts, settings, ball_type))


#: The files ``dropfit run`` writes into its output directory: the outputs of measure, analyse, fit
#: and report, named as the workflow names them.
RUN_FILES = ("trajectory.nc", "impacts.csv", "flights.csv", "analysis.json", "fit.json", "report.html", "report.png")
#: What ``dropfit run`` writes for a video besides: the tracked table and the contact sheet.
VIDEO_RUN_FILES = ("track.csv", "contact_sheet.png")


def run_files(recording, settings=None):
    """The names of the files ``dropfit run`` writes for ``recording`` (a path; a video's sound track
    measured, ``kind`` audio, writes no tracked table)."""
    tracked = is_video(recording) and (settings is None or settings.kind != "audio")
    return RUN_FILES + (VIDEO_RUN_FILES if tracked else ())


def run(recording, out_dir, ball=None, settings=None, sample_id=None, tracked=None, tracking_refusal=None):
    """One recording → every file the workflow writes for it (:func:`run_files`) in ``out_dir``, whole or
    not at all: they are made in a temporary directory inside ``out_dir`` and moved in only when all
    are made. A video's ``tracked`` table (:func:`dropfit.pipeline.track_recording`), when given, is not
    tracked again.

    Returns
    -------
    dropfit.result.RecordingResult
        The result (:func:`dropfit.pipeline.process_recording`); ``fit.json`` is its ``to_dict()``.
    """
    video = isinstance(recording, (str, os.PathLike)) and is_video(recording) and (settings is None
                                                                                   or settings.kind != "audio")
    refusal = tracking_refusal
    if video and tracked is None and refusal is None:
        tracked, refusal = track_or_refusal(recording, settings, ball)
    try:
        result = process_recording(recording, ball, settings, sample_id=sample_id, tracked=tracked,
                                   tracking_refusal=refusal)
    except InputError as error:
        if video and tracked is not None:  # what was tracked shows why: its failure records keep it (record_refused_video)
            error.tracked = tracked
        raise
    say_how_read(result.trajectory)
    fusion = result.fusion
    picture_refused = fusion is not None and fusion.picture_refusal is not None
    out = Path(out_dir)
    with writing(out, folder=True):
        out.mkdir(parents=True, exist_ok=True)
        remove_leftover_runs(out)
        temporary = tempfile.TemporaryDirectory(prefix=run_temporary_prefix(), dir=out)
    with temporary as directory:
        made = {name: Path(directory) / name for name in (run_files(recording, settings) if video else RUN_FILES)}
        write_trajectory(made["trajectory.nc"], result.trajectory)
        write_analysis(result.analysis, result.trajectory.attrs, made["impacts.csv"], made["flights.csv"],
                       made["analysis.json"])
        write_json(made["fit.json"], result.fit)
        if video and picture_refused:  # the sound's e: the sheet shows what was tracked and why it is refused
            write_refused_picture(recording, made["track.csv"], made["contact_sheet.png"], tracked,
                                  fusion.picture_refusal)
        elif video:  # the contact sheet from the files, as the workflow's overlay job makes it
            write_table(made["track.csv"], tracked.table)
            overlay(recording, made["contact_sheet.png"], results_dir=directory)
        # the report from the files, as the workflow's report job makes it
        report(made["trajectory.nc"], made["flights.csv"], made["impacts.csv"], made["analysis.json"],
               made["fit.json"], made["report.html"], made["report.png"], made.get("contact_sheet.png"))
        for name, path in made.items():
            with writing(out / name):
                os.replace(path, out / name)
    return result


#: Seconds after which a temporary folder of ``dropfit run`` that names no process (made by a dropfit before the
#: names held one) is taken for what a killed run left.
LEFTOVER_AGE_S = 3600.0  # s


def run_temporary_prefix():
    """The start of the name of :func:`run`'s temporary folder: :data:`dropfit.files.RUN_TEMPORARY_PREFIX`, the
    process id and the host (``.dropfit-run.<pid>@<host>.``), so that a later run can tell one left by a killed
    process from one in use."""
    return f"{RUN_TEMPORARY_PREFIX}{os.getpid()}@{_host()}."


def _host():
    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname())[:64] or "host"


def _process_is_gone(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # another user's process, alive
        return False
    return False


def remove_leftover_runs(out):
    """Remove from ``out`` the temporary folders of :func:`run` whose process is gone (killed mid-way): those of
    this host whose process no longer runs, and those that name no process and are older than
    :data:`LEFTOVER_AGE_S`. A run in progress (here or, on a shared disk, on another host) keeps its folder."""
    named = re.compile(re.escape(RUN_TEMPORARY_PREFIX) + r"(\d+)@([A-Za-z0-9-]+)\.[A-Za-z0-9_]+")
    for entry in out.glob(f"{RUN_TEMPORARY_PREFIX}*"):
        if entry.is_symlink() or not entry.is_dir():
            continue
        match = named.fullmatch(entry.name)
        if match:
            leftover = match.group(2) == _host() and _process_is_gone(int(match.group(1)))
        else:
            try:
                leftover = time.time() - entry.stat().st_mtime > LEFTOVER_AGE_S
            except OSError:
                continue
        if leftover:
            shutil.rmtree(entry, ignore_errors=True)


def track_or_refusal(video, settings=None, ball=None):
    """(the tracked table, None), or (None, the refusal) for a video with a sound track whose ball is not
    found: its sound may still give the e (:func:`dropfit.pipeline.measure_sound_and_picture`)."""
    from .audio.fuse import has_sound_track

    try:
        return track_recording(video, settings, ball), None
    except InputError as error:
        if not has_sound_track(video):
            raise
        return None, error


def write_refused_picture(video, track_path, sheet_path, tracked, reason):
    """A video whose picture is refused while its sound gives the e: the tracked table (or the refusal as a
    failure record, where the tracking itself failed) and the contact sheet with the reason as its caption."""
    from .files import write_failure
    from .video.overlay import SHEET_TILES, contact_sheet, overlay_scene

    if tracked is None:
        write_failure(track_path, one_line(reason))
        write_failure(sheet_path, one_line(reason))
        return
    write_table(track_path, tracked.table)
    image, _ = contact_sheet(video, overlay_scene(tracked.table, None, reason=one_line(reason)), SHEET_TILES,
                             title=shown_path(video))
    write_png(sheet_path, image)


def sound_video(video, pairs_path, summary_path, ball=None, settings=None, sample_id=None):
    """A video with sound: the impacts heard and seen, paired (CSV), and the audio/video offset with e from
    both (JSON) (:func:`dropfit.audio.compare.compare_sound_and_video`)."""
    from .audio.compare import compare_sound_and_video

    pairs, summary = compare_sound_and_video(video, ball, settings, sample_id)
    write_table(pairs_path, pairs)
    write_json(summary_path, summary)
    return summary


def write_trajectory(path, trajectory):
    """Write a trajectory (xarray.Dataset) as NetCDF to ``path`` atomically."""
    with atomic_output(path) as tmp:
        trajectory.to_netcdf(tmp)


def write_analysis(analysis, trajectory_attrs, impacts_path, flights_path, summary_path):
    """Write an analysis' impacts and flights tables (CSV, numbers that read back exactly) and its summary
    with the covariances and the trajectory's attributes (JSON, :func:`dropfit.fitrecord.analysis_summary`)."""
    write_table(impacts_path, analysis.impacts)
    write_table(flights_path, analysis.flights)
    write_json(summary_path, analysis_summary(analysis, trajectory_attrs))


def report(trajectory_path, flights_path, impacts_path, analysis_path, fit_path, html_path, figure_path,
           contact_sheet_path=None):
    """Per-recording HTML report and PNG figure; a video's contact sheet (PNG, :func:`overlay`) is shown in it."""
    from .report import write_recording_report

    write_recording_report(read_trajectory(trajectory_path), read_flights(flights_path), read_impacts(impacts_path),
                           read_report_analysis(analysis_path), read_fit(fit_path), html_path, figure_path,
                           read_bytes(contact_sheet_path, "contact sheet (PNG)") if contact_sheet_path else None)


def _read_fits(fit_paths):
    """Fit results of the recordings, a failed one as ``{"status": "failed", "error": ..., "sample_id": ...}``
    (the sample id is the name of the fit file's directory)."""
    rows = []
    for path in fit_paths:
        try:
            data = read_fit(path)
        except InputError as error:  # a failure record, or a file that is not a fit result
            data = {"status": "failed", "error": one_line(str(error)), "sample_id": Path(path).parent.name}
        data.setdefault("sample_id", Path(path).parent.name)
        rows.append(data)
    return rows


def summary(fit_paths, csv_path, html_path, samples_path=None, figure_path=None):
    """Batch summary over recordings: one row per fit result, failed recordings with their message, each
    linked to the report beside its fit result.

    With ``samples_path`` (the sample sheet, tab-separated, a ``sample_id`` column) its free columns
    (:func:`dropfit.report.sample_sheet_extras`) are carried into the table, and e is charted against each
    numeric one (shown on the page; written as PNG to ``figure_path`` if given).
    """
    from .report import batch_report_html, batch_rows, extras_png, report_href, sample_sheet_extras

    fits = _read_fits(fit_paths)
    table = batch_rows(fits, sample_sheet_extras(read_sample_sheet(samples_path)) if samples_path else None)
    png = extras_png(table) if samples_path or figure_path else None
    with atomic_output(csv_path) as tmp:
        table.to_csv(tmp, index=False, float_format="%.6g")
    if figure_path is not None:
        with atomic_output(figure_path) as tmp:
            tmp.write_bytes(png)
    write_text(html_path, batch_report_html(table, fits, [report_href(path, html_path) for path in fit_paths], png))


def qc(fit_paths, batch, html_path, figure_path, csv_path, ball_ids=None, settings=None):
    """Batch QC report: per-ball table (CSV), control chart (PNG) and HTML page over one batch's recordings.

    ``ball_ids`` names the ball of each fit result (default: every recording is a ball of its own);
    the ITF window (m) is that of ``settings``.
    """
    settings = settings or Settings()
    itf_drop_height_m, itf_rebound_min_m, itf_rebound_max_m = (
        settings.itf_drop_height_m, settings.itf_rebound_min_m, settings.itf_rebound_max_m)
    from .batch import ball_rows, batch_statistics, failed_recordings
    from .report import batch_rows, qc_chart_png, qc_report_html, report_href

    ball_ids = list(ball_ids) if ball_ids else [Path(path).parent.name for path in fit_paths]
    if len(ball_ids) != len(fit_paths):
        raise InputError(f"batch {batch}: {len(ball_ids)} ball ids for {len(fit_paths)} fit results; "
                         f"give one ball id per fit result")
    fits = _read_fits(fit_paths)
    recordings = batch_rows(fits)
    recordings.insert(1, "ball_id", ball_ids)
    window = {"drop_height_m": itf_drop_height_m, "rebound_min_m": itf_rebound_min_m,
              "rebound_max_m": itf_rebound_max_m}
    balls = ball_rows(recordings, itf_rebound_min_m, itf_rebound_max_m)
    statistics = batch_statistics(balls)
    png = qc_chart_png(batch, recordings, balls, statistics, window)
    with atomic_output(csv_path) as tmp:
        balls.to_csv(tmp, index=False, float_format="%.6g")
    with atomic_output(figure_path) as tmp:
        tmp.write_bytes(png)
    write_text(html_path, qc_report_html(batch, recordings, balls, statistics, failed_recordings(recordings),
                                         window, png, fits, [report_href(path, html_path) for path in fit_paths]))


# --- a batch of sample-sheet recordings in one process (the workflow's jobs) ---------------------

#: The dtype of the sample sheet's text columns (the rest are read as numbers where they are numbers).
SHEET_TEXT_COLUMNS = ("sample_id", "kind", "path", "ball_type", "batch", "ball_id", "format", "columns",
                      "scale_points_px", "board_inner_corners", "ball_colour", "roi_px", "ball_at_px")


def sample_sheet_lines(path):
    """(line number from 1, line) of a sample sheet's header and rows: blank lines and lines starting with
    ``#`` (comments) left out.

    Raises
    ------
    InputError
        For a file that cannot be read as text.
    """
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"{shown_path(path)}: cannot read the sample sheet ({type(error).__name__}: "
                         f"{shown(error)}); give a tab-separated text file") from None
    return [(number, line) for number, line in enumerate(text.splitlines(), 1)
            if line.strip() and not line.lstrip().startswith("#")]


def read_sample_sheet(path):
    """The sample sheet (tab-separated; :func:`sample_sheet_lines`) as a DataFrame indexed by ``sample_id``,
    the optional ``ball_id`` and ``batch`` filled in: a recording without a ball is a ball of its own, one
    without a batch belongs to the batch ``unbatched``. A ``#`` within a line is text (a colour
    ``#rrggbb``), not a comment.

    Raises
    ------
    InputError
        For a sheet that cannot be read or has no ``sample_id`` column.
    """
    import io

    import pandas as pd

    lines = sample_sheet_lines(path)
    try:
        sheet = pd.read_csv(io.StringIO("\n".join(line for _, line in lines)), sep="\t", keep_default_na=False,
                            na_values=[""], dtype={name: str for name in SHEET_TEXT_COLUMNS})
    except ValueError as error:
        raise InputError(f"{shown_path(path)}: cannot be read as a tab-separated sample sheet "
                         f"({type(error).__name__}: {shown(error)}); give one value per column, separated by "
                         f"tabs") from None
    if "sample_id" not in sheet.columns:
        columns = ", ".join(map(shown, sheet.columns[:8]))
        raise InputError(f"{shown_path(path)}: no sample_id column (columns: {columns}); separate the columns with "
                         f"tabs and name the first sample_id")
    duplicated = sheet["sample_id"][sheet["sample_id"].duplicated()]
    if len(duplicated):
        raise InputError(f"{shown_path(path)}: sample_id {shown(duplicated.iloc[0])} appears more than once; "
                         f"give every recording its own id")
    sheet = sheet.set_index("sample_id", drop=False)
    for column, default in (("ball_id", sheet["sample_id"]), ("batch", "unbatched")):
        sheet[column] = (sheet[column] if column in sheet.columns else pd.Series(index=sheet.index, dtype=str)
                         ).fillna(default)
    if len(lines) - 1 == len(sheet):  # the line of the file each row is on, for messages (a quoted cell may span two)
        sheet.attrs["line_numbers"] = [number for number, _ in lines[1:]]
    return sheet


def recording_files(kind):
    """The names of the files the workflow writes into ``results/<sample_id>/`` for a recording of
    sample-sheet ``kind`` (``height_log``, ``video`` or ``audio``): those of ``dropfit run``, and for a
    video (tracked, not heard) its tracked table and contact sheet too."""
    return RUN_FILES + (VIDEO_RUN_FILES if kind == "video" else ())


def run_batch(sheet_path, results_dir, config=None, sample_ids=None, say=print):
    """Every recording of a sample sheet (or those of ``sample_ids``) → the files of
    :func:`recording_files` in ``results_dir/<sample_id>/``, each recording as ``dropfit run`` does it.

    A recording that fails gets failure records in all its files (as ``--record-failure`` writes them;
    a video refused after tracking keeps its tracked table and gets its contact sheet) and the batch
    goes on. ``say`` receives one line per recording: ``<sample_id>: <headline>`` or
    ``<sample_id>: failed: <reason>``.

    Parameters
    ----------
    sheet_path : str or pathlib.Path
        The sample sheet (:func:`read_sample_sheet`); its paths are relative to the working directory.
    results_dir : str or pathlib.Path
        Where the recordings' directories go.
    config : dict, optional
        The workflow's config (site, ``analysis``, ``itf``; :func:`dropfit.settings.workflow_values`).
    sample_ids : list of str, optional
        The recordings to do, in this order; default every row of the sheet.

    Returns
    -------
    dict
        sample_id → the reason it failed (one line), for the recordings that failed.

    Raises
    ------
    InputError
        For a sheet that cannot be read or a sample id that is not in it (before any recording is done).
    """
    sheet = read_sample_sheet(sheet_path)
    sample_ids = list(sheet.index) if sample_ids is None else list(sample_ids)
    unknown = [sample for sample in sample_ids if sample not in sheet.index]
    if unknown:
        raise InputError(f"{shown_path(sheet_path)}: no row with sample_id {', '.join(map(shown, unknown[:5]))}; "
                         f"give sample ids of the sheet")
    failed = {}
    for sample_id in sample_ids:
        problem = sample_id_problem(sample_id, str(results_dir))
        if problem is not None:  # its files would lie outside results_dir (or in a folder of its own): none is written
            failed[sample_id] = _bad_sample_id(sheet, sheet_path, sample_id, problem)
            say(f"{shown(sample_id)}: failed: {failed[sample_id]}")
            continue
        row = sheet.loc[sample_id]
        out = Path(results_dir) / sample_id
        message, tracked, recordable = _run_row(row, out, config or {}, say)
        if message is None:
            continue
        try:  # (not where its files could not be written: the records would meet the same disk)
            if recordable:
                _record_failure(row, out, message, tracked)
        except InputError as error:  # its folder cannot be written (the disk, a file in the way): the batch goes on
            message = one_line(f"{message} (and its failure records were not written: {one_line(str(error))})")
        failed[sample_id] = message
        say(f"{sample_id}: failed: {message}")
    return failed


def _bad_sample_id(sheet, sheet_path, sample_id, problem):
    """The one line refusing the row of ``sample_id``, whose id cannot name a folder of the results (``problem``,
    :func:`dropfit.files.sample_id_problem`)."""
    numbers = sheet.attrs.get("line_numbers")
    position = [index for index, value in enumerate(sheet.index) if value is sample_id or value == sample_id]
    where = f"line {numbers[position[0]]}" if numbers and position else "a row"
    return one_line(f"{shown_path(sheet_path)}: {where}: sample_id '{shown(sample_id)}' {problem}; {SAMPLE_ID_ADVICE} "
                    f"(it names the folder of the recording's files)")


def _run_row(row, out, config, say):
    """Run one sample-sheet row into ``out``: (None, None, False) when done, else (reason, the video's tracked
    table if it was tracked before the failure, whether failure records may be written: not where an output
    could not be written)."""
    import traceback

    from .settings import OptionError, settings_from_config

    path, tracked = row["path"], None
    try:
        try:
            ball, settings = settings_from_config(config, row)
        except OptionError as error:
            raise InputError(f"{shown_path(path)}: {error.named(lambda name: name)} (sample sheet column or "
                             f"config key)") from None
        refusal = None
        if row["kind"] == "video":
            tracked, refusal = track_or_refusal(path, settings, ball)
        if refusal is not None:  # the sound may still measure it: run() tracks no more
            say(run(path, out, ball, settings, row["sample_id"], tracking_refusal=refusal).summary())
        else:
            say(run(path, out, ball, settings, row["sample_id"], tracked).summary())
        return None, None, False
    except InputError as error:
        return one_line(str(error)), tracked, not isinstance(error, OutputError)
    except Exception as error:  # noqa: BLE001 — a bug: the traceback to the log, the batch goes on
        environment = environment_message(error, out)
        if environment is not None:  # the user's disk or folders, not a bug
            return one_line(environment), tracked, False
        traceback.print_exc()
        return one_line(f"{shown_path(path)}: internal error in dropfit ({type(error).__name__}: {shown(error)}); "
                        f"please report it with this file"), tracked, True


def _record_failure(row, out, message, tracked):
    """Failure records in every file of a failed recording; a video tracked before it was refused keeps
    its tracked table, and its contact sheet shows what was tracked with the reason."""
    from .files import write_failure

    names = recording_files(row["kind"])
    for name in names:
        if name not in VIDEO_RUN_FILES + ("report.html",):
            write_failure(out / name, message)
    figure = None
    if "track.csv" in names:
        if tracked is not None:
            figure = record_refused_video(row["path"], out, tracked, message)
        else:
            write_failure(out / "track.csv", message)
            write_failure(out / "contact_sheet.png", message)
    write_failure(out / "report.html", message, figure)


def record_refused_video(video, out, tracked, message):
    """What a video refused after tracking leaves in its results directory ``out``, beside the failure records
    of the other files (written first: their message is the contact sheet's caption): its tracked table
    (``track.csv``) and a contact sheet of its frames, the ball drawn with each frame's quality, under the
    refusal (:func:`overlay`). Returns the sheet (PNG bytes) for the report's failure page, or None when it could
    not be drawn (then ``contact_sheet.png`` is the failure record of ``message``, the refusal)."""
    from .files import write_failure

    out = Path(out)
    write_table(out / "track.csv", tracked.table)
    try:
        overlay(video, out / "contact_sheet.png", results_dir=out)
        return (out / "contact_sheet.png").read_bytes()
    except Exception as error:  # noqa: BLE001 — the refusal, not a failure to draw it, is the recording's message
        if not isinstance(error, InputError):  # a bug: its traceback to the log
            import traceback

            traceback.print_exc()
        write_failure(out / "contact_sheet.png", message)
        return None
