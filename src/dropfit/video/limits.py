"""Where video analysis fails: limits, measured on the recording itself, below which e would be wrong.

``benchmarks/video_failure_sweep.py`` renders seeded synthetic clips and sweeps frame rate, sensor
noise, motion blur and ball size one at a time around a good 240 fps baseline; its table and chart
(``benchmarks/video_failure_sweep.csv``, ``.png``) are the evidence for every limit below. Over the
range where the tracker finds the ball, e stays within 3 × 10⁻⁴ of the generator's (7 × 10⁻⁴, within
its standard error, for a ball drawn with radius 1.5 px) and the only
way to a wrong e is a flight sampled by too few clean frames (a low frame rate; blurred frames
near the impacts count as clean since the tracker measures streaks as ``blurred``). The limits therefore use only what the tracker and the
analysis measure, never the ground truth:

* the tracked ball radius (px) and the number of clean frames, checked on the tracked table by
  :func:`check_recording`: below them (a blob smaller than any ball tracked, fewer clean frames than the two
  flights of one impact need) no impact can be measured and the whole recording is refused;
* how many frame intervals each flight lasts, how many clean frames it has and which fraction of its frames
  they are, checked per impact by :func:`select_resolved_impacts`: impact n is measured from flights n − 1
  and n alone, so a flight too poorly filmed costs the two impacts beside it (each keeps its row, with no e
  and the reason), never the others; the recording is refused only when no impact is measured, with each
  impact's reason. The fraction of clean frames is judged per flight: a hand holding the ball, an occlusion
  in one flight or an empty scene after the drop says nothing about the other flights. A flight of
  :data:`MIN_FRAME_INTERVALS_PER_FLIGHT` to :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` frame intervals (a phone
  clip at 20–30 frames/s) is measured from fewer clean frames, and its impacts' e carries the error so sparse a
  sampling makes (:func:`sparse_flight_e_se`, measured by ``benchmarks/sparse_flight_sweep.py``), with a note.

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
import re

import numpy as np
import pandas as pd

from ..analysis import estimate_noise, se_column_name
from ..analysis.tables import Z95, add_with_interval
from ..errors import InputError, shown_path
from ..physics import STANDARD_GRAVITY_M_S2
from .calibrate import slow_motion_reading
from .quality import (QUALITY_DUPLICATE, QUALITY_LOST, QUALITY_OCCLUDED, QUALITY_OFF_TRACK, QUALITY_PARTIAL,
                      QUALITY_SHADED, usable_rows)

#: Smallest tracked ball radius, px. Sweep: a ball drawn with radius 1 px is never found and one of
#: 1.25 px in no clean frame; drawn with 1.5–2 px it is tracked as 2.2–2.3 px (the edge threshold
#: widens it) and e is still right. No ball was tracked smaller, so a smaller blob is not a ball.
MIN_BALL_RADIUS_PX = 2.0
#: Smallest fraction of a flight's frames that are clean (judged per flight, :func:`select_resolved_impacts`;
#: the sweep measured it over the clip, whose flights were all alike). Sweep (the colour
#: tracker, 2026-11-23): e right wherever 49 % or more were clean (noise σ = 30 grey levels: 49–61 %); a
#: ball drawn with radius 1–1.5 px, tracked in 30–41 % of the frames, gave e₁ 7 standard errors off
#: once (38 %) and 2.4 once (33 %). The sweep's table was run with the earlier limit of 30 %.
MIN_CLEAN_FRACTION = 0.45
#: Frame intervals a flight around an impact lasts from which its impact needs no widening of e's interval (the
#: drop: from its apex, the release, to touchdown; a bounce: from lift-off to touchdown). Sweep (blurred frames
#: measured): a fall of 6.1 frame intervals (15 frames/s) gave e₁ off by 3 × 10⁻³ (18 standard errors); falls of
#: 7.8–12.5 intervals (20 and 30 frames/s) were within 8 × 10⁻⁴ and 1.8 standard errors, and every fall of
#: ≥ 15.6 intervals (40 frames/s and up) within 1.0 × 10⁻⁴. The independent phone-clip generator agrees
#: at 30 frames/s (tests/test_phone_clips.py). It is the flight that must be sampled densely, not the
#: clip: a high-speed close-up films only the last milliseconds of a long fall.
DENSE_FRAME_INTERVALS_PER_FLIGHT = 8
#: Fewest frame intervals a flight around an impact must last for the impact to be measured at all; from here to
#: :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` its e's interval is widened by :func:`sparse_flight_e_se`. The sweep
#: (``benchmarks/sparse_flight_sweep.py``) found e from flights of 5-8 intervals inside its widened interval at the
#: stated rate (below); a flight of 5 intervals holds at best the 5 clean frames a flight's parabola is fitted from
#: (:data:`MIN_CLEAN_FRAMES_PER_SPARSE_FLIGHT`), a shorter one fewer: the sweep's analyses fitted none under 5.
MIN_FRAME_INTERVALS_PER_FLIGHT = 5
#: Relative error of the impact speed measured from a drop (the fall from its release, a hand's, to impact 1) of
#: fewer than :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` frame intervals, beyond its fit's standard error (see
#: :func:`sparse_flight_e_se`). Sweep (``benchmarks/sparse_flight_sweep.py``, term off): phonesim's clips, a hand
#: releasing the ball, 37 impacts 1 after a fall of 5-8 intervals: 36 inside the fit's 95 % interval, but one fall of
#: 6.1 intervals (the white ball, 30 Hz in a 60 fps MOV) gave e₁ 0.023 low, 8.7 standard errors, and the rms of
#: (e − e_true) / se was 1.5 (2.5 for falls of 6-7 intervals); this term, the least that makes that rms 1, brings
#: falls of 6-7 intervals to rms 1.6 and leaves the others' coverage at 100 %. refsim's drops sampled without a
#: hand (51) needed none (rms 0.66, 98 % covered): it is the hand's release, seen in few frames, that a sparse fall
#: gets wrong.
SPARSE_DROP_SPEED_RELATIVE_SE = 0.0036
#: The same for a bounce's flight (from a lift-off to a touchdown) of fewer than
#: :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` intervals. Sweep: none is needed. Impacts beside a bounce of 5-8
#: intervals were inside the fit's 95 % interval 87 of 87 times on phonesim's clips (rms z 0.6-0.7 in each interval
#: bin) and 169 of 174 on refsim's sampled drops (96.7-98.7 % per bin, rms z 0.64-0.90): the fit's standard error,
#: larger from fewer samples, carries the sparse sampling.
SPARSE_BOUNCE_SPEED_RELATIVE_SE = 0.0
#: Fewest clean frames in each of the two flights around an impact. Sweep: 7–8 clean frames before
#: impact 1 (20 frames/s) gave e₁ within 1.3 × 10⁻⁴, 5 (15 frames/s) once 3 × 10⁻³ off; on the phone-clip
#: generator at 30 frames/s a fall seen cleanly in 6 frames (the rest behind a hand or blurred) gave e₁
#: 3 standard errors off, and 7 or more were right. The 1000 frames/s close-up sees 12 clean frames
#: before its contact and gives e within 5 × 10⁻⁵ (tests/test_videolog.py).
MIN_CLEAN_FRAMES_PER_FLIGHT = 7
#: Fewest clean frames in a flight shorter than :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` frame intervals: one that
#: short holds fewer than :data:`MIN_CLEAN_FRAMES_PER_FLIGHT` frames clear of its contacts however well it is filmed
#: (5 in flights of 5.5-7 intervals of the phone-clip generator's 20 frames/s clips), and its parabola is fitted from
#: as few as the analysis fits any flight from; the sparse sampling's error is carried by :func:`sparse_flight_e_se`.
MIN_CLEAN_FRAMES_PER_SPARSE_FLIGHT = 5
#: Columns of an impact that the flight before it decides (with their se and interval): NaN where that
#: flight is too poorly filmed (:func:`select_resolved_impacts`). The flights' own apex heights and durations
#: (``h_before_m``, ``h_after_m``, ``flight_time_after_s``) keep their fitted values and standard errors.
UNRESOLVED_IMPACT_COLUMNS = ("v_in_m_s", "e", "e_height", "flight_time_ratio", "t_contact_ms")
#: Columns of an impact that the flight after it decides: NaN where that flight is too poorly filmed.
UNRESOLVED_AFTER_COLUMNS = ("v_out_m_s", "e", "e_height", "flight_time_ratio", "t_contact_ms")
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
    """The recording-wide limits that ``measures`` (from :func:`recording_measures`) break: those below which no
    impact can be measured (the fraction of clean frames is judged per flight, :func:`select_resolved_impacts`).

    Returns
    -------
    list of str
        One phrase per broken limit, "<limit>: <measured> < <limit value>"; empty if none.
    """
    violations = []
    if measures["clean_frames"] < MIN_CLEAN_FRAMES:
        violations.append(f"frames measured cleanly: {measures['clean_frames']} < {MIN_CLEAN_FRAMES} (the two "
                          f"flights of one impact need {MIN_CLEAN_FRAMES_PER_FLIGHT} each)")
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
        few = measures["clean_frames"] < MIN_CLEAN_FRAMES
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
    covered would be fallen in fewer than :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` frame intervals, the
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
    # far slower than g: a time base off (slow motion stored at a playback rate), the first cause of a ball tracked
    # well, one of two of a ball lost in many frames
    slow = slow_motion_reading(acceleration_m_s2 / STANDARD_GRAVITY_M_S2, 1.0 / interval_s)
    if slow and well_tracked:
        return f"{said}; it {slow}"
    if slow:
        said = f"{said}; if it was tracked right, it {slow}; else"
    # (a fall that the analysis could not tell from its impacts: fewer intervals than a flight needs to be measured
    # without widening, DENSE_FRAME_INTERVALS_PER_FLIGHT, is the likely cause)
    sparse = np.isfinite(interval_s) and interval_s > 0 and fall_s < DENSE_FRAME_INTERVALS_PER_FLIGHT * interval_s
    if well_tracked and sparse:
        needed = math.ceil(DENSE_FRAME_INTERVALS_PER_FLIGHT / fall_s) if fall_s > 0 else math.inf
        return (f"{said}: a fall over that height lasts {fall_s / interval_s:.1f} frame intervals at "
                f"{1.0 / interval_s:.3g} frames/s, fewer than the {DENSE_FRAME_INTERVALS_PER_FLIGHT} a flight needs "
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


def _flight_problem(side, span, clean, frame_interval_s, share_judged=True):
    """Why one flight around an impact is too poorly filmed to measure, as (diagnosis, advice), or None.

    ``side`` is "before" or "after" (the impact), ``span`` the frame intervals the flight lasts, ``clean`` its
    clean frames (those in its fit), ``frame_interval_s`` the time between frames (s); ``share_judged`` false where
    the clip as a whole is measured cleanly enough (:func:`clean_share`) for its flights' clean share not to matter."""
    rate = 1.0 / frame_interval_s
    if span < MIN_FRAME_INTERVALS_PER_FLIGHT:
        # (the rate that films it densely: its e then needs no widening, sparse_flight_e_se)
        needed = math.ceil(rate * DENSE_FRAME_INTERVALS_PER_FLIGHT / span) if span > 0 else math.inf
        return (f"the flight {side} it lasts {span:.1f} frame intervals at {rate:.3g} frames/s, fewer than the "
                f"{MIN_FRAME_INTERVALS_PER_FLIGHT} a flight needs to be told from its impacts",
                f"film at {needed:g} frames/s or more, in slow motion")
    least = MIN_CLEAN_FRAMES_PER_FLIGHT if span >= DENSE_FRAME_INTERVALS_PER_FLIGHT \
        else MIN_CLEAN_FRAMES_PER_SPARSE_FLIGHT
    if clean < least:
        # as many frames clean in every frame interval: more frames a second give more clean ones
        faster = (f"film at {math.ceil(rate * MIN_CLEAN_FRAMES_PER_FLIGHT / clean):g} frames/s or more"
                  if clean > 0 else "film at a higher frame rate")
        return (f"clean frames in the flight {side} it: {int(clean)} < {least}",
                f"{faster}, with a shorter exposure")
    fraction = min(clean / max(span, 1.0), 1.0)
    if share_judged and fraction < MIN_CLEAN_FRACTION:
        return (f"the flight {side} it is measured cleanly in {fraction:.0%} of its frames < {MIN_CLEAN_FRACTION:.0%}",
                TRACKER_HELP)
    return None


def _impact_problems(impacts_row, frames_before, frames_after, frame_interval_s, share_judged=True):
    """The problems (:func:`_flight_problem`) of the flights before and after one impact: a dict, by side. A
    flight not fitted (NaN span: seen in too few frames, :func:`join_later_sequence`) is one."""
    problems = {}
    for side, span, clean in (("before", frames_before, impacts_row["n_samples_before"]),
                              ("after", frames_after, impacts_row["n_samples_after"])):
        if not np.isfinite(span):
            problems[side] = (f"the flight {side} it is seen in {int(clean)} frames, too few to fit (hidden or lost)",
                              TRACKER_HELP)
            continue
        problem = _flight_problem(side, span, clean, frame_interval_s, share_judged)
        if problem is not None:
            problems[side] = problem
    return problems


def sparse_flight_e_se(e, frames_before, frames_after, drop_before=False):
    """The standard error to add, in quadrature, to the e of an impact measured from a flight (before it, after it or
    both) that lasts fewer than :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` frame intervals: the error that so sparse
    a sampling of the flight makes in the speed at its contact, beyond the fit's standard error, relative
    :data:`SPARSE_DROP_SPEED_RELATIVE_SE` for the drop from a release, :data:`SPARSE_BOUNCE_SPEED_RELATIVE_SE` for
    a bounce (measured: ``benchmarks/sparse_flight_sweep.py``). e = v_out / v_in: the two flights' relative errors
    add in quadrature.

    Parameters
    ----------
    e : float
        The impact's e.
    frames_before, frames_after : float
        How many frame intervals the flights before and after the impact last (NaN: not fitted).
    drop_before : bool
        Whether the flight before the impact is the drop from its release (impact 1 of a drop), not a bounce.

    Returns
    -------
    float
        0 where both flights last :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` intervals or more.
    """
    variance = sum((SPARSE_DROP_SPEED_RELATIVE_SE if side == "before" and drop_before
                    else SPARSE_BOUNCE_SPEED_RELATIVE_SE) ** 2 for side in sparse_flights(frames_before, frames_after))
    return abs(float(e)) * math.sqrt(variance)


def sparse_flights(frames_before, frames_after):
    """The flights of an impact that last fewer than :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` frame intervals, as
    {"before": span, "after": span} (empty: densely filmed)."""
    return {side: span for side, span in (("before", frames_before), ("after", frames_after))
            if np.isfinite(span) and span < DENSE_FRAME_INTERVALS_PER_FLIGHT}


def _sparse_note(frames_before, frames_after, frame_interval_s, se, widened_se):
    """The note on an impact measured from a sparsely filmed flight: its span and how far e's interval grew."""
    spans = " and ".join(f"the flight {side} it lasts {span:.1f} frame intervals"
                         for side, span in sparse_flights(frames_before, frames_after).items())
    said = (f"sparsely filmed: {spans} at {1.0 / frame_interval_s:.3g} frames/s (fewer than "
            f"{DENSE_FRAME_INTERVALS_PER_FLIGHT}): ")
    if widened_se > se:
        return (f"{said}e's 95 % interval widened from ±{Z95 * se:.2g} to ±{Z95 * widened_se:.2g} for the error so "
                f"sparse a sampling makes")
    return f"{said}e's 95 % interval (±{Z95 * se:.2g}) not widened: such flights' fits covered their errors"


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

    Returns
    -------
    str or None
        "impact <n>: <the first flight's problem> (<what to do>)" for the flight before it, else the one after.
    """
    problems = _impact_problems(impacts_row, frames_before, frames_after, frame_interval_s)
    if not problems:
        return None
    diagnosis, advice = next(iter(problems.values()))
    return f"impact {int(impacts_row['impact'])}: {diagnosis} ({advice})"


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
    impacts, flights = analysis.impacts, analysis.flights
    touchdown = impacts["t_touchdown_s"].to_numpy()
    liftoff = impacts["t_liftoff_s"].to_numpy()
    numbers = impacts["impact"].to_numpy(int)
    flight_rows = {int(number): row for row, number in enumerate(flights["flight"])}
    apex = flights["t_apex_s"].to_numpy()
    start, end = flights["t_start_s"].to_numpy(), flights["t_end_s"].to_numpy()
    bounce = bool(analysis.summary.get("first_flight_is_a_bounce"))
    before, after = np.full(numbers.size, np.nan), np.full(numbers.size, np.nan)
    for i, number in enumerate(numbers):
        previous, following = (np.flatnonzero(numbers == number + step) for step in (-1, 1))
        if number - 1 in flight_rows:  # (NaN: a flight not fitted, seen in too few frames, join_later_sequence)
            row = flight_rows[number - 1]
            if previous.size and np.isfinite(liftoff[previous[0]]):  # a bounce: from the lift-off of the impact before
                began = liftoff[previous[0]]
            else:  # the first flight of a sequence: the drop from its apex (a bounce rising into it: from its start)
                began = min(apex[row], start[row]) if (bounce or i > 0) else apex[row]
            before[i] = (touchdown[i] if np.isfinite(touchdown[i]) else end[row]) - began
        if number in flight_rows:
            row = flight_rows[number]
            lift = liftoff[i] if np.isfinite(liftoff[i]) else start[row]
            ended = touchdown[following[0]] if following.size and np.isfinite(touchdown[following[0]]) else \
                lift + 2.0 * (apex[row] - lift)  # the last: twice its rise to the apex
            after[i] = ended - lift
    return before / frame_interval_s, after / frame_interval_s


#: Relative tolerance on the duration of a hidden flight, between those of the flights on either side of it: with
#: e ≤ 0.9 two hidden flights (1.9 times the first) outlast the one before (at most 1.11 times) by far more.
HIDDEN_FLIGHT_TOLERANCE = 0.1
#: How the analysis says its sequence ends before a flight with too few samples (``flight`` is its number).
_SPARSE_FLIGHT_CUT = re.compile(r"flight (?P<flight>\d+) has fewer than \d+ samples(?: once its outliers of the flight "
                                r"fit are left out)?: the bounce sequence ends before it")


def sparse_flight_cut(analysis):
    """The number of the flight, too sparsely sampled to fit, before which the analysed sequence ends (from its
    notes), or None."""
    for note in analysis.summary.get("notes") or []:
        match = _SPARSE_FLIGHT_CUT.fullmatch(note)
        if match:
            return int(match["flight"])
    return None


def join_later_sequence(analysis, later, hidden_flight, seen_s):
    """An analysis whose sequence ended before flight ``hidden_flight`` (seen in too few frames: a hand or a
    passer-by before the ball; ``seen_s``: the times, s, of the samples after the first sequence) joined with
    ``later``, the analysis of the samples
    after the first sequence, whose first fitted flight follows the hidden one: the impacts on either side of the hidden flight are not measured, the ones
    after it are (renumbered from the release), as if the flight had been filmed too poorly (see
    :func:`select_resolved_impacts`). The covariances are joined block-diagonally (the two sequences share no
    fitted parameter); the summary stays the first sequence's, with a note.

    Returns
    -------
    dropfit.analysis.BounceAnalysis or None
        None when the time between the two sequences does not hold one flight (as long as the flight after it, at
        most as long as the one before): the numbering of the later impacts would be a guess.
    """
    # the gap between the sequences must hold one flight: as long as the one after it at least, and at most as
    # long as the one before it (a ball's flights shorten), within HIDDEN_FLIGHT_TOLERANCE
    last, first = analysis.flights.iloc[-1], later.flights.iloc[0]
    before_s = 2.0 * (last["t_end_s"] - last["t_apex_s"])
    after_s = 2.0 * (later.impacts["t_touchdown_s"].iloc[0] - first["t_apex_s"])
    gap_s = first["t_apex_s"] - 0.5 * after_s - last["t_end_s"]
    if not (1.0 - HIDDEN_FLIGHT_TOLERANCE) * after_s <= gap_s <= (1.0 + HIDDEN_FLIGHT_TOLERANCE) * before_s:
        return None
    shift = hidden_flight + 1 - int(first["flight"])  # later's first fitted flight follows the hidden one
    # the frames that saw the hidden flight: in the middle 80 % of it, clear of both contacts
    seen_s = np.asarray(seen_s, dtype=float)
    hidden_samples = int(np.count_nonzero((seen_s > last["t_end_s"] + 0.1 * gap_s)
                                          & (seen_s < last["t_end_s"] + 0.9 * gap_s)))
    first_later = int(later.impacts["impact"].iloc[0])
    impacts = later.impacts.copy()
    impacts["impact"] = impacts["impact"] + shift
    flights = later.flights.copy()
    flights["flight"] = flights["flight"] + shift
    # the two impacts beside the hidden flight: rows with no measurement, the reason in their note
    hidden = pd.DataFrame({"impact": [hidden_flight, hidden_flight + 1], "in_fit": False, "contact_resolvable": False,
                           "n_samples_before": [float(analysis.flights["n_samples"].iloc[-1]), hidden_samples],
                           "n_samples_after": [hidden_samples, float(later.flights["n_samples"].iloc[0])],
                           "note": ""})  # the reason: select_resolved_impacts
    joined_impacts = pd.concat([analysis.impacts, hidden, impacts], ignore_index=True)
    joined_flights = pd.concat([analysis.flights, flights], ignore_index=True)
    n1, n2 = len(analysis.impacts) + 2, len(impacts)
    n0, n = n1 - 2, n1 + n2
    e_covariance = np.zeros((n, n))
    e_covariance[:n0, :n0], e_covariance[n1:, n1:] = analysis.e_covariance, later.e_covariance
    contact = np.zeros((2 * n, 2 * n))
    rows = np.r_[0:n0, n: n + n0], np.r_[n1:n, n + n1: 2 * n]
    contact[np.ix_(rows[0], rows[0])] = analysis.e_contact_covariance
    contact[np.ix_(rows[1], rows[1])] = later.e_contact_covariance
    note = (f"flight {hidden_flight} is seen in {hidden_samples} frames, too few to fit (hidden or lost): impacts "
            f"{hidden_flight} and {hidden_flight + 1} beside it are not measured; impacts {first_later + shift}-"
            f"{int(impacts['impact'].iloc[-1])} after it are measured from the flights that follow")
    notes = [item for item in analysis.summary.get("notes") or [] if not _SPARSE_FLIGHT_CUT.fullmatch(item)]
    summary = dict(analysis.summary, n_impacts=n1 + n2, notes=notes + [note],
                   later_sequence={"first_impact": first_later + shift, "hidden_flight": hidden_flight,
                                   "contact_height_m": later.summary.get("contact_height_m"),
                                   "notes": list(later.summary.get("notes") or [])})
    return dataclasses.replace(analysis, impacts=joined_impacts, flights=joined_flights, e_covariance=e_covariance,
                               e_contact_covariance=contact,
                               e_drag_covariance=np.concatenate([analysis.e_drag_covariance, np.zeros(2),
                                                                 later.e_drag_covariance]),
                               summary=summary)


def clean_share(clean_times_s, frame_interval_s):
    """The share of a clip's frames, from its first clean one to its last, that are clean (``clean_times_s``: the
    clean frames' times, s): the measure the sweep's limit :data:`MIN_CLEAN_FRACTION` was set on. Where it is
    met, a flight seen partly behind a hand or merged with a shadow is judged by its clean frames alone."""
    times = np.asarray(clean_times_s, dtype=float)
    if times.size < 2:
        return 0.0
    return min(times.size / ((times.max() - times.min()) / frame_interval_s + 1.0), 1.0)


def select_resolved_impacts(analysis, source, frame_interval_s, unclean=None, clean_times_s=None):
    """Judge each impact by its own two flights: an impact whose flight before or after is too poorly filmed
    (:func:`flight_violation`: too few frame intervals, too few clean frames, too small a part of its frames clean)
    keeps its row with no e and the reason; the others keep their e, whatever the flights elsewhere. An impact
    measured from a flight of fewer than :data:`DENSE_FRAME_INTERVALS_PER_FLIGHT` frame intervals (sparsely filmed,
    from :data:`MIN_FRAME_INTERVALS_PER_FLIGHT` up) has its e's standard error, interval and variance widened by
    :func:`sparse_flight_e_se`, and a note that says by how much.

    Impact n needs flights n − 1 and n: a flight too poorly filmed costs the impacts on both its sides (e, the
    flight-time ratio and the contact time of both; the impact speed of the one after it, the rebound speed of
    the one before it), and only those: an early impact is never lost because of a later flight, nor
    the impacts after an occluded flight because of it. A clip at 30 frames/s often films the drop's fast fall in
    too few clean frames (a white ball blurred into the wall, a hand in view) and the bounces after it well; a
    football at 20 frames/s has long early flights and a short fourth one.

    Parameters
    ----------
    analysis : dropfit.analysis.BounceAnalysis
        The analysis of a video's trajectory.
    source : str or pathlib.Path
        The recording, named in the message.
    frame_interval_s : float
        Time between frames in s.
    unclean : str, optional
        What the frames not measured cleanly were (:func:`unclean_frames`), told when no impact is measured
        for want of clean frames.
    clean_times_s : array_like, optional
        Times (s) of the frames measured cleanly: where the clip's clean share (:func:`clean_share`) meets
        :data:`MIN_CLEAN_FRACTION`, no flight is judged by its own share; without them, every flight is.

    Returns
    -------
    dropfit.analysis.BounceAnalysis
        The same analysis, every impact and flight kept; an impact not measured has NaN in the columns its
        unusable flights decide (:data:`UNRESOLVED_IMPACT_COLUMNS`, :data:`UNRESOLVED_AFTER_COLUMNS`, with their
        se and interval), ``in_fit`` false, its e's rows and columns of the covariances zero, and the reason in
        its ``note`` (the impacts table's reason for leaving an impact out, shared with e > 1).
        ``summary["impacts_unmeasured"]`` counts them, ``summary["impacts_sparsely_filmed"]`` the impacts measured
        from a sparsely filmed flight.

    Raises
    ------
    InputError
        When no impact is measured: nothing is left to report; the message gives each impact's reason, and the
        analysis's notes on the flights it could not fit (before its first flight, after the sequence's end).
    """
    spans = flight_spans(analysis, frame_interval_s)
    share_judged = clean_times_s is None or clean_share(clean_times_s, frame_interval_s) < MIN_CLEAN_FRACTION
    problems = [_impact_problems(row, before, after, frame_interval_s, share_judged)
                for (_, row), before, after in zip(analysis.impacts.iterrows(), *spans)]
    numbers = analysis.impacts["impact"].astype(int).tolist()
    if problems and all(problems):
        said = "; ".join(f"impact {number}: " + " and ".join(diagnosis for diagnosis, _ in found.values())
                         for number, found in zip(numbers, problems))
        # each kind of advice once, as the first impact needs it (the least a change must do to measure one)
        kinds = {}
        for found in problems:
            for diagnosis, advice_ in found.values():
                kinds.setdefault(advice_.split(" ", 3)[-1] if advice_.startswith("film at") else advice_, advice_)
        advice = list(kinds.values())
        tracking = TRACKER_HELP in advice or any(
            diagnosis.startswith("clean frames") for found in problems for diagnosis, _ in found.values())
        advice = [item for item in advice if item != TRACKER_HELP]
        why = f"; the frames not clean: {unclean}" if unclean and tracking else ""
        help_ = f"; {TRACKER_HELP}" if tracking else ""
        # the impacts the analysis found no flights for: before the first fitted flight, after the sequence's end
        cuts = [note for note in analysis.summary.get("notes") or []
                if "the fit starts with flight" in note or "sequence ends before" in note]
        said += "".join(f"; {note}" for note in cuts)
        raise InputError(f"{shown_path(source)}: not analysable: no impact can be measured: {said}"
                         f"{'; ' + '; '.join(advice) if advice else ''}{why}{help_}")
    impacts = analysis.impacts.copy()
    e_covariance = analysis.e_covariance.copy()
    e_contact_covariance = analysis.e_contact_covariance.copy()
    e_drag_covariance = analysis.e_drag_covariance.copy()
    n = len(impacts)
    notes = impacts["note"].astype(object).where(impacts["note"].notna(), "").tolist() if "note" in impacts \
        else [""] * n
    for i, found in enumerate(problems):
        if not found:
            continue
        names = dict.fromkeys((UNRESOLVED_IMPACT_COLUMNS if "before" in found else ())
                              + (UNRESOLVED_AFTER_COLUMNS if "after" in found else ()))
        for name in names:
            for column in (name, se_column_name(name), se_column_name(name, "ci95_low"),
                           se_column_name(name, "ci95_high")):
                if column in impacts:
                    impacts.loc[i, column] = np.nan
        impacts.loc[i, "contact_resolvable"] = False
        impacts.loc[i, "in_fit"] = False
        reason = "; ".join(f"{diagnosis} ({advice})" if advice != TRACKER_HELP else diagnosis
                           for diagnosis, advice in found.values()) + ": its e is not given"
        notes[i] = "; ".join(filter(None, (reason, notes[i] if notes[i] and "e > 1" not in notes[i] else "")))
        for matrix, rows in ((e_covariance, [i]), (e_contact_covariance, [i, n + i])):
            matrix[rows, :] = 0.0
            matrix[:, rows] = 0.0
        e_drag_covariance[i] = 0.0
    sparse = 0
    if "e" in impacts:
        e_se = impacts[se_column_name("e")].to_numpy(dtype=float).copy()
        for i, (found, before, after) in enumerate(zip(problems, *spans)):
            # measured from a flight sparsely filmed: e's interval covers the error that sampling makes
            if found or not sparse_flights(before, after):
                continue
            drop_before = i == 0 and int(numbers[0]) == 1 and not analysis.summary.get("first_flight_is_a_bounce")
            extra = sparse_flight_e_se(impacts["e"].iloc[i], before, after, drop_before)
            widened = math.hypot(e_se[i], extra)
            notes[i] = "; ".join(filter(None, (_sparse_note(before, after, frame_interval_s, e_se[i], widened),
                                               notes[i])))
            e_se[i] = widened
            e_covariance[i, i] += extra ** 2
            e_contact_covariance[i, i] += extra ** 2
            sparse += 1
        add_with_interval(impacts, "e", impacts["e"].to_numpy(dtype=float), e_se)
    impacts["note"] = notes
    summary = dict(analysis.summary, impacts_unmeasured=int(sum(bool(found) for found in problems)),
                   impacts_sparsely_filmed=sparse)
    return dataclasses.replace(analysis, impacts=impacts, e_covariance=e_covariance,
                               e_contact_covariance=e_contact_covariance, e_drag_covariance=e_drag_covariance,
                               summary=summary)
