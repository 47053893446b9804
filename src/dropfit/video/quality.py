"""The tracked table's quality flags (one per frame, column ``quality``; their meaning is in
:mod:`dropfit.video.detect`) and the tracked centre's error correlation.

A module of constants only, so that what reads a tracked table or analyses a video's trajectory
(:mod:`dropfit.video.limits`, :mod:`dropfit.pipeline`) does not load OpenCV or PyAV.
"""

QUALITY_OK = "ok"

QUALITY_PARTIAL = "partial"

QUALITY_OCCLUDED = "occluded"

QUALITY_LOST = "lost"

QUALITY_DUPLICATE = "duplicate"

QUALITY_BLURRED = "blurred"

#: Frames measured cleanly: a lone ball whose centre is its coverage-weighted centroid.
CLEAN_QUALITIES = (QUALITY_OK, QUALITY_BLURRED)

#: Lag-1 autocorrelation of the tracked centre's errors between successive frames (dimensionless): the
#: pixel grid and the codec's 8 × 8 blocks bias neighbouring frames alike. Measured against the
#: renderer's truth on seeded synthetic clips (120 and 240 fps, ball radius 5–12 px, noise σ 2, MJPEG
#: quality 90): 0.08–0.24 per clip, about 0.17 on average (tests/test_tracking.py). Taken as 0.2: with
#: independent errors assumed, the intervals of 200 small clips covered the truth only ~90 %.
TRACKED_CENTRE_CORRELATION = 0.2
