"""The ball in one frame: its sub-pixel centre and radius, and how cleanly it was measured.

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
``shaded``
    A ball lighter than the scene merged with its own (darker) shadow, as a white ball lit from one side
    before a light wall is: its blob holds pixels lighter and darker than the scene, and its shaded
    side can be as dark as the wall. The centre comes from a geometric circle fit to its lit side's
    outline, where the contrast falls fastest along rays from it (:func:`_fit_lit_side`); the radius is
    fitted in the first such frames and then held (``shaded_radius_px``). Once a clip's balls are
    shaded, every ball lighter than the scene is measured so, alike (the coverage centroid of a ball
    lit from one side is off towards the light). ``centre_se_px`` and ``fit_rms_px`` as for
    ``partial``.
``occluded``
    The ball's blob is merged with another object (a hand holding it, or the ball's own shadow)
    or is much smaller than expected (something in front of it). The centre and radius come from
    a robust circle fit to the part of the outline that lies on a circle; treat them as
    approximate. A hand holding the ball before release gives ``occluded`` frames.
    ``centre_se_px`` and ``fit_rms_px`` are those of the circle fit.
``centre_se_px`` and ``fit_rms_px`` are NaN for ``ok`` and ``blurred`` rows, whose coverage-weighted centroid is not a fit.

Hands. A hand holding the ball is a foreground blob merged with the ball. The ball is the largest
inscribed circle of the merged blob (this assumes the hand, as seen by the camera, is narrower
than the ball, as fingers or a wrist are); the frame is flagged ``occluded`` because the blob is
not a lone disc: its second-moment ellipse is elongated (axis ratio above ``MAX_AXIS_RATIO``),
it fills less than ``MIN_ELLIPSE_FILL`` of that ellipse, or its area exceeds
``ATTACHED_AREA_FRACTION`` times the expected ball area. Once the ball is released, the hand is a
separate blob, and its pixels are excluded from the ball's measurement.

Limitations: the camera must not move; the hand must not stay at one place for more than about
half the clip (else it becomes part of the median background: trim such clips); the ball must differ in grey level from the background (a red ball on a green
wall of the same luminance is invisible); shading on the ball biases the edge coverage slightly;
a ball that is cut by the image edge in every frame has no clean radius to hold, and a circle
fit with a free radius to a short arc is unreliable, so its frames are not usable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..numerics import fast_median, least_squares_covariance, robust_sigma
from .background import Background
from .contrast import chromaticity, frame_gain, hand_pixels, is_lone_disc, scene_colour
from .opencv import connected_components, cv2, foreground_components
# the flags documented above, kept importable from here; defined apart so that reading a tracked
# table does not load OpenCV
from .quality import (QUALITY_BLURRED, QUALITY_DUPLICATE, QUALITY_LOST, QUALITY_OCCLUDED, QUALITY_OK,  # noqa: F401
                      QUALITY_PARTIAL, QUALITY_SHADED)

#: A blob whose chromaticity is farther than this from the ball's given colour is not the ball (the share
#: of a channel in the sum: a red ball is about (0.14, 0.14, 0.71), a green one (0.2, 0.6, 0.2)).
MAX_CHROMATICITY_DISTANCE = 0.15
#: A camera renders a coloured ball paler than its name (its sheen, the ambient light, blur with the wall: the colour
#: mixed with grey), so a blob whose chromaticity lies off the given colour's towards grey is the ball too when its
#: hue is the given one's (within MAX_CHROMATICITY_DISTANCE across the line from grey to the colour) and it keeps at
#: least this share of the colour's saturation (its distance from grey): a crimson ball filmed dark is "red", a pale
#: red (skin, for a red or an orange ball) or a grey shadow is not.
MIN_SATURATION_SHARE = 0.5
#: The chromaticity of grey.
NEUTRAL_CHROMATICITY = np.full(3, 1.0 / 3.0)

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

#: A streak longer than the predicted travel is measured along its own long axis when that axis is within this
#: angle of the predicted motion (degrees; any, when the prediction moves less than a radius).
MAX_STREAK_AXIS_ANGLE_DEG = 20.0

#: ... and it is symmetric: its contrast-weighted centroid along the motion is within this fraction of
#: its length (plus half a pixel) from its middle.
MAX_STREAK_ASYMMETRY = 0.05

#: A ball whose measured area is below this fraction of the expected area is partly hidden ...
OCCLUDED_AREA_FRACTION = 0.9
#: ... or, where its radius scatters from frame to frame (a few px across, codec blur), whose radius
#: falls short of the expected one by more than this many times that scatter, up to
#: MAX_RADIUS_DEFICIT_FRACTION of it (a 4.6 px ball's radius scatters by 0.13 px: 0.35 px short is noise).
RADIUS_SPREAD_SIGMAS = 3.0
MAX_RADIUS_DEFICIT_FRACTION = 0.1

#: Half-length of the rays along which an outline point is placed where the coverage crosses ½, px.
EDGE_RAY_HALF_LENGTH_PX = 3.0
#: The ball is measured on its blob's box and this margin each way, px: more than the dilations about the
#: blob (3 px), a neighbour's dilation (2 px) and the edge rays (EDGE_RAY_HALF_LENGTH_PX) reach.
BLOB_MARGIN_PX = 8

#: A blob of a light ball merged with its own shadow holds at least SHADOW_PIXEL_FRACTION of pixels darker
#: than the scene and LIT_PIXEL_FRACTION lighter (beyond the threshold; a soft shadow's halo can be ten times
#: the ball's lit part): then the ball's lit side is measured alone.
SHADOW_PIXEL_FRACTION = 0.2
LIT_PIXEL_FRACTION = 0.05
#: Rays (count) from the ball along which the lit side's outline is looked for, between LIT_RAY_SPAN times
#: the radius: where the contrast falls fastest going out.
LIT_RAYS = 72
LIT_RAY_SPAN = (0.5, 1.5)
#: Rays whose fastest fall is at least this fraction of the steepest ray's are on the lit side; the shaded
#: side fades into the shadow and is left out.
LIT_EDGE_FRACTION = 0.5
#: Passes of outline and fit, each from the last fit's centre (the first from the lit part's centroid).
LIT_FIT_PASSES = 3

#: Outline points farther from the fitted circle than this many robust residual standard
#: deviations (and than EDGE_OUTLIER_MIN_PX) are dropped before the final fit.
EDGE_OUTLIER_SIGMAS = 3.0

EDGE_OUTLIER_MIN_PX = 0.5

_ELLIPSE_3 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))

_ELLIPSE_5 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))

_ELLIPSE_7 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))



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
    blur_px : float
        Length of the ball's motion blur, px, from its coverage's second moments (a disc of radius r swept a length
        L has variance r²/4 + L²/12 along the sweep and r²/4 across it); NaN but for ``ok`` and ``blurred``.
    """

    x_px: float
    y_px: float
    radius_px: float
    quality: str
    truncated: bool = False
    centre_se_px: float = math.nan
    fit_rms_px: float = math.nan
    blur_px: float = math.nan



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
    return _trimmed_circle(edge, centre, radius_ref_px if fixed else radius, fixed)


def _trimmed_circle(points, centre, radius, fixed_radius):
    """:func:`fit_circle_geometric` to ``points`` (n, 2; px) from ``centre`` and ``radius``, fitted again
    without the points farther from the first circle than ``EDGE_OUTLIER_SIGMAS`` robust standard
    deviations of the residuals (and than ``EDGE_OUTLIER_MIN_PX``); None when fewer than 8 remain."""
    fit = fit_circle_geometric(points[:, 0], points[:, 1], centre, radius, fixed_radius)
    residual = np.hypot(points[:, 0] - fit[0], points[:, 1] - fit[1]) - fit[2]
    inlier = np.abs(residual) <= max(EDGE_OUTLIER_SIGMAS * robust_sigma(residual), EDGE_OUTLIER_MIN_PX)
    if inlier.sum() < 8:
        return None
    return fit_circle_geometric(points[inlier, 0], points[inlier, 1], fit[:2], fit[2], fixed_radius)


def _steepest_outline(contrast, centre, radius):
    """Along ``LIT_RAYS`` rays from ``centre`` (px), the point where ``contrast`` falls fastest going out
    between ``LIT_RAY_SPAN`` times ``radius`` (px), placed to a fraction of a sample by a parabola
    through the fall's peak: the edge of a blurred step, whatever the levels on either side of it.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The points (n, 2), px, and the fall at each, contrast units per px.
    """
    angles = np.linspace(0.0, 2.0 * np.pi, LIT_RAYS, endpoint=False)
    step = 0.25
    distances = np.arange(LIT_RAY_SPAN[0] * radius, LIT_RAY_SPAN[1] * radius, step)
    cos, sin = np.cos(angles)[:, None], np.sin(angles)[:, None]
    values = cv2.remap(contrast.astype(np.float32), (centre[0] + cos * distances).astype(np.float32),
                       (centre[1] + sin * distances).astype(np.float32), cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_REPLICATE)
    fall = (values[:, :-2] - values[:, 2:]) / (2.0 * step)  # at distances[1:-1]
    rays = np.arange(LIT_RAYS)
    peak = np.clip(np.argmax(fall, axis=1), 1, fall.shape[1] - 2)
    before, at, after = fall[rays, peak - 1], fall[rays, peak], fall[rays, peak + 1]
    curvature = before - 2.0 * at + after
    shift = np.clip(np.divide(0.5 * (before - after), curvature, out=np.zeros_like(at), where=curvature < 0), -1, 1)
    distance = distances[peak + 1] + step * shift
    return np.column_stack([centre[0] + cos[:, 0] * distance, centre[1] + sin[:, 0] * distance]), at


def _fit_lit_side(contrast, start, radius_px, fixed_radius):
    """A light ball measured on its lit side: centre x, y, radius, centre standard error and RMS residual
    (px), as :func:`fit_circle_geometric` with the radius held at ``radius_px`` when ``fixed_radius``,
    else fitted from it; None when fewer than 8 outline points are left.

    ``contrast`` is the ball's contrast to the scene (positive on the ball), grey levels. A light ball lit
    from one side before a light wall is lighter than the wall on its lit side only; its shaded side is
    as dark as the wall and fades into its shadow. The lit side's outline is where the contrast falls
    fastest along rays (:func:`_steepest_outline`), on the rays whose fall is at least
    ``LIT_EDGE_FRACTION`` of the steepest; points off the circle are trimmed (:func:`_trimmed_circle`).
    Starts at ``start`` (x, y, px), refits ``LIT_FIT_PASSES`` times about the last centre.
    """
    centre, radius, fit = start, radius_px, None
    for _ in range(LIT_FIT_PASSES):
        points, fall = _steepest_outline(contrast, centre, radius)
        if not fall.max() > 0:
            return None
        lit = points[fall >= LIT_EDGE_FRACTION * fall.max()]
        if len(lit) < 8:
            return None
        fit = _trimmed_circle(lit, centre, radius, fixed_radius)
        if fit is None or not MIN_RADIUS_PX <= fit[2] <= 2.0 * radius:
            return None
        centre, radius = fit[:2], fit[2]
    return fit


def _shaded_ball(diff, blob, threshold_grey, radius_px=None):
    """The ball of a blob that is a light ball merged with its own shadow, by :func:`_fit_lit_side`; None
    when the blob is not one, or the fit fails.

    A shadow is darker than the scene, so a ball lighter than the scene merged with it makes a blob of
    both signs: at least ``LIT_PIXEL_FRACTION`` of its pixels lighter, and ``SHADOW_PIXEL_FRACTION``
    darker, than the scene by the threshold. The shadow's halo can make the blob round, and the ball's
    shaded side can be as dark as the scene: the ball is measured on the blob's largest lighter part (a
    hand, the other thing a ball merges with, is taken out of the frame by its colour first). With
    ``radius_px`` given (a clip whose balls are shaded), any blob with a lighter part is measured so.

    Parameters
    ----------
    diff : numpy.ndarray
        The frame less the background, grey levels.
    blob : numpy.ndarray
        The merged blob (``|diff|`` above the threshold), bool or 0/1.
    threshold_grey : float
        Foreground threshold, grey levels.
    radius_px : float, optional
        The ball's radius, px: held when given, else fitted from the lighter part's equivalent radius
        (that of its area).
    """
    lit = _lit_part(diff, blob, threshold_grey, shadow_needed=radius_px is None)
    if lit is None:
        return None
    moments = cv2.moments(lit, binaryImage=True)
    start = (moments["m10"] / moments["m00"], moments["m01"] / moments["m00"])
    equivalent = math.sqrt(moments["m00"] / math.pi)
    return _fit_lit_side(diff, start, radius_px or equivalent, radius_px is not None)


def _lit_part(diff, blob, threshold, shadow_needed=True):
    """The largest lighter part (uint8 mask) of a blob that is a light ball merged with its own shadow: at
    least ``LIT_PIXEL_FRACTION`` of its pixels lighter than the scene by ``threshold`` (and ``MIN_RADIUS_PX``
    across), and ``SHADOW_PIXEL_FRACTION`` darker (unless not ``shadow_needed``); None for any other blob.

    Parameters
    ----------
    diff : numpy.ndarray
        The contrast to the scene, signed.
    blob : numpy.ndarray
        The blob (``|diff|`` above ``threshold``), bool or 0/1.
    threshold : float
        The foreground threshold, in ``diff``'s units.
    """
    area = np.count_nonzero(blob)
    lit = (blob & (diff > threshold)).astype(np.uint8)
    if (np.count_nonzero(lit) < max(LIT_PIXEL_FRACTION * area, math.pi * MIN_RADIUS_PX ** 2)
            or shadow_needed and np.count_nonzero(blob & (diff < -threshold)) < SHADOW_PIXEL_FRACTION * area):
        return None
    count, labels, stats, _ = cv2.connectedComponentsWithStats(lit, connectivity=8)
    return (labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))).astype(np.uint8)


def _is_streak(filled, contrast, radius_ref_px, motion_px):
    """Whether a blob (uint8 mask) is a ball of radius ``radius_ref_px`` blurred along ``motion_px``.

    A ball moving during the exposure draws a stadium: a disc of its radius swept along its motion
    over at most its travel in a frame interval, ``motion_px`` (dx, dy), px, symmetric about its
    middle: the ``contrast``-weighted centroid lies within ``MAX_STREAK_ASYMMETRY`` of the stadium's
    length from the middle (a ball with its shadow attached behind it is heavier at the ball's end).
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
    weight = np.abs(contrast[inside])
    if weight.sum() > 0 and abs(float(np.average(along[inside], weights=weight)) - middle_along) > (
            MAX_STREAK_ASYMMETRY * (sweep + 2.0 * half_width) + 0.5):
        return False
    beyond = np.maximum(np.abs(along - middle_along) - max(sweep, 0.0) / 2.0, 0.0)
    stadium = np.hypot(beyond, across - middle_across) <= half_width
    return np.count_nonzero(stadium & inside) >= MIN_STREAK_OVERLAP * np.count_nonzero(stadium | inside)


def measure_ball(grey, background, threshold_grey, centre_guess, radius_ref_px=None,
                 image_edges=(True, True, True, True), motion_px=None, radius_spread_px=0.0,
                 shaded_radius_px=None):
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
    radius_spread_px : float
        Scatter (standard deviation) of the ball's measured radius from frame to frame, px: a radius
        short of ``radius_ref_px`` by less than ``RADIUS_SPREAD_SIGMAS`` of it is not taken for a
        partly hidden ball.
    shaded_radius_px : float, optional
        The radius of the clip's balls measured on their lit sides (``shaded``), px: held, and every
        ball lighter than the scene is measured so, its shadow merged or not. Without it, only a ball
        merged with its shadow is, with the radius fitted.

    Returns
    -------
    BallMeasurement or None
        In window px; None when no blob can be the ball.
    """
    height, width = grey.shape
    diff = grey - background
    foreground = (np.abs(diff) > threshold_grey).astype(np.uint8)
    components = connected_components(foreground)
    count, labels, stats = components[:3]
    if count < 2:
        return None
    areas = stats[1:, cv2.CC_STAT_AREA]
    min_area = max(math.pi * MIN_RADIUS_PX ** 2, 0.2 * math.pi * radius_ref_px ** 2 if radius_ref_px else 0.0)
    gx, gy = centre_guess
    candidates = np.flatnonzero(areas >= min_area) + 1
    if shaded_radius_px is not None:
        # the clip's ball is lighter than the scene on its lit side: a blob with no lighter part is a shadow
        lit_pixels = np.bincount(labels[diff > threshold_grey], minlength=count)
        candidates = candidates[lit_pixels[candidates] >= math.pi * MIN_RADIUS_PX ** 2]
    if candidates.size == 0:
        return None
    ix, iy = int(round(gx)), int(round(gy))
    inside = 0 <= ix < width and 0 <= iy < height
    if inside and labels[iy, ix] in candidates:
        label = int(labels[iy, ix])
    else:
        centroids = components.centroids(candidates)
        distance = np.hypot(centroids[:, 0] - gx, centroids[:, 1] - gy)
        label = int(candidates[np.argmin(distance)])

    x0, y0, w, h = stats[label, :4].tolist()
    touches = (x0 == 0, y0 == 0, x0 + w == width, y0 + h == height)
    at_image_edge = any(t and e for t, e in zip(touches, image_edges))
    truncated = any(t and not e for t, e in zip(touches, image_edges))
    # what follows reads only the blob and a few pixels about it: work on its box and that margin
    # (a window searched for a fast ball is many times the ball's size)
    left_px, top_px = max(x0 - BLOB_MARGIN_PX, 0), max(y0 - BLOB_MARGIN_PX, 0)
    right_px, bottom_px = min(x0 + w + BLOB_MARGIN_PX, width), min(y0 + h + BLOB_MARGIN_PX, height)
    box = (slice(top_px, bottom_px), slice(left_px, right_px))
    window_width, window_height = width, height
    grey, background, diff, foreground, labels = grey[box], background[box], diff[box], foreground[box], labels[box]
    height, width = grey.shape
    # the window's edges that are the image's, where they bound the box
    left, top, right, bottom = (image_edges[0] and left_px == 0, image_edges[1] and top_px == 0,
                                image_edges[2] and right_px == window_width,
                                image_edges[3] and bottom_px == window_height)

    blob = (labels == label).astype(np.uint8)
    if not at_image_edge:
        # a ball lighter than the scene merged with its darker shadow can be round in |contrast| with the
        # shadow's halo about it: measured on its lit side alone
        shaded = _shaded_ball(diff, blob, threshold_grey, shaded_radius_px)
        if shaded is not None:
            cx, cy, r, centre_se, fit_rms = shaded
            return BallMeasurement(float(cx + left_px), float(cy + top_px), float(r), QUALITY_SHADED, truncated,
                                   centre_se, fit_rms)
    filled, _ = _fill_largest(blob)

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
    streak = attached and motion_px is not None and _is_streak(filled, diff, radius_ref_px, motion_px)
    if attached and not streak and radius_ref_px and major > MAX_AXIS_RATIO ** 2 * minor:
        # a streak longer than the predicted travel: the prediction came from centres of earlier streaks fitted at
        # one end, or from a hand that held the ball (phonesim's white ball before a dark door, 20 fps, exposed
        # for the whole frame interval: 11 frames in a row after the release flagged occluded, their centres
        # 13-31 px short). Along its own long axis, when that is the predicted direction (or none is predicted)
        axis = 0.5 * math.atan2(2.0 * mu11, mu20 - mu02)
        direction = (math.cos(axis), math.sin(axis))
        travel = math.hypot(*motion_px) if motion_px is not None else 0.0
        aligned = travel < radius_ref_px or abs(direction[0] * motion_px[0] + direction[1] * motion_px[1]) >= (
            math.cos(math.radians(MAX_STREAK_AXIS_ANGLE_DEG)) * travel)
        length = 2.0 * math.sqrt(major) * math.sqrt(3.0)  # a stadium's length, generously
        streak = aligned and _is_streak(filled, diff, radius_ref_px, (direction[0] * length, direction[1] * length))
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
    ball_grey = float(fast_median(core_values))
    denominator = ball_grey - background
    small = np.abs(denominator) < threshold_grey
    if small.any():  # (most balls differ from their background everywhere)
        sign = 1.0 if ball_grey >= float(background[filled.astype(bool)].mean()) else -1.0
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
        cx, cy = cx + left_px, cy + top_px
        # partial: the ball itself (not a hand reaching in from the border) crosses an image edge
        crosses = (image_edges[0] and cx - r < -0.5, image_edges[1] and cy - r < -0.5,
                   image_edges[2] and cx + r > window_width - 0.5, image_edges[3] and cy + r > window_height - 0.5)
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
    x = float(weight.sum(axis=0) @ np.arange(width, dtype=np.float32)) / area + left_px
    y = float(weight.sum(axis=1) @ np.arange(height, dtype=np.float32)) / area + top_px
    blur = motion_blur_px(weight, (x - left_px, y - top_px), area)
    if streak:
        # no pixel is covered for the whole exposure, so the sum of coverage is not the ball's area
        return BallMeasurement(x, y, radius_ref_px, QUALITY_BLURRED, truncated, blur_px=blur)
    radius = math.sqrt(area / math.pi)
    quality = QUALITY_OK
    if radius_ref_px:
        deficit = max((1.0 - math.sqrt(OCCLUDED_AREA_FRACTION)) * radius_ref_px,
                      min(RADIUS_SPREAD_SIGMAS * radius_spread_px, MAX_RADIUS_DEFICIT_FRACTION * radius_ref_px))
        if radius < radius_ref_px - deficit:
            quality = QUALITY_OCCLUDED
    return BallMeasurement(x, y, radius, quality, truncated, blur_px=blur if quality == QUALITY_OK else math.nan)


def motion_blur_px(weight, centroid_px, area):
    """Length of a ball's motion blur, px, from its coverage ``weight`` (rows × columns) about its ``centroid_px``
    (x, y in the window, px); ``area`` is the sum of ``weight`` (px²). A disc swept a length L has variance L²/12
    more along the sweep than across it.
    """
    columns = np.arange(weight.shape[1]) - centroid_px[0]
    rows = np.arange(weight.shape[0]) - centroid_px[1]
    variance_x = float(weight.sum(axis=0) @ (columns * columns)) / area
    variance_y = float(weight.sum(axis=1) @ (rows * rows)) / area
    covariance = float(rows @ weight @ columns) / area
    spread = math.hypot((variance_x - variance_y) / 2, covariance)  # px², half the axes' difference
    return math.sqrt(24.0 * spread)


def _centre_colour(frame, blob):
    """Median BGR of a frame within half a blob's radius of its centre."""
    x, y, radius = blob[:3]
    reach = max(0.5 * radius, 1.0)
    x0, y0 = max(int(x - reach), 0), max(int(y - reach), 0)
    window = frame[y0:int(y + reach) + 1, x0:int(x + reach) + 1].reshape(-1, 3)
    return np.median(window, axis=0) if window.size else np.zeros(3)


class SearchedFrame(NamedTuple):
    """A frame as the whole-frame search reads it (:func:`searched_frame`): made once for all contrast channels.

    Attributes
    ----------
    image : numpy.ndarray
        The frame reduced ``scale`` times in each direction (pixel areas averaged), grey or BGR uint8.
    background : Background
        The background reduced alike.
    scale : int
        The reduction.
    hand : numpy.ndarray or None
        The image's hand pixels (:func:`dropfit.video.contrast.hand_pixels`), None without colour.
    expected_radius_px : float or None
        Expected radius, px.
    """

    image: np.ndarray
    background: Background
    scale: int
    hand: np.ndarray | None
    expected_radius_px: float | None

    def blobs(self, contrast, gain=1.0):
        """:func:`find_blobs` of the frame in ``contrast``, with the frame's ``gain`` against the background."""
        scale, expected_radius_px = self.scale, self.expected_radius_px
        signal = contrast.image(self.image, self.background.grey, scene_colour(self.background), gain, self.hand)
        left, top, labels, stats, _ = foreground_components(
            (np.abs(signal) > contrast.threshold).astype(np.uint8))
        min_area = max(2.0, math.pi * (MIN_RADIUS_PX / scale) ** 2)
        blobs = []
        for label in np.argsort(stats[1:, cv2.CC_STAT_AREA])[::-1][:50] + 1:
            x0, y0, w, h, area = stats[label]
            if area < min_area:
                break
            in_box = labels[y0:y0 + h, x0:x0 + w] == label
            lit = _lit_part(signal[top + y0:top + y0 + h, left + x0:left + x0 + w], in_box, contrast.threshold)
            if lit is not None:
                # a light ball merged with its shadow, where its lit part is: not a lone disc (a channel that
                # leaves the shadow out sees one), but what measure_ball measures on its lit side
                ys, xs = np.nonzero(lit)
                radius = math.sqrt(np.count_nonzero(lit) / math.pi) * scale
                if radius >= MIN_RADIUS_PX:
                    blobs.append(((left + x0 + xs.mean() + 0.5) * scale - 0.5,
                                  (top + y0 + ys.mean() + 0.5) * scale - 0.5, expected_radius_px or radius, False,
                                  True))
                continue
            blob = cv2.copyMakeBorder(in_box.astype(np.uint8), 1, 1, 1, 1,
                                      cv2.BORDER_CONSTANT, value=0)  # (np.pad costs 20 times more)
            inscribed = cv2.distanceTransform(blob, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
            r_in = float(inscribed.max())
            iy, ix = np.unravel_index(int(np.argmax(inscribed)), inscribed.shape)
            radius = r_in * scale
            if radius < MIN_RADIUS_PX:
                continue
            if expected_radius_px and not 0.5 * expected_radius_px <= radius <= 1.5 * expected_radius_px + scale:
                continue
            lone = bool(is_lone_disc(area, r_in))
            blobs.append(((left + x0 + ix - 1 + 0.5) * scale - 0.5, (top + y0 + iy - 1 + 0.5) * scale - 0.5,
                          radius, lone, False))
        return blobs


def searched_frame(frame, background, expected_radius_px=None):
    """The frame as :func:`find_blobs` searches it: reduced 1-4 times (by the expected radius; twice without
    one), with its hand pixels, as a :class:`SearchedFrame` to search in several contrast channels."""
    scale = int(np.clip(expected_radius_px // 4, 1, 4)) if expected_radius_px else 2
    scale = max(1, min(scale, *frame.shape[:2]))  # a strip thinner than the reduction is searched as it is
    if scale > 1:
        size = (frame.shape[1] // scale, frame.shape[0] // scale)
        frame = cv2.resize(frame[: size[1] * scale, : size[0] * scale], size, interpolation=cv2.INTER_AREA)
        background = background.shrunk(scale)
    return SearchedFrame(frame, background, scale, hand_pixels(frame, scene_colour(background)), expected_radius_px)


def find_blobs(frame, background, contrast, expected_radius_px=None, gain=1.0):
    """Round foreground blobs of a whole frame: the candidates for the ball.

    Parameters
    ----------
    frame : numpy.ndarray
        The frame, grey or BGR uint8 (BGR for a colour contrast).
    background : Background
        The static scene.
    contrast : dropfit.video.contrast.Contrast
        The channel in which the ball stands out, with its threshold.
    expected_radius_px : float, optional
        Expected radius, px; blobs whose inscribed radius is far from it are ignored.
    gain : float
        The frame's gain against the background (:func:`dropfit.video.contrast.frame_gain`).

    Returns
    -------
    list of (float, float, float, bool, bool)
        Per blob (the 50 largest), the centre x, y and radius of its largest inscribed circle, px
        (approximate: searched at a reduced size, :func:`searched_frame`), whether it is a lone disc
        (:func:`dropfit.video.contrast.is_lone_disc`), and whether it
        is a light ball merged with its shadow (then x, y and the radius are its lighter part's, and it is
        not a lone disc).
    """
    return searched_frame(frame, background, expected_radius_px).blobs(contrast, gain)


def frame_blobs(frame, background, contrast, expected_radius_px=None):
    """:func:`find_blobs` of a whole frame, its gain against the background measured from the frame itself
    (:func:`dropfit.video.contrast.frame_gain`) in a colour channel."""
    gain = frame_gain(frame, scene_colour(background)) if contrast.in_colour else 1.0
    return find_blobs(frame, background, contrast, expected_radius_px, gain)


def off_fixtures(blobs, fixtures):
    """The ``blobs`` (x, y, radius px, ...) not centred within a radius of one of ``fixtures`` (x, y, radius
    px): blobs that stay in one place through the clip are not the ball."""
    return [blob for blob in blobs
            if not any(math.hypot(blob[0] - x, blob[1] - y) <= max(r, blob[2]) for x, y, r in fixtures)]


def colour_matches(bgr, wanted_bgr):
    """Whether a blob's colour ``bgr`` is the ball's given colour ``wanted_bgr`` (BGR levels): its chromaticity
    (:func:`dropfit.video.contrast.chromaticity`) within ``MAX_CHROMATICITY_DISTANCE`` of the given one's, or of
    the given one's mixed with grey down to ``MIN_SATURATION_SHARE`` of its saturation."""
    colour, wanted = chromaticity(bgr), chromaticity(wanted_bgr)
    if np.linalg.norm(colour - wanted) <= MAX_CHROMATICITY_DISTANCE:
        return True
    saturation = wanted - NEUTRAL_CHROMATICITY
    power = float(saturation @ saturation)
    if power <= MAX_CHROMATICITY_DISTANCE ** 2:  # a grey, white or black ball: no hue to keep
        return False
    offset = colour - NEUTRAL_CHROMATICITY
    share = float(offset @ saturation) / power
    return share >= MIN_SATURATION_SHARE and float(np.linalg.norm(offset - share * saturation)) <= (
        MAX_CHROMATICITY_DISTANCE)


def find_ball(frame, background, contrast, expected_radius_px=None, gain=1.0, fixtures=(), colour_bgr=None):
    """Search a whole frame for the ball: of the blobs of :func:`find_blobs`, lone discs and light balls merged
    with their shadows before other merged blobs, then the radius nearest the expected one (without one, the
    largest: a speck of a hand's fringe is a lone disc too).

    ``fixtures`` are blobs that stay in one place in the whole clip (x, y, radius in px): blobs
    centred within a radius of one are not the ball. With the ball's colour ``colour_bgr`` (BGR
    levels) given, a blob whose centre's colour does not match it (:func:`colour_matches`) is not the ball.

    Returns
    -------
    (float, float, float, bool, bool) or None
        As one blob of :func:`find_blobs`; None when there is none.
    """
    blobs = off_fixtures(find_blobs(frame, background, contrast, expected_radius_px, gain), fixtures)
    if colour_bgr is not None and frame.ndim == 3:
        blobs = [blob for blob in blobs if colour_matches(_centre_colour(frame, blob), colour_bgr)]
    if not blobs:
        return None
    return max(blobs, key=lambda blob: (blob[3] or blob[4], -abs(blob[2] - expected_radius_px)
                                        if expected_radius_px else blob[2]))
