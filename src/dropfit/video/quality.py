"""The tracked table's quality flags (one per frame, column ``quality``; their meaning is in
:mod:`dropfit.video.detect`), which rows are usable for a trajectory, and the tracked centre's error
correlation.

Apart from the tracker, so that what reads a tracked table or analyses a video's trajectory
(:mod:`dropfit.video.limits`, :mod:`dropfit.pipeline`) does not load OpenCV or PyAV.
"""

import math

import numpy as np

from ..numerics import robust_sigma

QUALITY_OK = "ok"

QUALITY_PARTIAL = "partial"

QUALITY_OCCLUDED = "occluded"

QUALITY_LOST = "lost"

QUALITY_DUPLICATE = "duplicate"

QUALITY_BLURRED = "blurred"

QUALITY_SHADED = "shaded"

#: A ball measured alone whose centre the ballistic track through its neighbours does not support (a tracking
#: jump to a hand, a shadow or a speck beside the ball): left out of every fit (:func:`off_track_rows`).
QUALITY_OFF_TRACK = "off_track"

#: Frames measured cleanly: a lone ball whose centre is its coverage-weighted centroid.
CLEAN_QUALITIES = (QUALITY_OK, QUALITY_BLURRED)

#: Lag-1 autocorrelation of the tracked centre's errors between successive frames (dimensionless): the
#: pixel grid and the codec's 8 × 8 blocks bias neighbouring frames alike. Measured against the
#: renderer's truth on seeded synthetic clips (120 and 240 fps, ball radius 5–12 px, noise σ 2, MJPEG
#: quality 90): 0.08–0.24 per clip, about 0.17 on average (tests/test_tracking.py). Taken as 0.2: with
#: independent errors assumed, the intervals of 200 small clips covered the truth only ~90 %.
TRACKED_CENTRE_CORRELATION = 0.2

#: Largest error of a tracked centre that changes with the ball's speed (px, at its fastest) in a clip coded with
#: motion prediction (H.264, MPEG-4 …), which the flights' curvature takes for drag and which moves the apex heights
#: at any k: a standard error that widens a held k's and enters every quantity as two systematic parts, its v|v| and
#: v² shapes (dropfit.analysis.uncertainty). Measured against phonesim's truth: the yellow ball at 120 fps read
#: 0.3-0.45 px higher falling than rising near the floor in H.264 (crf 18) and none of it encoded losslessly; the
#: red ball, blurred over half a frame interval at 30 fps, 0.15-0.25 px high in its fast frames losslessly, 0.3-0.5 px
#: in H.264. Taken as twice the largest of these: neither its shape nor how it grows at the fastest speeds, by the
#: floor, was measured (at 0.5 px the yellow ball's seed 3 still read e 2.1 se high).
SPEED_DEPENDENT_CENTRE_ERROR_PX = 1.0

#: Codecs that store every frame by itself (and Photron's ``raw`` frames): no motion prediction errs with the ball's
#: speed, only its motion blur does.
INTRA_FRAME_CODECS = ("raw", "rawvideo", "mjpeg", "ljpeg", "jpeg2000", "png", "tiff", "bmp", "ffv1", "huffyuv",
                      "ffvhuff", "utvideo", "magicyuv", "prores", "dnxhd", "qtrle", "v210", "r210")

#: ... in such a clip, the speed-dependent error as a fraction of the ball's motion blur at its fastest. Measured:
#: phonesim's red ball, blurred over half its 72 px step at 30 fps in MJPEG (36 px, measured 36.2 px by the
#: tracker's ``blur_px``), read 0.38 px high in its fastest falling frames (1 % of the blur); taken as twice that.
MOTION_BLUR_CENTRE_ERROR_FRACTION = 0.02


def speed_dependent_centre_error_px(codec, rows_px, time_s, blur_px=None):
    """The error of a tracked centre that grows with the ball's speed, px at its fastest.

    Parameters
    ----------
    codec : str or None
        The clip's codec (FFmpeg's name; ``raw`` for a Photron clip; None: not known, taken as predicted).
    rows_px : numpy.ndarray
        The ball's tracked rows (px; NaN where it was not measured).
    time_s : numpy.ndarray
        Their times (s).
    blur_px : numpy.ndarray, optional
        The tracker's measured motion blur of each row (px; NaN where not measured); None: not measured, taken as
        a whole step (an exposure as long as the frame interval).

    Returns
    -------
    float
        :data:`SPEED_DEPENDENT_CENTRE_ERROR_PX` in a clip coded with motion prediction; else
        :data:`MOTION_BLUR_CENTRE_ERROR_FRACTION` of the blur at the largest step between successive measured
        frames (px; a step over a gap scaled to the typical frame interval): that step times the median ratio of
        blur to step over the steps at least half as large, their blur less a still ball's anisotropy (the median
        over the steps under a quarter as large).
    """
    if codec not in INTRA_FRAME_CODECS:
        return SPEED_DEPENDENT_CENTRE_ERROR_PX
    rows, time = np.asarray(rows_px, dtype=float), np.asarray(time_s, dtype=float)
    blur = np.full(rows.shape, np.nan) if blur_px is None else np.asarray(blur_px, dtype=float)
    measured = np.isfinite(rows) & np.isfinite(time)
    rows, time, blur = rows[measured], time[measured], blur[measured]
    intervals, moves = np.diff(time), np.abs(np.diff(rows))
    later = intervals > 0
    if not later.any():
        return 0.0
    steps = moves / np.where(later, intervals, np.inf) * np.median(intervals[later])  # px a frame interval
    largest = float(np.max(steps))
    fast = later & (steps >= 0.5 * largest) & (steps > 0)
    pair_blur = 0.5 * (blur[:-1] + blur[1:])  # the blur of the two frames of each step
    # a still ball's coverage is not quite round either (noise, shading, the pixel grid): its anisotropy adds to the
    # blur's as a random vector would, in blur⁴ (the moments' difference goes as the square of the length)
    slow = later & (steps < 0.25 * largest)
    still = float(np.nanmedian(pair_blur[slow])) if np.isfinite(pair_blur[slow]).any() else 0.0
    ratios = np.maximum(pair_blur[fast] ** 4 - still ** 4, 0.0) ** 0.25 / steps[fast]
    ratios = ratios[np.isfinite(ratios)]
    exposure_fraction = min(float(np.median(ratios)), 1.0) if ratios.size else 1.0
    return MOTION_BLUR_CENTRE_ERROR_FRACTION * exposure_fraction * largest

#: A partial frame enters the trajectory when its circle fit's centre standard error and its RMS
#: residual are at most these, px.
MAX_PARTIAL_CENTRE_SE_PX = 0.1
MAX_PARTIAL_FIT_RMS_PX = 0.5
#: ... and when its radius is within this of the clean frames' (a free-radius fit to a short arc can
#: settle on a wrong circle with small residuals), px.
MAX_PARTIAL_RADIUS_MISMATCH_PX = 0.5


def usable_rows(table, radius_px=None):
    """Rows whose centre is good for a trajectory: ``ok``, ``blurred``, and ``partial`` or ``shaded`` with a
    good circle fit.

    Parameters
    ----------
    table : pandas.DataFrame
        As returned by :func:`dropfit.video.track.track_frames` or :func:`dropfit.video.track.track_video`.
    radius_px : float, optional
        The ball's radius, px, when known; by default the median radius of the ``ok`` rows.

    Returns
    -------
    numpy.ndarray
        Boolean mask, one per row: ``ok``, ``blurred``, or ``partial`` or ``shaded`` with ``centre_se_px`` ≤
        ``MAX_PARTIAL_CENTRE_SE_PX``, ``fit_rms_px`` ≤ ``MAX_PARTIAL_FIT_RMS_PX`` and a radius
        within ``MAX_PARTIAL_RADIUS_MISMATCH_PX`` of ``radius_px`` (of the median ``shaded`` row's for a
        ``shaded`` row). Without a radius (no ``ok`` row and none given) no ``partial`` row is usable.
    """
    quality = table["quality"].to_numpy()
    radii = table["radius_px"].to_numpy()
    ok, shaded = quality == QUALITY_OK, quality == QUALITY_SHADED
    if radius_px is None:
        radius_px = float(np.median(radii[ok])) if ok.any() else math.nan
    # a shaded ball's lit side has an edge of its own: its radius is checked against the shaded balls'
    reference = np.where(shaded, float(np.median(radii[shaded])) if shaded.any() else math.nan, radius_px)
    good_fit = ((table["centre_se_px"].to_numpy() <= MAX_PARTIAL_CENTRE_SE_PX)
                & (table["fit_rms_px"].to_numpy() <= MAX_PARTIAL_FIT_RMS_PX)
                & (np.abs(radii - reference) <= MAX_PARTIAL_RADIUS_MISMATCH_PX))
    return np.isin(quality, CLEAN_QUALITIES) | ((quality == QUALITY_PARTIAL) | shaded) & good_fit


#: Neighbours of a position on each side that its ballistic track is fitted through (a parabola in time for x and
#: for y, three parameters each: four points leave one degree of freedom to judge the fit itself).
TRACK_NEIGHBOURS = 4
#: The neighbours lie within this many typical frame intervals of the position judged: a parabola extrapolated
#: farther errs by more than its centres do.
TRACK_REACH_FRAMES = 8
#: A position is off its track when it is farther from every valid fit's prediction than this many times the
#: centre error (per axis, px) ...
OFF_TRACK_SIGMAS = 6.0
#: ... and than this many ball radii: a frame taken while the ball is in contact lies a few px off both flights'
#: parabolas (the ball stops and flattens; at 3 m/s a 4 ms contact is 12 mm), a tracking jump is radii away.
OFF_TRACK_MIN_RADII = 0.5
#: A fit judges a position only when its own points lie within this fraction of the tolerance of it: four points
#: straddling a low bounce (hops of two or three frames at the end of a clip) fit a parabola nearly as well as
#: a flight and extrapolate off it.
OWN_FIT_FRACTION = 0.5
#: Passes of the gate, each without the positions found off track by the last (a wrong position spoils the fits
#: of its neighbours, which then judge nothing).
OFF_TRACK_PASSES = 3


def _neighbour_sets(order, k):
    """The neighbour sets of position ``order[k]`` (indices): (before, after, two each side), each None where there
    are too few."""
    before, after = order[max(k - TRACK_NEIGHBOURS, 0):k], order[k + 1:k + 1 + TRACK_NEIGHBOURS]
    centred = np.concatenate([order[max(k - 2, 0):k], order[k + 1:k + 3]])
    return [s if s.size == TRACK_NEIGHBOURS else None for s in (before, after, centred)]


def _free_acceleration(time_s, x_px, y_px, neighbours):
    """A free parabola in time through ``neighbours``: its acceleration x, y (px/s²), largest residual and the
    vertical travel over the neighbours (px)."""
    t = time_s[neighbours] - time_s[neighbours].mean()
    design = np.stack([np.ones_like(t), t, t * t], axis=1)
    values = np.stack([x_px[neighbours], y_px[neighbours]], axis=1)
    coefficients, *_ = np.linalg.lstsq(design, values, rcond=None)
    residual = float(np.max(np.hypot(*(values - design @ coefficients).T)))
    return 2.0 * coefficients[2, 0], 2.0 * coefficients[2, 1], residual, float(np.ptp(y_px[neighbours]))


def clip_acceleration(free, min_travel_px):
    """The clip's acceleration in the image (x, y px/s²) from free parabolas (rows: x, y acceleration, largest
    residual and vertical travel, px): the median of those accelerating downwards that travel at least
    ``min_travel_px`` (a ball at rest, rolling or held does not) and fit their points at least as well as the median
    one of those (a set across a bounce turns upwards, or fits its points worse); None without one."""
    free = np.asarray(free, dtype=float).reshape(-1, 4)
    falling = free[(free[:, 1] > 0) & (free[:, 3] >= min_travel_px)]
    if not falling.size:
        return None
    tight = falling[falling[:, 2] <= np.median(falling[:, 2])]
    return np.median(tight[:, :2], axis=0)


def _predicted(time_s, x_px, y_px, neighbours, at_s, acceleration):
    """The ballistic track through ``neighbours`` with the clip's ``acceleration`` (x, y px/s²) at ``at_s``:
    (predicted x, y px, the fit's largest own residual px)."""
    t = time_s[neighbours] - at_s
    design = np.stack([np.ones_like(t), t], axis=1)
    values = np.stack([x_px[neighbours], y_px[neighbours]], axis=1) - 0.5 * np.outer(t * t, acceleration)
    coefficients, *_ = np.linalg.lstsq(design, values, rcond=None)
    residual = float(np.max(np.hypot(*(values - design @ coefficients).T)))
    return coefficients[0, 0], coefficients[0, 1], residual


def _track_predictions(time_s, x_px, y_px, order, reach_s, min_travel_px):
    """For each position of ``order``: its offsets (dx, dy px) from the predictions of its three neighbour fits
    (before, after, centred) and each fit's own largest residual (px), NaN where a fit has too few neighbours
    within ``reach_s`` or its neighbours travel less than ``min_travel_px`` vertically (a ball at rest, rolling or
    held is not on a ballistic track); arrays (n, 3, 2) and (n, 3). The fits share the clip's acceleration
    (:func:`clip_acceleration` of the free parabolas through the neighbour sets), so that a fit across a bounce
    does not fit its own points."""
    sets = [[neighbours if neighbours is not None and np.max(np.abs(time_s[neighbours] - time_s[index])) <= reach_s
             else None for neighbours in _neighbour_sets(order, k)] for k, index in enumerate(order)]
    offsets = np.full((order.size, 3, 2), np.nan)
    residuals = np.full((order.size, 3), np.nan)
    free = [_free_acceleration(time_s, x_px, y_px, neighbours)
            for fits in sets for neighbours in fits if neighbours is not None]
    acceleration = clip_acceleration(free, min_travel_px)
    if acceleration is None:
        return offsets, residuals
    for k, (index, fits) in enumerate(zip(order, sets)):
        for j, neighbours in enumerate(fits):
            if neighbours is not None and np.ptp(y_px[neighbours]) >= min_travel_px:
                x, y, residuals[k, j] = _predicted(time_s, x_px, y_px, neighbours, time_s[index], acceleration)
                offsets[k, j] = x_px[index] - x, y_px[index] - y
    return offsets, residuals


def sideways_centre_error_px(x_px, frames):
    """The centre error of tracked positions, px: from the third differences of their columns ``x_px`` over runs of
    four evenly spaced ``frames`` (variance 20 σ² where the ball moves sideways at a constant or slowly changing
    speed: through its bounces too, which turn its vertical motion only); a robust σ, 0 with no such run."""
    x, frames = np.asarray(x_px, dtype=float), np.asarray(frames)
    if x.size < 4:
        return 0.0
    steps = np.diff(frames)
    even = (steps[:-2] == steps[1:-1]) & (steps[1:-1] == steps[2:])
    third = np.diff(x, 3)[even]
    return robust_sigma(third) / math.sqrt(20.0) if third.size else 0.0


def off_track_rows(time_s, x_px, y_px, measured, radius_px):
    """Positions that the ball's ballistic track through their neighbours does not support.

    For each measured position, ballistic tracks (x and y in time with the clip's constant acceleration, as in
    flight: the median of free parabolas') are fitted through ``TRACK_NEIGHBOURS`` measured neighbours before it, as
    many after it, and two on each side, all within ``TRACK_REACH_FRAMES`` typical frame intervals and travelling a ball radius or more vertically. A fit is valid
    when its own points lie within ``OWN_FIT_FRACTION`` of the tolerance of it: a fit across a bounce, or through another wrong position,
    judges nothing, nor does a ball at rest, rolling or held. The tolerance is
    ``OFF_TRACK_SIGMAS`` times the centre error (:func:`sideways_centre_error_px`), at least ``OFF_TRACK_MIN_RADII``
    radii.

    A position is off track when no valid fit predicts it within the tolerance and either two fits or the centred
    one are valid (the flight passes by it), or it lies more than twice the tolerance aside (in x) of every valid
    fit (a bounce turns the ball's vertical motion, hardly its sideways one: a position just after a bounce
    judged by the flight before it alone is off in y, not in x). Repeated ``OFF_TRACK_PASSES`` times without
    the positions found off track.

    Parameters
    ----------
    time_s : numpy.ndarray
        The frames' times, s.
    x_px, y_px : numpy.ndarray
        Centres, px (NaN where not measured).
    measured : numpy.ndarray
        Boolean, the positions to judge (those meant for a trajectory, :func:`usable_rows`).
    radius_px : float
        The ball's radius, px.

    Returns
    -------
    (numpy.ndarray, float)
        Boolean mask of the positions off track, and the tolerance of the last pass, px (NaN when nothing could be
        judged).
    """
    time_s, x_px, y_px = (np.asarray(a, dtype=float) for a in (time_s, x_px, y_px))
    measured = np.asarray(measured, dtype=bool) & np.isfinite(x_px) & np.isfinite(y_px) & np.isfinite(time_s)
    off = np.zeros(time_s.shape, dtype=bool)
    steps = np.diff(time_s[np.isfinite(time_s)])
    interval = float(np.median(steps[steps > 0])) if np.any(steps > 0) else math.nan
    floor = OFF_TRACK_MIN_RADII * radius_px if math.isfinite(radius_px) else math.nan
    tolerance = math.nan
    if not math.isfinite(interval) or not math.isfinite(floor):
        return off, tolerance
    for _ in range(OFF_TRACK_PASSES):
        order = np.flatnonzero(measured & ~off)
        if order.size <= TRACK_NEIGHBOURS:
            break
        offsets, residuals = _track_predictions(time_s, x_px, y_px, order, (TRACK_REACH_FRAMES + 0.5) * interval,
                                                2.0 * floor)
        distances = np.hypot(offsets[..., 0], offsets[..., 1])
        tolerance = max(OFF_TRACK_SIGMAS * sideways_centre_error_px(x_px[order], order), floor)
        with np.errstate(invalid="ignore"):
            valid = residuals <= OWN_FIT_FRACTION * tolerance
            agrees = (valid & (distances <= tolerance)).any(axis=1)
            passes_by = (valid.sum(axis=1) >= 2) | valid[:, 2]
            aside = valid.any(axis=1) & np.all(~valid | (np.abs(offsets[..., 0]) > 2.0 * tolerance), axis=1)
        found = order[~agrees & (passes_by | aside)]
        if not found.size:
            break
        off[found] = True
    return off, tolerance


def mark_off_track(table, radius_px=None):
    """The tracked table with its positions off the ballistic track (:func:`off_track_rows`) flagged
    ``off_track``; their centres are kept (the contact sheet draws them), every fit leaves them out.

    Parameters
    ----------
    table : pandas.DataFrame
        A tracked table (``time_s``, ``x_px``, ``y_px``, ``radius_px``, ``quality`` …).
    radius_px : float, optional
        The ball's radius, px; by default the median radius of the usable rows.

    Returns
    -------
    pandas.DataFrame
        A copy (the table itself when nothing is off track); ``attrs["off_track_frames"]`` holds how many were
        flagged (those flagged before included) and ``attrs["off_track_tolerance_px"]`` the distance beyond
        which a position was off.
    """
    usable = usable_rows(table, radius_px)
    if radius_px is None:
        radii = table["radius_px"].to_numpy(float)[usable]
        radius_px = float(np.median(radii)) if radii.size else math.nan
    off, tolerance = off_track_rows(table["time_s"].to_numpy(float), table["x_px"].to_numpy(float),
                                    table["y_px"].to_numpy(float), usable, radius_px)
    already = int((table["quality"] == QUALITY_OFF_TRACK).sum())
    if off.any():
        table = table.copy()
        table.loc[off, "quality"] = QUALITY_OFF_TRACK
    table.attrs.update(off_track_frames=already + int(off.sum()), off_track_tolerance_px=tolerance)
    return table


#: Measured frames on each side of a repeated frame that decide whether the frames after it are late
#: (:func:`retime_inserted_repeats`).
REPEAT_WINDOW_FRAMES = 4
#: ... the frames after it are late when the parabola through the neighbours with them shifted fits this many
#: times better (sum of squared residuals) than with their time stamps kept (the tennis clip: 7.1, its frame 93 blurred
#: over 67 px and 4 px off), and the step across the repeat
#: differs from the two timings' by more than this many px (a ball at rest, or at its apex, tells nothing).
REPEAT_SHIFT_FIT_RATIO = 4.0
REPEAT_SHIFT_MIN_PX = 3.0
#: Residual floor of those fits (px per sample): a tracked centre's scatter.
REPEAT_FIT_FLOOR_PX = 0.5


def retime_inserted_repeats(table):
    """The tracked table without its repeated frames, and the frames after a repeat that a recorder *inserted*
    moved back to their capture instants.

    A recorder that fills a nominal rate repeats a frame in one of two ways: in place of a capture it missed (the
    frames after it keep their time stamps), or inserted between two successive captures (a slow-motion phone
    clip: every frame after it is stamped one interval late). The ball's motion tells them apart: a parabola
    through :data:`REPEAT_WINDOW_FRAMES` measured frames on each side fits the two timings differently
    (tennis_ball_table_aruco.mp4, 120 fps stored at 30: its frame 92 repeats 91, the ball rises 21 px from 91 to 93
    as it does in one interval, not 44 px as in two; kept, the flight after impact 2 fits 19 px off and the
    sequence was cut before it).

    Parameters
    ----------
    table : pandas.DataFrame
        A tracked table (``time_s``, ``y_px``, ``x_px``, ``quality``), frames in order.

    Returns
    -------
    pandas.DataFrame
        The rows that are not ``duplicate``, with ``time_s`` moved back where the frames after a repeat are late;
        ``attrs["inserted_repeats"]`` lists the repeated frames found inserted (their ``frame`` or row number).
    """
    duplicate = (table["quality"] == QUALITY_DUPLICATE).to_numpy()
    kept = table[~duplicate].copy()
    kept.attrs = dict(table.attrs)
    time = table["time_s"].to_numpy(dtype=float).copy()
    if not duplicate.any() or time.size < 3:
        return kept
    interval = float(np.median(np.diff(time)))
    measured = np.isin(table["quality"].to_numpy(), CLEAN_QUALITIES) & np.isfinite(table["y_px"].to_numpy(float))
    y = table["y_px"].to_numpy(dtype=float)
    frames = table["frame"].to_numpy() if "frame" in table else np.arange(time.size)
    inserted = []
    index = 0
    while index < time.size:
        if not duplicate[index]:
            index += 1
            continue
        end = index
        while end + 1 < time.size and duplicate[end + 1]:
            end += 1
        run = end - index + 1
        # unbroken runs of measured frames on each side: a gap may hold an impact
        before = np.arange(index - 1, max(index - 1 - REPEAT_WINDOW_FRAMES, -1), -1)
        before = before[:np.argmin(measured[before])] if not measured[before].all() else before
        after = np.arange(end + 1, min(end + 1 + REPEAT_WINDOW_FRAMES, time.size))
        after = after[:np.argmin(measured[after])] if not measured[after].all() else after
        before = before[::-1]
        if before.size >= 2 and after.size >= 2 and before.size + after.size >= 5:
            sides = np.r_[before, after]
            fits = []
            for shift in (0.0, run * interval):
                t = time[sides] - np.where(sides > end, shift, 0.0)
                t = t - t.mean()
                coefficients = np.polyfit(t, y[sides], 2)
                fits.append((float(np.sum((np.polyval(coefficients, t) - y[sides]) ** 2)), coefficients))
            (kept_rss, kept_fit), (shifted_rss, shifted_fit) = fits
            floor = sides.size * REPEAT_FIT_FLOOR_PX ** 2
            # the step across the repeat as each timing has it (px): they must differ for the motion to tell
            t_after = time[end + 1] - time[sides].mean()
            differ = abs(np.polyval(shifted_fit, t_after - run * interval) - np.polyval(shifted_fit, t_after))
            if kept_rss > REPEAT_SHIFT_FIT_RATIO * max(shifted_rss, floor) and differ > REPEAT_SHIFT_MIN_PX:
                time[end + 1:] -= run * interval
                inserted.append(int(frames[index]))
        index = end + 1
    if inserted:
        kept["time_s"] = time[~duplicate]
        kept.attrs["inserted_repeats"] = inserted
    return kept
