"""Ball tracking in video: the sub-pixel centre and radius of the ball in every frame.

The camera is static, so the scene without the ball is one image, the background
(:mod:`dropfit.video.background`). In the first frame, and whenever the ball was lost, the whole
(downscaled) frame is searched for the foreground blob with the largest inscribed circle, preferring
lone, roughly circular blobs (:func:`dropfit.video.detect.find_ball`). Afterwards the position is
predicted from the last three positions (constant acceleration) and only a window of about four
radii around the prediction is measured (:func:`dropfit.video.detect.measure_ball`, which gives the
quality flags ``ok``, ``blurred``, ``partial`` and ``occluded``). The tracker adds two flags:

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
``centre_se_px`` and ``fit_rms_px`` are small (:func:`usable_rows`).

Ball in the background. A ball that is in view for the whole clip and moves less than a few
diameters (a close-up of a contact) covers some pixels in more than half of the background
samples, so their median is the ball, not the scene. The tracker then runs twice: the balls
found in the background samples by the first pass are cut out of them (discs of
``BALL_MASK_RADII`` tracked radii plus ``BALL_MASK_MARGIN_PX``), the median of what is left is
the background of the next pass (:func:`background_without_ball`), until the sampled balls
settle (a first pass misled by the ball in the background can misplace some of them).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import pandas as pd

from ..errors import InputError, shown_path
from ..files import check_input_file
from .background import BACKGROUND_SAMPLES, background_without_ball, estimate_background, grey_uint8, to_grey
from .decode import (MIN_FRAMES, FrameReader, check_frame_count, check_video_file, frame_times, spread_indices,
                     video_samples)
from .detect import (QUALITY_BLURRED, QUALITY_DUPLICATE, QUALITY_LOST, QUALITY_OCCLUDED, QUALITY_OK, QUALITY_PARTIAL,
                     find_ball, measure_ball)
from .opencv import cv2, decoder_output_silenced

#: Frames measured cleanly: a lone ball whose centre is its coverage-weighted centroid.
CLEAN_QUALITIES = (QUALITY_OK, QUALITY_BLURRED)
COLUMNS = ["frame", "time_s", "x_px", "y_px", "radius_px", "quality", "centre_se_px", "fit_rms_px"]
#: Lag-1 autocorrelation of the tracked centre's errors between successive frames (dimensionless): the
#: pixel grid and the codec's 8 × 8 blocks bias neighbouring frames alike. Measured against the
#: renderer's truth on seeded synthetic clips (120 and 240 fps, ball radius 5–12 px, noise σ 2, MJPEG
#: quality 90): 0.08–0.24 per clip, about 0.17 on average (tests/test_tracking.py). Taken as 0.2: with
#: independent errors assumed, the intervals of 200 small clips covered the truth only ~90 %.
TRACKED_CENTRE_CORRELATION = 0.2

#: Mean absolute grey-level difference to the previous frame at or below which a frame is a duplicate.
DUPLICATE_TOLERANCE_GREY = 0.5
#: Pixels between the sparse samples of the duplicate test.
DUPLICATE_STRIDE_PX = 16
#: A frame identical to the previous one is not a duplicate when the ball is predicted to move less
#: than this between them, px (a ball at rest in a noise-free video).
STILL_BALL_STEP_PX = 0.1
#: Extra margin of the search window, px.
WINDOW_MARGIN_PX = 6
#: At most this many further tracking passes, each with the ball cut out of the background samples
#: where the previous pass found it; they stop once the sampled balls move less than
#: BACKGROUND_SETTLED_PX between passes.
MAX_BACKGROUND_REFINEMENTS = 3
BACKGROUND_SETTLED_PX = 0.5
#: A partial frame enters the trajectory when its circle fit's centre standard error and its RMS
#: residual are at most these, px.
MAX_PARTIAL_CENTRE_SE_PX = 0.1
MAX_PARTIAL_FIT_RMS_PX = 0.5
#: ... and when its radius is within this of the clean frames' (a free-radius fit to a short arc can
#: settle on a wrong circle with small residuals), px.
MAX_PARTIAL_RADIUS_MISMATCH_PX = 0.5


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
            grey = grey_uint8(frame)
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
        indices = spread_indices(len(frames), BACKGROUND_SAMPLES)
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


def _track_decoded(path, background, expected_radius_px):
    """Decode a video file again and track the ball with a given background; the tracker's rows."""
    capture = cv2.VideoCapture(str(path))
    reader = FrameReader(capture)
    reader.start()
    try:
        return _run((frame for frame, _ in reader), background, expected_radius_px)
    finally:
        reader.close()
        capture.release()


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
    check_video_file(path)
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
        reader = FrameReader(capture)
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
    times, how = frame_times(stamps, container_fps, capture_fps, path)
    table = _table(rows, times)
    table.attrs.update(source=str(path), container_fps=container_fps, capture_fps=capture_fps,
                       time_source=how, frame_count_header=frame_count, noise_grey=background.noise_grey)
    return _found_or_raise(table, path)


