"""Where video analysis fails: limits, measured on the recording itself, below which e would be wrong.

``benchmarks/video_failure_sweep.py`` renders seeded synthetic clips and sweeps frame rate, sensor
noise, motion blur and ball size one at a time around a good 240 fps baseline; its table and chart
(``benchmarks/video_failure_sweep.csv``, ``.png``) are the evidence for every limit below. Over the
range where the tracker finds the ball, e stays within 3 × 10⁻⁴ of the generator's (7 × 10⁻⁴, within
its standard error, for a ball drawn with radius 1.5 px) and the only
way to a wrong e is a flight sampled by too few clean frames (a low frame rate; blurred frames
near the impacts count as clean since the tracker measures streaks as ``blurred``). The limits therefore use only what the tracker and the
analysis measure, never the ground truth:

* the tracked ball radius (px) and the fraction of frames measured cleanly, checked on the tracked
  table by :func:`check_recording`: below them the whole recording is refused;
* how many frame intervals each flight lasts and how many clean frames it has, checked per impact
  by :func:`select_resolved_impacts`: the impacts from the first under-sampled flight on are dropped with the reason stated, and the
  recording is refused only when its first impact is among them (later bounces are shorter, so
  dropping them first loses the least).

The centre noise relative to the travel (also measured, for the sweep's table) sets no limit: it
stayed under 5 × 10⁻³ wherever the tracker found the ball, was 1 × 10⁻⁴ in the clips whose e was
wrong, and e's standard error already carries it.

A refusal is an :class:`dropfit.errors.InputError` with one line,
``<file>: not analysable: <limit>: <measured value> < <limit value>``; one for too few clean
frames adds the options that tell the tracker about the ball (``TRACKER_HELP``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..analysis import estimate_noise, se_column_name
from ..errors import InputError, shown_path
from ..physics import STANDARD_GRAVITY_M_S2
from .quality import (QUALITY_DUPLICATE, QUALITY_LOST, QUALITY_OCCLUDED, QUALITY_OFF_TRACK, QUALITY_PARTIAL,
                      QUALITY_SHADED, usable_rows)

#: Smallest tracked ball radius, px. Sweep: a ball drawn with radius 1 px is never found and one of
#: 1.25 px in no clean frame; drawn with 1.5–2 px it is tracked as 2.2–2.3 px (the edge threshold
#: widens it) and e is still right. No ball was tracked smaller, so a smaller blob is not a ball.
MIN_BALL_RADIUS_PX = 2.0
#: Smallest fraction of the frames from the first clean one to the last that are clean. Sweep (the colour
#: tracker, 2026-11-23): e right wherever 49 % or more were clean (noise σ = 30 grey levels: 49–61 %); a
#: ball drawn with radius 1–1.5 px, tracked in 30–41 % of the frames, gave e₁ 7 standard errors off
#: once (38 %) and 2.4 once (33 %). The sweep's table was run with the earlier limit of 30 %.
MIN_CLEAN_FRACTION = 0.45
#: Fewest frame intervals a flight around an impact must last (the drop: from its apex, the release,
#: to touchdown; a bounce: from lift-off to touchdown). Sweep (blurred frames measured): a fall of 6.1
#: frame intervals (15 frames/s) gave e₁ off by 3 × 10⁻³ (18 standard errors); falls of 7.8–12.5
#: intervals (20 and 30 frames/s) were within 8 × 10⁻⁴ and 1.8 standard errors, and every fall of
#: ≥ 15.6 intervals (40 frames/s and up) within 1.0 × 10⁻⁴. The independent phone-clip generator agrees
#: at 30 frames/s (tests/test_phone_clips.py). It is the flight that must be sampled densely, not the
#: clip: a high-speed close-up films only the last milliseconds of a long fall.
MIN_FRAME_INTERVALS_PER_FLIGHT = 8
#: Fewest clean frames in each of the two flights around an impact. Sweep: 7–8 clean frames before
#: impact 1 (20 frames/s) gave e₁ within 1.3 × 10⁻⁴, 5 (15 frames/s) once 3 × 10⁻³ off; on the phone-clip
#: generator at 30 frames/s a fall seen cleanly in 6 frames (the rest behind a hand or blurred) gave e₁
#: 3 standard errors off, and 7 or more were right. The 1000 frames/s close-up sees 12 clean frames
#: before its contact and gives e within 5 × 10⁻⁵ (tests/test_videolog.py).
MIN_CLEAN_FRAMES_PER_FLIGHT = 7
#: Columns of an impact that the flight before it decides (with their se and interval): NaN where that
#: flight is too sparsely sampled and a later impact is resolved (:func:`select_resolved_impacts`).
UNRESOLVED_IMPACT_COLUMNS = ("v_in_m_s", "e", "flight_time_ratio", "t_contact_ms")
#: Fewest clean frames in a recording: the two flights around a first impact.
MIN_CLEAN_FRAMES = 2 * MIN_CLEAN_FRAMES_PER_FLIGHT


#: What a refusal for too few clean frames suggests: the options that tell the tracker about the ball.
TRACKER_HELP = ("see the contact sheet (dropfit overlay); help the tracker with --ball-at-px FRAME,X,Y (the ball's "
                "centre in one frame), --roi-px X0,Y0,X1,Y1 (where it moves), --ball-colour (e.g. yellow or "
                "#e0d040) or --ball-radius-px (samples.tsv columns ball_at_px, roi_px, ball_colour, ball_radius_px)")


def recording_measures(table):
    """What the tracked table says about a recording's fitness for analysis.

    Parameters
    ----------
    table : pandas.DataFrame
        As returned by :func:`dropfit.video.track.track_video` (``y_px``, ``radius_px``, ``quality``).

    Returns
    -------
    dict
        ``ball_radius_px`` (median tracked radius of the clean frames, those usable for a trajectory:
        :func:`dropfit.video.quality.usable_rows`, px), ``clean_fraction`` (clean frames over the frames,
        duplicates left out, from the first clean frame to the last:
        a hand holding the ball before it or an empty scene after it does not count against the
        recording), ``clean_frames`` (their number), ``centre_noise_px`` (robust noise of the clean frames' centre rows, px),
        ``travel_px`` (range of those rows, px) and ``noise_to_travel`` (their ratio). Radius,
        noise and travel are NaN when no frame is clean.
    """
    kept = table[table["quality"] != QUALITY_DUPLICATE]
    is_clean = usable_rows(kept)
    clean = kept[is_clean]
    rows = clean["y_px"].to_numpy(float)
    span = np.flatnonzero(is_clean)
    fraction = rows.size / (span[-1] - span[0] + 1) if span.size else 0.0
    if rows.size == 0:
        return dict(ball_radius_px=np.nan, clean_fraction=fraction, clean_frames=0, centre_noise_px=np.nan,
                    travel_px=np.nan, noise_to_travel=np.nan)
    noise = estimate_noise(rows)
    travel = float(np.ptp(rows))
    return dict(ball_radius_px=float(np.median(clean["radius_px"])), clean_fraction=fraction, clean_frames=rows.size,
                centre_noise_px=noise, travel_px=travel, noise_to_travel=noise / travel if travel > 0 else np.inf)


def recording_violations(measures):
    """The recording-wide limits that ``measures`` (from :func:`recording_measures`) break.

    Returns
    -------
    list of str
        One phrase per broken limit, "<limit>: <measured> < <limit value>"; empty if none.
    """
    violations = []
    if measures["clean_frames"] < MIN_CLEAN_FRAMES:
        violations.append(f"frames measured cleanly: {measures['clean_frames']} < {MIN_CLEAN_FRAMES}")
    elif not measures["clean_fraction"] >= MIN_CLEAN_FRACTION:
        violations.append(f"frames measured cleanly: {measures['clean_fraction']:.0%} < {MIN_CLEAN_FRACTION:.0%}")
    if np.isfinite(measures["ball_radius_px"]) and measures["ball_radius_px"] < MIN_BALL_RADIUS_PX:
        violations.append(f"tracked ball radius: {measures['ball_radius_px']:.2f} px < {MIN_BALL_RADIUS_PX:g} px")
    return violations


def check_recording(table, source):
    """Raise :class:`InputError` if the tracked recording breaks a recording-wide limit.

    Parameters
    ----------
    table : pandas.DataFrame
        The tracked table (see :func:`recording_measures`).
    source : str or pathlib.Path
        The recording, named in the message.
    """
    measures = recording_measures(table)
    violations = recording_violations(measures)
    if violations:
        few = measures["clean_frames"] < MIN_CLEAN_FRAMES or measures["clean_fraction"] < MIN_CLEAN_FRACTION
        cause = f" ({unclean_frames(table)}); {TRACKER_HELP}" if few else ""
        raise InputError(f"{shown_path(source)}: not analysable: {'; '.join(violations)}{cause}")


#: ``capture_fps_source`` of a capture rate inferred from the flights' curvature (alone, or followed by
#: " (not a common rate)").
GRAVITY_CAPTURE_RATE_SOURCE = "inferred from gravity"
#: What a refusal says when the tracking, not the drop, is the likely cause.
TRACKING_FAILED = "the tracker lost the ball in its flights or followed something else"
#: A video whose ball was measured in at least this fraction of its frames was tracked well: if its flights
#: do not fall with g, the cause is elsewhere (too few frames per flight, the scale).
WELL_TRACKED_FRACTION = 0.8


def not_free_fall(source, acceleration_m_s2, trajectory):
    """The refusal of a video whose tracked flights do not fall with g: what the tracker measured.

    When the ball was measured in most frames (:data:`WELL_TRACKED_FRACTION`) and the whole height
    covered would be fallen in fewer than :data:`MIN_FRAME_INTERVALS_PER_FLIGHT` frame intervals, the
    flights are too sparsely sampled to be told apart from their impacts, and the refusal says so (with
    the frame rate that would do). When the capture rate was inferred from the flights' curvature in the
    file's time (``capture_fps_source`` in the trajectory's attributes), it names that rate first: flights
    found wrongly there (a hand's jumps that turned the image rows' sign) made 1120 fps of a 120 fps clip, and
    the refusal had blamed the tracking alone. Else it points at the tracking.

    Parameters
    ----------
    source : str
        The video.
    acceleration_m_s2 : float
        The tracked flights' shared downward acceleration, m/s².
    trajectory : xarray.Dataset
        The video's trajectory (``time`` in s, ``y`` in m, ``quality`` 0 for a measured frame; ``attrs`` may hold
        ``capture_fps_source`` and ``capture_rate_note``).

    Returns
    -------
    str
        One line: the acceleration, how many frames were measured and over what height, and what to try.
    """
    measured, span, found = _measured(trajectory)
    said = (f"{shown_path(source)}: not analysable: the tracked ball falls with {acceleration_m_s2:.3g} m/s², not g: "
            f"{found}")
    times = trajectory["time"].values
    interval_s = float(np.median(np.diff(times))) if times.size > 1 else np.nan
    fall_s = math.sqrt(2.0 * span / STANDARD_GRAVITY_M_S2)
    well_tracked = measured.mean() >= WELL_TRACKED_FRACTION if measured.size else False
    sparse = np.isfinite(interval_s) and interval_s > 0 and fall_s < MIN_FRAME_INTERVALS_PER_FLIGHT * interval_s
    if well_tracked and sparse:
        needed = math.ceil(MIN_FRAME_INTERVALS_PER_FLIGHT / fall_s) if fall_s > 0 else math.inf
        return (f"{said}: a fall over that height lasts {fall_s / interval_s:.1f} frame intervals at "
                f"{1.0 / interval_s:.3g} frames/s, fewer than the {MIN_FRAME_INTERVALS_PER_FLIGHT} a flight needs "
                f"to be told from its impacts; film at {needed:g} frames/s or more (slow motion), or drop from higher")
    if str(trajectory.attrs.get("capture_fps_source", "")).startswith(GRAVITY_CAPTURE_RATE_SOURCE):
        # the rate came from flights found in the file's time: found wrongly, they give a wrong rate too
        return (f"{said}, at the capture rate inferred from the flights in the file's time "
                f"({trajectory.attrs.get('capture_rate_note', '')}); if the clip is not slow motion, give the file's "
                f"rate with --capture-fps (samples.tsv column capture_fps); else {TRACKING_FAILED}"
                f"{_unclean_words(trajectory)}; {TRACKER_HELP}")
    return f"{said} ({TRACKING_FAILED}, or the scale is wrong{_unclean_words(trajectory)}); {TRACKER_HELP}"


def _measured(trajectory):
    """Which frames the ball was measured in, the height (m) they span, and both in words."""
    measured = trajectory["quality"].values == 0
    heights = trajectory["y"].values[measured]
    span = float(np.ptp(heights)) if heights.size else 0.0
    words = f"it was measured in {int(measured.sum())} of {measured.size} frames, over {span:.3g} m of height"
    return measured, span, words


def analysis_refusal(message, trajectory):
    """A video's refusal by the analysis (``message``: no bounce, too few samples in a flight, ...) with
    what the tracker measured and the options that help, when the ball was measured in fewer than
    :data:`WELL_TRACKED_FRACTION` of the frames: then the tracking, not the drop, is the first cause.

    Parameters
    ----------
    message : str
        The analysis's one-line refusal.
    trajectory : xarray.Dataset
        The video's trajectory (``y`` in m, ``quality`` 0 for a measured frame).

    Returns
    -------
    str
        One line.
    """
    measured, _, found = _measured(trajectory)
    if measured.size and measured.mean() >= WELL_TRACKED_FRACTION:
        return message
    return (f"{message}: {found} ({TRACKING_FAILED}"
            f"{_unclean_words(trajectory)}); {TRACKER_HELP}")


def _unclean_words(trajectory):
    """"; the frames not measured cleanly: …" (:func:`unclean_frames`, kept in the trajectory's attributes), or
    nothing."""
    unclean = trajectory.attrs.get("frames_unclean")
    return f"; in the frames not measured cleanly {unclean}" if unclean else ""


def unclean_frames(table):
    """What the frames not measured cleanly were, in words: how many merged, partial, lost, and the channel.

    Parameters
    ----------
    table : pandas.DataFrame
        The tracked table; ``attrs["contrast"]`` names the channel it was tracked in.

    Returns
    -------
    str
        E.g. "the ball merged with something (its shadow, a hand) in 85 % of the frames, not found in
        5 %; tracked in chroma".
    """
    kept = table["quality"] != QUALITY_DUPLICATE
    total = max(int(kept.sum()), 1)
    quality = table["quality"][kept & ~usable_rows(table)]
    parts = []
    for flag, words in ((QUALITY_OCCLUDED, "merged with something (its shadow, a hand) or partly hidden"),
                        (QUALITY_PARTIAL, "cut by the image border"),
                        (QUALITY_SHADED, "merged with its shadow and too blurred to measure on its lit side"),
                        (QUALITY_LOST, "not found"),
                        (QUALITY_OFF_TRACK, "off the ballistic track through its neighbours (a tracking jump)")):
        count = int((quality == flag).sum())
        if count:
            parts.append(f"{words} in {count / total:.0%} of the frames")
    described = "the ball " + ", ".join(parts) if parts else "no frame measured"
    channel = table.attrs.get("contrast")
    return f"{described}; tracked in {channel}" if channel else described


def flight_violation(impacts_row, frames_before, frames_after, frame_interval_s):
    """Why an impact is unresolved, or None if both its flights are sampled densely enough.

    Parameters
    ----------
    impacts_row : mapping
        A row of the impacts table (``impact``, ``n_samples_before``, ``n_samples_after``: clean frames).
    frames_before, frames_after : float
        How many frame intervals the flights before and after the impact last.
    frame_interval_s : float
        Time between frames in s, for the frame rate that would film the flight long enough.
    """
    for side, span, clean in (("before", frames_before, impacts_row["n_samples_before"]),
                              ("after", frames_after, impacts_row["n_samples_after"])):
        if span < MIN_FRAME_INTERVALS_PER_FLIGHT:
            rate = 1.0 / frame_interval_s
            needed = math.ceil(rate * MIN_FRAME_INTERVALS_PER_FLIGHT / span) if span > 0 else math.inf
            return (f"impact {int(impacts_row['impact'])}: the flight {side} it lasts {span:.1f} frame intervals at "
                    f"{rate:.3g} frames/s, fewer than the {MIN_FRAME_INTERVALS_PER_FLIGHT} a flight needs to be told "
                    f"from its impacts; film at {needed:g} frames/s or more (slow motion)")
        if clean < MIN_CLEAN_FRAMES_PER_FLIGHT:
            # as many frames clean in every frame interval: more frames a second give more clean ones
            rate = 1.0 / frame_interval_s
            faster = (f"film at {math.ceil(rate * MIN_CLEAN_FRAMES_PER_FLIGHT / clean):g} frames/s or more"
                      if clean > 0 else "film at a higher frame rate")
            return (f"impact {int(impacts_row['impact'])}: clean frames in the flight {side} it: {int(clean)} "
                    f"< {MIN_CLEAN_FRAMES_PER_FLIGHT} ({faster}, with a shorter exposure)")
    return None


def flight_spans(analysis, frame_interval_s):
    """Frame intervals the flights before and after each impact last (see MIN_FRAME_INTERVALS_PER_FLIGHT).

    Parameters
    ----------
    analysis : dropfit.analysis.BounceAnalysis
        The analysis of a video's trajectory.
    frame_interval_s : float
        Time between frames in s.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Per impact, the frame intervals of the flight before it (the drop: from its apex; a first flight that
        follows a bounce: from its start) and of the flight after it (the last: twice its rise to the apex).
    """
    touchdown = analysis.impacts["t_touchdown_s"].to_numpy()
    liftoff = analysis.impacts["t_liftoff_s"].to_numpy()
    apex = analysis.flights["t_apex_s"].to_numpy()
    first_start = min(apex[0], analysis.flights["t_start_s"].iloc[0]) \
        if analysis.summary.get("first_flight_is_a_bounce") else apex[0]
    starts = np.concatenate([[first_start], liftoff[:-1]])
    ends = np.append(touchdown[1:], liftoff[-1] + 2.0 * (apex[len(liftoff)] - liftoff[-1]))
    return (touchdown - starts) / frame_interval_s, (ends - liftoff) / frame_interval_s


def select_resolved_impacts(analysis, source, frame_interval_s, unclean=None):
    """Keep the impacts whose two flights are both sampled densely enough, from the first that is to the first
    after it that is not; the impacts before the first resolved one keep their rows with no e.

    A clip at 30 frames/s often films the drop's fast fall in too few clean frames (a white ball blurred into
    the wall, a hand in view) and the bounces after it well: their e is measured, and the first impacts say
    why theirs is not.

    Parameters
    ----------
    analysis : dropfit.analysis.BounceAnalysis
        The analysis of a video's trajectory.
    source : str or pathlib.Path
        The recording, named in the message.
    frame_interval_s : float
        Time between frames in s.
    unclean : str, optional
        What the frames not measured cleanly were (:func:`unclean_frames`), told when no impact is resolved
        for want of clean frames.

    Returns
    -------
    dropfit.analysis.BounceAnalysis
        The same analysis with the impacts (and their flights, covariances and ``n_impacts``) from
        the first unresolved impact after a resolved one on removed; the unresolved impacts before the
        first resolved one have no e, impact speed, flight-time ratio or contact time (NaN, out of
        every fit, the reason in their note). ``summary["impacts_dropped"]`` gives the reasons (empty
        when all impacts are kept).

    Raises
    ------
    InputError
        When no impact is resolved: nothing is left to report.
    """
    spans = flight_spans(analysis, frame_interval_s)
    reasons = [flight_violation(row, before, after, frame_interval_s)
               for (_, row), before, after in zip(analysis.impacts.iterrows(), *spans)]
    first = next((i for i, reason in enumerate(reasons) if reason is None), None)
    if first is None:
        why = f"; the frames not clean: {unclean}; {TRACKER_HELP}" if unclean and "clean frames" in reasons[0] else ""
        raise InputError(f"{shown_path(source)}: not analysable: {reasons[0]}{why}")
    kept = next((i for i in range(first, len(reasons)) if reasons[i] is not None), len(reasons))
    n = len(reasons)
    pair = np.r_[0:kept, n: n + kept]  # e_1…e_kept and their contact times
    impacts = analysis.impacts.iloc[:kept].reset_index(drop=True)
    e_covariance = analysis.e_covariance[:kept, :kept].copy()
    e_contact_covariance = analysis.e_contact_covariance[np.ix_(pair, pair)].copy()
    e_drag_covariance = analysis.e_drag_covariance[:kept].copy()
    if first:
        unresolved = np.arange(first)
        for name in UNRESOLVED_IMPACT_COLUMNS:
            for column in (name, se_column_name(name), se_column_name(name, "ci95_low"),
                           se_column_name(name, "ci95_high")):
                impacts.loc[unresolved, column] = np.nan
        impacts.loc[unresolved, "contact_resolvable"] = False
        impacts.loc[unresolved, "in_fit"] = False
        impacts.loc[unresolved, "note"] = [reasons[i].split(": ", 1)[1] + ": its e is not given" for i in range(first)]
        for matrix, rows in ((e_covariance, unresolved), (e_contact_covariance, np.r_[unresolved, kept + unresolved])):
            matrix[rows, :] = 0.0
            matrix[:, rows] = 0.0
        e_drag_covariance[unresolved] = 0.0
    dropped = [f"{reasons[kept]}; this and the {n - kept - 1} later impacts dropped"] if kept < n else []
    summary = dict(analysis.summary, n_impacts=kept, impacts_dropped=dropped)
    flights = analysis.flights.iloc[: kept + 1].reset_index(drop=True)
    return dataclasses.replace(analysis, impacts=impacts, flights=flights, e_covariance=e_covariance,
                               e_contact_covariance=e_contact_covariance, e_drag_covariance=e_drag_covariance,
                               summary=summary)
