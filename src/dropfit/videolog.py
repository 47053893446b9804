"""Videos: track the ball and calibrate pixels to metres and frames to seconds, giving the same
trajectory as a height log.

Scales come from up to six sources (:mod:`dropfit.video.calibrate`, :mod:`dropfit.video.targets`): a
given scale, two points a known distance apart (``scale_points_px``), a printed ArUco marker or a
checkerboard of known size (a *target*), a ruler's ticks in the background (with ``ruler_tick_m``),
gravity (the flights' shared acceleration in px/s², quadratic drag included, over g) and the ball's
known diameter (its tracked radius in px against its radius in m). The one used is the first
available in the precedence given > points > target > ruler > gravity > diameter (what the user
states first, then by accuracy: see :mod:`dropfit.video.calibrate`); every other one is stored with
its disagreement relative to it. g arbitrates the scales measured in the image: a target, ruler or
diameter that disagrees with gravity's scale is suspect (``scale_suspect_<source>``: its likely cause),
and gravity's is used, however uncertain (its error goes into the heights, not into e).

A target in the ball's plane also gives the map from the image to that plane: the tracked centres
are mapped through it, so a camera that is not square to the plane of the drop is corrected. The
plane's vertical is the principal axis of the ball's track in it (a drop: its horizontal travel
is small against its fall), pointing up where the image's rows point down. Without a target, the
trend of the tracked radius with the image row tells how far a single scale can be off
(``tilt_note``, :func:`dropfit.video.targets.tilt_bias`); an upright ruler measures the keystone of
a camera tilted about its horizontal axis (the scale changing along the image's height), and the
tracked rows and the floor's row are rectified with it (:func:`dropfit.video.calibrate.rectify_rows`)
before any scale applies. The chosen scale's relative standard error (``scale_rel_se``; 0 for a
given scale) goes with the trajectory, and the analysis adds its effect on every impact quantity
(heights, and through the fitted drag also e, flight times and their ratios) to their covariance.

Time: a slow-motion file's container rate may be a playback rate. With a scale that does not
come from gravity, the flights' acceleration in the file's time gives the capture rate, snapped to a
common camera rate (the flights searched again at the common rates' slowdowns where the file's time
hides them); ``capture_fps`` overrides it. Without such a scale, a clip whose gravity scale makes the
ball larger than any ball is refused as slow motion, with the capture rate it would have.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .video import limits as video_limits
from .video.calibrate import (ARBITRATED_SCALES, COMMON_CAPTURE_RATES_FPS, MIN_SLOW_MOTION_FACTOR, SCALE_PRECEDENCE,
                              choose_scale, diameter_conflict, infer_capture_rate, rectify_rows, ruler_scale,
                              scales_agree, slow_motion_reading)
from .video.targets import aruco_plane, board_plane, local_scale_and_se, tilt_bias, to_plane, two_point_scale
from .video.quality import speed_dependent_centre_error_px
from .errors import InputError, shown_path
from .heightlog import check_floor, flight_acceleration, make_trajectory, nominal_drag_of, scale_from_gravity
from .numerics import robust_sigma
from .physics import STANDARD_GRAVITY_M_S2

VIDEO_SUFFIXES = (".avi", ".mp4", ".mov", ".mkv", ".m4v")
#: Standard error of the floor row found in the image relative to the tracked ball centres, px: the
#: sub-pixel edge and centroid biases on the rendered 2000 fps close-up are up to 0.03 px. A real
#: floor seen in perspective can be off by more: give floor_m when it matters.
FLOOR_ROW_SE_PX = 0.05


@dataclass(frozen=True)
class ScaleTargets:
    """What the user put in view, or clicked, to give a video's scale (each optional).

    Attributes
    ----------
    points_px : ((float, float), (float, float)), optional
        Two points of the displayed frame, px, ``distance_m`` apart (m).
    distance_m : float, optional
    marker_size_m : float, optional
        Printed side of an ArUco marker in the ball's plane, m.
    board_square_m : float, optional
        Side of a checkerboard's squares in the ball's plane, m, with ``board_inner_corners``
        (inner corners per row, per column).
    board_inner_corners : (int, int), optional
    """

    points_px: tuple | None = None
    distance_m: float | None = None
    marker_size_m: float | None = None
    board_square_m: float | None = None
    board_inner_corners: tuple | None = None


def scale_targets_of(settings):
    """The :class:`ScaleTargets` a :class:`dropfit.settings.Settings` gives."""
    return ScaleTargets(settings.scale_points(), settings.scale_distance_m, settings.marker_size_m,
                        settings.board_square_m, settings.board_corners())


def is_video(path):
    """True if ``path`` names a video file (by its suffix)."""
    return str(path).lower().endswith(VIDEO_SUFFIXES)


#: Relative standard error of a tracked radius as a measure of the ball's size (dimensionless), whatever its
#: scatter from frame to frame: the edge a tracker finds moves with the ball's shading, blur, colour and the
#: codec. On phonesim's colour clips (yellow at 120 fps, red blurred at 30 fps, H.264 and lossless; 9 clips)
#: the diameter scale was −2.2 % to +3.1 % off the truth's, where the radius's scatter alone said 0.05 %.
DIAMETER_SCALE_RELATIVE_SE = 0.02


def scale_from_diameter(radius_px, ball_radius_m):
    """Metres per pixel from the tracked ball radius.

    Parameters
    ----------
    radius_px : numpy.ndarray
        Tracked radius per frame in px (clean frames only).
    ball_radius_m : float
        The ball's radius in m.

    Returns
    -------
    (float, float)
        Scale in m/px and its standard error: the median radius's (robust spread over √n) and
        :data:`DIAMETER_SCALE_RELATIVE_SE`, combined.
    """
    radius_px = radius_px[np.isfinite(radius_px)]
    median = float(np.median(radius_px))
    spread = robust_sigma(radius_px, centre=median)
    median_se = 1.2533 * spread / np.sqrt(radius_px.size)
    scale = ball_radius_m / median
    return scale, scale * float(np.hypot(median_se / median, DIAMETER_SCALE_RELATIVE_SE))


def find_floor_row(background_grey, bottom_row_px, radius_px):
    """Image row (px, sub-pixel) of the floor's edge, searched within one ball radius of ``bottom_row_px``.

    The floor is the strongest horizontal edge of the background (the tracker's, in grey) near the
    lowest row the ball's bottom reaches. Its sub-pixel row is read in each column from how much of
    the pixels about the edge the floor covers, between the column's own levels just above and
    just below, and is the median over the columns that show the edge: what stands on the floor
    (a ruler, a wall's texture) changes the level above from column to column, and a halfway level
    taken from the rows' means was crossed 0.13 px off the edge on the coverage clips. The levels
    are taken as flat over the four rows either side: light that falls off by g grey levels a row
    moves the row found by about 2.5 g / (the edge's contrast) px.

    Returns
    -------
    float or None
        The row, or None if no clear edge is there.
    """
    grey = np.asarray(background_grey, dtype=float)
    profile = np.median(grey, axis=1)  # a ruler's ticks, in a few columns, leave it as the wall is
    low = max(int(bottom_row_px - radius_px), 8)
    high = min(int(bottom_row_px + radius_px), profile.size - 9)
    if high <= low:
        return None
    step = np.abs(np.diff(profile[low - 1: high + 2]))
    edge = low - 1 + int(np.argmax(step))  # the edge lies between rows edge and edge + 1
    above, below = np.median(profile[edge - 7: edge - 2]), np.median(profile[edge + 3: edge + 8])
    if abs(below - above) < 10 * np.std(profile[edge - 7: edge - 2]) + 1.0:
        return None
    # each column: its own levels above and below, from three rows either side of the four rows
    # around the edge; a column whose levels vary there (a ruler's tick at the floor) is left out
    rows_above, rows_below = grey[edge - 4: edge - 1], grey[edge + 3: edge + 6]
    column_above, column_below = np.median(rows_above, axis=0), np.median(rows_below, axis=0)
    contrast = column_below - column_above
    steady = np.maximum(np.ptp(rows_above, axis=0), np.ptp(rows_below, axis=0)) < 0.25 * abs(below - above)
    clear = steady & (np.sign(below - above) * contrast > 0.5 * abs(below - above))
    if not clear.any():
        return None
    # the part of each pixel the floor covers is its level's step of the way from above to below: the
    # floor's cover of rows edge - 1 … edge + 2 adds up to (edge + 2.5) − the edge's row, whatever the
    # edge's sub-pixel place (the rows' halfway crossing is off by up to 0.1 px between pixel centres)
    covered = (grey[edge - 1: edge + 3, clear] - column_above[clear]) / contrast[clear]
    return float(np.median(edge + 2.5 - covered.sum(axis=0)))


def trajectory_from_video(path, ball_radius_m=None, scale_m_per_px=None, capture_fps=None,
                          gravity_m_s2=STANDARD_GRAVITY_M_S2, attrs=None, ruler_tick_m=None, targets=None,
                          tracked=None):
    """Track the ball in a drop-test video and return the trajectory dataset (heights in m, up).

    Parameters
    ----------
    path : str or pathlib.Path
        The video file.
    ball_radius_m : float, optional
        Ball radius in m, for the scale from the ball's diameter.
    scale_m_per_px : float, optional
        Known scale in m/px (positive); takes precedence over every calibration.
    capture_fps : float, optional
        Capture rate in frames per second of a slow-motion file whose container rate differs;
        overrides the rate inferred from gravity.
    gravity_m_s2 : float
        Gravity in m/s².
    attrs : dict, optional
        Extra attributes for the dataset.
    ruler_tick_m : float, optional
        Spacing in m of the finest ticks of a ruler in the ball's plane, for the scale from the ruler.
    targets : ScaleTargets, optional
        Two points a known distance apart, an ArUco marker's or a checkerboard's size.
    tracked : dropfit.video.track.TrackedVideo, optional
        The video's tracked table and background (:func:`dropfit.video.track.track_video_and_background`
        with ``capture_fps``), when the caller has tracked it already; by default it is tracked here.

    Returns
    -------
    xarray.Dataset
        As :func:`dropfit.heightlog.make_trajectory`, plus ``x`` (m), ``radius`` (m) and ``frame`` (the
        video frame of each sample, counted from 0, as in the tracked table); image rows point down, so
        heights are −row × scale (the zero is the top image row), with rows rectified by a ruler's
        keystone (``keystone_per_px``, ``keystone_se_per_px``, ``keystone_row_px``) or mapped into a
        target's plane. The attributes hold every scale found (``scale_<source>_m_per_px`` and
        ``_se_m_per_px``), the chosen
        ``scale_source``, ``scale_m_per_px`` and its relative standard error ``scale_rel_se``, the
        others' ``scale_disagreement_<source>`` (s / s_chosen − 1), the time base
        (``capture_fps``, ``capture_fps_source``, ``capture_rate_note``), the ``codec`` and the centres'
        speed-dependent error ``speed_error_px`` (px at the fastest,
        :func:`dropfit.video.quality.speed_dependent_centre_error_px`).
    """
    from .video.quality import retime_inserted_repeats
    from .video.track import mark_off_track, track_video_and_background, usable_rows

    table, background = track_video_and_background(path, capture_fps=capture_fps) if tracked is None else tracked
    # a repeated frame carries no new instant; the frames after one a recorder inserted are late by an interval
    table = retime_inserted_repeats(table)
    inserted = table.attrs.pop("inserted_repeats", [])
    # positions the ballistic track does not support are left out (a table tracked elsewhere is judged too)
    table = mark_off_track(table)
    video_limits.check_recording(table, path)  # refuse below the limits of benchmarks/video_failure_sweep.py
    usable = usable_rows(table)
    if np.count_nonzero(usable) < 10:
        raise InputError(f"{shown_path(path)}: the ball is measured cleanly in only {np.count_nonzero(usable)} of "
                         f"{len(table)} frames (at least 10 are needed)")
    targets = targets or ScaleTargets()
    x_px = np.where(usable, table["x_px"].to_numpy(), np.nan)
    rows = np.where(usable, table["y_px"].to_numpy(), np.nan)
    radius_px = table["radius_px"].to_numpy()[usable]
    extra = dict(attrs or {})
    extra.update(video=str(path), frames=int(len(table)), frames_usable=int(np.count_nonzero(usable)),
                 frames_off_track=int(table.attrs.get("off_track_frames", 0)))
    if inserted:
        extra["repeat_note"] = (f"frame{'s' if len(inserted) > 1 else ''} {', '.join(map(str, inserted))} repeat"
                                f"{'' if len(inserted) > 1 else 's'} the frame before and the ball's motion shows the "
                                f"frames after {'them' if len(inserted) > 1 else 'it'} stamped one interval late: "
                                f"their times are moved back")
    if not usable.all():
        extra["frames_unclean"] = video_limits.unclean_frames(table)
    # the ruler, the targets (in colour) and the floor are read from the background the ball was tracked against
    scene = background.image() if background is not None else None
    background = background.grey if background is not None else None
    plane = _plane_target(scene, targets, extra, path)
    scales = _independent_scales(scene if ruler_tick_m else None, radius_px, ball_radius_m, scale_m_per_px,
                                 ruler_tick_m, extra)
    if targets.points_px is not None:
        scales["points"] = two_point_scale(targets.points_px, targets.distance_m)
    conflict = _diameter_conflict(scales, radius_px)
    image_rows = rows
    if plane is not None:
        extra.pop("keystone_per_px", None)  # the target's map takes the tilt in full, or an affine one none of it
        x_px, rows, scales["target"] = _through_plane(plane, x_px, rows, extra)
    else:
        rows = _rectified(image_rows, extra)
    if "keystone_per_px" not in extra and (plane is None or not plane.corrects_tilt):
        extra["tilt_scale_difference"], _, extra["tilt_note"] = tilt_bias(radius_px, image_rows[usable])
    seen_rows = _seen_rows(table, plane, extra)
    # a scale the diameter contradicts by a factor cannot set the time base: g arbitrates them in the file's time
    time = _capture_time(table, rows, seen_rows, {} if conflict else scales, capture_fps, gravity_m_s2, extra)
    if conflict and extra["capture_fps_source"] == "container":
        extra["capture_rate_note"] = (f"the file's rate is taken as the capture rate: the {conflict[0]} scale and the "
                                      f"ball's diameter differ by a factor {max(conflict[1], 1 / conflict[1]):.3g}, "
                                      f"so neither can check it")
    if table.attrs.get("frames_note"):
        extra["frames_note"] = table.attrs["frames_note"]
    extra.update(codec=table.attrs.get("codec") or "unknown",
                 speed_error_px=speed_dependent_centre_error_px(table.attrs.get("codec"), rows, time,
                                                                table["blur_px"].to_numpy()))
    if extra["capture_fps_source"] == _RAW_RATE_SOURCE:
        extra["gravity_calibration_failed"] = "gravity set the capture rate, so it gives no independent scale"
    else:
        _add_gravity_scale(scales, time, rows, seen_rows, gravity_m_s2, path, extra)
    _check_against_diameter(path, scales, conflict, radius_px, extra)
    if not capture_fps and not any(name in scales for name in SCALE_PRECEDENCE if name != "gravity"):
        _check_time_base_by_size(path, scales, radius_px, time, rows, seen_rows, gravity_m_s2, extra)
    if not scales:
        raise InputError(f"{shown_path(path)}: no scale: give the ball radius, a ruler's tick spacing or scale_m_per_px "
                         f"({extra.get('gravity_calibration_failed', 'gravity calibration failed')})")
    chosen, scale = _record_scales(scales, extra)
    check_floor(-rows[np.isfinite(rows)] * scale, extra, path)  # a given floor, in the video's frame
    if extra.get("floor_m") is None and background is not None:
        median_radius_px = float(np.nanmedian(radius_px))
        floor_row = find_floor_row(background, float(np.nanmax(image_rows)) + median_radius_px, median_radius_px)
        if floor_row is not None:
            extra["floor_row_px"] = floor_row
            if table.attrs.get("in_colour"):
                # lit from above, a ball's shaded lower half has less colour (and brightness): its centre reads up
                # to a tenth of its radius high (phonesim's green and yellow balls: 1.4 and 0.85 px, radii near
                # 12 px), which against the floor's edge is a floor as much too low (with the true floor given, e
                # came out 5-8 standard errors high at 30 frames/s); with that in its se the floor gives e no
                # better than the contact height modelled from the flights does
                extra["floor_note"] = (f"the floor's edge is seen at image row {floor_row:.1f} but not used: the "
                                       f"ball is measured in the {table.attrs.get('contrast')} channel, where "
                                       f"shading moves its centre up to a tenth of its radius (a floor given as "
                                       f"floor_m meets the same shift); the contact height is modelled from the "
                                       f"flights")
            else:
                if plane is not None:  # the floor's edge below the drop, in the plane's rows
                    floor_row = float(_plane_rows(plane, extra, [np.nanmedian(table["x_px"])], [floor_row])[0])
                else:
                    floor_row = float(_rectified(floor_row, extra))
                extra["floor_m"] = -floor_row * scale  # heights are −row × scale
                extra["floor_se_m"] = FLOOR_ROW_SE_PX * scale
    trajectory = make_trajectory(time, -rows * scale, path, _CALIBRATION_TEXT[chosen], extra)
    trajectory["y_seen"] = ("time", -seen_rows * scale,
                            {"units": "m", "long_name": "height wherever the ball was seen, measured cleanly or not"})
    trajectory["x"] = ("time", x_px * scale, {"units": "m"})
    trajectory["radius"] = ("time", np.where(usable, table["radius_px"].to_numpy(), np.nan) * scale, {"units": "m"})
    trajectory["frame"] = ("time", table["frame"].to_numpy(), {"long_name": "video frame, counted from 0"})
    return trajectory


#: ``capture_fps_source`` of a capture rate inferred from gravity but near no common rate.
_RAW_RATE_SOURCE = f"{video_limits.GRAVITY_CAPTURE_RATE_SOURCE} (not a common rate)"
_CALIBRATION_TEXT = {"given": "given scale in m/px", "points": "scale from two points a given distance apart",
                     "target": "plane and scale from a target of known size (camera tilt corrected)",
                     "ruler": "scale from the ruler's ticks",
                     "gravity": "scale from gravity (flight curvature, drag included)",
                     "diameter": "scale from the ball's diameter"}


def _plane_target(background, targets, extra, path):
    """The marker's or board's :class:`dropfit.video.targets.PlaneCalibration` in ``background``, or None.

    Raises InputError when the user named a target that is not in view: a scale from it was asked for.
    """
    if targets.marker_size_m is None and targets.board_square_m is None:
        return None
    if background is None:
        raise InputError(f"{shown_path(path)}: the background could not be read, so the marker or board cannot be "
                         f"found; give scale_m_per_px or scale_points_px instead")
    if targets.board_square_m is not None:
        plane, note = board_plane(background, targets.board_square_m, targets.board_inner_corners)
    else:
        plane, note = aruco_plane(background, targets.marker_size_m)
    if plane is None:
        raise InputError(f"{shown_path(path)}: {note} found in the background (the scene without the ball); keep the "
                         f"target in view, flat, in the ball's plane and unobstructed for most of the clip, or give "
                         f"scale_points_px")
    extra["target_note"] = note
    return plane


def _through_plane(plane, x_px, rows_px, extra):
    """Image points mapped into the target's plane, as pixels of the plane's scale at the drop.

    Returns (x, rows, (scale, se)): horizontal and vertical plane coordinates divided by ``scale`` (m/px,
    the map's local scale at the track's centre, and its standard error), rows pointing down as the
    image's do. The map back (``plane_homography``, the unit vectors ``plane_down`` and ``plane_across``
    in plane m, ``plane_scale_m_per_px``) goes into ``extra``.
    """
    points = np.column_stack([x_px, rows_px])
    found = np.isfinite(points).all(axis=1)
    plane_m = np.full(points.shape, np.nan)
    plane_m[found] = to_plane(plane.homography, points[found])
    centre_px = np.nanmedian(points, axis=0)
    centre_m = to_plane(plane.homography, centre_px)[0]
    # the plane's vertical: the track's principal axis, oriented along the image's rows
    spread = plane_m[found] - plane_m[found].mean(axis=0)
    down = np.linalg.svd(spread, full_matrices=False)[2][0]
    image_down = to_plane(plane.homography, centre_px + (0.0, 1.0))[0] - centre_m
    down = down if down @ image_down > 0 else -down
    across = np.array([-down[1], down[0]])
    across = across if across @ (to_plane(plane.homography, centre_px + (1.0, 0.0))[0] - centre_m) > 0 else -across
    scale = local_scale_and_se(plane.homography, plane.homography_cov, centre_px)
    extra.update(plane_homography=[float(v) for v in plane.homography.ravel()], plane_down=[float(v) for v in down],
                 plane_across=[float(v) for v in across], plane_scale_m_per_px=scale[0])
    return plane_m @ across / scale[0], plane_m @ down / scale[0], scale


def _plane_rows(plane, extra, x_px, rows_px):
    """Image points' rows in the plane, as :func:`_through_plane` gives them (its map in ``extra``)."""
    plane_m = to_plane(plane.homography, np.column_stack([x_px, rows_px]))
    return plane_m @ np.asarray(extra["plane_down"]) / extra["plane_scale_m_per_px"]


def _independent_scales(background, radius_px, ball_radius_m, scale_m_per_px, ruler_tick_m, extra):
    """Scales (m/px, se) that do not depend on the time base: given, ruler, diameter; notes in ``extra``."""
    scales = {}
    if scale_m_per_px is not None:
        scales["given"] = (float(scale_m_per_px), 0.0)  # a given scale carries no stated uncertainty
    if ruler_tick_m:
        ruler, extra["ruler_note"] = ruler_scale(background, ruler_tick_m) if background is not None else \
            (None, "no ruler: the background could not be read")
        if ruler is not None:
            scales["ruler"] = (ruler.scale_m_per_px, ruler.scale_se_m_per_px)
            extra.update(ruler_tick_m=float(ruler_tick_m), ruler_ticks=ruler.n_ticks,
                         keystone_per_px=ruler.keystone_per_px, keystone_se_per_px=ruler.keystone_se_per_px,
                         keystone_row_px=ruler.keystone_row_px)
    if ball_radius_m:
        scales["diameter"] = scale_from_diameter(radius_px, ball_radius_m)
    return scales


#: What to check when a scale contradicts the ball's diameter, per source.
_CONFLICT_ADVICE = {
    "given": "check scale_m_per_px (m per px) and the ball radius (m)",
    "points": "check the two points (px) and their distance (m), and the ball radius (m)",
    "target": "check the marker's or board's size (m) and the ball radius (m)",
}


def _diameter_conflict(scales, radius_px):
    """:func:`dropfit.video.calibrate.diameter_conflict` at the median tracked radius (px)."""
    median_radius_px = float(np.nanmedian(radius_px)) if np.isfinite(radius_px).any() else np.nan
    return diameter_conflict(scales, median_radius_px)


def _check_against_diameter(path, scales, conflict, radius_px, extra):
    """InputError when the scale to be used (given, points, target, ruler) and the ball's diameter differ by
    a factor (``conflict``, :func:`dropfit.video.calibrate.diameter_conflict`) and g does not tell which is
    right: the scale is one the user stated (given, points), or gravity's agrees with neither (or is
    missing). Where gravity agrees with one, :func:`dropfit.video.calibrate.choose_scale` uses it and names
    the other suspect."""
    if conflict is None:
        return
    source, ratio = conflict
    if source in ARBITRATED_SCALES and "gravity" in scales and any(
            scales_agree(scales[name], scales["gravity"]) for name in (source, "diameter")):
        return
    median_radius_px = float(np.nanmedian(radius_px))
    if source == "ruler":
        tick_m = extra["ruler_tick_m"]
        advice = (f"the ruler's marks are not {tick_m:g} m apart ({extra['ruler_note']}): by the ball's size they are "
                  f"{tick_m / ratio:.2g} m apart; give --ruler-tick-m for the marks seen, or check the ball radius (m)")
    else:
        advice = _CONFLICT_ADVICE[source]
    gravity = (f"; gravity's scale ({1 / scales['gravity'][0]:.4g} px/m) agrees with neither" if "gravity" in scales
               else "")
    raise InputError(f"{shown_path(path)}: not analysable: the {source} scale ({1 / scales[source][0]:.4g} px/m) and "
                     f"the ball's diameter ({1 / scales['diameter'][0]:.4g} px/m: radius {median_radius_px:.1f} px) "
                     f"differ by a factor {max(ratio, 1 / ratio):.3g}{gravity}; {advice}")


def _rectified(rows_px, extra):
    """Image rows (px) rectified by the ruler's keystone recorded in ``extra``; unchanged without a ruler."""
    if "keystone_per_px" not in extra:
        return rows_px
    return rectify_rows(rows_px, extra["keystone_per_px"], extra["keystone_row_px"])


def _seen_rows(table, plane, extra):
    """Rows (px, down) of every frame with a ball centre, clean or not (occluded, shaded, blurred), through the
    plane's map or the ruler's keystone as the clean rows go; NaN where the ball was lost or its centre repeats
    the previous frame's to the bit (a held ball in a repeated capture: its run of equal rows would pass for a
    noise-free track and set the noise the bounces are judged by)."""
    x_px, rows_px = table["x_px"].to_numpy(dtype=float), table["y_px"].to_numpy(dtype=float)
    repeated = np.r_[False, (np.diff(x_px) == 0) & (np.diff(rows_px) == 0)]
    seen = np.isfinite(x_px) & np.isfinite(rows_px) & ~repeated
    if plane is None:
        return _rectified(np.where(seen, rows_px, np.nan), extra)
    rows = np.full(rows_px.shape, np.nan)
    rows[seen] = _plane_rows(plane, extra, x_px[seen], rows_px[seen])
    return rows


def _capture_time(table, rows, seen_rows, scales, capture_fps, gravity_m_s2, extra):
    """Frame times in s of capture; infer the capture rate from gravity when no rate is given.

    With a scale independent of gravity, the flights' acceleration in the file's time (found on the rows
    seen, fitted on the clean ``rows``) tells the capture rate
    (:func:`dropfit.video.calibrate.infer_capture_rate`). The flights are found with times of capture
    (a contact's clearance, the lags of a bounce's dip are in seconds), so a slow-motion clip, whose
    flights are not found in the file's time or fall far slower than g there, is searched again at the
    slowdowns of the common capture rates (:func:`_slow_motion_rate`). Notes go into ``extra``.
    """
    time = table["time_s"].to_numpy()
    file_fps = float(table.attrs.get("container_fps") or 0.0)
    if not (np.isfinite(file_fps) and file_fps > 0):
        file_fps = 1.0 / float(np.median(np.diff(time)))
    if capture_fps:
        extra.update(capture_fps=float(capture_fps), capture_fps_source="given",
                     capture_rate_note=f"capture rate {capture_fps:g} fps given ({table.attrs.get('time_source')})")
        return time
    reference = next((name for name in SCALE_PRECEDENCE if name in scales), None)
    if reference is None:
        extra.update(capture_fps=file_fps, capture_fps_source="container",
                     capture_rate_note="the file's rate is taken as the capture rate: no scale independent of "
                                       "gravity (ball radius, ruler or given scale) to check it")
        return time
    try:
        rate = infer_capture_rate(_file_time_acceleration(time, rows, seen_rows, extra, gravity_m_s2),
                                  scales[reference][0], file_fps, gravity_m_s2)
        failed = None
    except InputError as error:
        rate, failed = None, error
    if rate is None or rate["capture_fps"] >= MIN_SLOW_MOTION_FACTOR * file_fps:
        rate = _slow_motion_rate(time, rows, seen_rows, extra, gravity_m_s2, scales[reference][0], file_fps) or rate
    if rate is None:
        extra.update(capture_fps=file_fps, capture_fps_source="container",
                     capture_rate_note=f"the file's rate is taken as the capture rate ({failed})")
        return time
    source = ("container" if rate["capture_fps"] == file_fps
              else video_limits.GRAVITY_CAPTURE_RATE_SOURCE if rate["snapped"] else _RAW_RATE_SOURCE)
    extra.update(capture_fps=rate["capture_fps"], capture_fps_source=source,
                 capture_fps_estimate=rate["estimate_fps"],
                 capture_rate_note=f"{rate['why']}; length scale from the {reference}")
    return time * file_fps / rate["capture_fps"]


def _file_time_acceleration(time, rows, seen_rows, extra, gravity_m_s2, slowdown=1.0):
    """The flights' downward acceleration in px/s² of the file's time, found and fitted in the file's time
    divided by ``slowdown`` (a capture rate over the file's)."""
    _, fit = flight_acceleration(time / slowdown, rows, str(extra["video"]), *nominal_drag_of(extra), gravity_m_s2,
                                 seen_rows)
    return fit.acceleration / slowdown**2


def _slow_motion_fits(time, rows, seen_rows, extra, gravity_m_s2, file_fps):
    """(capture rate tried in frames/s, the flights' acceleration in px/s² of the file's time) for each common
    capture rate at least :data:`dropfit.video.calibrate.MIN_SLOW_MOTION_FACTOR` times the file's, in order, at
    which the flights are found (:func:`_file_time_acceleration`)."""
    for candidate in COMMON_CAPTURE_RATES_FPS:
        if candidate < MIN_SLOW_MOTION_FACTOR * file_fps:
            continue
        try:
            yield candidate, _file_time_acceleration(time, rows, seen_rows, extra, gravity_m_s2, candidate / file_fps)
        except InputError:
            continue


#: A slowdown tried for a slow-motion clip is taken when the capture rate gravity then gives is within this
#: relative distance of the rate tried (the flights found at the right time base give it back).
SLOW_MOTION_CONSISTENCY = 0.1


def _slow_motion_rate(time, rows, seen_rows, extra, gravity_m_s2, scale_m_per_px, file_fps):
    """:func:`dropfit.video.calibrate.infer_capture_rate` of the flights found in the time of a capture at a
    common rate (:data:`dropfit.video.calibrate.COMMON_CAPTURE_RATES_FPS`, slower than the file's by
    :data:`dropfit.video.calibrate.MIN_SLOW_MOTION_FACTOR` or more), the first that gives back its own rate
    within :data:`SLOW_MOTION_CONSISTENCY`; None if none does."""
    for candidate, acceleration in _slow_motion_fits(time, rows, seen_rows, extra, gravity_m_s2, file_fps):
        rate = infer_capture_rate(acceleration, scale_m_per_px, file_fps, gravity_m_s2)
        if abs(rate["estimate_fps"] / candidate - 1.0) <= SLOW_MOTION_CONSISTENCY:
            # the flights found at that rate, fitted again at the rate they give
            slowdown = rate["capture_fps"] / file_fps
            try:
                again = _file_time_acceleration(time, rows, seen_rows, extra, gravity_m_s2, slowdown)
            except InputError:
                return rate
            return infer_capture_rate(again, scale_m_per_px, file_fps, gravity_m_s2)
    return None


#: Radii (m) of the balls drop tests use, from a bead to a basketball: a scale from gravity that makes the tracked
#: ball far larger says the clip's time runs slow (slow motion), far smaller that it runs fast.
PLAUSIBLE_BALL_RADIUS_M = (0.002, 0.15)
#: Radius (m) taken for a ball whose size is not known, to say what capture rate a slow clip would have.
TYPICAL_BALL_RADIUS_M = 0.03


def _check_time_base_by_size(path, scales, radius_px, time, rows, seen_rows, gravity_m_s2, extra):
    """InputError when the only scale, gravity's in the file's time, makes the tracked ball larger than any ball
    (:data:`PLAUSIBLE_BALL_RADIUS_M`), or gravity gives no scale in the file's time but does at a common capture
    rate's: the clip is slow motion, and without the ball's size its capture rate cannot be inferred
    (:func:`_capture_time`). The refusal says how many times slower than g it falls for a ball of the kind's
    regulation size (else :data:`TYPICAL_BALL_RADIUS_M`) and the capture rate that would be."""
    from .balls import ball_kind

    radius = float(np.nanmedian(radius_px)) if np.isfinite(radius_px).any() else np.nan
    if not (np.isfinite(radius) and radius > 0):
        return
    file_fps = 1.0 / float(np.median(np.diff(time)))
    if "gravity" in scales:
        implied_m = scales["gravity"][0] * radius
        if implied_m <= PLAUSIBLE_BALL_RADIUS_M[1]:
            return
        acceleration = gravity_m_s2 / scales["gravity"][0]  # px/s² of the file's time
    else:
        # the first common capture rate at which the flights are found and the ball has a plausible size
        acceleration = next((found for candidate, found in _slow_motion_fits(time, rows, seen_rows, extra,
                                                                               gravity_m_s2, file_fps)
                             if PLAUSIBLE_BALL_RADIUS_M[0] <= gravity_m_s2 / (found * (candidate / file_fps) ** 2)
                             * radius <= PLAUSIBLE_BALL_RADIUS_M[1]), None)
        if acceleration is None:
            return
        implied_m = gravity_m_s2 / acceleration * radius
    try:
        regulation = ball_kind(extra.get("ball_type")).regulation
    except InputError:
        regulation = None
    ball_m, kind = (regulation.radius_m, f"as a {extra.get('ball_type')} ball") if regulation is not None else \
        (TYPICAL_BALL_RADIUS_M, f"if {100 * TYPICAL_BALL_RADIUS_M:g} cm in radius")
    reading = slow_motion_reading(acceleration * ball_m / radius / gravity_m_s2, file_fps,
                                  advice="give --capture-fps {rate:g} and --ball-radius-m")
    if reading is None:
        return
    raise InputError(f"{shown_path(path)}: not analysable: gravity's scale in the file's time makes the ball "
                     f"({radius:.1f} px) {implied_m:.3g} m in radius; {kind} it {reading}")


def _record_scales(scales, extra):
    """Choose the scale (:func:`dropfit.video.calibrate.choose_scale`: by precedence, g arbitrating); store every
    scale, the others' disagreements, the suspect ones' likely causes (``scale_suspect_<source>``) and the chosen
    one's relative standard error in ``extra``. Returns the chosen source and its scale in m/px."""
    chosen, disagreements, suspects = choose_scale(scales)
    scale, scale_se = scales[chosen]
    for name, (value, se) in scales.items():
        extra[f"scale_{name}_m_per_px"], extra[f"scale_{name}_se_m_per_px"] = value, se
    for name, disagreement in disagreements.items():
        extra[f"scale_disagreement_{name}"] = disagreement
    for name, cause in suspects.items():  # the flights fall with g through gravity's scale, not through these
        if name == "ruler":  # what its marks' spacing is by gravity's scale
            spacing_m = extra["ruler_tick_m"] * scales["gravity"][0] / scales["ruler"][0]
            cause += (f"; by gravity's scale the marks found are {spacing_m:.2g} m apart, not "
                      f"{extra['ruler_tick_m']:g} m")
        extra[f"scale_suspect_{name}"] = cause
    extra.update(scale_source=chosen, scale_m_per_px=scale, scale_rel_se=scale_se / scale)
    return chosen, scale


def _add_gravity_scale(scales, time, rows, seen_rows, gravity_m_s2, path, extra):
    """Add the scale from gravity (drag included) to ``scales``, or note in ``extra`` why there is none."""
    try:
        # dropfit's tracked centres may err with the ball's speed (motion blur, the codec): as v² that bends the
        # flights like another g
        signed, se, details = scale_from_gravity(time, rows, gravity_m_s2, str(path), *nominal_drag_of(extra),
                                                 seen_rows, extra["speed_error_px"])
        extra.update(details)
    except InputError as error:
        extra["gravity_calibration_failed"] = str(error)
        return
    if signed < 0:  # image rows point down: a positive magnitude here
        scales["gravity"] = (-signed, se)
