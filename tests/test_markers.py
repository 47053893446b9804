"""Plane targets: a printed ArUco marker and a checkerboard seen by a tilted pinhole camera (drawn
from the truth), two clicked points, and the tilt bias of a scale without a target."""

import cv2
import numpy as np
import pandas as pd
import pytest

from dropfit.errors import InputError
from dropfit.video.targets import (CLICK_SE_PX, aruco_plane, board_plane, local_scale, local_scale_and_se,
                                   tilt_bias, to_plane, two_point_scale)
from helpers import phone_clip

#: A target's scale must match the truth to this relative accuracy ...
TARGET_SCALE_RTOL = 0.005  # 1 (0.5 %)
#: ... and lie within this many of its own standard errors of it.
TARGET_ERROR_IN_SE = 4.0  # 1
#: Known plane points over the target (and half its size beyond) must map back to within this, m.
PLANE_POINT_TOL_M = 5e-4  # m
#: ... a single marker's four corners (0.2 px each at 2.2 mm/px, extrapolated 1.5 sides) to this, m.
MARKER_POINT_TOL_M = 1.5e-3  # m
#: Plane raster the targets are drawn on before the camera's warp, px/m.
RASTER_PX_PER_M = 4000.0  # px/m
#: The camera's image is drawn at this many times its resolution and area-averaged down.
SUPERSAMPLING = 4


def tilted_camera(tilt_deg, distance_m=2.0, focal_px=900.0, size_px=(640, 720)):
    """Homography plane (m, y down the plane) → image (px) of a pinhole camera ``distance_m`` from the
    plane, tilted by ``tilt_deg`` about the horizontal axis, looking at the plane point (0.3, 0.5) m."""
    angle = np.radians(tilt_deg)
    rotation = np.array([[1, 0, 0], [0, np.cos(angle), -np.sin(angle)], [0, np.sin(angle), np.cos(angle)]])
    camera = np.array([[focal_px, 0, size_px[0] / 2], [0, focal_px, size_px[1] / 2], [0, 0, 1]])
    to_centre = np.array([[1, 0, -0.3], [0, 1, -0.5], [0, 0, 1]])
    return camera @ np.column_stack([rotation[:, 0], rotation[:, 1], [0, 0, distance_m]]) @ to_centre


def draw_on_plane(target, origin_m, plane_to_image, size_px=(640, 720), seed=0):
    """A grey image: ``target`` (grey, RASTER_PX_PER_M) placed with its top-left at ``origin_m`` on a
    light plane, seen through ``plane_to_image``, with blur and noise."""
    # raster pixel i is centred on origin + (i + ½)/R; drawn at SUPERSAMPLING × the image's resolution
    # (big pixel j is centred on image coordinate (j + ½)/S − ½) and area-averaged down
    raster_to_plane = np.array([[1 / RASTER_PX_PER_M, 0, origin_m[0] + 0.5 / RASTER_PX_PER_M],
                                [0, 1 / RASTER_PX_PER_M, origin_m[1] + 0.5 / RASTER_PX_PER_M], [0, 0, 1]])
    big = np.array([[SUPERSAMPLING, 0, 0.5 * SUPERSAMPLING - 0.5], [0, SUPERSAMPLING, 0.5 * SUPERSAMPLING - 0.5],
                    [0, 0, 1]])
    warp = big @ plane_to_image @ raster_to_plane
    big_size = (size_px[0] * SUPERSAMPLING, size_px[1] * SUPERSAMPLING)
    mask = cv2.warpPerspective(np.ones_like(target, np.float32), warp, big_size, flags=cv2.INTER_LINEAR)
    drawn = cv2.warpPerspective(target.astype(np.float32), warp, big_size, flags=cv2.INTER_LINEAR)
    image = cv2.resize(200.0 * (1 - mask) + drawn, size_px, interpolation=cv2.INTER_AREA)
    image = cv2.GaussianBlur(image, (0, 0), 0.6) + np.random.default_rng(seed).normal(0, 2.0, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8)


def aruco_target(side_m, marker_id=7):
    """A DICT_4X4_50 marker of side ``side_m`` on a white margin of a quarter side, and the margin in m."""
    side_px = int(round(side_m * RASTER_PX_PER_M))
    marker = cv2.aruco.generateImageMarker(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), marker_id, side_px)
    margin = side_px // 4
    return np.pad(marker, margin, constant_values=255), margin / RASTER_PX_PER_M


def checkerboard(squares, square_m):
    """A checkerboard of ``squares`` (columns, rows) with a white margin of one square; the margin in m."""
    side = int(round(square_m * RASTER_PX_PER_M))
    pattern = (np.add.outer(np.arange(squares[1]), np.arange(squares[0])) % 2 * 255).astype(np.uint8)
    return np.pad(np.kron(pattern, np.ones((side, side), np.uint8)), side, constant_values=255), square_m


def _check_scale(found, plane_to_image):
    """``found``'s scale at its centre against the true camera's; returns the relative error."""
    truth = local_scale(np.linalg.inv(plane_to_image), found.centre_px)
    error = found.scale_m_per_px / truth - 1.0
    assert abs(error) < TARGET_SCALE_RTOL
    assert abs(error) < TARGET_ERROR_IN_SE * found.scale_se_m_per_px / truth
    return error


def _check_plane(found, plane_to_image, corner_m, size_m, tolerance_m=PLANE_POINT_TOL_M):
    """Scale and plane points of ``found`` against the true camera; its plane's origin at ``corner_m``,
    the target ``size_m`` across (a homography extrapolated far beyond its target amplifies corner noise)."""
    error = _check_scale(found, plane_to_image)
    plane = corner_m + size_m * np.array([[0.0, 0.0], [1.0, 1.0], [-0.5, 0.5], [1.5, -0.5], [0.3, 1.5]])
    image = to_plane(plane_to_image, plane)
    assert np.abs(to_plane(found.homography, image) - (plane - corner_m)).max() < tolerance_m
    return error


@pytest.mark.parametrize("tilt_deg", [0.0, 20.0])
def test_one_aruco_marker_gives_scale_and_an_affine_map(tilt_deg):
    """One marker's map has no perspective: right at the marker, and square-on over the plane, but a tilt
    is left in (and said)."""
    camera = tilted_camera(tilt_deg)
    marker, margin = aruco_target(0.2)
    origin = np.array([0.35, 0.6])
    found, note = aruco_plane(draw_on_plane(marker, origin, camera), 0.2)
    assert found is not None, note
    assert "DICT_4X4_50 id 7" in found.source
    assert not found.corrects_tilt and "tilt is not corrected" in note
    if tilt_deg:
        _check_scale(found, camera)
    else:
        _check_plane(found, camera, origin + margin, 0.2, MARKER_POINT_TOL_M)


#: The phonesim clip of the plane tests: a tilted camera and four ArUco markers of this side (m) in the plane.
TILTED_PRESET, TILTED_MARKER_M = "tennis_aruco_tilted", 0.08
#: The found plane's heights of the truth's ball centres must match the truth's to this, m.
TRUTH_HEIGHT_TOL_M = 1e-3  # m


@pytest.fixture(scope="module")
def tilted_clip(tmp_path_factory):
    """phonesim's tilted-camera clip (seed 1, half size): its first frame and its per-frame truth."""
    path, truth = phone_clip(TILTED_PRESET, tmp_path_factory.mktemp("tilted"), seed=1, downscale=0.5)
    capture = cv2.VideoCapture(str(path))
    ok, frame = capture.read()
    capture.release()
    assert ok
    return frame, truth, pd.read_csv(path.with_suffix(".frames.csv"))


def test_markers_fitted_together_map_a_tilted_drop(tilted_clip):
    """All four markers (their placement unknown) give the plane: the truth's ball centres mapped through
    it have the truth's heights, and the scale at the drop is the truth's, within its se."""
    frame, truth, frames = tilted_clip
    found, note = aruco_plane(frame, TILTED_MARKER_M)
    assert found is not None and found.corrects_tilt, note
    assert "4 markers" in note
    flying = frames[frames["in_frame"] & (frames["phase"] != "held")]
    centres_px = flying[["x_px", "y_px"]].to_numpy()
    true_image_to_plane = np.linalg.inv(truth["camera"]["plane_to_px"])
    for point in centres_px[[np.argmin(centres_px[:, 1]), np.argmax(centres_px[:, 1])]]:  # top and bottom
        scale, se = local_scale_and_se(found.homography, found.homography_cov, point)
        error = scale / local_scale(true_image_to_plane, point) - 1.0
        assert abs(error) < TARGET_SCALE_RTOL and abs(error) < TARGET_ERROR_IN_SE * se / scale
    # heights along the found plane's axis nearest the truth's vertical, up to the plane's origin
    plane_m = to_plane(found.homography, centres_px)
    true_heights = flying["centre_height_m"].to_numpy()
    direction = np.linalg.lstsq(plane_m - plane_m.mean(axis=0), true_heights - true_heights.mean(), rcond=None)[0]
    assert np.linalg.norm(direction) == pytest.approx(1.0, abs=TARGET_SCALE_RTOL)
    heights = (plane_m - plane_m.mean(axis=0)) @ (direction / np.linalg.norm(direction))
    assert np.abs(heights - (true_heights - true_heights.mean())).max() < TRUTH_HEIGHT_TOL_M


def test_one_marker_in_the_tilted_clip_says_the_tilt_is_left_in(tilted_clip):
    frame, truth, _ = tilted_clip
    corners = np.array(truth["objects"]["markers"][0]["corners_px"])
    keep = np.zeros(frame.shape[:2], np.uint8)
    cv2.fillConvexPoly(keep, np.round(corners.mean(axis=0) + 1.5 * (corners - corners.mean(axis=0))).astype(np.int32), 1)
    found, note = aruco_plane(np.where(keep[..., None] > 0, frame, 128).astype(np.uint8), TILTED_MARKER_M)
    assert found is not None and not found.corrects_tilt and "tilt is not corrected" in note
    _check_scale(found, np.array(truth["camera"]["plane_to_px"]))


@pytest.mark.parametrize("tilt_deg", [0.0, 25.0])
def test_checkerboard_gives_scale_and_plane_map(tilt_deg):
    camera = tilted_camera(tilt_deg)
    board, margin = checkerboard((8, 6), 0.03)
    origin = np.array([0.05, 0.1])
    found, note = board_plane(draw_on_plane(board, origin, camera), 0.03, (7, 5))
    assert found is not None, note
    _check_plane(found, camera, origin + margin + 0.03, np.array([0.18, 0.12]))  # first inner corner: one square in


def test_tilted_camera_heights_are_corrected_through_the_homography():
    """A 1 m drop seen 20° tilted beside a board of 10 cm squares spanning it: one scale misreads heights
    by centimetres, the board's homography gives them to PLANE_POINT_TOL_M."""
    camera = tilted_camera(20.0)
    board, margin = checkerboard((6, 12), 0.1)
    origin = np.array([-0.2, -0.1])
    found, note = board_plane(draw_on_plane(board, origin, camera), 0.1, (5, 11))
    assert found is not None, note
    plane = np.column_stack([np.full(21, 0.3), np.linspace(0.0, 1.0, 21)])  # y down the plane, m
    image = to_plane(camera, plane)
    corrected = to_plane(found.homography, image)[:, 1]
    single = (image[:, 1] - image[0, 1]) * found.scale_m_per_px
    assert np.abs((corrected - corrected[0]) - plane[:, 1]).max() < PLANE_POINT_TOL_M
    assert np.abs(single - plane[:, 1]).max() > 20 * PLANE_POINT_TOL_M


def test_no_marker_is_said():
    found, note = aruco_plane(np.full((200, 200), 128, np.uint8), 0.1)
    assert found is None and note.startswith("no ArUco")
    found, note = board_plane(np.full((200, 200), 128, np.uint8), 0.03, (7, 5))
    assert found is None and "checkerboard" in note


def test_two_points_give_the_scale_with_the_click_uncertainty():
    scale, se = two_point_scale([[100.0, 50.0], [100.0, 450.0]], 1.0)
    assert scale == pytest.approx(1.0 / 400.0)
    assert se / scale == pytest.approx(np.sqrt(2) * CLICK_SE_PX / 400.0)
    with pytest.raises(InputError, match="coincide"):
        two_point_scale([[1, 2], [1, 2]], 1.0)


def test_tilt_bias_from_the_radius_trend_and_from_an_assumed_tilt():
    rows = np.linspace(50, 450, 40)
    radius = 20.0 * (1 + 0.02 * (rows - 250) / 400) + np.random.default_rng(1).normal(0, 0.02, rows.size)
    difference, se, note = tilt_bias(radius, rows)
    assert difference == pytest.approx(0.02, abs=4 * se)
    assert "keystone" in note
    difference, _, note = tilt_bias([], [], max_tilt_deg=1.0, distance_m=3.0, height_span_m=2.5)
    assert difference == pytest.approx(np.tan(np.radians(1.0)) * 2.5 / 3.0)
