"""The tracked table's quality flags (one per frame, column ``quality``; their meaning is in
:mod:`dropfit.video.detect`), which rows are usable for a trajectory, and the tracked centre's error
correlation.

Apart from the tracker, so that what reads a tracked table or analyses a video's trajectory
(:mod:`dropfit.video.limits`, :mod:`dropfit.pipeline`) does not load OpenCV or PyAV.
"""

import math

import numpy as np

QUALITY_OK = "ok"

QUALITY_PARTIAL = "partial"

QUALITY_OCCLUDED = "occluded"

QUALITY_LOST = "lost"

QUALITY_DUPLICATE = "duplicate"

QUALITY_BLURRED = "blurred"

QUALITY_SHADED = "shaded"

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
