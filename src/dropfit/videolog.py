"""Videos: track the ball and calibrate pixels to metres, giving the same trajectory as a height log.

The scale comes from gravity (the flights' shared curvature in px/s² over g) and from the ball's
known diameter (its tracked radius in px against its radius in m). Both are reported with their
disagreement; gravity's is used when it is precise enough (it measures the scale in the plane of
the ball's motion, while the tracked radius depends on the edge threshold and blur), else the
diameter's. A given scale overrides both.
"""

from __future__ import annotations

import numpy as np

from . import video_limits
from .errors import InputError
from .heightlog import make_trajectory, scale_from_gravity
from .physics import STANDARD_GRAVITY_M_S2

VIDEO_SUFFIXES = (".avi", ".mp4", ".mov", ".mkv", ".m4v")
#: Frames the tracker measured cleanly enough to enter the trajectory.
_USABLE = ("ok",)


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
    spread = 1.4826 * float(np.median(np.abs(radius_px - median)))
    median_se = 1.2533 * spread / np.sqrt(radius_px.size)
    scale = ball_radius_m / median
    return scale, scale * median_se / median


def find_floor_row(path, bottom_row_px, radius_px, samples=7):
    """Image row (px, sub-pixel) of the floor's edge, searched within one ball radius of ``bottom_row_px``.

    The floor is the strongest horizontal edge of the background (the per-pixel median of frames
    spread over the clip) near the lowest row the ball's bottom reaches; its sub-pixel row is where
    the row profile crosses halfway between the levels above and below it.

    Returns
    -------
    float or None
        The row, or None if no clear edge is there.
    """
    import cv2

    from .tracking import estimate_background

    capture = cv2.VideoCapture(str(path))
    count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
    frames = []
    for index in np.linspace(0, max(count - 1, 0), samples).astype(int):
        capture.set(cv2.CAP_PROP_POS_FRAMES, int(index))
        ok, frame = capture.read()
        if ok:
            frames.append(frame)
    capture.release()
    if not frames:
        return None
    profile = estimate_background(frames).grey.mean(axis=1)
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
                          gravity_m_s2=STANDARD_GRAVITY_M_S2, attrs=None):
    """Track the ball in a drop-test video and return the trajectory dataset (heights in m, up).

    Parameters
    ----------
    path : str or pathlib.Path
        The video file.
    ball_radius_m : float, optional
        Ball radius in m, for the scale from the ball's diameter.
    scale_m_per_px : float, optional
        Known scale in m/px (positive); overrides the calibration.
    capture_fps : float, optional
        Capture rate in frames per second of a slow-motion file whose container rate differs.
    gravity_m_s2 : float
        Gravity in m/s².
    attrs : dict, optional
        Extra attributes for the dataset.

    Returns
    -------
    xarray.Dataset
        As :func:`dropfit.heightlog.make_trajectory`, plus ``x`` (m) and ``radius`` (m); image rows
        point down, so heights are −row × scale (the zero is the top image row).
    """
    from .tracking import track_video

    table = track_video(path, capture_fps=capture_fps)
    table = table[table["quality"] != "duplicate"]  # a repeated frame carries no new instant
    usable = table["quality"].isin(_USABLE).to_numpy()
    video_limits.check_recording(table, path)  # refuse below the limits of benchmarks/video_failure_sweep.py
    if np.count_nonzero(usable) < 10:
        raise InputError(f"{path}: the ball is measured cleanly in only {np.count_nonzero(usable)} frames")
    time = table["time_s"].to_numpy()
    rows = np.where(usable, table["y_px"].to_numpy(), np.nan)
    extra = dict(attrs or {})
    extra.update(video=str(path), frames=int(len(table)), frames_usable=int(np.count_nonzero(usable)))
    scales = {}
    if ball_radius_m:
        scales["diameter"] = scale_from_diameter(table["radius_px"].to_numpy()[usable], ball_radius_m)
    try:
        signed, se = scale_from_gravity(time, rows, gravity_m_s2, source=str(path))
        if signed < 0:  # image rows point down: a positive magnitude here
            scales["gravity"] = (-signed, se)
    except InputError as error:
        extra["gravity_calibration_failed"] = str(error)
    for name, (value, se) in scales.items():
        extra[f"scale_{name}_m_per_px"], extra[f"scale_{name}_se_m_per_px"] = value, se
    if "diameter" in scales and "gravity" in scales:
        extra["scale_disagreement"] = scales["diameter"][0] / scales["gravity"][0] - 1.0
    if scale_m_per_px is not None:
        scale, calibration = float(scale_m_per_px), "given scale in m/px"
    elif "gravity" in scales:
        scale, calibration = scales["gravity"][0], "scale from gravity (flight curvature)"
    elif "diameter" in scales:
        scale, calibration = scales["diameter"][0], "scale from the ball's diameter"
    else:
        raise InputError(f"{path}: no scale: give the ball radius or scale_m_per_px "
                         f"({extra.get('gravity_calibration_failed', 'gravity calibration failed')})")
    extra["scale_m_per_px"] = scale
    if extra.get("floor_m") is None:
        radius_px = float(np.nanmedian(table["radius_px"].to_numpy()[usable]))
        floor_row = find_floor_row(path, float(np.nanmax(rows)) + radius_px, radius_px)
        if floor_row is not None:
            extra["floor_row_px"] = floor_row
            extra["floor_m"] = -floor_row * scale  # heights are −row × scale
    trajectory = make_trajectory(time, -rows * scale, path, calibration, extra)
    trajectory["x"] = ("time", np.where(usable, table["x_px"].to_numpy(), np.nan) * scale, {"units": "m"})
    trajectory["radius"] = ("time", np.where(usable, table["radius_px"].to_numpy(), np.nan) * scale, {"units": "m"})
    return trajectory
