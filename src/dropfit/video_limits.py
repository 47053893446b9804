"""Where video analysis fails: limits, measured on the recording itself, below which e would be wrong.

``benchmarks/video_failure_sweep.py`` renders seeded synthetic clips and sweeps frame rate, sensor
noise, motion blur and ball size one at a time around a good 240 fps baseline; its table and chart
(``benchmarks/video_failure_sweep.csv``, ``.png``) are the evidence for every limit below. Over the
range where the tracker finds the ball, e stays within 3 × 10⁻⁴ of the generator's and the only
way to a wrong e is a flight sampled by too few clean frames (a low frame rate; blurred frames
near the impacts count as clean since the tracker measures streaks as ``blurred``). The limits therefore use only what the tracker and the
analysis measure, never the ground truth:

* the tracked ball radius (px) and the fraction of frames measured cleanly, checked on the tracked
  table by :func:`check_recording`: below them the whole recording is refused;
* the clean frames in each flight, checked per impact by :func:`select_resolved_impacts`: the
  impacts from the first under-sampled flight on are dropped with the reason stated, and the
  recording is refused only when its first impact is among them (later bounces are shorter, so
  dropping them first loses the least).

The centre noise relative to the travel (also measured, for the sweep's table) sets no limit: it
stayed under 5 × 10⁻³ wherever the tracker found the ball, was 1 × 10⁻⁴ in the clips whose e was
wrong, and e's standard error already carries it.

A refusal is an :class:`dropfit.errors.InputError` with one line,
``<file>: not analysable: <limit>: <measured value> < <limit value>``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .analysis import estimate_noise
from .errors import InputError
from .tracking import CLEAN_QUALITIES, QUALITY_DUPLICATE

#: Smallest tracked ball radius, px. Sweep: a ball drawn with radius 1 px is never found and one of
#: 1.25 px in no clean frame; drawn with 1.5–2 px it is tracked as 2.2–2.3 px (the edge threshold
#: widens it) and e is still right. No ball was tracked smaller, so a smaller blob is not a ball.
MIN_BALL_RADIUS_PX = 2.0
#: Smallest fraction of the frames from the first clean one to the last that are clean. Sweep: e
#: right with 34 % clean (ball radius 1.5 px) and 46 % (noise σ = 25 grey levels); at σ ≥ 27.5 at
#: most 3 % of the frames are clean, or fewer than 10 in all.
MIN_CLEAN_FRACTION = 0.30
#: Fewest clean frames in each of the two flights around an impact. Sweep: with 6–16 clean frames
#: before impact 1 (30–50 frames/s, or 60 with long exposures) e₁ was off by 5–8 × 10⁻³ (2–4
#: standard errors) in 3 of 15 clips (in the one examined, the information criterion had taken a
#: drag term that is not there); with ≥ 20 every clip's e₁ was within 3 × 10⁻⁴. Re-run with blurred
#: frames measured: 5 clean frames (15 frames/s) gave e₁ off by 3 × 10⁻³ (19 standard errors) in 1
#: of 2 clips, 7–17 frames (20–40 frames/s) within 8 × 10⁻⁴ and 2.2 standard errors in 9 clips, and
#: ≥ 20 frames (50 frames/s and up, 60 with any exposure) within 2.6 × 10⁻⁴ (ball radius ≥ 2 px).
MIN_CLEAN_FRAMES_PER_FLIGHT = 20


def recording_measures(table):
    """What the tracked table says about a recording's fitness for analysis.

    Parameters
    ----------
    table : pandas.DataFrame
        As returned by :func:`dropfit.tracking.track_video` (``y_px``, ``radius_px``, ``quality``).

    Returns
    -------
    dict
        ``ball_radius_px`` (median tracked radius of the clean frames, ``ok`` and ``blurred``, px),
        ``clean_fraction`` (clean frames over the frames, duplicates left out, from the first clean frame to the last:
        a hand holding the ball before it or an empty scene after it does not count against the
        recording), ``centre_noise_px`` (robust noise of the clean frames' centre rows, px),
        ``travel_px`` (range of those rows, px) and ``noise_to_travel`` (their ratio). Radius,
        noise and travel are NaN when no frame is clean.
    """
    kept = table[table["quality"] != QUALITY_DUPLICATE]
    is_clean = kept["quality"].isin(CLEAN_QUALITIES).to_numpy()
    clean = kept[is_clean]
    rows = clean["y_px"].to_numpy(float)
    span = np.flatnonzero(is_clean)
    fraction = rows.size / (span[-1] - span[0] + 1) if span.size else 0.0
    if rows.size == 0:
        return dict(ball_radius_px=np.nan, clean_fraction=fraction, centre_noise_px=np.nan, travel_px=np.nan,
                    noise_to_travel=np.nan)
    noise = estimate_noise(rows)
    travel = float(np.ptp(rows))
    return dict(ball_radius_px=float(np.median(clean["radius_px"])), clean_fraction=fraction,
                centre_noise_px=noise, travel_px=travel, noise_to_travel=noise / travel if travel > 0 else np.inf)


def recording_violations(measures):
    """The recording-wide limits that ``measures`` (from :func:`recording_measures`) break.

    Returns
    -------
    list of str
        One phrase per broken limit, "<limit>: <measured> < <limit value>"; empty if none.
    """
    violations = []
    if not measures["clean_fraction"] >= MIN_CLEAN_FRACTION:
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
    violations = recording_violations(recording_measures(table))
    if violations:
        raise InputError(f"{source}: not analysable: {'; '.join(violations)}")


def flight_violation(impacts_row):
    """Why an impact (a row of the impacts table) is unresolved, or None if both flights are sampled enough."""
    before, after = int(impacts_row["n_samples_before"]), int(impacts_row["n_samples_after"])
    if min(before, after) >= MIN_CLEAN_FRAMES_PER_FLIGHT:
        return None
    side = "before" if before < after else "after"
    return (f"impact {int(impacts_row['impact'])}: clean frames in the flight {side} it: "
            f"{min(before, after)} < {MIN_CLEAN_FRAMES_PER_FLIGHT}")


def select_resolved_impacts(analysis, source):
    """Keep the impacts whose two flights both have enough clean frames, up to the first that does not.

    Parameters
    ----------
    analysis : dropfit.analysis.BounceAnalysis
        The analysis of a video's trajectory.
    source : str or pathlib.Path
        The recording, named in the message.

    Returns
    -------
    dropfit.analysis.BounceAnalysis
        The same analysis with the impacts (and their flights, e covariance and ``n_impacts``) from
        the first unresolved impact on removed; ``summary["impacts_dropped"]`` gives the reason
        (empty when all impacts are kept).

    Raises
    ------
    InputError
        When the first impact is unresolved: nothing is left to report.
    """
    reasons = [flight_violation(row) for _, row in analysis.impacts.iterrows()]
    kept = next((i for i, reason in enumerate(reasons) if reason is not None), len(reasons))
    if kept == 0:
        raise InputError(f"{source}: not analysable: {reasons[0]}")
    summary = dict(analysis.summary, n_impacts=kept,
                   impacts_dropped=[] if kept == len(reasons) else
                   [f"{reasons[kept]}; this and the {len(reasons) - kept - 1} later impacts dropped"])
    return dataclasses.replace(analysis, impacts=analysis.impacts.iloc[:kept].reset_index(drop=True),
                               flights=analysis.flights.iloc[: kept + 1].reset_index(drop=True),
                               e_covariance=analysis.e_covariance[:kept, :kept], summary=summary)
