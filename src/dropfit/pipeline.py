"""One recording from its file to its result: the one orchestrator of dropfit.

The command line's stages (``dropfit measure``, ``analyse``, ``fit`` and ``run``), the workflow (which
runs those stages), the coverage trials and a notebook all go through these functions, with the
defaults of :class:`dropfit.settings.Settings`, so they give the same numbers:

1. :func:`measure_recording`: height log or video → trajectory (heights in m, up);
2. :func:`analyse_trajectory`: trajectory → :class:`dropfit.analysis.BounceAnalysis`, with the
   options :func:`analysis_options` makes from the trajectory's attributes and the settings (the one
   place that does);
3. :func:`fit_analysis`: analysis → fit result (the content of ``fit.json``);
4. :func:`analyse_recording`: all three, → :class:`dropfit.result.RecordingResult`.

Nothing here reads or writes files other than the recording itself (:mod:`dropfit.stages` does).
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from . import __version__
from .video import limits as video_limits
from .analysis import analyse_bounces
from .analysis.horizontal import add_horizontal
from .audio.recording import analyse_sound, is_sound_dataset, is_sound_recording, sound_trajectory
from .audio.tables import is_table_file
from .balls import ball_kind
from .errors import InputError, NotFreeFallError, shown_path
from .files import sha256_of
from .fitrecord import analysis_summary, fit_summary, plain
from .heightlog import acceleration_reading, nominal_drag_of, regulation_note, trajectory_from_log
from .result import RecordingResult
from .settings import Ball, Settings, split_options
from .video.quality import SPEED_DEPENDENT_CENTRE_ERROR_PX, TRACKED_CENTRE_CORRELATION
from .videolog import VIDEO_SUFFIXES, is_video, scale_targets_of, trajectory_from_video

#: Settings that apply to measuring a recording, not to an already measured trajectory.
MEASURE_ONLY_SETTINGS = ("scale_m_per_px", "ruler_tick_m", "scale_points_px", "scale_distance_m", "marker_size_m",
                         "board_square_m", "board_inner_corners", "capture_fps", "ball_radius_px", "roi_px",
                         "ball_at_px", "format", "fps", "track_id", "columns", "sensor_height_m", "kind",
                         "release_time_s")


def track_recording(path, settings=None, ball=None):
    """A video → its tracked table (every frame's ball in px and quality flag), as :func:`measure_recording`
    tracks it.

    Parameters
    ----------
    path : str or pathlib.Path
        The video.
    settings : dropfit.settings.Settings, optional
        The capture rate (frames/s) of a slow-motion file, and what the user says of the ball in the
        image: its radius (px), a region of interest, its centre in one frame.
    ball : dropfit.settings.Ball, optional
        The ball; its colour, when given, is a hint to the tracker.

    Returns
    -------
    dropfit.video.track.TrackedVideo
        The tracked table (as :func:`dropfit.video.track.track_video`) and the background it was
        tracked against.

    Raises
    ------
    dropfit.errors.InputError
        For a file that is not a readable video, or one in which no ball is found.
    """
    from .video.track import TrackerHints, track_video_and_background

    if not is_video(path):
        raise InputError(f"{shown_path(path)}: is not a video ({', '.join(VIDEO_SUFFIXES)}); only a video is tracked")
    settings = settings or Settings()
    hints = TrackerHints(settings.roi_px, settings.ball_at_px, (ball or Ball()).colour)
    return track_video_and_background(path, capture_fps=settings.capture_fps,
                                      expected_radius_px=settings.ball_radius_px, hints=hints)


def recording_kind(path, settings=None):
    """What a recording is, ``height_log``, ``video`` or ``audio``: the settings' ``kind`` when given (a
    video given as ``audio`` is measured by its sound track), else told by the file's suffix and header.

    Raises
    ------
    dropfit.errors.InputError
        For a kind the file cannot be (a height log that is a video or a sound file, a video that is not).
    """
    told = "video" if is_video(path) else "audio" if is_sound_recording(path) else "height_log"
    kind = (settings or Settings()).kind or told
    # a table given as sound holds impact times whose column's name need not say so
    if kind != told and not (kind == "audio" and (told == "video" or is_table_file(path))):
        raise InputError(f"{shown_path(path)}: is given as kind {kind} but reads as {told.replace('_', ' ')} (by its "
                         f"suffix and header); give the kind of the file, or the file of that kind")
    return kind


def measure_recording(path, ball=None, settings=None, *, sample_id=None, tracked=None):
    """Height log or video → trajectory (heights in m, up; dropouts flagged), without writing a file; a
    sound file or a table of impact times → the impact times (:func:`dropfit.audio.recording.sound_trajectory`).

    Parameters
    ----------
    path : str or pathlib.Path
        A height log (CSV), a video (:data:`dropfit.videolog.VIDEO_SUFFIXES`), a sound file
        (:data:`dropfit.audio.decode.AUDIO_SUFFIXES`) or a table of impact times
        (:func:`dropfit.audio.tables.is_impact_table`).
    ball : dropfit.settings.Ball, optional
        The ball (radius in m, mass in kg, kind); default: nothing known.
    settings : dropfit.settings.Settings, optional
        The scale (m/px), ruler tick (m), floor (m), capture rate (frames/s) and the site's g.
    sample_id : str, optional
        Name of the recording, kept in the attributes.
    tracked : pandas.DataFrame, optional
        A video's table from :func:`track_recording`, when it is tracked already.

    Returns
    -------
    xarray.Dataset
        As :func:`dropfit.heightlog.make_trajectory` (and, for a video, as
        :func:`dropfit.videolog.trajectory_from_video`); the attributes hold the ball, the floor,
        the g used to calibrate (``gravity_m_s2``, ``gravity_se_m_s2``, ``gravity_source``), the
        dropfit version and the file's SHA-256.

    Raises
    ------
    dropfit.errors.InputError
        For a recording that cannot be measured (one line naming the file).
    """
    ball = ball or Ball()
    settings = settings or Settings()
    gravity = settings.site_gravity()
    attrs = _recording_attrs(ball, settings, sample_id)
    scale = settings.scale_m_per_px
    kind = recording_kind(path, settings)
    if settings.release_time_s is not None and kind != "audio":
        raise InputError(f"{shown_path(path)}: release_time_s applies to a sound recording; a log or a video shows "
                         f"the release itself: leave it out")
    if kind == "video":
        tracked = tracked if tracked is not None else track_recording(path, settings, ball)
        trajectory = trajectory_from_video(path, ball.radius_m, scale and abs(scale), settings.capture_fps,
                                           gravity.value_m_s2, attrs, settings.ruler_tick_m,
                                           scale_targets_of(settings), tracked)
    elif kind == "audio":
        trajectory = sound_trajectory(path, attrs, settings.release_time_s, columns=settings.columns)
    else:
        trajectory = trajectory_from_log(path, scale_m_per_px=scale, gravity_m_s2=gravity.value_m_s2, attrs=attrs,
                                         height_reference=settings.height_reference,
                                         import_options=settings.import_options())
    trajectory.attrs["source_sha256"] = sha256_of(path)  # after the read: it has checked the file exists
    return trajectory


def _recording_attrs(ball, settings, sample_id):
    """The attributes every measured recording starts with: the ball, the floor, the g used, the version."""
    gravity = settings.site_gravity()
    return {"sample_id": sample_id, "ball_radius_m": ball.radius_m, "ball_mass_kg": ball.mass_kg,
            "ball_type": ball.type, "floor_m": settings.floor_m, "dropfit_version": __version__,
            "gravity_m_s2": gravity.value_m_s2, "gravity_se_m_s2": gravity.se_m_s2, "gravity_source": gravity.source}


def gravity_scaled(attrs):
    """True when the trajectory's length scale came from gravity (a px log calibrated by the flights'
    curvature, or a video whose chosen scale is ``gravity``): its heights scale with the g assumed."""
    return attrs.get("scale_source") == "gravity" or str(attrs.get("calibration", "")).startswith("scale from gravity")


def analysis_options(attrs, settings=None, sample_interval_s=0.0):
    """The keyword arguments of :func:`dropfit.analysis.analyse_bounces` for a trajectory: the one place
    that turns a trajectory's attributes and the settings into them.

    Parameters
    ----------
    attrs : mapping
        The trajectory's attributes (ball radius in m and mass in kg, floor in m and its standard
        error, the scale's relative standard error, ``video``, ``source`` …).
    settings : dropfit.settings.Settings, optional
        Drag mode and the site's g.
    sample_interval_s : float
        The median time between samples in s (a video's frame interval).

    Returns
    -------
    dict
        ``gravity_m_s2`` and ``gravity_se_m_s2`` (the site's g, m/s²), ``gravity_scaled`` (a px scale
        from gravity), ``drag``, ``contact_height_m`` (floor + radius, m, when both are known; else
        None: modelled from the flights), ``contact_height_se_m`` (a floor found in a video, m) and
        ``contact_height_found`` (whether it was found, not given),
        ``source``, ``scale_rel_se`` (1), ``contact_guard_s`` (half a frame interval for a video or a table
        tracked on one, whose frames are exposed around their time; else 0), ``nominal_drag_k_per_m`` and
        ``nominal_drag_relative_se`` (a smooth ball of the kind's C_d, size and mass, 1/m; a tennis or
        table-tennis ball's size or mass not given: as its rules allow; else 0 when either is unknown),
        ``noise_correlation``
        (:data:`dropfit.video.quality.TRACKED_CENTRE_CORRELATION` for a video or Photron clip dropfit tracked,
        else 0), ``speed_dependent_error_m`` (the same: the tracker's ``speed_error_px``,
        :func:`dropfit.video.quality.speed_dependent_centre_error_px`, or where it is not recorded
        :data:`dropfit.video.quality.SPEED_DEPENDENT_CENTRE_ERROR_PX`, at its scale in m/px; else 0), and the ball
        kind's contact-time prior, exponent and longest contact time (:mod:`dropfit.balls`) with the radius.
    """
    settings = settings or Settings()
    gravity = settings.site_gravity()
    radius = attrs.get("ball_radius_m")
    floor = attrs.get("floor_m")
    # frames are exposed around their time whoever tracked them; dropfit's own tracker (a video, a Photron clip)
    # also has the centre errors measured for it
    filmed = "video" in attrs or "import_frame_rate_hz" in attrs
    video = "video" in attrs or attrs.get("import_format") == "mraw"
    try:
        kind = ball_kind(attrs.get("ball_type"))
    except InputError as error:  # a trajectory measured before ball types were checked
        raise InputError(f"{shown_path(attrs.get('source', 'trajectory'))}: {error}") from None
    drag = nominal_drag_of(attrs)
    return {
        "gravity_m_s2": gravity.value_m_s2,
        "drag": settings.drag,
        # with the floor and the radius known, the ball touches down where its centre is one radius up
        "contact_height_m": floor + radius if floor is not None and radius is not None else None,
        "contact_height_se_m": float(attrs.get("floor_se_m", 0.0)),
        # only a floor found in a video's image has an se (a given one replaces it)
        "contact_height_found": "floor_se_m" in attrs,
        "source": str(attrs.get("source", "trajectory")),
        "scale_rel_se": float(attrs.get("scale_rel_se", 0.0)),
        # a video frame is exposed for up to one frame interval around its time: keep the flights half an
        # interval clear of the contacts, where a frame may show the ball flattened
        "contact_guard_s": 0.5 * sample_interval_s if filmed else 0.0,
        "nominal_drag_k_per_m": drag[0],
        "nominal_drag_relative_se": drag[1],
        "noise_correlation": TRACKED_CENTRE_CORRELATION if video else 0.0,
        # (a trajectory tracked before the error was measured per clip: the largest, that of a predicted codec)
        "speed_dependent_error_m": float(attrs.get("speed_error_px", SPEED_DEPENDENT_CENTRE_ERROR_PX))
        * abs(attrs.get("scale_m_per_px") or 0.0) if video else 0.0,
        "gravity_se_m_s2": gravity.se_m_s2,
        "gravity_scaled": gravity_scaled(attrs),
        "contact_time_prior_s": (kind.contact_time_s, kind.contact_time_se_s),
        "contact_time_exponent": (kind.contact_time_exponent, kind.contact_time_exponent_se),
        "max_contact_time_s": kind.max_contact_time_s,
        "ball_radius_m": radius,
    }


def analyse_trajectory(trajectory, settings=None, source=None):
    """Trajectory → flights, impacts and their uncertainties, as every part of dropfit analyses it.

    Parameters
    ----------
    trajectory : xarray.Dataset
        As :func:`measure_recording` makes it (``time`` in s, ``y`` in m, attributes).
    settings : dropfit.settings.Settings, optional
        Drag mode and the site's g.
    source : str, optional
        Name for messages when the attributes name no ``source``.

    Returns
    -------
    dropfit.analysis.BounceAnalysis
        The analysis of :func:`dropfit.analysis.analyse_bounces` with :func:`analysis_options`; a
        video's impacts whose flights are too briefly filmed are dropped
        (:func:`dropfit.video.limits.select_resolved_impacts`). Its summary also holds the options
        (``analysis_options``, JSON-ready, without ``source``) and the g used (``gravity``: value, se,
        unit, source, note).
    """
    settings = settings or Settings()
    attrs = dict(trajectory.attrs)
    if source is not None:
        attrs.setdefault("source", str(source))
    if is_sound_dataset(trajectory):
        analysis = analyse_sound(trajectory.assign_attrs(attrs), settings.site_gravity(), settings.drag,
                                 nominal_drag_of(attrs))
        record = {"drag": settings.drag, "nominal_drag_k_per_m": analysis.summary["drag_k_per_m"]}
        summary = dict(analysis.summary, analysis_options=record, gravity=settings.site_gravity().record(),
                       ball_size_note=_ball_size_note(analysis.summary, attrs))
        return dataclasses.replace(analysis, summary=summary)
    time = trajectory["time"].values
    interval = float(np.median(np.diff(time))) if time.size > 1 else 0.0
    options = analysis_options(attrs, settings, interval)
    try:
        # a video's heights wherever the ball was seen (dropfit.videolog.trajectory_from_video)
        seen = trajectory["y_seen"].values if "y_seen" in trajectory and trajectory["y_seen"].dims == ("time",) \
            else None
        analysis = analyse_bounces(time, trajectory["y"].values, seen_height_m=seen, **options)
    except NotFreeFallError as error:
        if "video" not in attrs:  # wrong units or a time base off: say which the numbers point to
            heights = trajectory["y"].values
            reading = acceleration_reading(error.acceleration_m_s2 / options["gravity_m_s2"],
                                           1.0 / interval if interval > 0 else np.nan, float(np.nanmax(heights)
                                                                                             - np.nanmin(heights)))
            raise NotFreeFallError(f"{error}; {reading}" if reading else str(error), error.acceleration_m_s2) from None
        raise InputError(video_limits.not_free_fall(attrs["video"], error.acceleration_m_s2, trajectory)) from None
    except InputError as error:
        if "video" not in attrs:
            raise
        raise InputError(video_limits.analysis_refusal(str(error), trajectory)) from None
    if "video" in attrs:  # a video's later bounces may be too briefly filmed to resolve
        analysis = _across_hidden_flights(analysis, time, trajectory["y"].values, seen, options)
        # the limits count captures: a 30 Hz clip in a 60 fps file films a flight in half as many frames
        captures = capture_interval(time, trajectory["y_seen"].values if "y_seen" in trajectory else None)
        clean_s = time[np.isfinite(trajectory["y"].values)]
        analysis = video_limits.select_resolved_impacts(analysis, attrs["video"], captures,
                                                        attrs.get("frames_unclean"), clean_s)
        if not analysis.impacts["in_fit"].any():  # every e unphysical: the tracking, not the ball, is the cause
            first = analysis.impacts[np.isfinite(analysis.impacts["e"])].iloc[0]  # (a resolved impact has an e)
            reason = str(first["note"]).split(";")[0]
            raise InputError(video_limits.analysis_refusal(
                f"{shown_path(attrs['video'])}: not analysable: no impact gives a physical e (impact "
                f"{int(first['impact'])}: {reason})", trajectory))
    if "x" in trajectory:  # a 2-D recording: the tangential velocities and angles (e stays the vertical fit's)
        analysis = add_horizontal(analysis, time, trajectory["x"].values, options["noise_correlation"])
    record = {key: plain(value) for key, value in options.items() if key != "source"}
    summary = dict(analysis.summary, analysis_options=record, gravity=settings.site_gravity().record(),
                   ball_size_note=_ball_size_note(analysis.summary, attrs))
    return dataclasses.replace(analysis, summary=summary)


#: Most flights seen in too few frames to fit that a video's analysis is carried across.
MAX_HIDDEN_FLIGHTS = 3


def _across_hidden_flights(analysis, time_s, height_m, seen_height_m, options):
    """A video's analysis carried across flights seen in too few frames to fit (a hand or a passer-by before the
    ball): where its sequence ends before such a flight, the samples after it are analysed as a sequence of their
    own and joined (:func:`dropfit.video.limits.join_later_sequence`); the impacts beside the hidden flight are
    left out by the limits, those after it measured. Unchanged when the later samples give no sequence that
    starts at the flight after the hidden one."""
    for _ in range(MAX_HIDDEN_FLIGHTS):
        hidden = video_limits.sparse_flight_cut(analysis)
        if hidden is None or int(analysis.flights["flight"].iloc[-1]) != hidden - 1:
            return analysis
        end = float(analysis.flights["t_end_s"].iloc[-1])
        later = time_s > end
        try:
            rest = analyse_bounces(time_s[later], height_m[later],
                                   seen_height_m=None if seen_height_m is None else seen_height_m[later], **options)
        except InputError:
            return analysis
        joined = video_limits.join_later_sequence(analysis, rest, hidden, time_s[later & np.isfinite(height_m)])
        if joined is None:
            return analysis
        analysis = joined
    return analysis


#: A step between two frames longer than this (m) is the ball moving: far above a still ball's centre noise
#: (0.1-0.5 mm on phone clips). On a clip without repeated frames any subset of its steps gives its interval.
MOVING_STEP_M = 2e-3


def capture_interval(time_s, seen_m=None):
    """The time between captures (s): the median step of the samples, or, for a video, of the frames in which
    the ball was seen to move (``seen_m``, its heights in m wherever seen). A clip whose recorder repeats every
    capture (30 Hz in a 60 fps file) loses the repeats only where the ball moves, the one place they can be told
    from new frames: its still frames keep the file's step."""
    time_s = np.asarray(time_s, dtype=float)
    if time_s.size < 2:
        return 0.0
    if seen_m is not None:
        moves = np.abs(np.diff(np.asarray(seen_m, dtype=float)))  # NaN where either frame did not see the ball
        moving = moves > MOVING_STEP_M
        if np.count_nonzero(moving) >= 2:
            return float(np.median(np.diff(time_s)[moving]))
    return float(np.median(np.diff(time_s)))


def _ball_size_note(summary, attrs):
    """The note that the drag held (``nominal``) is a regulation ball's, when the ball's size or mass was not
    given (:func:`dropfit.heightlog.regulation_note`); None otherwise."""
    return regulation_note(attrs) if summary.get("drag_model") == "nominal" else None


def fit_analysis(analysis, trajectory_attrs, settings=None, ball_type=None):
    """Analysis → fit result (the content of ``fit.json``, JSON-ready; NaN where JSON has null).

    Parameters
    ----------
    analysis : dropfit.analysis.BounceAnalysis
        As :func:`analyse_trajectory` gives it.
    trajectory_attrs : mapping
        The attributes of the trajectory analysed (ball, calibration, provenance).
    settings : dropfit.settings.Settings, optional
        The ITF window and tolerance (m).
    ball_type : str, optional
        Overrides the trajectory's kind of ball.
    """
    return fit_summary(analysis_summary(analysis, trajectory_attrs), analysis.impacts, settings, ball_type)


def _given_trajectory(trajectory, ball, settings, sample_id):
    """A measured trajectory with what the caller gives about the ball, the floor and the sample set in a
    copy of its attributes."""
    given = [name for name in MEASURE_ONLY_SETTINGS if getattr(settings, name) is not None]
    if given:
        raise InputError(f"{trajectory.attrs.get('source', 'trajectory')}: {', '.join(given)} appl"
                         f"{'ies' if len(given) == 1 else 'y'} to measuring a recording; this trajectory is "
                         f"measured already: give the recording's path instead")
    trajectory = trajectory.copy()
    trajectory.attrs = dict(trajectory.attrs)
    trajectory.attrs.update({f"ball_{name}": value for name, value in dataclasses.asdict(ball).items()
                             if value is not None})
    if settings.floor_m is not None:
        trajectory.attrs["floor_m"] = settings.floor_m
        trajectory.attrs.pop("floor_se_m", None)  # a given floor replaces one found in the image
    if sample_id is not None:
        trajectory.attrs["sample_id"] = sample_id
    return trajectory


def process_recording(recording, ball=None, settings=None, *, sample_id=None, tracked=None, tracking_refusal=None):
    """:func:`analyse_recording` with the ball and the settings as objects (and a video's table from
    :func:`track_recording`, when it is tracked already, or the refusal that tracking it raised).

    A video with a sound track is measured by both (:func:`measure_sound_and_picture`)."""
    import xarray as xr

    ball = ball or Ball()
    settings = settings or Settings()
    if isinstance(recording, (str, os.PathLike)) and recording_kind(recording, settings) == "video":
        from .audio.fuse import has_sound_track

        if has_sound_track(recording):
            return measure_sound_and_picture(recording, ball, settings, sample_id=sample_id, tracked=tracked,
                                             tracking_refusal=tracking_refusal)
    if tracking_refusal is not None:
        raise tracking_refusal
    if isinstance(recording, xr.Dataset):
        trajectory = _given_trajectory(recording, ball, settings, sample_id)
    elif isinstance(recording, (str, os.PathLike)):
        trajectory = measure_recording(recording, ball, settings, sample_id=sample_id, tracked=tracked)
    else:
        raise TypeError(f"a recording is a path or a trajectory (xarray.Dataset), not {type(recording).__name__}")
    return _result_of(trajectory, settings, ball)


def _result_of(trajectory, settings, ball):
    """A measured trajectory analysed and fitted: the recording's result."""
    analysis = analyse_trajectory(trajectory, settings)
    fit = fit_analysis(analysis, trajectory.attrs, settings)
    return RecordingResult(trajectory=trajectory, analysis=analysis, fit=fit, settings=settings, ball=ball)


def _picture_result(path, ball, settings, sample_id, tracked):
    """A video measured, analysed and fitted by its picture alone."""
    trajectory = measure_recording(path, ball, settings, sample_id=sample_id, tracked=tracked)
    return _result_of(trajectory, settings, ball)


def _sound_result(path, sound, attrs, settings, ball, release_time_s=None):
    """A video's sound track measured, analysed and fitted as a sound recording (release on its clock, s)."""
    trajectory = sound_trajectory(path, attrs, release_time_s, sound=sound)
    trajectory.attrs["source_sha256"] = sha256_of(path)
    return _result_of(trajectory, settings, ball)


def _with_fusion(result, fusion):
    """``result`` with the sound-and-picture record in its analysis summary, its fit and its ``fusion``."""
    record = fusion.record()
    analysis = dataclasses.replace(result.analysis, summary=dict(result.analysis.summary, sound_and_picture=record))
    fit = dict(result.fit, sound_and_picture=record)
    return RecordingResult(trajectory=result.trajectory, analysis=analysis, fit=fit, settings=result.settings,
                           ball=result.ball)


def measure_sound_and_picture(path, ball=None, settings=None, *, sample_id=None, tracked=None, tracking_refusal=None):
    """A video with a sound track, measured both ways (:mod:`dropfit.audio.fuse`).

    The picture is measured, analysed and fitted as any video; the sound track as a sound recording (without
    a release: its e are of the impacts after the first, independent of the picture's). The impacts seen and heard are paired and the
    offset between the clocks fitted; e from each and combined (:func:`dropfit.audio.fuse.fuse`). Where
    the picture is refused, the sound's e is the result and its record keeps the picture's reason; where
    the sound hears too few clicks, the picture's.

    Returns
    -------
    dropfit.result.RecordingResult
        The picture's result (or, the picture refused, the sound's), with ``fusion``
        (:class:`dropfit.audio.fuse.SoundAndPicture`), also held as ``sound_and_picture`` in its fit and
        analysis summary.

    Raises
    ------
    dropfit.errors.InputError
        When neither the picture nor the sound gives an e: the picture's refusal, with the sound's reason.
    """
    from .audio import fuse
    from .audio.compare import clicks_offset, pair_impacts
    from .audio.decode import read_sound
    from .errors import one_line

    ball = ball or Ball()
    settings = settings or Settings()
    picture = picture_refusal = sound_refusal = None
    if tracking_refusal is not None:
        picture_refusal = str(tracking_refusal)
    else:
        try:
            picture = _picture_result(path, ball, settings, sample_id, tracked)
        except InputError as error:
            picture_refusal = str(error)
    attrs = _recording_attrs(ball, settings, sample_id)
    if picture is not None:
        attrs = {key: value for key, value in picture.trajectory.attrs.items()
                 if key.startswith(("ball_", "gravity_")) or key in ("sample_id", "dropfit_version")}
    heard = sound = None
    try:
        sound = read_sound(path)
        # the picture refused, a capture rate given still puts a slow-motion clip's sound on the capture clock
        given = fuse.slow_motion_factor(path, settings.capture_fps) if picture is None else 1.0
        heard = _sound_result(path, fuse.on_capture_clock(sound, given) if given != 1.0 else sound, attrs, settings,
                              ball)
    except InputError as error:
        sound_refusal = str(error)
    except Exception as error:  # noqa: BLE001 — a bug in the sound's analysis must not cost the picture's e
        if picture is None:
            raise
        sound_refusal = _internal_error(path, "its sound track", error)
    if picture is None and heard is None:
        # the picture's refusal last: its diagnosis and advice end the message
        sound_reason = str(sound_refusal).split(": ", 1)[-1].split("; ")[0]
        raise InputError(f"{shown_path(path)}: its sound track gives no e ({sound_reason}), and its picture none: "
                         f"{str(picture_refusal).split(': ', 1)[-1]}")
    if heard is None:
        return _with_fusion(picture, fuse.one_sensor("picture", picture.fit, sound_refusal=one_line(sound_refusal),
                                                     impacts=picture.impacts, covariance=picture.analysis.e_covariance))
    if picture is None:
        return _with_fusion(heard, fuse.one_sensor("sound", heard.fit, picture_refusal=picture_refusal,
                                                   impacts=heard.impacts, covariance=heard.analysis.e_covariance))
    seen = picture.impacts
    seen_index, heard_index = pair_impacts(seen["t_touchdown_s"].to_numpy(), heard.impacts["t_touchdown_s"].to_numpy())
    offset = (float("nan"), float("nan"))
    notes = []
    told = picture.trajectory.attrs
    slowing = fuse.slow_motion_factor(path, told.get("capture_fps")
                                      if told.get("capture_fps_source", "container") != "container" else None)
    if slowing != 1.0:  # slow motion: its sound is slowed with the frames, and belongs on the capture clock
        why = None
        try:
            captured = _sound_result(path, fuse.on_capture_clock(sound, slowing), attrs, settings, ball)
        except InputError as error:
            captured, why = None, str(error)
        # the file's clock only where it pairs the impacts seen and the capture clock pairs fewer (a sound
        # recorded unslowed)
        index = (pair_impacts(seen["t_touchdown_s"].to_numpy(), captured.impacts["t_touchdown_s"].to_numpy())
                 if captured is not None else None)
        if captured is not None and (index[0].size >= seen_index.size or seen_index.size < fuse.MIN_PAIRS):
            heard, (seen_index, heard_index) = captured, index
            notes.append(f"slow motion ({slowing:g} times slower than captured): the sound is analysed on the "
                         f"capture clock (its samples {slowing:g} times faster)")
        elif captured is None and seen_index.size < fuse.MIN_PAIRS:  # neither clock: the sound gives no e
            return _with_fusion(picture, fuse.one_sensor(
                "picture", picture.fit, sound_refusal=f"{one_line(why)} (on the capture clock of this slow-motion "
                                                      f"clip, {slowing:g} times faster than the file's)",
                impacts=picture.impacts, covariance=picture.analysis.e_covariance))
        else:
            notes.append(f"slow motion ({slowing:g} times): the sound on the capture clock pairs fewer impacts; "
                         f"it is analysed on the file's clock (recorded unslowed)")
    if seen_index.size:
        offset = fuse.fit_offset(seen["t_touchdown_s"].to_numpy()[seen_index],
                                 seen["t_touchdown_se_s"].to_numpy()[seen_index],
                                 heard.impacts["t_touchdown_s"].to_numpy()[heard_index],
                                 heard.impacts["t_touchdown_se_s"].to_numpy()[heard_index])
        if seen_index.size < fuse.MIN_PAIRS:
            notes.append("the offset is that of one impact paired: not checked by a second")
        # (the picture's release is not given to the sound: its first e would share the picture's error of the
        # release, not independent of the picture's first e, and the release's error is not carried)
    if seen_index.size < fuse.MIN_PAIRS and "candidate_time_s" in heard.trajectory:
        paired, between = clicks_offset(seen["t_touchdown_s"].to_numpy(), heard.trajectory["candidate_time_s"].values)
        if paired >= fuse.MIN_PAIRS:
            notes.append(f"the clocks are {between:+.3f} s apart (sound − picture): {paired} of the "
                         f"{len(seen)} impacts seen pair with clicks heard at that offset, but the sound's chain "
                         f"of bounces holds {seen_index.size} of them (it took other clicks, a rattle or echoes, "
                         f"for bounces, or a missed click broke it)")
    try:
        fusion = fuse.fuse(seen, picture.analysis.e_covariance, picture.fit, heard.impacts,
                           heard.analysis.e_covariance, heard.fit, seen_index, heard_index, offset, notes)
    except Exception as error:  # noqa: BLE001 — as above: the picture's e stands
        fusion = fuse.one_sensor("picture", picture.fit, sound_refusal=_internal_error(
            path, "combining its sound and picture", error))
    return _with_fusion(picture, fusion)


def _internal_error(path, what, error):
    """The words of a bug met in ``what`` of a recording (kept in its record, the other sensor's e stands)."""
    from .errors import shown

    return (f"{shown_path(path)}: internal error in dropfit while analysing {what} ({type(error).__name__}: "
            f"{shown(error)}); please report it with this file")


def analyse_recording(recording, *, ball_radius_m=None, ball_mass_kg=None, ball_type=None, sample_id=None,
                      settings=None, **options):
    """Analyse one drop-test recording as the workflow does: measure, analyse, fit.

    Parameters
    ----------
    recording : str, pathlib.Path or xarray.Dataset
        A height log or video, or a trajectory already measured (:func:`measure_recording`,
        :func:`dropfit.heightlog.make_trajectory`).
    ball_radius_m, ball_mass_kg : float, optional
        The ball's radius in m and mass in kg (for a trajectory: replace its attributes).
    ball_type : str, optional
        Kind of ball (:data:`dropfit.balls.BALL_KINDS`); ``tennis`` gets the ITF verdict.
    sample_id : str, optional
        Name of the recording.
    settings : dropfit.settings.Settings, optional
        Start from these settings instead of the defaults.
    **options
        Any field of :class:`dropfit.settings.Settings`, with its unit in the name: ``floor_m``,
        ``scale_m_per_px``, ``ruler_tick_m``, ``capture_fps``, ``gravity_m_s2``, ``latitude_deg``,
        ``altitude_m``, ``drag``, ``itf_drop_height_m``, ``itf_rebound_min_m``,
        ``itf_rebound_max_m``, ``itf_drop_height_tolerance_m``.

    Returns
    -------
    dropfit.result.RecordingResult
        ``params`` (every reported quantity with its standard error and 95 % interval),
        ``impacts``, ``flights``, ``notes``, ``report()``, ``to_dict()`` (the workflow's fit.json).

    Raises
    ------
    dropfit.settings.OptionError
        For an option outside its range.
    dropfit.errors.InputError
        For a recording that cannot be analysed (one line saying why).
    """
    ball, _ = split_options({"ball_radius_m": ball_radius_m, "ball_mass_kg": ball_mass_kg, "ball_type": ball_type})
    settings = (settings or Settings()).replace(**options)
    return process_recording(recording, ball, settings, sample_id=sample_id)
