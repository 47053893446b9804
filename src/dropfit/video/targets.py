"""Scales and plane maps from targets of known size in view: two points a known distance apart, a
printed ArUco marker and a checkerboard; and the tilt bias of a scale without one.

Pure functions on images and numbers (no file I/O).

A marker or board in the plane of the drop gives more than a scale: the homography H from image
pixels to metric plane coordinates, so a camera not square to that plane is corrected by mapping the
tracked centres through H (:func:`to_plane`). The scale it reports is the local one at the target,
√|det J| of the image→plane map (m/px).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

#: Standard error of a point clicked by hand, px, per coordinate.
CLICK_SE_PX = 1.0
#: Standard error of a refined ArUco corner, px, per coordinate (sub-pixel refinement on a sharp print;
#: an assumption, as four corners leave no residual to measure it by).
MARKER_CORNER_SE_PX = 0.2
#: Fewest px of residual scatter a checkerboard's corners are taken to have (a perfect drawing has none).
BOARD_CORNER_MIN_SE_PX = 0.05
#: ArUco dictionaries tried, in turn, when none is named.
ARUCO_DICTIONARIES = ("DICT_4X4_50", "DICT_5X5_100", "DICT_6X6_250", "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_36h11")


@dataclass(frozen=True)
class PlaneCalibration:
    """A target's image→plane map and the scale it gives.

    Attributes
    ----------
    homography : numpy.ndarray
        3×3 map from image pixels (x right, y down) to plane coordinates in m (x along the target's
        first edge, y along its second).
    scale_m_per_px, scale_se_m_per_px : float
        Local scale at the target's centre, m/px, and its standard error.
    centre_px : numpy.ndarray
        The target's centre in the image, px.
    source : str
        What was found (``aruco DICT_4X4_50 id 7``, ``checkerboard 9x6``).
    """

    homography: np.ndarray
    scale_m_per_px: float
    scale_se_m_per_px: float
    centre_px: np.ndarray
    source: str


def two_point_scale(points_px, distance_m, click_se_px=CLICK_SE_PX):
    """Scale from two image points a known distance apart (clicked by the user).

    Parameters
    ----------
    points_px : array_like
        ((x1, y1), (x2, y2)) in px.
    distance_m : float
        Their distance in m.
    click_se_px : float
        Standard error of each point's coordinates in px (default 1 px, a click's).

    Returns
    -------
    (float, float)
        Scale in m/px and its standard error (the length's se √2·σ over the length).
    """
    points = np.asarray(points_px, dtype=float).reshape(2, 2)
    length = float(np.hypot(*(points[1] - points[0])))
    if not length > 0:
        raise InputError(f"scale_points_px: the two points {points.tolist()} coincide; give two points "
                         f"{distance_m:g} m apart")
    scale = distance_m / length
    return scale, scale * np.sqrt(2.0) * click_se_px / length


def to_plane(homography, points_px):
    """Map image points (px, shape (n, 2)) to plane coordinates (m, shape (n, 2)) through ``homography``."""
    points = np.asarray(points_px, dtype=float).reshape(-1, 2)
    mapped = np.column_stack([points, np.ones(len(points))]) @ np.asarray(homography, dtype=float).T
    return mapped[:, :2] / mapped[:, 2:3]


def local_scale(homography, point_px):
    """Scale of the image→plane map at ``point_px``, m/px: √|det J| (the geometric mean of its two axes)."""
    step = 0.5
    x, y = np.asarray(point_px, dtype=float)
    around = to_plane(homography, [[x + step, y], [x - step, y], [x, y + step], [x, y - step]])
    jacobian = np.column_stack([around[0] - around[1], around[2] - around[3]]) / (2 * step)
    return float(np.sqrt(abs(np.linalg.det(jacobian))))


def _plane_from_points(image_px, plane_m, corner_se_px, source):
    """PlaneCalibration from matched image and plane points (at least 4); se from the residual
    scatter (floored at ``corner_se_px``) over the points' spread."""
    from .opencv import cv2

    image_px, plane_m = np.asarray(image_px, float).reshape(-1, 2), np.asarray(plane_m, float).reshape(-1, 2)
    homography, _ = cv2.findHomography(image_px, plane_m, 0)
    centre = image_px.mean(axis=0)
    scale = local_scale(homography, centre)
    back = cv2.perspectiveTransform(plane_m.reshape(-1, 1, 2), np.linalg.inv(homography)).reshape(-1, 2)
    dof = max(2 * len(image_px) - 8, 1)
    residual_se = float(np.sqrt(np.sum((back - image_px) ** 2) / dof)) if len(image_px) > 4 else 0.0
    sigma = max(residual_se, corner_se_px)
    # a length across the points' spread (rms radius r) from n points each σ per coordinate: σ/(r√(n/2))
    spread = float(np.sqrt(np.mean(np.sum((image_px - centre) ** 2, axis=1))))
    rel_se = sigma / (spread * np.sqrt(len(image_px) / 2.0))
    return PlaneCalibration(homography, scale, scale * rel_se, centre, source)


def aruco_plane(image, marker_size_m, dictionary=None):
    """Image→plane map and scale from the largest printed ArUco marker in view.

    Parameters
    ----------
    image : numpy.ndarray
        Grey or BGR image (the background).
    marker_size_m : float
        The marker's printed side in m (the black square's outer edge).
    dictionary : str, optional
        An OpenCV ArUco dictionary name (``DICT_4X4_50``); default: each of :data:`ARUCO_DICTIONARIES`.

    Returns
    -------
    (PlaneCalibration or None, str)
        The calibration (plane origin at the marker's top-left corner, se from
        :data:`MARKER_CORNER_SE_PX`), or None, and a sentence saying what was found.
    """
    from .opencv import cv2

    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    parameters = cv2.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    for name in (dictionary,) if dictionary else ARUCO_DICTIONARIES:
        detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)), parameters)
        corners, ids, _ = detector.detectMarkers(np.ascontiguousarray(grey.astype(np.uint8)))
        if ids is None or not len(ids):
            continue
        largest = int(np.argmax([cv2.contourArea(c.reshape(-1, 2).astype(np.float32)) for c in corners]))
        square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) * marker_size_m
        found = _plane_from_points(corners[largest].reshape(4, 2), square, MARKER_CORNER_SE_PX,
                                   f"aruco {name} id {int(np.ravel(ids)[largest])}")
        return found, f"{found.source} ({len(ids)} marker{'s' if len(ids) > 1 else ''} found, the largest used)"
    return None, f"no ArUco marker of {dictionary or ', '.join(ARUCO_DICTIONARIES)}"


def board_plane(image, square_m, inner_corners):
    """Image→plane map and scale from a checkerboard (:func:`cv2.findChessboardCornersSB`).

    Parameters
    ----------
    image : numpy.ndarray
        Grey or BGR image.
    square_m : float
        Side of a square in m.
    inner_corners : (int, int)
        Inner corners per row and per column (a 10 × 7 squares board has (9, 6)).

    Returns
    -------
    (PlaneCalibration or None, str)
        The calibration (se from the corners' residual scatter about the homography), or None, and
        a sentence saying what was found.
    """
    from .opencv import cv2

    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    columns, rows = (int(n) for n in inner_corners)
    ok, corners = cv2.findChessboardCornersSB(np.ascontiguousarray(grey.astype(np.uint8)), (columns, rows),
                                              cv2.CALIB_CB_ACCURACY)
    if not ok:
        return None, f"no {columns}x{rows} checkerboard"
    corners = corners.reshape(-1, 2)
    if corners[-1, 0] + corners[-1, 1] < corners[0, 0] + corners[0, 1]:
        corners = corners[::-1]  # the board's plane axes run right and down the image, as the image's do
    plane = np.stack(np.meshgrid(np.arange(columns), np.arange(rows)), axis=-1).reshape(-1, 2) * square_m
    found = _plane_from_points(corners, plane, BOARD_CORNER_MIN_SE_PX, f"checkerboard {columns}x{rows}")
    return found, found.source


def tilt_bias(radius_px, rows_px, max_tilt_deg=None, distance_m=None, height_span_m=None):
    """How large the relative scale bias over a drop can be without a plane target, for the report.

    From the keystone: a camera tilted about the horizontal axis images the ball larger where it is
    nearer; the tracked radius' linear trend with image row, over the rows the drop spans, gives the
    relative scale difference between top and bottom, and half of it is the bias of a single scale at
    the ends. Without radii, from an assumed largest tilt θ: the scale varies as 1 + tan θ · Δ/D over a
    height span Δ at distance D.

    Parameters
    ----------
    radius_px, rows_px : numpy.ndarray
        Tracked radius and centre row per clean frame, px.
    max_tilt_deg, distance_m, height_span_m : float, optional
        The assumed largest tilt (degrees), the camera's distance and the drop's height span (m),
        used when the radii do not tell (too few or too little spread).

    Returns
    -------
    (float, float, str)
        The relative scale difference bottom − top over the drop (dimensionless; radius trend), its
        standard error, and a sentence for the report.
    """
    radius_px, rows_px = np.asarray(radius_px, float), np.asarray(rows_px, float)
    good = np.isfinite(radius_px) & np.isfinite(rows_px)
    if good.sum() >= 10 and np.ptp(rows_px[good]) > 0:
        design = np.column_stack([np.ones(good.sum()), rows_px[good] - rows_px[good].mean()])
        coef, *_ = np.linalg.lstsq(design, radius_px[good], rcond=None)
        residual = radius_px[good] - design @ coef
        slope_se = float(np.sqrt(residual @ residual / (good.sum() - 2) / np.sum(design[:, 1] ** 2)))
        span, mean = float(np.ptp(rows_px[good])), float(coef[0])
        difference, se = float(coef[1]) * span / mean, slope_se * span / mean
        return difference, se, (f"keystone: the ball's tracked radius changes by {100 * difference:+.2f} % "
                                f"± {100 * se:.2f} % from the top to the bottom of the drop; a single scale is off "
                                f"by up to half that at the ends (a plane target removes it)")
    if None not in (max_tilt_deg, distance_m, height_span_m):
        difference = float(np.tan(np.radians(max_tilt_deg)) * height_span_m / distance_m)
        return difference, 0.0, (f"a tilt of up to {max_tilt_deg:g}° at {distance_m:g} m over {height_span_m:g} m "
                                 f"changes the scale by up to {100 * difference:.2f} % from top to bottom")
    return float("nan"), float("nan"), "tilt bias unknown: too few tracked radii and no assumed tilt"
