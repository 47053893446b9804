"""Videos: track the ball and calibrate pixels to metres and frames to seconds, giving the same
trajectory as a height log.

Scales come from up to four sources (:mod:`dropfit.video.calibrate`): a given scale, a ruler's ticks
in the background (with ``ruler_tick_m``), gravity (the flights' shared acceleration in px/s²,
quadratic drag included, over g) and the ball's known diameter (its tracked radius in px against
its radius in m). The one used is the first available in the precedence given > ruler > gravity >
diameter (an order by accuracy: see :mod:`dropfit.video.calibrate`); every other one is stored with its
disagreement relative to it. A ruler also measures the camera tilt's keystone (the scale changing
along the image's height): the tracked rows and the floor's row are rectified with it
(:func:`dropfit.video.calibrate.rectify_rows`) before any scale applies. The chosen scale's
relative standard error (``scale_rel_se``; 0 for a given scale) goes with the trajectory, and the
analysis adds its effect on every impact quantity (heights, and through the fitted drag also e,
flight times and their ratios) to their covariance.

Time: a slow-motion file's container rate may be a playback rate. With a scale that does not
come from gravity, the flights' acceleration in the file's time gives the capture rate, snapped to a
common camera rate; ``capture_fps`` overrides it.
"""

from __future__ import annotations

import numpy as np

from .video import limits as video_limits
from .video.calibrate import SCALE_PRECEDENCE, choose_scale, infer_capture_rate, rectify_rows, ruler_scale
from .errors import InputError, shown_path
from .heightlog import check_floor, flight_acceleration, make_trajectory, nominal_drag_of, scale_from_gravity
from .numerics import robust_sigma
from .physics import STANDARD_GRAVITY_M_S2

VIDEO_SUFFIXES = (".avi", ".mp4", ".mov", ".mkv", ".m4v")
#: Standard error of the floor row found in the image relative to the tracked ball centres, px: the
#: sub-pixel edge and centroid biases on the rendered 2000 fps close-up are up to 0.03 px. A real
#: floor seen in perspective can be off by more: give floor_m when it matters.
FLOOR_ROW_SE_PX = 0.05


def is_video(path):
    """True if ``path`` names a video file (by its suffix)."""
    return str(path).lower().endswith(VIDEO_SUFFIXES)


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
        Scale in m/px and its standard error (median radius, robust spread over √n).
    """
    radius_px = radius_px[np.isfinite(radius_px)]
    median = float(np.median(radius_px))
    spread = robust_sigma(radius_px, centre=median)
    median_se = 1.2533 * spread / np.sqrt(radius_px.size)
    scale = ball_radius_m / median
    return scale, scale * median_se / median


def video_background(path, samples=7):
    """Background grey image of a video: the per-pixel median of ``samples`` frames spread over it.

    Returns
    -------
    numpy.ndarray or None
        Grey levels (height, width), or None if no frame could be read.
    """
    from .video.opencv import cv2, decoder_output_silenced
    from .video.background import estimate_background
    from .video.decode import video_samples

    with decoder_output_silenced():
        capture = cv2.VideoCapture(str(path))
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        capture.release()
        _, frames = video_samples(path, count, samples)
    return estimate_background(frames).grey if frames else None


def find_floor_row(background_grey, bottom_row_px, radius_px):
    """Image row (px, sub-pixel) of the floor's edge, searched within one ball radius of ``bottom_row_px``.

    The floor is the strongest horizontal edge of the background (:func:`video_background`) near
    the lowest row the ball's bottom reaches; its sub-pixel row is where the row profile crosses
    halfway between the levels above and below it.

    Returns
    -------
    float or None
        The row, or None if no clear edge is there.
    """
    profile = background_grey.mean(axis=1)
    low = max(int(bottom_row_px - radius_px), 8)
    high = min(int(bottom_row_px + radius_px), profile.size - 9)
    if high <= low:
        return None
    step = np.abs(np.diff(profile[low - 1: high + 2]))
    edge = low - 1 + int(np.argmax(step))  # the edge lies between rows edge and edge + 1
    above, below = np.median(profile[edge - 7: edge - 2]), np.median(profile[edge + 3: edge + 8])
    if abs(below - above) < 10 * np.std(profile[edge - 7: edge - 2]) + 1.0:
        return None
    half = 0.5 * (above + below)
    segment = profile[edge - 2: edge + 4]
    crossing = np.flatnonzero(np.diff(np.sign(segment - half)))[0]
    a, b = segment[crossing], segment[crossing + 1]
    return float(edge - 2 + crossing + (half - a) / (b - a))


def trajectory_from_video(path, ball_radius_m=None, scale_m_per_px=None, capture_fps=None,
                          gravity_m_s2=STANDARD_GRAVITY_M_S2, attrs=None, ruler_tick_m=None):
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

    Returns
    -------
    xarray.Dataset
        As :func:`dropfit.heightlog.make_trajectory`, plus ``x`` (m) and ``radius`` (m); image rows
        point down, so heights are −row × scale (the zero is the top image row), with rows rectified
        by a ruler's keystone (``keystone_per_px``, ``keystone_se_per_px``, ``keystone_row_px``). The
        attributes hold every scale found (``scale_<source>_m_per_px`` and ``_se_m_per_px``), the chosen
        ``scale_source``, ``scale_m_per_px`` and its relative standard error ``scale_rel_se``, the
        others' ``scale_disagreement_<source>`` (s / s_chosen − 1), and the time base
        (``capture_fps``, ``capture_fps_source``, ``capture_rate_note``).
    """
    from .video.track import track_video, usable_rows

    table = track_video(path, capture_fps=capture_fps)
    table = table[table["quality"] != "duplicate"]  # a repeated frame carries no new instant
    video_limits.check_recording(table, path)  # refuse below the limits of benchmarks/video_failure_sweep.py
    usable = usable_rows(table)
    if np.count_nonzero(usable) < 10:
        raise InputError(f"{shown_path(path)}: the ball is measured cleanly in only {np.count_nonzero(usable)} of "
                         f"{len(table)} frames (at least 10 are needed)")
    image_rows = np.where(usable, table["y_px"].to_numpy(), np.nan)
    radius_px = table["radius_px"].to_numpy()[usable]
    extra = dict(attrs or {})
    extra.update(video=str(path), frames=int(len(table)), frames_usable=int(np.count_nonzero(usable)))
    # the ruler and the floor are read from the background; neither needed, no second read of the file
    background = video_background(path) if ruler_tick_m or extra.get("floor_m") is None else None
    scales = _independent_scales(background, radius_px, ball_radius_m, scale_m_per_px, ruler_tick_m, extra)
    rows = _rectified(image_rows, extra)
    time = _capture_time(table, rows, scales, capture_fps, gravity_m_s2, extra)
    if extra["capture_fps_source"] == _RAW_RATE_SOURCE:
        extra["gravity_calibration_failed"] = "gravity set the capture rate, so it gives no independent scale"
    else:
        _add_gravity_scale(scales, time, rows, gravity_m_s2, path, extra)
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
            extra["floor_m"] = -float(_rectified(floor_row, extra)) * scale  # heights are −row × scale
            extra["floor_se_m"] = FLOOR_ROW_SE_PX * scale
    trajectory = make_trajectory(time, -rows * scale, path, _CALIBRATION_TEXT[chosen], extra)
    trajectory["x"] = ("time", np.where(usable, table["x_px"].to_numpy(), np.nan) * scale, {"units": "m"})
    trajectory["radius"] = ("time", np.where(usable, table["radius_px"].to_numpy(), np.nan) * scale, {"units": "m"})
    return trajectory


#: ``capture_fps_source`` of a capture rate inferred from gravity but near no common rate.
_RAW_RATE_SOURCE = "inferred from gravity (not a common rate)"
_CALIBRATION_TEXT = {"given": "given scale in m/px", "ruler": "scale from the ruler's ticks",
                     "gravity": "scale from gravity (flight curvature, drag included)",
                     "diameter": "scale from the ball's diameter"}


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


def _rectified(rows_px, extra):
    """Image rows (px) rectified by the ruler's keystone recorded in ``extra``; unchanged without a ruler."""
    if "keystone_per_px" not in extra:
        return rows_px
    return rectify_rows(rows_px, extra["keystone_per_px"], extra["keystone_row_px"])


def _capture_time(table, rows, scales, capture_fps, gravity_m_s2, extra):
    """Frame times in s of capture; infer the capture rate from gravity when no rate is given.

    With a scale independent of gravity, the flights' acceleration in the file's time tells the
    capture rate (:func:`dropfit.video.calibrate.infer_capture_rate`). Notes go into ``extra``.
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
        _, fit = flight_acceleration(time, rows, str(extra["video"]), *nominal_drag_of(extra), gravity_m_s2)
    except InputError as error:
        extra.update(capture_fps=file_fps, capture_fps_source="container",
                     capture_rate_note=f"the file's rate is taken as the capture rate ({error})")
        return time
    rate = infer_capture_rate(fit.acceleration, scales[reference][0], file_fps, gravity_m_s2)
    source = "container" if rate["capture_fps"] == file_fps else "inferred from gravity" if rate["snapped"] \
        else _RAW_RATE_SOURCE
    extra.update(capture_fps=rate["capture_fps"], capture_fps_source=source,
                 capture_fps_estimate=rate["estimate_fps"],
                 capture_rate_note=f"{rate['why']}; length scale from the {reference}")
    return time * file_fps / rate["capture_fps"]


def _record_scales(scales, extra):
    """Choose the scale by precedence; store every scale, the others' disagreements and the chosen one's
    relative standard error in ``extra``. Returns the chosen source and its scale in m/px."""
    chosen, disagreements = choose_scale(scales)
    scale, scale_se = scales[chosen]
    for name, (value, se) in scales.items():
        extra[f"scale_{name}_m_per_px"], extra[f"scale_{name}_se_m_per_px"] = value, se
    for name, disagreement in disagreements.items():
        extra[f"scale_disagreement_{name}"] = disagreement
    extra.update(scale_source=chosen, scale_m_per_px=scale, scale_rel_se=scale_se / scale)
    return chosen, scale


def _add_gravity_scale(scales, time, rows, gravity_m_s2, path, extra):
    """Add the scale from gravity (drag included) to ``scales``, or note in ``extra`` why there is none."""
    try:
        signed, se, details = scale_from_gravity(time, rows, gravity_m_s2, str(path), *nominal_drag_of(extra))
        extra.update(details)
    except InputError as error:
        extra["gravity_calibration_failed"] = str(error)
        return
    if signed < 0:  # image rows point down: a positive magnitude here
        scales["gravity"] = (-signed, se)
