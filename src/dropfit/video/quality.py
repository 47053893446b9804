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

#: Largest error of a tracked centre that changes with the ball's speed (px, at its fastest), which the flights'
#: curvature takes for drag and which moves the apex heights at any k: a standard error that widens a held k's
#: and enters every quantity as two systematic parts, its v|v| and v² shapes (dropfit.analysis.uncertainty). Measured against phonesim's truth: the yellow ball at 120 fps read 0.3-0.45 px
#: higher falling than rising near the floor in H.264 (crf 18) and none of it encoded losslessly; the red ball,
#: blurred over half a frame interval at 30 fps, 0.15-0.25 px high in its fast frames losslessly, 0.3-0.5 px in
#: H.264. Taken as twice the largest of these: neither its shape nor how it grows at the fastest speeds, by the
#: floor, was measured (at 0.5 px the yellow ball's seed 3 still read e 2.1 se high).
SPEED_DEPENDENT_CENTRE_ERROR_PX = 1.0

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
