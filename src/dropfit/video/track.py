"""Ball tracking in video: the sub-pixel centre and radius of the ball in every frame.

The camera is static, so the scene without the ball is one image, the *background*. It is the
per-pixel median of a few frames spread over the whole clip (not the first frames: the ball is
usually held at the top, by a hand, before release). A pixel belongs to the foreground where its
grey level differs from the background by more than ``NOISE_THRESHOLD_SIGMAS`` robust noise
standard deviations (at least ``MIN_THRESHOLD_GREY`` grey levels).

In the first frame, and whenever the ball was lost, the whole (downscaled) frame is searched for
the foreground blob with the largest inscribed circle, preferring lone, roughly circular blobs.
Afterwards the position is predicted from the last three positions (constant acceleration) and
only a window of about four radii around the prediction is converted to grey and measured.

Measurement (:func:`measure_ball`). With the ball grey level ``F`` (median of the blob's interior)
and the background ``B``, each pixel's coverage by the ball is ``a = (I - B) / (F - B)``; a
pixel well inside the blob counts as fully covered, and an anti-aliased or motion-blurred edge
pixel counts with its measured ``a``. The centre is the coverage-weighted centroid, and the radius
is ``sqrt(sum(a) / pi)``; both are unbiased for a disc of uniform grey level, and the centroid
of a motion-blurred ball is its centre averaged over the exposure. Coordinates are in px with the
OpenCV convention: the centre of pixel (row ``i``, column ``j``) is at ``x = j``, ``y = i``;
``y`` increases downwards.

Quality flags, one per frame (column ``quality``):

``ok``
    A lone, complete ball: centre and radius are measured as above.
``blurred``
    A lone ball blurred by its motion into a streak longer than its own diameter: a stadium of
    about the expected radius, along the predicted motion, swept at most about as far as the ball
    travels in a frame interval (:func:`_is_streak`). The centre is the coverage-weighted centroid,
    as for ``ok``: the ball's centre averaged over the exposure. No pixel is covered for the whole
    exposure, so the radius is not measured: it is held at the radius of the ``ok`` frames.
``partial``
    The ball is cut by the image border: the centre comes from a geometric circle fit to the
    sub-pixel points of the visible outline that are not on the image border (where the coverage
    crosses one half along rays from a first centre guess), outliers trimmed. The radius is held
    at the radius of the clean frames when there are any (a short arc fixes the centre far better
    when it need not fix the radius too), else fitted. Column ``centre_se_px`` gives the fit's
    standard error of the centre; ``fit_rms_px`` the RMS distance of the outline points from the
    circle.
``occluded``
    The ball's blob is merged with another object (a hand holding it, or the ball's own shadow)
    or is much smaller than expected (something in front of it). The centre and radius come from
    a robust circle fit to the part of the outline that lies on a circle; treat them as
    approximate. A hand holding the ball before release gives ``occluded`` frames.
    ``centre_se_px`` and ``fit_rms_px`` are those of the circle fit.
``lost``
    No ball was found (it left the image, or it is hidden): ``x_px``, ``y_px`` and ``radius_px``
    are NaN.
``duplicate``
    The frame is identical to the previous frame, as when a recorder repeats frames to fill a
    nominal rate: its time stamp does not belong to its content, so it is dropped from the
    trajectory (NaN position). Identical means a mean absolute difference of sparse samples within
    ``DUPLICATE_TOLERANCE_GREY`` (the sensor noise repeats) and no pixel of the whole frame
    changing by more than the foreground threshold (nothing moved), while the ball was predicted
    to move (more than ``STILL_BALL_STEP_PX``): a ball at rest in a noise-free video gives
    identical frames that are true ones.

``ok`` and ``blurred`` rows are meant for fitting trajectories, and so are ``partial`` rows whose
``centre_se_px`` and ``fit_rms_px`` are small (:func:`usable_rows`). ``centre_se_px`` and
``fit_rms_px`` are NaN for ``ok`` and ``blurred`` rows, whose coverage-weighted centroid is not a fit.

Ball in the background. A ball that is in view for the whole clip and moves less than a few
diameters (a close-up of a contact) covers some pixels in more than half of the background
samples, so their median is the ball, not the scene. The tracker then runs twice: the balls
found in the background samples by the first pass are cut out of them (discs of
``BALL_MASK_RADII`` tracked radii plus ``BALL_MASK_MARGIN_PX``), the median of what is left is
the background of the next pass (:func:`background_without_ball`), until the sampled balls
settle (a first pass misled by the ball in the background can misplace some of them).

Hands. A hand holding the ball is a foreground blob merged with the ball. The ball is the largest
inscribed circle of the merged blob (this assumes the hand, as seen by the camera, is narrower
than the ball, as fingers or a wrist are); the frame is flagged ``occluded`` because the blob is
not a lone disc: its second-moment ellipse is elongated (axis ratio above ``MAX_AXIS_RATIO``),
it fills less than ``MIN_ELLIPSE_FILL`` of that ellipse, or its area exceeds
``ATTACHED_AREA_FRACTION`` times the expected ball area. Once the ball is released, the hand is a
separate blob, and its pixels are excluded from the ball's measurement.

Limitations: the camera must not move; the hand must not stay at one place for more than about
half the clip (else it becomes part of the median background: trim such clips; the ball is cut
out, see above); the ball must differ in grey level from the background (a red ball on a green
wall of the same luminance is invisible); shading on the ball biases the edge coverage slightly;
a ball that is cut by the image edge in every frame has no clean radius to hold, and a circle
fit with a free radius to a short arc is unreliable, so its frames are not usable.
"""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ..errors import InputError, shown_path
from ..files import check_input_file
from ..numerics import least_squares_covariance, robust_sigma
from .opencv import cv2, decoder_output_silenced

QUALITY_OK = "ok"
QUALITY_PARTIAL = "partial"
QUALITY_OCCLUDED = "occluded"
QUALITY_LOST = "lost"
QUALITY_DUPLICATE = "duplicate"
QUALITY_BLURRED = "blurred"
#: Frames measured cleanly: a lone ball whose centre is its coverage-weighted centroid.
CLEAN_QUALITIES = (QUALITY_OK, QUALITY_BLURRED)
COLUMNS = ["frame", "time_s", "x_px", "y_px", "radius_px", "quality", "centre_se_px", "fit_rms_px"]
#: Lag-1 autocorrelation of the tracked centre's errors between successive frames (dimensionless): the
#: pixel grid and the codec's 8 × 8 blocks bias neighbouring frames alike. Measured against the
#: renderer's truth on seeded synthetic clips (120 and 240 fps, ball radius 5–12 px, noise σ 2, MJPEG
#: quality 90): 0.08–0.24 per clip, about 0.17 on average (tests/test_tracking.py). Taken as 0.2: with
#: independent errors assumed, the intervals of 200 small clips covered the truth only ~90 %.
TRACKED_CENTRE_CORRELATION = 0.2

#: Foreground threshold, in robust noise standard deviations of (frame - background).
NOISE_THRESHOLD_SIGMAS = 5.0
#: Lower bound of the foreground threshold, grey levels (for noise-free or quantised video).
MIN_THRESHOLD_GREY = 6.0
#: Smallest ball radius the tracker looks for, px.
MIN_RADIUS_PX = 2.0
#: Coverage above which an edge-connected interior pixel counts as fully covered.
DEEP_COVERAGE = 0.9
#: A blob whose second-moment ellipse has a larger axis ratio is not a lone disc (a disc blurred
#: over its own diameter has 1.5).
MAX_AXIS_RATIO = 1.6
#: A blob filling less than this fraction of its second-moment ellipse (4π σ_major σ_minor) is not
#: a lone disc.
MIN_ELLIPSE_FILL = 0.85
#: In the whole-frame search, a blob whose area exceeds this multiple of its largest inscribed
#: circle's (plus a perimeter's worth for the coarse grid) is not a lone disc.
MAX_FILL_RATIO = 1.3
#: A blob larger than this multiple of the expected disc area (radius + 1 px) has something attached.
ATTACHED_AREA_FRACTION = 1.3
#: A blob that is not a lone disc is a motion-blur streak when the stadium (a disc of its width swept
#: along the ball's predicted motion) covers it: their intersection over union is at least this, ...
MIN_STREAK_OVERLAP = 0.9
#: ... its half-width is within this fraction of the expected radius (plus 1 px) ...
STREAK_RADIUS_TOLERANCE = 0.15
#: ... and its sweep is at most this multiple of the predicted travel in a frame interval (plus 2 px):
#: the exposure is at most a frame interval.
MAX_STREAK_TRAVEL_RATIO = 1.3
#: A ball whose measured area is below this fraction of the expected area is partly hidden.
OCCLUDED_AREA_FRACTION = 0.9
#: Mean absolute grey-level difference to the previous frame at or below which a frame is a duplicate.
DUPLICATE_TOLERANCE_GREY = 0.5
#: Number of frames, spread over the clip, whose per-pixel median is the background.
BACKGROUND_SAMPLES = 11
#: Pixels between the sparse samples of the duplicate test.
DUPLICATE_STRIDE_PX = 16
#: A frame identical to the previous one is not a duplicate when the ball is predicted to move less
#: than this between them, px (a ball at rest in a noise-free video).
STILL_BALL_STEP_PX = 0.1
#: Extra margin of the search window, px.
WINDOW_MARGIN_PX = 6
#: Radius of the disc cut out of a background sample around a tracked ball, in tracked radii (a
#: ball flattened in contact is up to ~10 % wider), plus BALL_MASK_MARGIN_PX (motion blur, edge).
BALL_MASK_RADII = 1.2
BALL_MASK_MARGIN_PX = 3.0
#: At most this many further tracking passes, each with the ball cut out of the background samples
#: where the previous pass found it; they stop once the sampled balls move less than
#: BACKGROUND_SETTLED_PX between passes.
MAX_BACKGROUND_REFINEMENTS = 3
BACKGROUND_SETTLED_PX = 0.5
#: Half-length of the rays along which an outline point is placed where the coverage crosses ½, px.
EDGE_RAY_HALF_LENGTH_PX = 3.0
#: Outline points farther from the fitted circle than this many robust residual standard
#: deviations (and than EDGE_OUTLIER_MIN_PX) are dropped before the final fit.
EDGE_OUTLIER_SIGMAS = 3.0
EDGE_OUTLIER_MIN_PX = 0.5
#: A partial frame enters the trajectory when its circle fit's centre standard error and its RMS
#: residual are at most these, px.
MAX_PARTIAL_CENTRE_SE_PX = 0.1
MAX_PARTIAL_FIT_RMS_PX = 0.5
#: ... and when its radius is within this of the clean frames' (a free-radius fit to a short arc can
#: settle on a wrong circle with small residuals), px.
MAX_PARTIAL_RADIUS_MISMATCH_PX = 0.5

_ELLIPSE_3 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
_ELLIPSE_5 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
_ELLIPSE_7 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))


@dataclass(frozen=True)
class Background:
    """The static scene.

    Attributes
    ----------
    grey : numpy.ndarray
        Background grey levels, float32, shape (height, width).
    noise_grey : float
        Robust standard deviation of a frame's grey level about the background, grey levels.
    threshold_grey : float
        Foreground threshold on ``|frame - background|``, grey levels.
    """

    grey: np.ndarray
    noise_grey: float
    threshold_grey: float


@dataclass(frozen=True)
class BallMeasurement:
    """One frame's ball, in the coordinates of the image that was measured.

    Attributes
    ----------
    x_px, y_px : float
        Centre, px (pixel centres at integer coordinates).
    radius_px : float
        Radius, px.
    quality : str
        One of ``ok``, ``blurred``, ``partial``, ``occluded``.
    truncated : bool
        The blob reaches an edge of the measured window that is not an image edge: the window was
        too small, measure again in a larger one.
    centre_se_px : float
        Standard error of the centre of a circle fit (partial and occluded balls), px; NaN for ``ok``.
    fit_rms_px : float
        RMS distance of the outline points from the fitted circle, px; NaN for ``ok``.
    """

    x_px: float
    y_px: float
    radius_px: float
    quality: str
    truncated: bool = False
    centre_se_px: float = math.nan
    fit_rms_px: float = math.nan


def to_grey(image):
    """Grey levels of an image as float32.

    Parameters
    ----------
    image : numpy.ndarray
        Grey (height, width) or BGR (height, width, 3) image, any numeric type.

    Returns
    -------
    numpy.ndarray
        float32 grey levels, shape (height, width).
    """
    image = np.asarray(image)
    if image.ndim == 2:
        return image.astype(np.float32, copy=False)
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(image.astype(np.float32), cv2.COLOR_BGR2GRAY)
    if image.ndim == 3 and image.shape[2] == 1:
        return image[:, :, 0].astype(np.float32)
    raise ValueError(f"expected a grey or BGR image, got shape {image.shape}")


def _median_uint8(images):
    """Per-pixel median of an odd number of uint8 images (odd-even transposition sort)."""
    images = list(images)
    k = len(images)
    for step in range(k):
        for i in range(step % 2, k - 1, 2):
            images[i], images[i + 1] = cv2.min(images[i], images[i + 1]), cv2.max(images[i], images[i + 1])
    return images[k // 2]


def _grey_uint8(image):
    image = np.asarray(image)
    if image.dtype != np.uint8:
        return None
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.ndim == 3 and image.shape[2] == 1:
        return np.ascontiguousarray(image[:, :, 0])
    return np.ascontiguousarray(image) if image.ndim == 2 else None


def estimate_background(samples):
    """Background from frames spread over the clip.

    Parameters
    ----------
    samples : sequence of numpy.ndarray
        At least one grey or BGR frame; an odd number of 5 or more, spread over the whole clip,
        makes the ball and hand disappear from the median.

    Returns
    -------
    Background
        Per-pixel median grey level, robust noise in grey levels and the foreground threshold.
    """
    greys = [_grey_uint8(sample) for sample in samples]
    if len(greys) % 2 and all(g is not None for g in greys):
        grey = _median_uint8(greys).astype(np.float32)
        stack = np.stack([g[::8, ::8] for g in greys]).astype(np.float32)
    else:
        full = np.stack([to_grey(sample) for sample in samples])
        grey = np.median(full, axis=0).astype(np.float32)
        stack = full[:, ::8, ::8]
    k = stack.shape[0]
    if k >= 3:
        # median absolute deviation about the median; of k samples, the median one contributes 0
        noise = robust_sigma(stack - grey[::8, ::8], centre=0.0) * k / (k - 1)
    else:
        noise = 0.0
    threshold = max(NOISE_THRESHOLD_SIGMAS * noise, MIN_THRESHOLD_GREY)
    return Background(np.ascontiguousarray(grey, dtype=np.float32), noise, threshold)


def _fill_largest(mask):
    """The largest 8-connected blob of a uint8 mask with its holes filled, and its outline."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None, None
    contour = max(contours, key=lambda c: (cv2.contourArea(c), len(c)))
    filled = np.zeros_like(mask)
    cv2.drawContours(filled, [contour], -1, 1, thickness=-1)
    return filled, contour.reshape(-1, 2)


def fit_circle(x, y):
    """Algebraic (Kåsa) least-squares circle through points.

    Parameters
    ----------
    x, y : numpy.ndarray
        Point coordinates, px.

    Returns
    -------
    (float, float, float)
        Centre x, centre y and radius, px.
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    mx, my = x.mean(), y.mean()
    u, v = x - mx, y - my
    design = np.column_stack([u, v, np.ones_like(u)])
    solution = np.linalg.lstsq(design, -(u * u + v * v), rcond=None)[0]
    cx, cy = -solution[0] / 2, -solution[1] / 2
    radius = math.sqrt(max(cx * cx + cy * cy - solution[2], 0.0))
    return cx + mx, cy + my, radius


def _robust_circle(points, centre, radius, keep_mask):
    """Circle fit to outline points near a first guess, trimmed three times; None if too few points."""
    points = points[keep_mask] if keep_mask is not None else points
    cx, cy, r = centre[0], centre[1], radius
    for fraction in (0.35, 0.15, 0.08):
        distance = np.hypot(points[:, 0] - cx, points[:, 1] - cy)
        near = np.abs(distance - r) <= max(1.5, fraction * r)
        if near.sum() < 8:
            return None
        cx, cy, r = fit_circle(points[near, 0], points[near, 1])
    return cx, cy, r


def fit_circle_geometric(x, y, centre, radius, fixed_radius=False, iterations=8):
    """Geometric least-squares circle (distances to the circle) by Gauss–Newton, with its errors.

    Parameters
    ----------
    x, y : numpy.ndarray
        Point coordinates, px.
    centre : (float, float)
        Starting centre (x, y), px.
    radius : float
        Starting radius, px; kept when ``fixed_radius``.
    fixed_radius : bool
        Fit the centre only.
    iterations : int
        Gauss–Newton steps (it converges in a few from a guess within a pixel or so).

    Returns
    -------
    (float, float, float, float, float)
        Centre x, y and radius, px, the standard error of the centre (root of the mean of the
        variances of x and y, from the residual scatter), px, and the RMS residual, px.
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    cx, cy, r = float(centre[0]), float(centre[1]), float(radius)
    n_params = 2 if fixed_radius else 3
    for _ in range(iterations):
        dx, dy = x - cx, y - cy
        distance = np.maximum(np.hypot(dx, dy), 1e-9)
        residual = distance - r
        jacobian = np.column_stack([-dx / distance, -dy / distance, -np.ones_like(dx)])[:, :n_params]
        step = np.linalg.lstsq(jacobian, -residual, rcond=None)[0]
        cx, cy = cx + step[0], cy + step[1]
        if not fixed_radius:
            r += step[2]
        if np.max(np.abs(step)) < 1e-6:
            break
    dx, dy = x - cx, y - cy
    distance = np.maximum(np.hypot(dx, dy), 1e-9)
    residual = distance - r
    jacobian = np.column_stack([-dx / distance, -dy / distance, -np.ones_like(dx)])[:, :n_params]
    covariance = least_squares_covariance(jacobian, residual)
    centre_se = math.sqrt(max((covariance[0, 0] + covariance[1, 1]) / 2, 0.0))
    return cx, cy, r, centre_se, math.sqrt(float(np.mean(residual ** 2)))


def _edge_points(coverage, points, centre):
    """Sub-pixel outline: where the coverage crosses ½ along the ray from ``centre`` through each point.

    Returns the points (n, 2) that have a crossing within EDGE_RAY_HALF_LENGTH_PX (the one nearest
    the starting point), in px.
    """
    direction = points - np.asarray(centre, float)
    direction /= np.maximum(np.hypot(direction[:, 0], direction[:, 1]), 1e-9)[:, None]
    offsets = np.arange(-EDGE_RAY_HALF_LENGTH_PX, EDGE_RAY_HALF_LENGTH_PX + 1e-9, 0.25)
    sample_x = (points[:, 0, None] + offsets * direction[:, 0, None]).astype(np.float32)
    sample_y = (points[:, 1, None] + offsets * direction[:, 1, None]).astype(np.float32)
    values = cv2.remap(coverage.astype(np.float32), sample_x, sample_y, cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_REPLICATE) - 0.5
    crossing = (values[:, :-1] >= 0) & (values[:, 1:] < 0)  # inside to outside, going out
    has = crossing.any(axis=1)
    nearest = np.argmin(np.where(crossing, np.abs(offsets[:-1]), np.inf), axis=1)[has]
    rows = np.flatnonzero(has)
    a, b = values[rows, nearest], values[rows, nearest + 1]
    offset = offsets[nearest] + (offsets[1] - offsets[0]) * a / (a - b)
    return points[rows] + offset[:, None] * direction[rows]


def _fit_outline(coverage, points, centre, radius, radius_ref_px):
    """Centre, radius, centre standard error and RMS residual (px) of the ball's sub-pixel outline.

    The radius is held at ``radius_ref_px`` when given; points off the circle (a seam at the edge,
    a hand) are trimmed once. None when too few points remain.
    """
    if len(points) < 8:
        return None
    edge = _edge_points(coverage, points, centre)
    if len(edge) < 8:
        return None
    fixed = radius_ref_px is not None
    start_r = radius_ref_px if fixed else radius
    fit = fit_circle_geometric(edge[:, 0], edge[:, 1], centre, start_r, fixed)
    residual = np.hypot(edge[:, 0] - fit[0], edge[:, 1] - fit[1]) - fit[2]
    spread = robust_sigma(residual)
    inlier = np.abs(residual) <= max(EDGE_OUTLIER_SIGMAS * spread, EDGE_OUTLIER_MIN_PX)
    if inlier.sum() < 8:
        return None
    return fit_circle_geometric(edge[inlier, 0], edge[inlier, 1], fit[:2], fit[2], fixed)


def _is_streak(filled, radius_ref_px, motion_px):
    """Whether a blob (uint8 mask) is a ball of radius ``radius_ref_px`` blurred along ``motion_px``.

    A ball moving during the exposure draws a stadium: a disc of its radius swept along its motion
    over at most its travel in a frame interval, ``motion_px`` (dx, dy), px.
    """
    travel = math.hypot(*motion_px)
    if not radius_ref_px or travel == 0.0:
        return False
    ux, uy = motion_px[0] / travel, motion_px[1] / travel
    rows, columns = np.indices(filled.shape)
    along, across = columns * ux + rows * uy, rows * ux - columns * uy
    inside = filled.astype(bool)
    half_width = (np.ptp(across[inside]) + 1.0) / 2.0
    sweep = np.ptp(along[inside]) + 1.0 - 2.0 * half_width
    if (abs(half_width - radius_ref_px) > STREAK_RADIUS_TOLERANCE * radius_ref_px + 1.0
            or sweep > MAX_STREAK_TRAVEL_RATIO * travel + 2.0):
        return False
    middle_along = (along[inside].min() + along[inside].max()) / 2.0
    middle_across = (across[inside].min() + across[inside].max()) / 2.0
    beyond = np.maximum(np.abs(along - middle_along) - max(sweep, 0.0) / 2.0, 0.0)
    stadium = np.hypot(beyond, across - middle_across) <= half_width
    return np.count_nonzero(stadium & inside) >= MIN_STREAK_OVERLAP * np.count_nonzero(stadium | inside)


def measure_ball(grey, background, threshold_grey, centre_guess, radius_ref_px=None,
                 image_edges=(True, True, True, True), motion_px=None):
    """Sub-pixel centre and radius of the ball in one (window of a) frame.

    A pure function of its arguments.

    Parameters
    ----------
    grey, background : numpy.ndarray
        float32 grey levels of the frame and of the background over the same window.
    threshold_grey : float
        Foreground threshold on ``|grey - background|``, grey levels.
    centre_guess : (float, float)
        Expected centre (x, y) in window px; the blob nearest to it is the ball.
    radius_ref_px : float, optional
        Expected radius, px; used to reject small blobs and to flag attached or hidden balls.
    image_edges : (bool, bool, bool, bool)
        Whether the window's left, top, right and bottom edges are edges of the image.
    motion_px : (float, float), optional
        Predicted displacement (dx, dy) of the ball over one frame interval, px; with
        ``radius_ref_px``, a blob that is the ball blurred along it (:func:`_is_streak`) is measured
        as ``blurred``.

    Returns
    -------
    BallMeasurement or None
        In window px; None when no blob can be the ball.
    """
    height, width = grey.shape
    diff = grey - background
    foreground = (np.abs(diff) > threshold_grey).astype(np.uint8)
    count, labels, stats, centroids = cv2.connectedComponentsWithStats(foreground, connectivity=8)
    if count < 2:
        return None
    areas = stats[1:, cv2.CC_STAT_AREA]
    min_area = max(math.pi * MIN_RADIUS_PX ** 2, 0.2 * math.pi * radius_ref_px ** 2 if radius_ref_px else 0.0)
    gx, gy = centre_guess
    candidates = np.flatnonzero(areas >= min_area) + 1
    if candidates.size == 0:
        return None
    ix, iy = int(round(gx)), int(round(gy))
    inside = 0 <= ix < width and 0 <= iy < height
    if inside and labels[iy, ix] in candidates:
        label = int(labels[iy, ix])
    else:
        distance = np.hypot(centroids[candidates, 0] - gx, centroids[candidates, 1] - gy)
        label = int(candidates[np.argmin(distance)])

    blob = (labels == label).astype(np.uint8)
    filled, _ = _fill_largest(blob)
    left, top, right, bottom = image_edges
    x0, y0, w, h = stats[label, :4]
    touches = (x0 == 0, y0 == 0, x0 + w == width, y0 + h == height)
    at_image_edge = any(t and e for t, e in zip(touches, image_edges))
    truncated = any(t and not e for t, e in zip(touches, image_edges))

    # A lone disc (even motion-blurred) is round and fills the ellipse of its second moments; a
    # ball with a hand attached is elongated or not convex. Moments ignore a stray pixel.
    moments = cv2.moments(filled, binaryImage=True)
    filled_area = moments["m00"]
    if filled_area <= 0:
        return None
    mu20, mu02, mu11 = (moments[k] / filled_area for k in ("mu20", "mu02", "mu11"))
    spread = math.hypot((mu20 - mu02) / 2, mu11)
    major, minor = (mu20 + mu02) / 2 + spread, max((mu20 + mu02) / 2 - spread, 1e-9)
    attached = (major > MAX_AXIS_RATIO ** 2 * minor
                or filled_area < MIN_ELLIPSE_FILL * 4 * math.pi * math.sqrt(major * minor))
    if radius_ref_px:
        attached |= filled_area > ATTACHED_AREA_FRACTION * math.pi * (radius_ref_px + 1.0) ** 2
    streak = attached and motion_px is not None and _is_streak(filled, radius_ref_px, motion_px)
    attached &= not streak
    if attached or at_image_edge:
        # the largest inscribed circle: the ball, when what is attached is narrower than the ball
        inscribed = cv2.distanceTransform(filled, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        r_in = float(inscribed.max())
        iy_in, ix_in = np.unravel_index(int(np.argmax(inscribed)), inscribed.shape)

    # The ball's grey level, and each pixel's coverage by the ball.
    core = cv2.erode(filled, _ELLIPSE_5)
    if attached:
        # only the inscribed disc is surely the ball
        yy, xx = np.ogrid[:height, :width]
        core = core & ((xx - ix_in) ** 2 + (yy - iy_in) ** 2 <= (0.7 * r_in) ** 2).astype(np.uint8)
    core_values = grey[core.astype(bool)] if core.any() else grey[filled.astype(bool)]
    ball_grey = float(np.median(core_values))
    denominator = ball_grey - background
    sign = 1.0 if ball_grey >= float(background[filled.astype(bool)].mean()) else -1.0
    small = np.abs(denominator) < threshold_grey
    denominator[small] = sign * threshold_grey
    coverage = diff / denominator

    others = foreground & (1 - blob)
    if count > 2:
        others = cv2.dilate(others, _ELLIPSE_5)
    region = cv2.dilate(filled, _ELLIPSE_7) & (1 - others)

    if attached or at_image_edge:
        half = ((coverage > 0.5) & region.astype(bool)).astype(np.uint8)
        half_filled, half_outline = _fill_largest(half)
        if half_filled is None:
            return None
        points = half_outline.astype(float)
        keep = np.ones(len(points), bool)
        if left:
            keep &= points[:, 0] > 0
        if top:
            keep &= points[:, 1] > 0
        if right:
            keep &= points[:, 0] < width - 1
        if bottom:
            keep &= points[:, 1] < height - 1
        if attached:
            # drop outline points next to the attached object (foreground beyond the ball's fringe)
            attachment = blob & (1 - cv2.dilate(half_filled, _ELLIPSE_3))
            attachment = cv2.dilate(cv2.morphologyEx(attachment, cv2.MORPH_OPEN, _ELLIPSE_3), _ELLIPSE_7)
            keep &= attachment[half_outline[:, 1], half_outline[:, 0]] == 0
        guess_r = radius_ref_px or r_in
        circle = _robust_circle(points, (float(ix_in), float(iy_in)), guess_r, keep)
        cx, cy, r = circle if circle is not None else (float(ix_in), float(iy_in), float(guess_r))
        centre_se = fit_rms = math.nan
        outline = points[keep]
        near = np.abs(np.hypot(outline[:, 0] - cx, outline[:, 1] - cy) - r) <= max(1.5, 0.08 * r)
        refined = _fit_outline(np.clip(coverage, -1.0, 2.0), outline[near], (cx, cy), r, radius_ref_px)
        if refined is not None:
            cx, cy, r, centre_se, fit_rms = refined
        # partial: the ball itself (not a hand reaching in from the border) crosses an image edge
        crosses = (left and cx - r < -0.5, top and cy - r < -0.5,
                   right and cx + r > width - 0.5, bottom and cy + r > height - 0.5)
        quality = QUALITY_PARTIAL if (any(crosses) or not attached) else QUALITY_OCCLUDED
        return BallMeasurement(float(cx), float(cy), float(r), quality, truncated and not attached,
                               centre_se, fit_rms)

    in_region = region.astype(bool)
    deep_filled, _ = _fill_largest(((coverage > DEEP_COVERAGE) & in_region).astype(np.uint8))
    weight = np.where(in_region, np.clip(coverage, -1.0, 2.0), 0.0).astype(np.float32)
    if deep_filled is not None:
        weight[cv2.erode(deep_filled, _ELLIPSE_3).astype(bool)] = 1.0
    area = float(weight.sum())
    if area <= math.pi * MIN_RADIUS_PX ** 2:
        return None
    x = float(weight.sum(axis=0) @ np.arange(width, dtype=np.float32)) / area
    y = float(weight.sum(axis=1) @ np.arange(height, dtype=np.float32)) / area
    if streak:
        # no pixel is covered for the whole exposure, so the sum of coverage is not the ball's area
        return BallMeasurement(x, y, radius_ref_px, QUALITY_BLURRED, truncated)
    radius = math.sqrt(area / math.pi)
    quality = QUALITY_OK
    if radius_ref_px and area < OCCLUDED_AREA_FRACTION * math.pi * radius_ref_px ** 2:
        quality = QUALITY_OCCLUDED
    return BallMeasurement(x, y, radius, quality, truncated)


def find_ball(grey, background, expected_radius_px=None):
    """Search a whole frame for the ball.

    Parameters
    ----------
    grey : numpy.ndarray
        Grey levels of the frame (uint8 or float32).
    background : Background
        The static scene.
    expected_radius_px : float, optional
        Expected radius, px; blobs whose inscribed radius is far from it are ignored.

    Returns
    -------
    (float, float, float) or None
        Approximate centre x, y and radius, px; None when no blob can be the ball. Lone round
        blobs are preferred over merged ones, then the largest inscribed circle wins.
    """
    if expected_radius_px:
        scale = int(np.clip(expected_radius_px // 4, 1, 4))
    else:
        scale = 2
    if scale > 1:
        size = (grey.shape[1] // scale, grey.shape[0] // scale)
        small = cv2.resize(grey[: size[1] * scale, : size[0] * scale], size,
                           interpolation=cv2.INTER_AREA).astype(np.float32)
        small_bg = cv2.resize(background.grey[: size[1] * scale, : size[0] * scale], size,
                              interpolation=cv2.INTER_AREA)
    else:
        small, small_bg = grey.astype(np.float32, copy=False), background.grey
    mask = (cv2.absdiff(small, small_bg) > background.threshold_grey).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if count < 2:
        return None
    min_area = max(2.0, math.pi * (MIN_RADIUS_PX / scale) ** 2)
    order = np.argsort(stats[1:, cv2.CC_STAT_AREA])[::-1][:50] + 1
    best, best_key = None, None
    for label in order:
        x0, y0, w, h, area = stats[label]
        if area < min_area:
            break
        blob = np.pad((labels[y0:y0 + h, x0:x0 + w] == label).astype(np.uint8), 1)
        inscribed = cv2.distanceTransform(blob, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        r_in = float(inscribed.max())
        iy, ix = np.unravel_index(int(np.argmax(inscribed)), inscribed.shape)
        radius = r_in * scale
        if radius < MIN_RADIUS_PX:
            continue
        if expected_radius_px and not 0.5 * expected_radius_px <= radius <= 1.5 * expected_radius_px + scale:
            continue
        lone = area <= MAX_FILL_RATIO * math.pi * r_in ** 2 + 2 * math.pi * r_in
        key = (lone, -abs(radius - expected_radius_px) if expected_radius_px else radius)
        if best_key is None or key > best_key:
            x = (x0 + ix - 1 + 0.5) * scale - 0.5
            y = (y0 + iy - 1 + 0.5) * scale - 0.5
            best, best_key = (x, y, radius), key
    return best


class BallTracker:
    """Frame-by-frame tracker; feed frames in order to :meth:`update`.

    Parameters
    ----------
    background : Background
        The static scene.
    expected_radius_px : float, optional
        Expected ball radius, px; learnt from the first ``ok`` frames when not given.
    """

    def __init__(self, background, expected_radius_px=None):
        self.background = background
        self.height, self.width = background.grey.shape
        self.expected_radius_px = expected_radius_px
        self._radii = []
        self._radius_ref = None
        self._history = []  # (frame index, x, y) of the last found balls
        self._previous = None
        self._index = -1

    @property
    def radius_ref_px(self):
        """The expected radius, px: the median of recent ``ok`` radii, else the given one."""
        return self._radius_ref if self._radii else self.expected_radius_px

    def _predict(self):
        """Predicted centre (x, y), distance from the last found centre, and travel per frame (dx, dy), px."""
        history = [h for h in self._history if self._index - h[0] <= 6]
        if not history:
            return None, 0.0, None
        if len(history) >= 3:
            (t0, x0, y0), (t1, x1, y1), (t2, x2, y2) = history[-3:]
            t = self._index
            l0 = (t - t1) * (t - t2) / ((t0 - t1) * (t0 - t2))
            l1 = (t - t0) * (t - t2) / ((t1 - t0) * (t1 - t2))
            l2 = (t - t0) * (t - t1) / ((t2 - t0) * (t2 - t1))
            predicted = (l0 * x0 + l1 * x1 + l2 * x2, l0 * y0 + l1 * y1 + l2 * y2)
        elif len(history) == 2:
            (t0, x0, y0), (t1, x1, y1) = history
            f = (self._index - t1) / (t1 - t0)
            predicted = (x1 + f * (x1 - x0), y1 + f * (y1 - y0))
        else:
            predicted = history[-1][1:]
        last = history[-1]
        step = math.hypot(predicted[0] - last[1], predicted[1] - last[2])
        gap = self._index - last[0]
        return predicted, step, ((predicted[0] - last[1]) / gap, (predicted[1] - last[2]) / gap)

    def _measure_around(self, frame, centre, half_size, motion_px=None):
        x_c, y_c = centre
        x0 = max(int(math.floor(x_c - half_size)), 0)
        y0 = max(int(math.floor(y_c - half_size)), 0)
        x1 = min(int(math.ceil(x_c + half_size)) + 1, self.width)
        y1 = min(int(math.ceil(y_c + half_size)) + 1, self.height)
        if x1 - x0 < 3 or y1 - y0 < 3:
            return None
        grey = to_grey(frame[y0:y1, x0:x1])
        edges = (x0 == 0, y0 == 0, x1 == self.width, y1 == self.height)
        result = measure_ball(grey, self.background.grey[y0:y1, x0:x1], self.background.threshold_grey,
                              (x_c - x0, y_c - y0), self.radius_ref_px, edges, motion_px)
        if result is None:
            return None
        return replace(result, x_px=result.x_px + x0, y_px=result.y_px + y0)

    def _is_duplicate(self, frame, predicted, predicted_step_px):
        previous = self._previous
        if previous is None or previous.shape != frame.shape:
            return False
        s = DUPLICATE_STRIDE_PX
        sparse = np.abs(frame[::s, ::s, ...].astype(np.int16) - previous[::s, ::s, ...]).mean()
        if sparse > DUPLICATE_TOLERANCE_GREY:
            return False
        # the sparse samples miss a small ball: nothing in the whole frame may have moved
        if float(cv2.absdiff(frame, previous).max()) > self.background.threshold_grey:
            return False
        # a ball at rest in a noise-free video repeats itself: its frames are true, not repeated
        return predicted is None or predicted_step_px > STILL_BALL_STEP_PX

    def update(self, frame):
        """Measure the ball in the next frame.

        Parameters
        ----------
        frame : numpy.ndarray
            Grey or BGR frame, uint8, the background's size.

        Returns
        -------
        (float, float, float, str, float, float)
            Centre x, y and radius, px (NaN when lost or duplicate), the quality flag, and the
            circle fit's centre standard error and RMS residual, px (NaN unless a fit was used).
        """
        frame = np.asarray(frame)
        if frame.shape[:2] != (self.height, self.width):
            raise ValueError(f"frame of shape {frame.shape} does not match the background {self.background.grey.shape}")
        self._index += 1
        predicted, step, motion = self._predict()
        radius = self.radius_ref_px or 10.0
        half_size = 1.5 * radius + 2.0 * step + WINDOW_MARGIN_PX
        duplicate = self._is_duplicate(frame, predicted, step)
        self._previous = frame
        if duplicate:
            return math.nan, math.nan, math.nan, QUALITY_DUPLICATE, math.nan, math.nan

        result = None
        if predicted is not None:
            result = self._measure_around(frame, predicted, half_size, motion)
            if result is not None and result.truncated:
                result = self._measure_around(frame, (result.x_px, result.y_px), 2.0 * half_size, motion)
        if result is None or result.truncated:
            grey = _grey_uint8(frame)
            found = find_ball(to_grey(frame) if grey is None else grey, self.background, self.radius_ref_px)
            if found is not None:
                x, y, r = found
                result = self._measure_around(frame, (x, y), 2.0 * max(r, self.radius_ref_px or r) + WINDOW_MARGIN_PX)
                if result is not None and result.truncated:
                    result = self._measure_around(frame, (result.x_px, result.y_px), 4.0 * r + 2 * WINDOW_MARGIN_PX)
        if result is None:
            return math.nan, math.nan, math.nan, QUALITY_LOST, math.nan, math.nan
        self._history = (self._history + [(self._index, result.x_px, result.y_px)])[-3:]
        if result.quality == QUALITY_OK:
            self._radii = (self._radii + [result.radius_px])[-15:]
            self._radius_ref = float(np.median(self._radii))
        return result.x_px, result.y_px, result.radius_px, result.quality, result.centre_se_px, result.fit_rms_px


def _found_or_raise(table, source):
    if not table["quality"].isin([QUALITY_OK, QUALITY_PARTIAL, QUALITY_OCCLUDED]).any():
        raise InputError(f"{shown_path(source)}: the ball was never found (no round foreground blob in {len(table)} "
                         f"frames): it must stand out from the background and move")
    return table


def _run(frames, background, expected_radius_px):
    """The tracker's rows for ``frames`` (an iterable of images) against ``background``."""
    tracker = BallTracker(background, expected_radius_px)
    return [tracker.update(frame) for frame in frames]


def background_without_ball(samples, balls, background):
    """The background again with the ball cut out of its samples, when the ball is in it; else None.

    Parameters
    ----------
    samples : sequence of numpy.ndarray
        The frames whose per-pixel median is ``background`` (grey or BGR).
    balls : sequence of (float, float, float)
        The ball's centre x, y and radius tracked in each sample with ``background``, px (NaN when
        not found).
    background : Background
        The first background.

    Returns
    -------
    Background or None
        None when no pixel is covered by the ball (a disc of ``BALL_MASK_RADII`` radii plus
        ``BALL_MASK_MARGIN_PX``) in more than half of the samples: the median is then the scene.
        Else the per-pixel median of the uncovered samples (the first background where every
        sample is covered), with the first background's noise and threshold.
    """
    balls = np.asarray(balls, float).reshape(-1, 3)
    found = np.isfinite(balls).all(axis=1)
    if not found.any():
        return None
    typical_radius = float(np.median(balls[found, 2]))
    height, width = background.grey.shape
    stack = np.stack([to_grey(sample) for sample in samples])
    rows, columns = np.ogrid[:height, :width]
    covered = np.zeros((height, width), np.int32)
    for grey, (x, y, radius), is_found in zip(stack, balls, found):
        if is_found:
            reach = BALL_MASK_RADII * max(radius, typical_radius) + BALL_MASK_MARGIN_PX
            disc = (columns - x) ** 2 + (rows - y) ** 2 <= reach * reach
            grey[disc] = np.nan
            covered += disc
    if covered.max() <= len(stack) // 2:
        return None
    everywhere = covered == len(stack)
    stack[0][everywhere] = background.grey[everywhere]
    grey = np.nanmedian(stack, axis=0).astype(np.float32)
    return Background(grey, background.noise_grey, background.threshold_grey)


def _sample_balls(rows, indices):
    """(x, y, radius) of the rows at ``indices``, px, shape (n, 3)."""
    return np.array([rows[i][:3] for i in indices], float)


def _track_without_ball_in_background(track, samples, indices, background, rows):
    """Rows of further passes of ``track(background)`` with the ball cut out of the background.

    Stops when the ball is not in the background, when the balls in the samples moved less than
    ``BACKGROUND_SETTLED_PX``, or after ``MAX_BACKGROUND_REFINEMENTS`` passes.
    """
    balls = _sample_balls(rows, indices)
    for _ in range(MAX_BACKGROUND_REFINEMENTS):
        cleaner = background_without_ball(samples, balls, background)
        if cleaner is None:
            break
        rows = track(cleaner)
        moved_balls = _sample_balls(rows, indices)
        change = np.abs(moved_balls - balls)
        change[np.isnan(moved_balls) & np.isnan(balls)] = 0.0
        balls = moved_balls
        if np.nan_to_num(change, nan=np.inf).max() < BACKGROUND_SETTLED_PX:
            break
    return rows


def _table(rows, times_s):
    x, y, r, quality, centre_se, fit_rms = zip(*rows) if rows else ((),) * 6
    return pd.DataFrame({"frame": np.arange(len(rows)), "time_s": np.asarray(times_s, float),
                         "x_px": np.asarray(x, float), "y_px": np.asarray(y, float),
                         "radius_px": np.asarray(r, float), "quality": list(quality),
                         "centre_se_px": np.asarray(centre_se, float), "fit_rms_px": np.asarray(fit_rms, float)},
                        columns=COLUMNS)


def usable_rows(table, radius_px=None):
    """Rows whose centre is good for a trajectory: ``ok``, ``blurred``, and ``partial`` with a good circle fit.

    Parameters
    ----------
    table : pandas.DataFrame
        As returned by :func:`track_frames` or :func:`track_video`.
    radius_px : float, optional
        The ball's radius, px, when known; by default the median radius of the ``ok`` rows.

    Returns
    -------
    numpy.ndarray
        Boolean mask, one per row: ``ok``, ``blurred``, or ``partial`` with ``centre_se_px`` ≤
        ``MAX_PARTIAL_CENTRE_SE_PX``, ``fit_rms_px`` ≤ ``MAX_PARTIAL_FIT_RMS_PX`` and a radius
        within ``MAX_PARTIAL_RADIUS_MISMATCH_PX`` of ``radius_px``. Without a radius (no ``ok``
        row and none given) no ``partial`` row is usable.
    """
    quality = table["quality"].to_numpy()
    ok = quality == QUALITY_OK
    if radius_px is None:
        radius_px = float(np.median(table["radius_px"].to_numpy()[ok])) if ok.any() else math.nan
    good_fit = ((table["centre_se_px"].to_numpy() <= MAX_PARTIAL_CENTRE_SE_PX)
                & (table["fit_rms_px"].to_numpy() <= MAX_PARTIAL_FIT_RMS_PX)
                & (np.abs(table["radius_px"].to_numpy() - radius_px) <= MAX_PARTIAL_RADIUS_MISMATCH_PX))
    return np.isin(quality, CLEAN_QUALITIES) | ((quality == QUALITY_PARTIAL) & good_fit)


def _spread(count, samples):
    return np.unique(np.round(np.linspace(0, count - 1, min(samples, count))).astype(int))


def track_frames(frames, times_s, expected_radius_px=None, *, background=None, source="frames"):
    """Track the ball through frames already in memory.

    Parameters
    ----------
    frames : sequence or iterable of numpy.ndarray
        Grey (height, width) or BGR (height, width, 3) uint8 frames in order. A sequence (list,
        array) is indexed to sample the background; any other iterable is first read into a list.
    times_s : array_like
        Time of each frame, s.
    expected_radius_px : float, optional
        Expected ball radius, px.
    background : Background, optional
        The static scene; by default the median of ``BACKGROUND_SAMPLES`` frames spread over the
        clip, with the ball cut out when it is in it (see the module documentation).
    source : str
        Name of the recording in error messages.

    Returns
    -------
    pandas.DataFrame
        One row per frame: ``frame``, ``time_s`` (s), ``x_px``, ``y_px``, ``radius_px`` (px),
        ``quality``, ``centre_se_px`` and ``fit_rms_px`` (px; see the module documentation).

    Raises
    ------
    InputError
        When there are no frames or the ball is never found.
    """
    if not isinstance(frames, (Sequence, np.ndarray)):
        frames = list(frames)
    times_s = np.asarray(times_s, float)
    if len(frames) == 0:
        raise InputError(f"{source}: no frames")
    if times_s.shape != (len(frames),):
        raise ValueError(f"{len(frames)} frames but {times_s.size} times")
    if background is None:
        indices = _spread(len(frames), BACKGROUND_SAMPLES)
        samples = [frames[i] for i in indices]
        first = estimate_background(samples)
        rows = _track_without_ball_in_background(lambda clean: _run(frames, clean, expected_radius_px), samples,
                                                 indices, first, _run(frames, first, expected_radius_px))
        background = first
    else:
        rows = _run(frames, background, expected_radius_px)
    table = _table(rows, times_s)
    table.attrs.update(source=str(source), noise_grey=background.noise_grey)
    return _found_or_raise(table, source)


def _read_samples(capture, indices):
    samples = []
    for index in indices:
        if not capture.set(cv2.CAP_PROP_POS_FRAMES, int(index)):
            return []
        ok, frame = capture.read()
        if not ok:
            return []
        samples.append(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame)
    return samples


def video_samples(path, frame_count, samples):
    """Grey frames spread over a video file and their indices: by seeking (cheap for MJPG AVI)."""
    if frame_count >= 1:
        indices = _spread(int(frame_count), samples)
        # OpenCV's own MJPEG reader seeks cheaply, but reads only AVI files (asked for another, it warns)
        backends = (cv2.CAP_OPENCV_MJPEG, cv2.CAP_ANY) if str(path).lower().endswith(".avi") else (cv2.CAP_ANY,)
        for backend in backends:
            capture = cv2.VideoCapture(str(path), backend)
            try:
                if capture.isOpened():
                    frames = _read_samples(capture, indices)
                    if len(frames) == len(indices):
                        return list(indices), frames
            finally:
                capture.release()
    # unknown length or no seeking: decode everything, keeping frames at a doubling stride
    capture = cv2.VideoCapture(str(path))
    kept, stride, index = [], 1, 0
    try:
        while True:
            ok, frame = capture.read()
            if not ok:
                break
            if index % stride == 0:
                kept.append((index, cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame))
                if len(kept) > 2 * samples:
                    stride *= 2
                    kept = [(i, f) for i, f in kept if i % stride == 0]
            index += 1
    finally:
        capture.release()
    return [i for i, _ in kept], [f for _, f in kept]


def _track_decoded(path, background, expected_radius_px):
    """Decode a video file again and track the ball with a given background; the tracker's rows."""
    capture = cv2.VideoCapture(str(path))
    reader = _FrameReader(capture)
    reader.start()
    try:
        return _run((frame for frame, _ in reader), background, expected_radius_px)
    finally:
        reader.close()
        capture.release()


def _frame_times(stamps_ms, container_fps, capture_fps, path):
    """Frame times, s, and how they were obtained."""
    count = len(stamps_ms)
    index = np.arange(count, dtype=float)
    stamps = np.asarray(stamps_ms, float)
    meaningful = (np.all(np.isfinite(stamps)) and (count == 1 or (np.all(np.diff(stamps) > 0) and stamps[-1] > 0)))
    nominal = container_fps if container_fps and np.isfinite(container_fps) and container_fps > 0 else None
    if meaningful:
        times, how = stamps / 1000.0, "container time stamps"
        if capture_fps:
            if nominal is None:
                return index / capture_fps, f"frame index / capture_fps {capture_fps:g}"
            times, how = times * nominal / capture_fps, f"container time stamps × {nominal:g} / {capture_fps:g} fps"
        return times, how
    if capture_fps:
        return index / capture_fps, f"frame index / capture_fps {capture_fps:g}"
    if nominal is None:
        raise InputError(f"{shown_path(path)}: the video has neither frame time stamps nor a frame rate; pass capture_fps")
    return index / nominal, f"frame index / container rate {nominal:g} fps"


def track_video(path, capture_fps=None, expected_radius_px=None, *, background_samples=BACKGROUND_SAMPLES):
    """Track the ball through a video file.

    Frames are decoded once, in order, with :class:`cv2.VideoCapture` in a second thread (which
    overlaps decoding and tracking where more than one core is available). The background is the
    median of ``background_samples`` frames reached by seeking: cheap for MJPG AVI files (OpenCV's
    own MJPEG reader), costlier for long-GOP codecs such as H.264, where FFmpeg's seek decodes
    from a key frame, about 16 frames per sample.

    Times come from the container's per-frame time stamps (``CAP_PROP_POS_MSEC``) when they
    increase, else from the frame index and the container's frame rate.

    Parameters
    ----------
    path : str or pathlib.Path
        The video file.
    capture_fps : float, optional
        The rate at which the camera captured the frames, frames/s, for slow-motion files whose
        container rate is a playback rate (a 240 fps capture stored as 30 fps): container times
        are scaled by ``container_fps / capture_fps``. Estimating it from the ball's gravitational
        acceleration is done elsewhere.
    expected_radius_px : float, optional
        Expected ball radius, px.
    background_samples : int
        Frames in the background median.

    Returns
    -------
    pandas.DataFrame
        As :func:`track_frames`; ``attrs`` holds ``source``, ``container_fps``, ``capture_fps``,
        ``time_source``, ``frame_count_header`` and ``noise_grey``.

    Raises
    ------
    InputError
        For a missing, unreadable or corrupt file, a file without frames, or a ball never found.
    """
    path = check_input_file(path, "video")
    name = shown_path(path)
    if capture_fps is not None and not capture_fps > 0:
        raise InputError(f"{name}: capture_fps must be positive, got {capture_fps}")
    _check_video_file(path)
    with decoder_output_silenced():  # FFmpeg's and OpenCV's complaints about damaged frames stay off the terminal
        capture = cv2.VideoCapture(str(path))
        if not capture.isOpened():
            raise InputError(f"{name}: cannot be opened as a video: the file is damaged or not a video (a truncated "
                             f".mp4 or .mov lacks its index, which is written last); copy or export it again")
        container_fps = float(capture.get(cv2.CAP_PROP_FPS))
        frame_count = float(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        ok, first = capture.read()
        if not ok:
            capture.release()
            declared = f" of the {frame_count:.0f} its container declares" if frame_count >= 1 else ""
            raise InputError(f"{name}: no frame{declared} could be decoded: the video is empty, truncated or "
                             f"corrupt; copy or export it again")
        stamps = [capture.get(cv2.CAP_PROP_POS_MSEC)]
        # decode in a second thread (OpenCV releases the GIL) while the background is estimated and
        # the ball tracked in this one
        reader = _FrameReader(capture)
        reader.start()
        try:
            indices, samples = video_samples(path, frame_count, background_samples)
            if not samples or samples[0].shape[:2] != first.shape[:2]:
                raise InputError(f"{name}: the frames could not be decoded consistently (corrupt video)")
            background = estimate_background(samples)
            tracker = BallTracker(background, expected_radius_px)
            rows = [tracker.update(first)]
            for frame, stamp in reader:
                stamps.append(stamp)
                rows.append(tracker.update(frame))
        finally:
            reader.close()
            capture.release()
        check_frame_count(len(rows), frame_count, path)
        if len(rows) < MIN_FRAMES:
            raise InputError(f"{name}: the video has only {len(rows)} frame{'s' if len(rows) > 1 else ''}; a drop "
                             f"test needs at least {MIN_FRAMES}, and tens in each flight")
        if indices[-1] < len(rows):
            frame_count_decoded = len(rows)

            def track_again(clean):
                rows_again = _track_decoded(path, clean, expected_radius_px)
                if len(rows_again) != frame_count_decoded:
                    raise InputError(f"{name}: the frames could not be decoded consistently (corrupt video)")
                return rows_again

            rows = _track_without_ball_in_background(track_again, samples, indices, background, rows)
    times, how = _frame_times(stamps, container_fps, capture_fps, path)
    table = _table(rows, times)
    table.attrs.update(source=str(path), container_fps=container_fps, capture_fps=capture_fps,
                       time_source=how, frame_count_header=frame_count, noise_grey=background.noise_grey)
    return _found_or_raise(table, path)


#: A video with fewer frames is refused before its ball is looked for (its background would be the ball).
MIN_FRAMES = 10
#: Frames a container may declare beyond those decoded before the video counts as truncated: a
#: count estimated from the duration (Matroska) can be a frame or two off.
FRAME_COUNT_SLACK = 2
FRAME_COUNT_SLACK_FRACTION = 0.02

#: Files that are not videos, by their first bytes: (signature, what it is).
_NOT_VIDEOS = [(b"\x89PNG", "a PNG image"), (b"\xff\xd8\xff", "a JPEG image"), (b"GIF8", "a GIF image"),
               (b"%PDF", "a PDF document"), (b"PK\x03\x04", "a ZIP archive or spreadsheet"),
               (b"CDF\x01", "a NetCDF file"), (b"\x89HDF", "a NetCDF-4/HDF5 file")]


def _check_video_file(path):
    """InputError for a video file that is empty, or plainly another kind of file (an image, a text file)."""
    name = shown_path(path)
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if not head:
        raise InputError(f"{name}: the file is empty (0 bytes): not a video; copy or export it again")
    for signature, what in _NOT_VIDEOS:
        if head.startswith(signature):
            raise InputError(f"{name}: is {what}, not a video; give the video file")
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        return
    if not any(ord(char) < 32 and char not in "\t\r\n" for char in text):
        raise InputError(f"{name}: is a text file, not a video (a height log must have the suffix .csv); give the "
                         f"video file")


def check_frame_count(decoded, declared, path):
    """Raise InputError if fewer frames were decoded than the container declares (a truncated or
    damaged video), allowing :data:`FRAME_COUNT_SLACK` frames for a count estimated from the duration."""
    if declared >= 1 and decoded < declared - max(FRAME_COUNT_SLACK, FRAME_COUNT_SLACK_FRACTION * declared):
        raise InputError(f"{shown_path(path)}: the video is truncated or corrupt: only {decoded} of the "
                         f"{declared:.0f} frames its container declares could be decoded; copy or export it again")


class _FrameReader(threading.Thread):
    """Decode frames ahead of the tracker, at most ``depth`` of them; iterate for (frame, time_ms)."""

    def __init__(self, capture, depth=16):
        super().__init__(daemon=True)
        self._capture = capture
        self._queue = queue.Queue(maxsize=depth)
        self._halt = threading.Event()

    def run(self):
        try:
            while not self._halt.is_set():
                ok, frame = self._capture.read()
                if not ok:
                    break
                item = (frame, self._capture.get(cv2.CAP_PROP_POS_MSEC))
                while not self._halt.is_set():
                    try:
                        self._queue.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
        finally:
            self._queue.put(None)

    def __iter__(self):
        while True:
            item = self._queue.get()
            if item is None:
                return
            yield item

    def close(self):
        """Stop decoding and wait for the thread."""
        self._halt.set()
        while self.is_alive():
            try:
                self._queue.get(timeout=0.1)
            except queue.Empty:
                pass
