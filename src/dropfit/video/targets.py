"""Scales and plane maps from targets of known size in view: two points a known distance apart, a
printed ArUco markers and a checkerboard; and the tilt bias of a scale without one.

Pure functions on images and numbers (no file I/O).

Markers spread over the drop's plane, or a board, give more than a scale: the homography H from image
pixels to metric plane coordinates, so a camera not square to that plane is corrected by mapping the
tracked centres through H (:func:`to_plane`). The scale it reports is the local one, √|det J| of the
image→plane map (m/px), with its standard error from H's covariance (:func:`local_scale_and_se`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

#: Standard error of a point clicked by hand, px, per coordinate.
CLICK_SE_PX = 1.0
#: Fewest px of standard error of an ArUco corner, per coordinate, taken from the crossing of its edges'
#: fitted lines (0.08 px rms against phonesim's truth for markers 40 px across; one marker's 4 corners
#: leave too few residuals to measure it by).
MARKER_CORNER_SE_PX = 0.1
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
        (first marker's) first edge, y along its second).
    homography_cov : numpy.ndarray
        9×9 covariance of ``homography``'s entries (row by row), from the corners' fit.
    scale_m_per_px, scale_se_m_per_px : float
        Local scale at the target's centre, m/px, and its standard error.
    centre_px : numpy.ndarray
        The target's centre in the image, px.
    corrects_tilt : bool
        Whether the map has perspective terms; a single marker gives an affine map only (scale,
        rotation, shear), which leaves a tilted camera's keystone in.
    source : str
        What was found (``aruco DICT_4X4_50 ids 0 1 2 3``, ``checkerboard 9x6``).
    """

    homography: np.ndarray
    homography_cov: np.ndarray
    scale_m_per_px: float
    scale_se_m_per_px: float
    centre_px: np.ndarray
    corrects_tilt: bool
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
    """Scale of the image→plane map at ``point_px``, m/px: √|det J| (the geometric mean of its two axes),
    |det J| = |det H| / |w|³ with w the point's homogeneous weight."""
    homography = np.asarray(homography, dtype=float)
    weight = homography[2] @ np.append(np.asarray(point_px, dtype=float), 1.0)
    return float(np.sqrt(abs(np.linalg.det(homography)) / abs(weight) ** 3))


def local_scale_and_se(homography, homography_cov, point_px):
    """Local scale (m/px) of the image→plane ``homography`` at ``point_px`` and its standard error from
    ``homography_cov`` (9×9, its entries row by row): d ln s = ½ tr(H⁻¹ dH) − (3/2) dw / w."""
    point = np.append(np.asarray(point_px, dtype=float), 1.0)
    weight = homography[2] @ point
    gradient = 0.5 * np.linalg.inv(homography).T
    gradient[2] -= 1.5 * point / weight
    scale = local_scale(homography, point_px)
    return scale, scale * float(np.sqrt(gradient.ravel() @ homography_cov @ gradient.ravel()))


def _fit_plane(image_px, plane_m, corner_se_px, source, perspective=True):
    """Least-squares image→plane map from groups of matched points, residuals in image px.

    Parameters
    ----------
    image_px, plane_m : list of numpy.ndarray
        Per printed object, its points in the image (px) and on the plane (m), shape (m, 2). The first
        object's plane points are fixed (they define the plane's axes); each further object's are known
        up to an in-plane pose (x, y in m, rotation), fitted jointly with the map.
    corner_se_px : float
        Fewest px of standard error per point coordinate (the residuals' scatter when larger).
    source : str
        What was found.
    perspective : bool
        Fit a homography (8 parameters); else an affine map (6), which does not extrapolate a perspective
        that points over a small area determine badly.

    Returns
    -------
    (PlaneCalibration, float)
        The calibration (covariance from the fit with the corners' se) and the residuals' rms, px.
    """
    from scipy.optimize import least_squares

    points = np.concatenate(image_px)
    centre = points.mean(axis=0)
    spread = float(np.sqrt(np.mean(np.sum((points - centre) ** 2, axis=1))))
    # fitted in image coordinates centred and divided by their spread: parameters of order one
    normalise = np.array([[1 / spread, 0, -centre[0] / spread], [0, 1 / spread, -centre[1] / spread], [0, 0, 1]])
    normalised = [to_plane(normalise, group) for group in image_px]
    n_map = 8 if perspective else 6

    def unpack(params):
        homography = np.append(np.concatenate([params[:n_map], np.zeros(8 - n_map)]), 1.0).reshape(3, 3)
        return homography, params[n_map:].reshape(-1, 3)

    def placed(local_m, pose):
        cos, sin = np.cos(pose[2]), np.sin(pose[2])
        return local_m @ np.array([[cos, sin], [-sin, cos]]) + pose[:2]

    def residuals(params):
        homography, poses = unpack(params)
        to_image = np.linalg.inv(homography)
        on_plane = [plane_m[0], *(placed(local, pose) for local, pose in zip(plane_m[1:], poses))]
        return spread * np.concatenate([(to_plane(to_image, plane) - image).ravel()
                                        for plane, image in zip(on_plane, normalised)])

    # start: the first object's affine map, the others placed where it puts them
    design = np.column_stack([normalised[0], np.ones(len(normalised[0]))])
    affine = np.linalg.lstsq(design, plane_m[0], rcond=None)[0].T
    start = [affine.ravel(), np.zeros(n_map - 6)]
    for image, local in zip(normalised[1:], plane_m[1:]):
        mapped = image @ affine[:, :2].T + affine[:, 2]
        local_c, mapped_c = local - local.mean(axis=0), mapped - mapped.mean(axis=0)
        angle = np.arctan2(np.sum(local_c[:, 0] * mapped_c[:, 1] - local_c[:, 1] * mapped_c[:, 0]),
                           np.sum(local_c * mapped_c))
        start.append([*(mapped.mean(axis=0) - placed(local.mean(axis=0, keepdims=True), [0, 0, angle])[0]), angle])
    fit = least_squares(residuals, np.concatenate(start), method="lm", x_scale="jac")
    dof = fit.fun.size - fit.x.size
    rms_px = float(np.sqrt(np.sum(fit.fun ** 2) / dof)) if dof > 0 else 0.0
    parameter_cov = max(rms_px, corner_se_px) ** 2 * np.linalg.pinv(fit.jac.T @ fit.jac)
    # the map in px: H = H_normalised · N, linear in the fitted entries
    homography = unpack(fit.x)[0] @ normalise
    entry_jacobian = np.stack([(np.eye(9)[i].reshape(3, 3) @ normalise).ravel() for i in range(n_map)], axis=1)
    homography_cov = entry_jacobian @ parameter_cov[:n_map, :n_map] @ entry_jacobian.T
    scale, scale_se = local_scale_and_se(homography, homography_cov, centre)
    return PlaneCalibration(homography, homography_cov, scale, scale_se, centre, perspective, source), rms_px


def _edge_refined_corners(grey, corners_px, bits):
    """A marker's corners (4, 2 px, ArUco order) as the crossings of its four outer edges, each a straight
    line through the sub-pixel mid-level crossings of grey profiles across it (a corner detector is
    biased on an L-shaped corner by a few tenths of a px, i.e. a per cent of a small marker's side).

    ``bits`` is the marker's side in bits, border included: the profiles reach half a bit each side of the
    edge (the black border inside, the white paper outside) and stay a bit clear of the corners.
    """
    from .opencv import cv2

    lines = []
    centre = corners_px.mean(axis=0)
    for start, end in zip(corners_px, np.roll(corners_px, -1, axis=0)):
        length = float(np.hypot(*(end - start)))
        along = (end - start) / length
        normal = np.array([-along[1], along[0]])
        normal = normal if normal @ (start - centre) > 0 else -normal  # outwards, dark → light
        bit_px = length / bits
        fractions = np.linspace(1.0 / bits, 1.0 - 1.0 / bits, max(int(length * (1 - 2.0 / bits)), 3))
        offsets = np.linspace(-0.5 * bit_px, 0.5 * bit_px, 25)
        feet = start + np.outer(fractions, end - start)
        samples = (feet[:, None, :] + offsets[None, :, None] * normal).astype(np.float32)
        profiles = cv2.remap(grey.astype(np.float32), samples[..., 0], samples[..., 1], cv2.INTER_LINEAR)
        ends = max(len(offsets) // 5, 1)
        half = 0.5 * (profiles[:, :ends].mean(axis=1) + profiles[:, -ends:].mean(axis=1))
        points = []
        for foot, profile, level in zip(feet, profiles, half):
            above = np.flatnonzero((profile[:-1] < level) & (profile[1:] >= level))
            if len(above) == 1:  # a single crossing: the edge, not a bit's
                i = above[0]
                offset = offsets[i] + (level - profile[i]) / (profile[i + 1] - profile[i]) * (offsets[1] - offsets[0])
                points.append(foot + offset * normal)
        if len(points) < 3:
            return corners_px
        points = np.array(points)
        mean = points.mean(axis=0)
        direction = np.linalg.svd(points - mean, full_matrices=False)[2][0]
        lines.append(np.cross([*mean, 1.0], [*(mean + direction), 1.0]))  # homogeneous line
    # corner i is where the edge ending at it (i − 1 → i) meets the edge starting at it
    crossings = [np.cross(lines[i - 1], lines[i]) for i in range(4)]
    return np.array([point[:2] / point[2] for point in crossings])


def aruco_plane(image, marker_size_m, dictionary=None):
    """Image→plane map and scale from the printed ArUco markers in view, all of one size.

    Their placement on the plane is not known: one homography and each further marker's in-plane pose
    (x, y, rotation) are fitted to all their corners together, so markers spread over the view pin the
    perspective down. A single marker gives an affine map (scale, rotation, shear) only: its perspective
    terms, from 4 corners over a few tens of px, would be extrapolated over the whole drop.

    Parameters
    ----------
    image : numpy.ndarray
        Grey or BGR image (the background).
    marker_size_m : float
        The markers' printed side in m (the black square's outer edge).
    dictionary : str, optional
        An OpenCV ArUco dictionary name (``DICT_4X4_50``); default: the first of
        :data:`ARUCO_DICTIONARIES` with a marker in view.

    Returns
    -------
    (PlaneCalibration or None, str)
        The calibration (plane origin at the largest marker's top-left corner; corners' se from the fit's
        residuals, at least :data:`MARKER_CORNER_SE_PX`), or None, and a sentence saying what was found.
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
        bits = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)).markerSize + 2  # with the border
        corners = [_edge_refined_corners(grey, c.reshape(4, 2).astype(float), bits) for c in corners]
        ids = [int(i) for i in np.ravel(ids)]
        order = np.argsort([-cv2.contourArea(c.astype(np.float32)) for c in corners], kind="stable")
        square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) * marker_size_m
        found, rms_px = _fit_plane([corners[i] for i in order], [square] * len(order), MARKER_CORNER_SE_PX,
                                   f"aruco {name} id{'s' if len(ids) > 1 else ''} "
                                   + " ".join(str(ids[i]) for i in order), perspective=len(ids) > 1)
        if found.corrects_tilt:
            return found, (f"{found.source}: {len(ids)} markers fitted together (one homography, each marker's "
                           f"place on the plane), corners {rms_px:.2f} px rms")
        return found, (f"{found.source}: one marker, so scale and in-plane rotation only: the camera's tilt is "
                       f"not corrected (a second marker far from it would)")
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
    found, _ = _fit_plane([corners.astype(float)], [plane], BOARD_CORNER_MIN_SE_PX, f"checkerboard {columns}x{rows}")
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
